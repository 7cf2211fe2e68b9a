"""Steps 6 and 6f (`SurfaceSpline`, `SheetSpline` of `methods.temporal_fusion.spatial`): a thin-plate-spline height
field over the rim's PCA plane, trusted by its normals and its hold-out test; `rim_sheet` narrows the support to the
hole's own sheet."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill.common import (
    MAX_STEEP,
    SHEET_MIN_ALIGNMENT,
    SURFACE_POINTS,
    _link_components,
    even_subset,
    far_from,
    fit_height_field,
    unique_voxels,
)
from dpcbench.metrics.neighbours import estimate_normals


def height_spline(uv: np.ndarray, heights: np.ndarray, degree: int = 2):
    """The thin-plate spline of ``heights`` (K,) over ``uv`` (K, 2), both in point spacings (scipy's
    ``RBFInterpolator``: the biharmonic membrane through the rim, the smooth surface that bends least; smoothing 1: the
    rim's heights are samples with ~0.3-0.5 s noise; a polynomial of ``degree``): a callable (M, 2) -> (M,)."""
    from scipy.interpolate import RBFInterpolator

    return RBFInterpolator(uv, heights, kernel="thin_plate_spline", smoothing=1.0, degree=degree)


def rim_sheet(support: np.ndarray, region: HoleRegion, ring: float, spacing: float, *,
              min_cos: float = 0.5, link_spacings: float = 3.0) -> np.ndarray | None:
    """The sheet of ``support`` (K, 3) that ``region`` lies in (step 6f of `methods.temporal_fusion`), or None.

    Inner ring: the support points within ``ring`` of the region (the surface at the hole's edge), at
    least 12; a the principal eigenvector of sum n n^T over their PCA normals n (10 neighbours, as
    `fit_height_field`). The edge must be one sheet: mean (n . a)^2 over the ring at least
    `SHEET_MIN_ALIGNMENT`. Sheet: the support points whose normal is within 60 degrees of a
    (|n . a| >= ``min_cos``, step 6's steepness angle), and of those the connected part (links of
    ``link_spacings`` spacings, step 4's reach; `_link_components`) holding the most inner-ring points.
    None also when that leaves fewer than 12 points or drops none. Why: a crop that reaches a second
    surface (an arm against the chest, where a limb leaves the torso) is no height field as a whole,
    while the hole's own sheet is."""
    support = np.asarray(support, dtype=np.float64)
    inner = region.contains(support, margin=ring)
    if inner.sum() < 12:
        return None
    normals = estimate_normals(support, 10)
    values, vectors = np.linalg.eigh(normals[inner].T @ normals[inner])
    axis = vectors[:, -1]
    if values[-1] / inner.sum() < SHEET_MIN_ALIGNMENT:
        return None  # the hole's edge is no one sheet (a fold, a limb's side): steps 6c-6e judge it
    kept = np.flatnonzero(np.abs(normals @ axis) >= min_cos)
    if len(kept) < 12:
        return None
    points = support[kept]
    _, labels = _link_components(points, link_spacings * spacing)
    counts = np.bincount(labels[inner[kept]], minlength=int(labels.max()) + 1)
    sheet = points[labels == int(np.argmax(counts))]
    if len(sheet) < 12 or len(sheet) == len(support):
        return None
    return sheet


def rim_surface_fill(support: np.ndarray, region: HoleRegion, covered: cKDTree | None, spacing: float, *,
                     voxelized: bool, step: float | None = None, max_steep: float = MAX_STEEP,
                     gap_spacings: float = 1.0, ring: float = 0.0,
                     max_holdout_spacings: float = 1.0, degree: int = 2) -> np.ndarray:
    """Spatial fill (step 6 of `methods.temporal_fusion`) of the parts of ``region`` that no point of
    ``covered`` is within ``gap_spacings * spacing`` of, on the thin-plate-spline height field of
    ``support`` (K, 3) (the rim and the copied points around the hole). Returns (P, 3) points; (0, 3)
    when the surface is not trusted.

    Frame and height-field test: `fit_height_field` (at most ``max_steep`` of the support's normals
    more than 60 degrees off the axis n). Spline: scipy's ``RBFInterpolator`` (thin-plate kernel,
    smoothing 1, quadratic polynomial) of the heights h_i = (p_i - c) . n over (u_i, v_i), all in units
    of ``spacing``, on at most `SURFACE_POINTS` evenly strided support points. Hold-out test (when
    ``ring`` > 0): the spline of the support points farther than ``ring`` from the region must predict
    the heights of those within it with RMS error at most ``max_holdout_spacings`` (in spacings). The raw miss, not
    less the ring's own scatter as the later fills' hold-outs (`holdout_passes`): step 6 runs first, and a spline it
    passes takes the hole from the fills after it. With the scatter allowance it took holes that step 6c filled better
    (temporal-fusion 48: MVUB ricardo9 coherent seed 0, D1 32.41 -> 30.51; samba 10-19 coherent seed 6, 27.13 ->
    25.92; docs/temporal-fusion.md, "Version 49").
    Grid: step ``spacing / 2`` on voxelized data (then rounded half up to voxels, unique), else
    ``step`` (default ``spacing``); only grid points inside the convex hull of the support's (u, v),
    inside ``region`` and not covered are lifted onto the spline."""
    if len(support) < 12:
        return np.zeros((0, 3))
    centre, axes, _coef, _rms, steep = fit_height_field(support)
    if steep > max_steep:
        return np.zeros((0, 3))
    from scipy.spatial import ConvexHull, QhullError

    support = even_subset(support, SURFACE_POINTS)
    spread = support - centre
    uv = spread @ axes[:2].T
    step = spacing / 2.0 if voxelized else (step or spacing)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    gu = np.arange(lo[0], hi[0] + step, step)
    gv = np.arange(lo[1], hi[1] + step, step)
    grid = np.stack(np.meshgrid(gu, gv, indexing="ij"), axis=-1).reshape(-1, 2)
    # only grid points whose (u, v) lies within the region's bounding radius of its centre's (u, v) can
    # land inside the region at any height (the distance in the (u, v) plane is at most the 3-D one):
    # the hull test and the spline are evaluated on the hole's disc, not on the rim's whole bounding box
    centre_uv = (region.center - centre) @ axes[:2].T
    near = np.einsum("ij,ij->i", grid - centre_uv, grid - centre_uv) <= (region.bounding_radius * (1 + 1e-9)) ** 2
    grid = grid[near]
    if not len(grid):
        return np.zeros((0, 3))
    try:
        # inside the convex hull: on the inner side of every hull edge (a half-plane test; Delaunay's
        # find_simplex gives the same answer but its walk across the hole's long thin triangles
        # measured up to 4 s for 11k grid points on an 800k-point frame)
        edges = ConvexHull(uv).equations  # rows (a, b, c): a u + b v + c <= 0 inside, (a, b) unit length
        inside_hull = (grid @ edges[:, :2].T + edges[:, 2] <= 1e-9 * spacing).all(axis=1)
    except QhullError:
        return np.zeros((0, 3))
    grid = grid[inside_hull]
    if not len(grid):
        return np.zeros((0, 3))
    heights = (spread @ axes[2]) / spacing
    if ring > 0:
        # hold-out test of the surface across a gap: fit the outer rim only, predict the inner ring
        # (the rim points within ``ring`` of the region), which lies as far from the outer rim as the
        # hole's edge does
        inner = region.contains(support, margin=ring)
        if inner.sum() >= 6 and (~inner).sum() >= 12:
            outer_spline = height_spline(uv[~inner] / spacing, heights[~inner])
            held_out = float(np.sqrt(np.mean((outer_spline(uv[inner] / spacing) - heights[inner]) ** 2)))
            if held_out > max_holdout_spacings:
                return np.zeros((0, 3))
    spline = height_spline(uv / spacing, heights, degree)
    u, v = grid[:, 0], grid[:, 1]
    h = spline(grid / spacing) * spacing
    points = centre + u[:, None] * axes[0] + v[:, None] * axes[1] + h[:, None] * axes[2]
    points = points[region.contains(points)]
    points = points[far_from(points, covered, gap_spacings * spacing)]
    if voxelized and len(points):
        points = unique_voxels(np.floor(points + 0.5))
    return points
