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


def pytest_collection_modifyitems(config, items):
    """Benchmarks (tests using the `benchmark` fixture) run only with --benchmark-only."""
    if config.getoption("benchmark_only", default=False):
        return
    skip = pytest.mark.skip(reason="benchmark: run with `pytest tests/benchmarks --benchmark-only`")
    for item in items:
        if "benchmark" in getattr(item, "fixturenames", ()):
            item.add_marker(skip)
