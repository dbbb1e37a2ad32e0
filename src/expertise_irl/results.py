"""Result documents (JSON) and safe output files.

A discrete-set result holds ``beta_hat``, ``theta_hat``, the MAP hypothesis, the
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
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .errors import InputError
from .hypotheses import expertise_group
from .inference.belief import DiscreteBelief, Trace


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
    """``sha256:<hex>`` of a file, to record exactly which input a result came from."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return "sha256:" + h.hexdigest()


def map_digest(zone_map) -> str:
    """``sha256:<hex>`` of a map's content (grid and settings), whether from a file or bundled."""
    text = f"{zone_map.to_text()}goal_bonus={zone_map.goal_bonus!r}\ngamma={zone_map.gamma!r}\n"
    if hasattr(zone_map, "settings_text"):  # a floor plan: its world, cell size and axes too
        text = zone_map.to_text() + zone_map.settings_text()
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def write_json(path: str | Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` as strict JSON (no NaN/Infinity), atomically (via a fresh temporary file)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1, allow_nan=False)
            fh.write("\n")
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the mode open() would
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _umask() -> int:
    """The process umask, read once (reading it means setting it; doing that per write would race
    with threads that create files meanwhile)."""
    global _UMASK
    if _UMASK is None:
        _UMASK = os.umask(0o022)
        os.umask(_UMASK)
    return _UMASK


_UMASK: int | None = None


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
            with open(samples_path, "w", encoding="utf-8", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["chain", "draw", "beta", *feature_names])
                draw = np.zeros(len(beta), dtype=int)
                for c in np.unique(chain):
                    draw[chain == c] = np.arange(int(np.sum(chain == c)))
                for c, d, b, t in zip(chain, draw, beta, theta, strict=True):
                    w.writerow([int(c), int(d), repr(float(b)), *(repr(float(x)) for x in t)])
            doc["samples"] = str(samples_path)
    return doc
