"""`temporal-fusion`: fill each hole from every frame that saw the missing surface, motion-compensated, fused,
projected onto the surface and kept steady over time; a spatial fill only where no frame saw it.

Not a method from the paper. Where a neighbouring frame holds the missing patch, a rigidly aligned copy of it
beats any graph fill; where no frame holds it (coherent holes, occlusions) a spatial fill is needed, and it must
sit on the surface and stay put from frame to frame. docs/temporal-fusion.md has the decision record of every
step and switch, with its measurement.

Units: lengths in point spacings s (`metrics.neighbours.point_spacing` of the largest frame; 1 on voxelized data:
integer coordinates at a spacing of at most 1.5 voxels, `metrics.neighbours.is_voxelization`)
or hole radii r (a region's bounding radius); time in frames.

Frames are processed in order (reuse takes frame f-1's result), then from the last to the first for the holes
left open (back-fill takes frame f+1's). For frame f and each hole region R (given, or found by
`holes.detection.detect_holes` when regions=None) the stages run in this order, one module each:

1. `crop`: frame f's points within r + 2 shell of R and the rim within shell = max(0.5 r, 4 s) of it.
2. `rim_fill` (voxelized input): a thin gap the rim's own quadric closes within one fit radius is R's fill,
   unless a frame that saw all of R (stage align, run first) lies on the rim closer than that growth misses
   its own hold-out (`rim_fill.copy_beats_growth`): then the copies fill it, as any other hole.
3. `align`: frames within +-window, nearest first, aligned by ICP of their shell (point-to-point, refined
   point-to-plane, coarse to fine when it fails) and accepted when the rim residual is at most 1 s; a frame with
   its own hole near R gives a partial copy.
4. `fuse`: the copies best first, each later one only where the better ones left a hole-sized gap and where it
   continues the surface; re-voxelized by the capture's rule on voxelized input.
5. `reuse`: frame f-1's fill moved by its motion where R is still open and the fill fits the rim; then the
   partial copies, through the agreement rule widened by their rim residual.
6. `spatial`: where no frame saw all of R, an ordered cascade of fills on frame f's surface (spline, sheet, cap,
   closed surface, membrane, front), each with its own trust test, fitted to the rim within max(0.5 r,
   surface_shell_spacings s) of R (4 s: the crop's rim) and held out on half of it.
7. `settle`: moved points onto the MLS surface (re-voxelized on voxelized input), no second layer over captured
   points in an occlusion box, one point per voxel.
8. `back_fill`: once all frames are done, last to first, a hole left open takes frame f+1's fill moved back.

Colour (``inpaint_with_colours``, `colours`): each new point carries the colour of what decided its position (a
copy its source point's, a voxel the mean of the copies that chose it, a reused or back-filled point its colour in
the frame it came from); the rim fill and the spatial cascade get the harmonic fill of `methods._colour`.

Every step is vectorised over points; the per-hole work runs on crops of size O(r^2 / s^2), so the time is
linear in the points and in the holes. The parameters, their ranges and reasons are `config.FusionConfig`; the
switches that only restore an older behaviour are `config.ABLATIONS`. Shared geometry comes from
`methods._geometry`, `methods._spatial_fill` (the spatial fills) and `methods._front_fill` (the front)."""

from dpcbench.methods.temporal_fusion.align import ICP_POINTS
from dpcbench.methods.temporal_fusion.config import (
    ABLATIONS,
    FIT_NEIGHBOURS,
    VOXEL_FIT_NEIGHBOURS,
    FusionConfig,
    constraints,
    rim_fill_rounds,
)
from dpcbench.methods.temporal_fusion.method import TemporalFusion
from dpcbench.methods.temporal_fusion.motion import (
    PlaneTarget,
    interpolate_displacement,
    plane_target,
    refine_point_to_plane,
    rim_displacement,
    seen_rim_residual,
)
from dpcbench.methods.temporal_fusion.settle import FLOAT_LAYER_SPACINGS, VOXEL_LAYER_NEIGHBOURS, VOXEL_LAYER_REACH
from dpcbench.methods.temporal_fusion.surface import disagreeing, mls_fit, mls_project
from dpcbench.methods.temporal_fusion.voxels import (
    CALIBRATION_POINTS,
    COPY_REACH,
    crossed_voxels,
    crossing_offset,
    rim_crossing_threshold,
    rows_in,
    snap_to_voxels,
    surface_voxels,
)

__all__ = ["ABLATIONS", "CALIBRATION_POINTS", "COPY_REACH", "FIT_NEIGHBOURS", "FLOAT_LAYER_SPACINGS", "ICP_POINTS",
           "VOXEL_FIT_NEIGHBOURS", "VOXEL_LAYER_NEIGHBOURS", "VOXEL_LAYER_REACH", "FusionConfig", "PlaneTarget",
           "TemporalFusion", "constraints", "crossed_voxels", "crossing_offset", "disagreeing",
           "interpolate_displacement", "mls_fit", "mls_project", "plane_target", "refine_point_to_plane",
           "rim_crossing_threshold", "rim_displacement", "rim_fill_rounds", "rows_in", "seen_rim_residual",
           "snap_to_voxels", "surface_voxels"]
