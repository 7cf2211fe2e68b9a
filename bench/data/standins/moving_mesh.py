"""What the mesh stand-ins (`bunny`, `cow`) share: a rest mesh read from pymeshlab's sample meshes, and one frame
sampled from its moved vertices, as float samples or voxelized like 8i data.

Sampling (`sample_frame`): area-weighted random points on the moved triangles (``rng``, the caller's
``numpy.random.default_rng((seed, frame))``). Voxelized (``bit_depth``): the figure, ``extent`` voxels across at
rest, is placed in the grid [0, 2^bit_depth)^3 with its vertical axis at the grid's centre and its lowest rest point
0.1 of the grid up; the samples (8 per unit of voxel area, enough to hit every surface voxel) are rounded down to
voxel indices, one point per occupied voxel, each voxel coloured with the mean colour of its samples (then a
per-voxel gain and noise). Float (``bit_depth=None``): ``points`` samples in the unit-extent frame scaled by 1000
(millimetres for a figure one metre long), colours with per-point noise.

Normals: the moved mesh's vertex normals (area-weighted face normals, open3d ``compute_vertex_normals``)
interpolated at each sample with its barycentric weights (Phong normals) and normalized; a voxel's normal is the
normalized mean of its samples' normals (like its colour). The frames' PLY files carry them, so that D2 uses them,
as pc_error does with the reference's normals.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

SAMPLES_PER_VOXEL_AREA = 8.0


def sample_mesh_path(filename: str) -> str:
    """Path of one of pymeshlab's sample meshes (``tests/sample_meshes/<filename>``)."""
    import pymeshlab

    return os.path.join(os.path.dirname(pymeshlab.__file__), "tests", "sample_meshes", filename)


def normalized_mesh(path: str, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (T, 3) int, vertex normals (V, 3)) of the mesh at ``path``, its lowest point at
    y = 0, centred in x and z, scaled to unit largest extent; ValueError naming ``name`` when the file is missing."""
    import open3d as o3d

    if not os.path.isfile(path):
        raise ValueError(f"the {name} mesh is missing from the pymeshlab install ({path}); reinstall pymeshlab")
    mesh = o3d.io.read_triangle_mesh(path)  # type: ignore[arg-type]  # open3d's stub omits str, which it takes
    mesh.compute_vertex_normals()
    v = np.asarray(mesh.vertices, dtype=np.float64)
    lo, hi = v.min(0), v.max(0)
    v = (v - np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])) / (hi - lo).max()
    return v, np.asarray(mesh.triangles, dtype=np.int64), np.asarray(mesh.vertex_normals, dtype=np.float64)


def rot_y(deg: np.ndarray | float) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about the vertical (y) axis by ``deg`` degrees."""
    t = np.radians(deg)
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit vertex normals (V, 3) of a triangle mesh (open3d: area-weighted mean of the face normals)."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(triangles))
    mesh.compute_vertex_normals()
    return np.asarray(mesh.vertex_normals, dtype=np.float64)


def unit_rows(vectors: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Rows of ``vectors`` scaled to unit length; rows of (near) zero length take ``fallback``'s row."""
    norm = np.linalg.norm(vectors, axis=1)
    flat = ~(norm > 1e-9)
    if flat.any():
        vectors, norm = vectors.copy(), norm.copy()
        vectors[flat] = fallback[flat]
        norm[flat] = np.linalg.norm(fallback[flat], axis=1)
    return vectors / norm[:, None]


def check_size(size: str, extents: dict, fps: float) -> None:
    """ValueError for a size not in ``extents`` or a non-positive ``fps``."""
    if size not in extents:
        raise ValueError(f"unknown size {size!r}; choose one of {', '.join(extents)}")
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps!r}")


def sample_frame(rest: np.ndarray, triangles: np.ndarray, moved: np.ndarray, colour_of: Callable, rng, *,
                 bit_depth: int | None, extent: float, points: int, room: float, name: str
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One frame of a moving mesh (the module docstring): (points (N, 3) float64, colours (N, 3) uint8, unit
    normals (N, 3) float64). ``rest`` and ``moved``: the (V, 3) vertices at rest and in this frame (unit extent);
    ``colour_of``: rest positions (n, 3) -> float colours (n, 3); ``extent``: voxels across (voxelized) and
    ``points``: samples (float); ``room``: the largest ``extent`` as a share of the grid's side that leaves the moving
    figure room to move (8 <= extent <= room * 2^bit_depth)."""
    a, b, c = moved[triangles[:, 0]], moved[triangles[:, 1]], moved[triangles[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if bit_depth is not None:
        bit_depth = int(bit_depth)
        if not 4 <= bit_depth <= 16:
            raise ValueError(f"bit_depth must be an integer in 4..16 or None, got {bit_depth!r}")
        grid = 2 ** bit_depth
        limit = room * grid
        if not 8 <= extent <= limit:
            raise ValueError(f"{name} extent {extent:g} voxels does not fit a {bit_depth}-bit grid with room to "
                             f"move: use 8..{limit:g} or a larger bit_depth")
        count = int(SAMPLES_PER_VOXEL_AREA * area.sum() * extent ** 2)
    else:
        count = int(points)
        if count < 1:
            raise ValueError(f"points must be positive, got {points!r}")
    face = rng.choice(len(triangles), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    flip = r1 + r2 > 1  # fold the unit square onto the triangle: uniform barycentric coordinates
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    w = np.stack([1 - r1 - r2, r1, r2], 1)
    tri_f = triangles[face]
    samples = np.einsum("nk,nkj->nj", w, moved[tri_f])
    colour = colour_of(np.einsum("nk,nkj->nj", w, rest[tri_f]))
    # the moves are a uniform scale away from the voxel / millimetre frame: normals keep their direction
    face_normal = np.cross(moved[tri_f[:, 1]] - moved[tri_f[:, 0]], moved[tri_f[:, 2]] - moved[tri_f[:, 0]])
    normal = np.einsum("nk,nkj->nj", w, vertex_normals(moved, triangles)[tri_f])
    if bit_depth is None:
        colour = colour + rng.normal(0.0, 5.0, colour.shape)
        return samples * 1000.0, np.clip(np.rint(colour), 0, 255).astype(np.uint8), unit_rows(normal, face_normal)
    centre = np.array([grid / 2.0, 0.1 * grid, grid / 2.0])
    vox = np.floor(samples * extent + centre).astype(np.int64)
    if vox.min() < 0 or vox.max() >= grid:  # guarded by the extent limit above; never clip silently
        raise ValueError(f"the moving {name} leaves the {bit_depth}-bit grid; lower height or deform_amount")
    keys = (vox[:, 0] * grid + vox[:, 1]) * grid + vox[:, 2]
    unique_keys, inverse = np.unique(keys, return_inverse=True)
    counts = np.bincount(inverse)
    mean = np.stack([np.bincount(inverse, weights=colour[:, j]) for j in range(3)], 1) / counts[:, None]
    mean = mean * rng.uniform(0.92, 1.08, size=(len(mean), 1)) + rng.normal(0.0, 4.0, mean.shape)
    pts = np.stack([unique_keys // (grid * grid), (unique_keys // grid) % grid, unique_keys % grid], 1)
    normal = unit_rows(normal, face_normal)
    voxel_normal = np.stack([np.bincount(inverse, weights=normal[:, j]) for j in range(3)], 1)
    first = np.zeros(len(unique_keys), dtype=np.int64)
    first[inverse[::-1]] = np.arange(len(inverse))[::-1]  # a voxel's first sample (fallback where they cancel)
    return pts.astype(np.float64), np.clip(np.rint(mean), 0, 255).astype(np.uint8), unit_rows(voxel_normal, normal[first])
