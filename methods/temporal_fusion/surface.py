"""Local surface fits: the moving-least-squares quadric of a point's nearest support points, and the test of
points against the local plane of accepted ones."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.methods._front_fill import local_quadric
from dpcbench.methods._spatial_fill import plane_offsets


def mls_project(points: np.ndarray, support: np.ndarray, neighbours: int = 20,
                support_tree: cKDTree | None = None) -> np.ndarray:
    """``points`` (P, 3) moved onto the moving-least-squares quadric of their ``neighbours`` nearest
    ``support`` points (stage settle). Points with fewer than 6 support points
    near are returned unchanged."""
    return mls_fit(points, support, neighbours, support_tree)[0]


def mls_fit(points: np.ndarray, support: np.ndarray, neighbours: int = 20,
            support_tree: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`mls_project` with the fit's unit normals: (projected (P, 3), normal (P, 3), the PCA normal of
    each point's support neighbourhood; zero where the point is returned unchanged)."""
    foot, normal, _ = local_quadric(points, support, neighbours, support_tree)
    return foot, normal


def disagreeing(points: np.ndarray, accepted: np.ndarray, reach: float, tolerance: float) -> np.ndarray:
    """Mask (P,) of ``points`` that lie farther than ``tolerance`` off the PCA plane of their (up to)
    8 nearest ``accepted`` points within ``reach`` (points with fewer than 3 such are not judged)."""
    judged, off = plane_offsets(points, accepted, reach)
    return judged & (off > tolerance)

