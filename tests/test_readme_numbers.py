"""The README's measured figures name the machine they come from and match the committed outputs;
its install and test instructions say how to get the test tools and the quick tier."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
RESULTS = ROOT / "benchmarks" / "results"


def _paragraph(text: str, phrase: str) -> str:
    (para,) = [p for p in text.split("\n\n") if phrase in p]
    return " ".join(para.split())


def _observe_median(output: Path) -> tuple[str, float]:
    text = output.read_text(encoding="utf-8")
    cpu = re.search(r"^cpu: (.+)$", text, re.M).group(1)
    median = float(re.search(r"OnlineEstimator\.observe: median ([\d.]+) µs", text).group(1))
    return cpu, median


def test_the_observe_figure_gives_each_cpu_with_its_measured_median():
    para = _paragraph(README, "`observe` is a gather")
    for name in ("online.txt", "online-amd-epyc.txt"):
        assert name in para
        cpu, median = _observe_median(RESULTS / name)
        vendor = "Intel Xeon" if "Intel" in cpu else "AMD EPYC"
        found = re.search(rf"(\d+) µs (?:per action )?on a \d-core {vendor}", para)
        assert found, f"no figure for {vendor} in: {para}"
        assert round(median) == int(found.group(1))


def test_quick_start_says_how_to_get_the_test_tools():
    quick = README.split("## Quick start", 1)[1].split("The hard case is a novice", 1)[0]
    assert 'pip install -e ".[test]"' in quick


def test_the_slow_marker_and_the_quick_tier_are_explained():
    markers = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]["markers"]
    assert any(m.startswith("slow:") for m in markers)
    para = _paragraph(README, "`slow` marker")
    assert 'pytest -m "not slow"' in para
    assert "`tests/test_quick_tier.py`" in para and (ROOT / "tests" / "test_quick_tier.py").is_file()
    assert re.search(r"took [\d.]+ minutes on a fresh clone of a 2-core machine at a load average of \d",
                     para)
    for folder in re.findall(r"`(tests/[a-z]+/)`", para):
        assert (ROOT / folder).is_dir(), folder
