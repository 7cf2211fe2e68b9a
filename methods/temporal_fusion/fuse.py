"""Stage fuse: the copies of the frames that saw all of R, fused best first, then (voxelized input) re-voxelized.

Candidates in order of rim residual (equal residuals: the nearer frame). The first contributes its points
farther than ``gap_spacings`` s from frame f's points (a partly emptied region is not filled twice). Each later
one contributes only its points farther than the shell from everything accepted so far (the parts the better
frames did not see, which are hole-sized, not sampling gaps), and of those only the ones grown from the rim and
the accepted points through the agreement rule (`grown_agreeing`: within ``accept_spacings`` s of the local plane
of their 8 nearest support points within 3 s; unreachable patches dropped).

Re-voxelization (``revoxelize``, voxelized input): the fused copies sit at sub-voxel positions after the motion,
so the copied surface is voxelized by the capture's rule (`voxels.surface_voxels`): the free voxels of R within
`COPY_REACH` of a copied point whose cube the MLS quadric of frame f's crop and the copies crosses; the fit pools
f-1's and f+1's copies where both were sources (``pool_adjacent``: one fit over several captures averages their
alignment errors), and keeps as many voxels as the copies hold (``count_copies``; else the crossing bound read from
R's rim, `rim_crossing_threshold`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill import even_subset, far_from, grown_agreeing
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.records import Candidate, Crop, Fused, SequenceData
from dpcbench.methods.temporal_fusion.voxels import (
    CALIBRATION_POINTS,
    COPY_REACH,
    rim_crossing_threshold,
    surface_voxels,
)


def fusion_order(candidates, spacing: float) -> list:
    """``candidates`` sorted by (rim residual in spacings to 2 decimals, |g - f|, g)."""
    return sorted(candidates, key=lambda c: (round(c[0] / spacing, 2), c[1], c[2]))


def fuse(cfg: FusionConfig, seq: SequenceData, region: HoleRegion, crop: Crop,
         candidates: tuple[Candidate, ...]) -> Fused:
    """The `Fused` copies of ``candidates`` in ``region``."""
    spacing = seq.spacing
    ordered = fusion_order(candidates, spacing)
    accepted = np.zeros((0, 3))
    for rank, (_, _, _, points) in enumerate(ordered):
        points = points[far_from(points, crop.tree, cfg.gap_spacings * spacing)]
        if rank and len(accepted):
            # only the parts the better frames did not see (hole-sized gaps, not their sampling),
            # and only where the points continue the surface of the rim and of what is accepted
            points = points[far_from(points, cKDTree(accepted), crop.shell)]
            points = points[grown_agreeing(points, np.vstack([crop.rim, accepted]), 3 * spacing,
                                           cfg.accept_spacings * spacing)]
        if len(points):
            accepted = np.vstack([accepted, points])
    full_copy = bool(len(accepted))
    if seq.voxelized and cfg.revoxelize and len(accepted):
        accepted = revoxelized(cfg, seq, region, crop, accepted, ordered)
    return Fused(accepted, full_copy, tuple(ordered))


def revoxelized(cfg: FusionConfig, seq: SequenceData, region: HoleRegion, crop: Crop, accepted: np.ndarray,
                ordered: list) -> np.ndarray:
    """The voxels (V, 3) of ``region`` the fused copies ``accepted`` (A, 3) pass through."""
    k = max(seq.neighbours, 6)
    bound = 1.0 if cfg.count_copies else \
        rim_crossing_threshold(even_subset(crop.rim, CALIBRATION_POINTS), region, crop.local, crop.tree, k)
    fit_support, copies = [crop.local, accepted], 1
    if cfg.pool_adjacent:
        # f-1's and f+1's copies when they were sources and not the one fused first: each is another
        # capture of R's surface aligned on its own, so one fit over all of them (k points a copy, the
        # same disc) averages their alignment errors; farther frames moved more and are left out
        for _, gap, _, points in ordered[1:]:
            points = points[far_from(points, crop.tree, cfg.gap_spacings * seq.spacing)] if gap == 1 else points[:0]
            if len(points):
                fit_support, copies = fit_support + [points], copies + 1
    # as many voxels as the copies hold: they are the same capture's voxelization of the same surface
    # (the rim's bound is read where frame f's own fit judges its own voxels; a fit through aligned
    # copies judges the hole's with a wider scatter, so the same bound keeps too few or too many)
    return surface_voxels(accepted, region, np.vstack(fit_support), crop.tree, k * copies, bound,
                          count=len(accepted) if cfg.count_copies else None, reach=COPY_REACH)
