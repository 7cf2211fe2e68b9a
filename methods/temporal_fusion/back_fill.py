"""Stage back-fill (``reuse_next``): once every frame is filled, the frames are visited again from the last to the
first, and a hole R of frame f that the stages left open (nothing copied, reused or spatially filled; partial
copies may be there) takes what frame f+1 found in its own holes, moved back to f by f+1's motion to f (from stage
align while f was filled), with stage reuse's tests (only where R is still open, on the rim's surface) and stage
settle's treatment. What frame f+1 found: its copies, spatial fills and back-fills, not what it reused from f
(carried there and back by two motions it would lie beside f's own). Why: reuse carries a fill forward only, and
each frame's spatial tests are decided on its own rim, so a persistent hole refused in its first frames stayed
open there while a later frame filled it."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.methods._spatial_fill import far_from
from dpcbench.methods.temporal_fusion.colours import masked, no_colour, rounded, stacked
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.crop import crop_region
from dpcbench.methods.temporal_fusion.motion import deformed
from dpcbench.methods.temporal_fusion.records import Motion, SequenceData
from dpcbench.methods.temporal_fusion.settle import near_regions, settle
from dpcbench.methods.temporal_fusion.surface import disagreeing
from dpcbench.methods.temporal_fusion.voxels import rows_in, snap_to_voxels


def back_fill(cfg: FusionConfig, seq: SequenceData, f: int, later_fill: np.ndarray, added: np.ndarray,
              motions: tuple[Motion | None, ...], later_colours: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray | None]:
    """Frame f+1's fill ``later_fill`` (M, 3) moved back to frame f by f+1's motion per region (``motions``, None
    where the region is not open), where frame f's holes are still open after its own fill ``added`` (A, 3).
    Returns (P, 3) points to add to frame f and their colours (P, 3): each moved point carries its colour in frame
    f+1 (``later_colours`` (M, 3)) through stage settle and the snapping (`colours`); None without colour."""
    spacing, frame = seq.spacing, seq.frames[f]
    frame_regions = seq.regions[f]
    parts: list[np.ndarray] = []
    part_colours: list[np.ndarray | None] = []
    for k, (region, motion) in enumerate(zip(frame_regions, motions)):
        if motion is None:
            continue
        rotation, translation, field = motion
        moved = later_fill @ rotation.T + translation
        inside = region.contains(moved)
        moved, colours = deformed(moved[inside], field, cfg.deform_neighbours), masked(later_colours, inside)
        if not len(moved):
            continue
        crop = crop_region(cfg, seq, f, region)
        keep = far_from(moved, crop.tree, cfg.gap_spacings * spacing)
        near = np.vstack([added, *parts])
        near = near[region.contains(near, margin=crop.shell)]
        if len(near):
            keep &= far_from(moved, cKDTree(near), cfg.fill_gap_spacings * spacing)
        moved, colours = moved[keep], masked(colours, keep)
        keep = ~disagreeing(moved, crop.rim, 3 * spacing, cfg.accept_spacings * spacing)
        moved, colours = moved[keep], masked(colours, keep)
        if not len(moved):
            continue
        moved, colours = settle(cfg, seq, moved, near, region, crop, colours)
        keep = region.contains(moved, margin=spacing)
        for earlier in frame_regions[:k]:
            keep &= ~earlier.contains(moved)
        parts.append(moved[keep])
        part_colours.append(masked(colours, keep))
    if not parts:
        return np.zeros((0, 3)), None if later_colours is None else no_colour(0)
    back, colours = np.vstack(parts), stacked(part_colours, [len(p) for p in parts])
    if seq.voxelized:
        voxels = snap_to_voxels(back, frame[near_regions(seq.tree_of(f), frame_regions, spacing * 2)])
        colours = rounded(back, colours, voxels)
        keep = ~rows_in(voxels, added) if len(added) else np.ones(len(voxels), dtype=bool)
        return voxels[keep], masked(colours, keep)
    keep = far_from(back, seq.tree_of(f), cfg.gap_spacings * spacing)
    return back[keep], masked(colours, keep)
