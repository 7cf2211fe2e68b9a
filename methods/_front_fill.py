"""An advancing-front spatial fill for holes that no frame saw and that one surface over the whole hole
cannot describe (temporal-fusion's step 6b, the `Front` of `methods.temporal_fusion.spatial`; docs/temporal-fusion.md).

The hole is grown inwards from its rim one cell shell a round, on a cubic lattice of cell edge ``cell``
(one voxel on voxelized data, one point spacing s otherwise). A free lattice cell inside the region is
judged in the round its first trusted point (rim or accepted before) comes within sqrt 3 cells (the
26-neighbourhood): the moving-least-squares quadric of its ``neighbours`` nearest trusted points
(`local_quadric`) gives a foot point p, a unit normal n and the fit's weighted RMS residual e, and the
cell is accepted when

- the surface crosses the cell: |(c - p) . n| <= cell (|n_x| + |n_y| + |n_z|) / 2 (the exact test for
  a plane and a cube; the rule by which voxelized captures are made: one voxel per cube the surface
  passes through), and
- the fit is as consistent as the captured surface's own fits: e <= ``max_residual`` (the caller's
  rule: a high quantile of the same fit's residual at the captured rim points). Where two fronts
  meet at different heights, or a front folds onto itself, the k nearest trusted points form two
  layers and e grows: the cell is refused and the seam stays open rather than filled twice.

Each accepted cell becomes a point: the cell centre on voxelized data (the voxel), the foot point p
otherwise (on the surface, one point a crossed cell). Growth stops when a round accepts nothing (the
surface left the region, or the fits lost their consistency), or after ``max_rounds``.

Why a front and not one surface: a hole on a limb or round a fold is no height field over any one
plane (temporal-fusion's step 6 refuses it: its rim's normals turn by more than 60 degrees, or the
spline of the outer rim misses the inner rim by several spacings), but every cell of it is judged
from a chart of ~2.5 s across (the k nearest trusted points), which is a height field.

Written by hand: no library grows a surface from a point set's rim by a local fit (Open3D's and
MeshLab's hole closers work on meshes and close holes with flat triangles, off the curved surface).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the 27 offsets of a cell's 26-neighbourhood and itself
_OFFSETS = np.stack(np.meshgrid(*([np.arange(-1, 2)] * 3), indexing="ij"), axis=-1).reshape(-1, 3)
#: cell keys are packed into one int64: 21 bits an axis, offset so that negative indices fit
_BIAS = 1 << 20


def _keys(cells: np.ndarray) -> np.ndarray:
    c = cells.astype(np.int64) + _BIAS
    return (c[:, 0] << 42) | (c[:, 1] << 21) | c[:, 2]


def local_quadric(points: np.ndarray, support: np.ndarray, neighbours: int = 20,
                  support_tree: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The moving-least-squares quadric of each point's ``neighbours`` nearest ``support`` points:
    (foot (P, 3), unit normal (P, 3), weighted RMS residual (P,)).

    Per point: PCA frame (u, v, n) of the neighbours at their centroid; h(u, v) = c0 + c1 u + c2 v +
    c3 u^2 + c4 u v + c5 v^2 minimising sum_i w_i (h(u_i, v_i) - h_i)^2 with Gaussian weights
    w_i = exp(-d_i^2 / (2 b^2)), b the distance to the farthest neighbour / 2 (as temporal-fusion's
    `mls_fit`); foot = (u, v, h(u, v)) of the point; residual sqrt(sum w_i r_i^2 / sum w_i). Points
    with fewer than 6 support points get themselves, a zero normal and an infinite residual.

    The fit is solved in units of b (u / b, v / b, h / b), with a 1e-9 ridge on the normal equations:
    the same fit at any unit of length (a ridge in the data's own units would damp the quadratic terms of
    data in metres, whose moments of u^4 shrink with the fourth power of the unit, towards a plane)."""
    points = np.asarray(points, dtype=np.float64)
    support = np.asarray(support, dtype=np.float64)
    k = int(min(neighbours, len(support)))
    if len(points) == 0 or k < 6:
        return points.copy(), np.zeros_like(points), np.full(len(points), np.inf)
    tree = support_tree if support_tree is not None else cKDTree(support)
    dist, idx = tree.query(points, k=k)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    # Each coordinate is a contiguous (P, k) array and every sum a reduction over its rows: einsum over
    # (P, k, 3) and (P, k, 6) stacks took two thirds of this fit's time at 800k points (the design
    # matrix's stack and its normal equations), and BLAS matmul would make the sums' order depend on the
    # machine. The normal equations are assembled from the 15 weighted moments of u, v to degree 4.
    centre = np.empty((len(points), 3))
    spread = []
    for axis in range(3):
        coordinate = support[:, axis][idx]
        centre[:, axis] = coordinate.mean(axis=1)
        spread.append(coordinate - centre[:, axis, None])
    covariance = np.empty((len(points), 3, 3))
    for i in range(3):
        for j in range(i, 3):
            covariance[:, i, j] = covariance[:, j, i] = (spread[i] * spread[j]).sum(axis=1)
    axes = np.linalg.eigh(covariance)[1]
    normal, u_axis, v_axis = axes[:, :, 0], axes[:, :, 2], axes[:, :, 1]

    def along(direction):  # (P, k): each neighbour's coordinate along its point's direction
        return spread[0] * direction[:, 0, None] + spread[1] * direction[:, 1, None] + spread[2] * direction[:, 2, None]

    bandwidth = np.maximum(dist[:, -1] / 2.0, 1e-12)
    # in units of the bandwidth, so that the ridge below weighs the same at any unit of length
    unit = bandwidth[:, None]
    u, v, h = along(u_axis) / unit, along(v_axis) / unit, along(normal) / unit
    weight = np.exp(-(dist / unit) ** 2 / 2.0)
    # monomials u^a v^b by (a, b); the design's columns are 1, u, v, u^2, u v, v^2
    columns = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]
    powers = {(0, 0): np.ones_like(u), (1, 0): u, (0, 1): v}
    for degree in range(2, 5):
        for a in range(degree, -1, -1):
            b = degree - a
            powers[(a, b)] = powers[(a - 1, b)] * u if a else powers[(a, b - 1)] * v
    moment = {ab: (weight * power).sum(axis=1) for ab, power in powers.items()}
    lhs = np.empty((len(points), 6, 6))
    for i, (a1, b1) in enumerate(columns):
        for j, (a2, b2) in enumerate(columns):
            lhs[:, i, j] = moment[(a1 + a2, b1 + b2)]
    lhs += 1e-9 * np.eye(6)
    weighted_h = weight * h
    rhs = np.stack([(weighted_h * powers[ab]).sum(axis=1) for ab in columns], axis=1)
    coef = np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]

    def quadric(pu, pv):  # h(u, v) of each point's fit; pu, pv (P, ...) with trailing axes broadcast
        c = [coef[:, i].reshape((-1,) + (1,) * (np.ndim(pu) - 1)) for i in range(6)]
        return c[0] + c[1] * pu + c[2] * pv + c[3] * pu * pu + c[4] * pu * pv + c[5] * pv * pv

    misfit = quadric(u, v) - h
    residual = np.sqrt((weight * misfit * misfit).sum(axis=1) / weight.sum(axis=1)) * bandwidth
    offset = points - centre
    pu = np.einsum("pi,pi->p", offset, u_axis)
    pv = np.einsum("pi,pi->p", offset, v_axis)
    ph = quadric(pu / bandwidth, pv / bandwidth) * bandwidth
    foot = centre + pu[:, None] * u_axis + pv[:, None] * v_axis + ph[:, None] * normal
    finite = np.isfinite(foot).all(axis=1) & np.isfinite(residual)
    return (np.where(finite[:, None], foot, points), np.where(finite[:, None], normal, 0.0),
            np.where(finite, residual, np.inf))


def rim_residual_bound(rim: np.ndarray, neighbours: int = 20, quantile: float = 0.9) -> float:
    """The ``quantile`` of `local_quadric`'s residual at the ``rim`` (K, 3) points, each fitted to
    its own ``neighbours`` nearest rim points: how far captured samples of this surface scatter
    about the local fit (sampling noise, a voxel staircase). inf when the rim has fewer than 6 points."""
    if len(rim) < 6:
        return float("inf")
    _, _, residual = local_quadric(rim, rim, neighbours)
    return float(np.quantile(residual, quantile))


def front_fill(support: np.ndarray, region, occupied: cKDTree | None, cell: float, *, voxelized: bool,
               max_residual: float, neighbours: int = 20, max_rounds: int | None = None,
               free_distance: float | None = None) -> np.ndarray:
    """Advancing-front fill of ``region`` (module docstring): (P, 3) new points.

    support: (K, 3) trusted points around (and in) the hole: the rim and the copies, the front's start;
    occupied: a tree on every point already there (captured and new), whose cells are not filled again
    (a cell is free when no such point is within ``free_distance``, default cell / 2, of its centre); cell: the lattice edge (1 on
    voxelized data, whose lattice is the integer grid; else the point spacing, the lattice anchored at
    the region's centre); max_residual: the fit-consistency bound (same units as the points);
    max_rounds: default ceil(2 r / cell) + 1, r the region's bounding radius (a front that crosses the
    whole region takes that many rounds)."""
    support = np.asarray(support, dtype=np.float64)
    if len(support) < 6:
        return np.zeros((0, 3))
    origin = np.zeros(3) if voxelized else np.asarray(region.center, dtype=np.float64)
    rounds = int(np.ceil(2 * region.bounding_radius / cell)) + 1 if max_rounds is None else int(max_rounds)
    reach = float(np.sqrt(3.0)) * cell * (1 + 1e-9)
    free = cell / 2.0 if free_distance is None else float(free_distance)
    judged = np.zeros(0, dtype=np.int64)
    front = support[np.linalg.norm(support - region.center, axis=1) <= region.bounding_radius + reach]
    accepted: list[np.ndarray] = []
    for _ in range(rounds):
        if not len(front):
            break
        cells = np.unique(np.floor((front - origin) / cell + 0.5).astype(np.int64), axis=0)
        cells = np.unique((cells[:, None, :] + _OFFSETS[None, :, :]).reshape(-1, 3), axis=0)
        keys = _keys(cells)
        fresh = ~np.isin(keys, judged)
        cells, keys = cells[fresh], keys[fresh]
        centres = origin + cells * cell
        keep = region.contains(centres)
        if occupied is not None and occupied.n and keep.any():
            dist, _ = occupied.query(centres[keep], distance_upper_bound=free)
            keep[np.flatnonzero(keep)[np.isfinite(dist)]] = False
        tree = cKDTree(support)
        if keep.any():
            dist, _ = tree.query(centres[keep], distance_upper_bound=reach)
            keep[np.flatnonzero(keep)[~np.isfinite(dist)]] = False  # not yet within reach: judged later
        # judged once: cells outside the region or already occupied are settled for good too
        settled = ~region.contains(centres) | keep
        judged = np.union1d(judged, keys[settled])
        if not keep.any():
            break
        centres = centres[keep]
        foot, normal, residual = local_quadric(centres, support, neighbours, tree)
        off = np.abs(np.einsum("ij,ij->i", centres - foot, normal))
        extent = np.abs(normal).sum(axis=1)
        ok = (off <= cell * extent / 2.0) & (extent > 0) & (residual <= max_residual)
        if not ok.any():
            break
        new = centres[ok] if voxelized else foot[ok]
        accepted.append(new)
        support = np.vstack([support, new])
        front = new
    return np.vstack(accepted) if accepted else np.zeros((0, 3))


__all__ = ["front_fill", "local_quadric", "rim_residual_bound"]
