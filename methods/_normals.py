"""Normals for a method's output, so that an inpainted frame carries what its input carried.

The methods fill positions only. For frame f with input points P (N, 3), their unit normals
N_P (N, 3), and the method's output Q (N', 3):

1. **Kept points**: an output point equal to an input point (exact coordinates, the first such input
   row: `methods._colour.kept_index`) keeps that point's normal, unchanged.
2. **New points**: a PCA normal of the ``k`` output points nearest to it (`metrics.neighbours.
   estimate_normals`, the new point among them), so it follows the filled surface rather than the
   hole's rim; its sign is chosen to agree with the normal of the nearest input point
   (n . n_nearest >= 0), so a renderer that shades by normals, or D2, sees the same orientation on
   both sides of the hole's rim.

Kept points keep the input's normals rather than re-estimated ones because the input's may come from
the capture (a mesh, a scanner) and are the ones the ground truth carries: renders and D2 of the
ground truth and of the result then agree wherever the method kept the points.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.methods._colour import kept_index
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.neighbours import DEFAULT_NORMAL_NEIGHBOURS, estimate_normals


def output_normals(inputs: np.ndarray, normals: np.ndarray, outputs: np.ndarray,
                   k: int = DEFAULT_NORMAL_NEIGHBOURS) -> np.ndarray:
    """(N', 3) float64 unit normals of ``outputs`` (N', 3) from ``inputs`` (N, 3) and their ``normals``
    (N, 3), as the module docstring says. UserError when the shapes disagree or a normal is not finite."""
    inputs = np.asarray(inputs, dtype=np.float64)
    outputs = np.asarray(outputs, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != inputs.shape:
        raise UserError(f"normals of shape {normals.shape} for {len(inputs)} points; give one (nx, ny, nz) per point")
    if not np.isfinite(normals).all():
        raise UserError("the input's normals are not all finite; remove the NaN/inf normals or drop the normals")
    out = np.zeros((len(outputs), 3))
    kept = kept_index(inputs, outputs)
    out[kept >= 0] = normals[kept[kept >= 0]]
    new = np.flatnonzero(kept < 0)
    if len(new) == 0:
        return out
    if len(outputs) < 3 or len(inputs) == 0:
        raise UserError(f"cannot estimate normals for {len(new)} new points of a {len(outputs)}-point output "
                        "(a plane needs three points); drop the normals")
    estimated = estimate_normals(outputs, k, queries=outputs[new], tree=cKDTree(outputs))
    _, nearest = cKDTree(inputs).query(outputs[new], workers=-1)
    flip = np.einsum("ij,ij->i", estimated, normals[nearest]) < 0
    estimated[flip] *= -1.0
    out[new] = estimated
    return out
