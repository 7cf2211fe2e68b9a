"""Foundation timings: generating one default-size 10-bit human frame (no cache), one default bunny
frame, reading and writing a 1M-point binary PLY frame, rendering a 1M-point frame.

Run: .venv/bin/python -m pytest tests/benchmarks/test_bench_io.py --benchmark-only
"""

from __future__ import annotations

import numpy as np
import pytest

from dpcbench.bench.data.plyio import PointCloud, read_ply, write_ply

ONE_MILLION = 1_000_000


@pytest.fixture(scope="module")
def million_cloud() -> PointCloud:
    """1M distinct 10-bit voxels with colours (seed 0), like one 8i frame's size and layout."""
    rng = np.random.default_rng(0)
    keys = rng.choice(1024 ** 3, size=ONE_MILLION, replace=False)
    points = np.stack([keys // (1024 * 1024), (keys // 1024) % 1024, keys % 1024], 1).astype(np.float64)
    return PointCloud(points, rng.integers(0, 256, size=(ONE_MILLION, 3)).astype(np.uint8))


@pytest.fixture(scope="module")
def million_ply(million_cloud, tmp_path_factory):
    return write_ply(tmp_path_factory.mktemp("io") / "million.ply", million_cloud)


def test_generate_default_human_frame(benchmark):
    """Seconds for one default-size (about 580k points) 10-bit human frame, generated from scratch."""
    from dpcbench.bench.data.standins.human import generate_frame

    points, _, _ = benchmark.pedantic(generate_frame, args=(0,), rounds=3, iterations=1)
    benchmark.extra_info["points"] = len(points)
    assert len(points) >= 300_000


def test_generate_default_bunny_frame(benchmark):
    from dpcbench.bench.data.standins.bunny import generate_frame, rest_mesh

    rest_mesh()  # the mesh is read once per process; time the per-frame work
    points, _, _ = benchmark.pedantic(generate_frame, args=(0,), rounds=3, iterations=1)
    benchmark.extra_info["points"] = len(points)
    assert len(points) >= 300_000


def test_read_1m_point_ply(benchmark, million_ply, million_cloud):
    cloud = benchmark.pedantic(read_ply, args=(million_ply,), rounds=5, iterations=1)
    np.testing.assert_array_equal(cloud.points, million_cloud.points)


def test_write_1m_point_ply(benchmark, million_cloud, tmp_path):
    path = benchmark.pedantic(write_ply, args=(tmp_path / "out.ply", million_cloud), rounds=5, iterations=1)
    assert path.stat().st_size > 15 * ONE_MILLION


def test_render_1m_points(benchmark, million_cloud, tmp_path):
    """One panel of a 1M-point cloud with its colours (z-buffer rasterizer), 480 px high."""
    from dpcbench.bench.reporting.render import render_clouds

    out = benchmark.pedantic(render_clouds, args=([million_cloud], tmp_path / "million.png"), rounds=3, iterations=1)
    assert out.stat().st_size > 0
