"""Point-to-plane ICP on numpy and cKDTree, repeatable bit for bit.

Used by temporal-fusion's refinement (step 2a). Its own module (not `_registration`, whose
point-to-point `align_to_partial` serves temporal-graph and fu-nonlocal) so that those methods' recorded
source is untouched.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def euler_update(x: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) of a point-to-plane step x = (alpha, beta, gamma, ...): Rz(gamma) Ry(beta) Rx(alpha),
    the parametrisation of open3d's point-to-plane estimation (so a step means what it means there)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("ZYX", [x[2], x[1], x[0]]).as_matrix()


def point_to_plane_icp(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray, max_distance: float,
                       init: tuple[np.ndarray, np.ndarray], *, iterations: int = 30, target_tree: cKDTree | None = None,
                       min_pairs: int = 6, relative_fitness: float = 1e-9, relative_rmse: float = 1e-9
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Rigid (R, t) refining ``init`` by point-to-plane ICP (Chen & Medioni 1992, linearised as in Low 2004).

    source (S, 3), target (T, 3), target_normals (T, 3) unit. Pairs: each moved source point p_i = R s_i + t
    with its nearest target point q_i, kept when |p_i - q_i| < ``max_distance``. Each iteration solves the
    linearised least squares min_x sum_i (J_i x + r_i)^2, r_i = (p_i - q_i) . n_i, J_i = (p_i x n_i, n_i),
    x = (alpha, beta, gamma, t_x, t_y, t_z), and left-multiplies the motion by
    (Rz(gamma) Ry(beta) Rx(alpha), (t_x, t_y, t_z)) (`euler_update`). Stops after ``iterations`` steps or
    when fitness (paired fraction of the source) and RMSE of the pair distances both change by less than
    ``relative_fitness`` / ``relative_rmse``. Returns ``init`` when fewer than ``min_pairs`` pairs are in
    reach at the end, or the normal equations are singular at the first step.

    Written here rather than calling open3d's ``registration_icp``: open3d (0.20) sums the normal
    equations in a thread-parallel reduction whose order varies from call to call, so two calls on the
    same input gave transforms that differ in the last bits, and temporal-fusion's fill changed from run
    to run (a pair within ``max_distance`` or a voxel's rounding flips). Here every sum is a numpy
    reduction in a fixed order: repeated calls are bitwise equal.
    """
    rotation = np.asarray(init[0], dtype=np.float64)
    translation = np.asarray(init[1], dtype=np.float64)
    source = np.asarray(source, dtype=np.float64)
    if len(source) < min_pairs or len(target) < min_pairs or iterations <= 0:
        return rotation, translation
    tree = target_tree if target_tree is not None else cKDTree(target)

    def pairs(rot, trans):
        moved = source @ rot.T + trans
        dist, idx = tree.query(moved, distance_upper_bound=max_distance)
        found = np.isfinite(dist)
        dist = dist[found]
        rmse = float(np.sqrt(np.mean(dist * dist))) if len(dist) else 0.0
        return moved[found], idx[found], len(dist) / len(source), rmse

    start = rotation, translation
    moved, idx, fitness, rmse = pairs(rotation, translation)
    for _ in range(int(iterations)):
        if len(idx) < min_pairs:
            break
        normal = target_normals[idx]
        residual = np.einsum("ij,ij->i", moved - target[idx], normal)
        jacobian = np.hstack([np.cross(moved, normal), normal])  # (P, 6)
        # einsum, not BLAS: a fixed summation order whatever the thread count
        jtj = np.einsum("pa,pb->ab", jacobian, jacobian)
        jtr = np.einsum("pa,p->a", jacobian, residual)
        try:
            step = np.linalg.solve(jtj, -jtr)
        except np.linalg.LinAlgError:
            break  # the pairs do not pin the motion down (e.g. all on one line): keep what we have
        update = euler_update(step)
        rotation, translation = update @ rotation, update @ translation + step[3:]
        last_fitness, last_rmse = fitness, rmse
        moved, idx, fitness, rmse = pairs(rotation, translation)
        if abs(last_fitness - fitness) < relative_fitness and abs(last_rmse - rmse) < relative_rmse:
            break
    if len(idx) < min_pairs:
        return start
    return rotation, translation
