"""``expertise-irl study``: every participant of a user study, Tables V–VI and Figs. 10–11."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ._app import ModelOption, _say, _warn, app, err, handles_errors, prepare_solver
from .recordings import FillGapsOption, MaxDtOption, RateOption, SnapOption

#: Bundled example studies: name -> folder inside the package.
BUNDLED = {"example": "example"}


def resolve_manifest(spec: str) -> Path:
    """A manifest file, or the manifest of a bundled study (``example``)."""
    p = Path(spec)
    if p.is_file() or spec not in BUNDLED:
        return p
    from importlib import resources

    return Path(str(resources.files("expertise_irl.userstudy") / BUNDLED[spec] / "manifest.csv"))


ThetasOption = Annotated[
    str | None, typer.Option(help="Θ: a preset (paper-real, paper-sim) or component values (default "
                             "paper-real, refined per participant: see --refine).")
]

BetasOption = Annotated[
    str | None, typer.Option(help="B: auto (from the maps' optimal values: 1e-3 to 100 times the median "
                             "gap between a state's two best actions, 3 per decade; the default), a "
                             "preset (paper-real, paper-sim) or temperatures.")
]

RefineOption = Annotated[
    bool | None,
    typer.Option("--refine/--no-refine", help="Refine each participant's hypothesis set where their "
                 "posterior's mass is, starting from the study's set (the default when neither "
                 "--thetas nor --betas is given; --share both, stationary expertise, discrete). A "
                 "report choice: a rerun on the same DIR may change it."),
]

MethodOption = Annotated[
    str,
    typer.Option(
        help="discrete (the hypothesis set; joint posterior over a participant's tasks), map or nuts "
        "(log-likelihoods of their tasks summed)."
    ),
]

ShareOption = Annotated[
    str,
    typer.Option(help="What a participant's tasks share: both (one θ and one β) or beta (one β, "
                 "a θ per task: tasks with different rewards)."),
]

ExpertiseOption = Annotated[
    str,
    typer.Option(help="stationary (one β per participant) or changing (--share both: a β per "
                 "episode in task order; discrete: a sticky chain on the β grid with its Bayes "
                 "factor, map/nuts: a log-linear learning curve; each participant's curve and "
                 "trend, and in study.md a sign test of whether people improve)."),
]

FiguresOption = Annotated[
    str,
    typer.Option(help="Participant figures to draw: all, none, or N (the first N participants). "
                 "DIR/study.png is always drawn."),
]

GroupByOption = Annotated[
    str | None,
    typer.Option(help="A manifest column: study.md compares β between its groups (Mann–Whitney)."),
]

PopulationOption = Annotated[
    bool,
    typer.Option("--population", help="Also fit the participants as one population (--method discrete, "
                 "--share both): log β ~ Normal(μ, σ²) and θ ~ Dirichlet(α·m) over the grid, learned "
                 "from the study (NUTS); each participant's pooled estimate beside the independent one "
                 "in study.csv (*_pooled), DIR/population.json and population.png, a held-out "
                 "comparison; with --group-by, each group its own (μ, σ)."),
]

CheckOption = Annotated[
    str,
    typer.Option("--check", help="Low expertise or missing features? off, fast (posterior predictive "
                 "checks, the default) or full (also a per-state reward fitted with β, compared on "
                 "held-out episodes): each result.json's diagnostics.misspecification, a warning when "
                 "the features do not explain a participant's behaviour."),
]

ModelsOption = Annotated[
    str | None,
    typer.Option(
        help="Also compare these observation models (comma-separated, --method discrete only): "
        "each participant's log evidence, Bayes factors and held-out check in DIR/models.csv; "
        "the main results still use --model."
    ),
]


LambdasOption = Annotated[
    str | None,
    typer.Option(help="The pedagogical model's grid of teaching weights λ (--model pedagogical or "
                 "pedagogical in --models): comma-separated, with 0 (the doer) and a λ > 0; default "
                 "0,0.003,0.01,0.03,0.1,0.3,1."),
]


@app.command()
@handles_errors
def study(
    manifest: Annotated[
        str,
        typer.Argument(
            metavar="MANIFEST",
            help="Manifest CSV participant,map,recording (or demos), paths relative to it; a map is a "
            "floor plan, a zone map, a bundled map's name or an .npz MDP archive; other columns are "
            "carried into the tables. Or 'example', the bundled study.",
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", help="Study directory (created, or resumed when it holds this study).")
    ],
    thetas: ThetasOption = None,
    betas: BetasOption = None,
    refine: RefineOption = None,
    method: MethodOption = "discrete",
    rate: RateOption = 1.0,
    max_dt: MaxDtOption = None,
    fill_gaps: FillGapsOption = False,
    snap: SnapOption = False,
    workers: Annotated[
        int | None, typer.Option(min=1, help="Local worker processes (default: one per core).")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address, e.g. tcp://HOST:8786.")
    ] = None,
    model: ModelOption = "maxent",
    share: ShareOption = "both",
    expertise: ExpertiseOption = "stationary",
    figures: FiguresOption = "all",
    group_by: GroupByOption = None,
    population: PopulationOption = False,
    check: CheckOption = "fast",
    models: ModelsOption = None,
    lambdas: LambdasOption = None,
) -> None:
    """Run every participant of a study: estimates, warnings, a held-out check, Tables V–VI, figures.

    Writes DIR/study.csv and study.md (one row per participant, the joint posterior over
    their tasks), DIR/tasks.csv (one row per manifest row), DIR/study.png and
    DIR/participants/ID/result.json and ID.png; with --models, DIR/models.csv too. Maps shared
    by participants are solved once; a second run on the same DIR resumes, and may change
    --figures, --group-by and --refine (docs/user-studies.md). With the pedagogical model
    (--model, or in --models) each participant's verdict, teaching or doing, is in study.md.
    """
    from ..options import Share, choose, one_of
    from ..userstudy.evidence import parse_models
    from ..userstudy.run import ReportOptions, StudyOptions
    from ..userstudy.study import DEFAULT_LAMBDAS, METHODS, lambdas_spec

    path = resolve_manifest(manifest)
    one_of(method, METHODS, "method")  # (the command line writes each field as its flag)
    choose(Share, share, "share")
    if models is not None and method != "discrete":
        raise InputError(f"--models needs --method discrete (got --method {method})")
    compared = parse_models(models) if models is not None else ()
    named = thetas is not None or betas is not None
    opts = StudyOptions(
        thetas=thetas if thetas is not None else StudyOptions.thetas,
        betas=betas if betas is not None else StudyOptions.betas,
        method=method,
        rate=rate,
        max_dt=max_dt,
        fill_gaps=fill_gaps,
        snap=snap,
        model=model,
        models=compared,
        share=share,
        expertise=expertise,
        lambdas=lambdas_spec(lambdas) if lambdas is not None else DEFAULT_LAMBDAS,
    )
    from ..inference.misspecification import check_level

    report = ReportOptions(figures=figures, group_by=group_by, population=population,
                           check=check_level(check), refine=False if refine is None and named else refine)
    _print_outcome(_run(path, out, opts, workers, scheduler, report), out)


def _run(path: Path, out: Path, opts, workers: int | None, scheduler: str | None, report):
    """Run the study, reporting progress; a failed task is printed and exits with 1."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from ..userstudy.run import StudyFailed, run_study

    def on_task(phase, total, todo, res) -> None:
        if res is None:
            err.print(f"{phase}: {total} task(s), {total - todo} already done", highlight=False)

    bar = Progress(TextColumn("figures"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                   console=err, transient=True)
    bar_task = None

    def on_figure(done: int, total: int) -> None:
        nonlocal bar_task
        if bar_task is None:
            bar.start()
            bar_task = bar.add_task("figures", total=total)
        bar.update(bar_task, completed=done)

    prepare_solver(measure=scheduler is None)  # local workers read this machine's lane width
    try:
        outcome = run_study(path, out, opts, workers=workers, scheduler=scheduler, on_task=on_task,
                            report=report, on_figure=on_figure)
    except StudyFailed as exc:
        for key, message in exc.failures:
            err.print(f"error: {exc.phase} task {key} failed: {message}", markup=False, highlight=False)
        _say(f"{len(exc.failures)} {exc.phase} task(s) failed; run the same command again to retry them")
        raise typer.Exit(1) from None
    finally:
        if bar_task is not None:
            bar.stop()
    return outcome


def _print_teaching(records, out: Path) -> None:
    """The pedagogical model's reading of each participant and the count of each verdict."""
    if not records:
        return
    for pid, r in records.items():
        _say(f"{pid}: " + (r["reading"] if r else "no hypothesis of the set explains the demonstrations"))
    counts = {v: sum(1 for r in records.values() if r and r["verdict"] == v)
              for v in ("teaching", "doing", "undecided")}
    _say("teaching verdicts: " + ", ".join(f"{v} {n}" for v, n in counts.items()) + f" (see {out}/study.md)")


def _print_outcome(outcome, out: Path) -> None:
    """One line per participant (and per model comparison), the warnings, then what was written."""
    import math

    names = outcome.feature_names
    for r in outcome.participants:
        own = [f for f in names if not math.isnan(r.get(f"theta_{f}", math.nan))]
        theta = ("[" + ", ".join(f"{f} {r[f'theta_{f}']:.2f}" for f in own) + "]") if own else "per task"
        held = r["heldout_log_likelihood_per_action"]
        band = "" if math.isnan(r["beta_q05"]) else f" (90% {r['beta_q05']:.3g}–{r['beta_q95']:.3g})"
        _say(
            f"{r['participant']}: β̂ = {r['beta_hat']:.3g}{band}, "
            f"θ̂ = {theta}, path length {r['path_length']} (optimal {r['optimal_path_length']}), "
            + (f"held-out {held:.3f} nats/action ({r['heldout_split']})" if not math.isnan(held)
               else "no held-out check")
            + (f", filled gaps {r['filled_gaps']}, snapped samples {r['snapped_samples']}"
               if r["filled_gaps"] or r["snapped_samples"] else "")
            + (f", {r['warnings']} warning(s)" if r["warnings"] else "")
        )
    for pid, ev in (outcome.evidence or {}).items():
        bfs = ", ".join(f"{f['model']} {f['log_bayes_factor']:.2f}" for f in ev["models"])
        _say(f"{pid}: best model {ev['best'] or 'n/a'} (log Bayes factors vs best: {bfs})")
    _print_teaching(outcome.teaching, out)
    verdicts: dict[str, list[str]] = {}
    for r in outcome.participants:
        if r.get("misspecification"):
            verdicts.setdefault(r["misspecification"], []).append(str(r["participant"]))
    if verdicts:
        _say("checks: " + "; ".join(f"{v}: {len(ps)}" + (f" ({', '.join(ps)})" if len(ps) <= 5 else "")
                                    for v, ps in verdicts.items()) + f" (see {out}/study.md)")
    n_warn = sum(r["warnings"] for r in outcome.participants)
    if n_warn:
        _warn(f"{n_warn} warning(s) for {sum(1 for r in outcome.participants if r['warnings'])} "
              f"participant(s): see {out}/study.md (Warnings) and each result.json's diagnostics")
    pop = outcome.population
    if pop is not None:
        parts = [f"{g}: median β {b['median_beta']['mean']:.3g} (90% {b['median_beta']['q05']:.3g}–"
                 f"{b['median_beta']['q95']:.3g}), σ of log β {b['sigma_log_beta']['mean']:.2f}"
                 for g, b in pop["population_beta"].items()]
        h = pop["heldout_nats_per_action"]
        held = (f"; held-out nats/action: population {h['population']:.3f}, independent "
                f"{h['independent']:.3f}, pooled {h['pooled']:.3f}" if h["actions"] else "")
        _say("population: " + "; ".join(parts) + held)
        for c in pop["comparisons"]:
            _say(f"population: P(μ_{c['a']} < μ_{c['b']}) = {c['p_mu_a_lt_mu_b']:.3f}")
        for w in pop["diagnostics"]["warnings"]:
            _warn(f"population: {w}")
    wrote = ("study.csv, study.md, tasks.csv, study.png" + (", models.csv" if outcome.evidence else "")
             + (", population.json, population.png" if pop is not None else ""))
    t = outcome.timing or {}
    _say(
        f"wrote {out}/{wrote} and participants/: {len(outcome.participants)} "
        f"participants, {t.get('figures', 0)} figure(s); {outcome.tasks_run} engine task(s) run, "
        f"{outcome.tasks_skipped} already done ({outcome.wall_time_s:.1f} s: reading and the β grid "
        f"{t.get('setup_s', 0):.1f} s, inference {t.get('inference_s', 0):.1f} s, "
        + (f"population {t['population_s']:.1f} s, " if "population_s" in t else "")
        + f"reports {t.get('reports_s', 0):.1f} s, figures {t.get('figures_s', 0):.1f} s)"
    )
