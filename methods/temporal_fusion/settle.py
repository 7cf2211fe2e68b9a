"""Stage settle: the new points onto the surface, no second layer, one point per voxel.

Projection: every new point that is not a captured voxel already (on voxelized input the copies are; the reused
and partial points are not) moves onto the moving-least-squares surface of frame f's crop and the new points: the
k nearest support points, a PCA frame at their centroid, a weighted least-squares quadric height field
h(u, v) = c0 + c1 u + c2 v + c3 u^2 + c4 u v + c5 v^2, the point replaced by (u, v, h(u, v)); on voxelized input
the moved points are then re-voxelized by the capture's rule with the bound read from R's rim (``revoxelize``; else
rounded). Layers (``drop_layers``): in a region that keeps captured points inside (an occlusion box), a new point
that its captured neighbours surround and that lies off their plane (0.5 s; on voxels: their plane misses its cube)
lies over surface the frame captured, as a misaligned copy's second layer, and is dropped. Voxelized input: all
new points are rounded to the grid (half up), duplicates merged, and voxels frame f occupies dropped."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill import even_subset, over_captured_surface, unique_voxels
from dpcbench.methods.temporal_fusion.colours import pooled, rounded
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.records import Crop, SequenceData
from dpcbench.methods.temporal_fusion.surface import mls_project
from dpcbench.methods.temporal_fusion.voxels import CALIBRATION_POINTS, rim_crossing_threshold, surface_voxels

#: how far off the captured surface's plane a fill point must lie to be a second layer over it, on float samples,
#: in spacings: half a spacing (two samplings of one surface lie about that far apart); the plane is that of its 16
#: nearest captured points within 2 s
FLOAT_LAYER_SPACINGS = 0.5
#: on voxelized input a voxel is a layer when the captured surface's plane does not cross its unit cube, the plane
#: fitted to the ``VOXEL_LAYER_NEIGHBOURS`` captured voxels within ``VOXEL_LAYER_REACH`` voxels (a disc of radius 4,
#: pi 4^2 ~ 50): a staircase's voxels scatter up to half a cube diagonal about its plane, and a smaller disc tilts
#: its fitted plane by that scatter (on voxelized planes 2 s and 16 voxels read 4-28 of a gap's own 32-75 voxels as
#: off the plane, 4 voxels and 50 at most 4, while 97-100 % of a layer one voxel above is read as one)
VOXEL_LAYER_REACH = 4.0
VOXEL_LAYER_NEIGHBOURS = 50
#: the reach within which `voxels.surface_voxels` chooses the settled points' voxels (its default, sqrt 3): a
#: settled voxel's colour is the mean of the moved points within it
SETTLE_REACH = float(np.sqrt(3.0))


def project_new(cfg: FusionConfig, seq: SequenceData, region: HoleRegion, crop: Crop, accepted: np.ndarray,
                copied: int, colours: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """``accepted`` (A, 3; its first ``copied`` rows copies, the rest reused) projected (all rows on float input,
    the reused ones on voxelized input, where the reused ones are then re-voxelized): a new array, and the colours
    of its rows (``colours`` (A, 3) carried: a projected point keeps its colour, a re-voxelized voxel takes the
    mean of the projected points within the reach that chose it, `colours.pooled`; None stays None)."""
    accepted = accepted.copy()
    local = crop.local
    # on voxelized data the copies are voxels of a captured surface already: projecting them
    # onto a smooth fit and rounding back thins the staircase
    first = copied if seq.voxelized else 0
    if seq.projection_neighbours >= 6 and first < len(accepted):
        support = np.vstack([local, accepted])
        accepted[first:] = mls_project(accepted[first:], support, seq.projection_neighbours)
    if seq.voxelized and copied < len(accepted) and cfg.revoxelize:
        # the copies' rule for the reused points too (moved by f-1's motion: sub-voxel positions)
        k = max(seq.projection_neighbours, 6)
        bound = rim_crossing_threshold(even_subset(crop.rim, CALIBRATION_POINTS), region, local, crop.tree, k)
        occupied = cKDTree(np.vstack([local, accepted[:copied]])) if copied else crop.tree
        reused = surface_voxels(accepted[copied:], region, np.vstack([local, accepted]), occupied, k, bound)
        if colours is not None:
            colours = np.vstack([colours[:copied], pooled(accepted[copied:], colours[copied:], reused, SETTLE_REACH)])
        accepted = np.vstack([accepted[:copied], reused])
    elif seq.voxelized and copied < len(accepted):
        reused = unique_voxels(np.floor(accepted[copied:] + 0.5))
        if colours is not None:
            colours = np.vstack([colours[:copied], rounded(accepted[copied:], colours[copied:], reused)])
        accepted = np.vstack([accepted[:copied], reused])
    return accepted, colours


def settle(cfg: FusionConfig, seq: SequenceData, points: np.ndarray, fixed: np.ndarray, region: HoleRegion,
           crop: Crop, colours: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Moved points (``points`` (P, 3), beside the new points ``fixed`` of R) onto the MLS surface of frame f's crop
    and all new points, then, on voxelized data, re-voxelized with the rim's bound, never on a voxel of the crop or
    of ``fixed``; with the settled points' colours from the moved points' ``colours`` (P, 3) as `project_new`
    carries them (None stays None)."""
    local = crop.local
    support = np.vstack([local, fixed, points])
    if seq.projection_neighbours >= 6:
        points = mls_project(points, support, seq.projection_neighbours)
    if seq.voxelized and cfg.revoxelize:
        k = max(seq.projection_neighbours, 6)
        bound = rim_crossing_threshold(even_subset(crop.rim, CALIBRATION_POINTS), region, local, crop.tree, k)
        occupied = cKDTree(np.vstack([local, fixed])) if len(fixed) else crop.tree
        voxels = surface_voxels(points, region, support, occupied, k, bound)
        return voxels, pooled(points, colours, voxels, SETTLE_REACH)
    if seq.voxelized:
        voxels = unique_voxels(np.floor(points + 0.5))
        return voxels, rounded(points, colours, voxels)
    return points, colours


def over_captured(fill: np.ndarray, tree: cKDTree, spacing: float, voxelized: bool) -> np.ndarray:
    """Mask (P,) of ``fill`` lying as a second layer over frame f's captured points (``tree``)."""
    if not voxelized:
        return over_captured_surface(fill, tree, spacing, off_plane_spacings=FLOAT_LAYER_SPACINGS)
    return over_captured_surface(fill, tree, spacing, reach_spacings=VOXEL_LAYER_REACH,
                                 neighbours=VOXEL_LAYER_NEIGHBOURS, off_plane_spacings=None)


def keeps_captured(tree: cKDTree, frame: np.ndarray, region: HoleRegion) -> bool:
    """Whether ``frame`` (its k-d tree ``tree``) has points inside ``region`` (an occlusion box)."""
    near = tree.query_ball_point(region.center, region.bounding_radius)
    return bool(len(near)) and bool(region.contains(frame[np.asarray(near, dtype=np.int64)]).any())


def near_regions(tree: cKDTree, frame_regions, margin: float) -> np.ndarray:
    """Indices of the frame's points within ``margin`` of any region's bounding ball, unique and sorted."""
    idx = [tree.query_ball_point(r.center, r.bounding_radius + margin) for r in frame_regions]
    return np.unique(np.concatenate([np.asarray(i, dtype=np.int64) for i in idx])) if idx else np.zeros(0, np.int64)
