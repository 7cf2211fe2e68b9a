"""Shared fixtures. Real data from ../shared is used when present and skipped cleanly when not."""

from __future__ import annotations

import contextlib
import json
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


@contextlib.contextmanager
def _file_lock(path: Path):
    """An exclusive lock on ``path`` (created) for the block: POSIX ``flock``; where there is none (Windows), no lock."""
    try:
        import fcntl
    except ImportError:  # the workers may then compute a shared value twice, never read a half-written one
        yield
        return
    with open(path, "a+") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


@pytest.fixture(scope="session")
def computed_once(tmp_path_factory):
    """``computed_once(name, compute)``: ``compute()`` (a JSON value) made once per test session, also under
    pytest-xdist: the first worker to ask computes it and writes it to the folder the session's workers share, the
    others wait for it and read it. For a costly fixture whose value the workers would otherwise each compute (xdist
    spreads a module's tests over the workers, and a module or session fixture is set up once per worker). Nothing is
    written when ``compute`` raises (a failure or a skip): each worker then raises on its own."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the session's folder; each worker's basetemp is a folder in it

    def once(name: str, compute):
        path = root / f"{name}.json"
        with _file_lock(root / f"{name}.lock"):
            if path.is_file():
                return json.loads(path.read_text())
            value = compute()
            partial = path.with_suffix(".partial")
            partial.write_text(json.dumps(value))
            partial.replace(path)
            return value

    return once


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
