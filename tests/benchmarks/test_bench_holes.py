"""Hole generator and hole detection timings on a 1M-point frame (run with --benchmark-only).

Frame: the embedded human, 1,009,042 points (conftest "1m": bit_depth 11, 1165 voxels tall), frame 0.
Each generator damages that one frame (KD-tree builds, normals and visibility included); the
coherent case times 3 frames (the tracking needs the next frame) and reports seconds for all 3.
Slow cases run one round (pedantic), the rest three.

    .venv/bin/python -m pytest tests/benchmarks/test_bench_holes.py --benchmark-only \
        [--benchmark-timer=time.process_time]

Hole detection's output is checked apart from its speed: ``detect_holes_agreement.py`` (the same regions after a
same-output change) and ``detect_holes_quality.py`` (recall and precision against the generators' truth). Figures
as measured, version by version: docs/benchmark-history.md.
"""

from __future__ import annotations

import pytest

from dpcbench.holes.detection import detect_holes
from dpcbench.holes.registry import get_generator

CASES = {
    "region-medium-ball": ("region", {"preset": "medium"}, 3),
    "region-large-cube": ("region", {"preset": "large", "shape": "cube"}, 3),
    "region-fraction-3pct": ("region", {"fraction": 0.03}, 3),
    "dropout-2pct": ("dropout", {"fraction": 0.02}, 3),
    "occlusion-stage-12cams": ("occlusion", {}, 1),
    "occlusion-sphere-8cams": ("occlusion", {"rig": "sphere", "count": 8}, 1),
}


@pytest.mark.parametrize("case", list(CASES))
def test_generator_1m(benchmark, frames_1m, case):
    name, params, rounds = CASES[case]
    generator = get_generator(name, **params)
    benchmark.group = "holes 1M points"
    benchmark.extra_info.update(points=len(frames_1m[0]), generator=name, params=params)
    result = benchmark.pedantic(generator.damage, args=([frames_1m[0]], 0), rounds=rounds, iterations=1)
    assert 0 < result.removed_fraction[0] < 0.5
    benchmark.extra_info["removed_fraction"] = result.removed_fraction[0]


def test_region_coherent_3_frames_1m(benchmark, frames_1m):
    generator = get_generator("region", preset="medium", coherent=True)
    benchmark.group = "holes 1M points"
    benchmark.extra_info.update(points=len(frames_1m[0]), frames=3)
    result = benchmark.pedantic(generator.damage, args=(frames_1m, 0), rounds=1, iterations=1)
    assert len(result.frames) == 3


def test_detect_holes_1m(benchmark, frames_1m):
    damaged = get_generator("region", preset="medium").damage([frames_1m[0]], 0)
    benchmark.group = "holes 1M points"
    regions = benchmark.pedantic(detect_holes, args=(damaged.frames[0],), rounds=1, iterations=1)
    benchmark.extra_info.update(points=len(damaged.frames[0]), regions=len(regions))
    assert len(regions) >= 1


def test_box_contains_843k(benchmark):
    """A rotated box region's test (`HoleRegion.contains`: an (N, 3) @ (3, 3) product, on one BLAS thread through
    `holes._blas.rows_times`) on 843,292 uniform points, the Longdress frame's count; 50 calls a round. The
    temporal-fusion run on that frame's 91 occlusion boxes makes 4,512 such calls on frames and crops."""
    import numpy as np

    from dpcbench.holes.regions import HoleRegion

    rng = np.random.default_rng(0)
    points = rng.uniform(0, 1024, size=(843292, 3))
    box = HoleRegion.box([500, 400, 600], [80, 120, 40], np.linalg.qr(rng.normal(size=(3, 3)))[0])
    benchmark.group = "region tests"

    def fifty_calls():
        return [box.contains(points) for _ in range(50)][-1]

    inside = benchmark.pedantic(fifty_calls, rounds=5, iterations=1)
    assert 0 < inside.sum() < len(points)
