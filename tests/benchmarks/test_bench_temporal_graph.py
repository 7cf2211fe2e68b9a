"""Speed of temporal-graph and fu-nonlocal (benchmarks; run with --benchmark-only).

The setting of the speed target: one voxelized frame with 5 medium region holes, with its two (intact)
neighbouring frames, inpainted as a 3-frame sequence. Sizes are the embedded human figure at
several heights (points grow with height^2): ~100k, ~290k, ~575k (10-bit default) and ~800k
(height 1040 on an 11-bit grid: the 10-bit grid cannot hold a figure that large; the point spacing
is one voxel either way, which is what the method's cost depends on). Holes: 1, 3 and 5 on the
~290k frame for the growth with the number of holes.

    .venv/bin/python -m pytest tests/benchmarks/test_bench_temporal_graph.py --benchmark-only \
        --benchmark-columns=min,mean,rounds
"""

from __future__ import annotations

import warnings

import pytest

SIZES = {
    "100k": dict(size="small"),
    "290k": dict(size="default", height=620),
    "575k": dict(size="default"),
    "800k": dict(size="default", bit_depth=11, height=1040),
}


def _case(size: str, holes: int):
    from dpcbench.bench.data.datasets import load_dataset
    from dpcbench.holes.registry import get_generator

    seq = load_dataset("human", frames=3, progress=False, **SIZES[size])
    truth = seq.points
    damage = get_generator("region", preset="medium", count=holes).damage(truth, seed=0)
    frames = [truth[0], damage.frames[1], truth[2]]
    regions = [[], damage.regions[1], []]
    return frames, regions


def _run(benchmark, method_name, size, holes):
    from dpcbench.methods.registry import get_method

    frames, regions = _case(size, holes)
    method = get_method(method_name)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = benchmark.pedantic(method.inpaint, args=(frames, regions), rounds=1, iterations=1, warmup_rounds=0)
    benchmark.extra_info.update(points=len(frames[1]), holes=holes, added=len(out[1]) - len(frames[1]))
    assert len(out[1]) > len(frames[1])


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("method_name", ["temporal-graph", "fu-nonlocal"])
def test_bench_size(benchmark, method_name, size):
    _run(benchmark, method_name, size, 5)


@pytest.mark.parametrize("holes", [1, 3])
@pytest.mark.parametrize("method_name", ["temporal-graph", "fu-nonlocal"])
def test_bench_holes(benchmark, method_name, holes):
    _run(benchmark, method_name, "290k", holes)
