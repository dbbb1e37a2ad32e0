"""Result documents (JSON), written and read here, and safe output files.

The typed form of a result is :class:`~expertise_irl.result.Result`; the functions here build its
document (:func:`discrete_result`, :func:`continuous_result`), write it (:func:`write_result`) and
read it back (:func:`read_result`; :func:`load_result` gives the checked document itself). A
discrete-set result holds ``beta_hat``, ``theta_hat``, the MAP hypothesis, the
marginals, every hypothesis with its ``log_likelihood``, ``log_posterior`` and
``probability``, the settings used and the package version. A log-likelihood of −∞
(a hypothesis that cannot produce an observed action) is written as ``null``.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import __version__
from .atomic import atomic_open
from .errors import InputError, read_text
from .hypotheses import expertise_group
from .result import METHODS, SAMPLED, SCHEMA_VERSION, Result, Samples, check_document

if TYPE_CHECKING:
    from .inference.belief import DiscreteBelief, Trace
    from .mdp import TabularMDP


def _num(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _vec(v) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=float).ravel()]


def discrete_result(belief: DiscreteBelief, *, feature_names, settings: dict[str, Any],
                    data: dict[str, Any] | None = None, trace: Trace | None = None,
                    trace_index=None) -> dict[str, Any]:
    """The JSON-ready result document of a discrete-set inference."""
    hyp = belief.hypotheses
    betas, pb = belief.marginal_beta()
    thetas, pt = belief.marginal_theta()
    theta_map, beta_map, p_map = belief.map_hypothesis()
    lp, ll, p = belief.log_posterior, belief.log_likelihood, belief.probabilities
    beta_hat = belief.mean_beta
    doc: dict[str, Any] = {
        "schema": SCHEMA_VERSION,
        "version": __version__,
        "method": "discrete",
        "feature_names": list(feature_names),
        "beta_hat": beta_hat,
        "theta_hat": _vec(belief.mean_theta),
        "expertise_group": expertise_group(beta_hat),
        "group_probabilities": belief.group_probabilities(),
        "map": {"theta": _vec(theta_map), "beta": beta_map, "probability": p_map},
        "entropy": belief.entropy,
        "log_evidence": _num(belief.log_evidence),
        "n_impossible": belief.n_impossible,
        "marginals": {
            "beta": {"values": _vec(betas), "probabilities": _vec(pb)},
            "theta": {"values": [_vec(t) for t in thetas], "probabilities": _vec(pt)},
        },
        "hypotheses": [
            {"theta": _vec(t), "beta": float(b), "log_likelihood": _num(l_),
             "log_posterior": _num(q), "probability": float(pp)}
            for t, b, l_, q, pp in zip(hyp.theta, hyp.beta, ll, lp, p, strict=True)
        ],
        "data": data or {},
        "settings": settings,
    }
    if trace is not None:
        episodes, steps = trace_index
        doc["trace"] = [
            {"episode": None if i == 0 else int(episodes[i - 1]),
             "step": None if i == 0 else int(steps[i - 1]),
             "beta_hat": float(trace.mean_beta[i]), "theta_hat": _vec(trace.mean_theta[i]),
             "entropy": float(trace.entropy[i]),
             "group_probabilities": trace.groups_at(i),
             "beta_band": [float(trace.beta_low[i]), float(trace.beta_high[i])]}
            for i in range(len(trace.mean_beta))
        ]
    return doc


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def check_writable(path: str | Path, *, force: bool, inputs=()) -> Path:
    """Check an output path before any work is done.

    Refuses to overwrite an existing file unless ``force``, and refuses, even with ``force``,
    a path that is one of the command's ``inputs`` (the same file by any name); the parent
    must be an existing, writable directory.
    """
    path = Path(path)
    for given in inputs:
        if given is not None and _same_file(path, Path(given)):
            raise InputError(f"{path}: is one of this command's inputs ({given}); "
                             "choose another output path (--force never overwrites an input)")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, expected a file path")
    if path.exists() and not force:
        raise InputError(f"{path}: already exists; pass --force to overwrite it")
    parent = path.parent
    if not parent.exists():
        raise InputError(f"{parent}: output directory does not exist")
    if not parent.is_dir():
        raise InputError(f"{parent}: is not a directory, so {path} cannot be created")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{parent}: output directory is not writable")
    return path


def file_digest(path: str | Path) -> str:
    """``sha256:<hex>`` of a file, to record exactly which input a result came from; of a folder
    (a ROS 2 bag), of its files' relative names and contents, in name order."""
    h = hashlib.sha256()
    path = Path(path)
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for p in files:
        if path.is_dir():
            name = p.relative_to(path).as_posix().encode()
            h.update(len(name).to_bytes(8, "little") + name + p.stat().st_size.to_bytes(8, "little"))
        with open(p, "rb") as fh:
            for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(block)
    return "sha256:" + h.hexdigest()


def map_digest(zone_map) -> str:
    """``sha256:<hex>`` of a map's content (grid and settings), whether from a file or bundled."""
    text = f"{zone_map.to_text()}goal_bonus={zone_map.goal_bonus!r}\ngamma={zone_map.gamma!r}\n"
    if zone_map.goal_reward_mode != "scaled":  # (scaled maps keep the digests they always had)
        text += f"goal_reward_mode={zone_map.goal_reward_mode}\n"
    if hasattr(zone_map, "settings_text"):  # a floor plan: its world, cell size and axes too
        text = zone_map.to_text() + zone_map.settings_text()
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def write_json(path: str | Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` as strict JSON (no NaN/Infinity), atomically (:mod:`expertise_irl.atomic`)."""
    with atomic_open(path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=1, allow_nan=False)
        fh.write("\n")


def finite_or_null(doc: Any, path: str = "", found: list[str] | None = None) -> Any:
    """``doc`` with every non-finite float replaced by ``None``; the paths of those go to ``found``."""
    if isinstance(doc, dict):
        return {k: finite_or_null(v, f"{path}.{k}" if path else str(k), found) for k, v in doc.items()}
    if isinstance(doc, list | tuple):
        return [finite_or_null(v, f"{path}[{i}]", found) for i, v in enumerate(doc)]
    if isinstance(doc, float | np.floating) and not math.isfinite(doc):
        if found is not None:
            found.append(path)
        return None
    return doc


#: Draws written inline in the result JSON up to this many; beyond, to a CSV beside it.
INLINE_DRAWS = 4000


def samples_path_for(out_path: str | Path) -> Path:
    """Where the draws of a large sampling run go: ``<out>.samples.csv`` beside the JSON."""
    out_path = Path(out_path)
    return out_path.with_name(out_path.stem + ".samples.csv")


def continuous_result(method_out: dict[str, Any], *, method: str, feature_names, settings: dict[str, Any],
                      data: dict[str, Any], samples_path: Path | None) -> dict[str, Any]:
    """The JSON-ready result of ``birl``, ``map`` or ``nuts``; writes large draws to ``samples_path``."""
    out = dict(method_out)
    draws = out.pop("draws", None)
    beta_hat = float(out["beta_hat"])
    doc: dict[str, Any] = {
        "schema": SCHEMA_VERSION,
        "version": __version__,
        "method": method,
        "feature_names": list(feature_names),
        **{k: out.pop(k) for k in ("beta_hat", "theta_hat")},
        "expertise_group": expertise_group(beta_hat),
        **out,
        "data": data,
        "settings": settings,
    }
    # A statistic that came out NaN or infinite is written as null, with the reason.
    bad: list[str] = []
    doc = finite_or_null(doc, found=bad)
    if bad:
        diag = doc.setdefault("diagnostics", {})
        missing = diag.setdefault("unavailable", {})
        for where_ in bad:
            missing.setdefault(where_, "not a finite number for this run (too few draws, or a stuck chain)")
    if draws is not None:
        chain, theta, beta = draws
        if len(beta) <= INLINE_DRAWS or samples_path is None:
            doc["samples"] = {"chain": [int(c) for c in chain], "beta": _vec(beta),
                              "theta": [_vec(t) for t in theta]}
        else:
            doc["samples"] = str(write_samples_csv(samples_path, chain, beta, theta, feature_names))
    return doc


def write_samples_csv(path: str | Path, chain, beta, theta, feature_names) -> Path:
    """Draws as ``chain,draw,beta,<feature names>`` (one row each, full precision), atomically."""
    chain = np.asarray(chain)
    with atomic_open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["chain", "draw", "beta", *feature_names])
        draw = np.zeros(len(beta), dtype=int)
        for c in np.unique(chain):
            draw[chain == c] = np.arange(int(np.sum(chain == c)))
        for c, d, b, t in zip(chain, draw, beta, theta, strict=True):
            w.writerow([int(c), int(d), repr(float(b)), *(repr(float(x)) for x in t)])
    return Path(path)


def write_result(path: str | Path, result: Result, *, samples_path: str | Path | None = None) -> Result:
    """Write ``result`` as strict JSON (:func:`write_json`), atomically.

    Draws beyond :data:`INLINE_DRAWS` go to a CSV file and the JSON names that file.

    Args:
        path: the JSON file to write.
        result: the result.
        samples_path: where the draws go when they do not stay inline (default
            :func:`samples_path_for` ``path``).

    Returns:
        The result as written (its ``samples`` the CSV's path when they went there).
    """
    s = result.samples
    if isinstance(s, Samples) and len(s.beta) > INLINE_DRAWS and np.ndim(s.theta) == 2:
        where = write_samples_csv(samples_path or samples_path_for(path), s.chain, s.beta, s.theta,
                                  result.feature_names)
        result = result.replace(samples=str(where))
    write_json(path, result.to_json())
    return result


def read_result(path: str | Path) -> Result:
    """The :class:`~expertise_irl.result.Result` in ``path`` (written by any version of the package).

    Args:
        path: a result JSON written by ``infer``, ``demo``, ``study`` or :func:`write_result`.

    Returns:
        The typed result.

    Raises:
        InputError: naming ``path`` if it is not JSON, not a result, or a part of it is not as any
            version wrote it.
    """
    doc = load_result(path)
    try:
        return Result.from_json(doc, path)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: a part of the result cannot be read "
                         f"({type(exc).__name__}: {exc})") from None


# ----------------------------------------------------------------------- reading

def is_number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def load_result(path: str | Path) -> dict[str, Any]:
    """Read and check a result JSON written by ``infer`` or ``demo``.

    Args:
        path: the JSON file.

    Returns:
        The document as parsed, checked to be a result.

    Raises:
        InputError: naming ``path`` if it is not JSON or not a result.
    """
    path = Path(path)
    text = read_text(path, "not a result JSON (not UTF-8 text)")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not a result JSON (line {exc.lineno}: {exc.msg})") from None
    check_result(doc, path)
    return doc


def check_result(doc, path: str | Path) -> None:
    """Raise :class:`InputError` naming ``path`` unless ``doc`` is a result document."""
    check_document(doc, path)
    method = doc["method"]
    if method not in METHODS:
        raise InputError(f"{path}: unknown method {method!r} (expected one of {', '.join(METHODS)})")
    names = doc.get("feature_names")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise InputError(f"{path}: 'feature_names' must be a non-empty list of names")
    K = len(names)
    if not is_number(doc.get("beta_hat")):
        raise InputError(f"{path}: 'beta_hat' must be a finite number")
    th = doc.get("theta_hat")
    if not isinstance(th, list) or len(th) != K or not all(is_number(v) for v in th):
        raise InputError(f"{path}: 'theta_hat' must be {K} finite numbers (one per feature)")
    if method == "discrete":
        _check_marginals(doc, path, K)
        trace = doc.get("trace")
        if trace is not None and (not isinstance(trace, list) or not trace or not all(
                isinstance(e, dict) and is_number(e.get("beta_hat")) and is_number(e.get("entropy"))
                for e in trace)):
            raise InputError(f"{path}: 'trace' must be a list of entries with beta_hat and entropy")
    elif method in SAMPLED and "samples" not in doc:
        raise InputError(f"{path}: a {method} result needs 'samples'")


def _check_marginals(doc, path, K: int) -> None:
    m = doc.get("marginals")
    try:
        b, t = m["beta"], m["theta"]
        bv, bp = np.asarray(b["values"], dtype=float), np.asarray(b["probabilities"], dtype=float)
        tv, tp = np.asarray(t["values"], dtype=float), np.asarray(t["probabilities"], dtype=float)
    except (TypeError, KeyError, ValueError):
        raise InputError(f"{path}: a discrete result needs 'marginals' of beta and theta "
                         "(values and probabilities)") from None
    if bv.ndim != 1 or bv.shape != bp.shape or bv.size == 0:
        raise InputError(f"{path}: marginals.beta: values and probabilities must be equal-length lists")
    if tv.ndim != 2 or tv.shape[1] != K or tp.shape != (tv.shape[0],):
        raise InputError(f"{path}: marginals.theta: expected [n, {K}] values and n probabilities")
    for what, p in (("beta", bp), ("theta", tp)):
        if not np.all(np.isfinite(p)) or (p < 0).any() or p.sum() <= 0:
            raise InputError(f"{path}: marginals.{what}: probabilities must be finite, >= 0, not all 0")


def load_samples(result: Result | Mapping[str, Any], path: str | Path
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(chain [n], beta [n], theta [n, K])`` of a sampling result (a :class:`Result` or its document).

    ``samples`` is inline (``{"chain", "beta", "theta"}``) or the path of a CSV
    ``chain,draw,beta,<feature names>``; a relative path not found as given is looked up
    in the folder of the result ``path``.
    """
    path = Path(path)
    if isinstance(result, Result):
        names, s = list(result.feature_names), result.samples
        s = s.to_json() if isinstance(s, Samples) else s
    else:
        names, s = result["feature_names"], result["samples"]
    K = len(names)
    if isinstance(s, Mapping):
        try:
            chain = np.asarray(s["chain"], dtype=np.int64)
            beta = np.asarray(s["beta"], dtype=float)
            theta = np.asarray(s["theta"], dtype=float).reshape(len(beta), K)
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{path}: 'samples' must hold chain, beta and theta ({K} per draw) "
                             "of equal length") from None
    elif isinstance(s, str):
        csv_path = Path(s)
        if not csv_path.is_file() and not csv_path.is_absolute():
            csv_path = path.parent / csv_path
        if not csv_path.is_file() and (path.parent / Path(s).name).is_file():
            csv_path = path.parent / Path(s).name
        if not csv_path.is_file():
            raise InputError(f"{path}: its samples file {s} is not found (looked beside the result too)")
        chain, beta, theta = _read_samples_csv(csv_path, names)
    else:
        raise InputError(f"{path}: 'samples' must be an object or the path of a CSV")
    if chain.shape != beta.shape or len(beta) == 0:
        raise InputError(f"{path}: 'samples' must hold at least one draw, chain and beta of equal length")
    if not (np.all(np.isfinite(beta)) and np.all(np.isfinite(theta))):
        raise InputError(f"{path}: 'samples' hold non-finite values")
    return chain, beta, theta


def _read_samples_csv(path: Path, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    with open(path, encoding="utf-8", newline="") as fh:
        rows = list(csv.reader(fh))
    want = ["chain", "draw", "beta", *names]
    if not rows or rows[0] != want:
        raise InputError(f"{path}:1: expected the header {','.join(want)}")
    try:
        data = np.array([[float(v) for v in r] for r in rows[1:] if r], dtype=float)
    except ValueError:
        raise InputError(f"{path}: every value after the header must be a number") from None
    if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != len(want):
        raise InputError(f"{path}: expected at least one row of {len(want)} numbers")
    return data[:, 0].astype(np.int64), data[:, 2], data[:, 3:]


def check_features(result: Result | Mapping[str, Any], result_path, mdp: TabularMDP, mdp_label) -> None:
    """The map's features must be the result's ``feature_names``, in order."""
    names = result.feature_names if isinstance(result, Result) else result["feature_names"]
    have, want = list(mdp.feature_names), list(names)
    if have != want:
        raise InputError(f"{mdp_label}: its features ({', '.join(have)}) do not match the "
                         f"feature_names of {result_path} ({', '.join(want)})")
