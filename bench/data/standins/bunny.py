"""The Stanford bunny (a real 3D scan, shipped by pymeshlab as a sample mesh) deformed non-rigidly and
moving rigidly, resampled independently for every frame.

Per frame at time t = index / fps (seconds), with the mesh normalized to unit extent, ``y`` its
height above its lowest point (0..~1):

1. bend:  x += 0.12 * deform * sin(2 pi t / 1.6) * y^2          (the ears and head sway sideways)
2. twist: rotate about the vertical axis through the centre by 25 * deform * sin(2 pi t / 2.2) * y deg
3. bumps: v += n_v * sum_i 0.035 * deform * exp(-|v - c_i(t)|^2 / (2 * 0.12^2)) for three bump
   centres c_i(t) circling the body at different speeds (n_v: rest vertex normal)
4. rigid: rotation about the vertical axis by ``turn`` deg/s * t, and a 4 cm (x0.1 extent) sway in x.

Resampling: area-weighted random points on the deformed triangles with
``numpy.random.default_rng((seed, frame))``. With ``bit_depth`` the figure (extent ``height``
voxels) is placed in the grid [0, 2^bit_depth)^3 and the samples (8 per unit of voxel area, enough to
hit every surface voxel) are rounded down to voxel indices, one point per occupied voxel, each voxel
coloured with the mean colour of its samples; with ``bit_depth=None`` the frame is ``points`` float
samples in the unit-extent frame scaled by 1000. Colours are a procedural fur pattern of the rest
position (so it moves with the surface) plus per-point noise.

Normals: the deformed mesh's vertex normals (area-weighted face normals, open3d
``compute_vertex_normals``) interpolated at each sample with its barycentric weights (Phong normals)
and normalized; a voxel's normal is the normalized mean of its samples' normals (like its colour).
They are written into the frames' PLY files (float nx, ny, nz), so that D2 uses them, as pc_error
does with the reference's normals.
"""

from __future__ import annotations

import os
from functools import lru_cache

import numpy as np

#: bump when the output for the same parameters changes (part of the cache key); 2: frames carry normals
GENERATOR_VERSION = 2
SIZE_EXTENTS = {"tiny": 80, "small": 180, "default": 460}  # largest extent in voxels
SIZE_POINTS = {"tiny": 20_000, "small": 100_000, "default": 600_000}  # samples when not voxelized
SAMPLES_PER_VOXEL_AREA = 8.0


def bunny_path() -> str:
    """Path of pymeshlab's sample ``bunny.obj``."""
    import pymeshlab

    return os.path.join(os.path.dirname(pymeshlab.__file__), "tests", "sample_meshes", "bunny.obj")


@lru_cache(maxsize=1)
def rest_mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (T, 3) int, vertex normals (V, 3)): the bunny with its lowest point at
    y = 0, centred in x and z, scaled to unit largest extent."""
    import open3d as o3d

    path = bunny_path()
    if not os.path.isfile(path):
        raise ValueError(f"the bunny mesh is missing from the pymeshlab install ({path}); reinstall pymeshlab")
    mesh = o3d.io.read_triangle_mesh(path)  # type: ignore[arg-type]  # open3d's stub omits str, which it takes
    mesh.compute_vertex_normals()
    v = np.asarray(mesh.vertices, dtype=np.float64)
    lo, hi = v.min(0), v.max(0)
    v = (v - np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])) / (hi - lo).max()
    return v, np.asarray(mesh.triangles, dtype=np.int64), np.asarray(mesh.vertex_normals, dtype=np.float64)


def _rot_y(deg: np.ndarray | float) -> np.ndarray:
    t = np.radians(deg)
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def deform(v: np.ndarray, n: np.ndarray, t: float, amount: float, turn: float) -> np.ndarray:
    """Deformed and moved vertices (V, 3) at time t (see the module docstring for the formulas)."""
    y = v[:, 1:2]
    out = v.copy()
    out[:, 0:1] += 0.12 * amount * np.sin(2 * np.pi * t / 1.6) * y ** 2
    twist = 25.0 * amount * np.sin(2 * np.pi * t / 2.2) * v[:, 1]
    out = np.einsum("vij,vj->vi", _rot_y(twist), out)
    bump = np.zeros(len(v))
    for i, speed in enumerate((0.7, -0.45, 0.3)):
        angle = 2 * np.pi * (speed * t + i / 3)
        centre = np.array([0.35 * np.cos(angle), 0.2 + 0.15 * i, 0.35 * np.sin(angle)])
        bump += 0.035 * amount * np.exp(-((v - centre) ** 2).sum(1) / (2 * 0.12 ** 2))
    out += n * bump[:, None]
    out = out @ _rot_y(turn * t).T
    out[:, 0] += 0.1 * np.sin(2 * np.pi * t / 3.0)
    return out


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit vertex normals (V, 3) of a triangle mesh (open3d: area-weighted mean of the face normals)."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(triangles))
    mesh.compute_vertex_normals()
    return np.asarray(mesh.vertex_normals, dtype=np.float64)


def _unit(vectors: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Rows of ``vectors`` scaled to unit length; rows of (near) zero length take ``fallback``'s row."""
    norm = np.linalg.norm(vectors, axis=1)
    flat = ~(norm > 1e-9)
    if flat.any():
        vectors, norm = vectors.copy(), norm.copy()
        vectors[flat] = fallback[flat]
        norm[flat] = np.linalg.norm(fallback[flat], axis=1)
    return vectors / norm[:, None]


def _fur(rest: np.ndarray) -> np.ndarray:
    """Procedural colour (n, 3) float of rest positions: light brown with darker patches, pale chest."""
    base = np.array([176.0, 140.0, 104.0])
    patches = (np.sin(11 * rest[:, 0] + 3) * np.sin(9 * rest[:, 1]) * np.sin(13 * rest[:, 2] + 1)) > 0.25
    colour = np.where(patches[:, None], base * 0.6, base)
    belly = (rest[:, 0] < -0.22) & (rest[:, 1] < 0.32)  # the bunny faces -x: a pale chest
    colour[belly] = [226, 216, 200]
    return colour


def generate_frame(index: int, *, bit_depth: int | None = 10, size: str = "default", height: float | None = None,
                   points: int | None = None, fps: float = 30.0, deform_amount: float = 1.0, turn: float = 12.0,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame ``index``: (points (N, 3) float64, colours (N, 3) uint8, unit outward normals (N, 3)
    float64). Voxelized (integer-valued in [0, 2^bit_depth)) unless ``bit_depth`` is None."""
    if size not in SIZE_EXTENTS:
        raise ValueError(f"unknown size {size!r}; choose one of {', '.join(SIZE_EXTENTS)}")
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps!r}")
    v, tri, n = rest_mesh()
    moved = deform(v, n, index / fps, deform_amount, turn)
    rng = np.random.default_rng((int(seed), int(index)))
    a, b, c = moved[tri[:, 0]], moved[tri[:, 1]], moved[tri[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if bit_depth is not None:
        bit_depth = int(bit_depth)
        if not 4 <= bit_depth <= 16:
            raise ValueError(f"bit_depth must be an integer in 4..16 or None, got {bit_depth!r}")
        grid = 2 ** bit_depth
        extent = float(height if height is not None else SIZE_EXTENTS[size])
        # 0.45: the moving, twisting bunny reaches about 1.03 extents from the vertical axis
        if not 8 <= extent <= 0.45 * grid:
            raise ValueError(f"bunny extent {extent:g} voxels does not fit a {bit_depth}-bit grid with room to "
                             f"move: use 8..{0.45 * grid:g} or a larger bit_depth")
        count = int(SAMPLES_PER_VOXEL_AREA * area.sum() * extent ** 2)
    else:
        count = int(points if points is not None else SIZE_POINTS[size])
        if count < 1:
            raise ValueError(f"points must be positive, got {points!r}")
    face = rng.choice(len(tri), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    flip = r1 + r2 > 1  # fold the unit square onto the triangle: uniform barycentric coordinates
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    w = np.stack([1 - r1 - r2, r1, r2], 1)
    tri_f = tri[face]
    samples = np.einsum("nk,nkj->nj", w, moved[tri_f])
    colour = _fur(np.einsum("nk,nkj->nj", w, v[tri_f]))
    # the moves are a uniform scale away from the voxel / millimetre frame: normals keep their direction
    face_normal = np.cross(moved[tri_f[:, 1]] - moved[tri_f[:, 0]], moved[tri_f[:, 2]] - moved[tri_f[:, 0]])
    normal = np.einsum("nk,nkj->nj", w, vertex_normals(moved, tri)[tri_f])
    if bit_depth is None:
        colour = colour + rng.normal(0.0, 5.0, colour.shape)
        return samples * 1000.0, np.clip(np.rint(colour), 0, 255).astype(np.uint8), _unit(normal, face_normal)
    centre = np.array([grid / 2.0, 0.1 * grid, grid / 2.0])
    vox = np.floor(samples * extent + centre).astype(np.int64)
    if vox.min() < 0 or vox.max() >= grid:  # guarded by the extent limit above; never clip silently
        raise ValueError(f"the deformed bunny leaves the {bit_depth}-bit grid; lower height or deform_amount")
    keys = (vox[:, 0] * grid + vox[:, 1]) * grid + vox[:, 2]
    unique_keys, inverse = np.unique(keys, return_inverse=True)
    counts = np.bincount(inverse)
    mean = np.stack([np.bincount(inverse, weights=colour[:, j]) for j in range(3)], 1) / counts[:, None]
    mean = mean * rng.uniform(0.92, 1.08, size=(len(mean), 1)) + rng.normal(0.0, 4.0, mean.shape)
    pts = np.stack([unique_keys // (grid * grid), (unique_keys // grid) % grid, unique_keys % grid], 1)
    normal = _unit(normal, face_normal)
    voxel_normal = np.stack([np.bincount(inverse, weights=normal[:, j]) for j in range(3)], 1)
    first = np.zeros(len(unique_keys), dtype=np.int64)
    first[inverse[::-1]] = np.arange(len(inverse))[::-1]  # a voxel's first sample (fallback where they cancel)
    return pts.astype(np.float64), np.clip(np.rint(mean), 0, 255).astype(np.uint8), _unit(voxel_normal, normal[first])
