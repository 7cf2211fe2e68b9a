"""dpcbench.metrics.neighbours: the one normal estimator and the point-spacing estimators."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from dpcbench.bench.core.errors import UserError
from dpcbench.metrics.neighbours import (
    estimate_normals,
    is_voxelization,
    median_neighbour_distance,
    point_spacing,
    probe,
)


def _sphere(n: int, seed: int = 0) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return 10.0 * v / np.linalg.norm(v, axis=1, keepdims=True)


def _grid(side: int, step: float = 1.0) -> np.ndarray:
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    return np.column_stack([i.ravel() * step, j.ravel() * step, np.zeros(side * side)])


def test_both_paths_are_one_estimator_brute_force_pca():
    pts = _sphere(3000)
    k = 12
    # brute-force reference: full sort of distances, covariance, smallest eigenvector
    d = np.linalg.norm(pts[:200, None, :] - pts[None, :, :], axis=2)
    reference = []
    for row in np.argsort(d, axis=1)[:, :k]:
        nb = pts[row] - pts[row].mean(axis=0)
        reference.append(np.linalg.eigh(nb.T @ nb)[1][:, 0])
    reference = np.array(reference)
    whole = estimate_normals(pts, k)[:200]  # open3d, every point
    at = estimate_normals(pts, k, queries=pts[:200])  # numpy, at queries
    for normals in (whole, at):
        assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)
        assert np.abs(np.einsum("ij,ij->i", normals, reference)).min() > 1 - 1e-9  # same up to sign
    # on a sphere the PCA normal is the radial direction
    radial = pts[:200] / 10.0
    assert np.abs(np.einsum("ij,ij->i", at, radial)).min() > 0.99


def test_orient_from_points_away_and_tree_reuse_changes_nothing():
    pts = _sphere(2000, seed=1)
    tree = cKDTree(pts)
    plain = estimate_normals(pts, 10, queries=pts, tree=tree)
    outward = estimate_normals(pts, 10, queries=pts, orient_from=pts.mean(axis=0))
    assert (np.einsum("ij,ij->i", outward, pts - pts.mean(axis=0)) >= 0).all()
    assert np.array_equal(np.abs(plain), np.abs(outward))  # orientation flips signs only
    assert estimate_normals(pts, 10, queries=np.zeros((0, 3))).shape == (0, 3)


def test_normals_refuse_fewer_than_three_points():
    with pytest.raises(UserError, match="at least 3 points"):
        estimate_normals(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], 12)
    with pytest.raises(UserError, match="NaN"):
        estimate_normals(np.array([[0.0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]), 12)


def test_point_spacing_is_one_on_a_unit_grid_and_scales():
    assert point_spacing(_grid(40)) == pytest.approx(1.0)
    assert point_spacing(_grid(40, 2.5)) == pytest.approx(2.5)
    with pytest.raises(UserError, match="at least 9"):
        point_spacing(_grid(2))
    with pytest.raises(UserError, match="duplicates"):
        point_spacing(np.zeros((50, 3)))


def test_a_voxelization_is_integer_coordinates_about_one_voxel_apart():
    assert is_voxelization([_grid(40), _grid(30)])  # spacing 1 (the largest frame's)
    assert is_voxelization([_grid(40, 1.0) * [1, 1, 0] + [0, 0, 5]])
    assert not is_voxelization([_grid(40, 2.0)])  # integer, spacing 2: a sampling every second voxel
    assert is_voxelization([_grid(40), _grid(10, 3.0)[:, [2, 0, 1]] + [7, 0, 0]])  # the largest frame decides
    # if every frame is on the grid: a frame off it makes the sequence unvoxelized
    assert not is_voxelization([_grid(40), _grid(40) + 0.5])
    assert not is_voxelization([_grid(40) + 0.25])
    assert is_voxelization([_grid(2, 7.0)])  # under 9 points: the coordinates alone
    assert not is_voxelization([])


def test_median_neighbour_distance_grid_and_duplicates():
    assert median_neighbour_distance(_grid(30, 0.5)) == pytest.approx(0.5)
    doubled = np.vstack([_grid(10), _grid(10)])  # every point twice: the median nearest distance is 0
    # falls back to the mean of the non-zero distances (no point of a doubled grid has one: 1.0)
    assert median_neighbour_distance(doubled) == 1.0
    pts = np.vstack([_grid(10), _grid(10)[:60]])
    d = cKDTree(pts).query(pts, k=2)[0][:, 1]
    assert np.median(d) == 0 and median_neighbour_distance(pts) == pytest.approx(d[d > 0].mean())


def test_probe_is_deterministic_random_or_strided():
    pts = np.arange(3000, dtype=float).reshape(1000, 3)
    assert probe(pts, None) is pts and probe(pts, 5000) is pts
    assert np.array_equal(probe(pts, 100), pts[::10])
    a, b = probe(pts, 100, seed=3), probe(pts, 100, seed=3)
    assert np.array_equal(a, b) and len(np.unique(a[:, 0])) == 100
    assert not np.array_equal(a, probe(pts, 100, seed=4))
