"""Acquisition (occlusion) holes: what a rig of K cameras around the subject cannot see.

A point counts as *seen* by a camera when the visibility operator says nothing lies in front of it
and the camera looks at it at a non-grazing angle: ``|n . v| >= min_cos``, with n the point's PCA
normal and v the unit vector from the point to the camera (real depth sensors lose surfaces viewed
edge-on). Points seen by no camera are removed; the removed points are grouped into connected pieces
(radius graph, 3 point spacings), each bounded by an oriented box (PCA axes) that becomes its hole
region. Every removed point lies inside a region. Unseen points within ``seen_within`` point spacings
of a seen point are kept (`unseen_after_cover`): they are the inner layer of a surface that is more
than one sample thick (voxelized data), not a hole.

Visibility operators. Default (version 2) ``visibility="zbuffer"``: a z-buffer of splats of one point
spacing per camera (`zbuffer_visible_mask`), what a renderer does. ``visibility="hpr"`` (version 1's
default): open3d's hidden point removal (Katz, Tal, Basri, "Direct visibility of point sets",
SIGGRAPH 2007; the standard operator for bare point sets). `raycast_visible_mask` is the exact
operator where the surface is known (a mesh); it is the reference the other two are measured against.

How the default was chosen (version 2), by a rule stated before the comparison: the operator whose
removed set is closer to the exact one (F1 of the removed set against ray casting on the mesh, with
the mesh's normals for the grazing test and the same ``seen_within`` cover), averaged over the
stage-rig cases, becomes the default. Cases (tests/benchmarks/occlusion_truth.py): the Stanford bunny,
MIT samba frame 0 (a dancer) and two spheres 0.25 radii apart, sampled 8 per voxel^2 and voxelized in
a 10-bit grid, largest extent E voxels. F1, HPR / z-buffer:

    E = 250:  bunny 0.942 / 0.950   samba 0.781 / 0.554   spheres 0.511 / 0.705   mean 0.745 / 0.736
    E = 500:  bunny 0.937 / 0.964   samba 0.782 / 0.748   spheres 0.542 / 0.828   mean 0.754 / 0.847
    E = 1000:                       samba 0.794 / 0.854

At the scale of the data the generator is for (the paper's 8i frames and the 1M stand-ins are about
1000 voxels tall) the z-buffer is closer on every case; at E = 250 the two tie on the mean, HPR ahead
on the dancer (the z-buffer's depth slack, 2 point spacings, lets points through in gaps between limbs
that are only a few spacings wide there: recall 0.44). HPR's errors do not shrink with resolution:
it calls seen the points along the grazing band and in narrow gaps (recall 0.36-0.40 on the spheres).
With the 8-camera sphere rig ray casting leaves 0-35 points unseen on these shapes and both operators
remove 20-200, mostly seen ones: neither is reliable for such tiny sets. CPU: the z-buffer generator
costs 5-7x less than HPR (Longdress, 858k points: 5.8 s against 37.3 s, version 1 measurements).

Consequence on small figures: on the tiny human (186 voxels tall) the default stage rig leaves 2-3
points unseen with the z-buffer (HPR: 20-24); `bench.reporting.paper.STANDIN_OCCLUSION` (one ring of 3 cameras)
is the rig `reproduce-paper` uses for its real-hole rows on the stand-in.

Choices, by measurement (one-off scripts, not kept; timings noisy on the shared 2-core machine):

- z-buffer ``depth_tolerance`` = 2 point spacings, ``splat`` = 1 spacing (kept from version 1's opt-in
  operator): a voxelized surface is 1-2 voxels thick, and a splat of one spacing closes the gaps
  between the samples of a surface. At E = 250 (table above) a depth slack of 1 or 0.5 spacings
  raises samba's F1 from 0.554 to 0.626 / 0.643 (mean of the three cases 0.777 / 0.790); not
  measured at E = 500-1000, so the values stay (`occlusion_truth.py --depth-tolerance` measures it).

- HPR (version 1) radius = 1000 x the camera's distance to the farthest point (``hpr_factor``). On a sampled
  sphere seen from 3 radii, factors 1-100 match the true visible cap exactly and 1000 lets 0.6 %
  extra points near the horizon through (those fail the grazing test anyway); on the Dynamic FAUST
  human (random surface samples) with a 20-camera sphere rig, 100 leaves 11 % of the points unseen,
  scattered over the whole body, while 1000 leaves 1.5 %, in the armpits and between the legs.
- ``seen_within`` = 1.5 point spacings. On voxelized surfaces HPR hides voxels in the one-voxel
  steps of the staircase: on the embedded human (small) 11.2 % of the points were unseen by a
  20-camera sphere rig, every one exactly 1 voxel from a seen point, none on a real hole. Points
  are treated as splats of about one spacing: an unseen point that close to a seen one is covered.

Measured removal with HPR (version 1; frame 0): Dynamic FAUST punching, stage rig 3.1 % (armpits, between the legs,
top of the head, soles), 20-camera sphere rig 0.9 % (armpits, between the legs). Embedded human
(small, walk/dance/wave): stage rig 0.2-0.3 % (crown, tops of the shoulders and arms, soles); an
8-camera sphere rig 0.2-0.3 % in the concavities; a 20-camera sphere rig sees all of it (its limbs
are well apart), so the generator refuses (nothing removed).

Default rig, after a volumetric capture stage: 2 rings of 6 cameras around the vertical axis of the
subject, at 30 % and 80 % of its height, at a horizontal distance of 1.5 bounding-box diagonals
from its centre, all looking at the centre. Such a rig leaves realistic holes: under the arms,
between the legs, on the top of the head and under the chin. ``rig="sphere"`` spreads ``count``
cameras evenly over a sphere (Fibonacci lattice) around the subject; on a convex object it sees
everything.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from dpcbench.holes.base import (
    Colors,
    DamageResult,
    HoleGenerator,
    Seed,
    as_generator,
    check_sequence_input,
    make_result,
)
from dpcbench.holes.geometry import components_to_regions, estimate_normals, point_spacing
from dpcbench.metrics.errors import UserError

_AXES = {"x": 0, "y": 1, "z": 2}


def stage_cameras(points: np.ndarray, rings: Sequence[float] = (0.3, 0.8), per_ring: int = 6, distance: float = 1.5,
                  up: str = "y", azimuth: float = 0.0) -> np.ndarray:
    """Camera positions (rings * per_ring, 3) of a capture stage around ``points``.

    Ring r is at height ``min + rings[r] * height`` along the ``up`` axis, cameras evenly spaced in
    azimuth (starting at ``azimuth`` radians, rings offset by half a step so they interleave), at a
    horizontal distance ``distance * diagonal`` from the bounding-box centre.
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = (lo + hi) / 2
    diag = float(np.linalg.norm(hi - lo))
    u = _AXES[up]
    a, b = [i for i in range(3) if i != u]
    cams = []
    for r, level in enumerate(rings):
        for k in range(per_ring):
            phi = azimuth + 2 * np.pi * (k + 0.5 * (r % 2)) / per_ring
            cam = center.copy()
            cam[a] += distance * diag * np.cos(phi)
            cam[b] += distance * diag * np.sin(phi)
            cam[u] = lo[u] + level * (hi[u] - lo[u])
            cams.append(cam)
    return np.asarray(cams)


def sphere_cameras(points: np.ndarray, count: int = 20, distance: float = 1.5) -> np.ndarray:
    """``count`` cameras on a Fibonacci lattice of a sphere of radius ``distance * diagonal``
    around the bounding-box centre: the most even spread of K directions in closed form."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = (lo + hi) / 2
    diag = float(np.linalg.norm(hi - lo))
    i = np.arange(count) + 0.5
    z = 1 - 2 * i / count
    theta = np.pi * (1 + 5**0.5) * i
    rho = np.sqrt(1 - z**2)
    dirs = np.column_stack([rho * np.cos(theta), rho * np.sin(theta), z])
    return center + distance * diag * dirs


def visible_mask(points: np.ndarray, normals: np.ndarray, cameras: np.ndarray, min_cos: float,
                 hpr_factor: float = 1000.0) -> np.ndarray:
    """Mask (N,) of the points seen by at least one camera (HPR-visible and ``|n.v| >= min_cos``).

    hpr_factor: HPR's spherical-flipping radius as a multiple of the camera's distance to the
    farthest point (Katz et al.: larger is stricter; 100 is open3d's tutorial value).
    """
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    seen = np.zeros(len(points), dtype=bool)
    for cam in cameras:
        far = float(np.sqrt(((points - cam) ** 2).sum(axis=1).max()))
        _, visible = cloud.hidden_point_removal(cam, far * hpr_factor)
        kept = np.asarray(visible, dtype=np.int64)
        view = cam - points[kept]
        view /= np.linalg.norm(view, axis=1, keepdims=True)
        cos = np.abs(np.einsum("ij,ij->i", view, normals[kept]))
        seen[kept[cos >= min_cos]] = True
    return seen


def zbuffer_visible_mask(points: np.ndarray, normals: np.ndarray, cameras: np.ndarray, min_cos: float,
                         spacing: float, center: np.ndarray, depth_tolerance: float = 2.0,
                         splat: float = 1.0, pixels_per_spacing: int = 2) -> np.ndarray:
    """Mask (N,) of the points seen by at least one camera, by a z-buffer of splats (a renderer's test).

    Per camera (pinhole looking at ``center``): each point p projects to pixel
    ``(floor(x / a), floor(y / a))`` with x, y its image-plane coordinates divided by its depth
    z = (p - cam) . forward, and pixel size a = spacing / (pixels_per_spacing * min(z)) (radians).
    The z-buffer holds the nearest depth per pixel; a minimum filter over a square of
    r = round(splat * pixels_per_spacing) pixels each side turns each point into a splat of radius
    ``splat`` point spacings (at the nearest depth), which closes the gaps between the samples of a
    surface (a surface is opaque). p is visible when

        z_p <= zbuf(pixel_p) + spacing * depth_tolerance + r * a * z_p * tan(angle_p)

    where angle_p is the angle between p's normal and its view ray: the splat's reach times the
    surface's slope is how much farther the same surface can lie within the filter's footprint. As
    in `visible_mask`, a point must also be seen at a non-grazing angle (``|n . v| >= min_cos``).

    Written with numpy because no library at hand renders a depth buffer of a bare point set
    (open3d's raycasting needs a mesh, and a reconstruction per frame costs more than HPR did).
    """
    # float32 throughout: coordinates of captured data are far below 2^24, and the depth test's slack
    # is a point spacing, so float32 rounding (1e-7 relative) cannot flip it; it halves the memory traffic.
    # Coordinates are kept as rows (3, N) so that every per-axis step runs over contiguous memory.
    coords_t = np.ascontiguousarray(np.asarray(points, dtype=np.float32).T)
    normals_t = np.ascontiguousarray(np.asarray(normals, dtype=np.float32).T)
    # n . (p - c) = n . p - n . c: the first term once for all cameras
    n_dot_p = np.einsum("in,in->n", normals_t, coords_t)
    seen = np.zeros(coords_t.shape[1], dtype=bool)
    radius = round(splat * pixels_per_spacing)
    world_up = np.array([0.0, 1.0, 0.0])
    for cam in np.asarray(cameras, dtype=np.float64):
        forward = center - cam
        forward /= np.linalg.norm(forward)
        helper = world_up if abs(forward @ world_up) < 0.9 else np.array([1.0, 0.0, 0.0])
        right = np.cross(forward, helper)
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        rel_t = coords_t - cam.astype(np.float32)[:, None]
        x, y, depth = np.vstack([right, up, forward]).astype(np.float32) @ rel_t  # camera frame
        nearest = float(depth.min())
        if nearest <= 0:
            raise UserError(f"occlusion holes: camera {cam.tolist()} has points behind or beside it; place the "
                            "cameras around the subject, looking at it")
        pixel = spacing / nearest / pixels_per_spacing
        scale = depth * np.float32(pixel)
        x /= scale
        y /= scale
        x -= x.min()
        y -= y.min()
        col = x.astype(np.int64)
        col += radius
        row = y.astype(np.int64)
        row += radius
        width = int(col.max()) + radius + 1
        height = int(row.max()) + radius + 1
        flat = row * width + col
        zbuf = np.full(height * width, np.inf, dtype=np.float32)
        np.minimum.at(zbuf, flat, depth)
        if radius > 0:
            zbuf = ndimage.minimum_filter(zbuf.reshape(height, width), size=2 * radius + 1, mode="nearest").ravel()
        # only points not yet seen, facing the camera at a non-grazing angle, can become seen here;
        # |p - c| is the length of the camera-frame coordinates (a rotation keeps it)
        idx = np.flatnonzero(~seen)
        rel = rel_t[:, idx]
        cos = np.abs(n_dot_p[idx] - cam.astype(np.float32) @ normals_t[:, idx])
        cos /= np.sqrt(np.einsum("in,in->n", rel, rel))
        keep = cos >= min_cos
        idx, cos = idx[keep], cos[keep]
        tan = np.sqrt(np.maximum(1.0 - cos * cos, 0.0)) / cos
        depth_idx = depth[idx]
        slack = spacing * depth_tolerance + radius * pixel * depth_idx * tan
        seen[idx[depth_idx <= zbuf[flat[idx]] + slack]] = True
    return seen


def raycast_visible_mask(vertices: np.ndarray, triangles: np.ndarray, points: np.ndarray, normals: np.ndarray,
                         cameras: np.ndarray, min_cos: float, tolerance: float) -> np.ndarray:
    """Mask (N,) of the surface points (N, 3) seen by at least one camera, by ray casting against their
    mesh (vertices (V, 3), triangles (T, 3)): exact visibility where the surface is known (the reference
    the point-set operators are measured against, tests/benchmarks/occlusion_truth.py).

    Camera c sees p when the first hit of the ray from c towards p lies at distance >= |p - c| - tolerance
    (nothing in front of p; tolerance absorbs open3d's float32 ray arithmetic) and |n . v| >= min_cos,
    v = (c - p) / |c - p|, n the unit normal (N, 3) of p's face (the generator's grazing test).
    """
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor.from_numpy(np.ascontiguousarray(vertices, dtype=np.float32)),
                        o3d.core.Tensor.from_numpy(np.ascontiguousarray(triangles, dtype=np.uint32)))
    points = np.asarray(points, dtype=np.float64)
    seen = np.zeros(len(points), dtype=bool)
    for cam in np.asarray(cameras, dtype=np.float64):
        ray = points - cam
        dist = np.linalg.norm(ray, axis=1)
        direction = ray / dist[:, None]
        cos = np.abs(np.einsum("ij,ij->i", direction, normals))
        rays = np.hstack([np.broadcast_to(cam, points.shape), direction]).astype(np.float32)
        hit = scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()
        seen |= (hit >= dist - tolerance) & (cos >= min_cos)
    return seen


def unseen_after_cover(points: np.ndarray, seen: np.ndarray, within: float, tree: cKDTree | None = None) -> np.ndarray:
    """Mask (N,) of the points not ``seen`` (N,) and farther than ``within`` (a length; 0: off) from every
    seen point. A voxelized surface is 1-2 voxels thick: its inner layer is hidden behind the outer one
    but is no hole, so an unseen point next to a seen one counts as covered (a splat of about one spacing).

    tree: a cKDTree of ``points`` to reuse: then the unseen points query their k nearest of all points
    within ``within`` (k = 16, x4 for the few whose k nearest all lie within and are all unseen), which
    costs less than a tree of the seen points; the result is the same.
    """
    seen = np.asarray(seen, dtype=bool)
    mask = ~seen
    if not (within > 0 and seen.any() and mask.any()):
        return mask
    if tree is None:
        near, _ = cKDTree(points[seen]).query(points[mask], distance_upper_bound=within)
        mask[np.flatnonzero(mask)[np.isfinite(near)]] = False
        return mask
    undecided, k = np.flatnonzero(mask), 16
    while len(undecided):
        k = min(k, len(points))
        dist, nbr = tree.query(points[undecided], k=k, distance_upper_bound=within)
        inside = np.isfinite(dist)
        covered = (inside & seen[np.where(inside, nbr, 0)]).any(axis=1)
        mask[undecided[covered]] = False
        if k == len(points):
            break
        undecided, k = undecided[~covered & inside[:, -1]], 4 * k
    return mask


class OcclusionHoles(HoleGenerator):
    """Points that no camera of a simulated capture rig sees (at a non-grazing angle) are removed.

    Parameters
    ----------
    rig:       "stage" (rings of cameras around the up axis) or "sphere" (Fibonacci sphere).
    cameras:   explicit camera positions, a list of [x, y, z] (overrides ``rig``).
    rings:     stage ring heights as fractions of the subject's height.
    per_ring:  cameras per stage ring.
    count:     cameras of the sphere rig.
    distance:  camera distance from the centre in bounding-box diagonals.
    up:        "x" | "y" | "z", the vertical axis of the subject (MPEG bodies: "y").
    min_cos:   grazing threshold: seen only if |normal . view| >= min_cos (0.2: angle <= 78 deg).
    random_azimuth: rotate the stage by a random azimuth drawn from the seed (else fixed at 0;
               the damage is then the same for every seed).
    normal_k:  neighbours for the PCA normals.
    seen_within: an unseen point within this many point spacings of a seen point is kept (0: off).
               Voxelized surfaces (8i data, the embedded human) are 1-2 voxels thick; the inner
               layer is hidden behind the outer one everywhere, yet the surface there is captured.
               Measured on the embedded human (small, frame 0, sphere rig): 11.2 % of the points
               unseen without this, and none of them on visible surface (render); see the report.
    max_fraction: refuse a rig that removes more than this fraction of a frame.
    visibility: "zbuffer" (default; `zbuffer_visible_mask`, a z-buffer of splats of one point spacing
               per camera) or "hpr" (version 1's default; open3d hidden point removal, `visible_mask`;
               about 2 s a camera on a 1M-point frame, 5-7x the z-buffer's CPU; farther from ray
               casting on meshes at 500-1000 voxels, see the module docstring).
    depth_tolerance: z-buffer only: a point within this many point spacings behind the nearest
               surface in its pixel is on that surface.
    splat:     z-buffer only: splat radius in point spacings (at the depth nearest the camera).
    Regions are oriented boxes with ``point_count`` (removed points in the piece).
    """

    name = "occlusion"
    summary = ("acquisition holes: points no camera of a simulated capture rig sees "
               "(a z-buffer of splats or open3d HPR, + grazing angle)")
    # "2": the default operator is the z-buffer (version 1: HPR), chosen against ray casting (module docstring)
    version = "2"

    def __init__(self, rig: str = "stage", cameras: Sequence[Sequence[float]] | None = None,
                 rings: Sequence[float] = (0.3, 0.8), per_ring: int = 6, count: int = 20,
                 distance: float = 1.5, up: str = "y", min_cos: float = 0.2, random_azimuth: bool = False,
                 normal_k: int = 16, seen_within: float = 1.5, max_fraction: float = 0.5,
                 visibility: str = "zbuffer", depth_tolerance: float = 2.0, splat: float = 1.0):
        self.rig = rig
        self.cameras = cameras
        self.rings = rings
        self.per_ring = per_ring
        self.count = count
        self.distance = distance
        self.up = up
        self.min_cos = min_cos
        self.random_azimuth = random_azimuth
        self.normal_k = normal_k
        self.seen_within = seen_within
        self.max_fraction = max_fraction
        self.visibility = visibility
        self.depth_tolerance = depth_tolerance
        self.splat = splat

    def _check(self) -> None:
        if self.visibility not in ("zbuffer", "hpr"):
            raise UserError(f"occlusion holes: visibility must be 'zbuffer' or 'hpr', got {self.visibility!r}")
        if not self.depth_tolerance >= 0:
            raise UserError("occlusion holes: depth_tolerance must be >= 0 (point spacings), "
                            f"got {self.depth_tolerance!r}")
        if not 0 <= self.splat <= 5:
            raise UserError(f"occlusion holes: splat must be from 0 to 5 (point spacings), got {self.splat!r}")
        if self.rig not in ("stage", "sphere"):
            raise ValueError(f"occlusion holes: rig must be 'stage' or 'sphere', got {self.rig!r}")
        if self.up not in _AXES:
            raise ValueError(f"occlusion holes: up must be 'x', 'y' or 'z', got {self.up!r}")
        if not 0 <= self.min_cos < 1:
            raise ValueError(f"occlusion holes: min_cos must be in [0, 1), got {self.min_cos!r}")
        if not self.distance > 0.5:
            raise ValueError(
                f"occlusion holes: distance {self.distance!r} (in bounding-box diagonals) would put cameras "
                "inside the subject; use a value above 0.5"
            )
        if self.cameras is None:
            if self.rig == "stage" and (int(self.per_ring) < 1 or len(self.rings) < 1):
                raise ValueError("occlusion holes: the stage rig needs at least one ring with one camera")
            if self.rig == "sphere" and int(self.count) < 1:
                raise ValueError(f"occlusion holes: count must be >= 1, got {self.count!r}")
        if not self.seen_within >= 0:
            raise ValueError(f"occlusion holes: seen_within must be >= 0 (point spacings), got {self.seen_within!r}")
        if not 4 <= int(self.normal_k):
            raise ValueError(f"occlusion holes: normal_k must be >= 4, got {self.normal_k!r}")

    def _cameras(self, points, azimuth):
        if self.cameras is not None:
            cams = np.asarray(self.cameras, dtype=np.float64)
            if cams.ndim != 2 or cams.shape[1] != 3 or not np.isfinite(cams).all():
                raise UserError(
                    f"occlusion holes: cameras must be a list of [x, y, z] positions, got shape {cams.shape}")
            lo, hi = points.min(axis=0), points.max(axis=0)
            inside = ((cams >= lo) & (cams <= hi)).all(axis=1)
            if inside.any():
                raise UserError(
                    f"occlusion holes: camera(s) {np.flatnonzero(inside).tolist()} lie inside the subject's "
                    f"bounding box {lo.tolist()} - {hi.tolist()}; place cameras around the subject"
                )
            return cams
        if self.rig == "sphere":
            return sphere_cameras(points, int(self.count), self.distance)
        return stage_cameras(points, tuple(self.rings), int(self.per_ring), self.distance, self.up, azimuth)

    def occluded_mask(self, points: np.ndarray, azimuth: float = 0.0, spacing: float | None = None,
                      tree: cKDTree | None = None) -> np.ndarray:
        """Mask (N,) of the points of one frame (N, 3) that the rig does not see (what `damage` removes):
        PCA normals, the cameras (stage rig turned by ``azimuth`` radians), the visibility operator, then
        `unseen_after_cover` with ``seen_within``. spacing: `point_spacing` of ``points`` (computed if None);
        tree: a cKDTree of ``points`` to reuse (built if None)."""
        self._check()
        pts = np.asarray(points, dtype=np.float64)
        tree = cKDTree(pts) if tree is None else tree
        if spacing is None:
            spacing = point_spacing(pts, tree)
        normals = estimate_normals(pts, int(self.normal_k))
        cams = self._cameras(pts, azimuth)
        if self.visibility == "hpr":
            seen = visible_mask(pts, normals, cams, self.min_cos)
        else:
            center = (pts.min(axis=0) + pts.max(axis=0)) / 2
            seen = zbuffer_visible_mask(pts, normals, cams, self.min_cos, spacing, center,
                                        float(self.depth_tolerance), float(self.splat))
        return unseen_after_cover(pts, seen, float(self.seen_within) * spacing, tree)

    def damage(self, frames: list[np.ndarray], seed: Seed, colors: Colors = None) -> DamageResult:
        frames, colors = check_sequence_input(frames, colors, "occlusion holes")
        self._check()
        rng = as_generator(seed)
        azimuth = float(rng.uniform(0, 2 * np.pi)) if self.random_azimuth else 0.0
        regions, removed = [], []
        for f, pts in enumerate(frames):
            if len(pts) < self.normal_k:
                raise ValueError(
                    f"occlusion holes: frame {f} has {len(pts)} points, fewer than normal_k={self.normal_k}")
            tree = cKDTree(pts)
            spacing = point_spacing(pts, tree)
            mask = self.occluded_mask(pts, azimuth, spacing, tree)
            frame_regions, _ = (components_to_regions(pts[mask], 3 * spacing, margin=spacing)
                                if mask.any() else ([], None))
            regions.append(frame_regions)
            removed.append(mask)
        return make_result(frames, removed, regions, colors, what="occlusion holes", max_fraction=self.max_fraction)
