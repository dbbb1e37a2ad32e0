"""``study --check``: each participant's verdict in ``study.csv`` (column ``misspecification``) and the
count of each verdict in ``study.md``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import invoke, ok
from detour_map import MAP, REDUCED

from expertise_irl.demos.csv_io import write_demos_csv
from expertise_irl.demos.simulation import simulate
from expertise_irl.inference.misspecification import EXPLAINED, UNEXPLAINED, UNKNOWN
from expertise_irl.mdp import TabularMDP
from expertise_irl.worlds.zones import parse_map

BETAS = ",".join(f"{b:g}" for b in np.round(np.logspace(-2.5, 1, 8), 5))
SECTION = "## Low expertise or missing features? (--check fast)"


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """Three people on the map, the study told only the reduced features (an MDP archive):
    A avoids the zone (a preference the features cannot see), 20 episodes; C gives it no weight,
    20 episodes; D gives it no weight, one episode. All at β = 0.05, seeded."""
    d = tmp_path_factory.mktemp("study_mis")
    full = parse_map(MAP.strip("\n"), name="detour").to_mdp()
    reduced = TabularMDP(full.next_state, full.features[..., REDUCED], full.terminal, gamma=full.gamma,
                         feature_names=tuple(full.feature_names[i] for i in REDUCED),
                         start_states=full.start_states, state_xy=full.state_xy)
    reduced.save(d / "reduced.npz")
    people = {"A": (0.6, 20, 1), "C": (0.0, 20, 1), "D": (0.0, 1, 2)}
    for pid, (avoid, n, seed) in people.items():
        th = np.array([0.3, 0.05, avoid, 0.025, 0.025])
        trajs = simulate(full, th / th.sum(), 0.05, n, np.random.default_rng(seed))
        write_demos_csv(d / f"{pid}.csv", trajs, full, fmt="state")
    (d / "manifest.csv").write_text("participant,map,demos\n" + "".join(f"{p},reduced.npz,{p}.csv\n"
                                                                        for p in people), encoding="utf-8")
    return d


@pytest.mark.slow
def test_study_csv_and_md_carry_each_participants_verdict(study):
    # The default (--check fast). Measured with these seeds: A's visits lie far outside the
    # replicates' (p ≈ 0.001, Holm's threshold 0.05/8), C's checks all pass, D has one episode
    # (below the 4 the verdict needs) and no rejected check.
    out = study / "fast"
    res = invoke("study", study / "manifest.csv", "--out", out, "--betas", BETAS, "--figures", "none",
                 "--workers", "1")
    ok(res)
    assert f"{UNEXPLAINED}: 1 (A)" in res.stdout  # the summary line of the checks
    rows = {r["participant"]: r for r in read_csv(out / "study.csv")}
    cols = list(next(iter(rows.values())))
    assert cols[cols.index("warnings") + 1] == "misspecification"
    want = {"A": UNEXPLAINED, "C": EXPLAINED, "D": UNKNOWN}
    assert {p: r["misspecification"] for p, r in rows.items()} == want
    for p, r in rows.items():  # the column is the result's verdict
        doc = json.loads((out / "participants" / p / "result.json").read_text())
        assert doc["diagnostics"]["misspecification"]["verdict"] == r["misspecification"]
    md = (out / "study.md").read_text()
    assert SECTION in md
    section = md.split(SECTION)[1].split("\n## ")[0]
    assert f"| {UNEXPLAINED} | 1 | A |" in section
    assert f"| {EXPLAINED} | 1 | C |" in section
    assert f"| {UNKNOWN} | 1 | D |" in section
    assert "upper bound on the person's noise" in section

    # --check off: the column stays (empty), the section goes
    off = study / "off"
    ok(invoke("study", study / "manifest.csv", "--out", off, "--betas", BETAS, "--figures", "none",
              "--workers", "1", "--check", "off"))
    assert {r["misspecification"] for r in read_csv(off / "study.csv")} == {""}
    assert "Low expertise or missing features?" not in (off / "study.md").read_text()


def test_the_section_without_checks():
    from expertise_irl.userstudy.report import misspecification_markdown

    rows = [{"participant": "P1", "misspecification": ""}]
    assert misspecification_markdown(rows, "off") == ""
    beta = misspecification_markdown(rows, "fast", share="beta")
    assert beta.startswith(SECTION) and "Not available with --share beta" in beta and "| verdict" not in beta
