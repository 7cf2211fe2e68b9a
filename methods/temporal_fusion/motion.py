"""Motion between frames: point-to-plane refinement of a rigid alignment, the rim's residual after it, and the
rim's normal displacement field carried into the hole (Shepard interpolation)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._point_to_plane import point_to_plane_icp
from dpcbench.methods._registration import alignment_residual
from dpcbench.metrics.neighbours import estimate_normals


def seen_rim_residual(source_tree: cKDTree, rim: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
                      source_holes: Sequence[HoleRegion]) -> float:
    """`alignment_residual` of ``rim`` (K, 3) to the source moved by (R, t), over the rim points whose
    place in the source's frame, (q - t) R, lies in none of ``source_holes`` (the source frame's own hole
    regions, in its coordinates): a rim point where the source has a hole has no counterpart there, and
    its distance measures the hole, not the alignment. inf when fewer than 6 rim points are left."""
    back = (np.asarray(rim) - translation) @ rotation
    seen = np.ones(len(back), dtype=bool)
    for hole in source_holes:
        seen &= ~hole.contains(back)
    if seen.sum() < 6:
        return float("inf")
    return alignment_residual(source_tree, rim[seen], rotation, translation)


def rim_displacement(rim: np.ndarray, moved_source: np.ndarray, max_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """Normal residual of the rim after a rigid alignment: (rim points kept (K, 3), v (K, 3)).

    Each rim point q pairs with its nearest ``moved_source`` point p; pairs longer than
    ``max_distance`` (the source has a hole there) are dropped. v_q = ((q - p) . n_p) n_p, n_p the
    PCA normal of p's 10 nearest source points: the part of the misfit that bends the surface (the
    tangential part is only the two samplings' offset)."""
    if len(rim) == 0 or len(moved_source) < 3:
        return np.zeros((0, 3)), np.zeros((0, 3))
    tree = cKDTree(moved_source)
    dist, idx = tree.query(rim)
    keep = dist <= max_distance
    if not keep.any():
        return np.zeros((0, 3)), np.zeros((0, 3))
    p = moved_source[idx[keep]]
    n = estimate_normals(moved_source, 10, queries=p, tree=tree)
    offset = np.einsum("ij,ij->i", rim[keep] - p, n)
    return rim[keep], offset[:, None] * n


def interpolate_displacement(points: np.ndarray, anchors: np.ndarray, displacement: np.ndarray,
                             neighbours: int = 32) -> np.ndarray:
    """Shepard interpolation (P, 3) of the ``displacement`` (K, 3) given at ``anchors`` (K, 3) to
    ``points`` (P, 3): sum_i w_i v_i / sum_i w_i over the ``neighbours`` nearest anchors,
    w_i = 1 / max(d_i, 1e-12)^2. Zero when there is no anchor."""
    if len(anchors) == 0 or len(points) == 0:
        return np.zeros((len(points), 3))
    k = int(min(neighbours, len(anchors)))
    dist, idx = cKDTree(anchors).query(points, k=k)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    weight = 1.0 / np.maximum(dist, 1e-12) ** 2
    return np.einsum("pk,pki->pi", weight, displacement[idx]) / weight.sum(axis=1, keepdims=True)


@dataclass(frozen=True)
class PlaneTarget:
    """A point-to-plane ICP target: points (T, 3), their unit normals (T, 3) (PCA of each point's 16
    nearest target points, arbitrary sign) and a cKDTree on the points."""

    points: np.ndarray
    normals: np.ndarray
    tree: cKDTree


def plane_target(target: np.ndarray) -> PlaneTarget:
    """The `PlaneTarget` of ``target`` (T, 3) that `refine_point_to_plane` pairs against: built once and
    reused for every source aligned to the same target. Normals by open3d's KNN estimate (each point's
    normal computed on its own, so it is repeatable; its neighbour choice among equidistant voxels is
    the one the defaults were measured with; `estimate_normals`' cKDTree neighbours lost 0.7 dB D1 on the human,
    docs/temporal-fusion.md)."""
    import open3d as o3d

    points = np.asarray(target, dtype=np.float64)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(16))
    return PlaneTarget(points, np.asarray(cloud.normals).copy(), cKDTree(points))


def refine_point_to_plane(source: np.ndarray, target: np.ndarray, max_distance: float,
                          init: tuple[np.ndarray, np.ndarray], iterations: int = 30,
                          target_cloud: PlaneTarget | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rigid (R, t) refining ``init`` by point-to-plane ICP (`_point_to_plane.point_to_plane_icp`):
    minimises sum_i ((R s_i + t - q_i) . n_i)^2 over the pairs (source s_i, nearest target q_i) closer
    than ``max_distance``, n_i the PCA normal of q_i's 16 nearest target points. Returns ``init`` when
    fewer than 6 pairs are in reach. ``target_cloud``: `plane_target` of ``target`` (reused).
    Deterministic: repeated calls give bitwise equal transforms."""
    rotation, translation = init
    if len(source) < 6 or len(target) < 16 or iterations <= 0:
        return rotation, translation
    if target_cloud is None:
        target_cloud = plane_target(target)
    return point_to_plane_icp(source, target_cloud.points, target_cloud.normals, max_distance, (rotation, translation),
                              iterations=int(iterations), target_tree=target_cloud.tree)


def deformed(points: np.ndarray, field: tuple[np.ndarray, np.ndarray] | None, neighbours: int) -> np.ndarray:
    """``points`` (P, 3) moved by the displacement ``field`` (anchors, displacement) interpolated over the
    ``neighbours`` nearest anchors (`interpolate_displacement`); unchanged without a field."""
    if field is None or len(field[0]) == 0 or len(points) == 0:
        return points
    anchors, displacement = field
    return points + interpolate_displacement(points, anchors, displacement, int(neighbours))
