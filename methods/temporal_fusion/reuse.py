"""Stage reuse: the previous frame's fill, and what frames with their own hole near R saw of it.

Previous fill (``reuse_previous``): the points frame f-1's result added (but its partial copies, caps and
membranes) are moved to frame f by f-1's motion (rigid, then the rim's displacement field) and fill the parts of
R the copies left open: farther than ``fill_gap_spacings`` s from the copies, and not off the rim's local plane
(points within 3 s of the rim and farther than ``accept_spacings`` s off it are dropped). They replace the spatial
fill there (the cascade fills only what is still open), so fills never pile up and a persistent hole keeps its
fill, moved with the body.

Partial copies (``partial_sources``): the frames that failed the coverage test only for their own hole near R
saw part of it. Best rim residual first, their points fill what is still open, through the agreement rule of
stage fuse with its tolerance widened by the copy's own rim residual (aligned on a rim its own hole cuts, the
copy sits up to that far off the rim's surface)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill import far_from, grown_agreeing
from dpcbench.methods.temporal_fusion.colours import masked, no_colour, stacked
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.fuse import fusion_order
from dpcbench.methods.temporal_fusion.motion import deformed
from dpcbench.methods.temporal_fusion.records import Alignments, Candidate, Crop, SequenceData
from dpcbench.methods.temporal_fusion.surface import disagreeing


def reuse_previous(cfg: FusionConfig, seq: SequenceData, f: int, region: HoleRegion, crop: Crop,
                   accepted: np.ndarray, previous_fill: np.ndarray, alignments: Alignments
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The points of ``previous_fill`` (M, 3; frame f-1's reusable fill) moved to frame f that fill what the copies
    ``accepted`` (A, 3) leave open in ``region``: (moved points (P, 3), their rows in ``previous_fill`` (P,)), so
    each carries its previous-frame colour."""
    spacing = seq.spacing
    carrying = alignments.motions.get(f - 1, alignments.carried)
    rows = np.zeros(0, dtype=np.intp)
    if not (cfg.reuse_previous and len(previous_fill) and carrying is not None):
        return np.zeros((0, 3)), rows
    rotation, translation, field = carrying
    moved = previous_fill @ rotation.T + translation
    rows = np.flatnonzero(region.contains(moved))
    moved = deformed(moved[rows], field, cfg.deform_neighbours)
    keep = far_from(moved, crop.tree, cfg.gap_spacings * spacing)
    if len(accepted):
        keep &= far_from(moved, cKDTree(accepted), cfg.fill_gap_spacings * spacing)
    moved, rows = moved[keep], rows[keep]
    # the moved fill must still fit the rim: points off the rim's local plane are dropped
    # (what they covered is filled afresh below)
    keep = ~disagreeing(moved, crop.rim, 3 * spacing, cfg.accept_spacings * spacing)
    return moved[keep], rows[keep]


def partial_copies(cfg: FusionConfig, seq: SequenceData, crop: Crop, accepted: np.ndarray,
                   partial: tuple[Candidate, ...]) -> tuple[np.ndarray, np.ndarray | None]:
    """The points (P, 3) of the partial copies that fill what ``accepted`` (A, 3) leaves open, and their colours
    (P, 3; None without colour)."""
    spacing = seq.spacing
    seen = np.zeros((0, 3))
    seen_colours = None if seq.colours is None else no_colour(0)
    for candidate in fusion_order(partial, spacing):
        points, colours = candidate.points, candidate.colours
        keep = far_from(points, crop.tree, cfg.gap_spacings * spacing)
        known = np.vstack([accepted, seen])
        if len(known):
            keep &= far_from(points, cKDTree(known), cfg.fill_gap_spacings * spacing)
        points, colours = points[keep], masked(colours, keep)
        # the agreement rule, widened by this copy's own misfit at the rim (its points near the rim sit
        # that far off the rim's surface however well the rest of it fits)
        keep = grown_agreeing(points, np.vstack([crop.rim, known]), 3 * spacing,
                              cfg.accept_spacings * spacing + candidate.residual)
        if keep.any():
            seen_colours = stacked([seen_colours, masked(colours, keep)], [len(seen), int(keep.sum())])
            seen = np.vstack([seen, points[keep]])
    return seen, seen_colours
