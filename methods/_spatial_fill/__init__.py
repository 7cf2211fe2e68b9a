"""The spatial fills of `temporal-fusion` (its stage `methods.temporal_fusion.spatial` says when each runs;
docs/temporal-fusion.md why, and what it measured; the step numbers below are the labels used there): surfaces
for the parts of a hole that no frame saw, each with the tests that decide whether it is trusted, and the
agreement rule of step 4 (stage fuse) they share with the copies. Step 6b, the advancing front, is
`methods._front_fill`.

- `rim_surface_fill` (step 6): a thin-plate-spline height field over the rim's PCA plane; `rim_sheet` (step 6f)
  narrows its support to the hole's own sheet.
- `poisson_surface_fill` (step 6c): screened Poisson of the crop, body by body (`tube_fill` across a limb the
  hole cuts through).
- `cap_fill` (step 6d): the membrane spanning an opening's boundary loop (`harmonic_height_field`).
- `membrane_fill` (step 6e): lozes-pde's harmonic graph fill anchored at the data round and inside the hole.
- `grown_agreeing` / `plane_offsets` (step 4): a point is kept when it continues its neighbours' local plane.

Every function works on numpy arrays ((N, 3) points, a `HoleRegion`, distances in coordinate units with the
point spacing given), so each can be tested and used alone.
"""

from dpcbench.methods._spatial_fill.cap import (
    cap_fill,
    cap_walled,
    harmonic_height_field,
)
from dpcbench.methods._spatial_fill.common import (
    COARSE_LOOK_FACTOR,
    COARSE_LOOK_MIN_DEPTH,
    MAX_STEEP,
    POISSON_CELL_STEPS,
    POISSON_HOLDOUT_CELL_STEPS,
    POISSON_MAX_DEPTH,
    POISSON_SCALE,
    SHEET_MIN_ALIGNMENT,
    SURFACE_POINTS,
    _flat_anchors,
    _link_components,
    _voxel_keys,
    even_subset,
    far_from,
    first_in_cells,
    fit_height_field,
    grown_agreeing,
    over_captured_surface,
    plane_offsets,
    unique_voxels,
)
from dpcbench.methods._spatial_fill.membrane import (
    _open_radius,
    _sheet_bounded,
    _within_hull_of,
    between_layers,
    membrane_fill,
    membrane_sag,
)
from dpcbench.methods._spatial_fill.poisson import (
    _bodies,
    _holds_out,
    _native_stderr_silenced,
    _path_parity,
    _poisson_points,
    _poisson_samples,
    _triangles_near,
    limb_ends,
    orient_along_surface,
    poisson_surface_fill,
    sample_triangles,
    tube_fill,
)
from dpcbench.methods._spatial_fill.spline import (
    rim_sheet,
    rim_surface_fill,
)

#: every name of the former single module, private helpers included (tests import them from here)
__all__ = ["COARSE_LOOK_FACTOR", "COARSE_LOOK_MIN_DEPTH", "MAX_STEEP", "POISSON_CELL_STEPS", "POISSON_HOLDOUT_CELL_STEPS", "POISSON_MAX_DEPTH", "POISSON_SCALE",
           "SHEET_MIN_ALIGNMENT", "SURFACE_POINTS", "_bodies", "_flat_anchors", "_holds_out", "_link_components",
           "_native_stderr_silenced", "_open_radius", "_path_parity", "_poisson_points", "_poisson_samples",
           "_sheet_bounded", "_triangles_near", "_voxel_keys", "_within_hull_of", "between_layers", "cap_fill",
           "cap_walled", "even_subset", "far_from", "first_in_cells", "fit_height_field", "grown_agreeing",
           "harmonic_height_field", "limb_ends", "membrane_fill", "membrane_sag", "orient_along_surface",
           "over_captured_surface", "plane_offsets", "poisson_surface_fill", "rim_sheet", "rim_surface_fill",
           "sample_triangles", "tube_fill", "unique_voxels"]
