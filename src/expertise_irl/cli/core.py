"""Core commands: ``demo | simulate | infer | export-mdp | render | maps``."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..errors import InputError, plural
from ..result import Result
from ._app import (
    GoalRewardOption,
    ModelOption,
    _check_beta,
    _check_model,
    _load_mdp,
    _map_files,
    _note,
    _parse_theta,
    _progress,
    _report_capped,
    _say,
    _say_capped,
    _solve_progress,
    _warn,
    app,
    handles_errors,
    load_map,
    out,
    prepare_solver,
    with_goal_reward,
)


# --------------------------------------------------------------------------- commands
@app.command()
@handles_errors
def demo(
    seed: Annotated[int, typer.Option(min=0, help="Random seed: map, hypothesis set, truth, episodes.")] = 0,
    out_dir: Annotated[Path, typer.Option(
        "--out", help="Directory for demo-seedN.png and result-seedN.json (demo-MAP-seedN.png and "
        "result-MAP-seedN.json with --map).")] = Path(
        "expertise-irl-demo"
    ),
    map_spec: Annotated[
        str | None, typer.Option("--map", help="Map file or bundled map name (default: a random map).")
    ] = None,
    episodes: Annotated[int, typer.Option(min=1, help="Episodes the simulated person demonstrates.")] = 20,
    k: Annotated[int, typer.Option(min=1, help="Preference vectors in the hypothesis set Θ_k.")] = 20,
    model: ModelOption = "maxent",
    beta: Annotated[float | None, typer.Option(
        "--beta", help="The person's expertise β*, one of the paper's 0.01, 0.09, 0.5, 1, 5, 10 "
        "(default: an expert, 0.01 or 0.09, drawn by --seed; --beta 10 is a novice).")] = None,
    goal_reward: GoalRewardOption = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite this seed's figure and result.")] = False,
) -> None:
    """Simulate a person on a map, infer their expertise and preferences, and report."""
    from ..experiments.demo import demo_outputs, run_demo
    from ..pipeline import discrete_result
    from ..plots.maps import render_demo_png
    from ..results import check_writable, write_result
    from ..worlds.grid import check_goal_reward_mode
    from ..worlds.zones import resolve_map

    _check_model(model)
    if goal_reward is not None:
        check_goal_reward_mode(goal_reward, "--goal-reward")
    zone_map = with_goal_reward(resolve_map(map_spec), goal_reward) if map_spec else None
    if zone_map is not None:
        zone_map.to_mdp()  # validate the map before any output is started
    mode = zone_map.goal_reward_mode if zone_map is not None else (goal_reward or "scaled")
    png, js = demo_outputs(out_dir, seed, map_spec, beta, mode)  # refuses a β* not among the paper's
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a directory")
    out_dir.mkdir(parents=True, exist_ok=True)
    for p in (png, js):
        check_writable(p, force=force, inputs=_map_files(map_spec))
    prepare_solver()
    t0 = time.perf_counter()
    with _progress() as bar:
        run = run_demo(seed, zone_map=zone_map, goal_reward_mode=goal_reward, episodes=episodes, k=k,
                       model=model, beta=beta, progress=_solve_progress(bar, "solving soft value iteration"))
    elapsed = time.perf_counter() - t0
    s = run.summary()
    names = run.mdp.feature_names
    _say(f"map {run.zone_map.name}: {run.mdp.n_states} states; {len(run.hypotheses)} hypotheses "
         f"({run.hypotheses.n_theta} θ × {run.hypotheses.n_beta} β); "
         f"{plural(run.trajectories.n_episodes, 'episode')}, {plural(len(run.trajectories), 'action')}")
    table = Table(title=escape(f"expertise-irl demo, seed {seed}: true vs inferred"))
    table.add_column("")
    table.add_column("true", justify="right")
    table.add_column("inferred", justify="right")
    table.add_row("expertise β", f"{s['beta_true']:g}", f"{s['beta_hat']:.3g}")
    table.add_row("expertise group", s["group_true"], s["group_hat"])
    for i, n in enumerate(names):
        table.add_row(f"θ {n}", f"{s['theta_true'][i]:.3f}", f"{s['theta_hat'][i]:.3f}")
    table.add_row("P(θ*, β*) (joint posterior)", "", f"{s['truth_probability']:.3f}")
    table.add_row("expertise distance |β*−β̂|", "", f"{s['expertise_distance']:.3g}")
    table.add_row("cosine similarity (θ*, θ̂)", "", f"{s['cosine_similarity']:.3f}")
    table.add_row("policy regret (Eq. 17)", "", f"{s['policy_regret']:.3g}")
    table.add_row("return regret (θ̂'s optimal policy)", "", f"{s['return_regret']:.3g}")
    out.print(table)
    b = run.belief
    render_demo_png(png, run, title=f"seed {seed}: β*={run.beta_true:g}, β̂={b.mean_beta:.3g}")
    result = discrete_result(
        b, feature_names=names,
        settings={"command": "demo", "seed": seed, "map": run.zone_map.name, "episodes": episodes,
                  "k": k, "thetas": "paper-sim (sampled k)", "betas": "paper-sim", "beta": beta,
                  "model": model,
                  "gamma": run.mdp.gamma, "goal_bonus": run.zone_map.goal_bonus,
                  "goal_reward_mode": run.zone_map.goal_reward_mode},
        data={"episodes": run.trajectories.n_episodes, "actions": len(run.trajectories),
              "capped_episodes": _report_capped(run.trajectories, run.mdp, run.max_steps, model)},
        extra={"truth": {"theta": s["theta_true"], "beta": s["beta_true"], "group": s["group_true"],
                         "probability": s["truth_probability"]},
               "metrics": {k_: s[k_] for k_ in ("expertise_distance", "cosine_similarity", "policy_regret",
                                                "return_regret")}},
        run_time_s=elapsed)
    write_result(js, result)
    _say(f"wrote {png} and {js} ({elapsed:.1f} s)")


@app.command("export-mdp")
@handles_errors
def export_mdp(
    map_spec: Annotated[str, typer.Argument(metavar="MAP", help="Map file or bundled map name.")],
    out_path: Annotated[Path, typer.Option("--out", help="Output .npz archive.")],
    goal_reward: GoalRewardOption = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output if it exists.")] = False,
) -> None:
    """Compile a text map to the MDP archive (.npz) that every command accepts."""
    from ..results import check_writable

    check_writable(out_path, force=force, inputs=_map_files(map_spec))
    mdp = load_map(map_spec, goal_reward).to_mdp()
    mdp.save(out_path)
    _say(f"wrote {out_path}: {mdp.n_states} states, {mdp.n_actions} actions, "
              f"features {', '.join(mdp.feature_names)}, gamma {mdp.gamma:g}"
              + (", a fixed goal reward" if mdp.has_offset else ""))


@app.command()
@handles_errors
def simulate(
    out_path: Annotated[Path, typer.Option("--out", help="Output demonstrations CSV.")],
    theta: Annotated[str, typer.Option(help="Preferences θ*, comma-separated (normalised to unit l1).")],
    beta: Annotated[float, typer.Option(help="Expertise temperature β* > 0 (small = expert).")],
    map_spec: Annotated[str | None, typer.Argument(metavar="MAP", help="Map file or bundled name.")] = None,
    mdp_path: Annotated[Path | None, typer.Option("--mdp", help="MDP archive (.npz) instead of MAP.")] = None,
    episodes: Annotated[int, typer.Option(min=1, help="Number of episodes.")] = 20,
    seed: Annotated[int, typer.Option(min=0, help="Random seed.")] = 0,
    max_steps: Annotated[int, typer.Option(min=1, help="Episode length cap (actions).")] = 500,
    model: ModelOption = "maxent",
    lam: Annotated[float | None, typer.Option(
        "--lambda", help="--model pedagogical: the teaching weight λ >= 0 (reward units per nat of the "
        "observer's belief about θ; default 0, a doer who does not teach).", show_default=False)] = None,
    observer_thetas: Annotated[str | None, typer.Option(
        help="--model pedagogical: the literal observer's Θ, as infer's --thetas (default paper-real).",
        show_default=False)] = None,
    observer_betas: Annotated[str | None, typer.Option(
        help="--model pedagogical: the literal observer's B, as infer's --betas (default paper-sim).",
        show_default=False)] = None,
    goal_reward: GoalRewardOption = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output if it exists.")] = False,
) -> None:
    """Simulate a person with preferences θ* and expertise β*; write demonstrations CSV.

    The person acts by --model (default maxent, the paper's). With --model pedagogical the person
    teaches a literal observer who believes in the set --observer-thetas × --observer-betas: each
    action's maxent probability is reweighted by exp(λ/β* · what the action tells the observer
    about θ*), λ from --lambda (0: a doer). Episodes that run to --max-steps without reaching a goal
    are counted on stderr. More than 100,000 episodes are simulated and written in batches of
    100,000, with a size estimate first and a progress bar; the CSV appears at --out only once
    complete (Ctrl-C or SIGTERM leave nothing there).
    """
    from ..demos.csv_io import demos_csv_stream, stream_format
    from ..demos.simulation import BATCH_EPISODES, capped_episodes, simulate_batches
    from ..models import check_model
    from ..results import check_writable

    check_writable(out_path, force=force, inputs=[*_map_files(map_spec), mdp_path])
    mdp, _ = _load_mdp(map_spec, mdp_path, goal_reward)
    th = _parse_theta(theta, mdp.n_features, mdp.feature_names, fixed_reward=mdp.has_offset)
    _check_beta(beta)
    check_model(model, solvable=False)
    teacher = _teacher_options(mdp, model, lam, observer_thetas, observer_betas)
    lp = None if teacher is None else _teacher_policy(mdp, th, beta, *teacher[:2])
    big = episodes > BATCH_EPISODES
    fmt = stream_format(mdp) if big else "auto"  # (one batch: the format its episodes allow)
    if big:
        _size_estimate(out_path, mdp, th, beta, episodes, seed, max_steps, model, fmt, lp)
    n_actions = n_capped = 0
    with demos_csv_stream(out_path, mdp, fmt=fmt) as write, _progress("episodes") as bar:
        task = bar.add_task("simulating", total=episodes) if big else None
        for trajs in simulate_batches(mdp, th, beta, episodes, np.random.default_rng(seed),
                                      max_steps=max_steps, model=model if lp is None else "maxent",
                                      log_policy=lp):
            write(trajs)
            n_actions += len(trajs)
            n_capped += capped_episodes(trajs, mdp, max_steps)
            if task is not None:
                bar.update(task, advance=trajs.n_episodes)
    how = f"model {model}" if teacher is None else \
        f"model {model}, λ={teacher[0]:g}, observer {teacher[2]}: {len(teacher[1])} hypotheses"
    _say(f"wrote {out_path}: {plural(episodes, 'episode')}, {plural(n_actions, 'action')} "
         f"(θ*={np.round(th, 4).tolist()}, β*={beta:g}, {how})")
    _say_capped(n_capped, episodes, max_steps, model)


def _teacher_options(mdp, model: str, lam: float | None, thetas: str | None, betas: str | None):
    """``(λ, observer's set, the set in words)`` of a pedagogical teacher; None for another model,
    which takes none of --lambda, --observer-thetas, --observer-betas."""
    import math

    from ..hypotheses import HypothesisSet, resolve_betas, resolve_thetas
    from ..models import PEDAGOGICAL
    from ..options import DEFAULT_BETAS, DEFAULT_THETAS

    if model != PEDAGOGICAL:
        for flag_, value in (("--lambda", lam), ("--observer-thetas", thetas), ("--observer-betas", betas)):
            if value is not None:
                raise InputError(f"{flag_} applies only to --model pedagogical, not to --model {model}")
        return None
    from ..planning.teaching import MAX_LAMBDA

    lam = 0.0 if lam is None else float(lam)
    if not (math.isfinite(lam) and 0 <= lam <= MAX_LAMBDA):
        raise InputError(f"--lambda must be a number from 0 to {MAX_LAMBDA:g}, got {lam:g}")
    try:
        th = resolve_thetas(thetas or DEFAULT_THETAS, mdp.n_features)
    except InputError as e:
        raise InputError(str(e).replace("--thetas", "--observer-thetas", 1)) from None
    try:
        b = resolve_betas(betas or DEFAULT_BETAS)
    except InputError as e:
        raise InputError(str(e).replace("--betas", "--observer-betas", 1)) from None
    return lam, HypothesisSet(th, b), f"{thetas or DEFAULT_THETAS} Θ × {betas or DEFAULT_BETAS} B"


def _teacher_policy(mdp, theta, beta: float, lam: float, hypotheses) -> np.ndarray:
    """``[S, A]`` log-policy of the teacher (θ, β, λ) before the literal observer of ``hypotheses``
    (one maxent solve of the set, with a progress bar)."""
    from ..inference.pedagogical import solved_observer, teacher_log_policy

    prepare_solver()
    with _progress() as bar:
        obs = solved_observer(mdp, hypotheses, progress=_solve_progress(bar, "solving the observer's set"))
    return teacher_log_policy(mdp, theta, beta, lam, obs)


def _size_estimate(out_path: Path, mdp, theta, beta: float, episodes: int, seed: int, max_steps: int,
                   model: str, fmt: str, log_policy=None) -> None:
    """A note of the CSV's expected size and actions, from 1,000 trial episodes (their own random
    stream: the run's episodes are not changed by it); a warning when the folder has less room."""
    import shutil

    from ..demos.csv_io import csv_bytes
    from ..demos.simulation import simulate as simulate_episodes

    trial = simulate_episodes(mdp, theta, beta, 1000, np.random.default_rng([seed, 1]), max_steps=max_steps,
                              model=model if log_policy is None else "maxent", log_policy=log_policy)
    size = csv_bytes(trial, mdp, fmt) * episodes / trial.n_episodes
    actions = len(trial) * episodes / trial.n_episodes
    _note(f"{episodes:,} episodes: about {_bytes(size)} and {actions:,.0f} actions to write to {out_path} "
          "(estimated from 1,000 trial episodes)")
    free = shutil.disk_usage(out_path.parent if str(out_path.parent) else Path(".")).free
    if size > free:
        _warn(f"{out_path.parent}: {_bytes(free)} free, less than the about {_bytes(size)} this run writes")


def _bytes(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB"):
        if n < 1000:
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"


@app.command()
@handles_errors
def infer(
    ctx: typer.Context,
    demos: Annotated[Path, typer.Option(help="Demonstrations CSV (episode,step,state,action or x,y).")],
    out_path: Annotated[Path, typer.Option("--out", help="Output result JSON.")],
    map_spec: Annotated[str | None, typer.Argument(metavar="MAP", help="Map file or bundled name.")] = None,
    mdp_path: Annotated[Path | None, typer.Option("--mdp", help="MDP archive (.npz) instead of MAP.")] = None,
    thetas: Annotated[str | None, typer.Option(
        help="Θ: a preset (paper-sim, paper-real) or comma-separated component values; "
        "the unit-l1 grid over all features is built from them. Naming a set (--thetas, --betas or "
        "--sample-thetas) uses it as given; the other defaults to paper-real Θ, paper-sim B. "
        "Default: an adaptive set (see --refine).", show_default=False)] = None,
    betas: Annotated[str | None, typer.Option(
        help="B: a preset (paper-sim, paper-real) or comma-separated temperatures.",
        show_default=False)] = None,
    refine: Annotated[bool | None, typer.Option(
        "--refine/--no-refine", help="Refine the hypothesis set where the posterior's mass is (β "
        "log-spaced, θ on the simplex) until β̂, E[θ] and the 90% intervals settle; the result's "
        "`refinement` records each round. Default: refine when no set is named; --no-refine alone "
        "is the paper-real Θ × paper-sim B set.", show_default=False)] = None,
    max_seconds: Annotated[float | None, typer.Option(
        help="discrete with refinement: no new round starts after this many seconds; the refinement "
        "stops there with a warning and the posterior so far.", show_default=False)] = None,
    max_hypotheses: Annotated[int, typer.Option(
        min=1, help="discrete with refinement: the most hypotheses solved in all; the refinement "
        "stops there with a warning and the posterior so far.")] = 20_000,
    sample_thetas: Annotated[int | None, typer.Option(
        min=1, help="Use only k preference vectors drawn at random (--seed) from Θ.")] = None,
    seed: Annotated[int, typer.Option(
        min=0, help="Seed of every random choice: --sample-thetas, and the chains and starts of "
        "birl, map and nuts.")] = 0,
    per_action: Annotated[bool, typer.Option(
        "--per-action", help="Update after every action and record the live estimates (trace).")] = False,
    tol: Annotated[float | None, typer.Option(
        help="Soft value iteration tolerance (nats). Default (discrete): the one the demonstrations need "
        "for every posterior probability to be within 1e-6 of the exact one, after hypotheses certainly "
        "too unlikely to matter stop at a looser one.")] = None,
    chunk_size: Annotated[int | None, typer.Option(
        min=1, help="Hypotheses in flight at once in the solver (default: sized to the map).")] = None,
    method: Annotated[str, typer.Option(
        help="discrete (hypothesis set, Eq. 13), birl (Algorithm 1), map (L-BFGS on the simplex) "
        "or nuts (full posterior).")] = "discrete",
    model: ModelOption = "maxent",
    lambdas: Annotated[str | None, typer.Option(
        help="discrete with --model pedagogical: the teaching weight's grid, comma-separated, 0 (a doer) "
        "among them (default 0,0.003,0.01,0.03,0.1,0.3,1); its prior puts half the mass on 0.",
        show_default=False)] = None,
    expertise: Annotated[str, typer.Option(
        help="discrete: stationary (one β for every episode, the paper's) or changing (a β per "
        "episode, a sticky chain on the β grid: the learning curve, its Bayes factor against "
        "stationary and the trend; beta_hat stays the stationary estimate).")] = "stationary",
    prior: Annotated[str, typer.Option(
        help="birl, map, nuts: the prior. log-uniform (default): θ uniform, log β uniform on "
        "[0.001, 100]; paper (Sec. VII-A): θ uniform, β ~ Normal(5.005, 1.5) truncated to "
        "[0.01, 10], which pulls β̂ towards 5.")] = "log-uniform",
    concentration: Annotated[float | None, typer.Option(
        help="map, nuts: θ ~ Dirichlet(α) on the simplex, α > 0 (default 1: uniform; larger pulls θ̂ "
        "towards equal weights). MAP's mode is taken in its coordinates θ = softmax(z), log β, where "
        "it maximises likelihood × ∏θ_i^α × p(β)·β (docs/model.md).", show_default=False)] = None,
    iterations: Annotated[int, typer.Option(min=1, help="birl: iterations K.")] = 1000,
    delta: Annotated[float, typer.Option(help="birl: θ grid step δ.")] = 0.05,
    beta_step: Annotated[float, typer.Option(help="birl: β grid step.")] = 0.1,
    variant: Annotated[str, typer.Option(help="birl: 'box' (as printed) or 'simplex' (‖θ‖₁ = 1).")] = "box",
    starts: Annotated[int, typer.Option(min=1, help="map: random starts.")] = 4,
    chains: Annotated[int, typer.Option(min=1, help="nuts: chains.")] = 4,
    warmup: Annotated[int, typer.Option(min=1, help="nuts: warm-up steps per chain.")] = 500,
    samples: Annotated[int, typer.Option(min=1, help="nuts: draws per chain.")] = 500,
    goal_reward: GoalRewardOption = None,
    check: Annotated[str, typer.Option(
        "--check", help="Low expertise or missing features? off, fast (posterior predictive checks, the "
        "default) or full (also a per-state reward fitted with β, compared on held-out episodes): "
        "diagnostics.misspecification, a warning when the features do not explain the behaviour, "
        "and features whose θ the task cannot identify.")] = "fast",
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output if it exists.")] = False,
) -> None:
    """Infer expertise β and preferences θ from demonstrations.

    The default method is the paper's discrete hypothesis set (Eq. 13, uniform prior over
    the set); birl, map and nuts search the continuous space (θ on the simplex or box,
    β > 0) under --prior: by default log-uniform (θ uniform, log β uniform on [0.001, 100]),
    or the paper's (Sec. VII-A: β ~ Normal(5.005, 1.5) truncated to [0.01, 10]) with
    --prior paper. --model chooses the observation model for every method (pedagogical: the
    discrete method on a fixed set, with the teaching weight's grid --lambdas; the result's
    `teaching` says whether the demonstrations read as teaching). --seed makes every method
    reproducible. Convergence warnings go to stderr and to the result's
    diagnostics.warnings.
    """
    from ..inference.methods import get_method
    from ..inference.misspecification import check_level
    from ..pipeline import as_demos, prepare, refuse_check
    from ..results import INLINE_DRAWS, check_writable, samples_path_for, write_result

    chosen = get_method(method)
    check_level(check)
    _refuse_options_of_other_methods(ctx, method)
    inputs = [demos, *_map_files(map_spec), mdp_path]
    check_writable(out_path, force=force, inputs=inputs)
    opts = chosen.options_from(ctx.params)
    _refuse_caps_without_refinement(ctx, opts)
    refuse_check(opts, check)
    world = _world(map_spec, mdp_path, goal_reward)
    data = as_demos(demos, world)
    prepare_solver(measure=chosen.measure_lanes)  # the others solve one hypothesis at a time
    samples_path = samples_path_for(out_path)
    if opts.max_draws > INLINE_DRAWS:
        check_writable(samples_path, force=force, inputs=inputs)
    # notes (the prior, a capped set) before the bar
    job = prepare(world, data, method, options=opts, seed=seed, check=check, note=_note, command="infer")
    with _progress(job.unit) as bar:
        result = job.run(progress=_solve_progress(bar, job.progress_label))
    result = write_result(out_path, result, samples_path=samples_path)
    _report_result(result, out_path, len(data.trajectories), check_s=result.timing.get("checks_s"))


def _world(map_spec, mdp_path, goal_reward):
    """The task of MAP or --mdp with its name and digest, as the result records them."""
    from ..pipeline import World
    from ..results import file_digest, map_digest

    mdp, zone_map = _load_mdp(map_spec, mdp_path, goal_reward)
    if mdp_path is not None:
        return World(mdp, None, str(mdp_path), file_digest(mdp_path))
    return World(mdp, zone_map, str(map_spec), map_digest(zone_map))


def _report_result(result: Result, out_path: Path, n_actions: int, check_s: float | None = None) -> None:
    """The estimate, its interval or impossible hypotheses, the misspecification verdict, the warnings
    and what was written (``check_s``: the seconds the checks took, beside the inference's)."""
    names, est = result.feature_names, result.estimate
    theta_str = ", ".join(f"{n}={v:.3f}" for n, v in zip(names, est.theta_hat, strict=True))
    _say(f"β̂ = {est.beta_hat:.4g} ({est.expertise_group} expertise), θ̂ = [{theta_str}]")
    n_hypotheses = result.settings.n_hypotheses
    if result.posterior is not None and result.posterior.n_impossible:
        _note(f"{result.posterior.n_impossible} of {n_hypotheses} hypotheses cannot produce the "
              "demonstrations")
    ci = est.credible_intervals
    if ci and ci["beta"] is None:
        _say("90% credible interval of β: none (a chain did not move in β; see the warning)")
    elif ci:
        kind = "Laplace 90% interval" if result.method == "map" else "90% credible interval"
        _say(f"{kind} of β: [{ci['beta'][0]:.4g}, {ci['beta'][1]:.4g}]")
    if result.changing is not None and result.changing.evidence:
        ch, curve, tr = result.changing.evidence, result.changing.by_episode, result.changing.trend
        bf = ch["log_bayes_factor"]
        if bf is not None:
            _say(f"changing expertise: log Bayes factor {bf:.2f} against one β (P(changing) = "
                 f"{ch['p_changing']:.3g}); β̂ by episode {curve[0]['mean']:.3g} → {curve[-1]['mean']:.3g}, "
                 f"P(β falls from the first episode to the last) = {tr['p_falls']:.2f}")
        else:
            _say(f"learning curve: log β_e = log β_0 + λ·{tr['g']}, β̂_0 = {tr['beta0']:.3g}, λ̂ = "
                 f"{tr['slope']:.3g} (β̂ by episode {curve[0]['mean']:.3g} → {curve[-1]['mean']:.3g})")
    if result.teaching is not None:
        t = result.teaching
        lo, hi = t.lambda_interval
        _say(f"teaching: {t.reading}; λ̂ = {t.lambda_hat:.3g}, 90% credible interval [{lo:.3g}, {hi:.3g}]")
    mis = result.misspecification
    if mis:
        _say(f"check ({mis.check}): {mis.verdict} ({mis.reason})")
    for w in result.warnings:
        _warn(w)
    extra = f" and {result.samples}" if isinstance(result.samples, str) else ""
    what = f"{n_hypotheses} hypotheses" if result.method == "discrete" else result.method
    took = f"{result.run_time_s:.1f} s" + (f", checks {check_s:.1f} s" if mis and check_s is not None else "")
    _say(f"wrote {out_path}{extra} ({what}, {plural(n_actions, 'action')}, {took})")


def _refuse_options_of_other_methods(ctx: typer.Context, method: str) -> None:
    from ..inference.methods import option_owners

    for name, methods in option_owners().items():
        if method in methods:
            continue
        source = ctx.get_parameter_source(name)  # typer's own click: compare by name
        if source is not None and source.name not in ("DEFAULT", "DEFAULT_MAP"):
            flag = "--" + name.replace("_", "-")
            which = " or ".join(f"--method {m}" for m in methods)
            raise InputError(f"{flag} applies only to {which}, not to --method {method}")


def _refuse_caps_without_refinement(ctx: typer.Context, opts) -> None:
    """--max-seconds and --max-hypotheses cap the refinement: given for a set that is not refined
    they would do nothing, so they are refused rather than ignored."""
    if getattr(opts, "refines", True):
        return
    fixed = getattr(opts, "model", None) == "pedagogical"
    why = ("--model pedagogical, whose set is fixed before the data): leave it out" if fixed else
           "a named set, --no-refine or --expertise changing): leave it out, or add --refine")
    for name in ("max_seconds", "max_hypotheses"):
        source = ctx.get_parameter_source(name)
        if source is not None and source.name not in ("DEFAULT", "DEFAULT_MAP"):
            flag = "--" + name.replace("_", "-")
            raise InputError(f"{flag} caps the refinement of the hypothesis set, and this set is not "
                             f"refined ({why}")


@app.command()
@handles_errors
def render(
    map_spec: Annotated[str, typer.Argument(metavar="MAP", help="Map file or bundled map name.")],
    out_path: Annotated[Path, typer.Option("--out", help="Output PNG.")],
    demos: Annotated[Path | None, typer.Option(help="Demonstrations CSV to draw on the map.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output if it exists.")] = False,
) -> None:
    """Draw a map (and optionally demonstrations) as a PNG in the style of the paper's Fig. 1."""
    from ..demos.csv_io import read_demos_csv
    from ..plots.floorplan import render_floor_plan_png
    from ..plots.maps import paths_to_xy, render_map_png
    from ..results import check_writable
    from ..worlds.maps import resolve_world
    from ..worlds.warehouse import WarehouseMap

    check_writable(out_path, force=force, inputs=[*_map_files(map_spec), demos])
    _check_figure_format(out_path)
    zone_map = resolve_world(map_spec)
    mdp = zone_map.to_mdp()  # refuses what simulate, infer and export-mdp refuse (an unreachable goal)
    paths = None if demos is None else paths_to_xy(read_demos_csv(demos, mdp), mdp)
    draw = render_floor_plan_png if isinstance(zone_map, WarehouseMap) else render_map_png
    draw(zone_map, out_path, trajectories_xy=paths, title=zone_map.name)
    _say(f"wrote {out_path}")


def _check_figure_format(path: Path) -> None:
    from matplotlib.figure import Figure

    supported = Figure().canvas.get_supported_filetypes()
    ext = path.suffix.lower().lstrip(".")
    if ext and ext not in supported:
        raise InputError(
            f"{path}: cannot write a figure as .{ext} (use one of: {', '.join(sorted(supported))})"
        )


@app.command()
def maps() -> None:
    """List the bundled example maps."""
    from ..worlds.maps import load_bundled_world
    from ..worlds.warehouse import WarehouseMap
    from ..worlds.zones import bundled_maps as names

    for name in names():
        m = load_bundled_world(name)
        if isinstance(m, WarehouseMap):
            _say(f"{name:12s} {m.width}×{m.height}, {m.n_states} states (warehouse, with heading)")
        else:
            _say(f"{name:12s} {m.width}×{m.height}, {int(m.passable.sum())} states")

