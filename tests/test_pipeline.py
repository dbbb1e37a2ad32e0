"""One pipeline: the Python API's ``infer`` gives the command line's result, and the README's
examples give the results they gave before the pipeline existed (tests/data/results)."""

import gzip
import json
import math
from pathlib import Path

import pytest
from cli_helpers import invoke, ok

import expertise_irl as ei
from expertise_irl.options import Expertise, Method, OptionError

DATA = Path(__file__).parent / "data" / "results"
TIMING = {"version", "schema", "run_time_s", "seconds", "created"}


def _normalised(doc):
    if isinstance(doc, dict):
        return {k: _normalised(v) for k, v in doc.items() if k not in TIMING}
    if isinstance(doc, list):
        return [_normalised(v) for v in doc]
    return doc


def _close(a, b, where=""):
    """Equal JSON values, numbers within 1e-7 relative (the solver's lane width may move the last bits)."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert set(a) == set(b), where
        for k in a:
            _close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{where}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert a is not None and b is not None and math.isclose(a, b, rel_tol=1e-7, abs_tol=1e-9), where
    else:
        assert a == b, where


@pytest.fixture()
def readme(tmp_path, monkeypatch):
    """The README's demonstrations (simulate crossroads --theta 0.5,0.5,0,0,0 --beta 0.5 --seed 1)."""
    (tmp_path / "demos.csv").write_bytes((DATA / "demos.csv").read_bytes())
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.slow
def test_python_infer_is_the_command_lines(readme):
    ok(invoke("infer", "crossroads", "--demos", "demos.csv", "--method", "map", "--out", "map.json"))
    cli = json.loads((readme / "map.json").read_text())
    result = ei.infer("crossroads", "demos.csv", method="map")
    assert isinstance(result, ei.Result)
    assert _normalised(result.to_json()) == _normalised(cli)
    before = json.loads(gzip.decompress((DATA / "map.json.gz").read_bytes()))
    _close(_normalised(cli), _normalised(before))


def test_a_named_set_per_action_gives_the_result_it_gave_before(readme):
    result = ei.infer("crossroads", "demos.csv", thetas="0,0.5,1", betas="0.1,1,10", per_action=True,
                      check="off")
    before = _normalised(json.loads(gzip.decompress((DATA / "trace.json.gz").read_bytes())))
    now = _normalised(result.to_json())
    for part in ("beta_hat", "theta_hat", "marginals", "hypotheses", "trace"):
        _close(now[part], before[part], part)
    assert result.settings["check"] == "off" and result.misspecification is None


def test_objects_and_enums_are_taken_as_well_as_names(readme):
    mdp = ei.load_bundled("crossroads").to_mdp()
    demos = ei.read_demos_csv("demos.csv", mdp)
    result = ei.infer(mdp, demos, Method.DISCRETE, thetas="paper-real", betas="0.1,1,10",
                      expertise=Expertise.CHANGING, check="off")
    assert result.changing is not None and len(result.changing.by_episode) == demos.n_episodes
    assert result.settings["mdp"] is None and result.settings["expertise"] == "changing"


def test_options_are_refused_by_their_field_name(readme):
    with pytest.raises(OptionError, match=r"^tol must be > 0") as e:
        ei.infer("crossroads", "demos.csv", tol=-1)
    assert e.value.fields == ("tol",) and e.value.message(lambda f: f"--{f}").startswith("--tol must")
    with pytest.raises(OptionError, match=r"^method must be one of discrete, birl, map, nuts"):
        ei.infer("crossroads", "demos.csv", method="gibbs")
    with pytest.raises(OptionError, match=r"^chains is not an option of method discrete"):
        ei.infer("crossroads", "demos.csv", chains=2)
    with pytest.raises(OptionError, match=r"^check must be one of off, fast, full"):
        ei.infer("crossroads", "demos.csv", check="slow")
