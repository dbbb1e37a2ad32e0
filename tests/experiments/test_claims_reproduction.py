"""The claim × protocol matrix of docs/reproduction/README.md, from hand-made runs."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from expertise_irl.experiments.report import reproduction as R

COLUMNS = ["id", "section", "claim", "paper", "ours", "verdict", "why", "rule", "n", "value", "ci_low",
           "ci_high", "number"]


def _claim(id, section, verdict, number="", why="", paper="p", claim=None):
    return {"id": id, "section": section, "claim": claim or f"claim {id}", "paper": paper,
            "ours": f"{number} (n = 9)", "verdict": verdict, "why": why, "rule": "ordering", "n": 9,
            "value": 1.0, "ci_low": "", "ci_high": "", "number": number}


def _run(folder: Path, name: str, claims: list[dict], *, rows: int = 10, mode: str | None = None,
         config: str = "", legacy: bool = False) -> Path:
    """A run folder: config.toml, rows/ (with ``goal_reward_mode`` = ``mode`` if given) and
    report/claims.csv (``legacy``: without the ``number`` column, as written before it existed)."""
    root = folder / name
    (root / "rows").mkdir(parents=True)
    (root / "report").mkdir()
    (root / "config.toml").write_text(config)
    cols = {"episodes": list(range(rows))}
    if mode is not None:
        cols["goal_reward_mode"] = [mode] * rows
    pq.write_table(pa.table(cols), root / "rows" / "t000.parquet")
    frame = pd.DataFrame(claims, columns=COLUMNS)
    if legacy:
        frame = frame.drop(columns="number")
    frame.to_csv(root / "report" / "claims.csv", index=False)
    return root


@pytest.fixture
def folder(tmp_path):
    f = tmp_path / "reproduction"
    f.mkdir()
    _run(f, "conditions-small", [_claim("VI-B", "VI-B", "reproduced", "Full 0.6 vs Fixed θ 1.7"),
                                 _claim("T1-x-beta", "VI-D", "differs", "ρ = −0.01", why="inconclusive: ...",
                                        claim="Table I, row “x”, column “Expertise distance”")],
         rows=500, legacy=True)  # no protocol anywhere: scaled
    _run(f, "conditions-paper", [_claim("VI-B", "VI-B", "not reproduced", "Full 2 vs Fixed θ 1")],
         rows=100, mode="scaled")  # fewer rows, but the paper-scale run
    _run(f, "conditions-paper-fixed", [_claim("VI-B", "VI-B", "reproduced", "Full 0.1 vs Fixed θ 1.9")],
         rows=100, config='[conditions]\ngoal_reward_mode = "fixed"\n')  # protocol from the config
    _run(f, "optimisation-small", [_claim("VII-B-beta-birl_box", "VII-B", "reproduced", "1.6×"),
                                   _claim("VII-B-beta-map", "VII-B", "not judged (ours)", "2×",
                                          paper="— (ours)")], rows=50, mode="fixed")
    _run(f, "optimisation-big", [_claim("VII-B-beta-birl_box", "VII-B", "differs", "3×"),
                                 _claim("VII-D", "VII-D", "not judged", "22×")], rows=80, mode="fixed")
    _run(f, "optimisation-relative", [_claim("VII-B-beta-birl_box", "VII-B", "not reproduced", "0.6×")],
         rows=50, config='[optimisation]\nmodel = "maxent-relative"\n')
    (f / "fixed.toml").write_text("[conditions]\n")  # not a run: ignored
    return f


def test_protocol_of_a_run(folder):
    assert R.run_protocol(folder / "conditions-small") == ("scaled", 500)
    assert R.run_protocol(folder / "conditions-paper") == ("scaled", 100)
    assert R.run_protocol(folder / "conditions-paper-fixed") == ("fixed", 100)
    assert R.run_protocol(folder / "optimisation-big") == ("fixed", 80)
    assert R.run_protocol(folder / "optimisation-relative") == ("scaled, model maxent-relative", 50)


def _table(text: str) -> dict:
    """{claim text: {column: cell}} of the matrix."""
    lines = [line for line in text.splitlines() if line.startswith("| ")]
    head = [c.strip() for c in lines[0].strip("|").split(" | ")]
    out = {}
    for line in lines[1:]:
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        out[cells[1]] = dict(zip(head, cells, strict=True))
    return out


def test_matrix_picks_the_paper_run_then_the_largest(folder):
    text = R.matrix(folder)
    table = _table(text)
    vib = table["claim VI-B"]
    assert vib["`scaled`"].startswith("**not reproduced**: Full 2 vs Fixed θ 1 ([conditions-paper](")
    assert vib["`fixed`"].startswith("**reproduced**: Full 0.1 vs Fixed θ 1.9 ([conditions-paper-fixed](")
    box = table["claim VII-B-beta-birl_box"]
    assert box["`fixed`"] == ("**differs**: 3× ([optimisation-big](optimisation-big/report/report.md)) "
                              "(small scale)")  # no paper-scale run judges it: said, not silent
    assert not vib["`fixed`"].endswith("(small scale)")
    assert box["`scaled`"] == "—"
    assert box["`scaled, model maxent-relative`"].startswith("**not reproduced**: 0.6×")
    # a legacy claims.csv: the number from the start of "ours"; an inconclusive differs says so
    cell = table["Table I, row “x”, column “Expertise distance”"]["`scaled`"]
    assert cell.startswith("**differs (inconclusive)**: ρ = −0.01 ([conditions-small](")
    assert "claim VII-B-beta-map" not in table  # ours, not the paper's
    # columns: the finishing protocol first; rows in the paper's section order
    assert text.splitlines()[6].startswith("| section | claim | paper | `fixed` | `scaled` | `scaled, model")
    assert [r["section"] for r in table.values()] == ["VI-B", "VI-D", "VII-B", "VII-D"]


def test_count_line(folder):
    first = R.matrix(folder).splitlines()[0]
    # fixed: VI-B reproduced, VII-B differs, VII-D not judged (not counted); scaled: VI-B not
    # reproduced, Table I differs
    assert first == ("Reproduced under the finishing protocol (`fixed`): 1 of 2; under `scaled`: 0 of 2; "
                     "under `scaled, model maxent-relative`: 0 of 1.")


def test_count_over_the_claims_judged_under_both(folder):
    lines = R.matrix(folder).splitlines()
    # judged under both protocols: VI-B only (fixed reproduced, scaled not); VII-B (fixed only) and
    # Table I (scaled only) are left out, so that the two counts compare the same claims
    assert lines[2] == "Judged under both protocols: reproduced under `fixed` 1 of 1, under `scaled` 0 of 1."
    assert '"(small scale)" after the run marks a cell' in lines[4]


def test_count_line_without_fixed_runs(tmp_path):
    _run(tmp_path, "only", [_claim("VI-B", "VI-B", "reproduced", "x")])
    assert R.matrix(tmp_path).splitlines()[0] == ("Reproduced under the finishing protocol (`fixed`): no run "
                                                  "yet; under `scaled`: 1 of 1.")


def test_write_between_the_markers_only(folder, capsys):
    readme = folder / "README.md"
    prose = "# Title\n\nSome prose | with a bar.\n\n"
    readme.write_text(prose + f"{R.START}\nold table\n{R.END}\n\nMore prose.\n")
    assert R.main([str(folder), "--write", "README.md"]) == 0
    text = readme.read_text()
    assert text.startswith(prose + R.START + "\nReproduced under the finishing protocol")
    assert text.endswith(f"{R.END}\n\nMore prose.\n") and "old table" not in text
    assert R.main([str(folder), "--write", str(readme)]) == 0  # again, by its path: the same text
    assert readme.read_text() == text
    assert "written between the markers" in capsys.readouterr().err


def test_without_markers_it_prints_and_writes_nothing(folder, capsys):
    readme = folder / "README.md"
    readme.write_text("# Title\n\nNo markers here.\n")
    assert R.main([str(folder), "--write", "README.md"]) == 1
    assert readme.read_text() == "# Title\n\nNo markers here.\n"
    out = capsys.readouterr()
    assert out.out.startswith("Reproduced under") and "no <!-- claims:start -->" in out.err
    assert R.main([str(folder)]) == 0 and capsys.readouterr().out.startswith("Reproduced under")
    assert R.replace_between_markers(f"{R.END} then {R.START}", "x") is None  # out of order


def test_missing_folder_and_readme_are_errors(tmp_path, capsys):
    assert R.main([str(tmp_path / "absent")]) == 2
    assert R.main([str(tmp_path), "--write", "NOPE.md"]) == 2
    assert "no such file" in capsys.readouterr().err
