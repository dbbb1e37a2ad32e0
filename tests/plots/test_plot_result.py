"""The figures read the typed Result: a result and its document draw the same pixels, and results
written by earlier versions (tests/data/results) draw as they did, a trace without its band and
group probabilities included."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from expertise_irl.errors import InputError
from expertise_irl.plots import check
from expertise_irl.plots import results as rp
from expertise_irl.result import Result
from expertise_irl.results import read_result

DATA = Path(__file__).resolve().parents[1] / "data" / "results"


def _doc(name: str) -> dict:
    return json.loads(gzip.decompress((DATA / f"{name}.json.gz").read_bytes()))


def _pixels(fig) -> np.ndarray:
    FigureCanvasAgg(fig).draw()
    return np.asarray(fig.canvas.buffer_rgba()).copy()


@pytest.mark.parametrize("name", ["trace", "demo"])
def test_a_result_and_its_document_draw_the_same_figure(name):
    doc = _doc(name)
    typed = Result.from_json(doc)
    a = _pixels(rp.result_figure(typed, source=f"{name}.json"))
    b = _pixels(rp.result_figure(doc, source=f"{name}.json"))
    assert a.shape == b.shape and np.array_equal(a, b)


def test_demo_truth_is_drawn_from_the_typed_result():
    typed = Result.from_json(_doc("demo"))
    assert isinstance(typed.extra["truth"]["theta"], tuple)  # read-only: a tuple, not a list
    fig = rp.result_figure(typed, source="demo.json")
    assert "red = the truth" in fig.get_suptitle()
    assert [ln for ax in fig.get_axes() for ln in ax.lines if ln.get_gid() == "true"]


def test_an_older_trace_reads_without_band_and_groups_and_draws_without_them():
    doc = _doc("trace")
    for e in doc["trace"]:
        del e["beta_band"], e["group_probabilities"]
    typed = Result.from_json(doc)
    entries = typed.posterior.trace
    assert all(e.beta_band is None and e.group_probabilities is None for e in entries)
    assert typed.to_json()["trace"] == doc["trace"]  # written back as it was read
    t = rp.trace_arrays(entries)
    assert t["band"] is None and t["groups"] is None
    fig = rp.result_figure(typed, source="old.json")
    (ax_b,) = [ax for ax in fig.get_axes() if any(ln.get_gid() == "trace-beta" for ln in ax.lines)]
    assert "this result has no band" in ax_b.get_title()
    assert not [c for ax in fig.get_axes() for c in ax.collections if c.get_gid() == "trace-band"]


def test_the_check_figure_reads_the_typed_diagnostics():
    typed = Result.from_json(_doc("trace"))
    fig = check.check_figure(typed, source="trace.json")
    assert fig.get_suptitle().startswith(typed.misspecification.verdict)
    with pytest.raises(InputError, match=r"demo\.json: the result has no diagnostics\.misspecification"):
        check.check_figure(Result.from_json(_doc("demo")), source="demo.json")


def test_broken_inline_samples_are_a_one_line_input_error(tmp_path):
    doc = _doc("birl")
    del doc["samples"]["chain"]
    path = tmp_path / "birl.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(InputError, match=r"birl\.json: 'samples' must hold chain, beta and theta \(5 per"):
        read_result(path)
