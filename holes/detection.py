"""Hole detection in a captured frame without ground truth: boundary points grouped into hole regions.

Algorithm (``detect_holes``), for one (N, 3) frame:

1. Boundary points (angle criterion, as in PCL's BoundaryEstimation): for each point p, take its
   ``k`` nearest neighbours, fit the tangent plane by PCA, project the neighbour offsets onto it and
   sort their angles. Interior points are surrounded by neighbours; on the rim of a hole or of an
   open scan one side is empty, so the largest angular gap between consecutive neighbours exceeds
   ``gap`` (radians). The unit tangent vector in the middle of that gap, g(p), points into the
   empty side.
2. Rings: boundary points closer than ``link`` point spacings are linked; each connected component
   with at least ``min_points`` points is one candidate rim.
3. Holes vs outer silhouette: a hole is empty *inside* its rim, so the gap directions of its rim
   points point towards the rim's centroid c; the outer silhouette of an open scan (e.g. the cut
   at the waist, the back of a front-only capture) is empty *outside*, its gap directions point
   away from c. A rim is kept as a hole when the mean of ``g(p) . (c - p) / |c - p|`` over its
   points is at least ``min_inward`` (default 0.1; measured: the outer rim of a sampled
   hemisphere scores -0.07, the outline rims of the ricardo9 capture -0.48 to 0.03, rims of
   synthetic holes on the embedded human mostly 0.5-0.97 but 0.08-0.2 where a hole cuts through
   a thin limb; on the embedded human 0.1 instead of 0.2 raised recall on "large" holes from 0.63
   to 0.87 (tiny) at precision 0.97 vs 0.98; a one-off measurement whose script was not kept).
   Rims larger than ``max_radius`` (fraction of the bounding-box diagonal) are dropped as well:
   they are the open ends of the scan, not holes.
4. Each kept rim becomes a ball at its centroid, radius = largest distance of a rim point to the
   centroid + one point spacing, so the ball covers the whole missing patch the rim surrounds.

Regions carry ``rim_points`` (boundary points in the rim) and ``inward`` (the score of step 3).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from dpcbench.holes.geometry import check_frame, estimate_normals, point_spacing, radius_components, tangent_basis
from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.errors import UserError

#: Version of `detect_holes`'s output: bump it whenever a change alters the regions it returns for
#: some input (a pure speed-up that returns the same regions keeps it). Runs with regions = "detected"
#: carry it in their ids (`bench.config`), so a bump re-runs exactly those runs instead of reusing
#: results computed from the old detector's regions.
DETECT_HOLES_VERSION = "1"

#: Points handled per block in `boundary_points` (bounds the (block, k, 3) temporaries to ~50 MB at k = 32).
_BLOCK = 1 << 16

#: Nearest neighbours (self included) whose sectors the prefilter of `boundary_points` tests first:
#: on the 1M human stand-in and on Longdress the 19 nearest other points leave a sector empty for 16 %
#: of the points (12: 71 %, 16: 39-46 %, all 31: 0.15 %), so 20 minimises the offsets projected.
_NEAREST_FIRST = 20


def _occupied_sectors(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n,) uint8: bit s set when some tangent-plane offset (u, v) (n, m) lies in sector s of 45 degrees.

    The sectors come from three comparisons (signs of u and v, |u| < |v|), much cheaper than the
    angles and their sort. Bits of disjoint neighbour subsets combine with ``|``.
    """
    code = (v < 0).astype(np.uint8) << 2
    code |= (u < 0).astype(np.uint8) << 1
    code |= (np.abs(u) < np.abs(v)).astype(np.uint8)
    bits = np.left_shift(np.uint8(1), code)
    return np.bitwise_or.reduce(bits, axis=1)


def _octants_all_occupied(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n,) bool: the tangent-plane offsets (u, v) (n, m) have a point in each of the 8 sectors of 45 degrees.

    Then no angular gap exceeds 90 degrees: an empty open arc longer than 90 degrees contains a whole
    closed 45-degree sector, which would be empty.
    """
    return _occupied_sectors(u, v) == 0xFF


def _tangent_offsets(points: np.ndarray, nbr: np.ndarray, centres: np.ndarray,
                     tangent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v), each (b, m): the offsets points[nbr] - centres (nbr (b, m), centres (b, 3)) in the
    tangent axes ``tangent`` (b, 3, 2)."""
    offsets = np.take(points, nbr, axis=0) - centres[:, None, :]
    return (np.einsum("nkd,nd->nk", offsets, tangent[:, :, 0]),
            np.einsum("nkd,nd->nk", offsets, tangent[:, :, 1]))


def boundary_points(points: np.ndarray, k: int = 32, gap: float = 0.6 * np.pi, tree: cKDTree | None = None,
                    *, interior_values: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point: is it on a boundary, and the unit tangent direction into the empty side.

    points: (N, 3). k: neighbours (including the point itself). gap: angular gap threshold (radians).
    tree: a cKDTree of ``points`` to reuse (built here when None).
    Returns (mask (N,) bool, largest gap (N,) radians, empty-side direction (N, 3)).

    With ``interior_values=False`` the largest gap and the direction are computed only for the
    points whose neighbours leave a 45-degree sector empty (`_octants_all_occupied`), NaN elsewhere;
    when ``gap`` >= pi / 2 those NaN points have no gap above 90 degrees, so the mask is exactly the
    same, and the work (arctan2 and sort of k - 1 angles per point) is done for a few percent of the
    points only.

    The k-nearest-neighbour query is made block by block (`_BLOCK` points) in the KD-tree's leaf
    order (``tree.indices``): only a block's (block, k) neighbour table is alive at a time instead of
    the (N, k) distances and indices of all points (0.5 GB at 1M points and k = 32), and consecutive
    queries walk the same tree nodes (k = 32, min of 3 on a shared 2-core machine at load ~6: CPU
    4.57 -> 3.98 s on Longdress 858k, 4.83 -> 4.47 s on the 1M human, whose points are already
    stored in grid order). Each point's neighbours do not depend on the query order or batching, so
    the results are the same as one query of all points in input order.
    """
    tree = tree if tree is not None else cKDTree(points)
    n = len(points)
    tangent = tangent_basis(estimate_normals(points, k))
    prefilter = not interior_values and gap >= np.pi / 2
    largest = np.full(n, np.nan)
    direction = np.full((n, 3), np.nan)
    leaf_order = np.asarray(tree.indices, dtype=np.intp)
    for start in range(0, n, _BLOCK):
        rows = leaf_order[start:start + _BLOCK]
        centres = points[rows]
        _, nbr = tree.query(centres, k=k, workers=-1)
        if prefilter:
            # sectors of the nearest neighbours first, then of the farther ones for the points still
            # missing a sector (most points have all 8 filled by their ~20 nearest): the same sector
            # set as all k - 1 at once, with fewer offsets projected
            sectors = np.zeros(len(rows), dtype=np.uint8)
            for lo, hi in ((1, min(_NEAREST_FIRST, k)), (min(_NEAREST_FIRST, k), k)):
                if hi > lo:
                    open_ = np.flatnonzero(sectors != 0xFF)
                    sectors[open_] |= _occupied_sectors(*_tangent_offsets(
                        points, nbr[open_, lo:hi], centres[open_], tangent[rows[open_]]))
            keep = sectors != 0xFF
            rows, centres, nbr = rows[keep], centres[keep], nbr[keep]
        t0, t1 = tangent[rows, :, 0], tangent[rows, :, 1]
        u, v = _tangent_offsets(points, nbr[:, 1:], centres, tangent[rows])  # self excluded
        angles = np.arctan2(v, u)
        angles.sort(axis=1)
        gaps = np.diff(angles, axis=1, append=angles[:, :1] + 2 * np.pi)  # wrap-around gap last
        widest = gaps.argmax(axis=1)
        local = np.arange(len(rows))
        widest_gap = gaps[local, widest]
        middle = angles[local, widest] + widest_gap / 2
        largest[rows] = widest_gap
        direction[rows] = np.cos(middle)[:, None] * t0 + np.sin(middle)[:, None] * t1
    return largest > gap, largest, direction


def detect_holes(
    points: ArrayLike,
    *,
    k: int = 32,
    gap: float = 0.6 * np.pi,
    link: float = 3.0,
    min_points: int = 10,
    min_inward: float = 0.1,
    max_radius: float = 0.25,
) -> list[HoleRegion]:
    """Hole regions (balls) of one captured frame; see the module docstring for the algorithm.

    points:     (N, 3) frame.
    k:          neighbours for the tangent plane and the angular gap.
    gap:        a point is on a boundary when its neighbours leave an angular gap above this (rad).
    link:       boundary points closer than ``link * spacing`` form one rim.
    min_points: smaller rims are noise (isolated boundary points of a rough surface) and dropped.
    min_inward: least mean inward score of a hole rim (1: all gaps point at the centroid).
    max_radius: largest hole radius, as a fraction of the bounding-box diagonal.
    Returns the regions, largest rim first.
    """
    points = check_frame(points, "detect_holes")
    if int(k) != k or k < 5:
        raise UserError(f"detect_holes: k must be an integer >= 5, got {k!r}")
    if len(points) <= k:
        raise UserError(f"detect_holes: the frame has {len(points)} points; need more than k={k}")
    if not 0 < gap < 2 * np.pi:
        raise UserError(f"detect_holes: gap must be an angle in (0, 2 pi) radians, got {gap!r}")
    if not link > 0 or not max_radius > 0 or min_points < 1:
        raise UserError("detect_holes: link, max_radius and min_points must be positive")
    tree = cKDTree(points)
    spacing = point_spacing(points, tree)
    on_rim, _, direction = boundary_points(points, int(k), gap, tree, interior_values=False)
    rim_idx = np.flatnonzero(on_rim)
    count, labels = radius_components(points[rim_idx], link * spacing)
    diag = float(np.linalg.norm(np.ptp(points, axis=0)))
    regions = []
    for c in np.flatnonzero(np.bincount(labels, minlength=count) >= min_points):
        idx = rim_idx[labels == c]
        rim = points[idx]
        centroid = rim.mean(axis=0)
        to_centre = centroid - rim
        dist = np.linalg.norm(to_centre, axis=1)
        radius = float(dist.max()) + spacing
        ok = dist > 0
        inward = (float(np.mean(np.einsum("ij,ij->i", direction[idx][ok], to_centre[ok]) / dist[ok]))
                  if ok.any() else 0.0)
        if inward < min_inward or radius > max_radius * diag:
            continue
        regions.append(HoleRegion.ball(centroid, radius, rim_points=int(len(idx)), inward=round(inward, 4)))
    regions.sort(key=lambda r: -r.extra["rim_points"])
    return regions


def detection_scores(detected: list[HoleRegion], truth: list[HoleRegion], removed_points: np.ndarray) -> dict:
    """Recall and precision of detected holes against known (synthetic) ones.

    A detected region *matches* a true hole h when it contains at least half of h's removed
    points (``removed_points`` (M, 3), the ground truth, tested with ``h.contains``) or when its
    centre lies inside h. recall = matched true holes / true holes; precision = detected regions
    matching some true hole / detected regions (1.0 when nothing was detected and nothing was
    missing, 0.0 when nothing was detected but holes exist is reported through recall).
    Returns {"recall", "precision", "true_holes", "detected", "found", "correct"}.
    """
    removed_points = np.asarray(removed_points, dtype=np.float64).reshape(-1, 3)
    match = np.zeros((len(detected), len(truth)), dtype=bool)
    for j, hole in enumerate(truth):
        hole_pts = removed_points[hole.contains(removed_points)]
        for i, det in enumerate(detected):
            centre_inside = bool(hole.contains(det.center[None, :])[0])
            covered = len(hole_pts) > 0 and det.contains(hole_pts).mean() >= 0.5
            match[i, j] = centre_inside or covered
    found = int(match.any(axis=0).sum())
    correct = int(match.any(axis=1).sum())
    return {
        "recall": found / len(truth) if truth else 1.0,
        "precision": correct / len(detected) if detected else 1.0,
        "true_holes": len(truth),
        "detected": len(detected),
        "found": found,
        "correct": correct,
    }
