"""Speed of the baselines: seconds per ~800k-point frame.

Run: ``.venv/bin/python -m pytest tests/benchmarks/test_bench_baselines.py --benchmark-only``
(skipped in the ordinary test run). Each benchmark does one frame's worth of work once
(``pedantic``, one round: meshlab on 800k points takes minutes): the middle frame of three
embedded human frames at bit_depth 11 and height 1040 voxels (~800k points a frame), damaged by
the ``region`` generator (preset medium, seed 0). temporal-copy gets all three frames with regions
only on the middle one, so it also does exactly one frame's filling. ``extra_info`` records the
point count and how many points the method added. open3d and pymeshlab are imported before the
timing: their import is a one-time cost (open3d took 15 s of a 31 s temporal-copy run when it was
imported inside it).
"""

from __future__ import annotations

import pytest

from methods.registry import get_method

CASES = {
    "none": ("none", {}),
    "temporal-copy": ("temporal-copy", {}),
    "lozes-pde-p2": ("lozes-pde", {"p": 2}),
    "lozes-pde-p1": ("lozes-pde", {"p": 1}),
    "meshlab-whole": ("meshlab", {"output": "whole"}),
    "meshlab-holes-only": ("meshlab", {"output": "holes-only"}),
}


@pytest.fixture(scope="module")
def big_frames():
    """(damaged frames, regions): 3 human frames of ~800k points with medium holes on frame 1."""
    import open3d  # noqa: F401  one-time imports (open3d ~15 s on a loaded machine) are not per-frame cost
    import pymeshlab  # noqa: F401

    from bench.datasets import load_dataset
    from holes.registry import get_generator

    seq = load_dataset("human", frames=[0, 1, 2], bit_depth=11, height=1040, progress=False)
    damage = get_generator("region", preset="medium").damage(seq.points, seed=0)
    return damage.frames, damage.regions


@pytest.mark.parametrize("case", list(CASES))
def test_seconds_per_800k_frame(benchmark, big_frames, case):
    frames, regions = big_frames
    name, params = CASES[case]
    method = get_method(name, **params)
    if method.uses_neighbour_frames:
        args = (frames, [[], regions[1], []])
    else:
        args = ([frames[1]], [regions[1]])
    out = benchmark.pedantic(method.inpaint, args=args, rounds=1, iterations=1)
    benchmark.extra_info["points"] = len(frames[1])
    benchmark.extra_info["holes"] = len(regions[1])
    benchmark.extra_info["added_points"] = len(out[1 if method.uses_neighbour_frames else 0]) - len(frames[1])
    assert len(out) == len(args[0])
