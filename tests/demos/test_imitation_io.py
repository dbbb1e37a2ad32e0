"""demos/imitation_io.py: demonstrations to and from imitation's Trajectory, and the arrival chain
that MCE IRL runs on.

imitation cannot share this package's environment (it requires gymnasium~=0.29, we gymnasium>=1.0),
so these tests convert with :class:`Trajectory` below, a copy of ``imitation.data.types.Trajectory``
1.0.1: the same four fields, and the same checks on construction. The conversion only calls the
class with those four keywords and reads the fields back by name, so what is tested here is what
runs with imitation's class. With imitation's environment at hand (``EXPERTISE_IRL_IMITATION_PYTHON``
or /tmp/imitation-venv, docs/vs-imitation.md), the last test also runs the round trip with the real
class there.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.special import logsumexp

from expertise_irl.demos.imitation_io import (
    DEAD_REWARD,
    arrival_chain,
    final_states,
    from_imitation,
    tabular_pomdp,
    to_imitation,
)
from expertise_irl.demos.simulation import simulate
from expertise_irl.demos.trajectories import Trajectories
from expertise_irl.errors import InputError
from expertise_irl.planning.soft_vi import solve
from expertise_irl.worlds.zones import load_bundled, parse_map

ROOT = Path(__file__).resolve().parents[2]
THETA = np.array([0.4, 0.3, 0.1, 0.1, 0.1])


@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory:
    """imitation 1.0.1's ``imitation.data.types.Trajectory``: its fields and its ``__post_init__``."""

    obs: np.ndarray
    acts: np.ndarray
    infos: np.ndarray | None
    terminal: bool

    def __len__(self) -> int:
        return len(self.acts)

    def __post_init__(self):
        if len(self.obs) != len(self.acts) + 1:
            raise ValueError("expected one more observations than actions: "
                             f"{len(self.obs)} != {len(self.acts)} + 1")
        if self.infos is not None and len(self.infos) != len(self.acts):
            raise ValueError(f"infos when present must be present for each action: {len(self.infos)} != "
                             f"{len(self.acts)}")
        if len(self.acts) == 0:
            raise ValueError("Degenerate trajectory: must have at least one action.")


@pytest.fixture(scope="module")
def crossroads():
    return load_bundled("crossroads").to_mdp()


@pytest.fixture(scope="module")
def corridor():
    return load_bundled("corridor").to_mdp()


@pytest.fixture(scope="module")
def demos(crossroads):
    """Episodes that reach the goal (an expert) and episodes cut at the step cap (a wanderer),
    labelled 7, 3, 10, … so that labels are not positions."""
    a = simulate(crossroads, THETA, 0.05, 3, np.random.default_rng(1))
    b = simulate(crossroads, THETA, 5.0, 2, np.random.default_rng(2), max_steps=40)
    labels = np.array([7, 3, 10, 4, 0])
    parts = [(a, 0), (b, 3)]
    ep = np.concatenate([labels[off + t.episode] for t, off in parts])
    rest = (np.concatenate([getattr(t, k) for t, _ in parts]) for k in ("step", "state", "action"))
    return Trajectories(ep, *rest)


def same(a: Trajectories, b: Trajectories) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("episode", "step", "state", "action"))


# ------------------------------------------------------------------------------ the mapping
def test_one_hot_mapping_is_as_documented(crossroads, demos):
    out = to_imitation(demos, crossroads, trajectory_cls=Trajectory)
    assert len(out) == demos.n_episodes == 5
    finals = final_states(demos, crossroads)
    for tr, (states, actions), final in zip(out, demos.episodes(), finals, strict=True):
        assert isinstance(tr, Trajectory)
        assert tr.obs.shape == (states.size + 1, crossroads.n_states) and tr.obs.dtype == np.float32
        assert np.all(tr.obs.sum(axis=1) == 1) and set(np.unique(tr.obs)) == {0.0, 1.0}
        assert np.array_equal(np.argmax(tr.obs, axis=1), np.append(states, final))
        assert final == crossroads.next_state[states[-1], actions[-1]]  # the last action's successor
        assert np.array_equal(tr.acts, actions) and tr.acts.dtype == np.int64  # indices unchanged
        assert tr.infos is None
        assert tr.terminal is bool(crossroads.terminal[final])
    assert [t.terminal for t in out] == [True, True, True, False, False]  # the expert ends, the cut ones not


@pytest.mark.parametrize("observations", ["one-hot", "index"])
def test_round_trip_is_exact(crossroads, demos, observations):
    out = to_imitation(demos, crossroads, observations=observations, trajectory_cls=Trajectory)
    if observations == "index":
        assert all(t.obs.ndim == 1 and t.obs.dtype == np.int64 for t in out)
    back = from_imitation(out, crossroads, episode_ids=demos.episode_ids)
    assert same(back, demos)
    # without labels: the episodes numbered in order, everything else the same
    plain = from_imitation(out, crossroads)
    assert plain.episode_ids.tolist() == list(range(5))
    assert np.array_equal(plain.state, demos.state) and np.array_equal(plain.action, demos.action)
    assert np.array_equal(plain.step, demos.step)


def test_reads_any_object_with_the_fields_and_ignores_rewards(crossroads, demos):
    @dataclasses.dataclass(frozen=True)
    class WithRew(Trajectory):
        rews: np.ndarray | None = None

    out = to_imitation(demos, crossroads, trajectory_cls=Trajectory)
    with_rew = [WithRew(t.obs, t.acts, t.infos, t.terminal, np.zeros(len(t.acts))) for t in out]
    assert same(from_imitation(with_rew, crossroads, episode_ids=demos.episode_ids), demos)


def test_without_imitation_a_clear_error(crossroads, demos, monkeypatch):
    monkeypatch.setitem(sys.modules, "imitation", None)  # import imitation raises ImportError
    monkeypatch.setitem(sys.modules, "seals", None)
    with pytest.raises(InputError, match=r"pip install imitation .*gymnasium~=0\.29.*trajectory_cls"):
        to_imitation(demos, crossroads)
    with pytest.raises(InputError, match="pip install imitation"):
        tabular_pomdp(arrival_chain(crossroads, 5))


def test_the_module_does_not_import_imitation_or_torch():
    code = ("import sys, expertise_irl.demos.imitation_io; "
            "assert not {'imitation', 'torch', 'seals', 'jax'} & set(sys.modules), sys.modules.keys()")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_bad_observations_option(crossroads, demos):
    with pytest.raises(InputError, match="observations must be one of one-hot, index"):
        to_imitation(demos, crossroads, observations="onehot", trajectory_cls=Trajectory)


# ---------------------------------------------------------------------- from_imitation's checks
def one(crossroads, demos, **changes):
    tr = to_imitation(demos, crossroads, trajectory_cls=Trajectory)[0]
    return dataclasses.replace(tr, **changes)


def test_refuses_what_is_not_our_demonstration(crossroads, demos):
    tr = one(crossroads, demos)
    two_hot = tr.obs.copy()
    two_hot[1, 0] = 1.0
    with pytest.raises(InputError, match="trajectory 0: observation 1 is not one-hot"):
        from_imitation([dataclasses.replace(tr, obs=two_hot)], crossroads)
    with pytest.raises(InputError, match="one-hot observations must have 185 columns"):
        from_imitation([dataclasses.replace(tr, obs=tr.obs[:, :-1])], crossroads)
    idx = np.argmax(tr.obs, axis=1)
    wrong_final = idx.copy()
    wrong_final[-1] = idx[0]
    with pytest.raises(InputError, match="the final observation is state"):
        from_imitation([dataclasses.replace(tr, obs=wrong_final)], crossroads)
    with pytest.raises(InputError, match="terminal=False but it ends in a goal"):
        from_imitation([dataclasses.replace(tr, terminal=False)], crossroads)
    cut = to_imitation(demos, crossroads, trajectory_cls=Trajectory)[-1]
    with pytest.raises(InputError, match="terminal=True but it ends in state"):
        from_imitation([dataclasses.replace(cut, terminal=True)], crossroads)
    far = np.where(np.arange(idx.size) == 2, 999, idx)
    with pytest.raises(InputError, match=r"observation 2 is state 999, outside 0\.\.184"):
        from_imitation([dataclasses.replace(tr, obs=far)], crossroads)
    jump = idx.copy()
    jump[2] = jump[0] if jump[0] != jump[2] else jump[1]
    with pytest.raises(InputError, match="does not follow from"):
        from_imitation([dataclasses.replace(tr, obs=jump)], crossroads)
    with pytest.raises(InputError, match="has no field 'obs'"):
        from_imitation([object()], crossroads)
    with pytest.raises(InputError, match="2 episode ids for 1 trajectories"):
        from_imitation([tr], crossroads, episode_ids=[1, 2])


def test_refuses_shapes_the_real_class_would_not_hold(crossroads, demos):
    tr = one(crossroads, demos)

    class Loose:  # no checks on construction, unlike imitation's class
        obs, acts, infos, terminal = tr.obs[:-1], tr.acts, None, tr.terminal

    with pytest.raises(InputError, match=r"expected T >= 1 actions and T \+ 1 observations"):
        from_imitation([Loose()], crossroads)
    Loose.obs, Loose.acts = tr.obs, tr.acts.astype(float) + 0.5
    with pytest.raises(InputError, match="acts must be a 1-D array of action indices"):
        from_imitation([Loose()], crossroads)


# -------------------------------------------------------------------------- the arrival chain
def finite_horizon_policy(chain, w, discount: float):
    """imitation's ``mce_partition_fh`` recursion (Ziebart 2010, 9.1-9.3) on the chain: the policy
    at t = 0 and V[0]."""
    r = chain.features @ w + chain.fixed_reward
    T = chain.transition_matrix
    V = logsumexp(np.repeat(r[:, None], T.shape[1], axis=1), axis=1)
    for _ in range(chain.horizon - 1):
        Q = r[:, None] + discount * (T @ V)
        V = logsumexp(Q, axis=1)
    return np.exp(Q - V[:, None]), V


@pytest.mark.parametrize("discounted_transitions", [False, True])
@pytest.mark.parametrize("beta", [0.1, 2.0])
def test_chain_policy_is_ours(corridor, beta, discounted_transitions):
    """With w = θ/β the chain's max-ent policy (MCE IRL's, finite horizon, γ^horizon ≈ 1e-9) is our
    discounted infinite-horizon policy of (θ, β) at every state, reached from anywhere."""
    mdp = corridor
    chain = arrival_chain(mdp, 400, starts=np.flatnonzero(~mdp.terminal),
                          discounted_transitions=discounted_transitions)
    pi, V = finite_horizon_policy(chain, THETA / beta, 1.0 if discounted_transitions else mdp.gamma)
    ours = solve(mdp, THETA[None], np.array([beta]), tol=1e-12)
    p_ours = np.exp(ours.log_policy[0])
    live = np.flatnonzero(~mdp.terminal)
    np.testing.assert_allclose(pi[chain.start_index[live]], p_ours[live], atol=1e-7)
    s, a = np.nonzero(mdp.available)
    into = mdp.next_state[s, a]
    ok = ~mdp.terminal[into]  # arriving in s' by any move: the policy of s'
    np.testing.assert_allclose(pi[chain.pair_index[s[ok], a[ok]]], p_ours[into[ok]], atol=1e-7)
    assert np.all(pi[chain.pair_index[s[~ok], a[~ok]], 0] > 1 - 1e-12)  # into a goal: on to the sink
    shift = V[chain.start_index[live]] - ours.value[0, live] / beta  # soft values: ours, up to a constant
    np.testing.assert_allclose(shift, shift[0], atol=1e-7)
    assert abs(shift[0]) < 1e-7 if not discounted_transitions else abs(shift[0] - np.log(4)) < 1e-6


def test_chain_structure(corridor):
    mdp = corridor
    chain = arrival_chain(mdp, 50, discounted_transitions=True)
    T = chain.transition_matrix
    np.testing.assert_allclose(T.sum(axis=2), 1.0)
    g = mdp.gamma
    np.testing.assert_allclose(T[:, :, chain.end][: chain.end], 1 - g)  # every move may end the episode
    assert T[chain.end, 0, chain.end] == 1.0
    assert chain.fixed_reward[chain.dead] == DEAD_REWARD and np.count_nonzero(chain.fixed_reward) == 1
    s, a = np.nonzero(mdp.available)
    np.testing.assert_allclose(chain.features[chain.pair_index[s, a]], mdp.features[s, a] / g)
    assert chain.observation_matrix.shape == (chain.n_states, mdp.n_features + 1)
    np.testing.assert_allclose(chain.initial_state_dist[chain.start_index[mdp.start_states]],
                               1 / mdp.start_states.size)
    # an unavailable action leads to dead
    s0 = int(mdp.start_states[0])
    blocked = np.flatnonzero(~mdp.available[s0])
    assert blocked.size and np.all(T[chain.start_index[s0], blocked, chain.dead] == g)
    theta, beta = chain.theta_beta(THETA / 0.5)
    np.testing.assert_allclose(theta, THETA / THETA.sum())
    assert beta == pytest.approx(0.5 / THETA.sum())


def test_fixed_goal_reward_becomes_a_learned_feature():
    text = "S..\n.#G\n...\n"
    mdp = parse_map(text, goal_reward_mode="fixed").to_mdp()
    assert mdp.has_offset
    chain = arrival_chain(mdp, 300)
    assert chain.features.shape[1] == mdp.n_features + 1 and chain.n_theta == mdp.n_features
    beta = 0.7
    pi, _ = finite_horizon_policy(chain, np.append(THETA, 1.0) / beta, mdp.gamma)
    ours = np.exp(solve(mdp, THETA[None], np.array([beta]), tol=1e-12).log_policy[0])
    s0 = int(mdp.start_states[0])
    np.testing.assert_allclose(pi[chain.start_index[s0]], ours[s0], atol=1e-7)
    theta, b = chain.theta_beta(np.append(THETA, 1.0) / beta)  # the offset's weight left out
    np.testing.assert_allclose(theta * THETA.sum(), THETA)
    assert b == pytest.approx(beta / THETA.sum())


def test_chain_trajectories_and_occupancy(crossroads, demos):
    starts = np.array([s[0] for s, _ in demos.episodes()])
    chain = arrival_chain(crossroads, 30, starts=starts, discounted_transitions=True)
    trs = chain.trajectories(demos, crossroads, trajectory_cls=Trajectory)
    om = np.zeros(chain.n_states)
    for tr, (states, actions) in zip(trs, demos.episodes(), strict=True):
        n = min(actions.size, 30)
        assert tr.obs[0] == chain.start_index[states[0]]
        assert np.array_equal(tr.obs[1:], chain.pair_index[states[:n], actions[:n]])
        assert np.array_equal(tr.acts, actions[:n])
        assert tr.terminal == (n == actions.size and bool(crossroads.terminal[
            crossroads.next_state[states[-1], actions[-1]]]))
        for t, x in enumerate(tr.obs):  # MCEIRL._set_demo_from_trajectories' count
            om[x] += crossroads.gamma**t
    np.testing.assert_allclose(chain.occupancy(demos, crossroads), om / len(trs), rtol=1e-14)
    assert [t.terminal for t in trs][-2:] == [False, False]  # cut at the horizon or at the step cap
    other = arrival_chain(crossroads, 30, starts=starts[:1])
    with pytest.raises(InputError, match="not a start state of the chain"):
        other.states(demos, crossroads)


def test_chain_refuses_bad_arguments(corridor):
    with pytest.raises(InputError, match="horizon must be >= 1"):
        arrival_chain(corridor, 0)
    with pytest.raises(InputError, match="starts must be non-terminal"):
        arrival_chain(corridor, 5, starts=np.flatnonzero(corridor.terminal))
    with pytest.raises(InputError, match="all zero"):
        arrival_chain(corridor, 5).theta_beta(np.zeros(5))


# ------------------------------------------------------------------- with the real library
def imitation_python() -> str | None:
    path = os.environ.get("EXPERTISE_IRL_IMITATION_PYTHON", "/tmp/imitation-venv/bin/python")
    return path if Path(path).exists() else None


@pytest.mark.skipif(imitation_python() is None, reason="no imitation environment (docs/vs-imitation.md)")
def test_round_trip_with_imitations_own_class(tmp_path):
    code = textwrap.dedent("""
        import numpy as np
        from imitation.data import types
        from expertise_irl.demos.imitation_io import from_imitation, to_imitation
        from expertise_irl.demos.trajectories import Trajectories
        from expertise_irl.mdp import TabularMDP
        mdp = TabularMDP.load("__MDP__")
        d = np.load("__DEMOS__")
        trajs = Trajectories(d["episode"], d["step"], d["state"], d["action"])
        for obs in ("one-hot", "index"):
            out = to_imitation(trajs, mdp, observations=obs)
            assert all(type(t) is types.Trajectory for t in out)
            back = from_imitation(out, mdp, episode_ids=trajs.episode_ids)
            assert all(np.array_equal(getattr(back, k), getattr(trajs, k))
                       for k in ("episode", "step", "state", "action"))
        print("ok", [t.terminal for t in out])
    """)
    mdp = load_bundled("crossroads").to_mdp()
    a = simulate(mdp, THETA, 0.05, 2, np.random.default_rng(1))
    b = simulate(mdp, THETA, 5.0, 1, np.random.default_rng(2), max_steps=20)
    mdp.save(tmp_path / "mdp.npz")
    np.savez(tmp_path / "demos.npz", episode=np.concatenate([a.episode, b.episode + 2]),
             step=np.concatenate([a.step, b.step]), state=np.concatenate([a.state, b.state]),
             action=np.concatenate([a.action, b.action]))
    code = code.replace("__MDP__", str(tmp_path / "mdp.npz"))
    code = code.replace("__DEMOS__", str(tmp_path / "demos.npz"))
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "PYTHONWARNINGS": "ignore"}
    out = subprocess.run([imitation_python(), "-c", code], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "ok [True, True, False]"
