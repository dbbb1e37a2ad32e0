"""Tests for demos/: the simulated person, validation and the CSV formats."""

from __future__ import annotations

import numpy as np
import pytest

from expertise_irl.demos.csv_io import read_demos_csv, write_demos_csv
from expertise_irl.demos.simulation import DEFAULT_MAX_STEPS, best_move, cap_note, episode_outcomes, simulate
from expertise_irl.demos.trajectories import Trajectories, validate
from expertise_irl.errors import InputError
from expertise_irl.mdp import TabularMDP
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.zones import load_bundled, parse_map

# Small map for the CSV error cases. States, row-major:
#   0 (0,0) S   1 (1,0)     2 (3,0)
#   3 (0,1)     4 (1,1)     5 (3,1) G
#   6 (0,2)     7 (1,2)     8 (2,2)   9 (3,2)
SMALL = """
S.#.
..#G
....
"""
# A corridor with a single shortest path from S: right 4, down 2, left 4.
DETOUR = """
S....
####.
G....
"""
THETA = np.array([1.0, 0.5, 0.5, 0.5, 0.5])
UP, DOWN, LEFT, RIGHT = range(4)


@pytest.fixture(scope="module")
def small():
    return parse_map(SMALL, name="small").to_mdp()


@pytest.fixture(scope="module")
def crossroads():
    return load_bundled("crossroads").to_mdp()


def state_at(mdp: TabularMDP, x: int, y: int) -> int:
    return int(np.flatnonzero((mdp.state_xy[:, 0] == x) & (mdp.state_xy[:, 1] == y))[0])


def as_tuple(t: Trajectories):
    return t.episode.tolist(), t.step.tolist(), t.state.tolist(), t.action.tolist()


def without_grid(mdp: TabularMDP) -> TabularMDP:
    return TabularMDP(mdp.next_state, mdp.features, mdp.terminal, gamma=mdp.gamma)


# ------------------------------------------------------------------------- simulation
def test_same_seed_same_output_different_seed_different(crossroads):
    a = simulate(crossroads, THETA, 1.0, 20, np.random.default_rng(7))
    b = simulate(crossroads, THETA, 1.0, 20, np.random.default_rng(7))
    c = simulate(crossroads, THETA, 1.0, 20, np.random.default_rng(8))
    assert as_tuple(a) == as_tuple(b)
    assert as_tuple(a) != as_tuple(c)


def test_labels_and_steps(crossroads):
    t = simulate(crossroads, THETA, 1.0, 12, np.random.default_rng(0))
    assert t.episode_ids.tolist() == list(range(12))
    for e in range(12):
        assert t.step[t.episode == e].tolist() == list(range(int((t.episode == e).sum())))


def test_episodes_end_at_terminal_or_max_steps(crossroads):
    max_steps = 15
    t = simulate(crossroads, THETA, 1.0, 300, np.random.default_rng(1), max_steps=max_steps)
    assert DEFAULT_MAX_STEPS == 500
    assert not crossroads.terminal[t.state].any()  # nobody acts from the goal
    ended = truncated = 0
    for states, actions in t.episodes():
        assert 1 <= len(states) <= max_steps
        if crossroads.terminal[crossroads.next_state[states[-1], actions[-1]]]:
            ended += 1
        else:
            assert len(states) == max_steps
            truncated += 1
    assert ended > 0 and truncated > 0  # both ways of ending actually happened


def test_every_simulated_transition_is_valid(crossroads):
    t = simulate(crossroads, THETA, 3.0, 100, np.random.default_rng(2))
    nxt = crossroads.next_state[t.state, t.action]
    assert (nxt >= 0).all()
    same = t.episode[1:] == t.episode[:-1]
    assert (nxt[:-1][same] == t.state[1:][same]).all()
    validate(t, crossroads)


def test_tiny_beta_follows_the_shortest_path():
    mdp = parse_map(DETOUR).to_mdp()
    theta = np.array([1.0, 0, 0, 0, 0])
    t = simulate(mdp, theta, 1e-3, 20, np.random.default_rng(3))
    moves = [RIGHT] * 4 + [DOWN] * 2 + [LEFT] * 4
    for states, actions in t.episodes():
        assert actions.tolist() == moves
        assert states[0] == state_at(mdp, 0, 0)
    # The check has teeth: a less expert person sometimes strays from that path.
    noisy = simulate(mdp, theta, 5.0, 20, np.random.default_rng(3))
    assert any(a.tolist() != moves for _, a in noisy.episodes())


def test_action_frequencies_match_the_policy(crossroads):
    beta = 2.0
    pi = solve(crossroads, THETA, beta).policy[0]
    # The non-terminal state whose policy has the most entropy, so every action is tested.
    ent = -np.sum(np.where(pi > 0, pi * np.log(np.where(pi > 0, pi, 1)), 0), axis=1)
    s0 = int(np.argmax(np.where(crossroads.terminal, -1, ent)))
    p = pi[s0]
    assert (p[p > 0] > 0.05).all()
    n = 4000
    t = simulate(crossroads, THETA, beta, n, np.random.default_rng(4), starts=[s0], max_steps=1)
    assert len(t) == n and (t.state == s0).all()
    freq = np.bincount(t.action, minlength=crossroads.n_actions) / n
    # Step-0 actions are n iid draws from pi(.|s0), so each frequency is binomial with
    # standard error sqrt(p(1-p)/n) (<= 0.008 here); 5 standard errors is a
    # two-sided miss probability below 1e-6 per action.
    se = np.sqrt(p * (1 - p) / n)
    assert np.all(np.abs(freq - p) <= 5 * se + 1e-12)


def test_start_states(small, crossroads):
    t = simulate(small, THETA, 1.0, 50, np.random.default_rng(5))
    first = t.state[t.step == 0]
    assert (first == state_at(small, 0, 0)).all()  # the map's S cell
    # crossroads has no S cell: every non-terminal state is a possible start.
    assert crossroads.start_states is None
    t = simulate(crossroads, THETA, 1.0, 200, np.random.default_rng(5), max_steps=1)
    assert not crossroads.terminal[t.state].any()
    assert len(np.unique(t.state)) > 50
    starts = np.array([state_at(small, 3, 2), state_at(small, 1, 1)])
    t = simulate(small, THETA, 1.0, 100, np.random.default_rng(5), starts=starts)
    first = t.state[t.step == 0]
    assert set(first.tolist()) == set(starts.tolist())


@pytest.mark.parametrize(
    ("starts", "fragment"),
    [([5], "terminal"), ([10], "not a state index"), ([-1], "not a state index"), ([], "non-empty")],
)
def test_bad_starts(small, starts, fragment):
    with pytest.raises(InputError, match=fragment):
        simulate(small, THETA, 1.0, 3, np.random.default_rng(0), starts=np.array(starts, dtype=int))


@pytest.mark.parametrize(
    ("theta", "beta"),
    [
        ([1.0, -0.1, 0, 0, 0], 1.0),
        ([1.0, np.nan, 0, 0, 0], 1.0),
        ([1.0, 0, 0, 0], 1.0),
        (THETA, 0.0),
        (THETA, -1.0),
        (THETA, np.inf),
    ],
)
def test_bad_hypothesis(small, theta, beta):
    with pytest.raises(InputError):
        simulate(small, theta, beta, 3, np.random.default_rng(0))


def test_theta_is_used_as_given(crossroads):
    # Scaling θ changes the policy (it is not normalised): (2θ, β) acts like (θ, β/2).
    a = simulate(crossroads, 2 * THETA, 1.0, 30, np.random.default_rng(6))
    b = simulate(crossroads, THETA, 0.5, 30, np.random.default_rng(6))
    c = simulate(crossroads, THETA, 1.0, 30, np.random.default_rng(6))
    assert as_tuple(a) == as_tuple(b)
    assert as_tuple(a) != as_tuple(c)


def test_given_log_policy(small):
    # Always move right where possible, else down, else up (deterministic policy).
    lp = np.full((small.n_states, small.n_actions), -np.inf)
    for s in np.flatnonzero(~small.terminal):
        for a in (RIGHT, DOWN, UP):
            if small.available[s, a]:
                lp[s, a] = 0.0
                break
    t = simulate(small, None, None, 3, np.random.default_rng(0), log_policy=lp)
    assert t.paths(small)[0].tolist() == [0, 1, 4, 7, 8, 9, 5]
    bad = lp.copy()
    bad[0, LEFT] = 0.0  # mass on a move off the grid
    with pytest.raises(InputError, match="unavailable"):
        simulate(small, None, None, 3, np.random.default_rng(0), log_policy=bad)


def test_zero_episodes_and_bad_counts(small):
    assert len(simulate(small, THETA, 1.0, 0, np.random.default_rng(0))) == 0
    with pytest.raises(InputError, match="n_episodes"):
        simulate(small, THETA, 1.0, -1, np.random.default_rng(0))
    with pytest.raises(InputError, match="max_steps"):
        simulate(small, THETA, 1.0, 2, np.random.default_rng(0), max_steps=0)


# ------------------------------------------------------------------------- validate()
def test_validate_arrays_names_episode_and_step(small):
    # episode 3: state 3 up -> state 0, then left from state 0 walks off the grid.
    t = Trajectories([3, 3], [0, 1], [3, 0], [UP, LEFT])
    with pytest.raises(InputError) as exc:
        validate(t, small)
    assert str(exc.value) == (
        "episode 3 step 1: action 2 (left) is not available in state 0 (cell x=0, y=0)"
    )
    with pytest.raises(InputError, match=r"^mine: episode 3 step 1: "):
        validate(t, small, source="mine")
    with pytest.raises(InputError, match="episode 0 step 2: step 2 follows step 0"):
        validate(Trajectories([0, 0], [0, 2], [3, 0], [UP, DOWN]), small)
    with pytest.raises(InputError, match="no demonstrations to write"):
        write_demos_csv("unused.csv", Trajectories([], [], [], []), small)


def test_writer_validates_first(small, tmp_path):
    t = Trajectories([0], [0], [0], [LEFT])
    with pytest.raises(InputError, match="not available"):
        write_demos_csv(tmp_path / "d.csv", t, small)
    assert not (tmp_path / "d.csv").exists()


# ------------------------------------------------------------------------- CSV round trip
@pytest.mark.parametrize("fmt", ["grid", "state", "auto"])
def test_csv_round_trip_grid_map(crossroads, tmp_path, fmt):
    t = simulate(crossroads, THETA, 1.0, 15, np.random.default_rng(9), max_steps=30)
    path = tmp_path / "demos.csv"
    write_demos_csv(path, t, crossroads, fmt=fmt)
    header = path.read_text().splitlines()[0]
    assert header == ("episode,step,state,action" if fmt == "state" else "episode,step,x,y")
    n_rows = len(path.read_text().splitlines()) - 1
    assert n_rows == len(t) + (t.n_episodes if fmt != "state" else 0)  # grid adds final cells
    assert as_tuple(read_demos_csv(path, crossroads)) == as_tuple(t)


def test_csv_round_trip_generic_mdp(crossroads, tmp_path):
    mdp = without_grid(crossroads)
    t = simulate(mdp, THETA, 1.0, 10, np.random.default_rng(10))
    path = tmp_path / "demos.csv"
    write_demos_csv(path, t, mdp)  # auto: no cells, so the generic format
    assert path.read_text().startswith("episode,step,state,action\n")
    assert as_tuple(read_demos_csv(path, mdp)) == as_tuple(t)
    with pytest.raises(InputError, match="grid format"):
        write_demos_csv(path, t, mdp, fmt="grid")


def test_csv_keeps_labels_and_file_order(small, tmp_path):
    path = tmp_path / "demos.csv"
    path.write_text("episode,step,state,action\n7,0,3,0\n2,0,6,3\n2,1,7,3\n")
    t = read_demos_csv(path, small)
    assert as_tuple(t) == ([7, 2, 2], [0, 0, 1], [3, 6, 7], [UP, RIGHT, RIGHT])


def test_csv_tolerates_whitespace_crlf_bom_and_blank_lines(small, tmp_path):
    path = tmp_path / "demos.csv"
    text = "\ufeff Episode , step, x ,y \r\n 0, 0, 0, 0\r\n\r\n0,1,0,1 \r\n0, 2,0,2\r\n\r\n"
    path.write_bytes(text.encode("utf-8"))
    t = read_demos_csv(path, small)
    assert as_tuple(t) == ([0, 0], [0, 1], [0, 3], [DOWN, DOWN])
    path.write_text("episode,step,state,action\n0,0.0,3,0\n")  # integral floats are integers
    assert as_tuple(read_demos_csv(path, small)) == ([0], [0], [3], [UP])


# ------------------------------------------------------------------------- CSV errors
def demo_file(tmp_path, text: str):
    path = tmp_path / "demos.csv"
    path.write_text(text)
    return path


def check_error(path, mdp, line, *fragments):
    with pytest.raises(InputError) as exc:
        read_demos_csv(path, mdp)
    msg = str(exc.value)
    assert "\n" not in msg
    prefix = f"demos.csv:{line}: " if line is not None else "demos.csv: "
    assert prefix in msg, msg
    for f in fragments:
        assert f in msg, msg


STATE = "episode,step,state,action\n"
GRID = "episode,step,x,y\n"


@pytest.mark.parametrize(
    ("text", "line", "fragments"),
    [
        ("", None, ["no demonstrations"]),
        ("\n\n", None, ["no demonstrations"]),
        (STATE, 1, ["no demonstrations"]),
        ("episode,step,state\n0,0,0\n", 1, ["missing column(s) action", "episode,step,state,action"]),
        ("ep,step,x,y\n0,0,0,0\n", 1, ["missing column(s) episode"]),
        ("episode,step,state,state,action\n0,0,0,0,1\n", 1, ["'state' appears more than once"]),
        (STATE + "0,0,99999999999999999999999,1\n", 2, ["column 'state'", "out of range"]),
        (STATE + "0,0,1e300,1\n", 2, ["column 'state'", "out of range"]),
        ("0,0,0,1\n", 1, ["missing header"]),
        (STATE + "0,0,3,0\n0,1,0\n", 3, ["3 fields, expected 4"]),
        (STATE + "0,0,3,0\n0,1,0,1,\n", 3, ["5 fields, expected 4"]),
        (STATE + "0,1,0,1\n", 2, ["sort the file by episode, then step"]),
        (STATE + "0,0,abc,1\n", 2, ["column 'state'", "'abc' is not a number"]),
        (STATE + "0,0,,1\n", 2, ["column 'state' is empty"]),
        (STATE + "0,1.5,0,1\n", 2, ["column 'step'", "'1.5' is not an integer"]),
        (GRID + "0,0,0,0\n0,1,x1,0\n", 3, ["column 'x'", "not a number"]),
        (STATE + "0,0,0,1\n0,2,3,1\n", 3, ["episode 0 step 2", "step 2 follows step 0"]),
        (STATE + "0,1,0,1\n", 2, ["episode 0 step 1", "starts at step 1, expected step 0"]),
        (STATE + "0,0,3,1\n1,0,0,1\n0,1,6,3\n", 4, ["episode 0 step 1", "contiguous"]),
        (STATE + "0,0,3,1\n\n1,0,10,1\n", 4, ["episode 1 step 0", "state 10 is out of range"]),
        (STATE + "0,0,-1,1\n", 2, ["state -1 is out of range"]),
        (STATE + "0,0,0,4\n", 2, ["action 4 is out of range"]),
        (
            STATE + "3,0,3,0\n3,1,0,2\n",
            3,
            ["episode 3 step 1: action 2 (left) is not available in state 0 (cell x=0, y=0)"],
        ),
        (
            STATE + "0,0,0,1\n0,1,4,1\n",
            3,
            [
                "episode 0 step 1: state 4 (cell x=1, y=1) does not follow from state 0 "
                "(cell x=0, y=0) by action 1 (down): expected state 3 (cell x=0, y=1)"
            ],
        ),
        (STATE + "0,0,2,1\n0,1,5,1\n", 3, ["episode 0 step 1", "state 5 (cell x=3, y=1)", "terminal"]),
        (GRID + "0,0,3,0\n0,1,4,0\n", 3, ["cell (x=4, y=0) is outside the map"]),
        (GRID + "0,0,0,-1\n0,1,0,0\n", 2, ["cell (x=0, y=-1) is outside the map"]),
        (GRID + "0,0,1,0\n0,1,2,0\n", 3, ["episode 0 step 1", "cell (x=2, y=0) is an obstacle"]),
        (GRID + "0,0,0,0\n0,1,0,1\n0,2,0,3\n", 4, ["outside the map"]),
        (GRID + "0,0,0,0\n0,1,0,1\n0,2,2,1\n", 4, ["episode 0 step 2", "obstacle"]),
        (GRID + "0,0,0,0\n0,1,0,1\n0,2,1,2\n", 4, ["jumps from (0,1) to (1,2)"]),
        (GRID + "0,0,0,2\n0,1,2,2\n", 3, ["jumps from (0,2) to (2,2)"]),
        (GRID + "0,0,0,0\n0,1,0,0\n", 3, ["cell (x=0, y=0) repeats the previous cell"]),
        (GRID + "0,0,0,0\n0,1,0,1\n1,0,1,2\n", 4, ["episode 1 step 0", "single cell"]),
        (
            GRID + "0,0,3,2\n0,1,3,1\n0,2,3,2\n",
            4,
            ["episode 0 step 2", "acts from state 5 (cell x=3, y=1), which is terminal"],
        ),
        (GRID + "0,0,0,0\n0,2,0,1\n", 3, ["step 2 follows step 0"]),
        # An episode that starts in the goal is blamed on its first row, step 0, in both formats.
        (STATE + "0,0,5,0\n", 2, ["episode 0 step 0: starts in state 5 (cell x=3, y=1)", "terminal"]),
        (GRID + "0,0,3,1\n0,1,3,2\n", 2, ["episode 0 step 0: starts in state 5 (cell x=3, y=1)"]),
        (
            STATE + "0,0,3,0\n1,0,5,0\n",
            3,
            ["episode 1 step 0: starts in state 5 (cell x=3, y=1)", "must start outside every goal"],
        ),
    ],
)
def test_csv_errors(small, tmp_path, text, line, fragments):
    check_error(demo_file(tmp_path, text), small, line, *fragments)


def test_csv_error_missing_file(small, tmp_path):
    check_error(tmp_path / "demos.csv", small, None, "no such file")


def test_csv_error_grid_format_needs_a_grid(small, tmp_path):
    path = demo_file(tmp_path, GRID + "0,0,0,0\n0,1,0,1\n")
    check_error(path, without_grid(small), None, "grid format", "episode,step,state,action")


def test_csv_error_line_numbers_count_crlf_and_blank_lines(small, tmp_path):
    path = tmp_path / "demos.csv"
    path.write_bytes(b"episode,step,state,action\r\n\r\n0,0,3,0\r\n\r\n0,1,0,2\r\n")
    check_error(path, small, 5, "episode 0 step 1", "action 2 (left) is not available")


def test_columns_are_found_by_name_and_extra_columns_ignored(tmp_path):
    """A recording exported with its columns in another order, plus a timestamp, reads the same."""
    mdp = parse_map("S..\n.#G\n").to_mdp()
    plain = tmp_path / "plain.csv"
    plain.write_text("episode,step,x,y\n0,0,0,0\n0,1,1,0\n0,2,2,0\n0,3,2,1\n")
    shuffled = tmp_path / "shuffled.csv"
    shuffled.write_text(
        "t,y,x,step,episode\n0.0,0,0,0,0\n1.0,0,1,1,0\n2.0,0,2,2,0\n3.0,1,2,3,0\n"
    )
    a, b = read_demos_csv(plain, mdp), read_demos_csv(shuffled, mdp)
    for k in ("episode", "step", "state", "action"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert a.action.tolist() == [3, 3, 1]  # right, right, down


def test_simulate_accepts_an_integer_seed():
    mdp = parse_map("S..\n.#G\n").to_mdp()
    a = simulate(mdp, [1, 0, 0, 0, 0], 0.5, 5, 7)
    b = simulate(mdp, [1, 0, 0, 0, 0], 0.5, 5, np.random.default_rng(7))
    np.testing.assert_array_equal(a.action, b.action)
    with pytest.raises(InputError, match="seed"):
        simulate(mdp, [1, 0, 0, 0, 0], 0.5, 5, -1)


# ------------------------------------------------------------------ episode outcomes
def test_episode_outcomes_goal_cap_and_cut():
    zm = parse_map("S..\n.#G\n")
    mdp = zm.to_mdp()
    idx = zm.state_index()
    trajs = Trajectories(
        episode=[0, 0, 0, 1, 1, 1, 2],
        step=[0, 1, 2, 0, 1, 2, 0],
        state=[idx[0, 0], idx[0, 1], idx[0, 2], idx[0, 0], idx[0, 1], idx[0, 0], idx[0, 0]],
        action=[RIGHT, RIGHT, DOWN, RIGHT, LEFT, RIGHT, DOWN],
    )
    assert episode_outcomes(trajs, mdp, 3) == ["goal", "cap", "cut"]
    assert episode_outcomes(trajs, mdp, None) == ["goal", "cut", "cut"]


def test_cap_note_names_paying_moves_and_entropy():
    assert cap_note(["goal", "cut"], 500, 10.0) is None
    note = cap_note(["cap", "goal"], 500, 0.01, (0.14, "road"))
    assert note.startswith("1 of 2 episodes hit the 500-step cap")
    assert "from road" in note and "entropy" not in note  # an expert: the road pays
    note = cap_note(["cap"], 200, 10.0, (-0.2, "length"))
    assert "200-step cap" in note and "entropy" in note and "from length" not in note


def test_cap_note_without_the_entropy_bonus():
    note = cap_note(["cap"], 500, 10.0, (-0.2, "length"), model="boltzmann")
    assert "entropy" not in note and "boltzmann" in note


def test_best_move_is_the_largest_reward_short_of_the_goal():
    mdp = parse_map("S>.\n.#G\n").to_mdp()  # one road cell, whose entering move pays +1 under θ = road
    assert best_move(mdp, [0, 1, 0, 0, 0]) == (1.0, "road")
    assert best_move(mdp, [1, 0, 0, 0, 0])[0] == -1.0  # every move costs one step of length
