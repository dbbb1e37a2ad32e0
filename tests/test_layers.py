"""The package's architecture (docs/architecture.md): layers that import only downwards, no import cycles.

The contracts live in pyproject.toml (``[tool.importlinter]``) and are checked by import-linter's
own command, ``lint-imports``, as a developer would run it.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "expertise_irl"


def _contracts() -> list[dict]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"][
        "contracts"]


def _lint_imports() -> Path:
    exe = Path(sys.executable).with_name("lint-imports")
    if not exe.exists():
        pytest.skip("import-linter is not installed (pip install -e '.[test]')")
    return exe


def test_import_contracts_hold():
    """Every package imports only from the layers below it, and no package's modules import each
    other in a circle."""
    run = subprocess.run([str(_lint_imports()), "--no-cache"], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert f"{len(_contracts())} kept, 0 broken" in run.stdout


def test_every_package_has_a_layer():
    """A new top-level module or package must be placed in the layers, or it escapes the check."""
    (layers,) = [c["layers"] for c in _contracts() if c["type"] == "layers"]
    placed = {name.strip() for layer in layers for name in layer.split("|")}
    present = {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()
               if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").exists()}
    assert present == placed, f"not in a layer: {sorted(present - placed)}; gone: {sorted(placed - present)}"


def test_the_cycle_contract_covers_the_whole_package():
    (cycles,) = [c for c in _contracts() if c["type"] == "acyclic_siblings"]
    assert cycles["ancestors"] == ["expertise_irl"]
    assert "ignore_imports" not in cycles
