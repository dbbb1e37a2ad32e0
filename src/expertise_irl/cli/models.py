"""``expertise-irl compare-models``: which observation model fits the demonstrations best."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import InputError, plural
from ._app import (
    GoalRewardOption,
    _load_mdp,
    _map_files,
    _note,
    _progress,
    _say,
    _solve_progress,
    _warn,
    app,
    goal_reward_mode_of,
    handles_errors,
    out,
    prepare_solver,
)


@app.command("compare-models")
@handles_errors
def compare_models_command(
    demos: Annotated[Path, typer.Option(help="Demonstrations CSV (episode,step,state,action or x,y).")],
    map_spec: Annotated[str | None, typer.Argument(metavar="MAP", help="Map file or bundled name.")] = None,
    mdp_path: Annotated[Path | None, typer.Option("--mdp", help="MDP archive (.npz) instead of MAP.")] = None,
    models: Annotated[str, typer.Option(
        help="Comma-separated observation models to compare.")] = "maxent,maxent-relative,boltzmann",
    thetas: Annotated[str, typer.Option(
        help="Θ: a preset (paper-sim, paper-real) or comma-separated component values.")] = "paper-real",
    betas: Annotated[str, typer.Option(
        help="B: a preset (paper-sim, paper-real) or comma-separated temperatures.")] = "paper-sim",
    holdout: Annotated[float, typer.Option(
        help="Fraction of the episodes (the last in the file) held out for the predictive check.")] = 0.5,
    tol: Annotated[float, typer.Option(help="Soft value iteration tolerance (nats).")] = 1e-8,
    out_path: Annotated[Path | None, typer.Option("--out", help="Also write the comparison as JSON.")] = None,
    goal_reward: GoalRewardOption = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite --out if it exists.")] = False,
    lambdas: Annotated[str | None, typer.Option(
        help="pedagogical's grid of teaching weights λ (comma-separated, with 0, the doer, and a λ > 0; "
        "default 0,0.003,0.01,0.03,0.1,0.3,1).")] = None,
) -> None:
    """Compare observation models on the same demonstrations and hypothesis set.

    For each model: the log evidence log Σ_h P(Ξ|h) P(h) (uniform prior over the set), the
    Bayes factor against the best model, and the held-out log-likelihood per action of the
    last episodes predicted from the posterior of the first ones. pedagogical's evidence is a
    teacher's (the mean over the positive λ of the grid), so its difference to maxent's is the
    Bayes factor of teaching against doing; its row adds λ̂, its 90% interval and the verdict.
    """
    from .. import __version__
    from ..demos.csv_io import read_demos_csv
    from ..inference.evidence import check_model_list, compare_models
    from ..inference.methods import DiscreteOptions
    from ..inference.pedagogical import LAMBDAS, parse_lambdas
    from ..models import PEDAGOGICAL
    from ..results import check_writable, file_digest, write_json

    names = list(check_model_list([m.strip() for m in models.split(",") if m.strip()]))
    taught = PEDAGOGICAL in names
    if lambdas is not None and not taught:
        raise InputError("--lambdas is the pedagogical model's λ grid: name pedagogical in --models")
    grid = parse_lambdas(lambdas if lambdas is not None else LAMBDAS)
    if out_path is not None:
        check_writable(out_path, force=force, inputs=[demos, *_map_files(map_spec), mdp_path])
    mdp, zone_map = _load_mdp(map_spec, mdp_path, goal_reward)
    trajs = read_demos_csv(demos, mdp)
    prepare_solver()
    hyp = DiscreteOptions(thetas=thetas, betas=betas).hypotheses(mdp.n_features)
    t0 = time.perf_counter()
    with _progress() as bar:
        cmp = compare_models(mdp, trajs, hyp, names, holdout=holdout, tol=tol, lambdas=grid,
                             progress=lambda m: _solve_progress(bar, f"solving ({m})"))
    elapsed = time.perf_counter() - t0
    table = Table(title=escape(f"{len(hyp)} hypotheses, {plural(trajs.n_episodes, 'episode')}, "
                               f"{plural(len(trajs), 'action')}"))
    for col in ("model", "log evidence", "log BF vs best", "reading", "held-out log-lik / action", "β̂",
                "group"):
        table.add_column(col, justify="left" if col in ("model", "reading", "group") else "right",
                         no_wrap=col == "model")
    for f in cmp.fits:
        held = "n/a" if f.heldout_per_action is None else f"{f.heldout_per_action:.4f}"
        table.add_row(f.model, f"{f.log_evidence:.2f}", f"{f.log_bayes_factor:.2f}", f.strength, held,
                      f"{f.beta_hat:.3g}", f.expertise_group)
    out.print(table)
    if cmp.n_test_episodes:
        _note(f"held out the last {cmp.n_test_episodes} of {plural(trajs.n_episodes, 'episode')} "
              f"({plural(cmp.n_test_actions, 'action')}); fitted on the first {cmp.n_fit_episodes}")
    for why in cmp.unavailable.values():
        _note(why)
    _say(f"best: {cmp.best.model}")
    for f in cmp.fits:  # the teaching model's verdict, λ̂ and evidence against maxent: a line
        if f.teaching is not None:
            _say(f"{f.model}: {_teaching_line(f.teaching)}")
            for w in f.teaching.get("warnings", []):
                _warn(w)
    if out_path is not None:
        doc = {
            "version": __version__, "command": "compare-models", "feature_names": list(mdp.feature_names),
            "best": cmp.best.model,
            "models": [{"model": f.model, "log_evidence": f.log_evidence,
                        "log_bayes_factor": f.log_bayes_factor, "reading": f.strength,
                        "heldout_log_likelihood_per_action": f.heldout_per_action,
                        "beta_hat": f.beta_hat, "theta_hat": [float(x) for x in f.theta_hat],
                        "expertise_group": f.expertise_group,
                        **({"teaching": f.teaching} if f.teaching is not None else {})} for f in cmp.fits],
            "heldout": {"fit_episodes": cmp.n_fit_episodes, "test_episodes": cmp.n_test_episodes,
                        "test_actions": cmp.n_test_actions, "fraction": holdout},
            "unavailable": cmp.unavailable,
            "settings": {"demos": str(demos), "demos_digest": file_digest(demos),
                         "mdp": str(mdp_path) if mdp_path else str(map_spec), "thetas": thetas,
                         "betas": betas, "n_hypotheses": len(hyp), "prior": "uniform", "tol": tol,
                         "goal_reward_mode": goal_reward_mode_of(mdp, zone_map),
                         **({"lambdas": grid.tolist()} if taught else {})},
            "run_time_s": elapsed,
        }
        from ..results import finite_or_null

        write_json(out_path, finite_or_null(doc))
        _say(f"wrote {out_path}")


def _teaching_line(teaching: dict) -> str:
    """pedagogical's reading (verdict, 2 log BF against maxent, β under both) with λ̂ and its interval."""
    lo, hi = teaching["lambda_interval"]
    return (f"{teaching['reading']}; λ̂ = {teaching['lambda_hat']:.3g}, "
            f"90% credible interval [{lo:.3g}, {hi:.3g}]")
