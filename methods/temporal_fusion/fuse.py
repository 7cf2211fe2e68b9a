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
from dpcbench.methods.temporal_fusion.colours import masked, no_colour, pooled, stacked
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
    """The `Fused` copies of ``candidates`` in ``region``, with their colours (each copied point its source point's;
    a re-voxelized voxel the mean of the copies within `COPY_REACH` of it, `pooled`, f-1's and f+1's pooled as
    the fit pools them)."""
    spacing = seq.spacing
    ordered = fusion_order(candidates, spacing)
    accepted = np.zeros((0, 3))
    accepted_colours = None if seq.colours is None else no_colour(0)
    pooled_rows = np.zeros(0, dtype=bool)  # accepted rows of a copy that the re-voxelization pools whole
    for rank, candidate in enumerate(ordered):
        points, colours = candidate.points, candidate.colours
        keep = far_from(points, crop.tree, cfg.gap_spacings * spacing)
        points, colours = points[keep], masked(colours, keep)
        if rank and len(accepted):
            # only the parts the better frames did not see (hole-sized gaps, not their sampling),
            # and only where the points continue the surface of the rim and of what is accepted
            keep = far_from(points, cKDTree(accepted), crop.shell)
            points, colours = points[keep], masked(colours, keep)
            keep = grown_agreeing(points, np.vstack([crop.rim, accepted]), 3 * spacing, cfg.accept_spacings * spacing)
            points, colours = points[keep], masked(colours, keep)
        if len(points):
            accepted = np.vstack([accepted, points])
            accepted_colours = stacked([accepted_colours, colours], [len(accepted) - len(points), len(points)])
            whole = rank > 0 and candidate.gap == 1 and cfg.pool_adjacent
            pooled_rows = np.concatenate([pooled_rows, np.full(len(points), whole)])
    full_copy = bool(len(accepted))
    if seq.voxelized and cfg.revoxelize and len(accepted):
        voxels = revoxelized(cfg, seq, region, crop, accepted, ordered)
        if accepted_colours is not None:
            # each copied point once: the pooled copies whole, and the rows accepted of the others
            pool = [(accepted[~pooled_rows], masked(accepted_colours, ~pooled_rows))]
            pool += adjacent_copies(cfg, seq, crop, ordered)
            accepted_colours = pooled(np.vstack([p for p, _ in pool]), stacked([c for _, c in pool],
                                      [len(p) for p, _ in pool]), voxels, COPY_REACH)
        accepted = voxels
    return Fused(accepted, full_copy, tuple(ordered), accepted_colours)


def adjacent_copies(cfg: FusionConfig, seq: SequenceData, crop: Crop, ordered: list
                    ) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """(points, colours) of the copies of f-1 and f+1 that the re-voxelization pools beside the first (``pool_adjacent``:
    the candidates after the first one fused whose gap is 1, their points farther than ``gap_spacings`` s from frame
    f's crop); empty without ``pool_adjacent``."""
    if not cfg.pool_adjacent:
        return []
    pool = []
    for candidate in ordered[1:]:
        if candidate.gap != 1:
            continue
        keep = far_from(candidate.points, crop.tree, cfg.gap_spacings * seq.spacing)
        if keep.any():
            pool.append((candidate.points[keep], masked(candidate.colours, keep)))
    return pool


def revoxelized(cfg: FusionConfig, seq: SequenceData, region: HoleRegion, crop: Crop, accepted: np.ndarray,
                ordered: list) -> np.ndarray:
    """The voxels (V, 3) of ``region`` the fused copies ``accepted`` (A, 3) pass through."""
    k = max(seq.neighbours, 6)
    bound = 1.0 if cfg.count_copies else \
        rim_crossing_threshold(even_subset(crop.rim, CALIBRATION_POINTS), region, crop.local, crop.tree, k)
    # f-1's and f+1's copies when they were sources and not the one fused first (``pool_adjacent``): each is
    # another capture of R's surface aligned on its own, so one fit over all of them (k points a copy, the same
    # disc) averages their alignment errors; farther frames moved more and are left out
    pool = [points for points, _ in adjacent_copies(cfg, seq, crop, ordered)]
    fit_support, copies = [crop.local, accepted, *pool], 1 + len(pool)
    # as many voxels as the copies hold: they are the same capture's voxelization of the same surface
    # (the rim's bound is read where frame f's own fit judges its own voxels; a fit through aligned
    # copies judges the hole's with a wider scatter, so the same bound keeps too few or too many)
    return surface_voxels(accepted, region, np.vstack(fit_support), crop.tree, k * copies, bound,
                          count=len(accepted) if cfg.count_copies else None, reach=COPY_REACH)
