"""tests/slow_tests.txt names tests that exist, and the duration parser reads pytest's --durations lines."""

from __future__ import annotations

import subprocess
import sys

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
