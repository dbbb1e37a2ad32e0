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
- ``pedagogical``: a demonstrator who may be teaching (:mod:`expertise_irl.inference.pedagogical`):
  ``maxent``'s policy reweighted by what each action would tell a literal observer of a fixed
  hypothesis set, ``π_show ∝ π_{θ,β} · exp(λ/β · I_θ)``, with the teaching weight λ ≥ 0 inferred
  (λ = 0 is ``maxent``). It has no Bellman backup of its own (the values are the doer's), so it is
  not in :data:`BACKUP_MODELS`: no solver takes it; the discrete method solves the set under
  ``maxent`` once and reweights.
"""

from __future__ import annotations

#: The models with a Bellman backup (:func:`backup`): those a solver takes.
BACKUP_MODELS = ("maxent", "maxent-relative", "boltzmann")
#: The teaching model: ``maxent`` reweighted by a literal observer of a fixed hypothesis set.
PEDAGOGICAL = "pedagogical"
#: Every observation model.
MODELS = (*BACKUP_MODELS, PEDAGOGICAL)
DEFAULT_MODEL = "maxent"


def check_model(model: str, field: str = "model", *, solvable: bool = True) -> str:
    """``model`` if it is known (with ``solvable``, the default, one a solver takes: one of
    :data:`BACKUP_MODELS`).

    Args:
        model: the model's name.
        field: the option's name, in the message.
        solvable: refuse :data:`PEDAGOGICAL`, which has no Bellman backup of its own.

    Returns:
        ``model``.

    Raises:
        OptionError: naming ``field``: an unknown model (with the choices), or ``pedagogical``
            where a model is solved.
    """
    from .options import OptionError, one_of

    if solvable and model == PEDAGOGICAL:
        raise OptionError(f"{{{field}}} pedagogical has no Bellman backup of its own (a teacher's policy is "
                          "maxent's reweighted by what a literal observer of a fixed hypothesis set would "
                          "learn): it is inferred on a discrete set (method discrete) and simulated with a "
                          "teaching weight, not solved; use " + ", ".join(BACKUP_MODELS) + " here", field)
    return one_of(model, MODELS if not solvable else BACKUP_MODELS, field)


def backup(model: str, q, log_n_actions, axis: int = 0):
    """One backup of scaled Q-values ``q`` (``-inf`` where an action is unavailable).

    Args:
        model: one of :data:`BACKUP_MODELS` (a static Python string inside ``jit``).
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
        check_model(model)  # pedagogical (no backup) or an unknown name: an OptionError naming model
        raise ValueError(f"unknown model {model!r}")
    return v, log_pi
