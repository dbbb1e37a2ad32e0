"""The quick tier, ``pytest -m "not slow"``: a few minutes that call every module of the package.

A test that takes more than a second or two carries the ``slow`` marker (pyproject.toml); the
rest are the quick tier. The check below runs after every other test of the session (conftest.py
puts it last) and reads what ``tests/quick_tier.py`` recorded while the tier's tests ran: the
source file of every function that started. A module counts when one of its functions or methods
ran during a test of the tier (importing it is not enough; a module with no function counts when
imported). It needs the whole tier, so it skips when the session was given paths or deselected
some of the tier's tests; ``pytest`` and ``pytest -m "not slow"`` from the repository root both
run it.
"""

from __future__ import annotations

import pytest
import quick_tier


def test_every_module_of_the_package_is_called_by_a_quick_test(request):
    why = quick_tier.whole_tier_ran(request.config)
    if why:
        pytest.skip(f"needs the whole quick tier: {why}")
    missing = quick_tier.not_exercised()
    assert not missing, (
        f"{len(missing)} module(s) of src/expertise_irl that no test outside the slow marker calls: "
        f"{', '.join(missing)}; give each a fast test (or make one of its slow tests fast)"
    )


def test_the_module_list_is_the_package():
    names = quick_tier.modules()
    assert {"expertise_irl", "expertise_irl.cli", "expertise_irl.planning.soft_vi"} <= set(names)
    assert all(path.is_file() and path.suffix == ".py" for path in names.values())
