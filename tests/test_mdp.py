"""TabularMDP validation and the .npz archive ."""

from __future__ import annotations

import re

import numpy as np
import pytest

from expertise_irl.errors import InputError
from expertise_irl.mdp import DEFAULT_GAMMA, TabularMDP
from expertise_irl.worlds.zones import parse_map

# A 4-state chain 0 -> 1 -> 2 -> 3 (goal); action 1 goes back where it can.
NEXT = np.array([[1, -1], [2, 0], [3, 1], [-1, -1]])
FEATS = np.arange(4 * 2 * 3, dtype=float).reshape(4, 2, 3) / 10
TERM = np.array([False, False, False, True])


def make(**overrides) -> TabularMDP:
    args = {"next_state": NEXT, "features": FEATS, "terminal": TERM}
    args.update(overrides)
    return TabularMDP(**args)


def test_valid_chain():
    mdp = make(gamma=0.9, feature_names=("a", "b", "c"))
    assert (mdp.n_states, mdp.n_actions, mdp.n_features) == (4, 2, 3)
    assert mdp.gamma == 0.9 and mdp.feature_names == ("a", "b", "c")
    assert mdp.next_state.dtype == np.int64 and mdp.features.dtype == np.float64
    np.testing.assert_array_equal(mdp.available, [[1, 0], [1, 1], [1, 1], [0, 0]])
    np.testing.assert_array_equal(mdp.initial_states(), [0, 1, 2])
    assert make().feature_names == ("f0", "f1", "f2")
    assert make().gamma == DEFAULT_GAMMA
    # unavailable entries are zeroed, available ones kept
    np.testing.assert_array_equal(mdp.features[0, 1], 0.0)
    np.testing.assert_array_equal(mdp.features[1], FEATS[1])
    # 0/1 integers are accepted as terminal flags
    assert make(terminal=np.array([0, 0, 0, 1])).terminal.dtype == bool


def _cycle_next():
    ns = NEXT.copy()
    ns[0] = [0, -1]  # state 0 only loops on itself
    return ns


def _stuck_next():
    ns = NEXT.copy()
    ns[1] = [-1, -1]
    return ns


def _out_of_range_next():
    ns = NEXT.copy()
    ns[2, 1] = 4
    return ns


def _nan_feats():
    f = FEATS.copy()
    f[1, 0, 2] = np.nan
    return f


@pytest.mark.parametrize(("overrides", "match"), [
    ({"next_state": NEXT[0]}, r"next_state must have shape \[S, A\]"),
    ({"next_state": NEXT.astype(float)}, "next_state must be integer"),
    ({"next_state": np.zeros((0, 2), dtype=int)}, "non-empty"),
    ({"next_state": _out_of_range_next()}, r"next_state\[2, 1\] = 4 is not a state index"),
    ({"next_state": np.where(NEXT == 1, -2, NEXT)}, r"= -2 is not a state index"),
    ({"features": FEATS[:, :, 0]}, r"features must have shape \[S, A, K\]"),
    ({"features": FEATS[:3]}, r"features must have shape \[S, A, K\] = \[4, 2, K\]"),
    ({"features": np.zeros((4, 2, 0))}, "at least one feature"),
    ({"features": FEATS.astype(complex)}, "real numbers"),
    ({"features": _nan_feats()}, r"features\[1, 0, 2\] is nan"),
    ({"terminal": TERM[:3]}, r"terminal must have shape \[S\]"),
    ({"terminal": np.array([0, 0, 2, 1])}, "terminal must be boolean"),
    ({"terminal": np.zeros(4, dtype=bool)}, "no terminal"),
    ({"next_state": _stuck_next()}, "state 1 has no available action"),
    ({"next_state": _cycle_next()}, r"state 0 cannot reach a terminal \(goal\) state \(1 such"),
    ({"gamma": 1.0}, r"gamma must be in \(0, 1\)"),
    ({"gamma": 0.0}, r"gamma must be in \(0, 1\)"),
    ({"gamma": -0.5}, r"gamma must be in \(0, 1\)"),
    ({"gamma": float("nan")}, r"gamma must be in \(0, 1\)"),
    ({"feature_names": ("a", "b")}, "2 feature names for 3 features"),
    ({"start_states": np.array([[0]])}, "start_states must be a 1-D integer array"),
    ({"start_states": np.array([0.0])}, "start_states must be a 1-D integer array"),
    ({"start_states": np.array([0, 4])}, r"start_states contains an index outside \[0, 4\)"),
    ({"start_states": np.array([-1])}, r"outside \[0, 4\)"),
    ({"start_states": np.array([0, 3])}, "start_states contains a terminal state"),
    ({"state_xy": np.zeros((4, 3), dtype=int)}, r"state_xy must be an integer array of shape \[4, 2\]"),
    ({"state_xy": np.zeros((4, 2))}, "state_xy must be an integer array"),
])
def test_validation_errors(overrides, match):
    with pytest.raises(InputError, match=match):
        make(**overrides)


def test_error_names_source_and_cell():
    xy = np.array([[0, 0], [1, 0], [2, 0], [3, 0]])
    with pytest.raises(InputError, match=r"^mine\.npz: state 1 \(cell x=1, y=0\) has no available"):
        make(next_state=_stuck_next(), state_xy=xy, source="mine.npz")
    with pytest.raises(InputError, match=r"state 0 \(cell x=0, y=0\) cannot reach"):
        make(next_state=_cycle_next(), state_xy=xy)


def test_nan_on_unavailable_action_is_accepted_and_zeroed():
    f = FEATS.copy()
    f[0, 1] = np.nan  # next_state[0, 1] == -1
    f[3] = np.inf  # terminal row with no available action
    mdp = make(features=f)
    np.testing.assert_array_equal(mdp.features[0, 1], 0.0)
    np.testing.assert_array_equal(mdp.features[3], 0.0)
    assert np.all(np.isfinite(mdp.features))


def test_terminal_rows_may_have_actions():
    ns = NEXT.copy()
    ns[3] = [3, 0]  # ignored: the episode ends on entering the goal
    mdp = make(next_state=ns)
    assert not mdp.available[3].any()


def test_arrays_are_read_only_copies():
    ns, f, t = NEXT.copy(), FEATS.copy(), TERM.copy()
    mdp = TabularMDP(ns, f, t, start_states=np.array([0, 1]), state_xy=np.zeros((4, 2), int))
    for arr in (mdp.next_state, mdp.features, mdp.terminal, mdp.start_states, mdp.state_xy):
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr[0] = 0
    ns[0, 0] = 2
    f[0, 0, 0] = 99.0
    assert mdp.next_state[0, 0] == 1 and mdp.features[0, 0, 0] == FEATS[0, 0, 0]
    with pytest.raises(AttributeError):
        mdp.gamma = 0.5  # frozen dataclass


def test_empty_start_states_mean_all():
    mdp = make(start_states=np.array([], dtype=np.int64))
    assert mdp.start_states is None
    np.testing.assert_array_equal(mdp.initial_states(), [0, 1, 2])


# --------------------------------------------------------------------------- archive
ZONES = """
S....xx....
.###.xx.##.
.#>>>>>>>>.
.#...ss...G
.....ss..tt
"""


def at(path, pattern: str) -> str:
    """Regex: a message that starts with ``path: `` and then matches ``pattern``."""
    return "^" + re.escape(str(path)) + ": " + pattern


def _assert_same(a: TabularMDP, b: TabularMDP) -> None:
    for name in ("next_state", "features", "terminal", "start_states", "state_xy"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None:
            assert y is None, name
        else:
            np.testing.assert_array_equal(x, y, err_msg=name)
            assert x.dtype == y.dtype, name
    assert a.gamma == b.gamma
    assert a.feature_names == b.feature_names


@pytest.mark.parametrize("which", ["zones", "chain"])
def test_archive_round_trip(tmp_path, which):
    if which == "zones":
        mdp = parse_map(ZONES, gamma=0.9, goal_bonus=3.0).to_mdp()
        assert mdp.start_states is not None and mdp.state_xy is not None
    else:
        mdp = make(gamma=0.77, feature_names=("length", "road", "x y"))
    path = tmp_path / "m.npz"
    mdp.save(path)
    back = TabularMDP.load(path)
    _assert_same(mdp, back)
    assert back.source == str(path)
    assert not back.features.flags.writeable
    back.save(tmp_path / "again.npz")  # a loaded archive saves again identically
    _assert_same(mdp, TabularMDP.load(str(tmp_path / "again.npz")))


def test_hand_made_minimal_archive(tmp_path):
    path = tmp_path / "min.npz"
    np.savez(path, next_state=NEXT, features=FEATS, terminal=TERM)
    mdp = TabularMDP.load(path)
    assert mdp.gamma == DEFAULT_GAMMA
    assert mdp.feature_names == ("f0", "f1", "f2")
    assert mdp.start_states is None and mdp.state_xy is None


def test_archive_validation_names_path(tmp_path):
    path = tmp_path / "bad.npz"
    np.savez(path, next_state=_stuck_next(), features=FEATS, terminal=TERM)
    with pytest.raises(InputError, match=at(path, r"state 1 has no available action")):
        TabularMDP.load(path)


def test_archive_missing_features(tmp_path):
    path = tmp_path / "nofeat.npz"
    np.savez(path, next_state=NEXT, terminal=TERM)
    with pytest.raises(InputError, match=at(path, r"archive lacks required array\(s\) features")):
        TabularMDP.load(path)


def test_archive_unknown_array(tmp_path):
    path = tmp_path / "extra.npz"
    np.savez(path, next_state=NEXT, features=FEATS, terminal=TERM, rewards=np.zeros(4))
    with pytest.raises(InputError, match=at(path, r"unknown array\(s\) in archive: rewards")):
        TabularMDP.load(path)


def test_archive_bad_gamma(tmp_path):
    path = tmp_path / "g.npz"
    np.savez(path, next_state=NEXT, features=FEATS, terminal=TERM, gamma=np.array([0.9, 0.8]))
    with pytest.raises(InputError, match=at(path, r"gamma must be a single number")):
        TabularMDP.load(path)


def test_non_npz_file(tmp_path):
    path = tmp_path / "map.npz"
    path.write_text("S..G\n")
    with pytest.raises(InputError, match=at(path, r"not a readable \.npz archive")):
        TabularMDP.load(path)
    with pytest.raises(InputError, match=at(tmp_path / "missing.npz", r"no such file")):
        TabularMDP.load(tmp_path / "missing.npz")


def test_pickled_object_array_is_rejected(tmp_path):
    path = tmp_path / "obj.npz"
    np.savez(path, next_state=NEXT, features=FEATS, terminal=TERM,
             feature_names=np.array(["a", None, "c"], dtype=object))
    with pytest.raises(InputError, match=at(path, r"not a readable \.npz archive")):
        TabularMDP.load(path)
