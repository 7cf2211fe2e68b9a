"""Shared, deterministic data for the benchmark suite (pytest-benchmark; see README.md here).

Every fixture is session-scoped and lazy: a benchmark file pays only for the sizes it asks for, and
the embedded human figure is cached on disk by bench.data.datasets after its first generation (about
2 s / 14 s / 24 s per 100k / 800k / 1M-point frame on a 2-core machine), so later sessions start at once.

Sizes (embedded "human", walk motion, seed 0; point counts measured on frame 0):
  "100k": size="small", 10-bit grid                        ~96k points a frame
  "800k": bit_depth=11, height=1037 voxels                 ~800k points a frame (799,626)
  "1m":   bit_depth=11, height=1165 voxels                 ~1M points a frame (1,009,042)
The 800k and 1M figures are about 1000 voxels tall with unit voxel spacing, like the paper's 8i
sequences (10-bit, ~800k-1M points), so methods' default cube size (M = 20) fits them as it fits
8i data; their coordinates run up to 2047 because the figure is taller than a 10-bit grid allows
(bench.data.standins.human caps the height at a fraction of the grid).

Fixtures:
  bench_sequence(size)      -> bench.data.sequences.Sequence of 3 consecutive frames
  frames_100k / 800k / 1m   -> list of 3 (N, 3) float64 arrays
  damaged_100k / 800k       -> holes.base.DamageResult: "region" holes, preset medium, 5 a frame,
                               temporally coherent, seed 0 (methods take .frames and .regions)
  cloud_pair_100k / 1m      -> (reference, result): frame 0, and frame 0 with 5 medium holes removed
                               and every point moved by N(0, 0.5^2) voxels (seed 0): what a metric
                               sees when scoring an imperfect inpainting
"""

from __future__ import annotations

import numpy as np
import pytest

SIZES = {
    "100k": {"size": "small"},
    "800k": {"bit_depth": 11, "height": 1037},
    "1m": {"bit_depth": 11, "height": 1165},
}
N_FRAMES = 3
HOLES = {"preset": "medium", "count": 5, "coherent": True}
SEED = 0


_sequences: dict[str, object] = {}


def bench_sequence(size: str):
    """The embedded human at one of SIZES (3 frames), generated once per session (cached on disk)."""
    if size not in SIZES:
        raise KeyError(f"unknown benchmark size {size!r}; choose one of {', '.join(SIZES)}")
    if size not in _sequences:
        from dpcbench.bench.data.datasets import load_dataset

        _sequences[size] = load_dataset("human", frames=N_FRAMES, seed=SEED, **SIZES[size])
    return _sequences[size]


def damage(frames, seed: int = SEED):
    """Region holes (HOLES) on the frames with a fixed seed."""
    from dpcbench.holes.registry import get_generator

    return get_generator("region", **HOLES).damage(frames, seed=seed)


def cloud_pair(frames, seed: int = SEED):
    """(reference, imperfect result) as described in the module docstring."""
    reference = frames[0]
    damaged = damage([reference], seed=seed).frames[0]
    rng = np.random.default_rng(seed)
    return reference, damaged + rng.normal(0.0, 0.5, size=damaged.shape)


@pytest.fixture(scope="session")
def frames_100k():
    return bench_sequence("100k").points


@pytest.fixture(scope="session")
def frames_800k():
    return bench_sequence("800k").points


@pytest.fixture(scope="session")
def frames_1m():
    return bench_sequence("1m").points


@pytest.fixture(scope="session")
def damaged_100k(frames_100k):
    return damage(frames_100k)


@pytest.fixture(scope="session")
def damaged_800k(frames_800k):
    return damage(frames_800k)


@pytest.fixture(scope="session")
def cloud_pair_100k(frames_100k):
    return cloud_pair(frames_100k)


@pytest.fixture(scope="session")
def cloud_pair_1m(frames_1m):
    return cloud_pair(frames_1m)
