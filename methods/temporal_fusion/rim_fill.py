"""Stage rim fill (voxelized input, ``rim_fill``): a thin gap closed from frame f's own rim.

The gap is grown from the rim by the voxelization rule (`voxels.crossed_voxels`: a free voxel within sqrt 3 of the
support is accepted when the MLS quadric of its k nearest support points crosses its unit cube). When the growth
closes within ceil(sqrt(k / pi)) rounds (one fit radius: every new voxel lies within it of captured points), the
gap is thin and the growth is R's whole fill; otherwise it is discarded and the later stages fill R. Why: thin
gaps no camera saw (armpits, soles) sit between captured points a voxel or two apart, where a moved copy of a
neighbouring frame lies up to a voxel off.

A copy beats the growth where it predicts the captured surface better (`copy_beats_growth`): then the thin gap is
filled like any other hole, from the copies. Each is judged on captured points it was not made from: the copy by
its rim residual (its shape comes from another frame; the rim fixes only its six degrees of motion), the growth by
a hold-out, grown again from the crop without the captured points within one fit radius of R (the distance its
own fill reaches) and scored on those. Where frames differ by less than a voxel round R (a still part of the body,
a capture coarse enough that the motion between two frames is under a voxel, or noisy enough that a fit smooths
what a copy keeps), the copy is the closer one. Measured: MVUB ricardo9 at 7 bits (a medium hole of radius 2.7
spacings, closed by the growth), independent holes, seeds 0-1: with the growth alone, temporal-fusion scored 7.7 dB
of D1 below temporal-copy (docs/temporal-fusion.md, "Version 55")."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._registration import alignment_residual
from dpcbench.methods.temporal_fusion.config import FusionConfig, rim_fill_rounds
from dpcbench.methods.temporal_fusion.records import Alignments, Crop, SequenceData
from dpcbench.methods.temporal_fusion.voxels import crossed_voxels


def rim_fill(cfg: FusionConfig, seq: SequenceData, region: HoleRegion, crop: Crop) -> np.ndarray | None:
    """Integer voxels (P, 3) filling ``region`` from the crop's rim when the growth closes; None when the stage
    is off, the input is not voxelized, or the gap is not thin."""
    if not (seq.voxelized and cfg.rim_fill):
        return None
    thin, closed = crossed_voxels(region, crop.local, crop.tree, neighbours=max(seq.neighbours, 6),
                                  max_rounds=rim_fill_rounds(seq.neighbours), with_closed=True)
    return thin if closed else None


def copy_beats_growth(seq: SequenceData, region: HoleRegion, crop: Crop, alignments: Alignments) -> bool:
    """Whether a full copy (a frame that saw all of R, `Alignments.candidates`) predicts the captured surface round R
    better than the rim fill's growth: its rim residual (`Candidate.residual`, the trimmed mean distance from the
    rim's points to the moved frame) below the growth's hold-out miss (`growth_holdout_miss`), the same statistic.
    Ties go to the growth; where too few captured points lie round R to hold out (the miss is inf), a full copy,
    accepted by stage align's own rim test, goes first."""
    if not alignments.candidates:
        return False
    best = min(candidate.residual for candidate in alignments.candidates)
    return best < growth_holdout_miss(seq, region, crop)


def growth_holdout_miss(seq: SequenceData, region: HoleRegion, crop: Crop) -> float:
    """The rim fill's growth judged on captured points it did not see: the crop's points outside R and within w =
    ceil(sqrt(k / pi)) spacings of it (one fit radius, the reach of the growth's own fill, `rim_fill_rounds`) are
    held out, the growth (`voxels.crossed_voxels`, at most that many rounds) fills R grown by w from the rest, and the
    miss is the trimmed mean distance from each held-out point to the nearest grown or remaining point
    (`methods._registration.alignment_residual`, the copies' statistic: the 90 % smallest). inf when fewer than 6
    points are held out or remain."""
    rounds = rim_fill_rounds(seq.neighbours)
    width = rounds * seq.spacing
    held = region.contains(crop.local, margin=width) & ~region.contains(crop.local)
    rest = crop.local[~held]
    if held.sum() < 6 or len(rest) < 6:
        return float("inf")
    grown = crossed_voxels(region.grown(width), rest, cKDTree(rest), neighbours=max(seq.neighbours, 6),
                           max_rounds=rounds)
    return alignment_residual(cKDTree(np.vstack([rest, grown])), crop.local[held], np.eye(3), np.zeros(3))
