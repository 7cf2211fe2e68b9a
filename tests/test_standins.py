"""The embedded stand-in sequences: distance primitives, the narrow-band voxelizer against brute force,
determinism, 8i-like voxelization, articulated (human, cow) and non-rigid (bunny) motion, the frame cache."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial import cKDTree

from dpcbench.bench.data.standins import bunny, cache, cow, human
from dpcbench.bench.data.standins.sdf import Ellipsoid, RoundCone, smooth_min, surface_voxels


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Every test gets its own empty frame cache."""
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))


def random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


# -- distance primitives ---------------------------------------------------------------------------
def test_round_cone_matches_brute_force_outside():
    """Outside, the round cone's distance is min over t of |p - c(t)| - r(t) (it is the union of
    the balls interpolated between its end balls)."""
    rng = np.random.default_rng(0)
    cone = RoundCone(np.array([0.0, 0.0, 0.0]), np.array([10.0, 3.0, -2.0]), 3.0, 1.2)
    p = rng.uniform(-8, 18, size=(2000, 3))
    t = np.linspace(0, 1, 2001)
    centres = cone.a + t[:, None] * (cone.b - cone.a)
    radii = cone.ra + t * (cone.rb - cone.ra)
    brute = (np.linalg.norm(p[:, None, :] - centres[None], axis=2) - radii[None]).min(axis=1)
    d = cone.distance(p)
    outside = brute > 0.05
    assert outside.sum() > 1500
    np.testing.assert_allclose(d[outside], brute[outside], atol=2e-3)
    assert np.all(d[brute < -0.05] < 0)


def test_capsule_closed_form():
    """Equal radii: distance to the segment minus the radius, inside and out."""
    rng = np.random.default_rng(1)
    a, b, r = np.array([1.0, 2.0, 3.0]), np.array([-4.0, 0.0, 5.0]), 1.5
    p = rng.uniform(-8, 8, size=(2000, 3))
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    expected = np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1) - r
    np.testing.assert_allclose(RoundCone(a, b, r, r).distance(p), expected, atol=1e-9)


def test_ellipsoid_zero_set_and_lower_bound():
    rng = np.random.default_rng(2)
    R = random_rotation(rng)
    ell = Ellipsoid(np.array([3.0, -1.0, 2.0]), np.array([4.0, 2.0, 1.5]), R)
    u = rng.normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    surface = ell.c + (u * ell.radii) @ R.T
    np.testing.assert_allclose(ell.distance(surface), 0.0, atol=1e-9)
    p = rng.uniform(-6, 10, size=(3000, 3))
    d = ell.distance(p)
    true = cKDTree(surface).query(p)[0]
    outside = d > 0
    # a lower bound of the true distance outside (up to the surface sampling's resolution)
    assert np.all(d[outside] <= true[outside] + 0.05)
    lo, hi = ell.aabb()
    assert np.all(surface >= lo - 1e-9) and np.all(surface <= hi + 1e-9)
    assert np.allclose(surface.min(0), lo, atol=0.05) and np.allclose(surface.max(0), hi, atol=0.05)


def test_smooth_min_properties():
    a = np.linspace(-3, 3, 101)
    b = np.zeros_like(a)
    s = smooth_min(a, b, 1.0)
    assert np.all(s <= np.minimum(a, b) + 1e-12)
    far = np.abs(a - b) >= 1.0
    np.testing.assert_allclose(s[far], np.minimum(a, b)[far])
    np.testing.assert_allclose(smooth_min(np.array([0.0]), np.array([0.0]), 1.0), [-0.25])


def posed_body(size=180.0, motion="walk", t=0.3):
    scale = size / human.rest_height_m()
    origin = np.array([128.0, 6.0, 128.0])
    return human.build_body(motion, t, 0.0, scale, origin)[0]


def test_human_field_is_1_lipschitz():
    """The narrow band relies on |f(p) - f(q)| <= |p - q|."""
    rng = np.random.default_rng(3)
    body = posed_body()
    p = rng.uniform([60, 0, 60], [200, 200, 200], size=(20000, 3))
    q = p + rng.normal(scale=3.0, size=p.shape)
    fp, _ = body.evaluate(p, np.inf)
    fq, _ = body.evaluate(q, np.inf)
    assert np.all(np.abs(fp - fq) <= np.linalg.norm(p - q, axis=1) + 1e-9)


def test_surface_voxels_match_brute_force():
    """Narrow band + primitive culling find exactly the voxels a full-grid evaluation finds."""
    size = 64
    body = human.build_body("dance", 0.2, 0.0, 52.0 / human.rest_height_m(), np.array([32.0, 2.0, 32.0]))[0]
    fast = surface_voxels(body, size)
    ax = np.arange(size + 1, dtype=np.float64)
    corners = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    values, _ = body.evaluate(corners, np.inf)
    neg = (values < 0).reshape(size + 1, size + 1, size + 1)
    cube = np.stack([neg[i:i + size, j:j + size, k:k + size] for i in (0, 1) for j in (0, 1) for k in (0, 1)], -1)
    crossed = cube.any(-1) & ~cube.all(-1)
    brute = np.argwhere(crossed)
    assert len(fast) > 1500
    np.testing.assert_array_equal(fast, brute)  # both lexicographic


# -- the human figure -------------------------------------------------------------------------------
def test_human_is_deterministic_and_8i_like():
    p1, c1, _ = human.generate_frame(3, size="tiny")
    p2, c2, _ = human.generate_frame(3, size="tiny")
    np.testing.assert_array_equal(p1, p2)
    np.testing.assert_array_equal(c1, c2)
    assert 10_000 <= len(p1) <= 30_000
    assert p1.dtype == np.float64 and c1.dtype == np.uint8 and c1.shape == p1.shape
    assert np.array_equal(p1, np.round(p1)) and p1.min() >= 0 and p1.max() <= 1023
    assert len(np.unique(p1, axis=0)) == len(p1)  # one point per occupied voxel
    # a surface, not a volume: nearly every point has a face/edge neighbour, the shell is thin
    d, _ = cKDTree(p1).query(p1, k=2)
    assert np.median(d[:, 1]) == 1.0
    # several materials (skin, shirt, trousers, hair, shoes) -> several distinct colour clusters
    assert len(np.unique(c1 // 64, axis=0)) >= 4


def test_human_seed_and_frame_change_output():
    p0, c0, _ = human.generate_frame(0, size="tiny")
    p_seed, c_seed, _ = human.generate_frame(0, size="tiny", seed=1)
    p_next, _, _ = human.generate_frame(1, size="tiny")
    assert not np.array_equal(p0, p_seed) and not np.array_equal(c0, c_seed)
    assert not (len(p0) == len(p_next) and np.array_equal(p0, p_next))


def test_human_motion_is_articulated():
    """Walking: between consecutive frames the feet move far more than the chest (not a rigid motion)."""
    p0, _, _ = human.generate_frame(0, size="tiny")
    p1, _, _ = human.generate_frame(1, size="tiny")
    moved = cKDTree(p1).query(p0)[0]
    y = p0[:, 1]
    lo, h = y.min(), np.ptp(y)
    feet = y < lo + 0.12 * h
    chest = (y > lo + 0.6 * h) & (y < lo + 0.75 * h) & (np.abs(p0[:, 0] - p0[:, 0].mean()) < 15)
    assert feet.sum() > 500 and chest.sum() > 500
    assert moved[feet].mean() > 4 * moved[chest].mean()
    assert moved[feet].mean() > 1.5  # voxels, on a 180-voxel figure


def test_human_motions_and_bit_depth():
    for motion in human.MOTIONS:
        p, _, _ = human.generate_frame(5, motion=motion, size="tiny", bit_depth=9)
        assert p.max() <= 511 and p.min() >= 0
    with pytest.raises(ValueError, match="unknown motion"):
        human.generate_frame(0, motion="fly", size="tiny")
    with pytest.raises(ValueError, match="does not fit"):
        human.generate_frame(0, size="default", bit_depth=10, height=1000)
    with pytest.raises(ValueError, match="unknown size"):
        human.generate_frame(0, size="huge")


# -- the bunny --------------------------------------------------------------------------------------
def icp_rmse(a: np.ndarray, b: np.ndarray) -> float:
    """RMSE of the best rigid (point-to-point ICP) alignment of a onto b."""
    pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a))
    pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(b))
    reg = o3d.pipelines.registration.registration_icp(
        pa, pb, 10.0, np.eye(4), o3d.pipelines.registration.TransformationEstimationPointToPoint(),
        o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=100))
    return reg.inlier_rmse


def test_bunny_deterministic_voxelized_and_non_rigid():
    p0, c0, _ = bunny.generate_frame(0, size="tiny")
    again, c_again, _ = bunny.generate_frame(0, size="tiny")
    np.testing.assert_array_equal(p0, again)
    np.testing.assert_array_equal(c0, c_again)
    assert 10_000 <= len(p0) <= 30_000
    assert np.array_equal(p0, np.round(p0)) and p0.min() >= 0 and p0.max() <= 1023
    assert len(np.unique(p0, axis=0)) == len(p0)
    resampled, _, _ = bunny.generate_frame(0, size="tiny", seed=1)  # same shape, other samples
    later, _, _ = bunny.generate_frame(10, size="tiny")
    assert icp_rmse(later, p0) > 3 * icp_rmse(resampled, p0)


def test_bunny_float_samples():
    p, c, _ = bunny.generate_frame(2, bit_depth=None, points=5000, seed=4)
    assert p.shape == (5000, 3) and c.shape == (5000, 3)
    assert not np.array_equal(p, np.round(p))
    q, _, _ = bunny.generate_frame(2, bit_depth=None, points=5000, seed=5)
    assert not np.array_equal(p, q)


def test_cow_walks_its_legs_and_keeps_its_body():
    """The cow: deterministic, voxelized like 8i data at the preset sizes; its walk moves the legs (the points
    below the belly) far more than the body does between frames, and the diagonal legs swing together."""
    p0, c0, n0 = cow.generate_frame(0, size="tiny")
    again, c_again, _ = cow.generate_frame(0, size="tiny")
    np.testing.assert_array_equal(p0, again)
    np.testing.assert_array_equal(c0, c_again)
    assert 20_000 <= len(p0) <= 30_000 and len(np.unique(p0, axis=0)) == len(p0)
    assert np.array_equal(p0, np.round(p0)) and p0.min() >= 0 and p0.max() <= 1023
    np.testing.assert_allclose(np.linalg.norm(n0, axis=1), 1.0, atol=1e-12)
    v, _, _ = cow.rest_mesh()
    assert np.ptp(v, axis=0).max() == pytest.approx(1.0) and v[:, 1].min() == 0.0
    # the rest pose against a quarter stride later (t = 0.275 s), without the turn: legs swing, the back does not
    later = cow.deform(v, 0.275, 1.0, 0.0)
    rest = cow.deform(v, 0.0, 1.0, 0.0)
    legs, back = v[:, 1] < 0.12, (v[:, 1] > 0.35) & (np.abs(v[:, 2]) < 0.15)
    shift = later - rest
    move = np.linalg.norm(shift - shift[back].mean(axis=0), axis=1)  # less the body's own sway and bob
    assert np.median(move[legs]) > 0.05 > 10 * np.median(move[back])
    # at a quarter stride the hooves of the phase-0 pair (one front, the diagonal hind) swing back (-z, the head
    # is at +z), those of the other pair forward
    for (leg_x, leg_z), phase in cow.LEGS:
        hoof = legs & (np.hypot(v[:, 0] - leg_x, v[:, 2] - leg_z) < 0.05) & (v[:, 1] < 0.03)
        forward = np.mean(shift[hoof, 2])
        assert (forward < -0.05) if phase == 0.0 else (forward > 0.05)


def test_cow_float_samples_lie_on_the_moved_mesh_with_its_normals():
    p, _, n = cow.generate_frame(3, bit_depth=None, points=4000, seed=2)
    assert p.shape == (4000, 3)
    v, tri, _ = cow.rest_mesh()
    moved = cow.deform(v, 3 / 30.0, 1.0, 12.0) * 1000.0
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(moved.astype(np.float32), tri.astype(np.uint32))
    closest = scene.compute_closest_points(p.astype(np.float32))
    assert np.abs(closest["points"].numpy() - p).max() < 1e-2
    face = closest["primitive_ids"].numpy().astype(np.int64)
    a, b, c = (moved[tri[face, k]] for k in range(3))
    face_normal = np.cross(b - a, c - a)
    face_normal /= np.linalg.norm(face_normal, axis=1, keepdims=True)
    assert np.median((face_normal * n).sum(axis=1)) > 0.95


def test_the_cow_is_an_embedded_dataset_whose_runs_carry_its_own_version():
    """`load_dataset("cow")` generates it; its runs' data fingerprint names its own generator's version, and the
    human's and the bunny's keep the version their stored runs have."""
    from dpcbench.bench.data import datasets
    from dpcbench.bench.experiment.config import data_fingerprint

    seq = datasets.load_dataset("cow", frames=2, size="tiny", progress=False)
    assert len(seq.points) == 2 and len(seq.points[0]) > 20_000
    assert data_fingerprint({"name": "cow", "params": {"size": "tiny"}}, "s")["version"] == f"cow{cow.GENERATOR_VERSION}"
    for name in ("human", "bunny"):
        assert data_fingerprint({"name": name}, "s")["version"] == datasets.DATASETS_VERSION == (
            f"human{human.GENERATOR_VERSION}-bunny{bunny.GENERATOR_VERSION}")


# -- exact normals ----------------------------------------------------------------------------------
def _central_differences(fn, p: np.ndarray, h: float = 1e-5) -> np.ndarray:
    return np.stack([(fn(p + h * e) - fn(p - h * e)) / (2 * h) for e in np.eye(3)], axis=1)


def test_primitive_gradients_match_finite_differences():
    rng = np.random.default_rng(3)
    primitives = [RoundCone(np.array([0.0, 0, 0]), np.array([3.0, 1, 0.5]), 1.2, 0.6),
                  RoundCone(np.array([1.0, 0, 0]), np.array([-2.0, 2, 1]), 0.4, 1.1),
                  Ellipsoid(np.array([1.0, 2, 3]), np.array([2.0, 1, 0.7]), random_rotation(rng))]
    for prim in primitives:
        centre = prim.a if isinstance(prim, RoundCone) else prim.c
        p = centre + rng.normal(size=(3000, 3)) * 2.5
        np.testing.assert_allclose(prim.gradient(p), _central_differences(prim.distance, p), atol=1e-6)


def test_smooth_union_gradient_and_human_normals():
    """The body's field gradient (chain rule through the smooth minima) against central differences
    of the field itself, at the points of a frame; the frame's normals are that gradient normalized,
    point outwards, and agree with the surface the points sample (PCA normals)."""
    scale = 180 / human.rest_height_m()
    body, _, _ = human.build_body("walk", 0.1, 0.3, scale, np.array([512.0, 20.0, 512.0]))
    points = surface_voxels(body, 1024).astype(np.float64)
    _, _, grad = body.evaluate(points, 2.0, gradient=True)
    numeric = _central_differences(lambda q: body.evaluate(q, 2.0)[0], points)
    np.testing.assert_allclose(grad, numeric, atol=1e-5)

    p, _, n = human.generate_frame(2, size="tiny")
    assert n.shape == p.shape and n.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    frame_body, _, _ = human.build_body("walk", 2 / 30.0, float(np.random.default_rng(0).uniform(0, 2 * np.pi)),
                                        scale, np.array([512.0, 0.02 * 1024, 512.0]))
    outside, _ = frame_body.evaluate(p + 0.5 * n, 3.0)
    inside, _ = frame_body.evaluate(p - 0.5 * n, 3.0)
    assert (outside > inside).all()  # outward: the field grows along every normal
    pca = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    pca.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=12))
    agreement = np.abs((np.asarray(pca.normals) * n).sum(axis=1))
    assert np.median(agreement) > 0.97


def test_bunny_normals_are_the_mesh_normals():
    """Float samples: each normal is the interpolated vertex normal of the sample's triangle, on the
    outward side of the triangle; voxelized: unit, and the mean of the samples' normals per voxel
    agrees with the surface the voxels sample (PCA)."""
    p, _, n = bunny.generate_frame(1, bit_depth=None, points=4000, seed=2)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    v, tri, rest_n = bunny.rest_mesh()
    moved = bunny.deform(v, rest_n, 1 / 30.0, 1.0, 12.0) * 1000.0
    mesh = o3d.t.geometry.RaycastingScene()
    mesh.add_triangles(moved.astype(np.float32), tri.astype(np.uint32))
    closest = mesh.compute_closest_points(p.astype(np.float32))
    assert np.abs(closest["points"].numpy() - p).max() < 1e-2  # the samples lie on the deformed mesh
    face = closest["primitive_ids"].numpy().astype(np.int64)
    a, b, c = (moved[tri[face, k]] for k in range(3))
    face_normal = np.cross(b - a, c - a)
    face_normal /= np.linalg.norm(face_normal, axis=1, keepdims=True)
    assert np.mean((face_normal * n).sum(axis=1) > 0) > 0.99
    assert np.median((face_normal * n).sum(axis=1)) > 0.99

    pv, _, nv = bunny.generate_frame(1, size="tiny")
    np.testing.assert_allclose(np.linalg.norm(nv, axis=1), 1.0, atol=1e-12)
    pca = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pv))
    pca.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=12))
    assert np.median(np.abs((np.asarray(pca.normals) * nv).sum(axis=1))) > 0.97


# -- cache ------------------------------------------------------------------------------------------
def test_cache_round_trip_and_key(tmp_path):
    key = cache.cache_key("human", 1, {"size": "tiny", "seed": 0}, 3)
    assert key != cache.cache_key("human", 1, {"size": "tiny", "seed": 1}, 3)
    assert key != cache.cache_key("human", 2, {"size": "tiny", "seed": 0}, 3)
    assert key != cache.cache_key("human", 1, {"size": "tiny", "seed": 0}, 4)
    assert cache.load_cached(key, "human") is None
    arrays = {"points": np.arange(12, dtype=np.uint16).reshape(4, 3), "colors": np.ones((4, 3), np.uint8)}
    path = cache.store_cached(key, "human", arrays)
    assert path is not None and path.parent.parent == tmp_path / "cache"
    back = cache.load_cached(key, "human")
    for name in arrays:
        np.testing.assert_array_equal(back[name], arrays[name])
    path.write_bytes(b"not a zip")  # a damaged entry reads as a miss
    assert cache.load_cached(key, "human") is None
    assert not list(path.parent.glob(".tmp-*"))  # no temporary file left behind
