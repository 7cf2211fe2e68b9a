"""`TemporalFusion`: the method, running the stages of this package in order per frame and hole region
(see the package docstring), then the back-fill from the last frame to the first."""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._colour import colour_frame
from dpcbench.methods._geometry import detect_regions, sampling_step
from dpcbench.methods._spatial_fill import far_from
from dpcbench.methods.base import InpaintingMethod, Regions
from dpcbench.methods.progress import frame_done
from dpcbench.methods.temporal_fusion.align import align_sources
from dpcbench.methods.temporal_fusion.back_fill import back_fill
from dpcbench.methods.temporal_fusion.colours import as_sources, masked, no_colour, rounded, stacked
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.crop import crop_region
from dpcbench.methods.temporal_fusion.fuse import fuse
from dpcbench.methods.temporal_fusion.records import FrameFill, Motion, RegionFill, SequenceData
from dpcbench.methods.temporal_fusion.reuse import partial_copies, reuse_previous
from dpcbench.methods.temporal_fusion.rim_fill import copy_beats_growth, rim_fill
from dpcbench.methods.temporal_fusion.settle import (
    keeps_captured,
    near_regions,
    over_captured,
    project_new,
    settle,
)
from dpcbench.methods.temporal_fusion.spatial import spatial_fill
from dpcbench.methods.temporal_fusion.voxels import rows_in, snap_to_voxels
from dpcbench.metrics.neighbours import is_voxelization, point_spacing


def fill_region(cfg: FusionConfig, seq: SequenceData, f: int, region: HoleRegion, previous_fill: np.ndarray,
                previous_colours: np.ndarray | None = None) -> RegionFill:
    """The stages for one hole region R of frame f, in run order: crop, rim fill (kept for a thin gap unless a copy
    beats it, which the alignments decide), align, fuse, reuse (previous fill, partial copies), spatial cascade,
    settle. ``previous_fill`` (M, 3): frame f-1's reusable fill, and its
    colours in frame f-1's output (M, 3) when the run tracks colour (`colours`: the copies carry their source
    points' colours, the reused points their previous-frame colours, the rim fill and the spatial fills none)."""
    tracking = seq.colours is not None
    crop = crop_region(cfg, seq, f, region)
    if len(crop.rim) < 6:  # nothing around the hole to align to or to continue
        return RegionFill(np.zeros((0, 3)), colours=no_colour(0) if tracking else None)
    thin = rim_fill(cfg, seq, region, crop)
    alignments = align_sources(cfg, seq, f, region, crop)
    if thin is not None and not copy_beats_growth(seq, region, crop, alignments):
        return RegionFill(thin, colours=no_colour(len(thin)) if tracking else None)
    fused = fuse(cfg, seq, region, crop, alignments.candidates)
    copied = len(fused.points)  # points copied from captured data; the rest is reused or spatial fill
    moved, rows = reuse_previous(cfg, seq, f, region, crop, fused.points, previous_fill, alignments)
    accepted = np.vstack([fused.points, moved])
    if tracking and previous_colours is None:
        previous_colours = no_colour(len(previous_fill))
    accepted_colours = stacked([fused.colours, masked(previous_colours, rows)], [copied, len(moved)])
    seen, seen_colours = partial_copies(cfg, seq, crop, accepted, alignments.partial)
    spatial, not_reused = spatial_fill(cfg, seq, f, region, crop, accepted, copied, seen, fused.full_copy)
    if not len(accepted) and not len(spatial) and not len(seen):
        return RegionFill(np.zeros((0, 3)), alignments.next_motion, not_reused,
                          colours=no_colour(0) if tracking else None)
    accepted, accepted_colours = project_new(cfg, seq, region, crop, accepted, copied, accepted_colours)
    from_previous = (accepted[copied:],)
    if len(seen):
        # the partial copies as the reused points: onto the surface, re-voxelized; not reused
        seen, seen_colours = settle(cfg, seq, seen, accepted, region, crop, seen_colours)
        not_reused = not_reused + (seen,)
    # the back-fill only where R stayed open but for the partial copies
    next_motion = None if len(accepted) or len(spatial) else alignments.next_motion
    points = np.vstack([accepted, seen, spatial])
    colours = stacked([accepted_colours, seen_colours, None], [len(accepted), len(seen), len(spatial)])
    keep = region.contains(points, margin=seq.spacing)
    return RegionFill(points[keep], next_motion, not_reused, from_previous, masked(colours, keep))


def _as_added(parts, voxelized: bool) -> np.ndarray:
    """``parts`` stacked as `fill_frame` puts them in its output (rounded to voxels on voxelized data)."""
    points = np.vstack(parts)
    return np.floor(points + 0.5) if voxelized else points


def fill_frame(cfg: FusionConfig, seq: SequenceData, f: int, previous_fill: np.ndarray,
               previous_colours: np.ndarray | None = None) -> FrameFill:
    """Every hole region of frame f (`fill_region`), then no second layer over the captured points of a region that
    keeps some, each point in the first region that holds it, snapped to the voxels (voxelized input) or farther
    than ``gap_spacings`` s from the frame's points; the carried colours follow their points (a snapped voxel the
    mean of the coloured points rounded to it, `colours.rounded`)."""
    spacing, frame, tree = seq.spacing, seq.frames[f], seq.tree_of(f)
    frame_regions = seq.regions[f]
    new_parts: list[np.ndarray] = []
    new_colours: list[np.ndarray | None] = []
    not_reused: list[np.ndarray] = []
    from_previous: list[np.ndarray] = []
    next_motions: list[Motion | None] = []
    for k, region in enumerate(frame_regions):
        region_fill = fill_region(cfg, seq, f, region, previous_fill, previous_colours)
        next_motions.append(region_fill.next_motion)
        not_reused += region_fill.not_reused
        from_previous += region_fill.from_previous
        fill, colours = region_fill.points, region_fill.colours
        if len(fill) and cfg.drop_layers and keeps_captured(tree, frame, region):
            # in a region that keeps captured points (an occlusion box), nothing laid as a second layer over them
            keep = ~over_captured(fill, tree, spacing, seq.voxelized)
            fill, colours = fill[keep], masked(colours, keep)
        if len(fill):
            # overlapping regions: what an earlier region filled is not filled again
            keep = np.ones(len(fill), dtype=bool)
            for earlier in frame_regions[:k]:
                keep &= ~earlier.contains(fill)
            new_parts.append(fill[keep])
            new_colours.append(masked(colours, keep))
    if not new_parts:
        return FrameFill(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), tuple(next_motions),
                         no_colour(0) if seq.colours is not None else None)
    added, colours = np.vstack(new_parts), stacked(new_colours, [len(p) for p in new_parts])
    if seq.voxelized:
        snapped = snap_to_voxels(added, frame[near_regions(tree, frame_regions, spacing * 2)])
        added, colours = snapped, rounded(added, colours, snapped)
    else:
        keep = far_from(added, tree, cfg.gap_spacings * spacing)
        added, colours = added[keep], masked(colours, keep)
    reusable_rows = np.arange(len(added))
    if not_reused:
        # partial copies, caps and membranes rest on the frames round f as they are, so frame f + 1 builds its own
        # rather than reusing these: reused, they drift and pile up in a persistent occlusion box
        reusable_rows = np.flatnonzero(~rows_in(added, _as_added(not_reused, seq.voxelized)))
    found_rows = reusable_rows
    if from_previous:
        # frame f - 1 holds these already: carried back after a round trip they would lie beside it
        found_rows = reusable_rows[~rows_in(added[reusable_rows], _as_added(from_previous, seq.voxelized))]
    return FrameFill(added, added[reusable_rows], added[found_rows], tuple(next_motions), colours, reusable_rows,
                     found_rows)


class TemporalFusion(InpaintingMethod):
    """Motion-compensated fusion of every frame within +-``window`` that saw the missing surface, surface
    projection, voxel snapping, reuse of the previous frame's fill (replacing, never adding) and, where a hole
    stayed open, of the next frame's; a spatial cascade on the rim's surface where no frame saw it and the surface
    is trusted. The parameters and their constraints are `config.FusionConfig`'s; the stages are this package's
    modules."""

    name = "temporal-fusion"
    summary = ("fills thin voxel gaps from the frame's own rim by the voxelization rule where that predicts the "
               "captured surface better than another frame's copy; elsewhere "
               "fuses the hole's patch from every frame within +-W (rigid + rim-driven non-rigid motion "
               "compensation), MLS surface projection, steady reuse of the previous fill (of the next one where a "
               "hole stayed open), spline fill of the "
               "rim's surface (or of the hole's own sheet of it) where no frame saw it and the fit is trusted; "
               "a graph membrane across the open parts of occlusion boxes")
    version = "58"  # the history of each version: docs/temporal-fusion.md
    uses_neighbour_frames = True
    needs_regions = False
    detects_holes = True

    def __init__(self, window: int = 3, shell_factor: float = 0.5, shell_spacings: float = 4.0,
                 surface_shell_spacings: float = 4.0, icp_iterations: int = 30, accept_spacings: float = 1.0, refine: bool = True, deform: bool = True,
                 deform_neighbours: int = 32, gap_spacings: float = 0.5, fill_gap_spacings: float = 1.0,
                 reuse_previous: bool = True, fallback: bool = True, surface_holdout_spacings: float = 1.0,
                 mls_neighbours: int | str = "auto", rim_fill: bool = True, poisson: bool = True,
                 poisson_bodies: bool = True, poisson_bridges: bool = True, cap: bool = True, harmonic_cap: bool = True,
                 walled_cap_first: bool = True, membrane: bool = True, front: bool = False,
                 partial_sources: bool = True, sheet: bool = True, revoxelize: bool = True, pool_adjacent: bool = True,
                 adjacent_first: bool = True, count_copies: bool = True, reuse_next: bool = True,
                 drop_layers: bool = True, coarse_retry: bool = True,
                 poisson_in_boxes: bool = True, membrane_after_poisson: bool = True, best_surface: bool = True,
                 snap: bool | str = "auto") -> None:
        self.window = window
        self.shell_factor = shell_factor
        self.shell_spacings = shell_spacings
        self.surface_shell_spacings = surface_shell_spacings
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
        self.best_surface = best_surface
        self.snap = snap

    def _validate(self) -> FusionConfig:
        """The frozen `FusionConfig` of the stored parameters; ValueError naming a parameter out of its range."""
        return FusionConfig.of(self.get_params(), self.name)

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        return self._fill(frames, regions)[0]

    def inpaint_with_colours(self, frames: list[np.ndarray], colours: Sequence[np.ndarray], regions: Regions = None,
                             *, fill: str = "auto") -> tuple[list[np.ndarray], list[np.ndarray]]:
        """``inpaint``'s output with colours fused like its positions (package docstring, `colours`): with ``fill``
        "auto" (or "source") each new point takes the colour of what decided its position (the copies' source
        colours, the reused points' previous-frame colours, the back-filled points' next-frame colours; a voxel the
        mean of the coloured points that chose it) and the rest the harmonic (or nearest) fill of
        `methods._colour`, frame by frame, so a reused fill carries the colour its frame gave it. "nearest" and
        "harmonic" colour every new point by that fill alone (`InpaintingMethod.inpaint_with_colours`)."""
        if fill not in ("auto", "source"):
            return super().inpaint_with_colours(frames, colours, regions, fill=fill)
        _, checked = self._check_colours(frames, colours, regions, fill)
        outputs, coloured = self._fill(frames, regions, checked, fill)
        assert coloured is not None
        return outputs, coloured

    def _fill(self, frames: list[np.ndarray], regions: Regions = None, colours: list[np.ndarray] | None = None,
              fill: str = "auto") -> tuple[list[np.ndarray], list[np.ndarray] | None]:
        """(outputs, their colours or None): the stages on every frame, then the back-fill; colours (F arrays
        (N_f, 3) uint8) tracked when given. The geometry does not depend on them."""
        cfg = self._validate()
        frames, regions = self._check_inputs(frames, regions)
        if regions is None:
            regions = detect_regions(frames, self.name)
        if len(frames) == 1 and any(regions[0]):
            warnings.warn(f"{self.name}: a one-frame sequence has no other frame to copy from; "
                          "using the spatial fill only", RuntimeWarning, stacklevel=3)
        trees: dict[int, cKDTree] = {}

        def tree_of(g):
            if g not in trees:
                # built for crops and distances only: the unbalanced, non-compact build is ~40% faster
                # on an 800k-point frame, and the crops are sorted, so nothing depends on its layout
                trees[g] = cKDTree(frames[g], balanced_tree=False, compact_nodes=False)
            return trees[g]

        seq = _sequence(cfg, frames, regions, tree_of, colours)
        outputs: list[np.ndarray] = []
        out_colours: list[np.ndarray] = []
        fills: dict[int, FrameFill] = {}
        previous_fill = np.zeros((0, 3))
        previous_colours = None if colours is None else no_colour(0)
        for f, frame in enumerate(frames):
            for old in [g for g in trees if g < f - int(cfg.window)]:
                del trees[old]
            if not regions[f]:
                outputs.append(frame.copy())
                previous_fill = np.zeros((0, 3))
                if colours is not None:
                    out_colours.append(colours[f].copy())
                    previous_colours = no_colour(0)
            else:
                fills[f] = fill_frame(cfg, seq, f, previous_fill, previous_colours)
                added, previous_fill = fills[f].added, fills[f].reusable
                outputs.append(np.vstack([frame, added]) if len(added) else frame.copy())
                carried = fills[f].colours
                if colours is not None and carried is not None:  # (always, when colours are given)
                    out_colours.append(colour_frame(frame, colours[f], outputs[f], fill, as_sources(len(frame), carried)))
                    previous_colours = out_colours[f][len(frame):][fills[f].reusable_rows].astype(np.float64)
            frame_done(f + 1, len(frames))  # the back-fill after the last frame is short
        if cfg.reuse_next:
            _back_fill_all(cfg, seq, outputs, fills, trees, out_colours if colours is not None else None, fill)
        return outputs, (out_colours if colours is not None else None)


def _sequence(cfg: FusionConfig, frames, regions, tree_of, colours=None) -> SequenceData:
    """The `SequenceData` of a run: the spacing s of the largest frame (1 on voxelized data: integer coordinates
    about one voxel apart, `metrics.neighbours.is_voxelization`), the spatial fill's grid step (1 / sqrt(areal
    density) on unvoxelized data, so a square grid has the frame's density), the fit sizes, and the frames'
    colours as float64 (None without colour)."""
    largest = max(range(len(frames)), key=lambda g: len(frames[g]))
    voxel_data = is_voxelization(frames, tree_of(largest))
    voxelized = cfg.snap is True or (cfg.snap == "auto" and voxel_data)
    spacing = 1.0 if voxel_data else point_spacing(frames[largest], tree=tree_of(largest))
    step = spacing if voxel_data else sampling_step(frames[largest])
    return SequenceData(frames, regions, tree_of, spacing, step, voxelized, cfg.fit_neighbours(voxelized),
                        cfg.fit_neighbours(False),
                        None if colours is None else [np.asarray(c, dtype=np.float64) for c in colours])


def _back_fill_all(cfg, seq, outputs, fills, trees, out_colours=None, fill: str = "auto") -> None:
    """The back-fill, last frame first, so a fill found late in a persistent hole reaches back over every frame;
    ``outputs`` (and ``out_colours``, when the run tracks colour: a back-filled point carries its colour in frame
    f+1, `back_fill`, else the colour fill) are extended in place."""
    frames = seq.frames
    found_of = {f: fill_.found for f, fill_ in fills.items()}
    found_colours = {} if out_colours is None else \
        {f: out_colours[f][len(frames[f]):][fill_.found_rows].astype(np.float64) for f, fill_ in fills.items()}
    for f in range(len(frames) - 2, -1, -1):
        for old in [g for g in trees if g > f + 1]:
            del trees[old]
        later = found_of.get(f + 1)
        if f not in found_of or later is None or not len(later):
            continue
        back, colours = back_fill(cfg, seq, f, later, outputs[f][len(frames[f]):], fills[f].next_motions,
                                  found_colours.get(f + 1))
        if len(back):
            outputs[f] = np.vstack([outputs[f], back])
            found_of[f] = np.vstack([found_of[f], back])
            if out_colours is not None and colours is not None:
                kept = len(frames[f])
                carried = np.vstack([out_colours[f][kept:].astype(np.float64), colours])
                out_colours[f] = colour_frame(frames[f], seq.colours[f].astype(np.uint8), outputs[f], fill,
                                              as_sources(kept, carried))
                found_colours[f] = np.vstack([found_colours[f], out_colours[f][-len(back):].astype(np.float64)])
