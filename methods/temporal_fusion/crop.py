"""Stage crop: frame f's points round a hole region R, and its rim.

shell = max(shell_factor r, shell_spacings s) (r: R's bounding radius); the crop is frame f's points within
r + 2 shell of R's centre, in the frame's point order (a sorted ball query, so nothing depends on how the k-d
tree is laid out); the rim is those within the shell of R (points inside R, where an occlusion box keeps some,
count too: they are data)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.records import Crop, SequenceData


def crop_region(cfg: FusionConfig, seq: SequenceData, f: int, region: HoleRegion) -> Crop:
    """The `Crop` of frame f round ``region``."""
    shell = cfg.shell(region, seq.spacing)
    reach = region.bounding_radius + 2 * shell
    idx = np.asarray(seq.tree_of(f).query_ball_point(region.center, reach, return_sorted=True), dtype=np.int64)
    local = seq.frames[f][idx]
    return Crop(local, cKDTree(local), local[region.contains(local, margin=shell)], shell, reach)
