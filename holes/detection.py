"""Hole detection in a captured frame without ground truth: boundary points grouped into hole regions.

Algorithm (``detect_holes``), for one (N, 3) frame:

1. Boundary points (angle criterion, as in PCL's BoundaryEstimation): for each point p, take its
   ``k`` nearest neighbours (one query serves both steps), fit the tangent plane by PCA of those
   k points, project the neighbour offsets onto it and sort their angles. Interior points are
   surrounded by neighbours; on the rim of a hole or of an open scan one side is empty, so the
   largest angular gap between consecutive neighbours exceeds ``gap`` (radians). The unit tangent
   vector in the middle of that gap, g(p), points into the empty side. A point is tested first with
   its ``screen`` = 16 nearest, and only the few that pass are tested again with the k = 32
   nearest; both tests must pass (`boundary_points` says why; one k-NN query per test serves both
   its normal and its angles, where the normals used to come from a second, open3d search).
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

from dpcbench.holes.geometry import check_frame, point_spacing, radius_components
from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.errors import UserError

#: Points handled per block in `boundary_points` (bounds the (block, k) temporaries to ~100 MB at k = 32).
_BLOCK = 1 << 16


def smallest_eigenvectors(xx: np.ndarray, yy: np.ndarray, zz: np.ndarray, xy: np.ndarray, xz: np.ndarray,
                          yz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit eigenvectors (x, y, z components, each (n,)) of the smallest eigenvalue of the symmetric
    3 x 3 matrices with entries ``xx, yy, zz`` (diagonal) and ``xy, xz, yz`` (off-diagonal), each (n,).

    Written by hand because numpy's batched ``eigh`` costs ~1.8 CPU-s per million 3 x 3 matrices (the
    whole time budget of `detect_holes`), and no library offers a closed-form batched solver. Closed form
    (Smith 1961): with q = tr(A) / 3, p = sqrt(|A - q I|_F^2 / 6) and r = det((A - q I) / p) / 2, the
    smallest eigenvalue is l = q + 2 p cos(arccos(r) / 3 + 2 pi / 3). The eigenvector is the longest
    of the three cross products of two rows of A - l I (each row is orthogonal to it). Where even that
    one is tiny against |A|_F^2 (the smallest eigenvalue is repeated, or A is a multiple of I: no
    well-defined normal) ``numpy.linalg.eigh`` decides, for those matrices only. The sign is arbitrary.
    """
    q = (xx + yy + zz) / 3.0
    a, b, c = xx - q, yy - q, zz - q
    p = np.sqrt((a * a + b * b + c * c + 2.0 * (xy * xy + xz * xz + yz * yz)) / 6.0)
    safe = np.where(p > 0, p, 1.0)
    det = a * (b * c - yz * yz) - xy * (xy * c - yz * xz) + xz * (xy * yz - b * xz)
    r = np.clip(det / (2.0 * safe ** 3), -1.0, 1.0)
    smallest = q + 2.0 * p * np.cos(np.arccos(r) / 3.0 + 2.0 * np.pi / 3.0)
    a, b, c = xx - smallest, yy - smallest, zz - smallest  # rows (a, xy, xz), (xy, b, yz), (xz, yz, c)
    best = [xy * yz - xz * b, xz * xy - a * yz, a * b - xy * xy]  # row 0 x row 1
    best_len = best[0] ** 2 + best[1] ** 2 + best[2] ** 2
    for cand in ([xy * c - xz * yz, xz * xz - a * c, a * yz - xy * xz],  # row 0 x row 2
                 [b * c - yz * yz, yz * xz - xy * c, xy * yz - b * xz]):  # row 1 x row 2
        cand_len = cand[0] ** 2 + cand[1] ** 2 + cand[2] ** 2
        longer = cand_len > best_len
        for i in range(3):
            best[i] = np.where(longer, cand[i], best[i])
        best_len = np.maximum(cand_len, best_len)
    length = np.sqrt(best_len)
    scale = xx * xx + yy * yy + zz * zz + 2.0 * (xy * xy + xz * xz + yz * yz)  # |A|_F^2
    degenerate = np.flatnonzero(~(length > 1e-6 * scale))
    length[degenerate] = 1.0
    vx, vy, vz = best[0] / length, best[1] / length, best[2] / length
    if len(degenerate):
        d = degenerate
        mats = np.stack([np.stack([xx[d], xy[d], xz[d]], -1), np.stack([xy[d], yy[d], yz[d]], -1),
                         np.stack([xz[d], yz[d], zz[d]], -1)], axis=1)
        vectors = np.linalg.eigh(mats)[1][:, :, 0]
        vx[d], vy[d], vz[d] = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    return vx, vy, vz


def _tangent_axes(nx: np.ndarray, ny: np.ndarray, nz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangent axes (each (n, 3)) orthogonal to the unit normals (nx, ny, nz): those of
    `holes.geometry.tangent_basis` (first = n x e, e the coordinate axis least aligned with n; second
    = n x first), computed per coordinate column."""
    ax, ay, az = np.abs(nx), np.abs(ny), np.abs(nz)
    ex = (ax <= ay) & (ax <= az)  # argmin picks the first of equal minima
    ey = ~ex & (ay <= az)
    # n x e for e = x, y, z: (0, nz, -ny), (-nz, 0, nx), (ny, -nx, 0)
    fx = np.where(ex, 0.0, np.where(ey, -nz, ny))
    fy = np.where(ex, nz, np.where(ey, 0.0, -nx))
    fz = np.where(ex, -ny, np.where(ey, nx, 0.0))
    norm = np.sqrt(fx * fx + fy * fy + fz * fz)
    fx, fy, fz = fx / norm, fy / norm, fz / norm
    first = np.stack([fx, fy, fz], axis=1)
    second = np.stack([ny * fz - nz * fy, nz * fx - nx * fz, nx * fy - ny * fx], axis=1)
    return first, second


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


def _widest_gaps(points: np.ndarray, columns: list[np.ndarray], tree: cKDTree, rows: np.ndarray, k: int,
                 prefilter: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The widest angular gap around each point ``rows`` (b,) among its k nearest (see `boundary_points`).

    columns: the x, y, z columns of ``points``, contiguous. prefilter: skip the points whose k - 1
    neighbours fill all 8 sectors of 45 degrees (their widest gap is at most 90 degrees).
    Returns (rows computed (c,), widest gap (c,) radians, unit direction of its middle (c, 3)).
    """
    _, nbr = tree.query(points[rows], k=k, workers=-1)
    ox, oy, oz = (col[nbr[:, 1:]] - col[rows, None] for col in columns)  # offsets to the k - 1 others
    # covariance of the k points (p's own offset is 0): E[o o^T] - E[o] E[o]^T over the k
    mx, my, mz = ox.sum(axis=1) / k, oy.sum(axis=1) / k, oz.sum(axis=1) / k
    nx, ny, nz = smallest_eigenvectors(
        np.einsum("nk,nk->n", ox, ox) / k - mx * mx, np.einsum("nk,nk->n", oy, oy) / k - my * my,
        np.einsum("nk,nk->n", oz, oz) / k - mz * mz, np.einsum("nk,nk->n", ox, oy) / k - mx * my,
        np.einsum("nk,nk->n", ox, oz) / k - mx * mz, np.einsum("nk,nk->n", oy, oz) / k - my * mz)
    t0, t1 = _tangent_axes(nx, ny, nz)
    u = ox * t0[:, 0, None] + oy * t0[:, 1, None] + oz * t0[:, 2, None]
    v = ox * t1[:, 0, None] + oy * t1[:, 1, None] + oz * t1[:, 2, None]
    if prefilter:
        keep = np.flatnonzero(~_octants_all_occupied(u, v))
        rows, u, v, t0, t1 = rows[keep], u[keep], v[keep], t0[keep], t1[keep]
    angles = np.arctan2(v, u)
    angles.sort(axis=1)
    gaps = np.diff(angles, axis=1, append=angles[:, :1] + 2 * np.pi)  # wrap-around gap last
    widest = gaps.argmax(axis=1)
    local = np.arange(len(rows))
    widest_gap = gaps[local, widest]
    middle = angles[local, widest] + widest_gap / 2
    return rows, widest_gap, np.cos(middle)[:, None] * t0 + np.sin(middle)[:, None] * t1


def boundary_points(points: np.ndarray, k: int = 32, gap: float = 0.6 * np.pi, tree: cKDTree | None = None,
                    *, interior_values: bool = True, screen: int | None = 16
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point: is it on a boundary, and the unit tangent direction into the empty side.

    points: (N, 3). k: neighbours (including the point itself). gap: angular gap threshold (radians).
    tree: a cKDTree of ``points`` to reuse (built here when None).
    screen: neighbours of a first, cheaper test (None, or >= k: none).
    Returns (mask (N,) bool, largest gap among the k nearest (N,) radians, empty-side direction (N, 3)).

    The test at n neighbours: the normal of p is the PCA normal of its n nearest points (p included;
    covariance C = sum_i o_i o_i^T / n - m m^T of the offsets o_i to p, m their mean; eigenvector of
    the smallest eigenvalue by `smallest_eigenvectors`), the other n - 1 offsets are projected on the
    tangent plane (axes of `holes.geometry.tangent_basis`), and p passes when the widest angle between
    consecutive projections exceeds ``gap``. One k-NN query serves the normal and the angles (the same
    normal as `metrics.neighbours.estimate_normals` up to sign and the choice among neighbours at
    equal distance, as the k-th nearest often ties on voxelized data).

    p is a boundary point when it passes the test at ``screen`` neighbours *and* at k. Why: the
    k-NN query is most of the cost (1M points: 4.5 CPU-s at k = 32, 2.5 at 16), but few points pass
    at 16 (a few percent on voxelized frames, ~10 % on a randomly sampled sphere), and only those need
    the query at k. With one normal, fewer neighbours can only widen the gaps, so the second test
    alone decides almost always; the screen at 16 alone would flag ~10 % of a randomly sampled
    surface (spurious holes) where k = 32 flags ~0.1 %.

    With ``interior_values=False`` the largest gap and the direction are computed only for the
    points that pass the screen and whose k - 1 neighbours leave a 45-degree sector empty
    (`_octants_all_occupied`), NaN elsewhere; when ``gap`` >= pi / 2 those NaN points have no gap
    above 90 degrees, so the mask is exactly the same (the screen's own prefilter likewise).
    With ``interior_values=True`` both tests are made at every point.

    The queries are made block by block (`_BLOCK` points) in the KD-tree's leaf order (``tree.indices``):
    only a block's (block, k) neighbour table is alive at a time, and consecutive queries walk the same
    tree nodes. Each point's neighbours do not depend on the query order or batching.
    """
    tree = tree if tree is not None else cKDTree(points)
    n = len(points)
    prefilter = not interior_values and gap >= np.pi / 2
    screen_k = k if screen is None else screen  # a screen of k or more neighbours would test nothing new
    if screen_k < k and (int(screen_k) != screen_k or screen_k < 5):
        raise UserError(f"boundary_points: screen must be None or an integer >= 5, got {screen!r}")
    screened = screen_k < k
    largest = np.full(n, np.nan)
    direction = np.full((n, 3), np.nan)
    passed_screen = np.ones(n, dtype=bool)
    leaf_order = np.asarray(tree.indices, dtype=np.intp)
    columns = [np.ascontiguousarray(points[:, i]) for i in range(3)]  # (b, k) gathers per coordinate
    for start in range(0, n, _BLOCK):
        rows = leaf_order[start:start + _BLOCK]
        if screened:
            passed_screen[rows] = False
            done, widest, _ = _widest_gaps(points, columns, tree, rows, int(screen_k), prefilter)
            passed_screen[done[widest > gap]] = True
            if not interior_values:
                rows = done[widest > gap]
        done, widest, towards = _widest_gaps(points, columns, tree, rows, int(k), prefilter)
        largest[done] = widest
        direction[done] = towards
    return (largest > gap) & passed_screen, largest, direction


def detect_holes(
    points: ArrayLike,
    *,
    k: int = 32,
    gap: float = 0.6 * np.pi,
    link: float = 3.0,
    min_points: int = 10,
    min_inward: float = 0.1,
    max_radius: float = 0.25,
    screen: int | None = 16,
) -> list[HoleRegion]:
    """Hole regions (balls) of one captured frame; see the module docstring for the algorithm.

    points:     (N, 3) frame.
    k:          neighbours for the tangent plane and the angular gap.
    gap:        a point is on a boundary when its neighbours leave an angular gap above this (rad).
    link:       boundary points closer than ``link * spacing`` form one rim.
    min_points: smaller rims are noise (isolated boundary points of a rough surface) and dropped.
    min_inward: least mean inward score of a hole rim (1: all gaps point at the centroid).
    max_radius: largest hole radius, as a fraction of the bounding-box diagonal.
    screen:     neighbours of the first, cheaper boundary test (`boundary_points`); None: k only.
    Returns the regions, largest rim first.
    """
    points = check_frame(points, "detect_holes")
    if int(k) != k or k < 5:
        raise UserError(f"detect_holes: k must be an integer >= 5, got {k!r}")
    if len(points) <= k:
        raise UserError(f"detect_holes: the frame has {len(points)} points; need more than k={k}")
    if not 0 < gap < 2 * np.pi:
        raise UserError(f"detect_holes: gap must be an angle in (0, 2 pi) radians, got {gap!r}")
    if screen is not None and (int(screen) != screen or screen < 5):
        raise UserError(f"detect_holes: screen must be None or an integer >= 5, got {screen!r}")
    if not link > 0 or not max_radius > 0 or min_points < 1:
        raise UserError("detect_holes: link, max_radius and min_points must be positive")
    tree = cKDTree(points)
    spacing = point_spacing(points, tree)
    on_rim, _, direction = boundary_points(points, int(k), gap, tree, interior_values=False,
                                           screen=None if screen is None else int(screen))
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
