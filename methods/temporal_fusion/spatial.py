"""Stage spatial: where no frame saw all of R (``fallback``), the parts still open are filled from frame f's own
surface by an ordered cascade of strategies (`CASCADE`). Each has a test of when it runs (``applies``: mostly,
that the strategies before it added nothing), a ``fill`` and a ``trust`` test inside the fill that refuses a
surface it cannot put on the data with confidence (then it adds nothing and the next one runs). A hole every
strategy refuses goes to the last, `BestSurface`, which leaves it open only where the open hole is predicted to
cost less than the best candidate surface.

In run order:

1. `SurfaceSpline`: a thin-plate spline height field over the PCA plane of the rim and the copies.
2. `SheetSpline` (``sheet``): the same on the hole's own sheet of that support (a second surface in reach
   refused 1); what it fills counts as covered, and what it leaves open goes on.
3. `WalledCap` (``cap`` and ``walled_cap_first``, voxelized input): a cap across an opening whose walls rise
   from it and that is shallow past its loop's plane (no surface round it continues over it).
4. `ClosedSurface` (``poisson``): screened Poisson of the crop's bodies (a hole round a limb or a neck).
5. `Cap` (``cap``, voxelized input): the harmonic membrane across an opening's loop (a base, a sole).
6. `Membrane` (``membrane``): the graph membrane of the data round and inside R (an occlusion box's open
   parts); in a region that keeps captured points also after `ClosedSurface` (``membrane_after_poisson``); where the
   output is not snapped to voxels, thinned to one point a cubic cell of the grid step (the capture's density).
7. `Front` (``front``, off): an advancing front grown chart by chart from the rim and the copies.
8. `BestSurface` (``best_surface``): where every strategy before refused and nothing else covers any of R (no copy,
   reused fill, partial copy or captured point inside it), the candidate surfaces (spline, sheet spline, closed surface, without their refusal
   tests) ranked by their hold-out miss: the first that is predicted to cost less D1 than the open hole fills, the
   others nothing (`methods._spatial_fill.best`).

A new strategy is one class with ``applies`` / ``fill`` / ``trust`` put in its place in `CASCADE`."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._front_fill import front_fill, rim_residual_bound
from dpcbench.methods._spatial_fill import (
    cap_fill,
    cap_walled,
    first_in_cells,
    membrane_fill,
    poisson_surface_fill,
    rim_sheet,
    rim_surface_fill,
    unique_voxels,
)
from dpcbench.methods._spatial_fill.best import best_surface_fill, candidates
from dpcbench.methods.temporal_fusion.config import FusionConfig, rim_fill_rounds
from dpcbench.methods.temporal_fusion.records import Crop, SequenceData
from dpcbench.methods.temporal_fusion.settle import keeps_captured


@dataclass(frozen=True)
class Opening:
    """What the cascade fills: ``region`` R with frame f's `Crop`, the points accepted so far (copies and reused
    fill, ``copied`` of them copies), the partial copies ``seen``, the spline's ``support`` (the rim within
    `FusionConfig.surface_shell` of R and the copies), the hold-out ``ring`` (half that width), and whether R keeps
    captured points inside (``in_box``: an occlusion box)."""

    region: HoleRegion
    crop: Crop
    accepted: np.ndarray
    copied: int
    seen: np.ndarray
    support: np.ndarray
    ring: float
    in_box: bool
    seq: SequenceData


@dataclass(frozen=True)
class Cascade:
    """The cascade's state: the spatial fill so far, the tree of what is covered, the sheet's and the closed
    surface's fills, whether the walled cap ran, the parts frame f+1 must not reuse, and the membrane's fill where
    it was the first fill (every surface before it refused)."""

    spatial: np.ndarray
    covered: cKDTree
    sheet_fill: np.ndarray
    poisson_fill: np.ndarray
    capped_first: bool = False
    not_reused: tuple[np.ndarray, ...] = ()
    membrane_alone: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def _surface(cfg: FusionConfig, hole: Opening, support: np.ndarray, covered: cKDTree) -> np.ndarray:
    seq = hole.seq
    return rim_surface_fill(support, hole.region, covered, seq.spacing, voxelized=seq.voxelized, step=seq.step,
                            max_holdout_spacings=cfg.surface_holdout_spacings, ring=hole.ring,
                            gap_spacings=cfg.fill_gap_spacings)


class SurfaceSpline:
    trust = ("the support is a height field over its PCA plane (at most 1/4 of its normals 60 degrees off) and the "
             "spline of the outer rim predicts the inner rim within surface_holdout_spacings s RMS")

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        return True

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        return replace(state, spatial=_surface(cfg, hole, hole.support, state.covered))


class SheetSpline:
    trust = "the hole's edge is one sheet (mean squared cosine to its normal axis >= cos^2 30 degrees), then 1's tests"

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        return cfg.sheet and not len(state.spatial)

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        sheet = rim_sheet(hole.support, hole.region, hole.ring, hole.seq.spacing)
        if sheet is None:
            return state
        sheet_fill = _surface(cfg, hole, sheet, state.covered)
        covered = cKDTree(np.vstack([state.covered.data, sheet_fill])) if len(sheet_fill) else state.covered
        return replace(state, sheet_fill=sheet_fill, covered=covered)


def _cap(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
    seq = hole.seq
    spatial = cap_fill(hole.crop.local, hole.region, state.covered, seq.spacing, voxelized=seq.voxelized,
                       step=seq.step, gap_spacings=cfg.fill_gap_spacings, harmonic=cfg.harmonic_cap)
    # the harmonic cap: frame f's own loop spans it afresh in each frame; moved on by each frame's motion it drifted
    not_reused = state.not_reused + (spatial,) if cfg.harmonic_cap else state.not_reused
    return replace(state, spatial=spatial, not_reused=not_reused)


class WalledCap:
    trust = "the loop's heights over its plane have an RMS of at most max(1 s, r / 20)"

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        return (cfg.cap and hole.seq.voxelized and not len(state.spatial) and cfg.walled_cap_first
                and cap_walled(hole.crop.local, hole.region, hole.seq.spacing))

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        return replace(_cap(cfg, hole, state), capped_first=True)


class ClosedSurface:
    trust = ("the surface of the crop without its inner ring misses that ring by at most surface_holdout_spacings s "
             "RMS, less the ring's own scatter in quadrature (`holdout_passes`)")

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        return cfg.poisson and not len(state.spatial) and (cfg.poisson_in_boxes or not hole.in_box)

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        seq = hole.seq
        spatial = poisson_surface_fill(np.vstack([hole.crop.local, hole.accepted]), hole.region, state.covered,
                                       seq.spacing, voxelized=seq.voxelized, step=seq.step,
                                       gap_spacings=cfg.fill_gap_spacings, ring=hole.ring,
                                       max_holdout_spacings=cfg.surface_holdout_spacings,
                                       separate_bodies=cfg.poisson_bodies, bridge_ends=cfg.poisson_bridges)
        return replace(state, spatial=spatial, poisson_fill=spatial)


class Cap:
    trust = WalledCap.trust

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        return cfg.cap and hole.seq.voxelized and not state.capped_first and not len(state.spatial)

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        return _cap(cfg, hole, state)


class Membrane:
    trust = ("height field over the seeds' plane (a majority bound), interpolation or a bounded sag, the hold-out of "
             "the band round the open part (less the band's own scatter in quadrature, `holdout_passes`), and the agreement "
             "rule")

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        after_poisson = (cfg.membrane_after_poisson and hole.in_box and len(state.poisson_fill)
                         and len(state.spatial) == len(state.poisson_fill))
        return bool(cfg.membrane and (not len(state.spatial) or after_poisson))

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        seq, poisson_fill = hole.seq, state.poisson_fill
        anchors = np.vstack([hole.accepted, poisson_fill])
        gaps = cKDTree(np.vstack([state.covered.data, poisson_fill])) if len(poisson_fill) else state.covered
        membrane = membrane_fill(hole.crop.local, hole.region, gaps, seq.spacing, step=seq.step, accepted=anchors,
                                 partial=hole.seen, gap_spacings=cfg.fill_gap_spacings,
                                 agree_spacings=cfg.accept_spacings, max_holdout_spacings=cfg.surface_holdout_spacings)
        if not seq.voxelized and len(membrane):
            # at the capture's density, one point a cubic cell of the grid step, as the closed surface's fill: the
            # harmonic solution gathers its seeds towards the anchors, and unsnapped nothing after it thins them
            # (the float cow's occlusion rig: about 45 % of its points shared a cell; docs, "Version 58")
            membrane = membrane[first_in_cells(membrane, seq.step)]
        alone = membrane if not len(state.spatial) else state.membrane_alone
        return replace(state, spatial=np.vstack([state.spatial, membrane]), not_reused=state.not_reused + (membrane,),
                       membrane_alone=alone)


class Front:
    trust = "each accepted cell's fit residual is at most the 90th percentile of the same fit's residual on the rim"

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        return cfg.front and not len(state.spatial)

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        seq, spacing = hole.seq, hole.seq.spacing
        k = max(seq.neighbours, 6)
        points = front_fill(hole.support, hole.region, state.covered, spacing, voxelized=seq.voxelized,
                            max_residual=rim_residual_bound(hole.crop.rim, k), neighbours=k,
                            max_rounds=rim_fill_rounds(k),
                            free_distance=spacing / 2 if seq.voxelized else cfg.fill_gap_spacings * spacing)
        if seq.voxelized and len(points):
            points = unique_voxels(np.floor(points + 0.5))
        return replace(state, spatial=points)


class BestSurface:
    trust = ("the candidate's hold-out miss (its RMS distance to the inner ring it was built without) is below the open "
             "part's predicted error (its fill's RMS distance to the frame's points and the fill so far), and no "
             "candidate with a smaller miss passed; only that one candidate fills")

    @staticmethod
    def applies(cfg: FusionConfig, hole: Opening, state: Cascade) -> bool:
        # only in an emptied region where nothing at all was put: where copies, the reused fill, partial copies or
        # captured points (an occlusion box) cover part of it, a candidate's points that keep their gap from them are
        # as often a sheet off the surface as the rest of the hole (human small coherent, seed 1, frame 8: 164 such
        # points 3.4 s RMS off the truth, D1 22.19 -> 18.83)
        # the membrane's points where it ran alone count as data round what it left open: it spans a region's open
        # parts from the data round them, and in a hole every surface refused it often spans a few voxels only
        # (Longdress at 8 bits, small holes, seed 3: 22 points in three holes, which stayed open)
        return (cfg.best_surface and len(state.spatial) == len(state.membrane_alone) and not len(state.sheet_fill)
                and not len(hole.accepted) and not len(hole.seen) and not hole.in_box)

    @staticmethod
    def fill(cfg: FusionConfig, hole: Opening, state: Cascade) -> Cascade:
        seq = hole.seq
        surfaces = candidates(hole.support, np.vstack([hole.crop.local, hole.accepted]), hole.region, seq.spacing,
                              voxelized=seq.voxelized, step=seq.step, gap_spacings=cfg.fill_gap_spacings,
                              ring=hole.ring, sheet=cfg.sheet, closed=cfg.poisson)
        # the open part's error is measured to everything the output holds round it (the frame's points, the copies,
        # the reused fill, the partial copies), not to the captured points alone: in a persistent hole the reused fill
        # covers most of it
        covered = (cKDTree(np.vstack([state.covered.data, state.membrane_alone])) if len(state.membrane_alone)
                   else state.covered)
        _, spatial = best_surface_fill(covered, hole.region, surfaces, hole.ring)
        # built afresh in each frame, as the caps and membranes: its error is larger than the trusted fills', and
        # carried on by the next frame's reuse it would be carried into every later frame of a persistent hole
        return replace(state, spatial=np.vstack([state.spatial, spatial]), not_reused=state.not_reused + (spatial,))


#: the spatial strategies in the order they are tried
CASCADE = (SurfaceSpline, SheetSpline, WalledCap, ClosedSurface, Cap, Membrane, Front, BestSurface)


def spatial_fill(cfg: FusionConfig, seq: SequenceData, f: int, region: HoleRegion, crop: Crop, accepted: np.ndarray,
                 copied: int, seen: np.ndarray, full_copy: bool) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """(the spatial fill (P, 3) of what is open in ``region``, the parts of it frame f+1 must not reuse). Nothing
    where a copy's frame saw all of R (``full_copy``: the gaps its copy leaves are the capture's) or with
    ``fallback`` off."""
    if not cfg.fallback or full_copy:
        return np.zeros((0, 3)), ()
    covered = cKDTree(np.vstack([crop.local, accepted, seen])) if len(accepted) or len(seen) else crop.tree
    width = cfg.surface_shell(region, seq.spacing)
    rim = crop.rim if width >= crop.shell else crop.rim[region.contains(crop.rim, margin=width)]
    support = np.vstack([rim, accepted[:copied]]) if copied else rim
    hole = Opening(region, crop, accepted, copied, seen, support, width / 2,
                   keeps_captured(seq.tree_of(f), seq.frames[f], region), seq)
    state = Cascade(np.zeros((0, 3)), covered, np.zeros((0, 3)), np.zeros((0, 3)))
    for strategy in CASCADE:
        if strategy.applies(cfg, hole, state):
            state = strategy.fill(cfg, hole, state)
    return np.vstack([state.sheet_fill, state.spatial]), state.not_reused
