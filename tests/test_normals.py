"""Inpainted frames keep their normals (`methods._normals`, `dpcbench inpaint`), and methods report
per-frame progress to a listener (`methods.progress`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dpcbench.bench.cli import main
from dpcbench.bench.data.plyio import PointCloud, read_ply
from dpcbench.bench.data.sequences import save_sequence
from dpcbench.holes.regions import HoleRegion, regions_to_json
from dpcbench.methods._normals import output_normals
from dpcbench.methods.progress import frame_done, report_frames_to
from dpcbench.metrics.errors import UserError
from tests.runner_fixtures import voxel_plane


def sphere(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_kept_points_keep_the_input_normals_exactly():
    points = sphere(400, 0)
    # deliberately not the surface's normals: a re-estimated normal could not reproduce them
    normals = sphere(400, 1)
    out = output_normals(points, normals, points[::-1].copy())
    np.testing.assert_array_equal(out, normals[::-1])


def test_new_points_follow_the_surface_and_the_inputs_orientation():
    points = sphere(3000, 2)
    inward = -points  # the input's normals point inwards: new normals must too
    new = sphere(200, 3)
    out = output_normals(points, inward, np.vstack([points, new]))
    np.testing.assert_array_equal(out[:3000], inward)
    radial = np.einsum("ij,ij->i", out[3000:], new)
    assert np.all(radial < -0.97), radial.max()
    np.testing.assert_allclose(np.linalg.norm(out[3000:], axis=1), 1.0, atol=1e-9)


def test_bad_normals_are_refused_with_a_reason():
    points = sphere(50, 4)
    with pytest.raises(UserError, match="one \\(nx, ny, nz\\) per point"):
        output_normals(points, points[:10], points)
    bad = points.copy()
    bad[3] = np.nan
    with pytest.raises(UserError, match="not all finite"):
        output_normals(points, bad, points)


@pytest.fixture
def damaged_with_normals(tmp_path):
    """Three voxel-plane frames whose normals point down (-z), a hole in the middle one."""
    region = HoleRegion.ball([20.0, 20.0, 20.0], 6.0)
    frames = [voxel_plane(s) for s in (0, 1, 2)]
    frames[1] = frames[1][~region.contains(frames[1])]
    rng = np.random.default_rng(5)
    normals = []
    for f in frames:  # tilted a little at random, so that a kept normal is told from a re-estimated one
        n = np.column_stack([rng.normal(0, 0.05, (len(f), 2)), -np.ones(len(f))])
        normals.append(n / np.linalg.norm(n, axis=1, keepdims=True))
    clouds = [PointCloud(f, None, n) for f, n in zip(frames, normals)]
    folder = tmp_path / "damaged"
    save_sequence(clouds, folder, prefix="plane")
    holes = tmp_path / "holes.json"
    holes.write_text(json.dumps(regions_to_json([[], [region], []])))
    return folder, holes, frames, normals


def test_inpaint_writes_the_inputs_normals_and_oriented_new_ones(damaged_with_normals, tmp_path, monkeypatch):
    import dpcbench.bench.core.progress as progress

    folder, holes, frames, normals = damaged_with_normals
    bars = []

    def recording_bar(*args, **kwargs):
        bars.append(progress.tqdm(*args, **{**kwargs, "disable": False}))
        return bars[-1]

    monkeypatch.setattr(progress, "progress_bar", recording_bar)
    out = tmp_path / "out"
    assert main(["inpaint", str(folder), "--method", "lozes-pde", "--regions", str(holes), "--out", str(out)]) == 0
    filled = read_ply(sorted(out.glob("*.ply"))[1])
    assert filled.normals is not None and len(filled.points) > len(frames[1])
    stored = read_ply(sorted(folder.glob("*.ply"))[1]).normals  # as written: float32
    np.testing.assert_array_equal(filled.normals[:len(frames[1])], stored)
    new = filled.normals[len(frames[1]):]
    assert np.all(new[:, 2] < -0.99), new[:, 2].max()
    # one per-frame bar, advanced by the method to its last frame
    assert [(bar.total, bar.n, bar.unit) for bar in bars] == [(3, 3, "frame")]


class _Recorder:
    def __init__(self):
        self.calls = []

    def __call__(self, done, total):
        self.calls.append((done, total))


def test_frame_done_reaches_only_the_installed_listener():
    outer, inner = _Recorder(), _Recorder()
    frame_done(1, 2)  # no listener: nothing happens
    with report_frames_to(outer):
        frame_done(1, 2)
        with report_frames_to(inner):
            frame_done(2, 2)
        frame_done(2, 2)
    frame_done(2, 2)
    assert outer.calls == [(1, 2), (2, 2)] and inner.calls == [(2, 2)]


@pytest.mark.parametrize("name, params", [
    ("lozes-pde", {}),
    ("fu-nonlocal", {"cube_size": 12, "min_known_points": 12}),
    ("temporal-graph", {"cube_size": 12, "min_known_points": 12}),
    ("temporal-fusion", {}),
])
def test_methods_report_every_frame(name, params):
    from dpcbench.methods.registry import method_class

    region = HoleRegion.ball([20.0, 20.0, 20.0], 6.0)
    frames = [voxel_plane(s) for s in (0, 1, 2)]
    frames[1] = frames[1][~region.contains(frames[1])]
    seen = _Recorder()
    with report_frames_to(seen):
        method_class(name)(**params).inpaint(frames, [[], [region], []])
    assert seen.calls == [(1, 3), (2, 3), (3, 3)]
