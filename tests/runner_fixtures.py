"""Test-only methods and a hole generator that worker processes can import by name
(``tests.runner_fixtures:Class``), plus tiny synthetic sequences. Fixtures only: the name does not
start with ``test_``, so pytest does not collect it; the runner tests exercise every class here.

Registering them: tests monkeypatch ``method_registry.METHODS`` / ``hole_registry.GENERATORS`` in
the driver; the run spec carries the import string, so spawned workers (which never see the
monkeypatch) load the same classes.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np

from dpcbench.holes.base import DamageResult, HoleGenerator, as_generator
from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.base import PerFrameMethod

HERE = "tests.runner_fixtures"


class IdentityFill(PerFrameMethod):
    """Returns each damaged frame plus ``shift`` on every coordinate (shift changes the scores)."""

    name = "test-identity"

    def __init__(self, shift: float = 0.0):
        self.shift = shift

    def inpaint_frame(self, points, regions):
        return points + self.shift


class RaisingFill(PerFrameMethod):
    name = "test-raises"

    def __init__(self, message: str = "deliberate failure"):
        self.message = message

    def inpaint_frame(self, points, regions):
        raise RuntimeError(self.message)


class CrashingFill(PerFrameMethod):
    """Kills its own process: ``how="exit"`` -> os._exit(7); ``how="kill"`` -> SIGKILL."""

    name = "test-crashes"

    def __init__(self, how: str = "exit"):
        self.how = how

    def inpaint_frame(self, points, regions):
        if self.how == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        os._exit(7)


class HangOnFlagFill(PerFrameMethod):
    """Sleeps forever while the file ``flag`` exists (to kill a sweep mid-way), else like IdentityFill."""

    name = "test-hang"

    def __init__(self, flag: str = "", shift: float = 0.0):
        self.flag = flag
        self.shift = shift

    def inpaint_frame(self, points, regions):
        while self.flag and Path(self.flag).exists():
            time.sleep(0.2)
        return points + self.shift


class CostlyFill(PerFrameMethod):
    """Like IdentityFill, after spending known resources on each frame: ``burn`` CPU seconds of
    this process (a busy loop until `time.process_time` has advanced that much), ``child_burn`` CPU
    seconds in a child process it waits for, and ``sleep`` wall seconds without CPU."""

    name = "test-costly"

    def __init__(self, burn: float = 0.0, child_burn: float = 0.0, sleep: float = 0.0):
        self.burn = burn
        self.child_burn = child_burn
        self.sleep = sleep

    def inpaint_frame(self, points, regions):
        import subprocess
        import sys

        start = time.process_time()
        while time.process_time() - start < self.burn:
            pass
        if self.child_burn:
            subprocess.run([sys.executable, "-c", "import time\nt = time.process_time()\n"
                            f"while time.process_time() - t < {self.child_burn}: pass"], check=True)
        time.sleep(self.sleep)
        return points


class BallHoles(HoleGenerator):
    """Removes the points within ``radius`` of a seeded random point of each frame."""

    name = "test-ball"

    def __init__(self, radius: float = 0.3):
        self.radius = radius

    def damage(self, frames, seed, colors=None):
        rng = as_generator(seed)
        out, removed, regions = [], [], []
        for pts in frames:
            center = pts[rng.integers(len(pts))]
            region = HoleRegion.ball(center, self.radius)
            mask = region.contains(pts)
            out.append(pts[~mask])
            removed.append(mask)
            regions.append([region])
        return DamageResult(out, removed, regions, None)


def sphere_frames(n_frames: int = 3, n_points: int = 800, seed: int = 0) -> list[np.ndarray]:
    """Unit spheres (Fibonacci lattice) drifting along x by 0.05 per frame."""
    i = np.arange(n_points) + 0.5
    phi = np.arccos(1 - 2 * i / n_points)
    theta = np.pi * (1 + 5**0.5) * i
    base = np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])
    rng = np.random.default_rng(seed)
    return [base + [0.05 * f, 0, 0] + rng.normal(0, 1e-3, base.shape) for f in range(n_frames)]


def write_sequence(folder: Path, n_frames: int = 3, n_points: int = 800) -> Path:
    from dpcbench.bench.data.sequences import save_sequence

    save_sequence(sphere_frames(n_frames, n_points), folder, prefix="sphere")
    return folder


def register(monkeypatch) -> None:
    """Make the test methods and generator known by name in this process."""
    from dpcbench.holes import registry as hole_registry
    from dpcbench.methods import registry as method_registry

    for cls in (IdentityFill, RaisingFill, CrashingFill, HangOnFlagFill, CostlyFill):
        monkeypatch.setitem(method_registry.METHODS, cls.name, f"{HERE}:{cls.__name__}")
    monkeypatch.setitem(hole_registry.GENERATORS, BallHoles.name, f"{HERE}:BallHoles")


def register_global() -> None:
    """`register` for a separate driver process (no monkeypatch there: the process ends with the test)."""
    from dpcbench.holes import registry as hole_registry
    from dpcbench.methods import registry as method_registry

    for cls in (IdentityFill, RaisingFill, CrashingFill, HangOnFlagFill, CostlyFill):
        method_registry.METHODS[cls.name] = f"{HERE}:{cls.__name__}"
    hole_registry.GENERATORS[BallHoles.name] = f"{HERE}:BallHoles"


if __name__ == "__main__":  # a driver with the test entries registered: python -m tests.runner_fixtures run ...
    import sys

    from dpcbench.bench.cli import main

    register_global()
    sys.exit(main(sys.argv[1:]))


def voxel_plane(shift: int, size: int = 40, z: int = 20) -> np.ndarray:
    """A ``size`` x ``size`` plane of voxels at height ``z``, moved ``shift`` voxels along x (a frame of a
    sliding plane)."""
    i, j = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    return np.column_stack([i.ravel() + shift, j.ravel(), np.full(i.size, z)]).astype(np.float64)


def tidy_results(cells: dict, frames: int = 3, seeds: int = 3, metric: str = "gpsnr_d1", step: float = 1.0):
    """A tidy results table (pandas) as the store gives it: cells (sequence, method) -> the value of frame f, seed s
    = base + step (f + 0.1 s)."""
    import pandas as pd

    rows = [{"sequence": seq, "method": m, "method_params": "{}", "metric": metric, "scope": "frame",
             "peak": "intrinsic" if metric.startswith("gpsnr") else "", "frame": f, "seed": s,
             "value": base + step * (f + 0.1 * s)}
            for (seq, m), base in cells.items() for f in range(frames) for s in range(seeds)]
    return pd.DataFrame(rows)
