"""Speed of the baselines: seconds per ~100k- and ~800k-point frame.

Run: ``.venv/bin/python -m pytest tests/benchmarks/test_bench_baselines.py --benchmark-only``
(skipped in the ordinary test run). Each benchmark does one frame's worth of work once
(``pedantic``, one round): the middle frame of three embedded human frames (size "small", ~96k
points; or bit_depth 11 and height 1040 voxels, ~800k points a frame), damaged by
the ``region`` generator (preset medium, seed 0). temporal-copy gets all three frames with regions
only on the middle one, so it also does exactly one frame's filling. ``extra_info`` records the
point count and how many points the method added. open3d and pymeshlab are imported before the
timing: their import is a one-time cost (open3d took 15 s of a 31 s temporal-copy run when it was
imported inside it).

MeshLab on an 800k frame did not finish within 66 minutes while it ran ball pivoting over the whole
frame; since it reconstructs frames above ``max_points`` (120k) from a voxel-clustered copy
the 800k cases take under a minute (41 s for output=whole on 776k points, machine
shared) and always run. ``meshlab-whole-unclustered`` keeps the old behaviour at 800k
(``max_points=0``) for comparison, only with ``DPCBENCH_BENCH_SLOW=1``: over an hour.
"""

from __future__ import annotations

import importlib
import os

import pytest

from dpcbench.methods.registry import get_method

CASES = {
    "none": ("none", {}),
    "temporal-copy": ("temporal-copy", {}),
    "lozes-pde-p2": ("lozes-pde", {"p": 2}),
    "lozes-pde-p1": ("lozes-pde", {"p": 1}),
    "meshlab-whole": ("meshlab", {"output": "whole"}),
    "meshlab-holes-only": ("meshlab", {"output": "holes-only"}),
    "meshlab-whole-unclustered": ("meshlab", {"output": "whole", "max_points": 0}),
}


SIZES = {"100k": {"size": "small"}, "800k": {"bit_depth": 11, "height": 1040}}
SLOW = {("meshlab-whole-unclustered", "800k")}
_damaged: dict[str, tuple] = {}


def damaged_frames(size: str):
    """(damaged frames, regions): 3 human frames of SIZES[size] with medium holes on frame 1."""
    # one-time imports (open3d ~15 s on a loaded machine) are not per-frame cost: load them before timing
    importlib.import_module("open3d")
    importlib.import_module("pymeshlab")

    from dpcbench.bench.data.datasets import load_dataset
    from dpcbench.holes.registry import get_generator

    if size not in _damaged:
        seq = load_dataset("human", frames=[0, 1, 2], progress=False, **SIZES[size])
        damage = get_generator("region", preset="medium").damage(seq.points, seed=0)
        _damaged[size] = (damage.frames, damage.regions)
    return _damaged[size]


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("case", list(CASES))
def test_seconds_per_frame(benchmark, case, size):
    if (case, size) == ("meshlab-whole-unclustered", "100k"):
        pytest.skip("below max_points meshlab-whole is already unclustered")
    if (case, size) in SLOW and os.environ.get("DPCBENCH_BENCH_SLOW") != "1":
        pytest.skip(f"{case} on {size} points takes over an hour: set DPCBENCH_BENCH_SLOW=1 to run it")
    frames, regions = damaged_frames(size)
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
