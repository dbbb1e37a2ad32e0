"""Live commands: ``live`` (the tele-operation page) and ``next-start`` (active start choice)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ..errors import InputError, os_reason, plural
from ._app import (
    GoalRewardOption,
    _load_mdp,
    _note,
    _progress,
    _say,
    _solve_progress,
    _warn,
    app,
    handles_errors,
    load_map,
    prepare_solver,
)

THETAS_HELP = ("Θ: a preset (paper-sim, paper-real) or comma-separated component values; the unit-l1 "
               "grid over all features is built from them. Naming a set (--thetas or --betas) uses it "
               "as given; the other defaults to paper-real Θ, paper-sim B. Default: an adaptive set "
               "(see --refine).")
BETAS_HELP = "B: a preset (paper-sim, paper-real) or comma-separated temperatures."
REFINE_HELP = ("Refine the hypothesis set where the posterior's mass is (β log-spaced, θ on the simplex) "
               "until β̂, E[θ] and the 90% intervals settle, as infer does. Default: refine when no set "
               "is named; --no-refine alone is the paper-real Θ × paper-sim B set.")
LIVE_MODEL_HELP = ("maxent: the person does the task (the paper's model, the default); pedagogical: the "
                   "person may be teaching (docs/teaching.md): the estimate is the teaching model's over a "
                   "fixed set (no --refine; default paper-real Θ × paper-sim B), and the page reads the "
                   "demonstrations as teaching, doing or undecided.")
LAMBDAS_HELP = ("--model pedagogical: the grid of teaching weights λ (comma-separated numbers >= 0, 0 among "
                "them). Default: 0,0.003,0.01,0.03,0.1,0.3,1.")
RefineOption = Annotated[bool | None, typer.Option("--refine/--no-refine", help=REFINE_HELP,
                                                   show_default=False)]


def _options(thetas: str | None, betas: str | None, refine: bool | None, expertise: str = "stationary"):
    """The discrete method's options (the live page and next-start run that method)."""
    from ..inference.methods import DiscreteOptions

    return DiscreteOptions(thetas=thetas, betas=betas, refine=refine, expertise=expertise)


def _set_settings(opts, hyp) -> dict:
    """The hypothesis set's entries of the result's settings (those of ``infer``)."""
    from ..options import ADAPTIVE, DEFAULT_BETAS, DEFAULT_THETAS

    kind = ADAPTIVE if opts.refines else "fixed"
    return {"thetas": opts.thetas or (ADAPTIVE if opts.refines else DEFAULT_THETAS.value),
            "betas": opts.betas or (ADAPTIVE if opts.refines else DEFAULT_BETAS.value), "hypotheses": kind,
            "n_theta": hyp.n_theta, "n_beta": hyp.n_beta, "n_hypotheses": len(hyp), "prior": "uniform"}


def _teaching_settings(model: str, lambdas: str | None) -> dict:
    """The teaching model's entries of the settings (its λ grid), empty for maxent."""
    from ..inference.pedagogical import LAMBDAS, parse_lambdas

    if model != "pedagogical":
        return {}
    return {"lambdas": parse_lambdas(LAMBDAS if lambdas is None else lambdas).tolist()}


@app.command()
@handles_errors
def live(
    map_spec: Annotated[str, typer.Argument(metavar="MAP", help=(
        "Map file or bundled map name: a zone map, or a warehouse floor plan (a TOML beside it "
        "says world = \"warehouse\"; demos.csv then has the heading column)."))],
    thetas: Annotated[str | None, typer.Option(help=THETAS_HELP, show_default=False)] = None,
    betas: Annotated[str | None, typer.Option(help=BETAS_HELP, show_default=False)] = None,
    refine: RefineOption = None,
    out_dir: Annotated[Path, typer.Option(
        "--out", help="Directory for demos.csv (every action, appended as it happens) and result.json "
        "(rewritten after each episode); a directory that already holds demos.csv is resumed.")] = Path(
        "expertise-irl-live"),
    port: Annotated[int, typer.Option(min=0, max=65535, help="TCP port (0: any free port).")] = 8765,
    host: Annotated[str, typer.Option(
        help="Address to bind. The default, 127.0.0.1, is reachable from this machine only.")] = "127.0.0.1",
    seed: Annotated[int, typer.Option(min=0, help="Seed of the start choices (active and random).")] = 0,
    goal_reward: GoalRewardOption = None,
    expertise: Annotated[str, typer.Option(
        help="changing: also show the β of the episode being driven, filtered from the actions so far "
        "(a β per episode, docs/changing-expertise.md); stationary: one β (the default).")] = "stationary",
    model: Annotated[str, typer.Option("--model", help=LIVE_MODEL_HELP)] = "maxent",
    lambdas: Annotated[str | None, typer.Option(help=LAMBDAS_HELP, show_default=False)] = None,
) -> None:
    """Serve a local page where a person drives on the map and the estimate updates after every action.

    Drive with the arrow keys or WASD (or the on-screen buttons). After each episode (it ends
    at a goal) the robot picks the next start: the one whose episode is expected to tell the
    most about θ and β, or a random one (a toggle on the page). With no set named, the set
    starts coarse and is refined from every finished episode after each one. With --model
    pedagogical the set is fixed and the page also says whether the demonstrations read as
    teaching. Stop with Ctrl-C; run again with the same --out to continue.
    """
    from ..live.server import bind, is_loopback, serve
    from ..live.session import check_live_model, check_out_dir, open_session
    from ..options import Expertise, choose
    from ..results import map_digest

    choose(Expertise, expertise, "expertise")
    check_live_model(model, refine=refine or None, expertise=expertise, lambdas=lambdas)
    teaching = _teaching_settings(model, lambdas)
    zone_map = load_map(map_spec, goal_reward)
    mdp = zone_map.to_mdp()
    opts = _options(thetas, betas, False if teaching else refine, expertise)
    hyp = opts.hypotheses(mdp.n_features)
    settings = {"command": "live", "method": "discrete", "mdp": str(map_spec),
                "mdp_digest": map_digest(zone_map), "goal_bonus": zone_map.goal_bonus,
                "goal_reward_mode": zone_map.goal_reward_mode, **_set_settings(opts, hyp),
                "gamma": mdp.gamma, "seed": seed, "model": model, **teaching}
    check_out_dir(zone_map, out_dir, settings)  # before the solve: a bad DIR fails at once
    if not is_loopback(host):
        _warn(f"--host {host}: the page is reachable from other machines; anyone who can reach it can "
              "drive and read the estimate")
    try:
        sock = bind(host, port)
    except OSError as exc:
        raise InputError(f"--host {host} --port {port}: cannot listen there ({os_reason(exc)})") from None
    try:
        prepare_solver()
        with _progress() as bar:
            session = open_session(zone_map, hyp, out_dir, settings=settings, seed=seed,
                                   progress=_solve_progress(bar, "solving soft value iteration"),
                                   expertise=expertise, refine=opts if opts.refines else None,
                                   model=model, lambdas=teaching.get("lambdas"))
    except BaseException:
        sock.close()
        raise
    est = session.estimator
    if est.n_observed:
        _note(f"resumed {plural(est.n_episodes, 'episode')}, {plural(est.n_observed, 'action')} from "
              f"{session.demos_path}")

    def ready(url: str) -> None:
        size = f"{len(est.hypotheses)} hypotheses" + (", refined after each episode" if opts.refines else "")
        if teaching:
            size += f", teaching model over {len(teaching['lambdas'])} values of λ"
        _say(f"live page: {url}  ({size} on {zone_map.name}; recording to {out_dir}; Ctrl-C to stop)")
        import sys

        sys.stdout.flush()

    try:
        serve(session, sock, on_ready=ready)
    except KeyboardInterrupt:  # uvicorn shuts down cleanly, then re-raises the Ctrl-C
        pass
    _say(f"stopped: {plural(session.estimator.n_observed, 'action')} in {session.demos_path}")


@app.command("next-start")
@handles_errors
def next_start_cmd(
    map_spec: Annotated[str | None, typer.Argument(
        metavar="MAP", help="Map file (zone map or warehouse floor plan) or bundled map name.")] = None,
    demos: Annotated[Path | None, typer.Option(
        help="Demonstrations so far (CSV, episode,step,x,y[,heading] or episode,step,state,action).")] = None,
    mdp_path: Annotated[Path | None, typer.Option("--mdp", help="MDP archive (.npz) instead of MAP.")] = None,
    thetas: Annotated[str | None, typer.Option(help=THETAS_HELP, show_default=False)] = None,
    betas: Annotated[str | None, typer.Option(help=BETAS_HELP, show_default=False)] = None,
    refine: RefineOption = None,
    samples: Annotated[int, typer.Option(min=1, help="Simulated episodes per candidate start.")] = 48,
    max_steps: Annotated[int, typer.Option(min=1, help="Length cap of a simulated episode.")] = 100,
    candidates: Annotated[int, typer.Option(
        min=1, help="At most this many candidate starts are scored (a seeded subsample).")] = 32,
    target: Annotated[str, typer.Option(
        help="joint: information about (θ, β); beta: about the expertise β only.")] = "joint",
    seed: Annotated[int, typer.Option(min=0, help="Random seed (the answer is a function of it).")] = 0,
    goal_reward: GoalRewardOption = None,
) -> None:
    """Pick the start whose next episode is expected to tell the most about θ and β.

    Candidates are the map's start cells (S), or every non-goal cell if it has none. The
    score of a start is the expected reduction of the posterior entropy (nats) after one
    episode from it, estimated by simulating episodes under hypotheses drawn from the
    posterior given --demos.
    """
    from ..demos.csv_io import read_demos_csv
    from ..inference.active import TARGETS, expected_information_gain
    from ..inference.belief import DiscreteBelief
    from ..options import one_of

    if demos is None:
        raise InputError("--demos is required: the demonstrations observed so far (CSV)")
    one_of(target, TARGETS, "target")
    mdp, _ = _load_mdp(map_spec, mdp_path, goal_reward)
    trajs = read_demos_csv(demos, mdp)
    opts = _options(thetas, betas, refine)
    hyp = opts.hypotheses(mdp.n_features)
    prepare_solver()
    with _progress() as bar:
        tick = _solve_progress(bar, "solving soft value iteration")
        if opts.refines:  # the set the live page would be on after these episodes
            from ..inference.methods import refined_set

            r = refined_set(mdp, trajs, hyp, opts, tick)
            for w in r.warnings:
                _warn(w)
            prior = DiscreteBelief.from_log_policy(r.hypotheses, r.log_policy, prior=r.prior)
        else:
            prior = DiscreteBelief.from_mdp(mdp, hyp, progress=tick)
    post = prior.update(trajs)
    sc = expected_information_gain(post, None, mdp, n_samples=samples, max_steps=max_steps,
                                   max_candidates=candidates, target=target, rng=seed)
    order = np.argsort(-sc.gain, kind="stable")
    best = sc.best
    i = int(np.searchsorted(sc.candidates, best))
    where = mdp.describe_state(best)
    scored = (f"{sc.candidates.size} of {sc.n_offered} candidate starts scored" if sc.n_offered >
              sc.candidates.size else f"{sc.candidates.size} candidate starts")
    _say(f"next start: {where}: expected information gain {sc.gain[i]:.3f} ± {sc.stderr[i]:.3f} nats "
         f"({target}; entropy now {sc.entropy:.3f} nats; {scored})")
    for j in order[:5]:
        _say(f"  {mdp.describe_state(int(sc.candidates[j]))}: {sc.gain[j]:.3f} ± {sc.stderr[j]:.3f}")
