"""The typed result: every document the package wrote before the type existed loads, and
``Result.from_json(doc).to_json()`` gives the document back (with its schema version)."""

import gzip
import json
from pathlib import Path

import pytest

from expertise_irl.errors import InputError
from expertise_irl.result import SCHEMA_VERSION, Result, Samples
from expertise_irl.results import read_result, write_result

DATA = Path(__file__).parent / "data" / "results"
#: Results written by `expertise-irl` before the typed Result (benchmarks/result_digests.py's commands).
FIXTURES = sorted(DATA.glob("*.json.gz"))


def _doc(path: Path) -> dict:
    return json.loads(gzip.decompress(path.read_bytes()))


def test_the_fixtures_cover_every_kind_of_result():
    kinds = {p.name.removesuffix(".json.gz") for p in FIXTURES}
    assert {"result", "trace", "curve", "map", "birl", "demo", "study-P1"} <= kinds


@pytest.mark.parametrize("path", FIXTURES, ids=lambda p: p.name)
def test_an_earlier_result_loads_and_writes_back_unchanged(path):
    doc = _doc(path)
    assert "schema" not in doc  # written before the schema version existed: schema 1
    result = Result.from_json(doc, path)
    assert result.schema == 1
    assert result.method == doc["method"]
    assert result.beta_hat == doc["beta_hat"] and list(result.theta_hat) == doc["theta_hat"]
    assert list(result.warnings) == doc.get("diagnostics", {}).get("warnings", [])
    again = result.to_json()
    assert again.pop("schema") == SCHEMA_VERSION
    assert again == doc
    assert Result.from_json(result.to_json()) == result


def test_typed_parts_read_what_the_document_holds():
    curve = Result.from_json(_doc(DATA / "curve.json.gz"))
    assert curve.changing is not None and len(curve.changing.by_episode) == curve.data["episodes"]
    assert curve.settings.expertise == "changing" and curve.settings.command == "infer"
    trace = Result.from_json(_doc(DATA / "trace.json.gz"))
    assert trace.posterior is not None and len(trace.posterior.trace) == trace.data["actions"] + 1
    assert trace.misspecification is not None and trace.misspecification.verdict
    adaptive = Result.from_json(_doc(DATA / "result.json.gz"))
    assert adaptive.refinement is not None and adaptive.refinement.rounds
    assert len(adaptive.posterior.hypotheses) == adaptive.settings.n_hypotheses
    birl = Result.from_json(_doc(DATA / "birl.json.gz"))
    assert isinstance(birl.samples, Samples) and birl.estimate.credible_intervals["beta"] is not None
    demo = Result.from_json(_doc(DATA / "demo.json.gz"))
    assert demo.diagnostics is None and set(demo.extra) == {"truth", "metrics"}


def test_results_are_frozen():
    result = Result.from_json(_doc(DATA / "map.json.gz"))
    with pytest.raises(AttributeError):
        result.method = "nuts"
    with pytest.raises(TypeError):
        result.settings.values["seed"] = 3


def test_write_and_read_round_trip(tmp_path):
    result = Result.from_json(_doc(DATA / "birl.json.gz"))
    write_result(tmp_path / "r.json", result)
    assert read_result(tmp_path / "r.json") == result


def test_many_draws_go_to_a_csv_beside_the_json(tmp_path):
    result = Result.from_json(_doc(DATA / "birl.json.gz"))
    n, K = 5000, len(result.feature_names)
    draws = Samples(tuple([0] * n), tuple([1.0] * n), tuple((0.2,) * K for _ in range(n)))
    big = result.replace(samples=draws)
    written = write_result(tmp_path / "r.json", big)
    assert written.samples == str(tmp_path / "r.samples.csv")
    assert (tmp_path / "r.samples.csv").read_text().count("\n") == n + 1


def test_a_newer_schema_is_refused():
    doc = {**_doc(DATA / "map.json.gz"), "schema": SCHEMA_VERSION + 1}
    with pytest.raises(InputError, match="newer than this expertise-irl reads"):
        Result.from_json(doc, "new.json")
    with pytest.raises(InputError, match="not an expertise-irl result"):
        Result.from_json({"beta_hat": 1}, "x.json")
