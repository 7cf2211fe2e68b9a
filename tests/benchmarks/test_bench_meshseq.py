"""Mesh sequences (bench.data.meshseq): seconds to produce one 800k-point 10-bit frame from a 10k-vertex mesh.

- ``test_mesh_frame_800k_10bit``: one frame of a sequence whose samples are already drawn (what every
  frame after the first costs: evaluate the ~5M carried samples on the frame's vertices, voxelize, normals).
- ``test_mesh_sequence_one_frame_from_scratch``: read the mesh, fit the scale to 800k points (up to four
  trial voxelizations), draw the samples, produce the frame: the first frame's cost, no cache.

Target: under 2 s a frame. Run:
    .venv/bin/python -m pytest tests/benchmarks/test_bench_meshseq.py --benchmark-only
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from dpcbench.bench.data.meshseq import (
    face_areas_normals,
    fit_placement,
    frame_from_samples,
    load_mesh_sequence,
    sample_barycentric,
)

TARGET = 800_000


@pytest.fixture(scope="module")
def torus_10k(tmp_path_factory):
    """A torus of 100 x 100 = 10,000 vertices (19,998... faces), written as PLY."""
    mesh = o3d.geometry.TriangleMesh.create_torus(torus_radius=1.0, tube_radius=0.35, radial_resolution=100,
                                                  tubular_resolution=100)
    path = tmp_path_factory.mktemp("mesh") / "torus_0000.ply"
    o3d.io.write_triangle_mesh(str(path), mesh)
    return path, np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.triangles, dtype=np.int64)


def test_mesh_frame_800k_10bit(benchmark, torus_10k):
    _, v, t = torus_10k
    areas, normals = face_areas_normals(v, t)
    place = fit_placement(v, t, areas, normals, v.min(0), v.max(0), TARGET, 10, 8.0, 0, "torus")
    faces, bary = sample_barycentric(areas, place.samples, np.random.default_rng(0))
    placed = v * place.scale + place.offset
    frame = benchmark.pedantic(frame_from_samples, args=(placed, t, faces, bary, 10), rounds=5, iterations=1)
    benchmark.extra_info.update({"points": len(frame["points"]), "samples": place.samples, "vertices": len(v)})
    assert len(frame["points"]) == pytest.approx(TARGET, rel=0.01)


def test_mesh_sequence_one_frame_from_scratch(benchmark, torus_10k):
    path, v, _ = torus_10k
    seq = benchmark.pedantic(load_mesh_sequence, args=([path],), kwargs=dict(name="torus", points=TARGET, bit_depth=10,
                                                                           cache=False), rounds=3, iterations=1)
    benchmark.extra_info.update({"points": len(seq.frames[0]), "samples": seq.meta["samples_per_frame"]})
    assert len(seq.frames[0]) == pytest.approx(TARGET, rel=0.01)
