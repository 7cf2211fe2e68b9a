"""Geometry shared by several methods (below every method module, so that no method imports another):
the areal sampling step of a frame, rigid point-to-point ICP, and the blind protocol's hole regions."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.neighbours import point_spacing


def sampling_step(points: np.ndarray, sample: int = 2000, radius_spacings: float = 4.0) -> float:
    """Grid step s (same units as ``points`` (N, 3)) that reproduces the frame's areal density:
    s = 1 / sqrt(rho), rho = median over ~``sample`` probe points (even stride) of
    #{neighbours within r} / (pi r^2), r = ``radius_spacings`` * `metrics.neighbours.point_spacing`.

    Counting in a ball a few spacings wide is right for any sampling pattern: it gives s = 1.01 on a
    unit voxel grid, where nearest-neighbour spacings are exact, and 2.82 (not 3.14 as the 8-NN
    spacing) on dfaust_50004_punching, whose points are not evenly spread.
    """
    tree = cKDTree(points)
    radius = radius_spacings * point_spacing(points, tree=tree)
    probe = points[:: max(1, len(points) // sample)]
    counts = tree.query_ball_point(probe, radius, return_length=True, workers=-1)
    density = float(np.median(counts)) / (np.pi * radius ** 2)
    return 1.0 / np.sqrt(density)


def icp_align(source: np.ndarray, target: np.ndarray, max_distance: float, *,
              max_iterations: int = 30, min_points: int = 6,
              init: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rigid (R, t) moving ``source`` (S, 3) onto ``target`` (T, 3), so that R @ s + t lies on it.

    open3d's ``registration_icp`` with point-to-point error: sum_i ||R s_i + t - q_i||^2 over the
    pairs (s_i, nearest target point q_i) closer than ``max_distance``. Point-to-point, not
    point-to-plane, by measurement: 24 random ball holes (radius 25/40/60) in
    dfaust_50004_punching (spacing 1.35) copied from a neighbour frame, mean distance from the
    true points to the fill: no alignment 3.21, point-to-point 0.88, point-to-plane 0.98; with the
    3 shell re-selection rounds of `TemporalCopy` point-to-point 0.78 (a one-off measurement whose
    script was not kept). Starts from the identity (consecutive frames); returns the identity when
    either cloud has fewer than ``min_points`` points, ``max_iterations`` is 0, or fewer than
    ``min_points`` pairs were within ``max_distance``. Deterministic (checked: repeated calls give
    bitwise equal transforms).
    """
    rotation, translation = (np.eye(3), np.zeros(3)) if init is None else (np.asarray(init[0]), np.asarray(init[1]))
    if len(source) < min_points or len(target) < min_points or max_iterations <= 0:
        return rotation, translation
    import open3d as o3d  # lazily: only the methods that align need it

    reg = o3d.pipelines.registration
    init_transform = np.eye(4)
    init_transform[:3, :3], init_transform[:3, 3] = rotation, translation
    source_cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(source))
    target_cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(target))
    result = reg.registration_icp(
        source_cloud, target_cloud, float(max_distance), init_transform,
        reg.TransformationEstimationPointToPoint(),
        reg.ICPConvergenceCriteria(relative_fitness=1e-9, relative_rmse=1e-9, max_iteration=int(max_iterations)),
    )
    transform = np.asarray(result.transformation)
    if len(result.correspondence_set) < min_points:
        return rotation, translation  # nothing within reach: keep the starting motion
    return transform[:3, :3].copy(), transform[:3, 3].copy()


def detect_regions(frames: Sequence[np.ndarray], method: str) -> list[list[HoleRegion]]:
    """Blind protocol: hole regions of every frame from `holes.detection.detect_holes`."""
    from dpcbench.holes.detection import detect_holes

    return [list(detect_holes(frame)) for frame in frames]


__all__ = ["detect_regions", "icp_align", "sampling_step"]
