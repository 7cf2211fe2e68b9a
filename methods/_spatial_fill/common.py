"""Shared by the spatial fills and the copies: even subsets, voxel keys, distance masks, the layer test, the
agreement rule (a point is kept when it continues its neighbours' local plane), the height-field fit and the
links between points."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.metrics.neighbours import estimate_normals

#: most rim points the spatial fill's thin-plate spline interpolates (a dense solve, O(K^3))
SURFACE_POINTS = 1000

#: largest fraction of the spatial fill's support whose normals may be more than 60 degrees off the
#: fit's axis: a rim that is a height field over its own PCA plane has almost none (a hole on a
#: limb's side: the rim spans < 120 degrees of arc); a quarter means the rim wraps round a fold
MAX_STEEP = 0.25
#: step 6f: the least mean squared cosine between the inner ring's normals and their principal axis for the
#: hole's edge to count as one sheet: cos^2 30 degrees (a 90-degree fold gives 0.5; a ring over 120 degrees
#: of a limb's arc 0.71; a flat edge 1)
SHEET_MIN_ALIGNMENT = 0.75


#: screened Poisson (step 6c): open3d's default ratio of the reconstruction cube to the samples' bounding
#: cube, and the largest octree depth (2^10 cells a side: a crop of 1000 grid steps, far above a hole's)
POISSON_SCALE = 1.1
POISSON_MAX_DEPTH = 10
#: screened Poisson's finest octree cell, in grid steps g (the fill's sampling step): the fill's surface, and the
#: hold-out's (one level coarser: it only says whether the fill's surface is trusted; temporal-fusion version 43,
#: docs/temporal-fusion.md "Speed at paper scale")
POISSON_CELL_STEPS = 1
POISSON_HOLDOUT_CELL_STEPS = 2
#: the hold-out's first look (`poisson._holds_out`, temporal-fusion 51): the held-out surface one octree level coarser
#: still, where that octree is at least this deep, decides a body whose net miss there is beyond this factor of the
#: bound (refused) or within the bound over it (passed); in between, the hold-out's own surface decides. Measured on
#: 31 decisions at depth 5 to 7 (experiments/holdout_scatter.py --coarse 4): the coarser miss was 0.80-1.09 times the
#: hold-out's, so a factor 2 flips none of them; at depth 4 it was up to 3.9 times (a 3,664-point support)
COARSE_LOOK_MIN_DEPTH = 5
COARSE_LOOK_FACTOR = 2.0


#: the neighbours of the local quadric whose residual is a held-out point's own scatter (`holdout_passes`)
SCATTER_NEIGHBOURS = 20


def own_scatter_sq(held: np.ndarray, support: np.ndarray) -> float:
    """e^2 of `holdout_passes`: the mean squared residual of `local_quadric` at each of ``held`` (H, 3), fitted to its
    `SCATTER_NEIGHBOURS` nearest ``support`` (K, 3) points (0 where too few support points fix a quadric)."""
    from dpcbench.methods._front_fill import local_quadric

    residual = local_quadric(held, support, SCATTER_NEIGHBOURS)[2]
    return float(np.mean(np.where(np.isfinite(residual), residual, 0.0) ** 2)) if len(residual) else 0.0


def holdout_passes(offsets: np.ndarray, held: np.ndarray, support: np.ndarray, bound: float) -> bool:
    """The hold-out rule of the fills after step 6 (step 6c's tube and, with its own capped distances, its Poisson
    surface; step 6e's membrane; step 6's spline keeps the raw miss, its docstring says why): True when ``offsets``
    (H,), the distances of the held-out points ``held`` (H, 3) from the surface built without them, have an RMS m
    with m^2 - e^2 <= ``bound``^2, e the held-out points' own scatter about a smooth surface (`own_scatter_sq`). A
    noisy capture misses any smooth surface by its noise whether the surface saw it or not; only the rest measures
    how well the surface predicts what it did not see (MVUB ricardo9's depth noise: e 0.39-0.51 s at the membrane's
    hold-outs of its occlusion boxes, `experiments/cascade_trace.py --holdouts`)."""
    offsets = np.asarray(offsets, dtype=np.float64)
    if not len(offsets):
        return True
    miss_sq = float(np.mean(offsets ** 2))
    if miss_sq <= bound ** 2:
        return True  # passes whatever the scatter: no fit needed
    return miss_sq <= bound ** 2 + own_scatter_sq(held, support)


def even_subset(points: np.ndarray, count: int) -> np.ndarray:
    """At most ``count`` rows of ``points``, evenly strided (deterministic)."""
    if len(points) <= count:
        return points
    return points[np.linspace(0, len(points) - 1, count).astype(np.int64)]




def _voxel_keys(voxels: np.ndarray, origin: np.ndarray, side: np.int64) -> np.ndarray:
    """One int64 per integer point of a cube of ``side`` voxels from ``origin`` (row-major)."""
    v = (voxels - origin).astype(np.int64)
    return (v[:, 0] * side + v[:, 1]) * side + v[:, 2]


def unique_voxels(voxels: np.ndarray) -> np.ndarray:
    """``np.unique(voxels, axis=0)`` for integer-valued (V, 3) ``voxels``: unique rows in lexicographic order,
    found as one int64 key per row (`_voxel_keys`); np.unique on rows sorts a structured view of the
    floats (1.1 s of the 800k-point benchmark case in a cProfile run, step 4b's free voxels beside the rim)."""
    voxels = np.asarray(voxels, dtype=np.float64).reshape(-1, 3)
    if not len(voxels) or not np.isfinite(voxels).all():
        return np.unique(voxels, axis=0)
    origin = voxels.min(axis=0)
    side = int((voxels.max(axis=0) - origin).max()) + 1
    if side > 1 << 20:  # the keys would overflow int64
        return np.unique(voxels, axis=0)
    keys = np.unique(_voxel_keys(voxels, origin, np.int64(side)))
    rows = np.stack([keys // (side * side), (keys // side) % side, keys % side], axis=1)
    return rows.astype(np.float64) + origin


def first_in_cells(points: np.ndarray, cell: float) -> np.ndarray:
    """Indices (C,), increasing, of the first point of ``points`` (P, 3) in each cubic cell of edge ``cell``
    (cells floor(p / cell)) that holds any: ``np.unique(cells, axis=0, return_index=True)``'s, sorted, found
    by one int64 key a cell (`_voxel_keys`; np.unique on rows sorts a structured view, several times slower)
    unless the keys would overflow int64."""
    cells = np.floor(np.asarray(points, dtype=np.float64).reshape(-1, 3) / cell)
    if not len(cells):
        return np.zeros(0, dtype=np.int64)
    origin = cells.min(axis=0)
    side = int((cells.max(axis=0) - origin).max()) + 1
    if side <= 1 << 20:
        _, first = np.unique(_voxel_keys(cells, origin, np.int64(side)), return_index=True)
    else:
        _, first = np.unique(cells, axis=0, return_index=True)
    return np.sort(first)


def far_from(points: np.ndarray, tree: cKDTree | None, distance: float) -> np.ndarray:
    """Mask (P,) of ``points`` farther than ``distance`` from every point of ``tree`` (all True
    without a tree)."""
    if tree is None or tree.n == 0 or len(points) == 0:
        return np.ones(len(points), dtype=bool)
    dist, _ = tree.query(points, distance_upper_bound=distance)
    return ~np.isfinite(dist)


def over_captured_surface(points: np.ndarray, captured: cKDTree, spacing: float, *, reach_spacings: float = 2.0,
                          neighbours: int = 16, one_sided: float = 0.5,
                          off_plane_spacings: float | None = 0.5) -> np.ndarray:
    """Mask (P,) of the ``points`` that lie over the captured surface as a second layer (step 7b of
    `methods.temporal_fusion`): a point p whose captured neighbours (``captured``'s points within
    ``reach_spacings * spacing``, its ``neighbours`` nearest, at least 3) surround it and whose distance to their
    plane is more than ``off_plane_spacings * spacing``.

    With m the neighbours' centroid and n their PCA normal (smallest eigenvector of their covariance), each
    neighbour q gives the unit tangential direction u_q of (q - p) - ((q - p) . n) n; the neighbours surround p
    when |mean_q u_q| < ``one_sided`` (past the edge of a captured patch, at a hole's rim, they all lie to one side
    and the mean is near 1), and p is off their plane when |(p - m) . n| > ``off_plane_spacings * spacing``.
    A point inside a sampling gap of the captured surface (on its plane) and a point in a hole (one-sided
    neighbours, or none within reach) are kept. ``off_plane_spacings=None`` (voxelized input, ``spacing`` one
    voxel): p is off the plane when the plane does not cross p's unit cube, |(p - m) . n| > (|n_x| + |n_y| +
    |n_z|) / 2 (the exact plane-cube test, the voxelization rule of `crossed_voxels`): a voxel of the captured
    surface's own staircase is one the plane crosses."""
    points = np.asarray(points, dtype=np.float64)
    out = np.zeros(len(points), dtype=bool)
    if not len(points) or captured.n < 3:
        return out
    k = min(int(neighbours), captured.n)
    dist, idx = captured.query(points, k=k, distance_upper_bound=reach_spacings * spacing)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    valid = np.isfinite(dist)
    rows = np.flatnonzero(valid.sum(axis=1) >= 3)
    if not len(rows):
        return out
    weight = valid[rows].astype(np.float64)  # (R, k): 1 for a neighbour within reach
    near = captured.data[np.where(valid[rows], idx[rows], 0)]  # (R, k, 3); rows past reach weigh 0
    count = weight.sum(axis=1)
    centre = np.einsum("rk,rkd->rd", weight, near) / count[:, None]
    spread = near - centre[:, None, :]
    covariance = np.einsum("rk,rki,rkj->rij", weight, spread, spread) / count[:, None, None]
    normal = np.linalg.eigh(covariance)[1][:, :, 0]  # (R, 3): eigenvalues ascending
    offset = near - points[rows][:, None, :]
    tangential = offset - np.einsum("rkd,rd->rk", offset, normal)[:, :, None] * normal[:, None, :]
    length = np.linalg.norm(tangential, axis=2)
    usable = valid[rows] & (length > 1e-9 * spacing)
    unit = np.where(usable[:, :, None], tangential / np.maximum(length, 1e-300)[:, :, None], 0.0)
    mean = np.linalg.norm(unit.sum(axis=1), axis=1) / np.maximum(usable.sum(axis=1), 1)
    height = np.abs(np.einsum("rd,rd->r", points[rows] - centre, normal))
    bound = np.abs(normal).sum(axis=1) / 2.0 if off_plane_spacings is None else off_plane_spacings
    out[rows] = (usable.sum(axis=1) >= 3) & (mean < one_sided) & (height > bound * spacing)
    return out




def grown_agreeing(points: np.ndarray, support: np.ndarray, reach: float, tolerance: float) -> np.ndarray:
    """Mask (P,) of the ``points`` that continue the surface of ``support`` (K, 3) (step 4 of
    `methods.temporal_fusion`): grown from the support outwards, round by round. Each round judges the points
    not judged yet that have at least 3 support points within ``reach`` (`plane_offsets`); those within
    ``tolerance`` of the support's local plane are kept and join the support, the others are dropped
    for good. The growth stops when a round keeps nothing. A point that no chain of kept points
    connects to the support (a second layer more than ``reach`` off it, a patch floating in the
    hole) is dropped."""
    keep = np.zeros(len(points), dtype=bool)
    pending = np.arange(len(points))
    support = np.asarray(support, dtype=np.float64)
    while len(pending) and len(support) >= 3:
        judged, off = plane_offsets(points[pending], support, reach, min_planarity=0.01)
        agree = judged & (off <= tolerance)
        if not agree.any():
            break
        keep[pending[agree]] = True
        support = np.vstack([support, points[pending[agree]]])
        pending = pending[~judged]
    return keep


def plane_offsets(points: np.ndarray, accepted: np.ndarray, reach: float,
                  min_planarity: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(judged (P,) bool, offset (P,)): the distance of each of ``points`` from the PCA plane of its (up
    to) 8 nearest ``accepted`` points within ``reach``; judged is False (offset 0) for points with
    fewer than 3 such, and for those whose neighbours' middle PCA variance is below ``min_planarity``
    times the largest (points on a line, e.g. one row of voxels, fix no plane)."""
    out = np.zeros(len(points))
    judged_out = np.zeros(len(points), dtype=bool)
    if len(points) == 0 or len(accepted) < 3:
        return judged_out, out
    k = int(min(8, len(accepted)))
    dist, idx = cKDTree(accepted).query(points, k=k, distance_upper_bound=reach)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    judged = np.isfinite(dist).sum(axis=1) >= 3
    if not judged.any():
        return judged_out, out
    rows = np.flatnonzero(judged)
    near = np.isfinite(dist[rows])
    nb = accepted[np.where(near, idx[rows], idx[rows, :1])]  # unused slots repeat the nearest
    weight = near[:, :, None].astype(np.float64)
    centre = (nb * weight).sum(axis=1) / weight.sum(axis=1)
    spread = (nb - centre[:, None, :]) * weight
    variance, axes = np.linalg.eigh(np.einsum("pki,pkj->pij", spread, spread))
    normal = axes[:, :, 0]
    out[rows] = np.abs(np.einsum("pi,pi->p", points[rows] - centre, normal))
    if min_planarity > 0:
        flat = variance[:, 1] >= min_planarity * variance[:, 2]
        judged[rows[~flat]] = False
        out[rows[~flat]] = 0.0
    return judged, out


def fit_height_field(support: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """One least-squares quadric height field over all of ``support`` (K, 3), K >= 6:
    (centre (3,), axes (3, 3) with rows u, v, n, coefficients (6,), RMS residual, fraction of
    support points whose PCA normal (10 neighbours) is more than 60 degrees off n).

    Frame: PCA of the support (n the least-variance axis, u the largest); h(u, v) = c0 + c1 u + c2 v
    + c3 u^2 + c4 u v + c5 v^2 minimising sum (h(u_i, v_i) - h_i)^2 (unweighted: every rim point is
    evidence of the same surface). The last two figures are the confidence of step 6: the residual
    says whether one quadric describes the rim at all, the normal fraction whether the surface is a
    height field over the (u, v) plane (it is not where the rim wraps round a limb)."""
    centre = support.mean(axis=0)
    spread = support - centre
    axes = np.linalg.eigh(spread.T @ spread)[1][:, ::-1].T  # rows: largest, middle, least variance
    axes = np.array([axes[0], axes[1], np.cross(axes[0], axes[1])])
    u, v, h = spread @ axes[0], spread @ axes[1], spread @ axes[2]
    design = np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], axis=1)
    coef = np.linalg.lstsq(design, h, rcond=None)[0]
    rms = float(np.sqrt(np.mean((design @ coef - h) ** 2)))
    normals = estimate_normals(support, 10, queries=support)
    steep = float(np.mean(np.abs(normals @ axes[2]) < 0.5))
    return centre, axes, coef, rms, steep


def _flat_anchors(anchors: np.ndarray) -> np.ndarray:
    """Mask (K,) of the ``anchors`` whose PCA normal (10 neighbours) is within 60 degrees of their PCA plane's
    normal: `fit_height_field`'s test, point by point."""
    centre = anchors.mean(axis=0)
    axis = np.linalg.svd(anchors - centre, full_matrices=False)[2][2]
    return np.abs(estimate_normals(anchors, 10, queries=anchors) @ axis) >= 0.5


def _link_components(points: np.ndarray, reach: float) -> tuple[int, np.ndarray]:
    """(count, labels (K,)): the connected components of ``points`` (K, 3) under links of length <=
    ``reach`` (scipy's connected_components of the ``query_pairs`` graph)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = cKDTree(points).query_pairs(reach, output_type="ndarray")
    return connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                                           shape=(len(points), len(points))), directed=False)
