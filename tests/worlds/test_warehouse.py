"""Warehouse world (Sec. VIII-A): heading dynamics, turn costs, features, floor plans, archive,
heading demonstrations and the commands that take a floor plan."""

from __future__ import annotations

import numpy as np
import pytest
from cli_helpers import assert_input_error, invoke
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

from expertise_irl.demos.csv_io import read_demos_csv, write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.errors import InputError
from expertise_irl.mdp import TabularMDP
from expertise_irl.plots import floorplan
from expertise_irl.plots.maps import ROAD_ARROWS_GID
from expertise_irl.worlds.maps import resolve_world
from expertise_irl.worlds.warehouse import (
    FEATURE_NAMES,
    WarehouseMap,
    load_floor_plan,
    parse_floor_plan,
)
from expertise_irl.worlds.zones import ZoneMap

UP, DOWN, LEFT, RIGHT = range(4)
H, V = 0, 1
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def write_plan(tmp_path, text: str, toml: str = 'world = "warehouse"\ncell_size = 1.0\n', name="plan"):
    (tmp_path / f"{name}.txt").write_text(text, encoding="utf-8")
    if toml is not None:
        (tmp_path / f"{name}.toml").write_text(toml, encoding="utf-8")
    return tmp_path / f"{name}.txt"


def state(plan: WarehouseMap, col: int, row: int, heading: int) -> int:
    return int(plan.state_index()[heading, row, col])


# ------------------------------------------------------------------ dynamics
SMALL = "S..\n.#.\n..G\n"  # cells row-major: (0,0)=0 (1,0)=1 (2,0)=2 (0,1)=3 (2,1)=4 (0,2)=5 ...


def test_states_are_cell_and_heading_in_row_major_order():
    plan = parse_floor_plan(SMALL)
    mdp = plan.to_mdp()
    assert mdp.n_states == 2 * 8
    assert mdp.state_xy[:6].tolist() == [[0, 0], [0, 0], [1, 0], [1, 0], [2, 0], [2, 0]]
    assert mdp.state_heading[:6].tolist() == [H, V, H, V, H, V]
    assert state(plan, 2, 1, V) == 2 * 4 + 1
    assert plan.state_index()[:, 1, 1].tolist() == [-1, -1]  # the obstacle has no state


def test_a_move_along_the_heading_costs_1_and_a_turn_costs_2_and_sets_the_heading():
    plan = parse_floor_plan(SMALL, goal_bonus=5.0)
    mdp = plan.to_mdp()
    length = mdp.features[..., 0]
    s_h, s_v = state(plan, 0, 0, H), state(plan, 0, 0, V)
    assert mdp.next_state[s_h, RIGHT] == state(plan, 1, 0, H) and length[s_h, RIGHT] == -1
    assert mdp.next_state[s_h, DOWN] == state(plan, 0, 1, V) and length[s_h, DOWN] == -2
    assert mdp.next_state[s_v, DOWN] == state(plan, 0, 1, V) and length[s_v, DOWN] == -1
    assert mdp.next_state[s_v, RIGHT] == state(plan, 1, 0, H) and length[s_v, RIGHT] == -2
    # every move leaves the heading on its own axis
    ok = mdp.next_state >= 0
    axis = np.array([V, V, H, H])
    assert (mdp.state_heading[mdp.next_state[ok]] == np.broadcast_to(axis, ok.shape)[ok]).all()
    # into the goal: the move's cost plus the bonus
    g_v, g_h = state(plan, 2, 1, V), state(plan, 2, 1, H)
    assert length[g_v, DOWN] == -1 + 5.0 and length[g_h, DOWN] == -2 + 5.0


def test_walls_obstacles_and_the_map_edge_make_moves_unavailable():
    plan = parse_floor_plan(SMALL)
    mdp = plan.to_mdp()
    for h in (H, V):
        corner = state(plan, 0, 0, h)
        assert mdp.next_state[corner, UP] == -1 and mdp.next_state[corner, LEFT] == -1
        assert mdp.next_state[state(plan, 1, 0, h), DOWN] == -1  # obstacle below
        assert mdp.next_state[state(plan, 0, 1, h), RIGHT] == -1  # obstacle to the right


def test_several_goals_are_terminal_in_both_headings_and_starts_are_both_headings():
    plan = parse_floor_plan("G.S.G\n")
    mdp = plan.to_mdp()
    assert np.flatnonzero(mdp.terminal).tolist() == [0, 1, 8, 9]
    assert mdp.start_states.tolist() == [4, 5]


# ------------------------------------------------------------------ features
FEATURES = (
    "..>>.\n"
    ".xx.^\n"
    "....G\n"
)


def feature(plan, name, col, row, heading, action):
    mdp = plan.to_mdp()
    return float(mdp.features[state(plan, col, row, heading), action, FEATURE_NAMES.index(name)])


def test_feature_order_and_names():
    assert parse_floor_plan(FEATURES).to_mdp().feature_names == ("length", "restricted", "road")


def test_restricted_is_minus_one_for_a_move_ending_in_a_restricted_cell():
    plan = parse_floor_plan(FEATURES)
    assert feature(plan, "restricted", 0, 1, H, RIGHT) == -1  # entering
    assert feature(plan, "restricted", 1, 1, H, RIGHT) == -1  # moving inside
    assert feature(plan, "restricted", 2, 1, H, RIGHT) == 0  # leaving
    assert feature(plan, "restricted", 1, 0, V, DOWN) == -1  # entering from above
    assert feature(plan, "restricted", 0, 0, H, RIGHT) == 0


def test_road_is_plus_one_along_minus_one_against_zero_across_minus_one_off_road():
    plan = parse_floor_plan(FEATURES)
    assert feature(plan, "road", 1, 0, H, RIGHT) == 1  # onto '>' going right
    assert feature(plan, "road", 2, 0, H, RIGHT) == 1
    assert feature(plan, "road", 4, 0, H, LEFT) == -1  # onto '>' going left
    assert feature(plan, "road", 2, 1, V, UP) == 0  # onto '>' going up: across
    assert feature(plan, "road", 4, 2, V, UP) == 1  # onto '^' going up
    assert feature(plan, "road", 4, 0, V, DOWN) == -1  # onto '^' going down
    assert feature(plan, "road", 3, 1, H, RIGHT) == 0  # onto '^' going right: across
    assert feature(plan, "road", 0, 0, H, RIGHT) == -1  # onto a free cell: off road
    assert feature(plan, "road", 3, 2, H, RIGHT) == -1  # into the goal: off road


def test_length_has_no_bonus_except_into_a_goal():
    plan = parse_floor_plan(FEATURES, goal_bonus=7.0)
    assert feature(plan, "length", 3, 2, H, RIGHT) == -1 + 7.0
    assert feature(plan, "length", 4, 1, H, DOWN) == -2 + 7.0
    assert feature(plan, "length", 0, 2, H, RIGHT) == -1


# --------------------------------------------------------------- floor plans
def test_floor_plan_toml_is_read_and_a_txt_with_world_warehouse_loads_as_a_floor_plan(tmp_path):
    p = write_plan(tmp_path, FEATURES, 'world = "warehouse"\ncell_size = 0.25\ngoal_bonus = 3\n'
                   'gamma = 0.9\ny_up = true\n')
    plan = resolve_world(p)
    assert isinstance(plan, WarehouseMap)
    assert (plan.cell_size, plan.goal_bonus, plan.gamma, plan.y_up) == (0.25, 3.0, 0.9, True)
    assert plan.to_mdp().gamma == 0.9
    zone = write_plan(tmp_path, FEATURES, None, name="zones")
    assert isinstance(resolve_world(zone), ZoneMap)


@pytest.mark.parametrize(("toml", "message"), [
    ('world = "warehouse"\n', "missing setting cell_size"),
    ('world = "warehouse"\ncell_size = 0\n', "cell_size must be a number > 0"),
    ('world = "warehouse"\ncell_size = "1"\n', "setting 'cell_size' must be a number"),
    ('world = "warehouse"\ncell_size = 1\ny_up = 1\n', "'y_up' must be true or false"),
    ('world = "warehouse"\ncell_size = 1\ngamma = 1.5\n', "gamma must be in (0, 1)"),
    ('world = "warehouse"\ncell_size = 1\nspeed = 2\n', "unknown setting 'speed'"),
    ('world = "mars"\ncell_size = 1\n', "unknown world 'mars'"),
    ('world = "warehouse"\ncell_size = [\n', "invalid TOML"),
])
def test_bad_floor_plan_settings_are_one_line_errors_naming_the_toml(tmp_path, toml, message):
    p = write_plan(tmp_path, FEATURES, toml)
    with pytest.raises(InputError, match=r"plan\.toml: .*" + message.replace("(", r"\(").replace(")", r"\)")):
        resolve_world(p)
    assert_input_error(invoke("export-mdp", p, "--out", tmp_path / "m.npz"), "plan.toml", message)


def test_floor_plan_characters_outside_its_legend_are_refused_with_line_and_column(tmp_path):
    p = write_plan(tmp_path, "S..\n.s.\n..G\n")
    assert_input_error(invoke("export-mdp", p, "--out", tmp_path / "m.npz"), "plan.txt:2:2",
                       "unknown map character 's'")


def test_a_floor_plan_without_its_toml_is_refused(tmp_path):
    p = write_plan(tmp_path, SMALL, None)
    with pytest.raises(InputError, match=r"needs plan\.toml beside it"):
        load_floor_plan(p)


def test_zone_commands_refuse_a_floor_plan_with_the_reason(tmp_path):
    from expertise_irl.worlds.zones import load_map

    p = write_plan(tmp_path, SMALL)
    with pytest.raises(InputError, match="world = 'warehouse': not a zone map"):
        load_map(p)


def test_metric_coordinates_y_down_and_y_up():
    down = parse_floor_plan("....\n....\n...G\n", cell_size=0.5)
    col, row = down.cell_of([0.0, 0.49, 0.5, 1.99, 2.0, -0.01], [0.0, 0.0, 0.74, 1.49, 0.0, 0.0])
    assert col.tolist() == [0, 0, 1, 3, 4, -1]
    assert row.tolist() == [0, 0, 1, 2, 0, 0]
    up = parse_floor_plan("....\n....\n...G\n", cell_size=0.5, y_up=True)
    col, row = up.cell_of([0.1, 0.1, 0.1], [0.1, 0.6, 1.4])
    assert row.tolist() == [2, 1, 0]  # y measured up from the bottom edge
    x, y = up.centre_of(np.array([3]), np.array([0]))
    assert (x.tolist(), y.tolist()) == ([1.75], [1.25])


# -------------------------------------------------------------------- archive
def test_archive_holds_state_cell_and_state_heading_and_loads_back(tmp_path):
    plan = parse_floor_plan(FEATURES, gamma=0.9)
    plan.save_npz(tmp_path / "w.npz")
    with np.load(tmp_path / "w.npz") as z:
        assert "state_xy" not in z.files
        assert z["state_cell"].tolist() == plan.state_cells().tolist()
        assert z["state_heading"].tolist() == plan.state_headings().tolist()
    back = TabularMDP.load(tmp_path / "w.npz")
    mdp = plan.to_mdp()
    assert np.array_equal(back.next_state, mdp.next_state)
    assert np.array_equal(back.features, mdp.features)
    assert np.array_equal(back.state_heading, mdp.state_heading)
    assert back.describe_state(1) == "state 1 (cell x=0, y=0, heading v)"


def test_archive_with_a_heading_but_no_cells_is_refused(tmp_path):
    mdp = parse_floor_plan(SMALL).to_mdp()
    np.savez(tmp_path / "bad.npz", next_state=mdp.next_state, features=mdp.features,
             terminal=mdp.terminal, state_heading=mdp.state_heading)
    with pytest.raises(InputError, match="state_heading but no state_cell"):
        TabularMDP.load(tmp_path / "bad.npz")


# --------------------------------------------------------- heading demonstrations
def test_demonstrations_round_trip_with_the_heading_column(tmp_path):
    plan = parse_floor_plan(FEATURES)
    mdp = plan.to_mdp()
    trajs = simulate(mdp, [0.5, 0.2, 0.3], 0.5, 4, np.random.default_rng(3), max_steps=30)
    write_demos_csv(tmp_path / "d.csv", trajs, mdp)
    text = (tmp_path / "d.csv").read_text(encoding="utf-8").splitlines()
    assert text[0] == "episode,step,x,y,heading"
    back = read_demos_csv(tmp_path / "d.csv", mdp)
    assert np.array_equal(back.state, trajs.state) and np.array_equal(back.action, trajs.action)


def test_without_a_heading_column_each_state_takes_the_axis_of_the_move_into_it(tmp_path):
    plan = parse_floor_plan(FEATURES)
    mdp = plan.to_mdp()
    (tmp_path / "d.csv").write_text("episode,step,x,y\n0,0,0,2\n0,1,0,1\n0,2,0,0\n0,3,1,0\n",
                                    encoding="utf-8")
    tr = read_demos_csv(tmp_path / "d.csv", mdp)
    # first state takes the axis of the first move (up: vertical), so that move costs 1
    assert tr.state.tolist() == [state(plan, 0, 2, V), state(plan, 0, 1, V), state(plan, 0, 0, V)]
    assert tr.action.tolist() == [UP, UP, RIGHT]
    assert mdp.features[tr.state, tr.action, 0].tolist() == [-1, -1, -2]


def test_a_heading_column_sets_the_first_state(tmp_path):
    plan = parse_floor_plan(FEATURES)
    mdp = plan.to_mdp()
    (tmp_path / "d.csv").write_text("episode,step,x,y,heading\n0,0,0,2,h\n0,1,0,1,v\n", encoding="utf-8")
    tr = read_demos_csv(tmp_path / "d.csv", mdp)
    assert tr.state.tolist() == [state(plan, 0, 2, H)]
    assert mdp.features[tr.state, tr.action, 0].tolist() == [-2]  # a turn


def test_a_heading_that_contradicts_the_move_is_an_error_naming_the_row(tmp_path):
    p = write_plan(tmp_path, FEATURES)
    demos = tmp_path / "d.csv"
    demos.write_text("episode,step,x,y,heading\n0,0,0,2,v\n0,1,0,1,v\n0,2,1,1,v\n", encoding="utf-8")
    line = assert_input_error(invoke("infer", p, "--demos", demos, "--out", tmp_path / "r.json"),
                              "d.csv:4", "episode 0 step 2", "heading v at cell (x=1, y=1)",
                              "horizontal move")
    assert "Traceback" not in line


def test_a_heading_letter_other_than_h_or_v_is_an_error(tmp_path):
    p = write_plan(tmp_path, FEATURES)
    demos = tmp_path / "d.csv"
    demos.write_text("episode,step,x,y,heading\n0,0,0,2,v\n0,1,0,1,north\n", encoding="utf-8")
    assert_input_error(invoke("infer", p, "--demos", demos, "--out", tmp_path / "r.json"),
                       "d.csv:3", "column 'heading': 'north' is not h (horizontal) or v (vertical)")


# ------------------------------------------------------------------ commands
@pytest.mark.slow
def test_simulate_infer_render_and_export_work_on_a_floor_plan(tmp_path):
    p = write_plan(tmp_path, "S..>>.\n.#x..v\n.....G\n", 'world = "warehouse"\ncell_size = 0.5\n'
                   "gamma = 0.9\n")
    demos = tmp_path / "sim.csv"
    r = invoke("simulate", p, "--theta", "0.6,0.2,0.2", "--beta", "0.3", "--episodes", "5",
               "--out", demos)
    assert r.exit_code == 0, r.output
    assert demos.read_text(encoding="utf-8").startswith("episode,step,x,y,heading\n")
    r = invoke("infer", p, "--demos", demos, "--out", tmp_path / "r.json", "--betas", "paper-real")
    assert r.exit_code == 0, r.output
    r = invoke("render", p, "--demos", demos, "--out", tmp_path / "map.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "map.png").read_bytes()[:8] == PNG_SIGNATURE
    r = invoke("export-mdp", p, "--out", tmp_path / "m.npz")
    assert r.exit_code == 0, r.output
    assert "features length, restricted, road" in r.output
    mdp = TabularMDP.load(tmp_path / "m.npz")
    assert mdp.n_states == 2 * 17
    # the archive reads the same demonstrations as the floor plan
    assert len(read_demos_csv(demos, mdp)) == len(read_demos_csv(demos, resolve_world(p).to_mdp()))


def test_floor_plan_figure_has_green_road_arrows_red_restricted_dark_obstacles_and_goals():
    plan = parse_floor_plan("S>>\n#x^\nG.G\n")
    fig = Figure()
    ax = fig.add_subplot()
    floorplan.draw_floor_plan(ax, plan)
    (q,) = [c for c in ax.collections if c.get_gid() == ROAD_ARROWS_GID]
    assert np.allclose(q.get_facecolor()[0][:3], to_rgb(floorplan.ROAD_COLOR))
    assert sorted(zip(q.X.tolist(), q.Y.tolist(), q.U.tolist(), q.V.tolist(), strict=True)) == [
        (1, 0, 1, 0), (2, 0, 1, 0), (2, 1, 0, -1)]
    img = ax.images[0].get_array()
    assert np.allclose(img[1, 1], to_rgb(floorplan.CELL_COLORS["x"]))
    assert np.allclose(img[1, 0], to_rgb(floorplan.CELL_COLORS["#"]))
    goals = sorted(p.center for p in ax.patches if p.get_gid() == "goal")
    assert goals == [(0, 2), (2, 2)]


def test_an_expert_takes_a_cheapest_path_turning_once():
    plan = parse_floor_plan(SMALL, goal_bonus=0.0)
    mdp = plan.to_mdp()
    tr = simulate(mdp, [1.0, 0.0, 0.0], 0.01, 20, np.random.default_rng(0))
    for states, actions in tr.episodes():
        assert len(actions) == 4  # (0,0) to (2,2) around the obstacle
        headings = mdp.state_heading[mdp.next_state[states, actions]]
        assert int(np.sum(headings[1:] != headings[:-1])) == 1
        assert mdp.features[states, actions, 0].sum() == -5  # three moves along, one turn


def test_the_map_digest_tells_a_floor_plan_from_a_zone_map_with_the_same_cells():
    from expertise_irl.results import map_digest
    from expertise_irl.worlds.zones import parse_map

    text = "S..\n.x.\n..G\n"
    assert map_digest(parse_floor_plan(text)) != map_digest(parse_map(text))
    assert map_digest(parse_floor_plan(text, cell_size=0.5)) != map_digest(parse_floor_plan(text))


def test_an_mdp_heading_must_be_0_or_1_per_state_and_needs_the_cells():
    mdp = parse_floor_plan(SMALL).to_mdp()
    args = {"next_state": mdp.next_state, "features": mdp.features, "terminal": mdp.terminal}
    with pytest.raises(InputError, match=r"state_heading needs the cell of each state"):
        TabularMDP(**args, state_heading=mdp.state_heading)
    with pytest.raises(InputError, match=r"holding 0 \(horizontal\) or 1 \(vertical\)"):
        TabularMDP(**args, state_xy=mdp.state_xy, state_heading=mdp.state_heading * 2)
