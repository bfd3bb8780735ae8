"""Shared fixtures and the test tiers. VTK is configured as the application configures it (STDThread SMP, errors to
logging).

Tiers (``scripts/test`` runs them all; CI too):

- ``gui``: every test under ``tests/ui`` opens the real window and is marked here, automatically; they run in their
  own process under a virtual X server.
- ``slow``: tests whose call took more than 5 s with a warm kernel cache (``--durations``), listed in
  ``tests/slow_tests.txt`` and marked here. At the end of a run the terminal summary lists any unlisted test that took
  longer; ``VOXELSCOPE_UPDATE_SLOW=1 scripts/test`` rewrites the list from that run's durations (a test leaves the
  list only when it took under half the limit, so tests near 5 s do not flip between runs).
- The quick tier, while working: ``scripts/test -m "not slow and not gui"`` (no window, a few minutes).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from app.vtk_setup import configure_vtk

configure_vtk()

TESTS = Path(__file__).resolve().parent
UI_TESTS = TESTS / "ui"
#: The slow tier: one test id (relative to the repository root) per line, then its measured seconds after ``#``.
SLOW_LIST = TESTS / "slow_tests.txt"
#: A test whose call takes longer than this (s) belongs to the slow tier.
SLOW_SECONDS = 5.0


def _read_slow_list() -> dict[str, str]:
    listed = {}
    if SLOW_LIST.is_file():
        for line in SLOW_LIST.read_text(encoding="utf-8").splitlines():
            nodeid, _, note = line.partition("#")
            if nodeid.strip():
                listed[nodeid.strip()] = note.strip()
    return listed


_slow_ids = _read_slow_list()


def pytest_collection_modifyitems(config, items):
    for item in items:
        if UI_TESTS in Path(str(item.fspath)).resolve().parents:
            item.add_marker(pytest.mark.gui)
        if item.nodeid in _slow_ids:
            item.add_marker(pytest.mark.slow)


_durations: dict[str, float] = {}


def pytest_runtest_logreport(report):
    if report.when == "call":
        _durations[report.nodeid] = report.duration


def pytest_terminal_summary(terminalreporter):
    if hasattr(terminalreporter.config, "workerinput"):  # a pytest-xdist worker: the controller sums up
        return
    unlisted = sorted(((s, n) for n, s in _durations.items() if s > SLOW_SECONDS and n not in _slow_ids), reverse=True)
    if unlisted:
        terminalreporter.section(f"tests over {SLOW_SECONDS:g} s not in {SLOW_LIST.name}")
        for seconds, nodeid in unlisted:
            terminalreporter.write_line(f"{seconds:7.1f} s  {nodeid}")
    if os.environ.get("VOXELSCOPE_UPDATE_SLOW") == "1" and _durations:
        _update_slow_list()
        terminalreporter.write_line(f"{SLOW_LIST} rewritten from this run's durations")


def _update_slow_list() -> None:
    """Add every test of this run over :data:`SLOW_SECONDS`, drop those of this run under half of it, keep the rest
    (tests this run did not select keep their entries). Written whole and then renamed: a parallel part of
    ``scripts/test`` never sees half a file."""
    listed = _read_slow_list()
    for nodeid, seconds in _durations.items():
        if seconds > SLOW_SECONDS:
            listed[nodeid] = f"{seconds:.1f} s"
        elif seconds < SLOW_SECONDS / 2:
            listed.pop(nodeid, None)
    lines = ["# The slow tier (see tests/conftest.py): tests whose call took over 5 s with a warm kernel cache."]
    lines += [f"{nodeid}  # {note}" for nodeid, note in sorted(listed.items())]
    partial = SLOW_LIST.with_suffix(".partial")
    partial.write_text("\n".join(lines) + "\n", encoding="utf-8")
    partial.replace(SLOW_LIST)


@pytest.fixture(scope="session")
def ct_phantom():
    """The CT head phantom (FORBILD) at a reduced size (fast), int16 HU, anisotropic spacing."""
    from app.datasets import ct_head_phantom

    return ct_head_phantom(shape=(40, 96, 96), spacing=(2.5, 2.5, 5.4))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
