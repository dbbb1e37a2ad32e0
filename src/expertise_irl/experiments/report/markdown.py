"""report.md: the header of the sweep, the claims with their rules, figures, tables and sections."""

from __future__ import annotations

import math

from .claims import RULES, VERDICT_NOTES, claims_frame, rule_kinds
from .parts import Report, Table
from .sweep import workers_text


def _cell(v) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return "n/a"
        return f"{v:.4g}"
    return str(v).replace("|", "\\|").replace("\n", " ")


def md_table(frame) -> str:
    cols = [str(c) for c in frame.columns]
    lines = ["| " + " | ".join(_cell(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for row in frame.itertuples(index=False):
        lines.append("| " + " | ".join(_cell(v) for v in row) + " |")
    return "\n".join(lines)


def _inline(d: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in d.items())


def header(sweep) -> str:
    m = sweep.manifest
    versions = m.get("versions") or {}
    machine = m.get("machine") or {}
    vtext = ", ".join(f"{k} {v}" for k, v in versions.items() if v != "not installed")
    mtext = ", ".join(f"{k} {v}" for k, v in machine.items())
    cfg = _inline(m.get("config") or {})
    chash = str(m.get("config_hash", ""))[:12]
    rows = [
        ("study", f"{m.get('study')} (version {m.get('study_version', '?')})"),
        ("scale", m.get("scale", "?")),
        ("seed", m.get("seed", "?")),
        ("config", f"`{cfg}`" + (f" (SHA-256 {chash}…)" if chash else "")),
        ("rows", f"{len(sweep.rows):,}"),
        ("tasks", f"{sweep.done} done / {sweep.total} total, {sweep.failed} failed"),
        ("task wall time", f"{duration(sweep.task_time_s)}: the sum of the wall times of the "
                           f"{len(sweep.timings)} finished tasks (`wall_time_s` in `timings/`); tasks on "
                           "parallel workers overlap, so this is not the sweep's elapsed time"),
        ("runs", runs_text(sweep)),
        ("elapsed time", elapsed_text(sweep)),
        ("versions", vtext or "not recorded"),
        ("machine", mtext or "not recorded"),
        ("sweep created", m.get("created", "?")),
        ("sweep directory", f"`{sweep.root}`"),
    ]
    lines = ["| | |", "|---|---|"] + [f"| {k} | {_cell(v)} |" for k, v in rows]
    return "\n".join(lines)


def duration(seconds: float) -> str:
    """``"177.8 s"``, with minutes or hours beside it from two minutes on: ``"5400.0 s (1.5 h)"``."""
    text = f"{seconds:.1f} s"
    if seconds >= 3600:
        return f"{text} ({seconds / 3600:.1f} h)"
    return f"{text} ({seconds / 60:.1f} min)" if seconds >= 120 else text


def elapsed_text(sweep) -> str:
    """The elapsed time of the recorded invocations of ``experiment run`` (``wall_time_s`` of each
    ``runs/*.json``), summed; says how many records lack it."""
    if not sweep.runs:
        return "not recorded (no `runs/*.json`)"
    times, n = sweep.run_times_s, len(sweep.runs)
    if not times:
        return "not recorded (no `wall_time_s` in `runs/*.json`)"
    k = len(times)
    who = (f"the {k} invocation{'s' if k != 1 else ''} of `experiment run`" if k == n
           else f"the {k} of {n} invocations of `experiment run` that record it ({n - k} without "
                "`wall_time_s`)")
    return f"{duration(sum(times))}: the sum of the elapsed times of {who} (`wall_time_s` in `runs/*.json`)"


def runs_text(sweep) -> str:
    """The recorded invocations of ``experiment run`` (``runs/*.json``): engine and workers of each."""
    if not sweep.runs:
        return "not recorded (no `runs/*.json`)"
    n = len(sweep.runs)
    return f"{n} recorded in `runs/`: " + workers_text(sweep.runs)


def smoke_warning(report: Report, sweep, *, markdown: bool = False) -> str | None:
    """At scale ``smoke``: the line that says its verdicts mean nothing (None at other scales)."""
    if sweep.manifest.get("scale") != "smoke":
        return None
    n = f" (n = {report.people})" if report.people is not None else ""
    scale = "`smoke`" if markdown else "smoke"
    return (f"Scale {scale} is a test of the machinery: its verdicts rest on a handful of people{n} "
            "and mean nothing.")


def unfinished_warning(sweep) -> str | None:
    if sweep.unfinished <= 0:
        return None
    return (f"{sweep.unfinished} of {sweep.total} tasks are not finished ({sweep.failed} failed); "
            f"this report uses the {sweep.done} finished tasks only and may change when the sweep completes")


def _table_block(t: Table) -> str:
    return (f"### {t.title}\n\n{md_table(t.display)}\n\n{t.caption} "
            f"(Numbers: [`tables/{t.name}.csv`](tables/{t.name}.csv).)\n")


def render(report: Report, sweep) -> str:
    out = [f"# {report.title}\n"]
    smoke = smoke_warning(report, sweep, markdown=True)
    if smoke:
        out.append(f"**{smoke}**\n")
    warn = unfinished_warning(sweep)
    if warn:
        out.append(f"> **Warning: unfinished sweep.** {warn}.\n")
    out.append(header(sweep) + "\n")
    out.extend(n + "\n" for n in report.notes)
    out.append("## Claims\n")
    if report.claims:
        frame = claims_frame(report.claims)[["claim", "section", "paper", "ours", "verdict", "why"]]
        out.append(md_table(frame) + "\n")
        out.append("Every verdict is computed from the rows by the rule of its kind (numbers in "
                   "[`claims.csv`](claims.csv)):\n")
        kinds = list(dict.fromkeys(k for c in report.claims for k in rule_kinds(c.rule)))
        out.extend(f"- {RULES[k]}" for k in kinds)
        verdicts = {c.verdict for c in report.claims}
        out.extend(f"- {text}" for v, text in VERDICT_NOTES.items() if v in verdicts)
        out.append("")
    else:
        out.append("This study goes beyond the paper: it has no claim of the paper to judge.\n")
    out.extend(report.rules)
    if report.figures:
        out.append("## Figures\n")
        for f in report.figures:
            out.append(f"### {f.title}\n\n![{f.title}](figures/{f.name}.png)\n\n{f.caption} "
                       f"([PDF](figures/{f.name}.pdf))\n")
    if report.tables:
        out.append("## Tables\n")
        out.extend(_table_block(t) for t in report.tables)
    for s in report.sections:
        out.append(f"## {s.title}\n\n{s.text}\n")
        if s.table is not None:
            out.append(md_table(s.table.display) + "\n\n" + s.table.caption
                       + f" (Numbers: [`tables/{s.table.name}.csv`](tables/{s.table.name}.csv).)\n")
    return "\n".join(out).rstrip() + "\n"
