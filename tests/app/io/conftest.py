"""The long fuzz runs (marked ``long_fuzz``) run only when asked for (``-m long_fuzz``): minutes each, over the same
contract that the default run's fuzz tests check on a sample of the damaged files."""

from __future__ import annotations

import pytest


def pytest_collection_modifyitems(config, items):
    if "long_fuzz" in (config.getoption("markexpr") or ""):
        return
    skip = pytest.mark.skip(reason="a long fuzz run: select it with -m long_fuzz")
    for item in items:
        if item.get_closest_marker("long_fuzz"):
            item.add_marker(skip)
