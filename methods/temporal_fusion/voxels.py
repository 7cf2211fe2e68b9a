"""Voxel geometry on integer (voxelized) data: which voxels a fitted surface crosses (the plane-cube test
|(c - p) . n| <= (|n_x| + |n_y| + |n_z|) / 2, the rule voxelized captures are made by), grown from a rim or read
off a copied surface, and snapping new points to the grid."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._front_fill import local_quadric
from dpcbench.methods._spatial_fill import _voxel_keys, far_from, unique_voxels
from dpcbench.methods.temporal_fusion.surface import mls_fit

#: most rim voxels the crossing bound is read from (with their free neighbours): a statistic of the rim,
#: so an evenly strided subset gives it at a fixed cost per hole
CALIBRATION_POINTS = 1000

#: how far the fused copies' candidate voxels (`surface_voxels`, stage fuse) may lie from the nearest copied point:
#: one voxel edge. The copies are another frame's voxels moved by a motion, each a cube that surface crossed there,
#: so a cube the copied surface crosses holds a copied point or is next to one; a cube farther off is one only the
#: quadric says the surface crosses, and where a misaligned copy sits in the fit's support the quadric is off there
#: (samba independent holes: every voxel 1.41-1.73 from the truth lay 1.03-1.71 from the nearest copied point, while
#: 98-100 % of the voxels on the truth lie within 1 of one). Only for the copies: the reused and partial points are
#: projected onto a fit first (stage settle), no longer captured voxels, and one edge there lost 14 dB D1 on human
#: occlusion holes (docs/temporal-fusion.md)
COPY_REACH = 1.0


def crossed_voxels(region: HoleRegion, support: np.ndarray, occupied: cKDTree, *, neighbours: int = 20,
                   front: float = float(np.sqrt(3.0)), max_rounds: int = 64, with_closed: bool = False):
    """Voxel fill of ``region`` on integer (voxelized) data by the data's own voxelization rule,
    grown from the rim inwards (stage rim_fill). Returns integer (P, 3) voxels, or
    (voxels, closed) with ``with_closed``: closed is True when the growth stopped by itself (a round
    accepted nothing, or no candidate was left within reach) before ``max_rounds``.

    Candidates: the integer points inside ``region`` that ``occupied`` (frame f's points and the
    new points so far) does not hold. Each round judges the candidates within ``front`` (sqrt 3:
    the 26 neighbours of a voxel) of the support (``support`` (K, 3), the rim, grown by every voxel
    accepted so far): the `mls_fit` quadric of a candidate c's ``neighbours`` nearest support points
    gives its foot point p and unit normal n, and c is accepted when that surface crosses c's
    unit cube, |(c - p) . n| <= (|n_x| + |n_y| + |n_z|) / 2 (the exact test for a plane and a cube;
    the rule by which voxelized captures and our stand-ins are made: one voxel per cube the surface
    passes through). Every candidate is judged once, in the round its first support point comes
    within reach, so the fill grows across the hole one voxel shell a round and stops where no
    judged voxel is crossed (the surface left the hole, or the fit no longer reaches it)."""
    support = np.asarray(support, dtype=np.float64)
    # candidates are generated round by round round the support points added last (at first, those within
    # reach of R), not listed over R's bounding cube: the cube is O(r^3) integer points (63 million for a
    # 199-voxel occlusion opening, 17 s a frame), the grown shells O(r^2). Same candidates, same rounds.
    judged_keys = np.zeros(0, dtype=np.int64)
    origin = np.floor(region.center - region.bounding_radius) - 3
    side = np.int64(np.ceil(2 * region.bounding_radius) + 7)
    fresh = support[region.contains(support, margin=front * (1 + 1e-9))]
    accepted: list[np.ndarray] = []
    closed = False
    for _ in range(int(max_rounds)):
        judged = _reachable_voxels(fresh, region, front)
        if len(judged):
            judged = judged[~np.isin(_voxel_keys(judged, origin, side), judged_keys, assume_unique=True)]
            judged = judged[far_from(judged, occupied, 0.5)] if len(judged) else judged
        if not len(judged) or len(support) < 6:
            closed = True
            break
        judged_keys = np.union1d(judged_keys, _voxel_keys(judged, origin, side))
        tree = cKDTree(support)
        foot, normal = mls_fit(judged, support, neighbours, tree)
        off = np.abs(np.einsum("ij,ij->i", judged - foot, normal))
        crossed = (off <= np.abs(normal).sum(axis=1) / 2.0) & (np.abs(normal).sum(axis=1) > 0)
        if not crossed.any():
            closed = True
            break
        fresh = judged[crossed]
        accepted.append(fresh)
        support = np.vstack([support, fresh])
    voxels = np.vstack(accepted) if accepted else np.zeros((0, 3))
    return (voxels, closed) if with_closed else voxels


def _reachable_voxels(points: np.ndarray, region: HoleRegion, reach: float) -> np.ndarray:
    """The integer points inside ``region`` within ``reach`` (at most sqrt 3) of a point of ``points``
    (P, 3), unique rows in lexicographic order: the integer points of the 5^3 block round each point's
    nearest voxel, kept by distance."""
    if not len(points):
        return np.zeros((0, 3))
    offsets = np.stack(np.meshgrid(*[np.arange(-2, 3)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    centres = unique_voxels(np.floor(points + 0.5))
    integer = bool(np.all(np.floor(points + 0.5) == points))
    if integer:  # a voxel's integer points within sqrt 3 are its 26 neighbours
        offsets = offsets[np.abs(offsets).max(axis=1) <= 1]
    cand = unique_voxels((centres[:, None, :] + offsets[None, :, :]).reshape(-1, 3))
    cand = cand[region.contains(cand)]
    if not integer and len(cand):
        cand = cand[~far_from(cand, cKDTree(points), reach * (1 + 1e-9))]
    return cand


def _free_neighbours(points: np.ndarray, occupied: cKDTree) -> np.ndarray:
    """The integer points within the 26-neighbourhood of the voxels of ``points`` (rounded) that
    ``occupied`` does not hold (none within 0.5), unique rows."""
    offsets = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    cand = unique_voxels((np.floor(points + 0.5)[:, None, :] + offsets[None, :, :]).reshape(-1, 3))
    return cand[far_from(cand, occupied, 0.5)] if len(cand) else cand


def crossing_offset(voxels: np.ndarray, support: np.ndarray, neighbours: int, tree: cKDTree | None = None
                    ) -> np.ndarray:
    """|(c - p) . n| / ((|n_x| + |n_y| + |n_z|) / 2) for each voxel c (V,), with p, n the `mls_fit` quadric's
    foot point and normal from its ``neighbours`` nearest ``support`` points: <= 1 exactly when that
    surface's tangent plane crosses c's unit cube (inf where there is no fit)."""
    foot, normal, _ = local_quadric(voxels, support, neighbours, tree)
    l1 = np.abs(normal).sum(axis=1)
    off = np.abs(np.einsum("ij,ij->i", voxels - foot, normal))
    return np.where(l1 > 0, 2.0 * off / np.where(l1 > 0, l1, 1.0), np.inf)


def rim_crossing_threshold(rim: np.ndarray, region: HoleRegion, local: np.ndarray, occupied: cKDTree,
                           neighbours: int) -> float:
    """The `crossing_offset` bound that best reproduces the capture's own voxelization on the rim of
    ``region``: ``rim`` (K, 3) frame f's voxels around the region, ``local`` (L, 3) frame f's points near
    it and ``occupied`` their k-d tree. Over the rim voxels (occupied) and the free voxels next to them
    outside the region, each judged by the quadric of its ``neighbours`` nearest ``local`` points, the
    bound t minimising (occupied with offset > t) + (free with offset <= t), midway to the next offset
    seen. Captures differ in how thickly they voxelize a surface (every cube it crosses, t = 1; the cubes
    their samples fall in, fewer where a cube is only clipped), so the rule is read from the frame
    itself, per hole. 1.0 without enough data."""
    free = _free_neighbours(rim, occupied) if len(rim) else np.zeros((0, 3))
    free = free[~region.contains(free)] if len(free) else free
    if len(rim) < 6 or not len(free) or len(local) < 6:
        return 1.0
    tree = cKDTree(local)
    occupied_off = np.sort(crossing_offset(rim, local, neighbours, tree))
    free_off = np.sort(crossing_offset(free, local, neighbours, tree))
    bounds = np.concatenate([occupied_off, free_off])
    bounds = np.unique(bounds[np.isfinite(bounds) & (bounds <= 2.0)])
    if not len(bounds):
        return 1.0
    errors = (len(occupied_off) - np.searchsorted(occupied_off, bounds, side="right")) + \
        np.searchsorted(free_off, bounds, side="right")
    best = int(np.argmin(errors))
    # midway to the next offset seen: the widest margin on both sides (the hole's voxels are judged by
    # other fits than the rim's, so a bound at the last occupied offset loses those just above it)
    return float((bounds[best] + bounds[best + 1]) / 2.0) if best + 1 < len(bounds) else float(bounds[best])


def surface_voxels(points: np.ndarray, region: HoleRegion, support: np.ndarray, occupied: cKDTree,
                   neighbours: int = 20, threshold: float = 1.0, count: int | None = None,
                   reach: float = float(np.sqrt(3.0))) -> np.ndarray:
    """The voxels of ``region`` that the surface through ``points`` (P, 3; sub-voxel positions, e.g. an
    aligned copy) passes through: candidates are the free integer points (farther than 0.5 from
    ``occupied``) inside ``region`` within ``reach`` of a point (sqrt 3: the 26-neighbourhood of its voxel;
    stage fuse passes `COPY_REACH`, one voxel edge), kept when their `crossing_offset` from the
    quadric of ``support`` is at most ``threshold`` (1: every cube the surface crosses); or, given ``count``,
    the ``count`` of them with the smallest offsets (ties kept). Returns integer (V, 3) voxels, sorted. Why:
    rounding each moved sample to its nearest voxel puts 7-19 % of them one voxel off the voxels the surface
    crosses (docs/temporal-fusion.md); re-voxelizing the copied surface follows the capture's rule."""
    points = np.asarray(points, dtype=np.float64)
    cand = _free_neighbours(points, occupied)
    cand = cand[region.contains(cand)] if len(cand) else cand
    if len(cand):
        cand = cand[~far_from(cand, cKDTree(points), reach * (1 + 1e-9))]
    if not len(cand):
        return np.zeros((0, 3))
    offsets = crossing_offset(cand, support, neighbours)
    if count is not None:
        if count <= 0:
            return np.zeros((0, 3))
        nth = min(count, len(offsets)) - 1
        threshold = float(np.partition(offsets, nth)[nth])
    return cand[offsets <= threshold]


def snap_to_voxels(points: np.ndarray, occupied: np.ndarray) -> np.ndarray:
    """``points`` rounded (half up) to the integer grid, one per voxel, minus the voxels in
    ``occupied`` (integer (N, 3)); sorted rows."""
    if len(points) == 0:
        return np.zeros((0, 3))
    voxels = unique_voxels(np.floor(np.asarray(points) + 0.5))
    if len(occupied):
        dist, _ = cKDTree(occupied).query(voxels, distance_upper_bound=0.5)
        voxels = voxels[~np.isfinite(dist)]
    return voxels


def rows_in(points: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(P,) bool: which rows of ``points`` (P, 3) occur exactly in ``table`` (T, 3)."""
    if len(points) == 0 or len(table) == 0:
        return np.zeros(len(points), dtype=bool)
    both = np.ascontiguousarray(np.vstack([points, table]), dtype=np.float64)
    _, code = np.unique(both, axis=0, return_inverse=True)
    code = code.ravel()
    return np.isin(code[:len(points)], code[len(points):])

