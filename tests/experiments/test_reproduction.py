"""The committed reproduction (docs/reproduction/) is what today's code makes of its committed rows."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from expertise_irl.experiments.report import build_report

ROOT = Path(__file__).resolve().parents[2] / "docs" / "reproduction"
#: Every committed sweep (a folder with a manifest and a report).
RUNS = sorted(p.name for p in ROOT.iterdir() if (p / "manifest.json").is_file() and (p / "report").is_dir())


def test_every_committed_sweep_is_checked():
    assert {"conditions-paper", "conditions-paper-fixed", "cardinality-paper",
            "cardinality-paper-fixed"} <= set(RUNS)


@pytest.mark.slow
def test_the_readme_matrix_is_what_the_claims_say():
    """The claim × protocol table of docs/reproduction/README.md is the one the committed claims build."""
    from expertise_irl.experiments.report.reproduction import END, START, matrix

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    committed = text.split(START, 1)[1].split(END, 1)[0]
    assert committed.strip() == matrix(ROOT).strip()
    count_line = matrix(ROOT).strip().splitlines()[0]
    assert text.split("\n\n", 2)[1] == f"**{count_line}** (the claim × protocol table below).", \
        "the count line at the top of the page"


@pytest.mark.slow
@pytest.mark.parametrize("run", RUNS)
def test_committed_report_rebuilds_from_committed_rows(run, tmp_path):
    """Claims (verdicts and numbers) and tables rebuilt from the Parquet equal the committed ones:
    a change to the report code that moves a verdict must come with the regenerated report."""
    committed = ROOT / run / "report"
    build_report(ROOT / run, tmp_path / "report")
    ours = pd.read_csv(tmp_path / "report" / "claims.csv")
    theirs = pd.read_csv(committed / "claims.csv")
    assert list(ours["id"]) == list(theirs["id"])
    assert list(ours["verdict"]) == list(theirs["verdict"])
    np.testing.assert_allclose(ours["value"].astype(float), theirs["value"].astype(float), rtol=1e-9)
    for table in sorted((committed / "tables").glob("*.csv")):
        pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "report" / "tables" / table.name),
                                      pd.read_csv(table), check_exact=False, rtol=1e-9)
    links = [line for line in (ROOT / "README.md").read_text().splitlines() if f"]({run}/" in line]
    assert links, f"docs/reproduction/README.md does not link {run}"


def test_report_numbers_are_written_to_ten_significant_digits(tmp_path):
    """Rebuilding a report on another machine writes the same text: no number in its CSV files
    carries digits beyond the tenth, where summation order and SIMD width differ."""
    build_report(ROOT / "cardinality-paper", tmp_path / "report")
    files = [tmp_path / "report" / "claims.csv", *sorted((tmp_path / "report" / "tables").glob("*.csv"))]
    assert len(files) > 1
    for f in files:
        for mantissa in re.findall(r"(?<![\w.])-?(\d+\.\d+)(?:e[-+]\d+)?(?![\w.])", f.read_text()):
            digits = mantissa.replace(".", "").lstrip("0")
            assert len(digits) <= 10, f"{f.name}: {mantissa}"
