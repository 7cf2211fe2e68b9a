"""Local geometry from nearest neighbours: the one normal estimator and the point-spacing estimators
that every layer uses (metrics, holes, methods, bench).

Normals. ``estimate_normals(points, k)`` is PCA over the k nearest neighbours: for a query q with
neighbours p_1..p_k (q itself among them when q is a point of the cloud), the covariance
C = sum_i (p_i - mean)(p_i - mean)^T and the normal is the unit eigenvector of its smallest
eigenvalue. The sign is arbitrary unless ``orient_from`` is given (then n . (q - orient_from) >= 0).
Two implementations of this one estimator, chosen by what is asked:

- every point of the cloud (``queries`` None): open3d's multi-threaded ``estimate_normals``
  (numpy's batched ``eigh`` took 17 s on a 1M-point frame, open3d 1-2 s);
- arbitrary query positions (``queries`` given: a sample of the points, or positions that are not
  points of the cloud): numpy, a cKDTree query and a batched ``eigh``, because open3d only
  estimates the normals of the cloud's own points.

Both give the same normals up to sign, to about 1e-10 (`tests/test_metrics.py` checks it); the
two paths are kept apart so that each caller's figures stay bit-identical to what it always computed.

Point spacing. ``point_spacing``: median over the points of the distance to their 8th nearest
neighbour, divided by sqrt(2) (exactly 1 on a unit voxel surface, whose 8 nearest neighbours are
the 4 edge and 4 diagonal neighbours; ~1.13 / sqrt(rho) for random sampling of density rho; the 8th
neighbour, not the 1st, keeps it stable on duplicated or clumped samples). It sizes holes, cubes
and graph scales. ``median_neighbour_distance``: median distance to the nearest other point, the
distance to the closest sample (how far apart two samplings' points are; splat sizes in renders).
Both take a deterministic probe of large clouds: ``sample`` points drawn with a seeded
``numpy.random.Generator`` (``seed``) or an even stride (``seed`` None).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dpcbench.metrics.errors import UserError
from dpcbench.metrics.grid import is_integer_grid

if TYPE_CHECKING:
    from scipy.spatial import cKDTree


def _kdtree(points: np.ndarray) -> cKDTree:
    """scipy's cKDTree of ``points``, imported on first use: importing scipy.spatial costs ~40 MiB and
    0.4 s, which the integer-grid path of the metrics (`metrics.grid`) never pays."""
    from scipy.spatial import cKDTree

    return cKDTree(points)

#: neighbours of the normal estimate used by D2 when the reference has no normals (pc_error's golden
#: normals are open3d's KNN 12 exactly: mean |cos| 1.0000 against 0.990-0.997 for k = 6..30)
DEFAULT_NORMAL_NEIGHBOURS = 12


def check_points(points, label: str) -> np.ndarray:
    """``points`` as a float64 (N, 3) array with N >= 1 and finite values, else a UserError naming ``label``."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise UserError(f"{label}: coordinates must be an (N, 3) array, got shape {arr.shape}")
    if len(arr) == 0:
        raise UserError(f"{label}: the cloud has zero points; a metric needs at least one point on each side")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise UserError(
            f"{label}: {int(bad.sum())} point(s) have NaN or infinite coordinates (first at index "
            f"{int(np.flatnonzero(bad)[0])}); drop them before scoring"
        )
    return arr


def estimate_normals(points: np.ndarray, k: int = DEFAULT_NORMAL_NEIGHBOURS, *, queries: np.ndarray | None = None,
                     tree: cKDTree | None = None, orient_from: np.ndarray | None = None) -> np.ndarray:
    """Unit PCA normals from the ``k`` nearest of ``points`` (N, 3) (see the module docstring).

    queries:     None: the normals (N, 3) of every point (open3d); else (Q, 3) positions, normals (Q, 3)
                 (numpy; (0, 3) for no query).
    tree:        a cKDTree of ``points`` to reuse (numpy path only).
    orient_from: a position (3,): each normal n at q is flipped so that n . (q - orient_from) >= 0
                 (e.g. the centroid, for "outwards" on a closed body); None keeps the arbitrary sign.
    k is clipped to N. UserError when fewer than 3 points (a plane needs three); callers with a
    fallback for such clouds test ``len(points)`` first.
    """
    pts = check_points(points, "normal estimation")
    k = int(min(k, len(pts)))
    if k < 3:
        raise UserError(f"normal estimation needs at least 3 points, got {len(pts)}; pass normals instead")
    if queries is None:
        import open3d as o3d

        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
        cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=k))
        normals = np.asarray(cloud.normals).copy()
        at = pts
    else:
        at = np.asarray(queries, dtype=np.float64).reshape(-1, 3)
        if len(at) == 0:
            return np.zeros((0, 3))
        tree = tree if tree is not None else _kdtree(pts)
        _, idx = tree.query(at, k=k, workers=-1)
        neighbourhoods = pts[idx]
        neighbourhoods -= neighbourhoods.mean(axis=1, keepdims=True)
        covariance = np.einsum("qki,qkj->qij", neighbourhoods, neighbourhoods)
        normals = np.linalg.eigh(covariance)[1][:, :, 0]  # eigh: eigenvalues ascending
    if orient_from is not None:
        flip = np.einsum("ij,ij->i", normals, at - np.asarray(orient_from, dtype=np.float64)) < 0
        normals[flip] *= -1.0
    return normals


def probe_indices(n: int, sample: int | None, seed: int | None = None) -> np.ndarray:
    """The rows (indices into N = ``n`` rows) that `probe` takes, for callers that hold per-row values."""
    if sample is None or n <= sample:
        return np.arange(n)
    if seed is None:
        return np.arange(0, n, max(1, n // sample))
    return np.random.default_rng(seed).choice(n, sample, replace=False)


def probe(points: np.ndarray, sample: int | None, seed: int | None = None) -> np.ndarray:
    """A deterministic subset of the rows of ``points`` for estimates on large clouds.

    sample None or >= N: all points. Else ``seed`` an int: ``sample`` rows drawn without replacement
    by ``numpy.random.default_rng(seed)``; ``seed`` None: every (N // sample)-th row (about ``sample``
    rows, evenly strided). The rows are `probe_indices`."""
    n = len(points)
    if sample is None or n <= sample:
        return points
    if seed is None:
        return points[:: max(1, n // sample)]
    return points[probe_indices(n, sample, seed)]


def point_spacing(points: np.ndarray, tree: cKDTree | None = None, sample: int = 20000, seed: int = 0) -> float:
    """Typical neighbour distance: median 8th-NN distance / sqrt(2) (1.0 on a unit voxel grid).

    At most ``sample`` points (a ``seed``-ed random subset) are queried, which keeps this O(sample log N).
    ``tree``: a cKDTree of ``points`` to reuse.
    """
    points = np.asarray(points, dtype=np.float64)
    if len(points) < 9:
        raise UserError(f"need at least 9 points to estimate the point spacing, got {len(points)}")
    tree = tree if tree is not None else _kdtree(points)
    dist, _ = tree.query(probe(points, sample, seed), k=9, workers=-1)
    spacing = float(np.median(dist[:, 8])) / np.sqrt(2.0)
    if not spacing > 0:
        raise UserError("the points are (almost all) duplicates: cannot estimate a point spacing")
    return spacing


#: the most a voxelized capture's point spacing (`point_spacing`, in voxels) may be: a voxelization holds every
#: voxel its surface crosses (spacing 1, as on every integer sequence at hand), a surface sampled every second voxel
#: has spacing 2, and integer data sparser than midway between them is a capture whose coordinates were rounded (a
#: scan in whole millimetres), not a voxelization
VOXELIZED_SPACING_MAX = 1.5


def is_voxelization(frames, tree: cKDTree | None = None) -> bool:
    """Whether a sequence of frames (each (N_f, 3)) is a voxelization: every coordinate of every frame an integer
    (`grid.is_integer_grid`) and the largest frame's `point_spacing` at most `VOXELIZED_SPACING_MAX` voxels (a
    largest frame of under 9 points: its coordinates alone decide). ``tree``: a cKDTree of the largest frame to
    reuse. The spacing is measured only on integer data."""
    frames = [np.asarray(frame) for frame in frames]
    if not frames or not all(is_integer_grid(frame) for frame in frames):
        return False
    largest = max(frames, key=len)
    return len(largest) < 9 or point_spacing(largest, tree=tree) <= VOXELIZED_SPACING_MAX


def median_neighbour_distance(points: np.ndarray, sample: int | None = 20000, tree: cKDTree | None = None,
                              seed: int | None = None) -> float:
    """Median distance from a probe of ``points`` (N, 3) (see `probe`: ``sample`` rows, evenly
    strided when ``seed`` is None) to their nearest other point.

    The distance to the closest sample, not a density-based spacing (`point_spacing`): whether a
    copied point duplicates an existing one, how large a splat closes the gaps. When the median is 0
    (duplicated points) the mean of the non-zero distances is returned, 1.0 when there is none.
    ``tree``: a cKDTree of ``points`` to reuse."""
    points = np.asarray(points, dtype=np.float64)
    if len(points) < 2:
        raise UserError("need at least 2 points to estimate the point spacing")
    dist, _ = (tree if tree is not None else _kdtree(points)).query(probe(points, sample, seed), k=2, workers=-1)
    spacing = float(np.median(dist[:, 1]))
    if spacing <= 0:  # duplicated points: fall back to the mean of the non-zero distances
        nonzero = dist[:, 1][dist[:, 1] > 0]
        spacing = float(nonzero.mean()) if len(nonzero) else 1.0
    return spacing


__all__ = ["DEFAULT_NORMAL_NEIGHBOURS", "check_points", "estimate_normals", "median_neighbour_distance",
           "point_spacing", "probe", "probe_indices"]
