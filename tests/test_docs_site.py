"""The documentation site (mkdocs.yml) builds in strict mode, with its tutorials executed.

One build, shared by the tests below: `mkdocs build --strict` fails on a broken link or anchor,
a docstring griffe cannot read and a tutorial cell that raises. The tests then check what
strict mode cannot: that each tutorial page shows its outputs, that the links inside the
notebooks resolve, and that the API reference documents every public name.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from urllib.parse import urlsplit

import pytest

import expertise_irl

# Every test reads the one site build (2–3 minutes with its executed tutorials).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]

#: tutorial page -> lines its executed cells print (HTML-escaped as in the page)
TUTORIAL_OUTPUTS = {
    "infer-a-recording": [
        "filled gaps 1",                      # discretise --fill-gaps
        "gap from cell",                      # the error without it
        "wrote result.json (95 hypotheses",   # infer
        "→ medium expertise",                 # the result read back
        "cosine similarity of θ̂ and θ*",
    ],
    "user-study": [
        "wrote out/study.csv",
        "Spearman ρ between β* and β̂",
        "typical β, exp μ",                   # population.json read back
        "P(μ_novice &lt; μ_trained)",
    ],
    "reproduce-a-figure": [
        "168 rows written to conditions",     # experiment run, smoke
        "4 done / 4 total, 0 failed",         # experiment status
        "report written to conditions/report/report.md",
        "fig2.png",
    ],
    "teaching": [
        "model pedagogical, λ=1, observer paper-real Θ × 0.01,0.0158",   # simulate --lambda
        "teacher  verdict teaching",                                      # infer's teaching record
        "doer     verdict doing",
        "pedagogical: demonstrations read as teaching",                   # compare-models
    ],
}
#: PNG figures each tutorial displays
TUTORIAL_IMAGES = {"infer-a-recording": 3, "user-study": 2, "reproduce-a-figure": 1, "teaching": 1}


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built from this checkout, into a temporary folder, tutorials executed afresh."""
    work = tmp_path_factory.mktemp("docs")
    out = work / "site"
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "TMPDIR": str(work)}
    # From `work`, so that mkdocs-jupyter's cache (a path relative to the working directory)
    # starts empty and every tutorial is executed.
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"), "-d", str(out)],
        cwd=work, env=env, capture_output=True, text=True, timeout=1200,
    )
    log = f"{proc.stdout[-4000:]}\n{proc.stderr[-8000:]}"
    assert proc.returncode == 0, f"mkdocs build --strict failed:\n{log}"
    return out


def _page(site: Path, path: str) -> str:
    page = site / path / "index.html"
    assert page.is_file(), f"{path} was not built"
    return page.read_text(encoding="utf-8")


@pytest.mark.parametrize("name", sorted(TUTORIAL_OUTPUTS))
def test_tutorial_pages_show_their_outputs(site: Path, name: str) -> None:
    html = _page(site, f"tutorials/{name}")
    for line in TUTORIAL_OUTPUTS[name]:
        assert line in html, f"tutorials/{name}: no output {line!r}"
    images = html.count("data:image/png;base64,")
    assert images >= TUTORIAL_IMAGES[name], f"tutorials/{name}: {images} PNG outputs"
    assert "Traceback (most recent call last)" not in html
    assert (site / "tutorials" / name / f"{name}.py").is_file(), "the jupytext source is offered for download"


@pytest.mark.parametrize("name", sorted(TUTORIAL_OUTPUTS))
def test_tutorial_links_resolve(site: Path, name: str) -> None:
    """Links in a notebook's Markdown are HTML to mkdocs, so strict mode does not check them."""
    page_dir = site / "tutorials" / name
    html = _page(site, f"tutorials/{name}")
    links = [h for h in re.findall(r'href="([^"]+)"', html) if h.startswith("../../") or h.startswith("../")]
    targets = {urlsplit(h).path for h in links if not h.endswith((".css", ".js"))}
    assert targets, f"tutorials/{name} links to no other page"
    for target in targets:
        resolved = (page_dir / target).resolve()
        found = resolved.is_file() or (resolved / "index.html").is_file()
        assert found, f"tutorials/{name}: broken link {target}"


def test_api_reference_documents_every_public_name(site: Path) -> None:
    api = "".join(p.read_text(encoding="utf-8") for p in (site / "api").rglob("index.html"))
    public = [n for n in expertise_irl.__all__ if n != "__version__"]
    missing = [n for n in public
               if f'id="expertise_irl{expertise_irl._EXPORTS[n]}.{n}"' not in api]
    assert not missing, f"not in the API reference: {missing}"
    assert 'id="expertise_irl.experiments.load"' in api


def test_model_page_has_the_papers_equations(site: Path) -> None:
    html = _page(site, "model")
    assert html.count('class="arithmatex"') > 10  # typeset by MathJax in the browser
    assert 'id="a-property-of-the-model-worth-knowing"' in html  # linked from reproduction/README.md
