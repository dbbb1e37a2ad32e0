"""The claim × protocol matrix of ``docs/reproduction/README.md``, from every run's ``report/claims.csv``.

Each run folder under the reproduction folder is a sweep with its report. Its protocol is its rows'
``goal_reward_mode`` (rows written before the column existed: its ``config.toml``'s field of the same
name; neither: ``scaled``), with the goal bonus beside it where it is not the studies' 10
(``goal_bonus``: the finishing runs of Sec. VII pay more) and the observation model where the run's
model is not the paper's (``model`` in ``config.toml``). A claim judged by several runs of one
protocol takes the verdict of the paper-scale run (the one whose folder name contains ``paper``),
else of the run with the most rows, a cell then marked "(small scale)". Beside the count of
reproduced claims under each protocol, a second line counts them over only the claims judged under
both. The paper's claims
only: our methods' numbers (verdict "not judged (ours)") are left out.

``python -m expertise_irl.experiments.report.reproduction docs/reproduction [--write README.md]``
prints the table, or writes it between the ``<!-- claims:start -->`` and ``<!-- claims:end -->``
markers of the README (and nowhere else).
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ...atomic import write_atomic
from .claims import DIFFERS, NO_DATA, NOT_JUDGED, NOT_REPRODUCED, REPRODUCED, WITHHELD
from .sweep import DEFAULT_PROTOCOL

START, END = "<!-- claims:start -->", "<!-- claims:end -->"
#: The protocol under which the simulated people finish (the goal pays outside θ·φ).
FINISHING = "fixed"
#: The order of the protocols' columns: the finishing one first.
PROTOCOL_ORDER = (FINISHING, DEFAULT_PROTOCOL)
#: The order of the sections' rows.
SECTIONS = ("VI-A", "VI-B", "VI-C", "VI-D", "VI-E", "VII-A", "VII-B", "VII-C", "VII-D")
JUDGED = (REPRODUCED, DIFFERS, NOT_REPRODUCED)
#: After the run of a cell taken from a run that is not paper-scale (no paper-scale run judges it).
SMALL = " (small scale)"


@dataclass(frozen=True)
class Run:
    """One run folder: its name, protocol, rows (how many) and its claims (a DataFrame)."""

    name: str
    protocol: str
    rows: int
    claims: object  # pandas.DataFrame


def _config(root: Path) -> dict:
    """``config.toml`` flattened: every table's keys (the study's table holds the fields)."""
    path = root / "config.toml"
    if not path.is_file():
        return {}
    data = tomllib.loads(path.read_text())
    flat = {k: v for k, v in data.items() if not isinstance(v, dict)}
    for v in data.values():
        if isinstance(v, dict):
            flat.update(v)
    return flat


def _rows(root: Path) -> tuple[int, set[str]]:
    """How many rows the run holds and the values of their ``goal_reward_mode`` (empty without it)."""
    import pyarrow.parquet as pq

    count, modes = 0, set()
    for f in sorted((root / "rows").glob("*.parquet")):
        count += pq.read_metadata(f).num_rows
        if "goal_reward_mode" in pq.read_schema(f).names:
            col = pq.read_table(f, columns=["goal_reward_mode"]).column(0).to_pylist()
            modes |= {str(v) for v in col if v is not None}
    return count, modes


#: The studies' goal bonus (``goal_bonus``); a run with another one is its own protocol.
DEFAULT_GOAL_BONUS = 10.0


def run_protocol(root: Path) -> tuple[str, int]:
    """(protocol, rows) of the run in ``root``: see the module's docstring."""
    count, modes = _rows(root)
    cfg = _config(root)
    mode = "+".join(sorted(modes)) if modes else str(cfg.get("goal_reward_mode") or DEFAULT_PROTOCOL)
    model = cfg.get("model")
    bonus = cfg.get("goal_bonus")
    if isinstance(bonus, int | float) and bonus != DEFAULT_GOAL_BONUS:  # another protocol
        mode = f"{mode}, goal bonus {bonus:g}"
    return (mode if model in (None, "maxent") else f"{mode}, model {model}"), count


def read_runs(folder: Path) -> list[Run]:
    """Every run under ``folder`` with a ``report/claims.csv``."""
    import pandas as pd

    runs = []
    for path in sorted(Path(folder).glob("*/report/claims.csv")):
        root = path.parent.parent
        protocol, count = run_protocol(root)
        claims = pd.read_csv(path, dtype=str, keep_default_na=False)
        runs.append(Run(root.name, protocol, count, claims))
    return runs


def paper_scale(name: str) -> bool:
    """Whether the run folder ``name`` is a paper-scale run (its name contains ``paper``)."""
    return "paper" in name


def _preferred(runs: list[Run]) -> list[Run]:
    """The runs of one protocol, best first: paper-scale by name, then the most rows."""
    return sorted(runs, key=lambda r: (not paper_scale(r.name), -r.rows, r.name))


def _number(rec: dict) -> str:
    number = rec.get("number") or ""
    if not number:  # claims.csv written before the column: the start of "ours"
        number = rec.get("ours", "").split(" (")[0].split(";")[0]
    return number


def _verdict(rec: dict) -> str:
    v = rec["verdict"]
    return f"{v} (inconclusive)" if v == DIFFERS and rec.get("why", "").startswith("inconclusive") else v


def _rank(order: tuple, value) -> int:
    return order.index(value) if value in order else len(order)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def collect(runs: list[Run]) -> tuple[list[str], dict, dict]:
    """(protocols in column order, {claim id: (section, claim, paper)}, {(id, protocol): (run, record)})."""
    protocols = sorted({r.protocol for r in runs} | set(PROTOCOL_ORDER),
                       key=lambda p: (_rank(PROTOCOL_ORDER, p), p))
    rows, cells = {}, {}
    for protocol in protocols:
        for run in _preferred([r for r in runs if r.protocol == protocol]):
            for rec in run.claims.to_dict("records"):
                if rec["verdict"] == NOT_JUDGED:
                    continue
                rows.setdefault(rec["id"], (rec["section"], rec["claim"], rec["paper"]))
                cells.setdefault((rec["id"], protocol), (run.name, rec))
    return protocols, rows, cells


def count_line(protocols: list[str], rows: dict, cells: dict) -> str:
    """"Reproduced under the finishing protocol (`fixed`): N of M; under `scaled`: N of M"."""
    parts = []
    for p in protocols:
        recs = [cells[(i, p)][1] for i in rows if (i, p) in cells]
        judged = [r for r in recs if r["verdict"] in JUDGED]
        n = sum(r["verdict"] == REPRODUCED for r in judged)
        what = f"{n} of {len(judged)}" if recs else "no run yet"
        parts.append(f"the finishing protocol (`{p}`): {what}" if p == FINISHING else f"`{p}`: {what}")
    return "Reproduced under " + "; under ".join(parts) + "."


def both_line(rows: dict, cells: dict) -> str:
    """"Judged under both protocols: reproduced under `fixed` N1 of M, under `scaled` N2 of M", M the
    claims with a verdict under both (the same claims under each protocol)."""
    judged = {p: {i for i in rows if (i, p) in cells and cells[(i, p)][1]["verdict"] in JUDGED}
              for p in PROTOCOL_ORDER}
    common = set.intersection(*judged.values())
    counts = [(p, sum(cells[(i, p)][1]["verdict"] == REPRODUCED for i in common)) for p in PROTOCOL_ORDER]
    return ("Judged under both protocols: reproduced under "
            + ", under ".join(f"`{p}` {n} of {len(common)}" for p, n in counts) + ".")


def matrix(folder) -> str:
    """The Markdown block: the count line, what M counts, and the claim × protocol table."""
    protocols, rows, cells = collect(read_runs(Path(folder)))
    order = sorted(rows, key=lambda i: _rank(SECTIONS, rows[i][0]))
    lines = [count_line(protocols, rows, cells), "", both_line(rows, cells), "",
             f"N of M: M counts the paper's claims with a verdict ({', '.join(JUDGED)}) under that protocol; "
             f"a claim the rows cannot judge (\"{WITHHELD}\", \"{NO_DATA}\") is not counted; \"judged under "
             "both\" counts only the claims with a verdict under both protocols, so that the two numbers "
             "compare the same claims. Each cell: the verdict, our number and the run it comes from (the "
             "paper-scale run where several runs of one protocol judge the claim); \"(small scale)\" after "
             "the run marks a cell no paper-scale run of that protocol judges, taken from a smaller run. "
             "Built by `python -m expertise_irl.experiments.report.reproduction`.",
             "", "| section | claim | paper | " + " | ".join(f"`{p}`" for p in protocols) + " |",
             "|" + "---|" * (3 + len(protocols))]
    for i in order:
        section, claim, paper = rows[i]
        shown = []
        for p in protocols:
            if (i, p) not in cells:
                shown.append("—")
                continue
            run, rec = cells[(i, p)]
            number = _number(rec)
            shown.append(f"**{_verdict(rec)}**" + (f": {number}" if number else "")
                         + f" ([{run}]({run}/report/report.md))" + ("" if paper_scale(run) else SMALL))
        lines.append("| " + " | ".join(_cell(c) for c in [section, claim, paper, *shown]) + " |")
    return "\n".join(lines) + "\n"


def replace_between_markers(text: str, block: str) -> str | None:
    """``text`` with what lies between the markers replaced by ``block``; None if the markers are absent
    (or out of order)."""
    start, end = text.find(START), text.find(END)
    if start < 0 or end < start:
        return None
    head = text[:start + len(START)]
    return head + "\n" + block.rstrip("\n") + "\n" + text[end:]


def _readme(folder: Path, given: str) -> Path:
    """``given`` inside the folder where it is there (``--write README.md``), else as given."""
    path = Path(given)
    return folder / path if not path.is_absolute() and (folder / path).is_file() else path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m expertise_irl.experiments.report.reproduction",
                                     description="The claim × protocol matrix of the reproduction runs.")
    parser.add_argument("folder", help="the reproduction folder (e.g. docs/reproduction)")
    parser.add_argument("--write", metavar="README", help="write the table between the markers of README "
                        "(a name inside the folder, else a path)")
    args = parser.parse_args(argv)
    folder = Path(args.folder)
    if not folder.is_dir():
        print(f"error: {folder}: not a directory", file=sys.stderr)
        return 2
    block = matrix(folder)
    if not args.write:
        sys.stdout.write(block)
        return 0
    readme = _readme(folder, args.write)
    if not readme.is_file():
        print(f"error: {readme}: no such file", file=sys.stderr)
        return 2
    new = replace_between_markers(readme.read_text(), block)
    if new is None:
        sys.stdout.write(block)
        print(f"{readme}: no {START} … {END} markers; printed the table instead, wrote nothing",
              file=sys.stderr)
        return 1
    write_atomic(readme, new)
    print(f"{readme}: claims table written between the markers", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
