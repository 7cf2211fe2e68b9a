"""Geometry helpers shared by the hole generators and hole detection (numpy / scipy only).

Scale conventions, used everywhere in `holes/`:

- ``point_spacing(points)``: the typical distance between neighbouring surface samples,
  ``median_i d_8(i) / sqrt(2)`` (`metrics.neighbours.point_spacing`, the project's one spacing
  estimator: exactly 1 on a unit voxel surface).
- ``cube_size(points)``: the cube size M that hole sizes are measured in,
  ``M = min(20 * spacing, 20 * L / 1024)`` with L the largest side of the axis-aligned bounding
  box. The first term is M as the proposed method uses it (``methods.temporal_graph``: 20 point
  spacings, the paper's M = 20 voxels at 10 bits); the second is the paper's M relative to the
  body (paper, Sec. 3.1, commented text: "M is set according to the coordinate range of P_f";
  the 8i 10-bit bodies fill the 1024 grid). On those bodies both are 20. On sparser captures
  (Dynamic FAUST: 100k points for a 1023-tall body, spacing ~2.8) or on the embedded human at
  small sizes (186 voxels tall) the second is smaller and keeps holes the size the paper's holes
  have relative to the body, instead of swallowing a limb.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.errors import UserError

# the one point-spacing and normal estimator (metrics.neighbours), re-exported for holes' callers
from dpcbench.metrics.neighbours import estimate_normals, point_spacing

__all__ = ["PAPER_CUBE_SIZE", "PAPER_GRID", "bounding_box_region", "check_frame", "components_to_regions",
           "cube_size", "estimate_normals", "point_spacing", "radius_components", "regions_mask", "tangent_basis"]

#: the paper's cube size on 10-bit data, and the grid it refers to
PAPER_CUBE_SIZE = 20.0
PAPER_GRID = 1024.0


def check_frame(points: ArrayLike, what: str = "frame") -> np.ndarray:
    """``points`` as a float64 (N, 3) array; ValueError for a wrong shape, no points or non-finite values."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise UserError(f"{what}: expected an (N, 3) array of points, got shape {arr.shape}")
    if len(arr) == 0:
        raise UserError(f"{what}: has no points; remove empty frames from the sequence")
    if not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr).all(axis=1)).sum())
        raise UserError(f"{what}: {bad} points have NaN or infinite coordinates; clean the input first")
    return arr


def cube_size(points: np.ndarray, spacing: float | None = None, tree: cKDTree | None = None) -> float:
    """The cube size M for sizing holes: min(20 * spacing, 20 * (largest bounding-box side) / 1024).

    ``spacing`` (else estimated) and ``tree`` (a cKDTree of ``points``, reused) save work."""
    points = np.asarray(points, dtype=np.float64)
    extent = float((points.max(axis=0) - points.min(axis=0)).max())
    if not extent > 0:
        raise UserError("the frame has zero extent (all points coincide); cannot size holes")
    spacing = point_spacing(points, tree) if spacing is None else spacing
    return PAPER_CUBE_SIZE * min(spacing, extent / PAPER_GRID)


def radius_components(points: np.ndarray, radius: float) -> tuple[int, np.ndarray]:
    """Connected components of the graph linking points closer than ``radius``.

    Returns (number of components, label per point (N,)).
    """
    if len(points) == 0:
        return 0, np.zeros(0, dtype=np.int64)
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
    return connected_components(graph, directed=False)


def bounding_box_region(points: np.ndarray, margin: float, **extra: Any) -> HoleRegion:
    """An oriented box around ``points`` (M, 3): axes from PCA of the points, half extents from the
    largest absolute projection on each axis plus ``margin`` (> 0, so a single point gets a box)."""
    center = points.mean(axis=0)
    local = points - center
    if len(points) >= 3:
        # eigh returns ascending eigenvalues; columns are orthonormal axes
        _, axes = np.linalg.eigh(local.T @ local)
        if np.linalg.det(axes) < 0:
            axes[:, 0] = -axes[:, 0]  # keep a proper rotation
    else:
        axes = np.eye(3)
    proj = local @ axes
    # re-centre on the box middle so the box is tight along each axis
    lo, hi = proj.min(axis=0), proj.max(axis=0)
    center = center + axes @ ((lo + hi) / 2)
    half = (hi - lo) / 2 + margin
    return HoleRegion.box(center, half, axes, **extra)


def components_to_regions(
    points: np.ndarray, link_radius: float, margin: float, shape: str = "box"
) -> tuple[list[HoleRegion], np.ndarray]:
    """Group ``points`` (M, 3) (e.g. removed points) into connected pieces and bound each piece.

    link_radius: points closer than this belong to the same piece.
    margin:      added to each bounding shape so that every point lies strictly inside.
    shape:       "box" (PCA-oriented bounding box: tight for slivers under an arm) or "ball"
                 (centroid, radius = largest distance to it + margin).
    Returns (regions, label per point). Every input point is contained in the region of its label.
    """
    count, labels = radius_components(points, link_radius)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(count + 1))
    regions = []
    for c in range(count):
        piece = points[order[bounds[c]:bounds[c + 1]]]
        if shape == "ball":
            center = piece.mean(axis=0)
            radius = float(np.sqrt(((piece - center) ** 2).sum(axis=1).max())) + margin
            regions.append(HoleRegion.ball(center, radius, point_count=int(len(piece))))
        else:
            regions.append(bounding_box_region(piece, margin, point_count=int(len(piece))))
    return regions, labels


def tangent_basis(normals: np.ndarray) -> np.ndarray:
    """Two unit tangent axes per normal, (N, 3, 2), orthonormal and orthogonal to the normal.

    The first axis is normal x e, with e the coordinate axis least aligned with the normal (so the
    cross product never degenerates); the second is normal x first.
    """
    n = np.asarray(normals, dtype=np.float64)
    helper = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    first = np.cross(n, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = np.cross(n, first)
    return np.stack([first, second], axis=2)


def regions_mask(regions: list[HoleRegion], points: np.ndarray, tree: cKDTree | None = None) -> np.ndarray:
    """Mask (N,) of the points inside any region: exactly ``union_mask(regions, points)``, but each
    region is only tested on the KD-tree candidates within its bounding radius (thousands of small
    regions on a million points would otherwise cost regions x points)."""
    tree = tree if tree is not None else cKDTree(points)
    mask = np.zeros(len(points), dtype=bool)
    for region in regions:
        reach = region.bounding_radius * (1 + 1e-9) + 1e-12
        cand = np.asarray(tree.query_ball_point(region.center, reach), dtype=np.int64)
        if len(cand):
            mask[cand[region.contains(points[cand])]] = True
    return mask
