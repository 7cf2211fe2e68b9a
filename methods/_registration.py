"""Rigid "structure matching" of a complete source patch onto a partial target patch.

Closed-form Kabsch alignment on nearest-neighbour pairs, iterated (point-to-point ICP; Besl & McKay
1992, trimmed as in Chetverikov et al. 2002). Written with cKDTree rather than open3d's
``registration_icp`` because the pairs must go from the *partial* target (a cube with a hole) to
the *complete* source: every target point has a true counterpart in the source, but the source's
points that fill the hole have none in the target, so pairing source -> target (open3d's
direction) drags the source towards the hole's rim. Cubes hold a few hundred points, so the
per-call overhead of a small tree is what matters, not raw speed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


def kabsch(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R (3, 3) and translation t (3,) minimising sum_i ||R source_i + t - target_i||^2.

    source, target: (N, 3) paired rows. Closed form (Kabsch 1976): with centred rows X, Y and
    H = X^T Y = U S V^T, R = V diag(1, 1, det(V U^T)) U^T, t = mean(target) - R mean(source).
    With fewer than 3 pairs only the translation is estimated (R = I).
    """
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    # called ~10^4 times a frame on a few hundred rows, so numpy's per-call overheads are the cost: the sum
    # divided by the count is what ndarray.mean computes (same reduction, same division) without its wrapper
    mu_s = np.add.reduce(source, axis=0) / len(source)
    mu_t = np.add.reduce(target, axis=0) / len(target)
    if len(source) < 3:
        return np.eye(3), mu_t - mu_s
    h = (source - mu_s).T @ (target - mu_t)
    u, _, vt = np.linalg.svd(h)
    # det(V U^T) is +-1 (a product of orthogonal matrices), so its sign by cofactors is the sign LU gives
    (a, b, c), (e, f, g), (i, j, k) = (vt.T @ u.T).tolist()
    d = -1.0 if a * (f * k - g * j) - b * (e * k - g * i) + c * (e * j - f * i) < 0 else 1.0
    v = vt.T.copy()  # V diag(1, 1, d), C-ordered as the product V @ diag(1, 1, d) was
    v[:, 2] *= d
    rotation = v @ u.T
    return rotation, mu_t - rotation @ mu_s


def align_to_partial(source: np.ndarray, partial: np.ndarray, *, iterations: int = 10, trim: float = 0.9,
                     max_points: int = 256, source_tree: cKDTree | None = None,
                     start: tuple[np.ndarray, np.ndarray] | None = None, tol: float = 1e-4, unit: float = 1.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Rigid (R, t) that moves the complete ``source`` (S, 3) onto the ``partial`` target (T, 3).

    Each iteration pairs every target point q_j with its nearest source point under the current
    inverse transform, keeps the ``trim`` fraction of closest pairs (robust to the target's rim and
    to the source's extra surface), and solves `kabsch` for the pairs. ``start`` = (R, t) resumes
    from an earlier alignment. At most ``max_points`` target
    points are paired (an evenly spaced, deterministic subset of the rows): six unknowns need far
    fewer pairs than a cube holds. Starts from the identity
    (callers translate the source into place first). Stops early when the largest change of an entry of R
    plus that of t in units of ``unit`` (the data's unit of length: one voxel on voxelized data) is below ``tol``
    (1e-4: a hundredth of a percent of a voxel at 10 bits), so that data in metres stops where the same data in
    millimetres does.
    Returns (R, t) such that ``source @ R.T + t`` lies on the partial target.
    """
    rotation, translation = (np.eye(3), np.zeros(3)) if start is None else start
    if len(source) < 3 or len(partial) < 3 or iterations <= 0:
        return rotation, translation
    tree = source_tree if source_tree is not None else cKDTree(source)
    partial = np.asarray(partial, dtype=np.float64)
    if len(partial) > max_points:
        partial = partial[np.linspace(0, len(partial) - 1, max_points).astype(np.int64)]
    keep_count = max(3, int(np.ceil(trim * len(partial))))
    for _ in range(iterations):
        # target points expressed in the source's own frame: R^T (q - t)
        local = (partial - translation) @ rotation
        dist, idx = tree.query(local)
        if keep_count < len(partial):
            # the keep_count nearest pairs, ties taken by row and rows in order: np.argpartition's order
            # and its choice among tied distances depend on the CPU's SIMD kernel, and the sums in kabsch
            # (so the fit's last bits, and decisions downstream) depend on that order
            keep = np.sort(np.argsort(dist, kind="stable")[:keep_count])
            new_rotation, new_translation = kabsch(source[idx[keep]], partial[keep])
        else:
            new_rotation, new_translation = kabsch(source[idx], partial)
        change = np.abs(new_rotation - rotation).max() + np.abs(new_translation - translation).max() / unit
        rotation, translation = new_rotation, new_translation
        if change < tol:
            break
    return rotation, translation


def alignment_residual(source_tree: cKDTree, partial: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
                       trim: float = 0.9) -> float:
    """Trimmed mean distance from the ``partial`` points to the source moved by (R, t): the mean of
    the ``trim`` fraction of smallest nearest-neighbour distances (``source_tree`` is on the
    unmoved source)."""
    dist, _ = source_tree.query((np.asarray(partial) - translation) @ rotation)
    keep = max(1, int(np.ceil(trim * len(dist))))
    # sorted rather than partitioned: the partition's order (so the sum's last bits, and which candidate
    # wins a near tie in align_best) depends on the CPU's SIMD kernel
    return float(np.sort(dist)[:keep].mean())


@dataclass(frozen=True)
class RigidFit:
    """A source patch and the rigid motion that puts it on a partial target.

    source (S, 3): the points as given; tree: cKDTree on them; rotation (3, 3), translation (3,):
    ``source @ rotation.T + translation`` lies on the target; residual: `alignment_residual` of
    the target to the moved source (0.0 when not asked for).
    """

    source: np.ndarray
    tree: cKDTree
    rotation: np.ndarray
    translation: np.ndarray
    residual: float

    @property
    def aligned(self) -> np.ndarray:
        """The moved source (S, 3): R p + t for every source point p."""
        return self.source @ self.rotation.T + self.translation


def align_best(sources: Sequence[np.ndarray | None], partial: np.ndarray, *, iterations: int,
               screen_iterations: int = 3, residual: bool = True, unit: float = 1.0) -> RigidFit | None:
    """The candidate source patch that `align_to_partial` fits best onto ``partial`` (T, 3), aligned.

    sources: candidate patches (S_i, 3), already translated into place; None or fewer than 3
    points skip a candidate. One candidate: aligned with ``iterations`` ICP iterations. Several: each
    is screened by min(``screen_iterations``, ``iterations``) iterations, the smallest trimmed mean
    residual (`alignment_residual`) wins (the first on ties) and is refined by the remaining
    iterations, resuming from its screening alignment. ``residual``: compute the winner's final
    residual (else 0.0); ``unit``: `align_to_partial`'s. None when no candidate has 3 points.
    """
    single = len(sources) == 1
    screen = iterations if single else min(screen_iterations, iterations)
    best, best_residual = None, np.inf
    for source in sources:
        if source is None or len(source) < 3:
            continue
        tree = cKDTree(source)
        rotation, translation = align_to_partial(source, partial, iterations=screen, source_tree=tree, unit=unit)
        score = 0.0 if single else alignment_residual(tree, partial, rotation, translation)
        if score < best_residual:
            best, best_residual = (source, tree, rotation, translation), score
    if best is None:
        return None
    source, tree, rotation, translation = best
    if screen < iterations:
        rotation, translation = align_to_partial(source, partial, iterations=iterations - screen, source_tree=tree,
                                                 start=(rotation, translation), unit=unit)
    final = alignment_residual(tree, partial, rotation, translation) if residual else 0.0
    return RigidFit(source, tree, rotation, translation, final)
