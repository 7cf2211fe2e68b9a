"""`TemporalFusion`: the method, running the stages of this package in order per frame and hole region
(see the package docstring), then the back-fill from the last frame to the first."""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._geometry import detect_regions, sampling_step
from dpcbench.methods._spatial_fill import far_from
from dpcbench.methods.base import InpaintingMethod, Regions
from dpcbench.methods.progress import frame_done
from dpcbench.methods.temporal_fusion.align import align_sources
from dpcbench.methods.temporal_fusion.back_fill import back_fill
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.crop import crop_region
from dpcbench.methods.temporal_fusion.fuse import fuse
from dpcbench.methods.temporal_fusion.records import FrameFill, Motion, RegionFill, SequenceData
from dpcbench.methods.temporal_fusion.reuse import partial_copies, reuse_previous
from dpcbench.methods.temporal_fusion.rim_fill import rim_fill
from dpcbench.methods.temporal_fusion.settle import (
    keeps_captured,
    near_regions,
    over_captured,
    project_new,
    settle,
)
from dpcbench.methods.temporal_fusion.spatial import spatial_fill
from dpcbench.methods.temporal_fusion.voxels import rows_in, snap_to_voxels
from dpcbench.metrics.neighbours import point_spacing


def fill_region(cfg: FusionConfig, seq: SequenceData, f: int, region: HoleRegion, previous_fill: np.ndarray
                ) -> RegionFill:
    """The stages for one hole region R of frame f, in run order: crop, rim fill, align, fuse, reuse (previous
    fill, partial copies), spatial cascade, settle. ``previous_fill`` (M, 3): frame f-1's reusable fill."""
    crop = crop_region(cfg, seq, f, region)
    if len(crop.rim) < 6:
        return RegionFill(np.zeros((0, 3)))  # nothing around the hole to align to or to continue
    thin = rim_fill(cfg, seq, region, crop)
    if thin is not None:
        return RegionFill(thin)
    alignments = align_sources(cfg, seq, f, region, crop)
    fused = fuse(cfg, seq, region, crop, alignments.candidates)
    copied = len(fused.points)  # points copied from captured data; the rest is reused or spatial fill
    accepted = reuse_previous(cfg, seq, f, region, crop, fused.points, previous_fill, alignments)
    seen = partial_copies(cfg, seq, crop, accepted, alignments.partial)
    spatial, not_reused = spatial_fill(cfg, seq, f, region, crop, accepted, copied, seen, fused.full_copy)
    if not len(accepted) and not len(spatial) and not len(seen):
        return RegionFill(np.zeros((0, 3)), alignments.next_motion, not_reused)
    accepted = project_new(cfg, seq, region, crop, accepted, copied)
    from_previous = (accepted[copied:],)
    if len(seen):
        # the partial copies as the reused points: onto the surface, re-voxelized; not reused
        seen = settle(cfg, seq, seen, accepted, region, crop)
        not_reused = not_reused + (seen,)
    # the back-fill only where R stayed open but for the partial copies
    next_motion = None if len(accepted) or len(spatial) else alignments.next_motion
    points = np.vstack([accepted, seen, spatial])
    return RegionFill(points[region.contains(points, margin=seq.spacing)], next_motion, not_reused, from_previous)


def _as_added(parts, voxelized: bool) -> np.ndarray:
    """``parts`` stacked as `fill_frame` puts them in its output (rounded to voxels on voxelized data)."""
    points = np.vstack(parts)
    return np.floor(points + 0.5) if voxelized else points


def fill_frame(cfg: FusionConfig, seq: SequenceData, f: int, previous_fill: np.ndarray) -> FrameFill:
    """Every hole region of frame f (`fill_region`), then no second layer over the captured points of a region that
    keeps some, each point in the first region that holds it, snapped to the voxels (voxelized input) or farther
    than ``gap_spacings`` s from the frame's points."""
    spacing, frame, tree = seq.spacing, seq.frames[f], seq.tree_of(f)
    frame_regions = seq.regions[f]
    new_parts: list[np.ndarray] = []
    not_reused: list[np.ndarray] = []
    from_previous: list[np.ndarray] = []
    next_motions: list[Motion | None] = []
    for k, region in enumerate(frame_regions):
        region_fill = fill_region(cfg, seq, f, region, previous_fill)
        next_motions.append(region_fill.next_motion)
        not_reused += region_fill.not_reused
        from_previous += region_fill.from_previous
        fill = region_fill.points
        if len(fill) and cfg.drop_layers and keeps_captured(tree, frame, region):
            # in a region that keeps captured points (an occlusion box), nothing laid as a second layer over them
            fill = fill[~over_captured(fill, tree, spacing, seq.voxelized)]
        if len(fill):
            # overlapping regions: what an earlier region filled is not filled again
            for earlier in frame_regions[:k]:
                fill = fill[~earlier.contains(fill)]
            new_parts.append(fill)
    if not new_parts:
        return FrameFill(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), tuple(next_motions))
    added = np.vstack(new_parts)
    if seq.voxelized:
        added = snap_to_voxels(added, frame[near_regions(tree, frame_regions, spacing * 2)])
    else:
        added = added[far_from(added, tree, cfg.gap_spacings * spacing)]
    reusable = added
    if not_reused:
        # partial copies, caps and membranes rest on the frames round f as they are, so frame f + 1 builds its own
        # rather than reusing these: reused, they drift and pile up in a persistent occlusion box
        reusable = added[~rows_in(added, _as_added(not_reused, seq.voxelized))]
    found = reusable
    if from_previous:
        # frame f - 1 holds these already: carried back after a round trip they would lie beside it
        found = reusable[~rows_in(reusable, _as_added(from_previous, seq.voxelized))]
    return FrameFill(added, reusable, found, tuple(next_motions))


class TemporalFusion(InpaintingMethod):
    """Motion-compensated fusion of every frame within +-``window`` that saw the missing surface, surface
    projection, voxel snapping, reuse of the previous frame's fill (replacing, never adding) and, where a hole
    stayed open, of the next frame's; a spatial cascade on the rim's surface where no frame saw it and the surface
    is trusted. The parameters and their constraints are `config.FusionConfig`'s; the stages are this package's
    modules."""

    name = "temporal-fusion"
    summary = ("fills thin voxel gaps from the frame's own rim by the voxelization rule; elsewhere "
               "fuses the hole's patch from every frame within +-W (rigid + rim-driven non-rigid motion "
               "compensation), MLS surface projection, steady reuse of the previous fill (of the next one where a "
               "hole stayed open), spline fill of the "
               "rim's surface (or of the hole's own sheet of it) where no frame saw it and the fit is trusted; "
               "a graph membrane across the open parts of occlusion boxes")
    version = "43"  # the history of each version: docs/temporal-fusion.md
    uses_neighbour_frames = True
    needs_regions = False
    detects_holes = True

    def __init__(self, window: int = 3, shell_factor: float = 0.5, shell_spacings: float = 4.0,
                 icp_iterations: int = 30, accept_spacings: float = 1.0, refine: bool = True, deform: bool = True,
                 deform_neighbours: int = 32, gap_spacings: float = 0.5, fill_gap_spacings: float = 1.0,
                 reuse_previous: bool = True, fallback: bool = True, surface_holdout_spacings: float = 1.0,
                 mls_neighbours: int | str = "auto", rim_fill: bool = True, poisson: bool = True,
                 poisson_bodies: bool = True, poisson_bridges: bool = True, cap: bool = True, harmonic_cap: bool = True,
                 walled_cap_first: bool = True, membrane: bool = True, front: bool = False,
                 partial_sources: bool = True, sheet: bool = True, revoxelize: bool = True, pool_adjacent: bool = True,
                 adjacent_first: bool = True, count_copies: bool = True, reuse_next: bool = True,
                 drop_layers: bool = True, coarse_retry: bool = True,
                 poisson_in_boxes: bool = True, membrane_after_poisson: bool = True, snap: bool | str = "auto") -> None:
        self.window = window
        self.shell_factor = shell_factor
        self.shell_spacings = shell_spacings
        self.icp_iterations = icp_iterations
        self.accept_spacings = accept_spacings
        self.refine = refine
        self.deform = deform
        self.deform_neighbours = deform_neighbours
        self.gap_spacings = gap_spacings
        self.fill_gap_spacings = fill_gap_spacings
        self.reuse_previous = reuse_previous
        self.fallback = fallback
        self.surface_holdout_spacings = surface_holdout_spacings
        self.mls_neighbours = mls_neighbours
        self.rim_fill = rim_fill
        self.poisson = poisson
        self.poisson_bodies = poisson_bodies
        self.poisson_bridges = poisson_bridges
        self.cap = cap
        self.harmonic_cap = harmonic_cap
        self.walled_cap_first = walled_cap_first
        self.membrane = membrane
        self.partial_sources = partial_sources
        self.sheet = sheet
        self.front = front
        self.revoxelize = revoxelize
        self.pool_adjacent = pool_adjacent
        self.adjacent_first = adjacent_first
        self.count_copies = count_copies
        self.reuse_next = reuse_next
        self.drop_layers = drop_layers
        self.coarse_retry = coarse_retry
        self.poisson_in_boxes = poisson_in_boxes
        self.membrane_after_poisson = membrane_after_poisson
        self.snap = snap

    def _validate(self) -> FusionConfig:
        """The frozen `FusionConfig` of the stored parameters; ValueError naming a parameter out of its range."""
        return FusionConfig.of(self.get_params(), self.name)

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        cfg = self._validate()
        frames, regions = self._check_inputs(frames, regions)
        if regions is None:
            regions = detect_regions(frames, self.name)
        if len(frames) == 1 and any(regions[0]):
            warnings.warn(f"{self.name}: a one-frame sequence has no other frame to copy from; "
                          "using the spatial fill only", RuntimeWarning, stacklevel=2)
        trees: dict[int, cKDTree] = {}

        def tree_of(g):
            if g not in trees:
                # built for crops and distances only: the unbalanced, non-compact build is ~40% faster
                # on an 800k-point frame, and the crops are sorted, so nothing depends on its layout
                trees[g] = cKDTree(frames[g], balanced_tree=False, compact_nodes=False)
            return trees[g]

        seq = _sequence(cfg, frames, regions, tree_of)
        outputs: list[np.ndarray] = []
        fills: dict[int, FrameFill] = {}
        previous_fill = np.zeros((0, 3))
        for f, frame in enumerate(frames):
            for old in [g for g in trees if g < f - int(cfg.window)]:
                del trees[old]
            if not regions[f]:
                outputs.append(frame.copy())
                previous_fill = np.zeros((0, 3))
            else:
                fills[f] = fill_frame(cfg, seq, f, previous_fill)
                added, previous_fill = fills[f].added, fills[f].reusable
                outputs.append(np.vstack([frame, added]) if len(added) else frame.copy())
            frame_done(f + 1, len(frames))  # the back-fill after the last frame is short
        if cfg.reuse_next:
            _back_fill_all(cfg, seq, frames, outputs, fills, trees)
        return outputs


def _sequence(cfg: FusionConfig, frames, regions, tree_of) -> SequenceData:
    """The `SequenceData` of a run: the spacing s of the largest frame (1 on integer data), the spatial fill's
    grid step (1 / sqrt(areal density) on unvoxelized data, so a square grid has the frame's density), and the fit
    sizes."""
    integer = all(np.array_equal(frame, np.round(frame)) for frame in frames)
    voxelized = cfg.snap is True or (cfg.snap == "auto" and integer)
    largest = max(range(len(frames)), key=lambda g: len(frames[g]))
    spacing = 1.0 if integer else point_spacing(frames[largest], tree=tree_of(largest))
    step = spacing if integer else sampling_step(frames[largest])
    return SequenceData(frames, regions, tree_of, spacing, step, voxelized, cfg.fit_neighbours(voxelized),
                        cfg.fit_neighbours(False))


def _back_fill_all(cfg, seq, frames, outputs, fills, trees) -> None:
    """The back-fill, last frame first, so a fill found late in a persistent hole reaches back over every frame;
    ``outputs`` is extended in place."""
    found_of = {f: fill.found for f, fill in fills.items()}
    for f in range(len(frames) - 2, -1, -1):
        for old in [g for g in trees if g > f + 1]:
            del trees[old]
        later = found_of.get(f + 1)
        if f not in found_of or later is None or not len(later):
            continue
        back = back_fill(cfg, seq, f, later, outputs[f][len(frames[f]):], fills[f].next_motions)
        if len(back):
            outputs[f] = np.vstack([outputs[f], back])
            found_of[f] = np.vstack([found_of[f], back])
