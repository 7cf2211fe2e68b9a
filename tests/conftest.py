"""Shared fixtures. Real data from ../shared is used when present and skipped cleanly when not."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DPCBENCH_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder (real captures, golden values); the test is skipped without it."""
    if not (SHARED / "data").is_dir():
        pytest.skip(f"real data folder {SHARED / 'data'} not present")
    return SHARED


SLOW_LIST = REPO / "tests" / "slow_tests.txt"


def slow_tests() -> set[str]:
    """Node ids listed in tests/slow_tests.txt (its rule and how to regenerate it: tests/slow_list.py)."""
    if not SLOW_LIST.is_file():
        return set()
    lines = (line.strip() for line in SLOW_LIST.read_text().splitlines())
    return {line for line in lines if line and not line.startswith("#")}


@pytest.hookimpl(tryfirst=True)  # before -m selects on the marks
def pytest_collection_modifyitems(config, items):
    """Mark the tests of tests/slow_tests.txt ``slow``; benchmarks (tests using the `benchmark`
    fixture) run only with --benchmark-only."""
    slow = slow_tests()
    for item in items:
        if item.nodeid in slow:
            item.add_marker(pytest.mark.slow)
    if config.getoption("benchmark_only", default=False):
        return
    skip = pytest.mark.skip(reason="benchmark: run with `pytest tests/benchmarks --benchmark-only`")
    for item in items:
        if "benchmark" in getattr(item, "fixturenames", ()):
            item.add_marker(skip)
