"""The quick tier (``pytest -m "not slow"``): which of the package's modules its tests call.

While a test not marked ``slow`` runs (its setup, call and teardown), a trace function notes the
source file of every Python function that starts, in the main thread and in threads started
meanwhile. A module of ``src/expertise_irl`` counts as exercised by the quick tier when one of its
functions or methods ran; class bodies, module bodies, lambdas and comprehensions do not count,
so importing a module is not exercising it. A module that defines no function at all has
nothing to call and counts when it is imported. Code run in another process (a subprocess, a
process pool) is not seen, so it does not count.

Tracing slows Python down, so it stops once every module has been called: tracing less can only
leave a module uncounted, never count one that did not run. ``tests/test_quick_tier.py`` reads
the result after every other test of the session; ``tests/conftest.py`` registers the hooks.
"""

from __future__ import annotations

import ast
import inspect
import sys
import threading
from pathlib import Path

import pytest

import expertise_irl

SRC = Path(expertise_irl.__file__).parent  # as imported: the paths the interpreter gives code
CHECK = "test_quick_tier.py::test_every_module_of_the_package_is_called_by_a_quick_test"

_NEWLOCALS = inspect.CO_NEWLOCALS
state = {"collected": 0, "selected": 0, "whole_suite": False, "traced": True, "test": ""}
first_called_by: dict[str, str] = {}  # source file -> the test during which one of its functions first ran


def modules() -> dict[str, Path]:
    """Every module of the package, by dotted name."""
    out = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _defines_functions(path: Path) -> bool:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) for n in ast.walk(tree))


# The source files (as the interpreter names them) of the modules whose functions have not run yet.
pending: set[str] = {str(p) for p in modules().values() if _defines_functions(p)}


def _trace(frame, event, arg):
    code = frame.f_code
    if code.co_filename in pending and code.co_flags & _NEWLOCALS and code.co_name[0] != "<":
        pending.discard(code.co_filename)
        first_called_by[code.co_filename] = state["test"]
        if not pending:
            sys.settrace(None)
            threading.settrace(None)
    # None: no line events inside the frame.


def not_exercised() -> list[str]:
    """The modules that no test of the tier called in this session (see the module's docstring)."""
    missing = []
    for name, path in modules().items():
        if str(path) in pending or (not _defines_functions(path) and name not in sys.modules):
            missing.append(name)
    return missing


def whole_tier_ran(config) -> str | None:
    """None when this session ran every test of the tier in ``tests/``, else why it cannot tell."""
    if not state["whole_suite"]:
        return 'the session was given paths; run `pytest -m "not slow"` from the repository root'
    if state["selected"] < state["collected"]:
        return "some of its tests were deselected (-k, --deselect, -m)"
    if not state["traced"]:
        return "another tracer (a debugger, coverage) was active"
    return None


def in_tier(item) -> bool:
    """In the quick tier: not marked ``slow``."""
    return item.get_closest_marker("slow") is None


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(session, config, items):
    state["collected"] = sum(map(in_tier, items))
    state["whole_suite"] = config.args_source == pytest.Config.ArgsSource.TESTPATHS


@pytest.hookimpl(trylast=True)
def pytest_collection_finish(session):
    """After deselection: count the tier's tests kept and run the check after all of them."""
    items = session.items
    state["selected"] = sum(map(in_tier, items))
    checks = [i for i in items if i.nodeid.endswith(CHECK)]
    if checks:
        items[:] = [i for i in items if i not in checks] + checks


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if not pending or not in_tier(item):
        yield
        return
    if sys.gettrace() is not None:
        state["traced"] = False
        yield
        return
    state["test"] = item.nodeid
    sys.settrace(_trace)
    threading.settrace(_trace)
    try:
        yield
    finally:
        sys.settrace(None)
        threading.settrace(None)
