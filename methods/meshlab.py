"""`meshlab`: the paper's MeshLab baseline through pymeshlab, frame by frame.

Pipeline (pymeshlab filter names as in pymeshlab 2025.7):

1. ``compute_normal_for_point_clouds`` (k = ``normal_neighbours``): PCA normals, MeshLab's own
   orientation propagation.
2. Surface reconstruction: ``generate_surface_reconstruction_ball_pivoting`` (the paper's baseline;
   ``ball_radius`` in data units, 0 = MeshLab's automatic guess) or, with
   ``reconstruction="poisson"``, ``generate_surface_reconstruction_screened_poisson`` (``depth``).
3. ``meshing_repair_non_manifold_edges`` and ``..._vertices`` (close-holes needs a 2-manifold
   mesh), then ``meshing_close_holes`` with ``maxholesize = max_hole_size`` (boundary edges) and
   ``newfaceselected`` so that the faces it creates are known.
4. Back to points:
   - ``output="whole"`` (the paper's): the whole closed mesh resampled with as many points as the
     input frame has (the "same point count" resampling), spread uniformly over its area, so the
     density drops by the small fraction of area the closed holes add. Every point is new, which
     is why this scores low even where the surface was intact. Not area(mesh) / s^2: on voxelized
     frames the ball-pivoting mesh follows the voxel staircase and its area is inflated (measured:
     about twice the input count on the embedded human, size small); not len(points) * area(mesh) /
     area(reconstructed): ball pivoting leaves ~12% of the dfaust points unreferenced, closing
     those gaps counts as new area (110k samples for a 99.6k-point dfaust frame).
   - ``output="holes-only"``: the input points are kept and points are added only on the hole
     faces, at the input's areal density 1 / s^2 (s = `methods._geometry.sampling_step`; the
     closing faces are flat, so their area is not inflated).
     Hole faces: those ``meshing_close_holes`` created; with Poisson reconstruction, which leaves
     no holes to close, also the faces whose centroid is farther than ``s`` from every input
     point (surface Poisson made where there was no data). With ``regions`` given, only samples
     within ``region_margin_spacings * s`` of a region are kept (the task's holes, not every gap of
     the reconstruction); with ``regions=None`` (blind) every closed hole is filled.

Paper-scale frames (``max_points``, default 120,000): MeshLab's ball pivoting costs about a
millisecond per point on this 2-core machine (93k points: 114 s with a 1.5-spacing ball, 545 s with
the automatic radius, both under heavy contention), so an 800k-point frame took over an hour. When
a frame has more than ``max_points`` points, steps 1-3 run on a voxel-clustered copy (open3d
``voxel_down_sample``: the mean of the points in each cell; the cell size starts at
s * sqrt(N / max_points) and grows until at most ``max_points`` cells are occupied). A surface
reconstruction does not need 800k samples to describe a body that 120k describe (cells of about 2.6
points' spacing on the 8i frames): the mesh is the same surface at a coarser triangle size, the
holes stay holes (a medium hole is ~30 spacings across), and step 4 is unchanged: ``whole``
resamples the coarser mesh with the input's point count, ``holes-only`` keeps the input points and
samples the closing faces at the input's density 1 / s^2. Frames of at most ``max_points`` points
(every frame of the regression and quick presets, the 100k benchmark) are reconstructed exactly as
before. ``max_points=0`` turns the clustering off.

Sampling is uniform over the surface (`sample_triangles`: faces drawn with probability
proportional to area, uniform barycentric points), with numpy and the ``seed`` parameter, not with
pymeshlab's ``generate_sampling_montecarlo`` / ``_poisson_disk``: those are not reproducible (two
runs on the same mesh in one process gave different samples) and Poisson-disk with an exact count
took 483 s for 100k samples (Monte Carlo 0.5 s).

Known limitation (measured once; the diagnosis script was not kept): on voxelized frames (the embedded human,
size small, 93k points) ball pivoting with the automatic radius leaves a mesh with 54k boundary
edges of 285k and non-manifold vertices, so the synthetic holes are not separate boundary loops
and close-holes puts only 9-100 faces in them (with or without its self-intersection check,
maxholesize 1000 or 5000): holes-only then adds ~100 points a frame. A larger ``ball_radius`` or
``reconstruction="poisson"`` are the levers; not tuned yet.

Every pymeshlab failure becomes a `MeshlabError` naming the filter and MeshLab's message.
Choices not in the paper: ``max_hole_size=1000`` (MeshLab's default 30 edges does not close a
medium synthetic hole: radius 30 on a 1023-unit body is ~190 boundary edges at 10-bit spacing).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._geometry import sampling_step
from dpcbench.methods.base import PerFrameMethod, Regions
from dpcbench.metrics.errors import UserError


class MeshlabError(RuntimeError):
    """A pymeshlab filter failed or produced an unusable mesh."""


class MeshlabFill(PerFrameMethod):
    """Point cloud -> mesh -> close holes -> points, with pymeshlab (see module docstring)."""

    name = "meshlab"
    summary = "MeshLab baseline: normals, ball-pivoting (or screened Poisson) mesh, close holes, resample (pymeshlab)"
    version = "1"
    detects_holes = True

    def __init__(self, reconstruction: str = "ball-pivoting", output: str = "whole", normal_neighbours: int = 10,
                 ball_radius: float = 0.0, poisson_depth: int = 8, max_hole_size: int = 1000,
                 region_margin_spacings: float = 2.0, max_points: int = 120_000, seed: int = 0):
        self.reconstruction = reconstruction
        self.output = output
        self.normal_neighbours = normal_neighbours
        self.ball_radius = ball_radius
        self.poisson_depth = poisson_depth
        self.max_hole_size = max_hole_size
        self.region_margin_spacings = region_margin_spacings
        self.max_points = max_points
        self.seed = seed

    def _validate_params(self) -> None:
        if self.reconstruction not in ("ball-pivoting", "poisson"):
            raise UserError(
                f"meshlab: reconstruction must be 'ball-pivoting' or 'poisson', got {self.reconstruction!r}")
        if self.output not in ("whole", "holes-only"):
            raise UserError(f"meshlab: output must be 'whole' or 'holes-only', got {self.output!r}")
        if int(self.normal_neighbours) < 3:
            raise UserError(f"meshlab: normal_neighbours must be >= 3, got {self.normal_neighbours}")
        if not self.ball_radius >= 0:
            raise UserError(f"meshlab: ball_radius must be >= 0 (0 = automatic), got {self.ball_radius}")
        if not 1 <= int(self.poisson_depth) <= 16:
            raise UserError(f"meshlab: poisson_depth must be in 1..16, got {self.poisson_depth}")
        if int(self.max_hole_size) < 3:
            raise UserError(f"meshlab: max_hole_size (boundary edges) must be >= 3, got {self.max_hole_size}")
        if int(self.max_points) != self.max_points or not (self.max_points == 0 or self.max_points >= 1000):
            raise UserError(
                f"meshlab: max_points must be 0 (no clustering) or an integer >= 1000, got {self.max_points!r}")
        if not self.region_margin_spacings >= 0:
            raise UserError(f"meshlab: region_margin_spacings must be >= 0, got {self.region_margin_spacings}")

    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        self._validate_params()
        return super().inpaint(frames, regions)

    def inpaint_frame(self, points: np.ndarray, regions: Sequence[HoleRegion] | None) -> np.ndarray:
        import pymeshlab  # lazily: heavy import, only this method needs it

        if len(points) < 4:
            raise UserError(f"meshlab: a frame needs at least 4 points to build a mesh, got {len(points)}")
        step = sampling_step(points)
        support = cluster_points(points, int(self.max_points), step) if self.max_points else points
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(support, dtype=np.float64)))
        _apply(ms, "compute_normal_for_point_clouds", k=int(self.normal_neighbours))
        if self.reconstruction == "ball-pivoting":
            _apply(ms, "generate_surface_reconstruction_ball_pivoting",
                   ballradius=pymeshlab.PureValue(float(self.ball_radius)))
        else:
            _apply(ms, "generate_surface_reconstruction_screened_poisson", depth=int(self.poisson_depth),
                   threads=1)  # one thread: the same input gives the same mesh
        if ms.current_mesh().face_number() == 0:
            raise MeshlabError(f"meshlab: {self.reconstruction} reconstruction produced no faces from "
                               f"{len(points)} points (ball_radius={self.ball_radius}); try another ball_radius "
                               "or reconstruction='poisson'")
        _apply(ms, "meshing_remove_unreferenced_vertices")
        _apply(ms, "meshing_repair_non_manifold_edges")
        _apply(ms, "meshing_repair_non_manifold_vertices")
        reconstructed_faces = ms.current_mesh().face_number()
        _apply(ms, "meshing_close_holes", maxholesize=int(self.max_hole_size), newfaceselected=True,
               selfintersection=True)
        mesh = ms.current_mesh()
        vertices, faces = mesh.vertex_matrix(), mesh.face_matrix()
        hole_faces = mesh.face_selection_array().astype(bool).copy()
        hole_faces[:reconstructed_faces] = False  # only faces close-holes appended
        if self.reconstruction == "poisson":
            centroids = vertices[faces].mean(axis=1)
            far, _ = cKDTree(points).query(centroids, k=1, workers=-1)
            hole_faces |= far > step * len(points) ** 0.5 / len(support) ** 0.5  # the support's spacing
        areas = _triangle_areas(vertices, faces)

        rng = np.random.default_rng(self.seed)
        if self.output == "whole":
            return sample_triangles(vertices, faces, len(points), rng, areas=areas)

        count = int(round(float(areas[hole_faces].sum()) / step ** 2))
        if count == 0:
            return points.copy()
        added = sample_triangles(vertices, faces[hole_faces], count, rng, areas=areas[hole_faces])
        if regions is not None:
            near = np.zeros(len(added), dtype=bool)
            for region in regions:
                near |= region.contains(added, margin=self.region_margin_spacings * step)
            added = added[near]
        return np.concatenate([points, added], axis=0)


def cluster_points(points: np.ndarray, max_points: int, step: float) -> np.ndarray:
    """At most ``max_points`` points (K, 3) describing the surface of ``points`` (N, 3): ``points`` itself
    when N <= max_points, else the means of the points in each occupied cell of a voxel grid (open3d
    ``voxel_down_sample``). The cell starts at ``step * sqrt(N / max_points)`` (a surface's cell
    count falls with the square of the cell size) and grows by the square root of the remaining
    ratio, times 1.05, until the count fits."""
    if len(points) <= max_points:
        return points
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64)))
    cell = step * np.sqrt(len(points) / max_points)
    for _ in range(20):
        clustered = np.asarray(cloud.voxel_down_sample(float(cell)).points)
        if len(clustered) <= max_points:
            return clustered
        cell *= 1.05 * np.sqrt(len(clustered) / max_points)
    raise MeshlabError(f"meshlab: could not cluster {len(points)} points into at most {max_points}")


def _apply(ms, filter_name: str, **params) -> None:
    """Run one pymeshlab filter; any failure becomes a MeshlabError that names it."""
    import pymeshlab

    try:
        ms.apply_filter(filter_name, **params)
    except pymeshlab.PyMeshLabException as err:
        raise MeshlabError(f"meshlab: pymeshlab filter {filter_name!r} failed: {err}") from err


def sample_triangles(vertices: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator,
                     areas: np.ndarray | None = None) -> np.ndarray:
    """``count`` points (count, 3) uniform over the triangles ``faces`` (F, 3) of ``vertices``:
    face i drawn with probability area_i / sum(area); in it p = a + u (b - a) + v (c - a) with
    (u, v) uniform on the unit triangle (reflected when u + v > 1)."""
    if count <= 0 or len(faces) == 0:
        return np.empty((0, 3))
    areas = _triangle_areas(vertices, faces) if areas is None else areas
    total = float(areas.sum())
    if not total > 0:
        raise MeshlabError("meshlab: the mesh to sample has zero area")
    chosen = rng.choice(len(faces), size=int(count), p=areas / total)
    u, v = rng.random(int(count)), rng.random(int(count))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    a, b, c = (vertices[faces[chosen, i]] for i in range(3))
    return a + u[:, None] * (b - a) + v[:, None] * (c - a)


def _triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of each face (F,): |(b - a) x (c - a)| / 2."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
