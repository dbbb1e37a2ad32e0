"""Gymnasium adapter: check_env, rewards, refusals, rgb_array rendering, and the recording wrapper."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from expertise_irl.demos.csv_io import read_demos_csv
from expertise_irl.demos.trajectories import validate
from expertise_irl.errors import InputError
from expertise_irl.gym import ENV_ID, RecordTrajectories, ZoneEnv
from expertise_irl.plots.maps import GOAL_COLOR, ZONE_COLORS
from expertise_irl.worlds.zones import parse_map

MAP = """\
S..x.
.#...
...>G
"""


def test_check_env_passes_without_warnings():
    # Made through the registry, so the checker can also try the other render modes.
    for kwargs in ({"zone_map": "crossroads", "render_mode": "rgb_array"},
                   {"zone_map": parse_map(MAP), "max_steps": 5}):
        env = gymnasium.make(ENV_ID, **kwargs).unwrapped
        assert isinstance(env, ZoneEnv)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # any complaint of the checker fails the test
            check_env(env, skip_render_check=False)


def test_registered_and_made_by_id():
    env = gymnasium.make(ENV_ID, zone_map="corridor")
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and info["xy"] == (0, 0)  # corridor's only start


def test_moves_rewards_and_refusals():
    zm = parse_map(MAP, name="m")
    theta = np.array([1.0, 0.5, 2.0, 0.0, 0.0])
    env = ZoneEnv(zm, theta)
    mdp = env.mdp
    s, info = env.reset(seed=1)
    assert info["xy"] == (0, 0) and info["action_mask"].tolist() == [0, 1, 0, 1]
    obs, r, term, trunc, info = env.step(0)  # up, off the map
    assert obs == s and r == 0.0 and info["refused"] and not term and not trunc
    obs, r, term, trunc, info = env.step(3)  # right
    assert r == pytest.approx(theta @ mdp.features[s, 3]) and info["xy"] == (1, 0) and not info["refused"]
    np.testing.assert_array_equal(info["features"], mdp.features[s, 3])
    env.reset(options={"start_xy": (2, 2)})
    road, _, _, _, _ = env.step(3)  # onto the road, along it
    obs, r, term, trunc, _ = env.step(3)  # into the goal
    assert term and not trunc and mdp.terminal[obs]
    assert r == pytest.approx(theta @ mdp.features[road, 3])
    assert mdp.features[road, 3, 0] == 9.0  # a move (-1) plus the goal bonus (10)
    with pytest.raises(InputError, match="not a free cell"):
        env.reset(options={"start_xy": (1, 1)})
    with pytest.raises(InputError, match="unknown reset option"):
        env.reset(options={"path": "/etc"})


def test_truncation_after_max_steps():
    env = ZoneEnv(parse_map(MAP), max_steps=2)
    env.reset(options={"start_xy": (0, 0)})
    assert not env.step(1)[3]
    assert not env.step(3)[3] and env.step(3)[4]["refused"]  # (1, 1) is an obstacle: not a move
    assert env.step(1)[3]  # the second accepted move


def test_rgb_array_shows_the_map_and_the_agent():
    env = ZoneEnv(parse_map(MAP), render_mode="rgb_array", cell_px=10)
    env.reset(options={"start_xy": (0, 0)})
    img = env.render()
    assert img.shape == (30, 50, 3) and img.dtype == np.uint8
    red = (np.array(__import__("matplotlib.colors").colors.to_rgb(ZONE_COLORS["x"])) * 255).round()
    green = (np.array(__import__("matplotlib.colors").colors.to_rgb(GOAL_COLOR)) * 255).round()
    np.testing.assert_array_equal(img[2, 32], red)  # the avoid cell (3, 0), off its grid line
    np.testing.assert_array_equal(img[25, 45], green)  # the goal's disc at the centre of (4, 2)
    agent_before = img[5, 5].copy()
    env.step(3)
    after = env.render()
    assert not np.array_equal(after[5, 15], img[5, 15])  # the agent moved into (1, 0)
    assert not np.array_equal(after[5, 5], agent_before)  # and left a path dot, not itself
    assert ZoneEnv(parse_map(MAP)).render() is None


def test_recording_wrapper_feeds_the_library(tmp_path):
    from expertise_irl.hypotheses import BETA_PRESETS, HypothesisSet, theta_grid
    from expertise_irl.inference.belief import DiscreteBelief

    env = RecordTrajectories(ZoneEnv("crossroads", max_steps=40))
    rng = np.random.default_rng(0)
    accepted = []
    for ep in range(3):
        obs, _ = env.reset(seed=ep)
        pairs = []
        while True:
            a = int(rng.integers(4))
            nxt, _, term, trunc, info = env.step(a)
            if not info["refused"]:
                pairs.append((obs, a))
            obs = nxt
            if term or trunc:
                break
        accepted.append(pairs)
    env.reset()  # an empty episode is not kept
    t = env.trajectories()
    assert t.n_episodes == 3
    assert [list(zip(s.tolist(), a.tolist(), strict=True)) for s, a in t.episodes()] == accepted
    validate(t, env.mdp)
    env.write_csv(tmp_path / "demos.csv")
    back = read_demos_csv(tmp_path / "demos.csv", env.mdp)
    np.testing.assert_array_equal(back.action, t.action)
    hyp = HypothesisSet(theta_grid((0.0, 1.0), 5), BETA_PRESETS["paper-sim"])
    post = DiscreteBelief.from_mdp(env.mdp, hyp).update(back)
    assert post.mean_beta > 1  # a uniformly random walker looks like a low-expertise person
    with pytest.raises(InputError, match="wraps a ZoneEnv"):
        RecordTrajectories(gymnasium.make("CartPole-v1"))
