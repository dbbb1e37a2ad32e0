"""Figures of result documents: what ``expertise-irl plot RESULT.json`` draws.

One figure per result (any method of ``infer``, or ``demo``'s result):

- the posterior of β and of each θ_i: bars of the marginal for a discrete hypothesis set;
  histograms with the 90% credible interval shaded for sampling methods (``birl``,
  ``nuts``); a marked point for ``map``, which has no posterior;
- the map with the demonstrations, when a map (or an MDP archive with ``state_xy``) and
  demonstrations are given;
- for ``--per-action`` discrete results, the trace: β̂ with its 90% band, the
  expertise-group probabilities and the posterior entropy against the number of
  actions seen, with a dashed line where each new episode starts;
- the result's ``diagnostics.warnings`` (non-convergence and the like), in red below.

The figures read a typed :class:`~expertise_irl.result.Result`; a result document (a dict as
parsed from the JSON, of any earlier version) is read with :meth:`Result.from_json
<expertise_irl.result.Result.from_json>` first. Like :mod:`.maps`, figures are built on a
:class:`~matplotlib.figure.Figure` directly (no pyplot state). Artists carry gids so that tests can
find them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullLocator

from ..atomic import save_figure_atomic
from ..errors import ArgumentError, plural
from ..hypotheses import GROUP_NAMES as GROUPS
from ..result import ChangingExpertise, Result, TraceEntry
from ..results import SAMPLED, is_number, load_samples
from . import maps

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..demos.trajectories import Trajectories
    from ..mdp import TabularMDP
    from ..worlds.zones import ZoneMap

CREDIBLE = 0.9
GROUP_COLORS = {"high": "#2b8a3e", "medium": "#e67700", "low": "#c92a2a"}
POST_COLOR = "#4c72b0"
BAND_COLOR = "#a5c0e6"
POINT_COLOR = "#c0392b"
BOUNDARY_COLOR = "#868e96"
#: Narrowest map panel (inches): a one-column legend of episodes fits below the map.
MIN_MAP_PANEL = 3.6


# --------------------------------------------------------------------- posterior
def theta_component_marginal(values, probs, i: int) -> tuple[np.ndarray, np.ndarray]:
    """``(v, P(θ_i = v))`` from the θ marginal: probabilities of equal θ_i (to 1e-9) summed."""
    v = np.round(np.asarray(values, dtype=float)[:, i], 9) + 0.0
    p = np.asarray(probs, dtype=float)
    uniq, inv = np.unique(v, return_inverse=True)
    return uniq, np.bincount(inv.ravel(), weights=p / p.sum(), minlength=len(uniq))


def draw_discrete_component(ax: Axes, values, probs, name: str, *, mean: float | None = None,
                            true: float | None = None) -> Axes:
    """Bars of P(θ_i = v) at the values v of the set (gid ``"marginal"`` on each bar)."""
    v, p = np.asarray(values, dtype=float), np.asarray(probs, dtype=float)
    gaps = np.diff(v)
    width = min(0.06, max(0.8 * float(gaps.min()), 0.012)) if gaps.size else 0.06
    bars = ax.bar(v, p, width=width, color=POST_COLOR, edgecolor="#2f4b7c", lw=0.5)
    for bar in bars:
        bar.set_gid("marginal")
    if mean is not None:
        ax.axvline(mean, color="#1a1a1a", lw=1.1, ls="--", gid="mean")
    if true is not None:
        ax.axvline(true, color=POINT_COLOR, lw=1.3, alpha=0.8, gid="true", zorder=0)
    lo, hi = min(0.0, float(v.min())), max(1.0, float(v.max()))
    ax.set_xlim(lo - 0.06, hi + 0.06)
    ax.set_ylim(0, max(float(p.max()) * 1.15, 0.05))
    ax.set_title(rf"$\theta$ {name}: E = {mean:.3g}" if mean is not None else rf"$\theta$ {name}",
                 fontsize=8.5)
    ax.set_ylabel("marginal prob.", fontsize=7.5)
    maps.tidy(ax)
    return ax


def draw_sampled(ax: Axes, draws, label: str, *, interval=None, mean: float | None = None,
                 point: float | None = None, true: float | None = None, log: bool = False,
                 withheld: bool = False) -> Axes:
    """Histogram (density) of ``draws`` with the 90% interval shaded (gid ``"interval"``).

    ``interval`` defaults to the 5%/95% quantiles of the draws. ``mean`` is a dashed line,
    ``point`` (the MAP draw) a marker on the axis, ``true`` a red line. No interval is drawn when
    ``withheld`` (the result has none: a chain did not move) or when every draw is the same.
    """
    x = np.asarray(draws, dtype=float)
    span = float(x.max() - x.min())
    shade = not withheld and span > 0
    if shade and interval is None:
        interval = np.quantile(x, [(1 - CREDIBLE) / 2, (1 + CREDIBLE) / 2]).tolist()
    if shade:
        lo, hi = float(interval[0]), float(interval[1])
        ax.axvspan(lo, hi, color=BAND_COLOR, alpha=0.55, lw=0, gid="interval", zorder=0)
        ax.set_title(f"{label}: 90% [{lo:.3g}, {hi:.3g}]", fontsize=8.5)
    else:
        ax.set_title(f"{label}: no 90% interval (stuck chain)", fontsize=8.5)
    bins: Any = min(30, max(5, int(np.sqrt(x.size)) + 1))
    if span == 0:  # every draw the same: a narrow spike on a readable axis
        w = max(abs(float(x[0])) * 0.01, 1e-3)
        bins = [x[0] - w, x[0] + w]
        ax.set_xlim(x[0] - 25 * w, x[0] + 25 * w)
    ax.hist(x, bins=bins, density=True, color=POST_COLOR, alpha=0.85, edgecolor="white", lw=0.3,
            gid="hist", zorder=2)
    if mean is not None:
        ax.axvline(mean, color="#1a1a1a", lw=1.1, ls="--", gid="mean", zorder=3)
    if point is not None:
        ax.plot([point], [0], ls="", marker="^", ms=7, color=POINT_COLOR, clip_on=False,
                gid="map-point", zorder=4)
    if true is not None:
        ax.axvline(true, color=POINT_COLOR, lw=1.3, gid="true", zorder=3)
    ax.set_ylabel("density", fontsize=7.5)
    ax.set_yticks([])
    maps.tidy(ax)
    return ax


def draw_point(ax: Axes, value: float, label: str, *, lo: float, hi: float, log: bool = False) -> Axes:
    """A single estimate on an axis from ``lo`` to ``hi`` (gid ``"point"``): no posterior to draw."""
    ax.plot([value], [0.5], ls="", marker="D", ms=8, color=POINT_COLOR, gid="point")
    ax.axvline(value, color=POINT_COLOR, lw=0.8, alpha=0.5)
    ax.set_xlim(lo, hi)  # before the log scale: a lone point's automatic limits are degenerate
    if log:
        ax.set_xscale("log")
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    ax.set_title(f"{label} = {value:{'.3g' if log else '.3f'}}  (point estimate)", fontsize=8.5)
    maps.tidy(ax)
    ax.spines["left"].set_visible(False)
    return ax


# -------------------------------------------------------------------------- trace
def trace_arrays(trace: Sequence[TraceEntry | Mapping[str, Any]]) -> dict[str, np.ndarray | None]:
    """Arrays of a trace (its entries, or their JSON objects): ``x`` (actions seen), ``beta_hat``,
    ``entropy``, ``band`` ``[N + 1, 2]`` and ``groups`` ``[N + 1, 3]`` (None when the result
    predates them), and ``boundaries``: the x at which each episode after the first starts."""
    entries = [e if isinstance(e, TraceEntry) else TraceEntry.from_json(e) for e in trace]
    n = len(entries)
    x = np.arange(n)
    out: dict[str, np.ndarray | None] = {
        "x": x,
        "beta_hat": np.array([e.beta_hat for e in entries], dtype=float),
        "entropy": np.array([e.entropy for e in entries], dtype=float),
        "band": None,
        "groups": None,
    }
    bands = [e.beta_band for e in entries]
    if all(b is not None for b in bands):
        out["band"] = np.array(bands, dtype=float)
    groups = [e.group_probabilities for e in entries]
    if all(g is not None for g in groups):
        out["groups"] = np.array([[g.get(k, np.nan) for k in GROUPS] for g in groups if g is not None],
                                 dtype=float)
    # entry i (i >= 1) is the belief after action i - 1; an episode starts at entry i when its
    # step is 0, so its boundary is drawn at x = i - 1 (the actions seen before it).
    out["boundaries"] = np.array([i - 1 for i in range(2, n) if entries[i].step == 0], dtype=int)
    out["episodes"] = np.array([-1 if e.episode is None else e.episode for e in entries])
    return out


def draw_trace(axes: Sequence[Axes], trace: Sequence[TraceEntry | Mapping[str, Any]], *,
               beta_true: float | None = None, betas=None) -> Sequence[Axes]:
    """Three panels against the number of actions seen: β̂ with its 90% band, the group
    probabilities, and the posterior entropy; dashed lines where episodes start.

    gids: ``"trace-beta"``, ``"trace-band"``, ``"trace-group-<high|medium|low>"``,
    ``"trace-entropy"``, ``"episode-boundary"`` (one per boundary per panel).
    """
    ax_b, ax_g, ax_e = axes
    t = trace_arrays(trace)
    x = t["x"]
    if t["band"] is not None:
        ax_b.fill_between(x, t["band"][:, 0], t["band"][:, 1], step="mid", color=BAND_COLOR,
                          alpha=0.6, lw=0, label="90% band of the β marginal", gid="trace-band")
    ax_b.plot(x, t["beta_hat"], color=POST_COLOR, lw=1.4, label=r"$\hat\beta$ = E[$\beta$]",
              gid="trace-beta")
    if beta_true is not None:
        ax_b.axhline(beta_true, color=POINT_COLOR, lw=1.0, ls=":", label=rf"true $\beta^*$ = {beta_true:g}")
    positive = t["beta_hat"] > 0
    if positive.all() and (t["band"] is None or (t["band"] > 0).all()):
        ax_b.set_yscale("log")
        if betas is not None:
            ticks = sorted(set(np.asarray(betas, dtype=float).tolist()))
            ax_b.set_yticks(ticks, [f"{v:g}" for v in ticks])
            ax_b.minorticks_off()
    ax_b.set_ylabel(r"expertise $\beta$", fontsize=8)
    title = r"belief after each action: $\hat\beta$"
    if t["band"] is None:
        title += "  (this result has no band: rerun infer --per-action)"
    ax_b.set_title(title, fontsize=9)
    ax_b.legend(fontsize=7, frameon=False, loc="upper right")

    if t["groups"] is not None:
        for j, g in enumerate(GROUPS):
            ax_g.plot(x, t["groups"][:, j], color=GROUP_COLORS[g], lw=1.3, label=g,
                      gid=f"trace-group-{g}")
        ax_g.legend(fontsize=7, frameon=False, loc="upper right", ncol=3, title="expertise group",
                    title_fontsize=7)
    else:
        ax_g.text(0.5, 0.5, "no group probabilities in this result (rerun infer --per-action)",
                  ha="center", va="center", transform=ax_g.transAxes, fontsize=8, color="#666")
    ax_g.set_ylim(-0.02, 1.05)
    ax_g.set_ylabel("P(group)", fontsize=8)

    ax_e.plot(x, t["entropy"], color="#495057", lw=1.3, gid="trace-entropy")
    ax_e.set_ylabel("entropy (nats)", fontsize=8)
    ax_e.set_xlabel("actions seen (0 = prior); dashed lines: a new episode starts", fontsize=8)
    ax_e.set_ylim(bottom=0)
    for ax in axes:
        for b in t["boundaries"]:
            ax.axvline(b, color=BOUNDARY_COLOR, lw=0.7, ls="--", gid="episode-boundary", zorder=0)
        ax.set_xlim(0, max(len(x) - 1, 1))
        maps.tidy(ax)
    return axes


# ------------------------------------------------------------------------ the map
def draw_mdp_cells(ax: Axes, mdp: TabularMDP) -> Axes:
    """The cells of an MDP archive with ``state_xy``: free cells light, goals green."""
    from matplotlib.patches import Circle, Rectangle

    xy = np.asarray(mdp.state_xy)
    w, h = int(xy[:, 0].max()) + 1, int(xy[:, 1].max()) + 1
    ax.add_patch(Rectangle((-0.5, -0.5), w, h, fc="#3a3a3a", ec="none", zorder=0))
    for s, (x, y) in enumerate(xy.tolist()):
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, fc="#fafafa", ec=maps.GRID_COLOR,
                               lw=0.4, zorder=1))
        if mdp.terminal[s]:
            ax.add_patch(Circle((x, y), 0.36, fc=maps.GOAL_COLOR, ec="white", lw=0.8, zorder=6,
                                gid="goal"))
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    return ax


def map_key(mdp: TabularMDP, zone_map: ZoneMap | None) -> list:
    """Legend handles of what :func:`draw_demos_on_map` draws of the task (before the episodes)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from ..worlds.warehouse import WarehouseMap

    if isinstance(zone_map, WarehouseMap):
        from .floorplan import floor_plan_legend_handles

        return floor_plan_legend_handles(zone_map)
    if zone_map is not None:
        return maps.map_legend_handles(zone_map)
    return [Patch(fc="#fafafa", ec="#7a7a7a", lw=0.5, label="cell of a state"),
            Line2D([], [], ls="", marker="o", ms=7, mfc=maps.GOAL_COLOR, mec="white", label="goal")]


def _grid_of(mdp: TabularMDP):
    """A stand-in with ``width``/``height`` for path checks on an MDP archive."""
    xy = np.asarray(mdp.state_xy)

    class _Grid:
        width = int(xy[:, 0].max()) + 1
        height = int(xy[:, 1].max()) + 1

    return _Grid()


def draw_demos_on_map(ax: Axes, mdp: TabularMDP, zone_map: ZoneMap | None, trajs: Trajectories | None,
                      *, n_episodes: int = maps.DEMO_EPISODES, max_steps: int | None = None) -> list:
    """The map, visit dots of every episode and the first few episodes drawn distinctly.

    Returns the legend handles (zones, markers, episodes).
    """
    from ..demos.simulation import episode_outcomes
    from ..worlds.warehouse import WarehouseMap

    if isinstance(zone_map, WarehouseMap):  # a floor plan: roads as arrows, restricted red
        from .floorplan import draw_floor_plan

        draw_floor_plan(ax, zone_map, legend=False)
    elif zone_map is not None:
        maps.draw_map(ax, zone_map, legend=False)
    else:
        draw_mdp_cells(ax, mdp)
    grid = zone_map if zone_map is not None else _grid_of(mdp)
    handles = map_key(mdp, zone_map)
    if trajs is None:
        return handles
    paths = maps.paths_to_xy(trajs, mdp)
    outcomes = episode_outcomes(trajs, mdp, max_steps)
    maps.draw_visits(ax, grid, paths)
    shown = min(n_episodes, len(paths))
    ids = trajs.episode_ids
    eps = maps.draw_episodes(ax, grid, paths[:shown], outcomes[:shown],
                               labels=[f"episode {int(e)}" for e in ids[:shown]])
    return handles + maps.episode_marker_handles(outcomes[:shown]) + eps


# ------------------------------------------------------------------------ figure
def render_result_png(
    path: str | Path,
    result: Result | Mapping[str, Any],
    *,
    source: str | Path = "result",
    mdp: TabularMDP | None = None,
    zone_map: ZoneMap | None = None,
    trajs: Trajectories | None = None,
) -> Path:
    """Save :func:`result_figure` to ``path`` (the format follows the suffix; PNG at dpi 120)."""
    fig = result_figure(result, source=source, mdp=mdp, zone_map=zone_map, trajs=trajs)
    out = Path(path)
    save_figure_atomic(fig, out, dpi=maps.DPI, facecolor="white", bbox_inches="tight", pad_inches=0.08)
    fig.clear()
    return out


def result_figure(
    result: Result | Mapping[str, Any],
    *,
    source: str | Path = "result",
    mdp: TabularMDP | None = None,
    zone_map: ZoneMap | None = None,
    trajs: Trajectories | None = None,
):
    """The :class:`~matplotlib.figure.Figure` of a result (see the module docstring).

    Parameters
    ----------
    result : Result or dict
        The result (:func:`~expertise_irl.results.read_result`), or its document as checked by
        :func:`~expertise_irl.results.load_result`.
    source : str or Path
        The result's file: its folder is where a samples CSV is looked up; its name is
        in the title.
    mdp, zone_map, trajs : optional
        The task (a text map gives ``zone_map``; an archive only ``mdp``, drawn from
        ``state_xy``) and the demonstrations to draw on it.
    """
    source = Path(source)
    if not isinstance(result, Result):
        result = Result.from_json(result, source)
    method = result.method
    K = len(result.feature_names)
    truth = result.extra.get("truth")  # demo's: what the demonstrations were simulated with
    truth = truth if isinstance(truth, Mapping) else {}
    beta_true = truth.get("beta") if is_number(truth.get("beta")) else None
    theta_true = truth.get("theta") if isinstance(truth.get("theta"), list | tuple) and len(
        truth.get("theta")) == K else None
    post = result.posterior
    trace = post.trace if method == "discrete" and post is not None else None
    draw_map = mdp is not None and (zone_map is not None or mdp.state_xy is not None)

    ncols = 3 if K + 1 > 4 else K + 1
    nrows = math.ceil((K + 1) / ncols)
    post_h = 2.0 * nrows
    map_w = 0.0
    if draw_map:
        map_w, map_h = _map_panel_size(mdp, zone_map, trajs)
        post_h = max(post_h, map_h)
    trace_h = 5.2 if trace else 0.0
    curve = None if result.changing is None else result.changing.by_episode
    curve_h = 3.0 if curve else 0.0
    warnings = result_warnings(result)
    warn_h = 0.25 + 0.16 * min(len(warnings), 4) if warnings else 0.0
    fig = maps.new_figure((max(map_w + 3.0 * ncols, 8.5), post_h + trace_h + curve_h + warn_h + 0.6))
    heights = [h for h in (post_h, trace_h, curve_h, warn_h) if h > 0]
    rows = list(fig.subfigures(len(heights), 1, height_ratios=heights, hspace=0.02)) if len(
        heights) > 1 else [fig]
    top = rows[0]
    bottom = rows[1] if trace else None
    if curve:
        draw_learning_curve(rows[2 if trace else 1].subplots(1, 1), result, truth.get("beta_by_episode"))
    sf_warn = rows[-1] if warnings else None
    sf_post = _draw_map_panel(top, map_w, 3.0 * ncols, mdp, zone_map, trajs) if draw_map else top
    axes = sf_post.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[K + 1:]:
        ax.axis("off")
    ax_beta, ax_th = axes[0], axes[1:K + 1]
    if method == "discrete":
        subtitle = _draw_discrete(result, ax_beta, ax_th, beta_true, theta_true)
    elif method in SAMPLED:
        subtitle = _draw_samples(result, source, ax_beta, ax_th, beta_true, theta_true)
    else:  # map: a point, no posterior
        subtitle = _draw_optimum(result, ax_beta, ax_th)
    if bottom is not None and post is not None:
        axs = bottom.subplots(3, 1, sharex=True, height_ratios=[1.3, 1.0, 0.8])
        draw_trace(axs, trace, beta_true=beta_true, betas=post.marginals.beta_values)

    if beta_true is not None or theta_true is not None:
        subtitle += "; red = the truth (θ*, β*)"
    fig.suptitle(_title(result, source, subtitle), fontsize=10)
    if sf_warn is not None:
        _draw_warnings(sf_warn, warnings)
    return fig


#: The learning curve's β axis spans at least this factor: a curve that changes less than that
#: (1e-8 of rounding in a constant person's β̂_e, say) is drawn flat, not stretched to fill the axis.
CURVE_MIN_SPAN = 4.0


def curve_limits(values: np.ndarray, min_span: float = CURVE_MIN_SPAN) -> tuple[float, float]:
    """The β axis of the learning curve: every finite value > 0 in ``values``, with 8% of the log range
    either side, and at least ``min_span`` wide (centred on the values in log space)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return 0.1, 10.0
    lo, hi = np.log(v.min()), np.log(v.max())
    pad = 0.08 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    if hi - lo < math.log(min_span):
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * math.log(min_span), mid + 0.5 * math.log(min_span)
    return float(np.exp(lo)), float(np.exp(hi))


def _beta_axis(ax: Axes, values: np.ndarray) -> None:
    """Log scale over :func:`curve_limits`, ticks at 1, 2 and 5 times powers of ten, written plainly."""
    ax.set_yscale("log")
    ax.set_ylim(*curve_limits(values))
    ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.yaxis.set_major_formatter(FuncFormatter(lambda y, _: f"{y:g}"))


def draw_learning_curve(ax: Axes, result: Result | Mapping[str, Any], beta_true=None) -> Axes:
    """``--expertise changing``: β̂_e (posterior mean) with its 90% band against the episode (numbered
    from 0, as every command numbers them), the median as dots, and the stationary β̂ as a line; the
    true β_e in red when the result has it. The β axis is :func:`curve_limits`.

    ``result`` is a :class:`~expertise_irl.result.Result` with its ``changing`` part, or a document
    with ``expertise_by_episode`` and ``beta_hat`` (and ``changing``, ``trend``, as ``infer`` writes).

    gids: ``"curve-band"``, ``"curve-mean"``, ``"curve-median"``, ``"curve-stationary"``,
    ``"curve-truth"``.
    """
    if isinstance(result, Result):
        changing, beta_hat = result.changing, result.beta_hat
    else:
        changing, beta_hat = ChangingExpertise.from_json(result), float(result["beta_hat"])
    if changing is None or not changing.by_episode:
        raise ArgumentError("the result has no learning curve (infer --expertise changing writes it)")
    curve = changing.by_episode
    x = np.array([c["episode"] if is_number(c.get("episode")) else i for i, c in enumerate(curve)])
    get = {k: np.array([np.nan if c[k] is None else c[k] for c in curve], dtype=float)
           for k in ("mean", "median", "q05", "q95")}
    if np.isfinite(get["q05"]).all():  # (a MAP curve is a point per episode: no band)
        ax.fill_between(x, get["q05"], get["q95"], step=None, color="#a5c8ed", alpha=0.7, lw=0,
                        label="90% interval of β_e", gid="curve-band")
    ax.plot(x, get["mean"], color="#1f4e8c", lw=1.8, marker="o", ms=3.5, label="β̂_e (mean)", gid="curve-mean")
    ax.plot(x, get["median"], ls="none", marker="_", ms=9, color="#c2255c", label="median",
            gid="curve-median")
    ax.axhline(beta_hat, color="#495057", ls="--", lw=1.2,
               label=f"one β for all episodes: β̂ = {beta_hat:.3g}", gid="curve-stationary")
    shown = [*get.values(), [beta_hat]]
    if isinstance(beta_true, list | tuple) and len(beta_true) == len(curve):
        ax.plot(x, beta_true, color="#d62728", lw=1.2, marker="x", ms=4, label="true β_e", gid="curve-truth")
        shown.append(beta_true)
    _beta_axis(ax, np.concatenate([np.asarray(v, dtype=float).ravel() for v in shown]))
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("episode (from 0, in the order given)", fontsize=8.5)
    ax.set_ylabel("β (log scale; low = expert)", fontsize=8.5)
    ax.set_title(_curve_title(changing), fontsize=9)
    ax.legend(fontsize=7.5, loc="best", frameon=False)
    maps.tidy(ax)
    return ax


def _curve_title(changing: ChangingExpertise) -> str:
    ch, tr = changing.evidence or {}, changing.trend or {}
    bf = ch.get("log_bayes_factor")
    title = "expertise by episode: " + (f"log Bayes factor {bf:.2f} for changing against one β, "
                                        f"P(changing) = {ch.get('p_changing', float('nan')):.3g}"
                                        if is_number(bf) else "")
    if is_number(tr.get("p_falls")):
        title += f"; P(β falls) = {tr['p_falls']:.2f}"
    elif is_number(tr.get("slope")):
        title += f"MAP learning curve log β_e = log β_0 + λ·{tr.get('g', 'g(e)')}, λ̂ = {tr['slope']:.3g}"
    return title


def _title(result: Result, source: Path, subtitle: str) -> str:
    """The figure's title: file, method, data, β̂ and its group; then ``subtitle``."""
    data = result.data if isinstance(result.data, Mapping) else {}
    what = ""
    if is_number(data.get("episodes")) and is_number(data.get("actions")):
        n, m = int(data["episodes"]), int(data["actions"])
        what = f", {plural(n, 'episode')}, {plural(m, 'action')}"
    return (f"{source.name}: {result.method}{what}; β̂ = {result.beta_hat:.3g} "
            f"({result.estimate.expertise_group or '?'} expertise)\n{subtitle}")


def _draw_warnings(sf_warn, warnings: list[str]) -> None:
    """The first three warnings (each cut to 160 characters) in red, and how many more there are."""
    shown = [w if len(w) <= 160 else w[:157] + "…" for w in warnings[:3]]
    more = f"\n… and {len(warnings) - 3} more" if len(warnings) > 3 else ""
    sf_warn.text(0.5, 0.5, "\n".join(f"warning: {w}" for w in shown) + more
                 + "\n(all in the result's diagnostics.warnings)", ha="center", va="center",
                 fontsize=8.5, color="#b02a1a", gid="warnings")


def _draw_map_panel(top, map_w: float, post_w: float, mdp: TabularMDP, zone_map: ZoneMap | None,
                    trajs: Trajectories | None):
    """The map and demonstrations in a left subfigure of ``top``; the right one, for the posterior."""
    sf_map, sf_post = top.subfigures(1, 2, width_ratios=[map_w, post_w], wspace=0.02)
    ax_map = sf_map.add_subplot()
    handles = draw_demos_on_map(ax_map, mdp, zone_map, trajs)
    ax_map.set_anchor("N")  # spare height goes below the map, where the legend is
    n = trajs.n_episodes if trajs is not None else 0
    label = zone_map.name if zone_map is not None else Path(str(mdp.source)).name
    title = f"{label}: {plural(n, 'episode')}" if trajs is not None else label
    if zone_map is None:
        title += "\ncells from state_xy (for zones: --map MAP)"
    ax_map.set_title(title, fontsize=9)
    if handles:
        _fit_legend(ax_map, handles, width=(map_w - 0.1) * top.dpi)
    return sf_post


def _map_panel_size(mdp: TabularMDP, zone_map: ZoneMap | None, trajs: Trajectories | None
                    ) -> tuple[float, float]:
    """Inches of the map panel: the map (~0.42 in per cell, at most 5.5 in a side) and room
    below it for the legend, at least as wide as a one-column legend of episodes."""
    mw, mh = maps.map_size(zone_map if zone_map is not None else _grid_of(mdp), 5.5, 5.5)
    shown = min(maps.DEMO_EPISODES, trajs.n_episodes) if trajs is not None else 0
    n = len(map_key(mdp, zone_map)) + (1 + 2 * shown if shown else 0)  # + start and end markers, episodes
    rows = math.ceil(n / 2) if mw >= 4.4 else n  # see _fit_legend
    title = 0.45 if zone_map is None else 0.3  # an archive's title has a second line
    return max(mw, MIN_MAP_PANEL) + 0.3, mh + title + 0.2 + 0.15 * rows


def _fit_legend(ax: Axes, handles: list, width: float) -> None:
    """The map's legend below it in two columns (the map's key, then the episodes), or in one
    when two would be wider than ``width`` pixels: a legend wider than its panel would
    squeeze the map (the layout makes room for it) and run into the next panel."""
    for ncol in (2, 1):
        leg = ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=ncol,
                        frameon=False, fontsize=7, handlelength=1.3, columnspacing=0.9)
        leg.set_gid("map-legend")
        if ncol == 1 or leg.get_window_extent(ax.figure.canvas.get_renderer()).width <= width:
            return
        leg.remove()


def _draw_discrete(result: Result, ax_beta: Axes, ax_th, beta_true, theta_true) -> str:
    """Marginal posteriors of a discrete-set result; the subtitle that explains them."""
    names = result.feature_names
    if result.posterior is None:
        raise ArgumentError("a discrete result without its posterior (marginals)")
    m = result.posterior.marginals
    betas, pb = m.beta_values, m.beta_probabilities
    maps.draw_beta_marginal(ax_beta, betas, pb, beta_true=beta_true)
    ax_beta.set_title(rf"$\beta$: marginal posterior, E = {result.beta_hat:.3g}", fontsize=8.5)
    ax_beta.set_ylabel("marginal prob.", fontsize=7.5)
    ax_beta.set_xlabel(r"$\beta$ (low = expert)", fontsize=7.5)
    tv, tp = m.theta_values, m.theta_probabilities
    for i, ax in enumerate(ax_th):
        v, p = theta_component_marginal(tv, tp, i)
        draw_discrete_component(ax, v, p, names[i], mean=result.theta_hat[i],
                                true=None if theta_true is None else theta_true[i])
    return (f"discrete set: {len(betas)} β × {len(tv)} θ; bars = marginal posterior "
            "probabilities; dashed = posterior mean")


def _draw_samples(result: Result, source: Path, ax_beta: Axes, ax_th, beta_true, theta_true) -> str:
    """Histograms of a sampled result's draws (from the samples CSV beside ``source``); the subtitle."""
    names = result.feature_names
    K = len(names)
    chain, beta, theta = load_samples(result, source)
    ci = result.estimate.credible_intervals
    ci = ci if isinstance(ci, Mapping) else {}
    mp = result.estimate.point
    b_int = ci.get("beta") if _valid_interval(ci.get("beta")) else None
    draw_sampled(ax_beta, beta, r"$\beta$", interval=b_int, mean=result.beta_hat,
                 point=mp.beta if mp is not None and is_number(mp.beta) else None, true=beta_true,
                 withheld="beta" in ci and ci["beta"] is None)
    ax_beta.set_xlabel(r"$\beta$ (low = expert)", fontsize=7.5)
    t_ints = ci.get("theta") if isinstance(ci.get("theta"), list | tuple) and len(ci.get("theta")) == K \
        else None
    mp_t = mp.theta if mp is not None and len(mp.theta) == K else None
    for i, ax in enumerate(ax_th):
        draw_sampled(ax, theta[:, i], rf"$\theta$ {names[i]}",
                     interval=t_ints[i] if t_ints and _valid_interval(t_ints[i]) else None,
                     mean=result.theta_hat[i], point=None if mp_t is None else mp_t[i],
                     true=None if theta_true is None else theta_true[i],
                     withheld=t_ints is not None and t_ints[i] is None)
    n_chains = len(np.unique(chain))
    few = " (too few to show a shape)" if len(beta) < 50 else ""
    return (f"{plural(len(beta), 'draw')}{few} from {plural(n_chains, 'chain')}; "
            "shaded = 90% credible interval; dashed = posterior mean; ▲ = best draw")


def _draw_optimum(result: Result, ax_beta: Axes, ax_th) -> str:
    """The point estimate of a MAP result; the subtitle that says it is no posterior."""
    names = result.feature_names
    draw_point(ax_beta, result.beta_hat, r"$\hat\beta$", lo=0.005, hi=20, log=True)
    ax_beta.set_xlabel(r"$\beta$ (log scale; low = expert)", fontsize=7.5)
    hi = max(1.0, max(result.theta_hat) * 1.1)
    for i, ax in enumerate(ax_th):
        draw_point(ax, result.theta_hat[i], rf"$\hat\theta$ {names[i]}", lo=-0.02, hi=hi)
    return "MAP optimum only: this method gives a point, not a posterior"


def result_warnings(result: Result) -> list[str]:
    """The result's ``diagnostics.warnings`` (empty when there are none)."""
    return list(result.warnings)


def _valid_interval(v) -> bool:
    return isinstance(v, list | tuple) and len(v) == 2 and all(is_number(x) for x in v) and v[0] <= v[1]
