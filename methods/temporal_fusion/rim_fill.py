"""Stage rim fill (voxelized input, ``rim_fill``): a thin gap closed from frame f's own rim.

The gap is grown from the rim by the voxelization rule (`voxels.crossed_voxels`: a free voxel within sqrt 3 of the
support is accepted when the MLS quadric of its k nearest support points crosses its unit cube). When the growth
closes within ceil(sqrt(k / pi)) rounds (one fit radius: every new voxel lies within it of captured points), the
gap is thin and the growth is R's whole fill; otherwise it is discarded and the later stages fill R. Why: thin
gaps no camera saw (armpits, soles) sit between captured points a voxel or two apart, where a moved copy of a
neighbouring frame lies up to a voxel off."""

from __future__ import annotations

import numpy as np

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.temporal_fusion.config import FusionConfig, rim_fill_rounds
from dpcbench.methods.temporal_fusion.records import Crop, SequenceData
from dpcbench.methods.temporal_fusion.voxels import crossed_voxels


def rim_fill(cfg: FusionConfig, seq: SequenceData, region: HoleRegion, crop: Crop) -> np.ndarray | None:
    """Integer voxels (P, 3) filling ``region`` from the crop's rim when the growth closes; None when the stage
    is off, the input is not voxelized, or the gap is not thin."""
    if not (seq.voxelized and cfg.rim_fill):
        return None
    thin, closed = crossed_voxels(region, crop.local, crop.tree, neighbours=max(seq.neighbours, 6),
                                  max_rounds=rim_fill_rounds(seq.neighbours), with_closed=True)
    return thin if closed else None
