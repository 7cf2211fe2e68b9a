"""`QuadricFill`: each hole region is filled from its own rim by a least-squares quadric patch.

For one region of a frame (points P, median nearest-neighbour spacing s):

1. rim: the points of P within ``rim_spacings * s`` of the region (inside the region grown by that
   margin; a region that still holds captured points keeps them in its rim);
2. frame: the rim's centroid c and its principal axes (PCA): tangents t1, t2 and normal n (the axis
   of least variance);
3. surface: in local coordinates (u, v, w) = ((p - c).t1, (p - c).t2, (p - c).n), the least-squares
   quadric w = a0 + a1 u + a2 v + a3 u^2 + a4 uv + a5 v^2 through the rim;
4. samples: a square grid of step s over the rim's (u, v) bounding box, lifted onto the quadric,
   kept where it lies inside the region and farther than ``gap_spacings * s`` from every point of P.

A region whose rim has fewer than ``min_rim_points`` points, or whose rim is degenerate (all on a
line), is left as it is. Frames are filled independently: no temporal information is used. The
fill is deterministic (no randomness).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.base import PerFrameMethod
from dpcbench.metrics.errors import UserError


class QuadricFill(PerFrameMethod):
    name = "quadric-fill"
    summary = "fills each hole region from its rim with a least-squares quadric patch sampled at the frame's spacing"
    # Declared: stored results are keyed by it, so bump it when a change alters the output. (Without
    # it, dpcbench keys them by the sha256 of this module's source.)
    version = "1"
    needs_regions = True

    def __init__(self, rim_spacings: float = 3.0, gap_spacings: float = 0.5, min_rim_points: int = 12):
        self.rim_spacings = rim_spacings
        self.gap_spacings = gap_spacings
        self.min_rim_points = min_rim_points

    def _validate(self) -> None:
        if not self.rim_spacings > 0:
            raise UserError(f"quadric-fill: rim_spacings must be > 0, got {self.rim_spacings}")
        if not self.gap_spacings >= 0:
            raise UserError(f"quadric-fill: gap_spacings must be >= 0, got {self.gap_spacings}")
        if int(self.min_rim_points) < 6:
            raise UserError(f"quadric-fill: min_rim_points must be >= 6 (a quadric has 6 coefficients), "
                             f"got {self.min_rim_points}")

    def inpaint_frame(self, points: np.ndarray, regions: Sequence[HoleRegion] | None) -> np.ndarray:
        self._validate()
        if not regions or len(points) < 2:
            return points.copy()
        tree = cKDTree(points)
        spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
        if not spacing > 0:
            return points.copy()
        new = [self.fill_region(points, tree, region, spacing) for region in regions]
        return np.vstack([points, *new])

    def fill_region(self, points: np.ndarray, tree: cKDTree, region: HoleRegion, spacing: float) -> np.ndarray:
        """The new points (K, 3) of one region (K may be 0), by steps 1-4 of the module docstring."""
        empty = np.zeros((0, 3))
        near = tree.query_ball_point(region.center, region.bounding_radius + self.rim_spacings * spacing)
        candidates = points[np.asarray(near, dtype=np.int64)]
        rim = candidates[region.contains(candidates, self.rim_spacings * spacing)] if len(candidates) else empty
        if len(rim) < max(6, int(self.min_rim_points)):
            return empty
        centre = rim.mean(axis=0)
        _, singular, axes = np.linalg.svd(rim - centre, full_matrices=False)
        if singular[1] <= 1e-9 * max(singular[0], 1e-300):  # the rim lies on a line: no surface to fit
            return empty
        local = (rim - centre) @ axes.T  # columns u, v, w
        u, v, w = local[:, 0], local[:, 1], local[:, 2]
        design = np.column_stack([np.ones_like(u), u, v, u * u, u * v, v * v])
        coef = np.linalg.lstsq(design, w, rcond=None)[0]
        gu = np.arange(u.min(), u.max() + spacing / 2, spacing)
        gv = np.arange(v.min(), v.max() + spacing / 2, spacing)
        uu, vv = (a.ravel() for a in np.meshgrid(gu, gv, indexing="ij"))
        ww = np.column_stack([np.ones_like(uu), uu, vv, uu * uu, uu * vv, vv * vv]) @ coef
        samples = centre + np.column_stack([uu, vv, ww]) @ axes
        samples = samples[region.contains(samples)]
        if len(samples) and self.gap_spacings > 0:
            distance = tree.query(samples, k=1)[0]
            samples = samples[distance > self.gap_spacings * spacing]
        return samples
