"""Active choice of the next start state (the paper's Sec. IX future work).

The robot can ask the person to start the next episode anywhere; it should pick
the start whose episode is expected to tell the most about (θ, β). For a start c
the expected information gain is

    EIG(c) = E_{h ~ P(h | data)} E_{ξ ~ π_h from c} [ H(P(· | data)) − H(P(· | data, ξ)) ],

the mutual information between the hypothesis and the next episode. It is
estimated by Monte Carlo: ``n_samples`` hypotheses are drawn from the current
posterior, each acts out one episode from every candidate start (at most
``max_steps`` actions), and the posterior after each simulated episode is
computed exactly over the whole set. The same hypothesis draws and the same
uniform numbers are used for every candidate (common random numbers), so the
candidates are compared on equal terms and the answer is a pure function of the
belief, the candidates and the seed.

``target="beta"`` scores the entropy of the β marginal instead (expertise only).

Cost is bounded: at most ``max_candidates × n_samples × max_steps`` simulated
actions, each a gather of H log-probabilities; candidates beyond
``max_candidates`` are subsampled with the same seed.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..demos.simulation import check_start_states
from ..errors import InputError
from ..mdp import TabularMDP
from ..options import one_of
from .belief import DiscreteBelief
from .posterior import entropy

TARGETS = ("joint", "beta")
DEFAULT_SAMPLES = 48
DEFAULT_MAX_STEPS = 100
DEFAULT_MAX_CANDIDATES = 32
_BLOCK = 2**22  # floats in one [episodes, H] block


class StartScores(NamedTuple):
    """Expected information gain of each scored candidate start.

    Attributes:
        candidates: ``[M]`` the start states scored (a seeded subsample if there were more).
        gain: ``[M]`` estimated expected reduction of the posterior entropy (nats).
        stderr: ``[M]`` Monte Carlo standard error of ``gain``.
        best: the candidate with the largest gain (the first of equals).
        target: ``"joint"`` (entropy over Θ × B) or ``"beta"`` (entropy of the β marginal).
        entropy: the entropy now (of the same target).
        n_samples: simulated episodes per candidate.
        n_offered: how many candidates were offered before subsampling.
    """

    candidates: np.ndarray
    gain: np.ndarray
    stderr: np.ndarray
    best: int
    target: str
    entropy: float
    n_samples: int
    n_offered: int


def _resolve(belief, mdp: TabularMDP | None) -> tuple[DiscreteBelief, TabularMDP]:
    from .online import OnlineEstimator

    if isinstance(belief, OnlineEstimator):
        return belief.belief(), (mdp if mdp is not None else belief.mdp)
    if not isinstance(belief, DiscreteBelief):
        raise InputError("belief must be a DiscreteBelief or an OnlineEstimator")
    if mdp is None:
        raise InputError("next_start needs the MDP (mdp=...) to simulate episodes from a DiscreteBelief")
    return belief, mdp


def _check_candidates(mdp: TabularMDP, candidates) -> np.ndarray:
    return np.unique(check_start_states(mdp, candidates, "candidates"))


def _entropies(logw: np.ndarray, target: str, n_theta: int, n_beta: int) -> np.ndarray:
    """``[E]`` entropy of each row's normalised posterior (``logw [E, H]``)."""
    m = logw.max(axis=1, keepdims=True)
    w = np.exp(logw - m)
    z = w.sum(axis=1, keepdims=True)
    p = w / z
    if target == "beta":
        p = p.reshape(len(p), n_theta, n_beta).sum(axis=1)
        lp = np.log(p, out=np.full_like(p, -np.inf), where=p > 0)
    else:
        lp = logw - (m + np.log(z))
    return entropy(p, lp, axis=1)


def _check_sizes(b: DiscreteBelief, mdp: TabularMDP, target: str, sizes: dict[str, int], rng):
    """Raise :class:`InputError` on a bad argument; return ``rng`` as a Generator."""
    one_of(target, TARGETS, "target")
    for name, v in sizes.items():
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
            raise InputError(f"{name} must be an integer >= 1, got {v!r}")
    _, S, A = b.log_policy.shape
    if (S, A) != (mdp.n_states, mdp.n_actions):
        raise InputError(f"belief was solved on {S} states × {A} actions; the MDP has "
                         f"{mdp.n_states} × {mdp.n_actions}")
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, bool) or not isinstance(rng, int | np.integer) or rng < 0:
        raise InputError(f"rng must be a numpy Generator or a seed >= 0, got {rng!r}")
    return np.random.default_rng(int(rng))


def _episode_log_likelihoods(b: DiscreteBelief, mdp: TabularMDP, starts: np.ndarray, drawn: np.ndarray,
                             u: np.ndarray) -> np.ndarray:
    """``[len(starts) · n, H]`` log-likelihood of each simulated episode under every hypothesis.

    Episode ``c · n + i`` starts at ``starts[c]`` and acts under hypothesis ``drawn[i]`` with the
    uniform numbers ``u[:, i]`` (``u [max_steps, n]``), until a goal or ``max_steps`` actions.
    """
    A = b.log_policy.shape[2]
    n = drawn.size
    table = np.ascontiguousarray(np.transpose(b.log_policy, (1, 2, 0)))  # [S, A, H]
    hs = np.tile(drawn, starts.size)  # episode e acts under hypothesis hs[e]
    sample = np.tile(np.arange(n), starts.size)
    state = np.repeat(starts, n)
    ll = np.zeros((state.size, table.shape[2]))
    active = np.arange(state.size)
    for t in range(u.shape[0]):
        if active.size == 0:
            break
        s = state[active]
        cdf = np.cumsum(np.exp(b.log_policy[hs[active], s]), axis=1)  # [n_active, A]
        cdf /= cdf[:, -1:]
        a = np.minimum(np.sum(cdf <= u[t, sample[active], None], axis=1), A - 1)
        # Guard against round-off picking an unavailable action at the top of the CDF.
        a = np.where(mdp.next_state[s, a] >= 0, a, np.argmax(mdp.next_state[s] >= 0, axis=1))
        ll[active] += table[s, a]
        nxt = mdp.next_state[s, a]
        state[active] = nxt
        active = active[~mdp.terminal[nxt]]
    return ll


def expected_information_gain(
    belief,
    candidates=None,
    mdp: TabularMDP | None = None,
    *,
    n_samples: int = DEFAULT_SAMPLES,
    max_steps: int = DEFAULT_MAX_STEPS,
    max_candidates: int = DEFAULT_MAX_CANDIDATES,
    target: str = "joint",
    rng: np.random.Generator | int = 0,
) -> StartScores:
    """Score candidate starts by the expected information gain of one episode (module docstring).

    Args:
        belief: a :class:`DiscreteBelief` (then ``mdp`` is required) or an
            :class:`~expertise_irl.inference.online.OnlineEstimator`.
        candidates: start states to choose from; default ``mdp.initial_states()``.
        mdp: the task the belief was solved on.
        n_samples: simulated episodes per candidate (hypotheses drawn from the posterior).
        max_steps: length cap of a simulated episode.
        max_candidates: at most this many candidates are scored (a seeded subsample).
        target: ``"joint"`` or ``"beta"``.
        rng: a Generator or a seed; the result is a pure function of it.

    Returns:
        The scored candidates (:class:`StartScores`).

    Raises:
        InputError: ``belief`` is neither kind, or a DiscreteBelief comes without ``mdp`` or was
            solved on another MDP; an unknown ``target``, a size below 1, or a candidate that is
            not a non-terminal state.
    """
    b, mdp = _resolve(belief, mdp)
    rng = _check_sizes(b, mdp, target, {"n_samples": n_samples, "max_steps": max_steps,
                                        "max_candidates": max_candidates}, rng)
    cand = _check_candidates(mdp, candidates)
    offered = cand.size
    if cand.size > max_candidates:
        cand = np.sort(rng.choice(cand, size=max_candidates, replace=False))
    hyp = b.hypotheses
    H = len(hyp)
    log_post = b.log_posterior
    p = np.exp(log_post)
    drawn = rng.choice(H, size=n_samples, p=p / p.sum())  # [n]
    u = rng.random((max_steps, n_samples))  # shared by every candidate
    now = float(_entropies(log_post[None], target, hyp.n_theta, hyp.n_beta)[0])

    M = cand.size
    per_block = max(1, _BLOCK // max(H * n_samples, 1))  # candidates per block
    gains = np.empty((M, n_samples))
    for lo in range(0, M, per_block):
        c = cand[lo:lo + per_block]
        ll = _episode_log_likelihoods(b, mdp, c, drawn, u)
        after = _entropies(log_post[None] + ll, target, hyp.n_theta, hyp.n_beta)
        gains[lo:lo + c.size] = (now - after).reshape(c.size, n_samples)
    gain = gains.mean(axis=1)
    stderr = gains.std(axis=1, ddof=1) / np.sqrt(n_samples) if n_samples > 1 else np.full(M, np.nan)
    # Gains equal to round-off (an uninformative start scores 0 up to ~1e-15) tie; the first wins.
    best = int(cand[int(np.argmax(gain > gain.max() - 1e-12))])
    return StartScores(cand, gain, stderr, best, target, now, int(n_samples), int(offered))


def next_start(belief, candidates=None, mdp: TabularMDP | None = None, **kwargs) -> int:
    """The candidate start whose episode is expected to tell the most about (θ, β).

    Deterministic for a given seed.

    Args:
        belief: a :class:`DiscreteBelief` (then ``mdp`` is required) or an
            :class:`~expertise_irl.inference.online.OnlineEstimator`.
        candidates: start states to choose from; default ``mdp.initial_states()``.
        mdp: the task the belief was solved on.
        **kwargs: the options of :func:`expected_information_gain` (``n_samples``, ``max_steps``,
            ``max_candidates``, ``target``, ``rng``).

    Returns:
        The state index of the best candidate.

    Raises:
        InputError: as :func:`expected_information_gain`.
    """
    return expected_information_gain(belief, candidates, mdp, **kwargs).best
