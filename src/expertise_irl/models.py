"""Observation models: how a person with preferences θ and expertise β picks actions.

Each model is one Bellman backup in scaled units (``w = θ'/β``, ``q = w·φ' + γ v[next]`` with
φ', θ' the MDP's reward basis and weights,
``V = β v``); the batched solver (:mod:`expertise_irl.planning.kernels`), the differentiable
likelihood (:mod:`expertise_irl.planning.differentiable`) and the simulator all call
:func:`backup`, so a new model is one branch here.

- ``maxent`` (the paper's, Eqs. 1, 5–7; the default): ``v = logsumexp_a q`` and
  ``π(a|s) = exp(q − v)``. The entropy bonus pays for acting at random, so with an
  absorbing zero-value goal a person whose β is large next to their weights prefers
  to keep moving.
- ``maxent-relative``: entropy relative to the uniform choice among the available
  actions, ``v = log mean_a exp(q) = logsumexp_a q − log|A(s)|``, and
  ``π(a|s) = exp(q − v)/|A(s)|`` (= ``softmax_a q``). Random behaviour earns nothing,
  so a noisy person still heads for the goal. It is ``maxent`` with a step cost of
  ``β log|A(s)|`` added to every move's reward.
- ``boltzmann``: the noisy-rational model, ``π(a|s) ∝ exp(Q*(s,a)/β)`` with ``Q*`` the
  hard (β = 0) optimal values of ``θ·φ``: ``v = max_a q``, ``π = softmax_a q``. Hard
  values are homogeneous in the reward, so one solve per θ serves every β.
"""

from __future__ import annotations

MODELS = ("maxent", "maxent-relative", "boltzmann")
DEFAULT_MODEL = "maxent"


def check_model(model: str, field: str = "model") -> str:
    """``model`` if it is known, else an :class:`~expertise_irl.options.OptionError` naming
    ``field`` and the choices."""
    from .options import one_of

    return one_of(model, MODELS, field)


def backup(model: str, q, log_n_actions, axis: int = 0):
    """One backup of scaled Q-values ``q`` (``-inf`` where an action is unavailable).

    Args:
        model: one of :data:`MODELS` (a static Python string inside ``jit``).
        q: scaled Q-values with the actions along ``axis``.
        log_n_actions: ``log |A(s)|``, shaped like ``q`` without ``axis`` (used by
            ``maxent-relative`` only).

    Returns ``(v, log π)``: the state values (``q`` without ``axis``) and the normalised
    log-policy (the shape of ``q``). Every model's policy is ``softmax_a q``; the models
    differ in the value they back up.
    """
    import jax.numpy as jnp  # here, so that naming a model does not import JAX

    m = jnp.max(q, axis=axis)
    z = q - jnp.expand_dims(m, axis)
    log_sum = jnp.log(jnp.sum(jnp.exp(z), axis=axis))
    log_pi = z - jnp.expand_dims(log_sum, axis)
    if model == "maxent":
        v = m + log_sum
    elif model == "maxent-relative":
        v = m + log_sum - log_n_actions
    elif model == "boltzmann":
        v = m
    else:
        raise ValueError(f"unknown model {model!r}")
    return v, log_pi
