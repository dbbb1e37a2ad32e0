"""Cartesian recordings → demonstrations: reading, resampling, repeats, diagonal splits, gaps,
snapping, goals, every bad row with its message, and ``expertise-irl discretise`` end to end.

Floor plans here use 1 m cells unless said otherwise, and samples sit at cell centres
(col + 0.5, row + 0.5) with a small offset, so each test can say which cell a sample is in.
"""

from __future__ import annotations

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke

from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.demos.recordings import discretise, read_recording, shortest_free_path
from expertise_irl.errors import InputError
from expertise_irl.worlds.maps import resolve_world
from expertise_irl.worlds.warehouse import parse_floor_plan

H, V = 0, 1
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PLAN_TEXT = (
    "S.....\n"
    "..#...\n"
    "......\n"
    ".....G\n"
)
PLAN = parse_floor_plan(PLAN_TEXT)


def write_rec(path, rows, header="episode,t,x,y"):
    """Write a recording; each row is (episode, t, col, row) at the cell centre, or a raw string."""
    lines = [header]
    for r in rows:
        if isinstance(r, str):
            lines.append(r)
        else:
            e, t, c, w = r
            lines.append(f"{e},{t},{c + 0.5:g},{w + 0.5:g}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def run(tmp_path, rows, plan=PLAN, **options):
    return discretise(read_recording(write_rec(tmp_path / "rec.csv", rows)), plan, **options)


def only(result):
    (ep,) = result.episodes
    return ep


def cells(ep):
    return [tuple(c) for c in ep.cells.tolist()]


@pytest.fixture
def plan_file(tmp_path):
    (tmp_path / "plan.txt").write_text(PLAN_TEXT, encoding="utf-8")
    (tmp_path / "plan.toml").write_text('world = "warehouse"\ncell_size = 1.0\n', encoding="utf-8")
    return tmp_path / "plan.txt"


# --------------------------------------------------------------------- reading
def test_columns_are_found_by_name_and_other_columns_are_ignored(tmp_path):
    p = tmp_path / "rec.csv"
    p.write_text("y,note,x,t,episode\n0.5,a,0.5,0,3\n0.5,b,1.5,1,3\n", encoding="utf-8")
    rec = read_recording(p)
    assert rec.episode.tolist() == [3, 3] and rec.t.tolist() == [0, 1]
    assert rec.x.tolist() == [0.5, 1.5] and rec.line.tolist() == [2, 3]


# ------------------------------------------------------------------ resampling
TIMES = [0.0, 0.3, 0.9, 1.0, 1.4, 2.2, 2.9]
ALONG_ROW = [(0, 0), (0, 0), (1, 0), (1, 0), (2, 0), (3, 0), (3, 0)]


def test_each_tick_keeps_the_last_sample_at_or_before_it_and_the_last_tick_covers_the_end(tmp_path):
    rows = [(0, t, c, r) for t, (c, r) in zip(TIMES, ALONG_ROW, strict=True)]
    ep = only(run(tmp_path, rows))
    # ticks 0, 1, 2, 3: t=0 (0), t=1.0 at the tick itself (3), t=1.4 (4), t=2.9 (6, the end)
    assert ep.kept.tolist() == [0, 3, 4, 6]
    assert cells(ep) == [(0, 0), (1, 0), (2, 0), (3, 0)]


def test_the_rate_sets_the_ticks(tmp_path):
    rows = [(0, t, c, r) for t, (c, r) in zip(TIMES, ALONG_ROW, strict=True)]
    ep = only(run(tmp_path, rows, rate=2.0))
    # ticks 0, .5, 1, 1.5, 2, 2.5, 3 keep 0, 1, 3, 4, 4, 5, 6
    assert ep.kept.tolist() == [0, 1, 3, 4, 5, 6]


def test_ticks_start_at_the_episodes_first_sample(tmp_path):
    rows = [(0, 100.6, 0, 0), (0, 101.5, 1, 0), (0, 101.7, 1, 1), (0, 102.6, 2, 0)]
    ep = only(run(tmp_path, rows))
    assert ep.kept.tolist() == [0, 1, 3]  # ticks 100.6, 101.6, 102.6


def test_repeats_of_a_cell_are_dropped_and_a_pause_is_not_a_gap(tmp_path):
    rows = [(0, round(0.1 * k, 1), 0, 0) for k in range(50)]  # five seconds still, at 10 Hz
    rows += [(0, 5.0, 1, 0), (0, 6.0, 1, 0), (0, 7.0, 2, 0)]
    ep = only(run(tmp_path, rows))
    assert cells(ep) == [(0, 0), (1, 0), (2, 0)]
    assert ep.filled_gaps == 0


# -------------------------------------------------------------- moves, headings
def test_a_diagonal_step_with_no_heading_yet_goes_horizontal_first(tmp_path):
    ep = only(run(tmp_path, [(0, 0, 0, 0), (0, 1, 1, 1)]))
    assert cells(ep) == [(0, 0), (1, 0), (1, 1)]
    assert ep.headings.tolist() == [H, H, V]


def test_a_diagonal_step_keeps_the_current_heading_first(tmp_path):
    vertical = only(run(tmp_path, [(0, 0, 0, 0), (0, 1, 0, 1), (0, 2, 1, 2)]))
    assert cells(vertical) == [(0, 0), (0, 1), (0, 2), (1, 2)]
    horizontal = only(run(tmp_path, [(0, 0, 3, 0), (0, 1, 4, 0), (0, 2, 5, 1)]))
    assert cells(horizontal) == [(3, 0), (4, 0), (5, 0), (5, 1)]


def test_a_diagonal_step_whose_corner_is_an_obstacle_takes_the_other_corner(tmp_path):
    # heading h at (1, 1); horizontal first would cross the obstacle at (2, 1)
    ep = only(run(tmp_path, [(0, 0, 0, 1), (0, 1, 1, 1), (0, 2, 2, 2)]))
    assert cells(ep) == [(0, 1), (1, 1), (1, 2), (2, 2)]


def test_the_first_state_takes_the_axis_of_the_first_move_so_it_costs_one(tmp_path):
    result = run(tmp_path, [(0, 0, 0, 0), (0, 1, 0, 1), (0, 2, 1, 1)])
    ep = only(result)
    assert ep.headings.tolist() == [V, V, H]
    mdp = PLAN.to_mdp()
    tr = result.trajectories
    assert mdp.features[tr.state, tr.action, 0].tolist() == [-1, -2]
    assert tr.state[0] == PLAN.state_index()[V, 0, 0]


# ------------------------------------------------------------------------ gaps
def test_cells_more_than_one_apart_are_a_gap_naming_file_line_episode_and_time(tmp_path):
    rows = [(4, 0, 0, 0), (4, 1, 1, 0), (4, 2, 4, 0)]
    with pytest.raises(InputError) as exc:
        run(tmp_path, rows)
    msg = str(exc.value)
    assert msg.startswith(f"{tmp_path / 'rec.csv'}:4: episode 4 t=2: gap from cell (1, 0) at t=1 to cell "
                          "(4, 0): 3 cells apart after resampling at 1 Hz")


def test_a_filled_gap_is_a_shortest_free_path_with_fewest_turns_and_is_counted(tmp_path):
    result = run(tmp_path, [(0, 0, 2, 0), (0, 1, 3, 0), (0, 2, 5, 2)], fill_gaps=True)
    ep = only(result)
    # heading h at (3, 0): along the row first, one turn (down, down would turn twice)
    assert cells(ep) == [(2, 0), (3, 0), (4, 0), (5, 0), (5, 1), (5, 2)]
    assert ep.filled.tolist() == [False, False, True, True, True, False]
    assert (ep.filled_gaps, result.filled_gaps) == (1, 1)
    down_first = only(run(tmp_path, [(0, 0, 3, 0), (0, 1, 3, 1), (0, 2, 5, 3)], fill_gaps=True))
    assert cells(down_first)[2:] == [(3, 2), (3, 3), (4, 3), (5, 3)]  # heading v: down first


def test_a_filled_path_goes_round_obstacles():
    path = shortest_free_path(PLAN, (1, 1), (3, 1), H)
    assert len(path) == 4 and (2, 1) not in path and path[-1] == (3, 1)
    # heading v at (0, 1): of the 5-move ways round, up first turns only twice
    assert shortest_free_path(PLAN, (0, 1), (3, 1), V) == [(0, 0), (1, 0), (2, 0), (3, 0), (3, 1)]
    assert shortest_free_path(parse_floor_plan("S#.\n.#G\n"), (0, 0), (2, 0), None) is None


def test_a_diagonal_between_two_obstacles_is_a_gap(tmp_path):
    plan = parse_floor_plan("S.#.\n.#..\n...G\n")
    rows = [(0, 0, 0, 0), (0, 1, 1, 0), (0, 2, 2, 1)]
    with pytest.raises(InputError, match="cuts a corner: both cells between are obstacles or goals"):
        run(tmp_path, rows, plan=plan)
    ep = only(run(tmp_path, rows, plan=plan, fill_gaps=True))
    assert cells(ep) == [(0, 0), (1, 0), (0, 0), (0, 1), (0, 2), (1, 2), (2, 2), (2, 1)]
    assert ep.filled_gaps == 1


def test_samples_further_apart_in_time_than_max_dt_are_a_gap(tmp_path):
    rows = [(0, 0, 0, 0), (0, 1, 1, 0), (0, 5, 2, 0)]
    with pytest.raises(InputError, match=r"rec\.csv:4: episode 0 t=5: gap of 4 s since the previous kept "
                                         r"sample at t=1 \(max_dt 2 s\)"):
        run(tmp_path, rows)
    assert only(run(tmp_path, rows, max_dt=4.0)).filled_gaps == 0
    filled = only(run(tmp_path, rows, fill_gaps=True))
    assert filled.filled_gaps == 1 and cells(filled) == [(0, 0), (1, 0), (2, 0)]


def test_the_default_max_dt_is_two_ticks(tmp_path):
    rows = [(0, 0, 0, 0), (0, 0.5, 1, 0), (0, 1.6, 2, 0)]  # 1.1 s apart: more than 2 ticks at 2 Hz
    with pytest.raises(InputError, match=r"max_dt 1 s"):
        run(tmp_path, rows, rate=2.0)
    assert only(run(tmp_path, rows, rate=1.0)).filled_gaps == 0


# --------------------------------------------------------------------- snapping
def test_a_sample_outside_the_map_or_in_an_obstacle_is_an_error_naming_its_row(tmp_path):
    with pytest.raises(InputError, match=r"rec\.csv:3: episode 0 t=1: sample \(x=-0\.3, y=0\.5\) is "
                                         r"outside the map \(x 0\.\.6 m, y 0\.\.4 m\)"):
        run(tmp_path, [(0, 0, 0, 0), "0,1,-0.3,0.5", (0, 2, 1, 0)])
    with pytest.raises(InputError, match=r"rec\.csv:3: episode 0 t=1: sample \(x=2\.5, y=1\.2\) is "
                                         r"inside an obstacle \(cell 2, 1\)"):
        run(tmp_path, [(0, 0, 2, 0), "0,1,2.5,1.2", (0, 2, 3, 0)])


def test_snap_moves_a_sample_to_the_free_cell_whose_centre_is_nearest_and_counts_it(tmp_path):
    rows = [(0, 0, 1, 0), "0,1,2.5,1.2", (0, 2, 3, 0), (0, 3, 4, 0), "0,4,6.2,0.4", "0,5,5.5,-2"]
    result = run(tmp_path, rows, snap=True)
    ep = only(result)
    assert ep.sample_cells.tolist() == [[1, 0], [2, 0], [3, 0], [4, 0], [5, 0], [5, 0]]
    assert ep.snapped.tolist() == [False, True, False, False, True, True]
    assert (ep.snapped_samples, result.snapped_samples) == (3, 3)
    assert cells(ep) == [(1, 0), (2, 0), (3, 0), (4, 0), (5, 0)]


def test_y_up_measures_y_from_the_bottom_edge(tmp_path):
    plan = parse_floor_plan(PLAN_TEXT, cell_size=0.5, y_up=True)
    rows = ["0,0,0.25,1.75", "0,1,0.25,1.25", "0,2,0.75,1.25"]  # rows 0, 1, 1 from the top
    ep = only(run(tmp_path, rows, plan=plan))
    assert cells(ep) == [(0, 0), (0, 1), (1, 1)]


# ------------------------------------------------------------------------ goals
def test_entering_a_goal_ends_the_episode_and_later_samples_are_counted(tmp_path):
    rows = [(0, 0, 3, 3), (0, 1, 4, 3), (0, 2, 5, 3), (0, 3, 5, 3), (0, 4, 5, 2), (0, 5, 4, 2)]
    ep = only(run(tmp_path, rows))
    assert cells(ep) == [(3, 3), (4, 3), (5, 3)]
    assert ep.reached_goal and ep.after_goal == 2  # waiting in the goal is not counted
    stays = only(run(tmp_path, rows[:4]))
    assert stays.reached_goal and stays.after_goal == 0


def test_several_episodes_keep_their_labels_and_order(tmp_path):
    result = run(tmp_path, [(7, 0, 0, 0), (7, 1, 1, 0), (2, 0, 0, 2), (2, 1, 0, 3)])
    assert [e.episode for e in result.episodes] == [7, 2]
    assert result.trajectories.episode.tolist() == [7, 2]


# ------------------------------------------------------------------ bad input
BAD = [
    ("episode,time,x,y\n0,0,0.5,0.5\n", ["rec.csv:1", "missing column(s) t"]),
    ("episode,t,x,y,t\n0,0,0.5,0.5,1\n", ["rec.csv:1", "column 't' appears more than once"]),
    ("", ["rec.csv", "no samples: the file is empty"]),
    ("episode,t,x,y\n", ["rec.csv:1", "no samples: the file has a header but no rows"]),
    ("episode,t,x,y\n0,0,0.5,0.5\n0,1,1.5\n", ["rec.csv:3", "row has 3 fields, expected 4"]),
    ("episode,t,x,y\n,0,0.5,0.5\n", ["rec.csv:2", "column 'episode' is empty"]),
    ("episode,t,x,y\nA,0,0.5,0.5\n", ["rec.csv:2", "column 'episode': 'A' is not an integer"]),
    ("episode,t,x,y\n0,abc,0.5,0.5\n", ["rec.csv:2", "episode 0: column 't': 'abc' is not a number"]),
    ("episode,t,x,y\n0,0,nan,0.5\n", ["rec.csv:2", "episode 0: column 'x': 'nan' is not a finite number"]),
    ("episode,t,x,y\n0,0,0.5,\n", ["rec.csv:2", "episode 0: column 'y' is empty"]),
    ("episode,t,x,y\n0,1,0.5,0.5\n0,0.5,1.5,0.5\n",
     ["rec.csv:3", "episode 0 t=0.5: time goes backwards (the previous sample is at t=1)"]),
    ("episode,t,x,y\n0,0,0.5,0.5\n1,0,0.5,1.5\n0,1,1.5,0.5\n",
     ["rec.csv:4", "episode 0 appears again after other episodes"]),
    ("episode,t,x,y\n0,0,0.5,0.5\n0,1,9.5,0.5\n", ["rec.csv:3", "episode 0 t=1", "outside the map"]),
    ("episode,t,x,y\n0,0,1.5,1.5\n0,1,2.5,1.5\n", ["rec.csv:3", "episode 0 t=1", "inside an obstacle"]),
    ("episode,t,x,y\n0,0,0.5,0.5\n0,1,3.5,0.5\n",
     ["rec.csv:3", "episode 0 t=1", "gap from cell (0, 0)", "--fill-gaps"]),
    ("episode,t,x,y\n0,0,5.5,3.5\n0,1,4.5,3.5\n", ["rec.csv:2", "episode 0 t=0", "starts in a goal"]),
    ("episode,t,x,y\n0,0,0.5,0.5\n0,1,0.6,0.6\n", ["rec.csv:2", "episode 0", "never leaves cell (0, 0)"]),
    ("episode,t,x,y\n0,0,0.5,0.5\n0,1e7,1.5,0.5\n", ["rec.csv:3", "check the time unit"]),
]


@pytest.mark.parametrize(("content", "fragments"), BAD, ids=[f[-1] for _, f in BAD])
def test_every_bad_row_is_a_one_line_error_with_exit_code_2(tmp_path, plan_file, content, fragments):
    rec = tmp_path / "rec.csv"
    rec.write_text(content, encoding="utf-8")
    r = invoke("discretise", plan_file, "--recording", rec, "--out", tmp_path / "d.csv")
    assert_input_error(r, *fragments)
    assert not (tmp_path / "d.csv").exists() and not (tmp_path / "d.png").exists()


@pytest.mark.parametrize(("option", "fragment"), [
    (["--rate", "0"], "rate must be a number of ticks per second > 0"),
    (["--max-dt", "-1"], "max_dt must be a number of seconds > 0"),
])
def test_bad_settings_are_one_line_errors(tmp_path, plan_file, option, fragment):
    rec = write_rec(tmp_path / "rec.csv", [(0, 0, 0, 0), (0, 1, 1, 0)])
    assert_input_error(invoke("discretise", plan_file, "--recording", rec, "--out", tmp_path / "d.csv",
                              *option), fragment)


def test_a_missing_recording_and_a_zone_map_are_refused(tmp_path, plan_file):
    assert_input_error(invoke("discretise", plan_file, "--recording", tmp_path / "none.csv", "--out",
                              tmp_path / "d.csv"), "none.csv", "no such file")
    rec = write_rec(tmp_path / "rec.csv", [(0, 0, 0, 0), (0, 1, 1, 0)])
    assert_input_error(invoke("discretise", "crossroads", "--recording", rec, "--out", tmp_path / "d.csv"),
                       "crossroads: is a zone map", 'world = "warehouse"')


def test_the_figure_puts_samples_where_they_were_recorded_and_cells_at_their_centres(tmp_path):
    from expertise_irl.plots.floorplan import discretised_figure

    plan = parse_floor_plan(PLAN_TEXT, cell_size=0.5, y_up=True)
    rows = ["0,0,0.25,1.75", "0,1,0.3,1.2", "0,2,0.3,0.7", "0,3,1.4,0.7", "0,4,3.4,0.7"]  # gaps, off map
    result = run(tmp_path, rows, plan=plan, fill_gaps=True, snap=True)
    fig = discretised_figure(plan, result)
    lines = {ln.get_gid(): ln for ax in fig.get_axes() for ln in ax.lines if ln.get_gid()}
    # x / c - 0.5 across; y up from the bottom: row = H - y / c - 0.5
    assert np.allclose(lines["samples-0"].get_xdata(), [0.0, 0.1, 0.1, 2.3, 6.3])
    assert np.allclose(lines["samples-0"].get_ydata(), [0.0, 1.1, 2.1, 2.1, 2.1])
    assert lines["cells-0"].get_xydata().tolist() == [[0, 0], [0, 1], [0, 2], [1, 2], [2, 2], [3, 2],
                                                      [4, 2], [5, 2]]
    assert lines["filled-0"].get_xydata().tolist() == [[1, 2], [3, 2], [4, 2]]
    assert np.allclose(lines["snapped-0"].get_xydata(), [[6.3, 2.1]])


# ------------------------------------------------------------- command end to end
@pytest.mark.slow
def test_discretise_writes_the_heading_csv_and_a_png_and_reports_the_counts(tmp_path, plan_file):
    rec = write_rec(tmp_path / "rec.csv", [
        (0, 0.0, 0, 0), (0, 0.5, 0, 0), (0, 1.0, 1, 1),  # diagonal: horizontal first
        (0, 2.0, 1, 2), "0,3.0,1.6,2.4",                  # repeat of (1, 2)
        (0, 4.0, 4, 2),                                     # a gap of three cells
        "0,5.0,5.5,4.2",                                    # outside the map: snapped into (5, 3)
        (1, 0.0, 3, 0), (1, 1.0, 4, 0),
    ])
    out = tmp_path / "demos.csv"
    r = invoke("discretise", plan_file, "--recording", rec, "--out", out, "--fill-gaps", "--snap")
    assert r.exit_code == 0, r.output
    assert out.read_text(encoding="utf-8").splitlines() == [
        "episode,step,x,y,heading",
        "0,0,0,0,h", "0,1,1,0,h", "0,2,1,1,v", "0,3,1,2,v", "0,4,2,2,h", "0,5,3,2,h", "0,6,4,2,h",
        "0,7,5,2,h", "0,8,5,3,v",
        "1,0,3,0,h", "1,1,4,0,h",
    ]
    assert (tmp_path / "demos.png").read_bytes()[:8] == PNG_SIGNATURE
    assert "filled gaps 1, snapped samples 1" in r.stdout
    assert ("episode 0: 7 samples, 6 kept at 1 Hz, 8 moves, reached a goal; filled gaps 1, "
            "snapped samples 1") in r.stdout
    mdp = resolve_world(plan_file).to_mdp()
    assert len(read_demos_csv(out, mdp)) == 9
    r = invoke("infer", plan_file, "--demos", out, "--out", tmp_path / "r.json", "--betas", "paper-real")
    assert r.exit_code == 0, r.output


def test_discretise_refuses_to_overwrite_without_force_and_takes_a_png_path(tmp_path, plan_file):
    rec = write_rec(tmp_path / "rec.csv", [(0, 0, 0, 0), (0, 1, 1, 0)])
    out = tmp_path / "d.csv"
    r = invoke("discretise", plan_file, "--recording", rec, "--out", out, "--png", tmp_path / "look.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "look.png").is_file() and not (tmp_path / "d.png").exists()
    assert_input_error(invoke("discretise", plan_file, "--recording", rec, "--out", out), "d.csv",
                       "already exists")
    r = invoke("discretise", plan_file, "--recording", rec, "--out", out, "--force")
    assert r.exit_code == 0, r.output
