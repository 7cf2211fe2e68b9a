"""Mesh sequences (bench.data.meshseq): sampling, voxelization bound, normals, true motion, bad input, and the
temporal consistency metric's use of true correspondences. The meshes are built here (open3d
primitives written as OBJ / PLY / OFF), so nothing needs ../shared except the samba tests."""

from __future__ import annotations

import math

import numpy as np
import open3d as o3d
import pytest

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.datasets import load_dataset
from dpcbench.bench.data.meshseq import (
    face_areas_normals,
    list_mesh_files,
    load_mesh_sequence,
    read_mesh,
    sample_barycentric,
    voxelize_samples,
)
from dpcbench.bench.data.plyio import read_ply
from dpcbench.bench.data.sequences import save_sequence
from dpcbench.metrics.temporal import temporal_consistency


def rotation(axis: np.ndarray, degrees: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    t = math.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * k @ k


def torus() -> tuple[np.ndarray, np.ndarray]:
    mesh = o3d.geometry.TriangleMesh.create_torus(torus_radius=1.0, tube_radius=0.35, radial_resolution=40,
                                                  tubular_resolution=20)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.triangles, dtype=np.int64)


def write_mesh(path, vertices, triangles):
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(triangles))
    assert o3d.io.write_triangle_mesh(str(path), mesh, write_ascii=path.suffix == ".obj", write_vertex_normals=False)
    return path


def rigid_frames(folder, count=4, suffix=".ply"):
    """Frames of a torus under a known rigid motion: x_f = R_f x_0 + t_f. Returns (files, [(R_f, t_f)]).
    PLY by default: open3d writes float64 coordinates there (its OBJ text has fewer digits)."""
    v, t = torus()
    folder.mkdir(parents=True, exist_ok=True)
    motions, files = [], []
    for f in range(count):
        R = rotation([0.3, 1.0, 0.2], 17.0 * f)
        shift = np.array([0.21 * f, -0.13 * f, 0.05 * f])
        motions.append((R, shift))
        files.append(write_mesh(folder / f"frame_{f:03d}{suffix}", v @ R.T + shift, t))
    return files, motions


def surface_distance(vertices, triangles, queries) -> np.ndarray:
    """Exact distance from each query to the triangle mesh (open3d RaycastingScene, float32)."""
    scene = o3d.t.geometry.RaycastingScene()
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(vertices.astype(np.float32))
    mesh.triangle.indices = o3d.core.Tensor(triangles.astype(np.int32))
    scene.add_triangles(mesh)
    return scene.compute_distance(o3d.core.Tensor(queries.astype(np.float32))).numpy()


# -- sampling ------------------------------------------------------------------------------------
def test_sampling_density_follows_area():
    """Faces get samples in proportion to their area; barycentric coordinates are uniform on the triangle."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [4, 0, 0], [0, 4, 0]], dtype=np.float64)
    t = np.array([[0, 1, 2], [0, 3, 4]])  # areas 0.5 and 8: 1 : 16
    areas, _ = face_areas_normals(v, t)
    faces, bary = sample_barycentric(areas, 170_000, np.random.default_rng(3))
    share = np.bincount(faces, minlength=2) / len(faces)
    assert share[0] == pytest.approx(1 / 17, abs=0.002)  # binomial sd ~ 0.0006
    assert np.all(bary >= 0) and np.allclose(bary.sum(axis=1), 1.0)
    # uniform on a triangle: each barycentric coordinate has mean 1/3 and P(w_0 > 1/2) = 1/4
    assert bary.mean(axis=0) == pytest.approx([1 / 3] * 3, abs=0.003)
    assert (bary[:, 0] > 0.5).mean() == pytest.approx(0.25, abs=0.004)


def test_float_samples_count_and_density(tmp_path):
    files, _ = rigid_frames(tmp_path / "m", count=2)
    seq = load_mesh_sequence(files, name="torus", points=5000, bit_depth=None, cache=False)
    assert [len(f) for f in seq.frames] == [5000, 5000]
    v, t = read_mesh(files[0])
    area = face_areas_normals(v, t)[0].sum()
    dense = load_mesh_sequence(files, [0], name="torus", density=3000.0 / area, bit_depth=None, cache=False)
    assert len(dense.frames[0]) == 3000
    # the float samples lie on the surface
    assert surface_distance(v, t, seq.frames[0].points).max() < 1e-5


def test_sampling_is_deterministic(tmp_path):
    files, _ = rigid_frames(tmp_path / "m", count=2)
    kwargs = dict(name="torus", points=4000, bit_depth=8, cache=False)
    a = load_mesh_sequence(files, **kwargs)
    b = load_mesh_sequence(files, **kwargs)
    for fa, fb in zip(a.frames, b.frames):
        assert np.array_equal(fa.points, fb.points) and np.array_equal(fa.normals, fb.normals)
    f1 = load_mesh_sequence(files, name="torus", points=4000, bit_depth=None, seed=1, cache=False)
    f2 = load_mesh_sequence(files, name="torus", points=4000, bit_depth=None, seed=2, cache=False)
    assert not np.array_equal(f1.frames[0].points, f2.frames[0].points)
    # selecting frames does not change them: the samples always come from the folder's first frame
    alone = load_mesh_sequence(files, [1], **kwargs)
    assert np.array_equal(alone.frames[0].points, a.frames[1].points)


def test_cache_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    files, _ = rigid_frames(tmp_path / "m", count=2)
    fresh = load_mesh_sequence(files, name="torus", points=3000, bit_depth=8, cache=True)
    cached = load_mesh_sequence(files, name="torus", points=3000, bit_depth=8, cache=True)
    assert any((tmp_path / "cache" / "mesh").iterdir())
    for a, b in zip(fresh.frames, cached.frames):
        assert np.array_equal(a.points, b.points) and np.allclose(a.normals, b.normals, atol=1e-6)
    assert np.array_equal(fresh.motion.indices(0, 1), cached.motion.indices(0, 1))


# -- voxelization -------------------------------------------------------------------------------------
def test_voxelize_samples_matches_brute_force():
    rng = np.random.default_rng(0)
    positions = rng.uniform(-0.5, 31.49, size=(20_000, 3))
    voxels, anchor = voxelize_samples(positions, 5)
    rounded = np.rint(positions).astype(np.int64)
    expected = np.unique(rounded, axis=0)  # lexicographic, like voxelize_samples
    assert np.array_equal(voxels, expected)
    assert np.array_equal(rounded[anchor], voxels)  # each anchor lies in its voxel
    d2 = ((positions - rounded) ** 2).sum(axis=1)
    for i in rng.choice(len(voxels), 200, replace=False):  # the anchor is (up to quantization) the nearest
        members = np.flatnonzero((rounded == voxels[i]).all(axis=1))
        assert d2[anchor[i]] <= d2[members].min() + 0.75 / 2 ** 10


def test_voxelized_frames_are_integer_and_within_half_a_voxel(tmp_path):
    """Each output point q has its anchor, a point of the surface, with |anchor - q|_inf <= 1/2, so q is
    within sqrt(3)/2 voxel (Euclidean) of the surface: the bound that holds for voxel centres."""
    files, _ = rigid_frames(tmp_path / "m", count=3)
    seq = load_mesh_sequence(files, name="torus", points=20_000, bit_depth=9, cache=False)
    assert seq.bit_depth == 9
    v0, t0 = read_mesh(files[0])
    for f, frame in enumerate(seq.frames):
        pts = frame.points
        assert np.array_equal(pts, np.round(pts)) and pts.min() >= 0 and pts.max() <= 511
        assert len(np.unique(pts, axis=0)) == len(pts)  # one point per voxel
        anchors = seq.motion.positions(f, f)
        assert np.abs(anchors - pts).max() <= 0.5 + 1e-9
        placed = seq.motion.vertices[f]
        assert surface_distance(placed, t0, anchors).max() < 1e-3  # anchors are on the surface (float32 scene)
        assert surface_distance(placed, t0, pts).max() <= math.sqrt(3) / 2 + 1e-3
    # the target count is met on the reference frame (scale fitted)
    assert len(seq.frames[0]) == pytest.approx(20_000, rel=0.01)


def test_fill_default_spans_the_grid(tmp_path):
    files, _ = rigid_frames(tmp_path / "m", count=2)
    seq = load_mesh_sequence(files, name="torus", bit_depth=7, cache=False)
    lo = np.min([f.points.min(0) for f in seq.frames], axis=0)
    hi = np.max([f.points.max(0) for f in seq.frames], axis=0)
    assert (hi - lo).max() >= 125 and lo.min() >= 0 and hi.max() <= 127


# -- normals ---------------------------------------------------------------------------------------
def test_normals_are_the_anchor_faces_normals(tmp_path):
    files, motions = rigid_frames(tmp_path / "m", count=2)
    seq = load_mesh_sequence(files, name="torus", points=6000, bit_depth=8, cache=False)
    v0, t0 = read_mesh(files[0])
    for f, frame in enumerate(seq.frames):
        faces, _ = seq.motion.anchors[f]
        R, _ = motions[f]
        a, b, c = (v0[t0[faces, j]] for j in range(3))
        expected = np.cross(b - a, c - a) @ R.T  # frame 0's face normals turned by the frame's rotation
        expected /= np.linalg.norm(expected, axis=1, keepdims=True)
        assert np.allclose(frame.normals, expected, atol=1e-6)
    # the torus is closed and consistently wound (open3d): normals point away from the tube's axis circle
    pts = seq.motion.positions(0, 0)
    R, shift = motions[0]
    local = ((pts - seq.meta["offset"]) / seq.meta["scale"] - shift) @ R
    ring = local.copy()
    ring[:, 2] = 0
    ring = ring / np.linalg.norm(ring, axis=1, keepdims=True)  # nearest point of the tube's centre circle
    radial = local - ring
    assert (np.einsum("ij,ij->i", radial, seq.frames[0].normals @ R) > 0).mean() > 0.999


def test_normals_are_written_to_ply(tmp_path):
    files, _ = rigid_frames(tmp_path / "m", count=2)
    seq = load_mesh_sequence(files, name="torus", points=3000, bit_depth=8, cache=False)
    paths = save_sequence(seq, tmp_path / "out")
    back = read_ply(paths[1])
    assert np.array_equal(back.points, seq.frames[1].points)
    assert np.allclose(back.normals, seq.frames[1].normals, atol=1e-6)
    header = paths[1].read_bytes()[:400]
    assert b"property float nx" in header and b"property float nz" in header


# -- true motion ---------------------------------------------------------------------------------------
def test_correspondence_is_exact_under_rigid_motion_float(tmp_path):
    files, motions = rigid_frames(tmp_path / "m", count=3)
    seq = load_mesh_sequence(files, name="torus", points=4000, bit_depth=None, cache=False)
    R0, t0 = motions[0]
    for f in range(3):
        for g in range(3):
            Rf, tf = motions[f]
            Rg, tg = motions[g]
            # x_g = R_g R_f^T (x_f - t_f) + t_g for the same material point
            expected = (seq.frames[f].points - tf) @ Rf @ Rg.T + tg
            assert np.allclose(seq.frames[g].points, expected, atol=1e-9)
            assert np.allclose(seq.motion.positions(f, g), expected, atol=1e-9)
            assert np.allclose(seq.motion.flow(f, g), expected - seq.frames[f].points, atol=1e-9)
            assert np.array_equal(seq.motion.indices(f, g), np.arange(4000))


def test_correspondence_under_rigid_motion_voxelized(tmp_path):
    """Voxelized: a point's surface point moves exactly as the rigid motion says (in output units), and
    the point it is linked to in the other frame is the voxel that surface point falls in."""
    files, motions = rigid_frames(tmp_path / "m", count=3)
    seq = load_mesh_sequence(files, name="torus", points=15_000, bit_depth=9, cache=False)
    s, o = seq.meta["scale"], np.asarray(seq.meta["offset"])
    for f, g in ((0, 1), (1, 0), (0, 2), (2, 1)):
        Rf, tf = motions[f]
        Rg, tg = motions[g]
        here = seq.motion.positions(f, f)
        expected = (((here - o) / s - tf) @ Rf @ Rg.T + tg) * s + o
        there = seq.motion.positions(f, g)
        assert np.allclose(there, expected, atol=1e-8)
        idx = seq.motion.indices(f, g)
        assert np.array_equal(seq.frames[g].points[idx], np.rint(there))
    forward, backward = seq.motion.correspondences()[0]
    assert forward.shape == (len(seq.frames[0]),) and backward.shape == (len(seq.frames[1]),)


def test_mismatched_connectivity_samples_each_frame_and_warns(tmp_path):
    v, t = torus()
    folder = tmp_path / "m"
    folder.mkdir()
    write_mesh(folder / "a_0.obj", v, t)
    other = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=12)
    write_mesh(folder / "a_1.obj", np.asarray(other.vertices), np.asarray(other.triangles))
    with pytest.warns(UserWarning, match="do not share connectivity"):
        seq = load_dataset(folder, points=3000, bit_depth=None, cache=False, progress=False)
    assert seq.motion is None and [len(f) for f in seq.frames] == [3000, 3000]
    assert surface_distance(np.asarray(other.vertices), np.asarray(other.triangles),
                            seq.frames[1].points).max() < 1e-5


# -- bad input -------------------------------------------------------------------------------------------
def test_bad_meshes_are_refused(tmp_path):
    (tmp_path / "nofaces").mkdir()
    (tmp_path / "nofaces" / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(UserError, match="no faces"):
        load_dataset(tmp_path / "nofaces", cache=False)
    (tmp_path / "nan").mkdir()
    (tmp_path / "nan" / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 1 0\nf 1 2 4\nf 1 2 3\n")
    with pytest.raises(UserError, match="NaN, infinite"):
        load_dataset(tmp_path / "nan", cache=False)
    (tmp_path / "nan_off").mkdir()
    (tmp_path / "nan_off" / "a.off").write_text("OFF\n4 1 0\n0 0 0\ninf 1 0\n1 0 0\n0 1 0\n3 0 2 3\n")
    with pytest.raises(UserError, match="NaN, infinite"):
        load_dataset(tmp_path / "nan_off", cache=False)
    # a degenerate face: repeated vertex, and a collinear (zero-area) one
    (tmp_path / "degenerate").mkdir()
    (tmp_path / "degenerate" / "a.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(UserError, match="degenerate face.*drop_degenerate"):
        load_dataset(tmp_path / "degenerate", points=100, bit_depth=None, cache=False)
    with pytest.warns(UserWarning, match="dropped 1 face"):
        seq = load_dataset(tmp_path / "degenerate", points=100, bit_depth=None, drop_degenerate=True, cache=False)
    assert np.all(seq.frames[0].points[:, 2] == 0) and np.allclose(seq.frames[0].normals, [0, 0, 1])


def test_bad_parameters_are_refused(tmp_path):
    files, _ = rigid_frames(tmp_path / "m", count=2)
    with pytest.raises(UserError, match="not both"):
        load_mesh_sequence(files, name="t", points=10, density=1.0, cache=False)
    with pytest.raises(UserError, match="bit_depth"):
        load_mesh_sequence(files, name="t", bit_depth=3, cache=False)
    with pytest.raises(UserError, match="more than the 64-voxel grid.*at most about"):
        load_mesh_sequence(files, name="t", points=200_000, bit_depth=6, cache=False)
    with pytest.raises(UserError, match="unknown mesh sequence parameter.*size"):
        load_dataset(tmp_path / "m", size="tiny")


def test_mesh_folders_of_each_format(tmp_path):
    for suffix in (".ply", ".off", ".obj"):
        files, _ = rigid_frames(tmp_path / suffix[1:], count=2, suffix=suffix)
        assert list_mesh_files(tmp_path / suffix[1:]) == files
        seq = load_dataset(tmp_path / suffix[1:], points=2000, bit_depth=None, cache=False, progress=False)
        assert seq.motion is not None and len(seq.frames[1]) == 2000
    # a PLY point cloud folder is not a mesh sequence
    save_sequence([np.random.default_rng(0).random((50, 3))], tmp_path / "cloud")
    assert list_mesh_files(tmp_path / "cloud") is None


# -- temporal consistency with true correspondences -----------------------------------------------------------
def test_temporal_consistency_follows_true_correspondences():
    """A fill whose error is carried with the surface has no temporal change. Along true links TC is 0;
    nearest-point links (the surface slid by 1.5 spacings) pair different material points and see the
    error's spatial variation instead."""
    u = np.arange(60, dtype=np.float64)
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), -1).reshape(-1, 2)
    error = 0.2 * np.sin(grid[:, 0] / 3.0)  # normal offset of the fill, a function of the material point
    frames, results = [], []
    for f in range(3):
        pts = np.column_stack([grid[:, 0] + 1.5 * f, grid[:, 1], np.zeros(len(grid))])
        frames.append(pts)
        results.append(pts + np.column_stack([np.zeros((len(grid), 2)), error]))
    identity = np.arange(len(grid))
    true_tc = temporal_consistency(frames, results, correspondences=[(identity, identity)] * 2)
    nearest_tc = temporal_consistency(frames, results)
    assert true_tc == pytest.approx(0.0, abs=1e-12)
    assert nearest_tc > 0.05
    with pytest.raises(ValueError, match="frame pairs"):
        temporal_consistency(frames, results, correspondences=[(identity, identity)])
    with pytest.raises(ValueError, match="indices must lie"):
        temporal_consistency(frames, results, correspondences=[(identity, identity + 1)] * 2)


# -- configs, presets, the samba data ----------------------------------------------------------------------
def test_optional_sequence_is_skipped_when_data_is_missing(tmp_path, monkeypatch, capsys):
    import dpcbench.bench.data.sources.meshes as meshes
    from dpcbench.bench.experiment.config import ConfigError, parse_config

    monkeypatch.setattr(meshes, "default_data_dirs", lambda: [tmp_path / "nothing"])
    monkeypatch.delenv("DPCBENCH_DATA_DIR", raising=False)
    data = {"experiment": {"name": "x"},
            "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 2},
                          {"name": "samba", "frames": 2, "optional": True}],
            "holes": [{"generator": "region", "seed": 0}], "methods": [{"name": "none"}]}
    cfg = parse_config(data)
    runs = cfg.expand()
    assert [r.sequence["name"] for r in runs] == ["human"]
    assert len(cfg.skipped) == 1 and "samba" in cfg.skipped[0] and "mit_samba" in cfg.skipped[0]
    assert "optional sequences[1]" in capsys.readouterr().err
    data["sequences"][1]["optional"] = False
    with pytest.raises(ConfigError, match="mit_samba"):
        parse_config(data).expand()


def test_mesh_folder_as_config_path(tmp_path):
    from dpcbench.bench.data.datasets import load_run_sequence
    from dpcbench.bench.experiment.config import parse_config

    rigid_frames(tmp_path / "m", count=3)
    data = {"experiment": {"name": "x"},
            "sequences": [{"path": str(tmp_path / "m"), "params": {"points": 2000, "bit_depth": 7}, "frames": [1, 3]}],
            "holes": [{"generator": "region", "seed": 0}], "methods": [{"name": "none"}]}
    run = parse_config(data).expand()[0]
    assert run.versions["data"]["mesh"]["params"] == {"points": 2000, "bit_depth": 7}
    truth = load_run_sequence(run.sequence)
    assert len(truth.frames) == 2 and truth.bit_depth == 7 and truth.motion is not None
    other = parse_config({**data, "sequences": [{**data["sequences"][0], "params": {"points": 3000}}]}).expand()[0]
    assert other.run_id != run.run_id


def test_samba(shared_dir):
    seq = load_dataset("samba", frames=[0, 5], data_dir=shared_dir / "data", points=30_000, progress=False)
    assert len(seq.frames) == 2 and seq.bit_depth == 10 and seq.meta["vertices"] == 9971
    assert len(seq.frames[0]) == pytest.approx(30_000, rel=0.01)
    # the flow between frames 0 and 5 is a barycentric mix of the vertices' displacements (scaled)
    flow = np.linalg.norm(seq.motion.flow(0, 1), axis=1)
    v0, _ = read_mesh(seq.files[0])
    v5, _ = read_mesh(seq.files[1])
    moved = np.linalg.norm(v5 - v0, axis=1) * seq.meta["scale"]
    assert flow.max() <= moved.max() + 1e-9 and flow.max() > 0.5 * moved.max() and moved.max() > 1
    idx = seq.motion.indices(0, 1)
    assert np.array_equal(seq.frames[1].points[idx], np.rint(seq.motion.positions(0, 1)))


def test_reproduce_paper_has_a_real_motion_row(shared_dir, monkeypatch):
    from dpcbench.bench.reporting import paper

    monkeypatch.setenv("DPCBENCH_DATA_DIR", str(shared_dir / "data"))
    proto = paper.paper_protocol(quick=True, frames=2)
    samba = [s for s in proto.synthetic if s.sequence["name"] == "samba"]
    assert samba and {s.sequence_label for s in samba} == {paper.REAL_MOTION["samba"]}
    assert "not one of the paper's sequences" in samba[0].sequence_label
    assert samba[0].sequence["params"] == {"points": 20_000} and proto.standins
