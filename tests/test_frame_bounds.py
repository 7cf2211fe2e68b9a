"""A frame count that cannot fit in memory is refused at once with the count that fits (issue 51):
`generate --frames 99999999` on a stand-in used to run for hours."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.plyio import PointCloud
from dpcbench.bench.data.sources.embedded import available_memory_bytes, check_frames_fit


def _frame(n: int) -> PointCloud:
    return PointCloud(np.zeros((n, 3)), np.zeros((n, 3), np.uint8), np.zeros((n, 3)))


def test_the_bound_is_half_the_available_memory():
    frame = _frame(1000)  # 24 kB + 3 kB + 24 kB = 51 000 bytes
    check_frames_fit("s", 10, frame, available=2 * 10 * 51_000)  # exactly half: accepted
    with pytest.raises(UserError, match=r"s: 11 frames of 0\.0 MB each .* ask for at most 10 frames"):
        check_frames_fit("s", 11, frame, available=2 * 10 * 51_000)


def test_available_memory_is_known_here():
    available = available_memory_bytes()
    assert available is None or available > 2**20


def test_generate_refuses_a_count_past_memory_at_once(tmp_path):
    out = tmp_path / "g"
    done = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", "generate", "human", "--param", "size=tiny",
                           "--frames", "99999999", "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "ask for at most" in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not out.exists()
