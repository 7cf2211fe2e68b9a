"""Step 6d (`Cap`, `WalledCap` of `methods.temporal_fusion.spatial`): the membrane spanning an opening's boundary
loop (`harmonic_height_field`), and the test of whether walls rise from the loop (`cap_walled`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill.common import MAX_STEEP, _flat_anchors, far_from, unique_voxels
from dpcbench.methods._spatial_fill.spline import rim_surface_fill


def cap_walled(local: np.ndarray, region: HoleRegion, spacing: float, *, band_spacings: float = 2.0,
               max_steep: float = MAX_STEEP) -> bool:
    """Whether ``region`` is a walled, shallow opening (step 6d's, capped before step 6c tries a closed surface).

    Walled: the surface round the region's boundary loop turns away from the loop's plane: more than
    ``max_steep`` of the loop's points (those of ``local`` (K, 3) within ``band_spacings * spacing`` of the
    region, as `cap_fill`) have PCA normals (10 neighbours) more than 60 degrees off the loop's PCA normal n:
    step 6's height-field test (`fit_height_field`), failed. Walls rising from the opening (a base, a sole: 33-35 %
    steep at the bunny's) say no surface round it continues over it; a hole in a sheet that goes on over it has
    almost none (0-9 % at the bunny's coherent holes that step 6c fills).

    Shallow (version 35): the region reaches past the loop's plane, on the side away from the data round it
    (the side of the median of (p - c) . n over ``local``, c the loop's centroid), by at most the loop's radius
    (the RMS distance of its points from c within the plane): max over R of (c - p) . n s = support(-s n) + s n . c
    (`HoleRegion.support`, s that side's sign). A closed end of the walls (a hand past a wrist, the tip of a limb)
    is round and reaches about the loop's radius past it, so a region that reaches less cannot hide one: what it
    hides closes inside that depth, and the flat cap is within it (the bunny's base: 6 voxels past a loop of
    radius 52). A region that reaches further may hide a limb's end, which the closed surface follows and the
    flat cap does not (the 800k human's hand, 57 past a wrist loop of radius 15: the cap lay 6.2 voxels RMS off
    the hand, step 6c's surface 0.94)."""
    loop = local[region.contains(local, margin=band_spacings * spacing)]
    if len(loop) < 12 or float(np.mean(~_flat_anchors(loop))) <= max_steep:
        return False
    centre = loop.mean(axis=0)
    normal = np.linalg.svd(loop - centre, full_matrices=False)[2][2]
    side = 1.0 if np.median((local - centre) @ normal) >= 0 else -1.0
    past_plane = region.support(-side * normal) + side * float(normal @ centre)
    in_plane = (loop - centre) - np.outer((loop - centre) @ normal, normal)
    return past_plane <= float(np.sqrt(np.mean(np.sum(in_plane ** 2, axis=1))))


def cap_fill(local: np.ndarray, region: HoleRegion, covered: cKDTree | None, spacing: float, *,
             voxelized: bool, step: float | None = None, gap_spacings: float = 1.0, band_spacings: float = 2.0,
             max_loop_spacings: float = 1.0, max_loop_fraction: float = 1 / 20, harmonic: bool = True) -> np.ndarray:
    """Cap fill (step 6d of `methods.temporal_fusion`): the membrane spanning ``region``'s boundary loop.
    Returns (P, 3) points; (0, 3) when the loop is not flat enough to span.

    Loop: the points of ``local`` (K, 3) within ``band_spacings * spacing`` of the region's surface (inside
    included: those are data). Trust test: the loop's heights over its own least-squares plane have an
    RMS of at most max(``max_loop_spacings * spacing``, ``max_loop_fraction * r``) (r the region's bounding
    radius), so the loop bounds one opening (the base of a body,
    a sole, a crown cut off by the cameras' horizon); two rims of a band round a limb, or a rim bent
    round a fold, lie at different heights and are refused.

    Surface (``harmonic``, version 29): the harmonic height field over the loop's plane with the loop's
    heights fixed (`harmonic_height_field`, cells of step 6's grid step: the least-area membrane; by the
    maximum principle it never leaves the range of the loop's heights), from the loop's points on its sheet
    (`_flat_anchors`, when 12 or more: a wall's points project onto a few cells, whose mean height would be
    the middle of the wall's column). False (version 28): `rim_surface_fill` of the loop with the normals
    test off and a linear polynomial part, the least-bending thin plate, which continues the slope the loop
    has at its edge: at the bunny's base, whose rim rises from the body's walls, it rose 2-3 voxels above the
    rim and out of the box, and the middle of the opening stayed open (docs/notes-journal.md "version 29")."""
    loop = local[region.contains(local, margin=band_spacings * spacing)]
    if len(loop) < 12:
        return np.zeros((0, 3))
    spread = loop - loop.mean(axis=0)
    normal = np.linalg.eigh(spread.T @ spread)[1][:, 0]
    if float(np.sqrt(np.mean((spread @ normal) ** 2))) > max(max_loop_spacings * spacing, max_loop_fraction * region.bounding_radius):
        return np.zeros((0, 3))
    if not harmonic:
        return rim_surface_fill(loop, region, covered, spacing, voxelized=voxelized, step=step, max_steep=1.0,
                                gap_spacings=gap_spacings, degree=1)
    flat = _flat_anchors(loop)
    if flat.sum() >= 12:
        loop = loop[flat]
    centre = loop.mean(axis=0)
    axes = np.linalg.svd(loop - centre, full_matrices=False)[2]  # rows u, v, n
    uv, heights = (loop - centre) @ axes[:2].T, (loop - centre) @ axes[2]
    cells, cell_heights = harmonic_height_field(uv, heights, spacing / 2.0 if voxelized else (step or spacing))
    points = centre + cells @ axes[:2] + cell_heights[:, None] * axes[2]
    points = points[region.contains(points)]
    points = points[far_from(points, covered, gap_spacings * spacing)]
    if voxelized and len(points):
        points = unique_voxels(np.floor(points + 0.5))
    return points


def harmonic_height_field(uv: np.ndarray, heights: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """The harmonic interpolant of scattered heights over their plane, on a square grid: (centres (M, 2), heights
    (M,)) of the grid cells inside the convex hull of ``uv`` (K, 2) that hold none of the K points.

    Cells of side ``cell``; a cell holding points is fixed at their mean ``heights`` (K,). The others, inside the
    hull, solve the discrete Laplace equation (5-point stencil: each is the mean of its neighbours in the hull;
    cells outside the hull are left out, a zero-slope boundary), one sparse solve (scipy's ``spsolve``); a group
    of cells that no fixed cell borders has no solution and is left out. The grid, not a graph of the points:
    the stencil's Laplacian is exact for a height field, where a k-nearest-neighbour graph's is biased by the
    points' uneven spacing."""
    import scipy.sparse as sp
    from scipy.ndimage import label
    from scipy.sparse.linalg import spsolve
    from scipy.spatial import ConvexHull, QhullError

    empty = np.zeros((0, 2)), np.zeros(0)
    try:
        edges = ConvexHull(uv).equations  # rows (a, b, c): a u + b v + c <= 0 inside
    except QhullError:
        return empty
    origin = uv.min(axis=0) - 1.5 * cell  # the lowest point at the centre of cell 1: cell 0 pads np.roll below
    ij = np.floor((uv - origin) / cell).astype(np.int64)
    shape = tuple(ij.max(axis=0) + 2)
    flat = np.ravel_multi_index((ij[:, 0], ij[:, 1]), shape)
    count = np.bincount(flat, minlength=shape[0] * shape[1]).reshape(shape)
    fixed = count > 0
    value = np.zeros(shape)
    value[fixed] = (np.bincount(flat, weights=heights, minlength=count.size).reshape(shape)[fixed] / count[fixed])
    centres = origin + (np.stack(np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij"), axis=-1) + 0.5) * cell
    inside = (centres.reshape(-1, 2) @ edges[:, :2].T + edges[:, 2] <= 1e-9 * cell).all(axis=1).reshape(shape)
    free = inside & ~fixed
    # the free cells' groups (4-connected) that border a fixed cell: the others' Laplace problem is singular
    groups, _ = label(free)
    bordered = np.zeros(shape, dtype=bool)
    for axis in (0, 1):
        for shift in (1, -1):
            bordered |= np.roll(fixed, shift, axis=axis)  # the padding row keeps np.roll from wrapping onto data
    keep = np.unique(groups[free & bordered])
    free &= np.isin(groups, keep[keep > 0])
    rows_i, rows_j = np.nonzero(free)
    if not len(rows_i):
        return empty
    index = np.full(shape, -1, dtype=np.int64)
    index[rows_i, rows_j] = np.arange(len(rows_i))
    degree, rhs = np.zeros(len(rows_i)), np.zeros(len(rows_i))
    pair_rows, pair_cols = [], []
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        ni, nj = rows_i + di, rows_j + dj
        valid = (ni >= 0) & (nj >= 0) & (ni < shape[0]) & (nj < shape[1])
        ni, nj = np.where(valid, ni, 0), np.where(valid, nj, 0)
        to_fixed, to_free = valid & fixed[ni, nj], valid & free[ni, nj]
        degree += to_fixed | to_free
        rhs += np.where(to_fixed, value[ni, nj], 0.0)
        pair_rows.append(np.flatnonzero(to_free))
        pair_cols.append(index[ni, nj][to_free])
    n = len(rows_i)
    pr, pc = np.concatenate(pair_rows), np.concatenate(pair_cols)
    laplacian = sp.csc_matrix((np.concatenate([degree, -np.ones(len(pr))]),
                               (np.concatenate([np.arange(n), pr]), np.concatenate([np.arange(n), pc]))), shape=(n, n))
    return centres[rows_i, rows_j], np.atleast_1d(spsolve(laplacian, rhs))
