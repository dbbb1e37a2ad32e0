"""One live tele-operation session: the map, the online estimate, the recording, the next start.

Everything the page shows and does goes through :meth:`LiveSession.handle`, which
takes one decoded client message and returns the replies; the web server only
moves JSON between the socket and this class. Nothing a client sends names a
file: the session writes only ``DIR/demos.csv`` (every accepted action appended,
flushed and synced as it happens, grid format ``episode,step,x,y``, with the ``heading``
column on a warehouse floor plan) and
``DIR/result.json`` (the discrete-set result, written when the session opens and
rewritten atomically after every episode and when the start mode changes). Opening a
session on a DIR that already holds ``demos.csv`` replays it, so the belief, the history,
an episode cut short and the start mode (active or random, kept in ``result.json``) all
resume. Episodes are numbered from 0 everywhere, as in the ``episode`` column of
``demos.csv``.

With an adaptive set (``open_session(..., refine=options)``, the command's default when no set is
named) the session starts on the start set and, after each episode, refines it from every finished
episode (:func:`~expertise_irl.inference.methods.refined_set`, from the start set each time, as
``infer`` does) and rebuilds the estimator over the refined set with its prior weights, every
action replayed: the belief is the exact posterior over that set. The server runs the refinement
in its worker thread right after telling the page that the goal was reached
(:meth:`LiveSession.handle` with ``defer``, then :meth:`LiveSession.finish_episode`).

With ``model="pedagogical"`` (``live --model pedagogical``) the demonstrator may be teaching: the
set is fixed (the literal observer's set is fixed before the data, so it is never refined), and the
estimate after every action is the teaching model's exact posterior over the set with λ
marginalised (:class:`~expertise_irl.inference.teaching_online.TeachingOnlineEstimator`, one
``maxent`` solve of the set for every λ). Each state message carries the teaching reading
(``teaching``: the verdict, λ̂ and its interval) and ``result.json`` the result's ``teaching``
entry. The active start choice stays on the doer's policies: it simulates episodes under
hypotheses drawn from the λ-marginal belief over Ψ, acting as doers, and scores a start by how
much such an episode, read as a doer's, is expected to lower that belief's entropy; it does not
model a teacher's detours.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, os_reason, plural
from ..hypotheses import HypothesisSet
from ..inference.active import expected_information_gain
from ..inference.online import OnlineEstimator
from ..inference.teaching_online import TeachingOnlineEstimator
from ..mdp import ACTION_NAMES
from ..models import DEFAULT_MODEL, PEDAGOGICAL
from ..result import Result
from ..worlds.maps import Map
from ..worlds.warehouse import HEADING_LETTERS, WarehouseMap

DEMOS_NAME = "demos.csv"
RESULT_NAME = "result.json"
MODES = ("active", "random")
#: The observation models the live page runs (``maxent``: a doer; ``pedagogical``: a doer or a teacher).
LIVE_MODELS = (DEFAULT_MODEL, PEDAGOGICAL)
#: The keys of the teaching record that each state message carries (``--model pedagogical``).
TEACHING_SHOWN = ("verdict", "reading", "log_bayes_factor", "p_teaching", "lambda_hat", "lambda_interval")
#: Accepted keys of each client message type (anything else is refused).
MESSAGES: dict[str, tuple[str, ...]] = {
    "move": ("type", "action"),
    "mode": ("type", "mode"),
    "sync": ("type",),
}
#: Key aliases the page sends; the server accepts only these action names.
ACTIONS = {name: i for i, name in enumerate(ACTION_NAMES)}


@dataclass
class StartChoice:
    """How the current episode's start was chosen, for the page."""

    state: int
    how: str  # "active", "random" or "resumed"
    why: str
    gain: float | None = None


@dataclass
class LiveSession:
    """State of one session. Build with :func:`open_session`."""

    zone_map: Map  # a zone map or a warehouse floor plan
    estimator: OnlineEstimator
    out_dir: Path
    settings: dict[str, Any]
    seed: int = 0
    mode: str = "active"
    n_samples: int = 48
    history_beta: list[float] = field(default_factory=list)
    history_entropy: list[float] = field(default_factory=list)
    episode_starts: list[int] = field(default_factory=list)  # history index where each episode began
    start: StartChoice | None = None
    position: int = -1
    starts_log: list[dict[str, Any]] = field(default_factory=list)
    expertise: str = "stationary"  # "changing": also show the current episode's β, filtered
    refine: Any = None  # DiscreteOptions whose set is refined after each episode (None: a fixed set)
    start_hypotheses: HypothesisSet | None = None  # where each refinement starts
    refined: Any = None  # the last refinement (inference.adaptive.Refined), None before the first
    refine_pending: bool = False  # an episode ended and its refinement has not run yet
    _done: tuple[int, int] = (0, 0)  # the episode that ended last and its number of moves

    # ------------------------------------------------------------------ paths
    @property
    def demos_path(self) -> Path:
        return self.out_dir / DEMOS_NAME

    @property
    def result_path(self) -> Path:
        return self.out_dir / RESULT_NAME

    @property
    def mdp(self):
        return self.estimator.mdp

    @property
    def teaching(self) -> bool:
        """Whether the estimate is the teaching model's (``--model pedagogical``)."""
        return isinstance(self.estimator, TeachingOnlineEstimator)

    def _xy(self, s: int) -> list[int]:
        return [int(v) for v in self.mdp.state_xy[s]]

    def _heading(self, s: int) -> str | None:
        """``h`` or ``v``, the heading of state ``s`` in a heading world, else None."""
        h = self.mdp.state_heading
        return None if h is None else HEADING_LETTERS[int(h[s])]

    # ---------------------------------------------------------------- protocol
    def handle(self, msg: Any, *, defer: bool = False) -> list[dict[str, Any]]:
        """Replies to one decoded message (validated here; never raises for bad input).

        ``defer``: a move that ends an episode of an adaptive set replies at once that the set is
        being refined, and leaves the refinement to :meth:`finish_episode` (the server runs it next,
        so the page can say so while it runs); without it the reply comes after the refinement."""
        why = validate_message(msg)
        if why is not None:
            return [{"type": "error", "message": why}]
        if self.refine_pending:  # never act on a set whose refinement is owed
            self.finish_episode()
        kind = msg["type"]
        if kind == "sync":
            return [self.state_message()]
        if kind == "mode":
            return self.set_mode(msg["mode"])
        return self.move(ACTIONS[msg["action"]], defer=defer)

    def set_mode(self, mode: str) -> list[dict[str, Any]]:
        """Switch how the next start is chosen; saved in ``result.json`` so that a restart keeps it."""
        self.mode = mode
        text = ("The robot will choose the next start (the most informative one)."
                if mode == "active" else "The next start will be drawn at random.")
        try:
            self.write_result()
        except OSError as exc:
            text += (f" (Could not save it in {RESULT_NAME}: {os_reason(exc)}; a restart will "
                     "not keep it.)")
        return [self.state_message(message=text)]

    def move(self, action: int, *, defer: bool = False) -> list[dict[str, Any]]:
        s = self.position
        nxt = int(self.mdp.next_state[s, action])
        if nxt < 0:
            name = ACTION_NAMES[action]
            return [{"type": "refused", "action": name,
                     "message": f"Cannot move {name}: a wall or the edge of the map is in the way. "
                                "The move was not recorded."}]
        first = not self.estimator.episode_open
        est = self.estimator.observe(s, action)
        e, t, _, _ = self.estimator._pairs[-1]
        try:
            self._append_rows(e, t, s, nxt, first)
        except OSError as exc:  # not on disk, so not in the estimate either
            self.estimator.undo()
            if first:
                self.estimator.end_episode()
            return [{"type": "error", "message": f"could not record the move in {DEMOS_NAME}: "
                                                 f"{os_reason(exc)}; it was not counted"}]
        self.history_beta.append(est.beta_hat)
        self.history_entropy.append(est.entropy)
        self.position = nxt
        if not self.mdp.terminal[nxt]:
            return [self.state_message(event="moved")]
        self._done = (e, t + 1)
        self.refine_pending = self.refine is not None
        if self.refine_pending and defer:
            text = (f"Goal reached in {t + 1} moves (episode {e} done). Refining the hypothesis set from "
                    f"{plural(self.estimator.n_episodes, 'episode')}…")
            return [self.state_message(event="refining", message=text)]
        return self.finish_episode()

    def finish_episode(self) -> list[dict[str, Any]]:
        """After an episode: refine the set (an adaptive set), save ``result.json``, choose the next start."""
        e, n_moves = self._done
        note = ""
        if self.refine_pending:
            self.refine_pending = False
            try:
                note = self.refine_set() + " "
            except Exception as exc:  # the session goes on over the set it has
                note = f"The hypothesis set could not be refined ({exc}); it stays as it was. "
        self.write_result()
        self.choose_start()
        self.episode_starts.append(len(self.history_beta))
        text = (f"Goal reached in {n_moves} moves (episode {e} done; saved to {RESULT_NAME}). "
                f"{note}{self.start.why}")
        return [self.state_message(event="episode_done", message=text)]

    def refine_set(self, progress: Callable[[int, int], None] | None = None) -> str:
        """Refine the set from every finished episode (starting from the start set, as ``infer``
        does) and rebuild the estimator over it with its prior weights, every action so far
        replayed: the belief is then the exact posterior over the refined set. Says what it did."""
        from ..inference.methods import refined_set

        trajs = self.estimator.trajectories()
        done = finished_episodes(trajs, self.estimator.episode_open)
        if not len(done):
            return ""
        r = refined_set(self.mdp, done, self.start_hypotheses, self.refine, progress)
        est = OnlineEstimator(self.mdp, r.hypotheses, r.log_policy, prior=r.prior)
        est.feed(trajs)
        if not self.estimator.episode_open:
            est.end_episode()
        self.estimator, self.refined = est, r
        h = r.hypotheses
        return (f"The hypothesis set was refined to {len(h)} hypotheses ({h.n_theta} θ × {h.n_beta} β) "
                f"in {r.record['seconds']:.1f} s." + "".join(f" Warning: {w}." for w in r.warnings))

    # -------------------------------------------------------------- recording
    def _append_rows(self, episode: int, step: int, s: int, nxt: int, first: bool) -> None:
        def row(t: int, state: int) -> str:
            x, y = self._xy(state)
            h = self._heading(state)  # the heading column, in a heading world
            return f"{episode},{t},{x},{y}" + ("" if h is None else f",{h}") + "\n"

        rows = [row(step, s)] if first else []
        rows.append(row(step + 1, nxt))
        new = not self.demos_path.exists() or self.demos_path.stat().st_size == 0
        with open(self.demos_path, "a", encoding="utf-8", newline="") as fh:
            if new:
                fh.write(",".join(demos_header(self.mdp)) + "\n")
            fh.write("".join(rows))
            fh.flush()
            os.fsync(fh.fileno())

    def result(self) -> Result:
        """The session's result: the online posterior over the set in use, the refinement that made
        it, the start log (:func:`expertise_irl.pipeline.discrete_result`)."""
        from ..pipeline import discrete_result

        trajs = self.estimator.trajectories()
        hyp = self.estimator.hypotheses
        settings = self.settings
        if self.refine is not None:  # the set in use, as infer records it
            settings = {**settings, "n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "n_hypotheses": len(hyp),
                        "prior": self.refined.record["prior"] if self.refined else "uniform"}
        live: dict[str, Any] = {"starts": self.starts_log, "episode_open": self.estimator.episode_open,
                                "mode": self.mode}
        if self.refine is not None:  # what the page showed, which a resume cannot recompute
            live["history"] = {"beta_hat": self.history_beta, "entropy": self.history_entropy}
        refined = self.refined
        teaching = {"teaching": self.estimator.record()} if self.teaching else {}
        return discrete_result(self.estimator.belief(), feature_names=self.mdp.feature_names,
                               settings=settings,
                               data={"episodes": trajs.n_episodes, "actions": len(trajs),
                                     "demos": DEMOS_NAME},
                               refinement=None if refined is None else refined.record,
                               warnings=list(refined.warnings) if refined is not None and refined.warnings
                               else None,
                               extra={**teaching, "live": live})

    def write_result(self) -> None:
        from ..results import write_result

        write_result(self.result_path, self.result())

    # ------------------------------------------------------------ start choice
    def choose_start(self) -> StartChoice:
        """Pick where the next episode starts (active or random, as the mode says)."""
        cand = np.asarray(self.mdp.initial_states(), dtype=np.int64)
        n_done = self.estimator.n_episodes
        rng = np.random.default_rng([self.seed, n_done])  # the same choice after a restart
        if cand.size == 1:
            s = int(cand[0])
            choice = StartChoice(s, self.mode, f"The next episode starts at {self._cell(s)}, the map's "
                                 "only start cell.")
        elif self.mode == "random":
            s = int(rng.choice(cand))
            choice = StartChoice(s, "random", f"Random start: {self._cell(s)}, drawn uniformly from "
                                 f"{cand.size} possible starts (active choice is off).")
        else:
            sc = expected_information_gain(self.estimator, cand, n_samples=self.n_samples, rng=rng)
            s = sc.best
            g = float(sc.gain[np.searchsorted(sc.candidates, s)])
            sampled = (f"{sc.candidates.size} of {sc.n_offered} possible starts"
                       if sc.n_offered > sc.candidates.size else f"{sc.candidates.size} possible starts")
            choice = StartChoice(
                s, "active",
                f"The robot chose {self._cell(s)}: an episode from there is expected to reduce the "
                f"uncertainty about θ and β by {g:.2f} nats, the most of {sampled} "
                f"(median {float(np.median(sc.gain)):.2f}).", gain=g)
        self.start = choice
        self.position = choice.state
        label = self._next_episode_label()  # one entry per episode: a restart between episodes replaces it
        self.starts_log = [d for d in self.starts_log
                           if not (isinstance(d, dict) and d.get("episode") == label)]
        self.starts_log.append({"episode": label, "xy": self._xy(choice.state),
                                "how": choice.how, "expected_gain": choice.gain})
        return choice

    def _next_episode_label(self) -> int:
        pairs = self.estimator._pairs
        return pairs[-1][0] + 1 if pairs else 0

    def _cell(self, s: int) -> str:
        x, y = self._xy(s)
        h = self._heading(s)
        return f"cell (x={x}, y={y})" + ("" if h is None else
                                         f" heading {'horizontal' if h == 'h' else 'vertical'}")

    # ---------------------------------------------------------------- messages
    def static_message(self) -> dict[str, Any]:
        """The map and its colours (sent once, when a page connects)."""
        from ..plots.maps import ARROW_COLOR, GOAL_COLOR, GRID_COLOR, PATH_COLORS, ZONE_COLORS

        floor_plan = isinstance(self.zone_map, WarehouseMap)
        if floor_plan:  # the colours of the floor-plan figures (Figs. 10–11)
            from ..plots.floorplan import CELL_COLORS, GOAL_FILL, ROAD_COLOR

            cells, goal, arrow = CELL_COLORS, GOAL_FILL, ROAD_COLOR
        else:
            cells, goal, arrow = ZONE_COLORS, GOAL_COLOR, ARROW_COLOR
        return {
            "type": "init",
            "map": {"name": self.zone_map.name, "width": self.zone_map.width,
                    "height": self.zone_map.height,
                    "rows": ["".join(r) for r in self.zone_map.grid.tolist()],
                    "world": "warehouse" if floor_plan else "zones"},
            "colors": {"zones": cells, "goal": goal, "arrow": arrow,
                       "grid": GRID_COLOR, "path": PATH_COLORS[0], "agent": PATH_COLORS[1]},
            "feature_names": list(self.mdp.feature_names),
            "n_hypotheses": len(self.estimator.hypotheses),
            "actions": list(ACTION_NAMES),
            "state": self.state_message(),
        }

    def state_message(self, *, event: str = "state", message: str | None = None) -> dict[str, Any]:
        est = self.estimator.estimate
        trajs_pairs = self.estimator._pairs
        path = [self._xy(self.start.state if self.start else self.position)]
        if self.estimator.episode_open or self.refine_pending:  # (the episode just ended: its path)
            e = trajs_pairs[-1][0]
            ep = [p for p in trajs_pairs if p[0] == e]
            path = [self._xy(p[2]) for p in ep] + [self._xy(self.position)]
            episode, step = e, ep[-1][1] + 1
        else:
            episode, step = self._next_episode_label(), 0
        return {
            "type": "state",
            "event": event,
            "message": message,
            "position": self._xy(self.position),
            "heading": self._heading(self.position),
            "path": path,
            "episode": episode,
            "step": step,
            "episodes_done": self.estimator.n_episodes - int(self.estimator.episode_open),
            "actions": self.estimator.n_observed,
            "n_hypotheses": len(self.estimator.hypotheses),
            "mode": self.mode,
            "start": {"xy": self._xy(self.start.state), "how": self.start.how, "why": self.start.why}
            if self.start else None,
            "estimate": est.to_dict(self.mdp.feature_names),
            "history": {"beta_hat": self.history_beta, "entropy": self.history_entropy,
                        "episode_starts": self.episode_starts},
            **({"expertise_now": self.expertise_now()} if self.expertise == "changing" else {}),
            **({"teaching": self.teaching_now()} if self.teaching else {}),
        }

    def teaching_now(self) -> dict[str, Any]:
        """``--model pedagogical``: the teaching reading of every action so far (the verdict, its
        sentence, the Bayes factor, P(teaching), λ̂ and its 90% interval)."""
        record = self.estimator.record()
        return {k: record[k] for k in TEACHING_SHOWN}

    def expertise_now(self) -> dict[str, Any] | None:
        """``--expertise changing``: the β of the episode being driven (or of the last one), filtered
        from every action so far (:func:`~..inference.changing.filtered_by_action`), with its 90%
        band; None before the first action."""
        from ..inference.changing import filtered_by_action
        from ..inference.posterior import beta_quantile

        pairs = self.estimator._pairs
        if not pairs:
            return None
        order = {e: i for i, e in enumerate(dict.fromkeys(p[0] for p in pairs))}
        table = self.estimator._table  # [S, A, H]
        step_ll = np.stack([table[p[2], p[3]] for p in pairs])
        last = filtered_by_action(step_ll, np.array([order[p[0]] for p in pairs]),
                                  self.estimator.hypotheses)[-1]
        b = self.estimator.hypotheses.betas
        return {"episode": int(pairs[-1][0]), "beta_mean": float(last @ b),
                "q05": float(beta_quantile(b, last, 0.05)), "q95": float(beta_quantile(b, last, 0.95))}


def validate_message(msg: Any) -> str | None:
    """Why a decoded client message is refused, or None."""
    if not isinstance(msg, dict):
        return "a message must be a JSON object"
    kind = msg.get("type")
    if not isinstance(kind, str) or kind not in MESSAGES:
        return f"unknown message type {kind!r} (expected one of: {', '.join(MESSAGES)})"
    extra = sorted(set(msg) - set(MESSAGES[kind]))
    if extra:
        return f"unexpected field(s) in a {kind!r} message: {', '.join(map(str, extra))}"
    missing = [k for k in MESSAGES[kind] if k not in msg]
    if missing:
        return f"a {kind!r} message needs the field(s) {', '.join(missing)}"
    if kind == "move" and (not isinstance(msg["action"], str) or msg["action"] not in ACTIONS):
        return f"unknown action {msg['action']!r} (expected one of: {', '.join(ACTIONS)})"
    if kind == "mode" and (not isinstance(msg["mode"], str) or msg["mode"] not in MODES):
        return f"unknown mode {msg['mode']!r} (expected one of: {', '.join(MODES)})"
    return None


def open_session(zone_map: Map, hypotheses: HypothesisSet, out_dir: str | Path, *,
                 settings: dict[str, Any] | None = None, seed: int = 0,
                 progress: Callable[[int, int], None] | None = None,
                 n_samples: int = 48, expertise: str = "stationary", refine: Any = None,
                 model: str = DEFAULT_MODEL, lambdas=None) -> LiveSession:
    """Solve the hypotheses on the map and open (or resume) the recording in ``out_dir``.

    ``refine``: the :class:`~expertise_irl.inference.methods.DiscreteOptions` of an adaptive set, refined
    from ``hypotheses`` after every episode (None: ``hypotheses`` stay the set). A resumed adaptive
    session refines once from the finished episodes of ``demos.csv``: refinement is a function of
    the demonstrations, so it reaches the set the recording session was on.

    ``model``: one of :data:`LIVE_MODELS`; ``pedagogical`` estimates under the teaching model over
    the fixed set ``hypotheses`` with the λ grid ``lambdas`` (None: the default grid); it takes
    neither ``refine`` nor changing expertise (an :class:`~expertise_irl.options.OptionError` naming
    the option)."""
    check_live_model(model, refine=refine, expertise=expertise, lambdas=lambdas)
    out_dir = Path(out_dir)
    mdp = zone_map.to_mdp()
    trajs = check_out_dir(zone_map, out_dir, settings)
    out_dir.mkdir(parents=True, exist_ok=True)
    if model == PEDAGOGICAL:
        est = TeachingOnlineEstimator.from_mdp(mdp, hypotheses, progress=progress,
                                               **({} if lambdas is None else {"lambdas": lambdas}))
    else:
        est = None if refine is not None and trajs is not None and len(trajs) else \
            OnlineEstimator.from_mdp(mdp, hypotheses, progress=progress)
    session = LiveSession(zone_map, est, out_dir, dict(settings or {}), seed=seed, n_samples=n_samples,
                          expertise=expertise, refine=refine, start_hypotheses=hypotheses)
    previous = _previous_live(out_dir / RESULT_NAME)
    session.mode = _previous_mode(previous, session.mode)
    if trajs is not None and len(trajs):
        _replay(session, mdp, trajs, previous, progress)
        est = session.estimator
    if est.episode_open:
        session.position = int(est.current_state)
        s0 = int(est._pairs[[p[0] for p in est._pairs].index(est._pairs[-1][0])][2])
        session.start = StartChoice(s0, "resumed", f"Resumed episode {est._pairs[-1][0]} where it "
                                    f"stopped, at {session._cell(session.position)}.")
    else:
        if trajs is not None and len(trajs):
            session.episode_starts.append(len(session.history_beta))
        session.choose_start()
    session.write_result()  # from the start: records the map this DIR belongs to
    return session


def _replay(session: LiveSession, mdp, trajs, previous: dict[str, Any], progress) -> None:
    """Resume ``session`` from recorded ``trajs``: its set (refined from the finished episodes, for an
    adaptive set), its belief, the history of β̂ and entropy, and the log of starts."""
    if session.refine is not None:
        open_last = not bool(mdp.terminal[mdp.next_state[trajs.state[-1], trajs.action[-1]]])
        done = finished_episodes(trajs, open_last)
        if len(done):
            from ..inference.methods import refined_set

            r = refined_set(mdp, done, session.start_hypotheses, session.refine, progress)
            session.estimator = OnlineEstimator(mdp, r.hypotheses, r.log_policy, prior=r.prior)
            session.refined = r
        else:
            session.estimator = OnlineEstimator.from_mdp(mdp, session.start_hypotheses, progress=progress)
    est = session.estimator
    if session.teaching:  # the teaching model's estimate after each action, as the page showed it
        session.history_beta, session.history_entropy = _feed_traced(est, trajs)
    else:
        prior = est.belief()
        est.feed(trajs)
        trace = prior.trace(trajs)
        session.history_beta = trace.mean_beta[1:].tolist()
        session.history_entropy = trace.entropy[1:].tolist()
    if session.refine is not None:  # the finished episodes were shown over earlier sets: as saved
        n_done = len(finished_episodes(trajs, est.episode_open))
        shown = previous.get("history")
        b, h = (shown.get(k) if isinstance(shown, dict) else None for k in ("beta_hat", "entropy"))
        if (isinstance(b, list) and isinstance(h, list) and n_done <= len(b) == len(h) <= len(trajs)
                and all(isinstance(v, (int, float)) for v in b + h)):
            session.history_beta[:n_done] = [float(v) for v in b[:n_done]]
            session.history_entropy[:n_done] = [float(v) for v in h[:n_done]]
    first = np.flatnonzero(np.append(True, trajs.episode[1:] != trajs.episode[:-1]))
    session.episode_starts = first.tolist()
    starts = previous.get("starts")
    session.starts_log = starts if isinstance(starts, list) else []


def _feed_traced(est: OnlineEstimator, trajs) -> tuple[list[float], list[float]]:
    """Feed ``trajs`` to ``est`` one pair at a time: (β̂, entropy) after each pair."""
    from ..demos.trajectories import Trajectories

    beta, entropy = [], []
    for i in range(len(trajs)):
        one = slice(i, i + 1)
        e = est.feed(Trajectories(trajs.episode[one], trajs.step[one], trajs.state[one], trajs.action[one]))
        beta.append(e.beta_hat)
        entropy.append(e.entropy)
    return beta, entropy


def check_live_model(model: str, *, refine: Any = None, expertise: str = "stationary", lambdas=None) -> None:
    """Refuse a model the live page does not run, or options the model does not take.

    Args:
        model: the observation model (one of :data:`LIVE_MODELS`).
        refine: the adaptive set's options, or None for a fixed set.
        expertise: ``stationary`` or ``changing``.
        lambdas: the λ grid (``pedagogical`` only), or None.

    Raises:
        OptionError: naming the option: another model, ``pedagogical`` with an adaptive set
            (``refine``) or changing expertise, or ``lambdas`` without ``pedagogical``.
    """
    from ..options import OptionError, one_of

    one_of(model, LIVE_MODELS, "model")
    if model != PEDAGOGICAL:
        if lambdas is not None:
            raise OptionError("{lambdas} is the teaching model's λ grid: give it with {model} pedagogical",
                              "lambdas", "model")
        return
    if refine is not None:
        raise OptionError("{refine} cannot be used with {model} pedagogical: the literal observer's set "
                          "is fixed before the data (name a set with --thetas/--betas or take the default)",
                          "refine", "model")
    if expertise != "stationary":
        raise OptionError("{expertise} changing cannot be used with {model} pedagogical (one β for every "
                          "episode)", "expertise", "model")


def finished_episodes(trajs, last_open: bool):
    """``trajs`` without its last episode when that one is still open (the finished episodes)."""
    from ..demos.trajectories import Trajectories

    if not (last_open and len(trajs)):
        return trajs
    keep = trajs.episode != trajs.episode[-1]
    return Trajectories(trajs.episode[keep], trajs.step[keep], trajs.state[keep], trajs.action[keep])


def demos_header(mdp) -> tuple[str, ...]:
    """Columns of the session's ``demos.csv``: the grid form, plus ``heading`` in a heading world."""
    from ..demos.csv_io import GRID_COLUMNS, HEADING_COLUMN

    return GRID_COLUMNS + ((HEADING_COLUMN,) if mdp.state_heading is not None else ())


def check_out_dir(zone_map: Map, out_dir: str | Path, settings: dict[str, Any] | None = None):
    """Check that ``out_dir`` can hold (or resume) a recording on ``zone_map`` before any work is
    done; returns the demonstrations already recorded there (or None)."""
    from ..demos.csv_io import read_demos_csv

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a directory")
    if not out_dir.exists() and not out_dir.parent.is_dir():
        raise InputError(f"{out_dir.parent}: output directory does not exist")
    mdp = zone_map.to_mdp()
    if mdp.n_actions != len(ACTION_NAMES) or mdp.state_xy is None:
        raise InputError(f"{zone_map.name}: the live page needs a grid map with the four moves")
    _check_same_map(out_dir / RESULT_NAME, settings or {})
    demos = out_dir / DEMOS_NAME
    if not (demos.is_file() and demos.stat().st_size > 0):
        return None
    trajs = read_demos_csv(demos, mdp)
    _check_appendable(demos, demos_header(mdp))
    return trajs


def _check_appendable(demos: Path, header: tuple[str, ...]) -> None:
    """Refuse a ``demos.csv`` whose columns are not those the session appends."""
    with open(demos, encoding="utf-8-sig", newline="") as fh:
        got = tuple(c.strip().lower() for c in fh.readline().strip().split(","))
    if got != header:
        raise InputError(f"{demos}: columns {','.join(got)}, but the live page appends rows "
                         f"{','.join(header)} on this map; choose another --out")


def _check_same_map(result: Path, settings: dict[str, Any]) -> None:
    import json

    if not result.is_file() or "mdp_digest" not in settings:
        return
    try:
        old = json.loads(result.read_text(encoding="utf-8")).get("settings", {})
    except (OSError, ValueError, AttributeError):
        return
    digest = old.get("mdp_digest") if isinstance(old, dict) else None
    if digest is not None and digest != settings["mdp_digest"]:
        raise InputError(f"{result}: this directory was recorded on another map ({old.get('mdp')}); "
                         "choose another --out")


def _previous_live(result: Path) -> dict[str, Any]:
    """The ``live`` section of a previous session's ``result.json`` (empty if there is none)."""
    import json

    try:
        live = json.loads(result.read_text(encoding="utf-8"))["live"]
    except (OSError, ValueError, KeyError, TypeError):
        return {}
    return live if isinstance(live, dict) else {}


def _previous_mode(live: dict[str, Any], default: str) -> str:
    """The start mode a previous session left (``live.mode``; before it was saved, how the last
    start was chosen), else ``default``."""
    mode = live.get("mode")
    if mode in MODES:
        return mode
    starts = live.get("starts")
    last = starts[-1] if isinstance(starts, list) and starts else None
    how = last.get("how") if isinstance(last, dict) else None
    return how if how in MODES else default
