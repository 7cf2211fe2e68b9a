"""tests/slow_tests.txt names tests that exist, and the duration parser reads pytest's --durations lines."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.conftest import REPO, slow_tests
from tests.slow_list import durations


def test_every_listed_slow_test_exists():
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    collected = {line.strip() for line in done.stdout.splitlines() if "::" in line}
    missing = sorted(slow_tests() - collected)
    assert not missing, f"tests/slow_tests.txt names tests that are gone; regenerate it (tests/slow_list.py): {missing}"


def test_durations_sum_setup_call_and_teardown():
    log = ("============ slowest durations ============\n"
           "3.10s call     tests/test_a.py::test_x[1]\n"
           "0.50s setup    tests/test_a.py::test_x[1]\n"
           "0.01s teardown tests/test_b.py::test_y\n"
           "1 passed in 4.00s\n")
    assert durations(log) == {"tests/test_a.py::test_x[1]": 3.6, "tests/test_b.py::test_y": 0.01}


def test_computed_once_computes_a_value_once_per_session_and_keeps_no_failure(computed_once):
    import uuid

    calls = []

    def compute():
        calls.append(1)
        return {"calls": len(calls)}

    name = f"probe-{uuid.uuid4().hex}"
    assert computed_once(name, compute) == {"calls": 1}
    assert computed_once(name, compute) == {"calls": 1}  # read back, not computed again
    assert len(calls) == 1
    with pytest.raises(ZeroDivisionError):
        computed_once(name + "-raises", lambda: 1 / 0)
    assert computed_once(name + "-raises", lambda: [2]) == [2]  # the failure left nothing behind
