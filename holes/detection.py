"""Hole detection in a captured frame without ground truth: boundary points grouped into hole regions.

Algorithm (``detect_holes``), for one (N, 3) frame:

1. Boundary points (angle criterion, as in PCL's BoundaryEstimation): for each point p, take its
   ``k`` nearest neighbours, fit the tangent plane by PCA, project the neighbour offsets onto it and
   sort their angles. Interior points are surrounded by neighbours; on the rim of a hole or of an
   open scan one side is empty, so the largest angular gap between consecutive neighbours exceeds
   ``gap`` (radians). The unit tangent vector in the middle of that gap, g(p), points into the
   empty side. On a voxel frame (distinct integer coordinates) many neighbours are exactly as far as
   the k-th: all of them are taken (no arbitrary tie-breaking), read off a voxel stencil, which is
   also what makes this fast (`boundary_points`); other frames use a cKDTree's k nearest.
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

from dpcbench.holes._blas import OneBlasThread
from dpcbench.holes.geometry import check_frame, point_spacing, radius_components, tangent_basis
from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.neighbours import probe_indices

#: Version of `detect_holes`'s output: bump it whenever a change alters the regions it returns for
#: some input (a pure speed-up that returns the same regions keeps it). Runs with regions = "detected"
#: carry it in their ids (`bench.experiment.config`), so a bump re-runs exactly those runs instead of reusing
#: results computed from the old detector's regions.
#: "2" (2026-11-25): neighbourhoods of voxel frames are the k nearest plus every point tied with the
#: k-th (read off a voxel stencil, instead of whichever tied points a k-NN query returned) and normals
#: are the closed-form PCA of those neighbourhoods (instead of open3d's, over its own k nearest), for
#: speed (1M points: ~6.6 -> ~1.3 s CPU): the regions move slightly (quality yardstick: hole recall unchanged
#: at 0.972, region precision 0.988 -> 0.994).
DETECT_HOLES_VERSION = "2"

#: Points handled per block on the cKDTree path of `boundary_points` (bounds the (block, k, 3)
#: temporaries to ~50 MB at k = 32).
_BLOCK = 1 << 16

#: Nearest neighbours (self included) whose sectors the prefilter of the cKDTree path tests first:
#: on the 1M human stand-in and on Longdress the 19 nearest other points leave a sector empty for 16 %
#: of the points (12: 71 %, 16: 39-46 %, all 31: 0.15 %), so 20 minimises the offsets projected.
_NEAREST_FIRST = 20

#: Squared radii (in voxels) of the two stencils of the voxel-grid neighbour search: the near one
#: (147 offsets) holds the k = 32 nearest of nearly every point of a voxelized surface (a flat
#: axis-aligned patch has 37 points within squared radius 10, slanted ones more); the far one (925
#: offsets) is gathered only for the points the near one leaves short (rims of holes, thin parts);
#: the few points short even then (stray voxels) are handed to a cKDTree.
_NEAR_R2 = 10
_FAR_R2 = 36

#: Squared radius of the stencil offsets whose sectors the prefilter of the voxel path tests first
#: (57 offsets, of which ~20 are occupied on a surface: the counterpart of `_NEAREST_FIRST`).
_SECTOR_R2 = 5

#: Cells of one slab's occupancy grid on the voxel path (bool, 8 MiB), and points whose neighbourhoods
#: are gathered at a time (their (147, points) stencil tables: ~10 MB each): bound its memory.
_SLAB_CELLS = 1 << 23
_VOXEL_BLOCK = 1 << 14

#: Largest occupancy grid of one slab (bool, 128 MiB), reached when a single layer across the frame
#: exceeds `_SLAB_CELLS` (a 12-bit frame: 13 layers of 4108^2 cells, 219 MiB): such frames go to the
#: cKDTree path instead.
_MAX_SLAB_CELLS = 1 << 27

#: Points whose 9th-nearest distances give `detect_holes` its point spacing: `point_spacing`'s default sample.
_SPACING_SAMPLE = 20000


def _occupied_sectors(u: np.ndarray, v: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """(n,) uint8: bit s set when some tangent-plane offset (u, v) (m, n) (m offsets of n points; only
    those where ``mask`` (m, n) is True, when given) lies in sector s of 45 degrees. Bits of disjoint
    subsets combine with ``|``.

    The sectors come from three comparisons (signs of u and v, |u| < |v|), much cheaper than the
    angles and their sort. All 8 bits set means no angular gap exceeds 90 degrees: an empty open arc
    longer than 90 degrees contains a whole closed 45-degree sector, which would be empty. Offsets
    along the first axis: the reduction is then elementwise over rows of n (3x faster than along
    short rows of m).
    """
    code = (v < 0).view(np.uint8) << 2
    code |= (u < 0).view(np.uint8) << 1
    code |= (np.abs(u) < np.abs(v)).view(np.uint8)
    ones = np.ones(code.shape, dtype=np.uint8) if mask is None else mask.view(np.uint8)
    return np.bitwise_or.reduce(np.left_shift(ones, code), axis=0)


def _smallest_eigenvectors(cov: np.ndarray) -> np.ndarray:
    """(n, 3) unit eigenvectors of the smallest eigenvalue of the symmetric (n, 3, 3) ``cov`` (sign arbitrary).

    Closed form, because numpy's batched ``eigh`` is ~10x slower on millions of 3 x 3 matrices:
    the smallest eigenvalue by the trigonometric solution of the characteristic cubic
    (lambda = m + 2 p cos(phi + 2 pi / 3), m = trace / 3, p = |cov - m I|_F / sqrt(6),
    phi = arccos(det((cov - m I) / p) / 2) / 3), then the eigenvector as the largest of the cross
    products of two rows of cov - lambda I (each is orthogonal to the rows, so it spans the null
    space when lambda is a simple eigenvalue). Where the smallest eigenvalue is (nearly) double and
    the cross products vanish, ``numpy.linalg.eigh`` decides.
    """
    m = np.trace(cov, axis1=1, axis2=2) / 3
    b = cov - m[:, None, None] * np.eye(3)
    p = np.sqrt(np.einsum("nij,nij->n", b, b) / 6)
    det = (b[:, 0, 0] * (b[:, 1, 1] * b[:, 2, 2] - b[:, 1, 2] * b[:, 2, 1])
           - b[:, 0, 1] * (b[:, 1, 0] * b[:, 2, 2] - b[:, 1, 2] * b[:, 2, 0])
           + b[:, 0, 2] * (b[:, 1, 0] * b[:, 2, 1] - b[:, 1, 1] * b[:, 2, 0]))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.clip(det / (2 * p ** 3), -1.0, 1.0)
    phi = np.arccos(np.nan_to_num(r)) / 3
    lam = m + 2 * p * np.cos(phi + 2 * np.pi / 3)
    a = cov - lam[:, None, None] * np.eye(3)
    cands = np.stack([np.cross(a[:, 0], a[:, 1]), np.cross(a[:, 0], a[:, 2]), np.cross(a[:, 1], a[:, 2])], axis=1)
    norms = np.einsum("nci,nci->nc", cands, cands)
    best = norms.argmax(axis=1)
    rows = np.arange(len(cov))
    vec = cands[rows, best]
    norm = np.sqrt(norms[rows, best])
    # relative to the scale of the matrix: below this the smallest eigenvalue is (nearly) double
    scale = np.abs(m) + 2 * p
    weak = ~(norm > 1e-9 * scale ** 2)
    vec[~weak] /= norm[~weak, None]
    if weak.any():
        with OneBlasThread():
            vec[weak] = np.linalg.eigh(cov[weak])[1][:, :, 0]  # eigh: eigenvalues ascending
    return vec


def _moments(offsets: np.ndarray) -> np.ndarray:
    """(10, m) per offset (m, 3): 1, o_x, o_y, o_z, o_x^2, o_y^2, o_z^2, o_x o_y, o_x o_z, o_y o_z."""
    x, y, z = offsets.T
    return np.stack([np.ones(len(offsets)), x, y, z, x * x, y * y, z * z, x * y, x * z, y * z])


def _covariances_from_sums(s: np.ndarray) -> np.ndarray:
    """(n, 3, 3) covariances from the (10, n) sums of `_moments` over each neighbourhood:
    C = S2 / c - mean mean^T (translation invariant, so offsets from the point do as well as positions)."""
    s = np.asarray(s, dtype=np.float64).T
    c = s[:, 0]
    mean = s[:, 1:4] / c[:, None]
    second = s[:, [4, 7, 8, 7, 5, 9, 8, 9, 6]].reshape(-1, 3, 3) / c[:, None, None]
    return second - mean[:, :, None] * mean[:, None, :]


def _neighbourhood_gaps(offsets: np.ndarray, mask: np.ndarray, prefilter: bool) -> tuple[np.ndarray, np.ndarray]:
    """Largest angular gap (n,) and the unit tangent direction (n, 3) in its middle, per neighbourhood.

    offsets: (m, 3) integer offsets shared by all n points (a voxel stencil), or (m, n, 3) per point:
             from the point to its m candidate neighbours; candidate 0 is the point itself.
    mask:    (m, n) bool, the candidates that are neighbours (row 0 True). Candidates along the
             first axis: every step below is then elementwise over rows of n points.
    The normal is the PCA normal of the masked offsets (point included); the gap is that between
    consecutive angles of the other neighbours projected on the tangent plane (`tangent_basis`).
    prefilter: points whose neighbours fill all 8 sectors of 45 degrees (no gap above 90 degrees;
    the sectors of the offsets within ``_SECTOR_R2`` or the ``_NEAREST_FIRST`` nearest are tested
    first) get NaN instead of their gap and direction.
    """
    m, n = mask.shape
    shared = offsets.ndim == 2
    if shared:
        # integer offsets, at most 925 of squared length <= 36: the sums of their moments are
        # integers below 2^24, so float32 products are exact (and half the memory traffic)
        sums = _moments(offsets).astype(np.float32) @ mask.astype(np.float32)
    else:
        sums = np.einsum("mn,fmn->fn", mask.astype(np.float64),
                         _moments(offsets.reshape(-1, 3)).reshape(10, m, n))
    tangent = tangent_basis(_smallest_eigenvectors(_covariances_from_sums(sums)))
    axes = np.ascontiguousarray(tangent.transpose(1, 2, 0))  # (3, 2, n)

    def project(rows: np.ndarray, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """(u, v), each (hi - lo, len(rows)): offsets lo..hi of the points ``rows`` in their tangent axes."""
        if shared:
            return offsets[lo:hi] @ axes[:, 0, rows], offsets[lo:hi] @ axes[:, 1, rows]
        part = offsets[lo:hi, rows]
        return np.einsum("mnd,dn->mn", part, axes[:, 0, rows]), np.einsum("mnd,dn->mn", part, axes[:, 1, rows])

    rows = np.arange(n)
    largest = np.full(n, np.nan)
    direction = np.full((n, 3), np.nan)
    if prefilter:
        # sectors of the nearest offsets first, then of the farther ones for the points still missing
        # a sector (most fill all 8 with their ~20 nearest): the same sector set as all at once
        near = (int(np.searchsorted((offsets ** 2).sum(axis=1), _SECTOR_R2, side="right")) if shared
                else _NEAREST_FIRST)
        near = min(max(near, 1), m)
        sectors = np.zeros(n, dtype=np.uint8)
        for lo, hi in ((1, near), (near, m)):
            if hi > lo:
                open_ = np.flatnonzero(sectors != 0xFF)
                sectors[open_] |= _occupied_sectors(*project(open_, lo, hi), mask[lo:hi, open_])
        rows = np.flatnonzero(sectors != 0xFF)
    u, v = project(rows, 1, m)  # self excluded
    angles = np.arctan2(v, u).T  # (points, candidates): sorted along the candidates
    used = mask[1:, rows].T
    angles[~used] = np.inf  # sorted last, then replaced below
    angles.sort(axis=1)
    count = used.sum(axis=1)
    local = np.arange(len(rows))
    # past the last neighbour: the first angle + 2 pi, so that the first of these gaps is the
    # wrap-around gap and the rest are 0 (the largest gap and its position are those of the neighbours)
    pad = np.arange(m - 1)[None, :] >= count[:, None]
    angles[pad] = np.broadcast_to(angles[:, :1] + 2 * np.pi, angles.shape)[pad]
    gaps = np.diff(angles, axis=1, append=angles[:, :1] + 2 * np.pi)
    widest = gaps.argmax(axis=1)
    widest_gap = gaps[local, widest]
    middle = angles[local, widest] + widest_gap / 2
    largest[rows] = widest_gap
    direction[rows] = np.cos(middle)[:, None] * tangent[rows, :, 0] + np.sin(middle)[:, None] * tangent[rows, :, 1]
    return largest, direction


def _stencil(r2: int) -> tuple[np.ndarray, np.ndarray]:
    """Integer offsets (S, 3) with squared length <= ``r2``, by squared length (then lexicographically),
    and their squared lengths (S,). The first is (0, 0, 0)."""
    reach = int(np.sqrt(r2))
    axis = np.arange(-reach, reach + 1)
    offsets = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    d2 = (offsets ** 2).sum(axis=1)
    offsets, d2 = offsets[d2 <= r2], d2[d2 <= r2]
    order = np.lexsort((offsets[:, 2], offsets[:, 1], offsets[:, 0], d2))
    return offsets[order], d2[order]


def _voxel_coordinates(points: np.ndarray) -> np.ndarray | None:
    """``points`` (N, 3) as int64 coordinates from 0 when they are distinct voxels (integer-valued,
    no duplicates, extent under 2^20) whose thinnest slab (one layer across the two shorter extents,
    plus the stencil's margin) fits in `_MAX_SLAB_CELLS`; else None (the cKDTree path handles them)."""
    if not np.array_equal(points, np.rint(points)):
        return None
    grid = (points - points.min(axis=0)).astype(np.int64)
    extent = np.sort(grid.max(axis=0)) + 1
    reach = int(np.sqrt(_FAR_R2))
    if extent[-1] >= 1 << 20 or (1 + 2 * reach) * (extent[0] + 2 * reach) * (extent[1] + 2 * reach) > _MAX_SLAB_CELLS:
        return None
    key = (grid[:, 0] << 40) | (grid[:, 1] << 20) | grid[:, 2]
    key.sort()
    if (np.diff(key) == 0).any():
        return None
    return grid


def _shell_limits(hits: np.ndarray, d2: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per point (column) of ``hits`` (S, n) (occupied stencil offsets, ordered by squared length ``d2``
    (S,)): (done (n,) bool: at least k occupied, and width (n,) int: the number of stencil offsets up to
    and including the last one as long as the k-th nearest, i.e. the k nearest plus every tie)."""
    starts = np.flatnonzero(np.diff(d2, prepend=-1))  # first offset of each shell of equal length
    ends = np.append(starts[1:], len(d2))
    # occupied offsets up to the end of each shell, as one float32 product (exact: counts < 2^24;
    # 6x faster than a reduceat over the shells)
    upto = (np.arange(len(d2))[None, :] < ends[:, None]).astype(np.float32)
    reached = upto @ hits.astype(np.float32) >= k
    done = reached[-1]
    return done, ends[reached.argmax(axis=0)]


def _voxel_neighbourhoods(grid: np.ndarray, k: int, leftover: list):
    """Neighbourhoods of the points of a voxel frame ``grid`` (N, 3) int64 (`_voxel_coordinates`),
    read off a voxel stencil; yields groups (rows (n,), offsets (m, 3) float, mask (m, n) bool): the
    points ``rows`` and, for each, which of the stencil ``offsets`` (offset 0: the point itself) hold
    its neighbours.

    Neighbours of a point: its k nearest (itself included) plus every point as far as the k-th,
    found shell by shell of equal distance of `_stencil`, so no tie is broken arbitrarily (a k-NN
    query keeps whichever tied points its tree visits first). The frame is cut into slabs along its
    longest axis, each with an occupancy grid of at most `_SLAB_CELLS` cells covering the slab and a
    margin of the stencil's reach. The rows whose k-th neighbour lies beyond the far stencil are
    appended to ``leftover`` (arrays of rows) instead: the caller finds theirs with a cKDTree.
    """
    near, near_d2 = _stencil(_NEAR_R2)
    far, far_d2 = _stencil(_FAR_R2)
    reach = int(np.sqrt(_FAR_R2))
    slab_axis = int(np.argmax(grid.max(axis=0)))
    b_axis, c_axis = [a for a in range(3) if a != slab_axis]
    ext = grid.max(axis=0) + 1 + 2 * reach  # grid padded by the reach on both sides
    layer = int(ext[b_axis] * ext[c_axis])
    width = max(1, _SLAB_CELLS // layer - 2 * reach)
    # points by (slab axis, b, c): one packed key (extents < 2^20) sorts 7x faster than a lexsort
    order = np.argsort((grid[:, slab_axis] << 42) | (grid[:, b_axis] << 21) | grid[:, c_axis], kind="stable")
    a = grid[order, slab_axis]
    # slab-local key of a voxel: ((a - a0 + reach) * ext_b + b + reach) * ext_c + c + reach
    bc = (grid[order, b_axis] + reach) * ext[c_axis] + grid[order, c_axis] + reach

    def flat(offsets: np.ndarray) -> np.ndarray:
        return (offsets[:, slab_axis] * ext[b_axis] + offsets[:, b_axis]) * ext[c_axis] + offsets[:, c_axis]

    # int32 slab keys when they fit: the (rows, offsets) key tables are the largest temporaries
    key_type = np.int32 if (width + 2 * reach) * layer < 1 << 31 else np.int64
    near_flat, far_flat = flat(near).astype(key_type), flat(far).astype(key_type)
    near_offsets, far_offsets = near.astype(np.float64), far.astype(np.float64)
    for a0 in range(0, int(a[-1]) + 1, width):
        lo, first, last, hi = np.searchsorted(a, [a0 - reach, a0, a0 + width, a0 + width + reach])
        if first == last:
            continue
        occupied = np.zeros((width + 2 * reach) * layer, dtype=bool)
        slab_keys = ((a[lo:hi] - (a0 - reach)) * layer + bc[lo:hi]).astype(key_type)
        occupied[slab_keys] = True
        for start in range(first, last, _VOXEL_BLOCK):
            stop = min(start + _VOXEL_BLOCK, last)
            yield from _stencil_groups(occupied, slab_keys[start - lo:stop - lo], order[start:stop], k,
                                       (near_flat, near_offsets, near_d2), (far_flat, far_offsets, far_d2),
                                       leftover)


def _stencil_groups(occupied: np.ndarray, keys: np.ndarray, rows: np.ndarray, k: int, near: tuple, far: tuple,
                    leftover: list):
    """The groups of `_voxel_neighbourhoods` for the points ``rows`` at slab keys ``keys`` of the slab's
    occupancy grid ``occupied``; near and far: (flat offsets, offsets, squared lengths) of each stencil."""
    near_flat, near_offsets, near_d2 = near
    far_flat, far_offsets, far_d2 = far
    hits = occupied[near_flat[:, None] + keys[None, :]]
    done, cols = _shell_limits(hits, near_d2, k)
    if done.all():  # the usual case: no copy of the table
        groups = [(rows, near_offsets, hits, cols)]
    else:
        short, done = np.flatnonzero(~done), np.flatnonzero(done)
        groups = [(rows[done], near_offsets, np.take(hits, done, axis=1), cols[done])]
        # the far stencil's first offsets are the near one (both ordered by length)
        hits = np.concatenate([np.take(hits, short, axis=1), occupied[far_flat[len(near_flat):, None] + keys[short]]])
        done, cols = _shell_limits(hits, far_d2, k)
        groups.append((rows[short[done]], far_offsets, hits[:, done], cols[done]))
        leftover.append(rows[short[~done]])
    for group_rows, offsets, group_hits, group_cols in groups:
        if len(group_rows):
            m = int(group_cols.max())
            yield group_rows, offsets[:m], group_hits[:m] & (np.arange(m)[:, None] < group_cols[None, :])


def _tree_boundary(points: np.ndarray, rows: np.ndarray, k: int, tree: cKDTree, ties: bool, prefilter: bool,
                   largest: np.ndarray, direction: np.ndarray, ninth: np.ndarray | None, wanted: np.ndarray) -> None:
    """Largest gaps and directions of ``points[rows]``, neighbours from ``tree``, written into
    ``largest`` and ``direction``.

    ties False: the k nearest (a k-NN query; on points in general position there are no ties).
    ties True (integer coordinates, the few voxels the stencils miss): also every point exactly as
    far as the k-th, found with a ball of radius sqrt(d_k^2 + 1/2), which squared distances, being
    integers, cannot fall between.
    Rows are handled `_BLOCK` at a time in the given order (pass them in the tree's leaf order,
    ``tree.indices``, for consecutive queries to walk the same nodes). ``ninth`` (N,) (when not None)
    gets the distance to the 9th nearest of the rows where ``wanted`` (N,) is True.
    """
    for start in range(0, len(rows), _BLOCK):
        block = rows[start:start + _BLOCK]
        centres = points[block]
        dist, nbr = tree.query(centres, k=k, workers=-1)
        if ninth is not None:
            ninth[block[wanted[block]]] = dist[wanted[block], 8]
        if ties:
            balls = tree.query_ball_point(centres, np.sqrt(np.rint(dist[:, -1] ** 2) + 0.5), workers=-1)
            sizes = np.fromiter(map(len, balls), dtype=np.intp, count=len(balls))
            m = int(sizes.max())
            nbr = np.repeat(block[:, None], m, axis=1)  # padding: the point itself, masked out below
            nbr[np.arange(m)[None, :] < sizes[:, None]] = np.concatenate(balls)
            # the point itself in column 0 (as the k-NN query puts it), where the ball had another
            first = np.argmax(nbr == block[:, None], axis=1)
            nbr[np.arange(len(block)), first] = nbr[:, 0]
            nbr[:, 0] = block
            mask = np.arange(m)[None, :] < sizes[:, None]
        else:
            mask = np.ones(nbr.shape, dtype=bool)
        offsets = np.take(points, nbr.T, axis=0) - centres[None, :, :]  # (candidates, points, 3)
        largest[block], direction[block] = _neighbourhood_gaps(offsets, mask.T, prefilter)


def boundary_points(points: np.ndarray, k: int = 32, gap: float = 0.6 * np.pi, tree: cKDTree | None = None,
                    *, interior_values: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point: is it on a boundary, and the unit tangent direction into the empty side.

    points: (N, 3). k: neighbours (including the point itself). gap: angular gap threshold (radians).
    tree: a cKDTree of ``points`` to reuse (built here when needed and None).
    Returns (mask (N,) bool, largest gap (N,) radians, empty-side direction (N, 3)).

    Neighbourhood of a point: on a voxel frame (distinct integer coordinates, `_voxel_coordinates`)
    its k nearest plus every point tied with the k-th, read off a voxel stencil (`_voxel_neighbourhoods`;
    a cKDTree with the ties for the few points beyond the stencil); on other frames its k nearest
    by a cKDTree k-NN query, block by block in the tree's leaf order. The normal is the PCA normal
    of the neighbourhood (`_smallest_eigenvectors` of its covariance), the tangent axes those of
    `tangent_basis`; the gap is the largest between consecutive angles of the neighbours' offsets
    projected on the tangent plane, the direction the tangent vector in its middle.

    With ``interior_values=False`` the largest gap and the direction are computed only for the
    points whose neighbours leave a 45-degree sector empty (`_occupied_sectors`), NaN elsewhere;
    when ``gap`` >= pi / 2 those NaN points have no gap above 90 degrees, so the mask is exactly the
    same, and the work (arctan2 and sort of the angles) is done for a few percent of the points only.
    """
    largest, direction, _, _ = _boundary(points, k, gap, tree, interior_values)
    return largest > gap, largest, direction


def _boundary(points: np.ndarray, k: int, gap: float, tree: cKDTree | None, interior_values: bool,
              ninth_of: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, cKDTree | None, np.ndarray | None]:
    """`boundary_points`' largest gaps (N,) and directions (N, 3), the cKDTree if one was built or given,
    and, for the rows ``ninth_of`` (indices, k >= 9), their distances to the 9th nearest point (self
    included; what `point_spacing` takes the median of), from the same neighbourhoods; None when
    ``ninth_of`` is None or k < 9."""
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    prefilter = not interior_values and gap >= np.pi / 2
    largest = np.full(n, np.nan)
    direction = np.full((n, 3), np.nan)
    ninth = np.full(n, np.nan) if ninth_of is not None and k >= 9 else None
    wanted = np.zeros(n, dtype=bool)
    if ninth is not None:
        wanted[ninth_of] = True
    grid = _voxel_coordinates(points)
    with OneBlasThread():
        if grid is not None:
            leftover: list[np.ndarray] = []
            for rows, offsets, mask in _voxel_neighbourhoods(grid, k, leftover):
                largest[rows], direction[rows] = _neighbourhood_gaps(offsets, mask, prefilter)
                pick = wanted[rows]
                if pick.any():
                    assert ninth is not None  # rows are wanted only when the 9th distances are asked for
                    # the 9th occupied column (columns by distance; a group holds >= k >= 9 of them)
                    col = (mask[:, pick].cumsum(axis=0) >= 9).argmax(axis=0)
                    ninth[rows[pick]] = np.sqrt((offsets[col] ** 2).sum(axis=1))
            rest = np.sort(np.concatenate(leftover)) if leftover else np.zeros(0, dtype=np.intp)
        if grid is None or len(rest):
            tree = tree if tree is not None else cKDTree(points)
            if grid is None:
                rest = np.asarray(tree.indices, dtype=np.intp)  # leaf order
            _tree_boundary(points, rest, k, tree, grid is not None, prefilter, largest, direction, ninth, wanted)
    return largest, direction, tree, (None if ninth is None else ninth[ninth_of])


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
    # point_spacing's probe rows: their 9th-nearest distances come with the neighbourhoods (no second
    # search, no cKDTree at all for a voxel frame); the same value as point_spacing(points)
    probe_rows = probe_indices(len(points), _SPACING_SAMPLE, seed=0)
    largest, direction, tree, ninth = _boundary(points, int(k), gap, None, False, probe_rows)
    on_rim = largest > gap
    spacing = float(np.median(ninth)) / np.sqrt(2.0) if ninth is not None else point_spacing(points, tree)
    if not spacing > 0:  # as point_spacing refuses it
        raise UserError("detect_holes: the points are (almost all) duplicates: cannot estimate a point spacing")
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
