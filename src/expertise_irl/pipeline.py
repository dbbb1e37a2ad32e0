"""One inference from a task and demonstrations to a :class:`~expertise_irl.result.Result`.

:func:`infer` is the path every entry point takes: ``expertise-irl infer`` and ``demo``, the live
page (:mod:`expertise_irl.live`) and Python users; ``study`` builds each participant's result with
the same constructor (:func:`discrete_result`) from the posteriors its engine computes. One call::

    world = as_world("crossroads")                 # a map name or file, an .npz, a map or an MDP
    demos = as_demos("demos.csv", world)           # a demonstrations CSV or Trajectories
    job = prepare(world, demos, "discrete", seed=0, check="fast")   # options checked, set chosen
    result = job.run()                             # the method, then the checks
    write_result("result.json", result)

or ``infer(world, demos)`` for the same in one call. In order: the options are read into the
method's options dataclass (:mod:`.inference.methods`; an
:class:`~expertise_irl.options.OptionError` names a bad field), the method's setup runs (the
discrete set is chosen; ``note`` hears the prior of a continuous method), the method fits and
describes its posterior, the settings record the inputs with their digests, the seed, the map's
goal reward and γ and the method's options, and the misspecification checks
(:mod:`.inference.misspecification`) add their verdict and warnings.

With ``model="pedagogical"`` (discrete only) the result also holds ``teaching``: the verdict (teaching,
doing or undecided), λ̂ with its interval and the ``maxent`` reading of the same set. The predictive
checks then judge the teaching model itself: their replicates are simulated from draws of (θ, β, λ)
of its joint posterior with each draw's teacher policy
(:func:`~.inference.methods.teaching_draws`). The named set is not refitted for a *too coarse* verdict
(the observer's set is fixed before the data), and ``check="full"`` is refused: its per-state
reward is fitted under a model with a Bellman backup, which the teaching model has not.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .demos.trajectories import Trajectories
from .errors import InputError
from .inference.methods import Method, MethodRun, Note, Progress, document, get_method
from .mdp import TabularMDP
from .models import PEDAGOGICAL
from .options import DEFAULT_CHECK, DEFAULT_METHOD
from .result import Result
from .results import discrete_result as _discrete_document
from .results import file_digest, map_digest


@dataclass(frozen=True)
class World:
    """The task inferred on and where it came from.

    Attributes:
        mdp: the tabular MDP.
        map: the zone map or floor plan it was compiled from (None for an archive or an MDP object).
        name: how it was named (a bundled name, a file path; None for an object).
        digest: ``sha256:`` of its content (:func:`~expertise_irl.results.map_digest` of a map, the
            file's of an archive; None for an MDP object).
    """

    mdp: TabularMDP
    map: Any = None
    name: str | None = None
    digest: str | None = None

    @property
    def goal_reward_mode(self) -> str:
        """The map's goal reward mode; an MDP's: ``fixed`` when it holds a reward outside θ·φ."""
        if self.map is not None:
            return self.map.goal_reward_mode
        return "fixed" if self.mdp.has_offset else "scaled"

    def source(self) -> dict[str, Any]:
        """The result's settings of the task: its name and digest.

        Returns:
            ``{"mdp": name, "mdp_digest": digest}``.
        """
        return {"mdp": self.name, "mdp_digest": self.digest}

    def reward(self) -> dict[str, Any]:
        """The result's settings of the task's reward: goal bonus, goal reward mode and γ.

        Returns:
            ``{"goal_bonus": ..., "goal_reward_mode": ..., "gamma": ...}`` (no bonus for an MDP).
        """
        return {"goal_bonus": self.map.goal_bonus if self.map is not None else None,
                "goal_reward_mode": self.goal_reward_mode, "gamma": self.mdp.gamma}


@dataclass(frozen=True)
class Demos:
    """Demonstrations and the file they came from.

    Attributes:
        trajectories: the pairs.
        path: the CSV file they were read from (None for a :class:`Trajectories` object).
        digest: ``sha256:`` of that file (None for an object).
    """

    trajectories: Trajectories
    path: str | None = None
    digest: str | None = None


def as_world(world: Any, goal_reward: str | None = None) -> World:
    """``world`` as a :class:`World`.

    Args:
        world: a :class:`World`, a :class:`TabularMDP`, a zone map or floor plan, an ``.npz``
            archive's path, or a map file's path or bundled map's name.
        goal_reward: ``scaled`` or ``fixed``; applies to a map, never to an MDP.

    Returns:
        The world, with its name and digest where it has them.

    Raises:
        InputError: ``goal_reward`` given for an MDP archive or an unknown one, a ``world`` of
            another type, or a file or name that cannot be read as a world.
    """
    import dataclasses

    if isinstance(world, World):
        return world
    if isinstance(world, TabularMDP):
        return World(world)
    if isinstance(world, str | Path) and Path(world).suffix == ".npz":
        if goal_reward is not None:
            raise InputError("goal_reward applies to a map; an MDP archive holds its own reward")
        return World(TabularMDP.load(world), None, str(world), file_digest(world))
    if isinstance(world, str | Path):
        from .worlds.maps import resolve_world

        zone_map, name = resolve_world(str(world)), str(world)
    elif hasattr(world, "to_mdp"):
        zone_map, name = world, getattr(world, "name", None)
    else:
        raise InputError(f"world must be a map, a map's name or file, an .npz archive or a TabularMDP, "
                         f"got {type(world).__name__}")
    if goal_reward is not None:
        from .worlds.grid import check_goal_reward_mode

        zone_map = dataclasses.replace(zone_map, goal_reward_mode=check_goal_reward_mode(goal_reward,
                                                                                         "goal_reward"))
    return World(zone_map.to_mdp(), zone_map, name, map_digest(zone_map))


def as_demos(demos: Any, world: World | TabularMDP) -> Demos:
    """``demos`` as :class:`Demos`.

    Args:
        demos: :class:`Demos`, :class:`Trajectories` or a demonstrations CSV's path.
        world: the task a CSV is read for (its MDP checks every pair).

    Returns:
        The demonstrations, with their file's path and digest when read from one.

    Raises:
        InputError: the CSV cannot be read or does not fit the MDP (:func:`read_demos_csv`).
    """
    if isinstance(demos, Demos):
        return demos
    if isinstance(demos, Trajectories):
        return Demos(demos)
    from .demos.csv_io import read_demos_csv

    mdp = world.mdp if isinstance(world, World) else world
    return Demos(read_demos_csv(demos, mdp), str(demos), file_digest(demos))


# --------------------------------------------------------------------------- one inference
@dataclass(frozen=True)
class Prepared:
    """An inference whose options are checked and whose setup is done; :meth:`run` does the rest.

    Attributes:
        method: the method (:class:`~expertise_irl.inference.methods.Method`).
        options: its options.
        world, demos: the inputs.
        seed: the seed of every random choice.
        check: the misspecification checks (``off``, ``fast``, ``full``).
        setup: the method's setup (the discrete set).
        command: the command recorded in the settings (``infer`` unless told).
    """

    method: Method
    options: Any
    world: World
    demos: Demos
    seed: int
    check: str
    setup: Any
    command: str

    @property
    def unit(self) -> str:
        """What the method's progress counts."""
        return self.method.unit

    @property
    def progress_label(self) -> str:
        return self.method.progress_label(self.options)

    def run(self, progress: Progress = None) -> Result:
        """The method's fit, described, recorded and checked.

        Args:
            progress: ``progress(done, total)`` in the method's :attr:`unit`, or None.

        Returns:
            The result; its ``timing`` holds the seconds of the inference and of the checks.
        """
        from .inference.misspecification import add_to_result

        mdp, trajs = self.world.mdp, self.demos.trajectories
        run = self.method.run(mdp, trajs, self.options, self.seed, progress=progress, setup=self.setup)
        doc = self.document(run)
        t0 = time.perf_counter()
        if self.check != "off":
            posterior, refit = self._checked_posterior(run)
            add_to_result(doc, [(mdp, trajs)], posterior, check=self.check, model=run.settings["model"],
                          seed=self.seed, refit=refit)
        result = Result.from_json(doc)
        return result.replace(timing={"inference_s": float(run.fields["run_time_s"]),
                                      "checks_s": time.perf_counter() - t0})

    def _checked_posterior(self, run: MethodRun) -> tuple[dict[str, Any], Any]:
        """The posterior the misspecification checks judge and the refit of a named set (None: none):
        the teaching model's draws and no refit for ``pedagogical`` (see the module docstring)."""
        from .inference.misspecification import posterior_of_run, refit_of_run

        mdp, trajs = self.world.mdp, self.demos.trajectories
        if getattr(run.result, "teaching", None) is None:
            return posterior_of_run(run, mdp), refit_of_run(run, mdp, trajs, self.options)
        import numpy as np

        from .inference.methods import teaching_draws
        from .inference.predictive_checks import MAX_DRAWS

        return teaching_draws(run.result, MAX_DRAWS, np.random.default_rng([self.seed, 48])), None

    def settings(self) -> dict[str, Any]:
        """The settings every result of this inference starts with (the method's options follow)."""
        return {"command": self.command, "method": self.method.name, **self.world.source(),
                "demos": self.demos.path, "demos_digest": self.demos.digest, "seed": self.seed,
                **self.world.reward()}

    def document(self, run: MethodRun) -> dict[str, Any]:
        """The result document of a method's run, with this inference's settings and data.

        Args:
            run: what the method's fit returned.

        Returns:
            The JSON-ready document, before the misspecification checks.
        """
        trajs = self.demos.trajectories
        doc = document(run, feature_names=self.world.mdp.feature_names, settings=self.settings(),
                       data={"episodes": trajs.n_episodes, "actions": len(trajs)})
        doc["settings"]["check"] = self.check
        return doc


def prepare(world: Any, demos: Any, method: str = DEFAULT_METHOD, *, options: Any = None, seed: int = 0,
            check: str = DEFAULT_CHECK, note: Note = None, command: str = "infer",
            **values: Any) -> Prepared:
    """Check the options and set up one inference (see the module docstring).

    Args:
        world: the task (:func:`as_world`).
        demos: the demonstrations (:func:`as_demos`).
        method: ``discrete`` (the default), ``birl``, ``map`` or ``nuts``.
        options: the method's options dataclass; or give its fields as keyword ``values``.
        seed: the seed of every random choice.
        check: the misspecification checks: ``off``, ``fast`` (the default) or ``full``.
        note: hears what a user should know before the long part (the prior, a capped set).
        command: recorded as ``settings.command``.
        **values: the method's options by field name (``thetas``, ``tol``, ``chains``, ...).

    Returns:
        The prepared inference.

    Raises:
        OptionError: an option's value (naming the field), an option the method does not take, or
            both ``options`` and ``values``.
    """
    from .inference.misspecification import check_level
    from .options import OptionError

    chosen = get_method(method)
    check = check_level(check)
    if options is None:
        known = {f for f in chosen.options.__dataclass_fields__}
        for name in values:
            if name not in known:
                raise OptionError(f"{{{name}}} is not an option of method {chosen.name}", name)
        options = chosen.options_from(values)
    elif values:
        raise OptionError("give the options either as {options} or by field, not both", "options")
    refuse_check(options, check)
    w = as_world(world)
    d = as_demos(demos, w)
    setup = chosen.setup(w.mdp, options, seed, note)
    return Prepared(chosen, options, w, d, seed, check, setup, command)


def refuse_check(options: Any, check: str) -> None:
    """Refuse ``check="full"`` for the ``pedagogical`` model (see the module docstring).

    Args:
        options: a method's options.
        check: the misspecification checks asked for.

    Raises:
        OptionError: naming ``check`` and ``model``.
    """
    from .options import OptionError

    if check == "full" and getattr(options, "model", None) == PEDAGOGICAL:
        raise OptionError("{check} full fits a per-state reward under a model with a Bellman backup, which "
                          "{model} pedagogical has not: use {check} fast (posterior predictive checks under "
                          "the teaching model) or off", "check", "model")


def infer(world: Any, demos: Any, method: str = DEFAULT_METHOD, *, options: Any = None, seed: int = 0,
          check: str = DEFAULT_CHECK, progress: Progress = None, note: Note = None, command: str = "infer",
          **values: Any) -> Result:
    """Infer expertise β and preferences θ from ``demos`` on ``world``: the command line's ``infer``.

    Args:
        world: a :class:`~expertise_irl.mdp.TabularMDP`, a zone map or floor plan, a bundled map's
            name, a map file or an ``.npz`` archive.
        demos: :class:`~expertise_irl.demos.trajectories.Trajectories` or a demonstrations CSV.
        method: ``discrete`` (the default; an adaptive set unless one is named), ``birl``, ``map``
            or ``nuts``.
        options: the method's options dataclass (or give its fields as keywords).
        seed: the seed of every random choice.
        check: ``off``, ``fast`` (the default) or ``full``: low expertise or missing features?
        progress: ``progress(done, total)`` as the method runs.
        note: hears the notes the command line prints before its progress bar.
        command: recorded as ``settings.command``.
        **values: the method's options by field name.

    Returns:
        The :class:`~expertise_irl.result.Result`, as ``expertise-irl infer`` writes it (with paths
        given for ``world`` and ``demos``, the same document).

    Raises:
        OptionError: an option's value, naming the field.
        InputError: the task or the demonstrations.
    """
    job = prepare(world, demos, method, options=options, seed=seed, check=check, note=note, command=command,
                  **values)
    return job.run(progress)


# --------------------------------------------------------------------------- constructors
def discrete_result(belief, *, feature_names, settings: Mapping[str, Any],
                    data: Mapping[str, Any] | None = None, trace=None, trace_index=None, refinement=None,
                    warnings=None, extra: Mapping[str, Any] | None = None,
                    run_time_s: float | None = None) -> Result:
    """The :class:`~expertise_irl.result.Result` of a discrete posterior computed elsewhere.

    The live page's online estimate, a study participant's posterior over their tasks, the demo's.

    Args:
        belief: the posterior, a :class:`~expertise_irl.inference.belief.DiscreteBelief`.
        feature_names: the features θ weighs, in order.
        settings: what the run was asked to do.
        data: what was read (episodes, actions, ...).
        trace: the belief after every action (:meth:`DiscreteBelief.trace`), or None.
        trace_index: the ``(episodes, steps)`` arrays labelling ``trace``'s entries after the first.
        refinement: an adaptive set's record.
        warnings: the run's warnings (None: the result records no diagnostics).
        extra: the command's own entries beside the inference.
        run_time_s: the inference's seconds.

    Returns:
        The result.
    """
    doc = _discrete_document(belief, feature_names=feature_names, settings=dict(settings),
                             data=dict(data or {}), trace=trace, trace_index=trace_index)
    if refinement is not None:
        doc["refinement"] = refinement
    if warnings is not None:
        doc["diagnostics"] = {"warnings": list(warnings)}
    if run_time_s is not None:
        doc["run_time_s"] = run_time_s
    doc.update(extra or {})
    return Result.from_json(doc)
