"""The Stanford bunny (a real 3D scan, shipped by pymeshlab as a sample mesh) deformed non-rigidly and
moving rigidly, resampled independently for every frame.

Per frame at time t = index / fps (seconds), with the mesh normalized to unit extent, ``y`` its
height above its lowest point (0..~1):

1. bend:  x += 0.12 * deform * sin(2 pi t / 1.6) * y^2          (the ears and head sway sideways)
2. twist: rotate about the vertical axis through the centre by 25 * deform * sin(2 pi t / 2.2) * y deg
3. bumps: v += n_v * sum_i 0.035 * deform * exp(-|v - c_i(t)|^2 / (2 * 0.12^2)) for three bump
   centres c_i(t) circling the body at different speeds (n_v: rest vertex normal)
4. rigid: rotation about the vertical axis by ``turn`` deg/s * t, and a 4 cm (x0.1 extent) sway in x.

Resampling, voxelization and normals: `moving_mesh.sample_frame` (area-weighted random points on the deformed
triangles with ``numpy.random.default_rng((seed, frame))``, 8 samples per unit of voxel area rounded to voxels, or
``points`` float samples scaled by 1000; Phong normals). Colours are a procedural fur pattern of the rest position
(so it moves with the surface) plus per-point noise.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from dpcbench.bench.data.standins.moving_mesh import check_size, normalized_mesh, rot_y, sample_frame, sample_mesh_path

#: bump when the output for the same parameters changes (part of the cache key); 2: frames carry normals
GENERATOR_VERSION = 2
SIZE_EXTENTS = {"tiny": 80, "small": 180, "default": 460}  # largest extent in voxels
SIZE_POINTS = {"tiny": 20_000, "small": 100_000, "default": 600_000}  # samples when not voxelized
#: 0.45: the moving, twisting bunny reaches about 1.03 extents from the vertical axis
ROOM = 0.45


def bunny_path() -> str:
    """Path of pymeshlab's sample ``bunny.obj``."""
    return sample_mesh_path("bunny.obj")


@lru_cache(maxsize=1)
def rest_mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (T, 3) int, vertex normals (V, 3)): the bunny with its lowest point at
    y = 0, centred in x and z, scaled to unit largest extent."""
    return normalized_mesh(bunny_path(), "bunny")


def deform(v: np.ndarray, n: np.ndarray, t: float, amount: float, turn: float) -> np.ndarray:
    """Deformed and moved vertices (V, 3) at time t (see the module docstring for the formulas)."""
    y = v[:, 1:2]
    out = v.copy()
    out[:, 0:1] += 0.12 * amount * np.sin(2 * np.pi * t / 1.6) * y ** 2
    twist = 25.0 * amount * np.sin(2 * np.pi * t / 2.2) * v[:, 1]
    out = np.einsum("vij,vj->vi", rot_y(twist), out)
    bump = np.zeros(len(v))
    for i, speed in enumerate((0.7, -0.45, 0.3)):
        angle = 2 * np.pi * (speed * t + i / 3)
        centre = np.array([0.35 * np.cos(angle), 0.2 + 0.15 * i, 0.35 * np.sin(angle)])
        bump += 0.035 * amount * np.exp(-((v - centre) ** 2).sum(1) / (2 * 0.12 ** 2))
    out += n * bump[:, None]
    out = out @ rot_y(turn * t).T
    out[:, 0] += 0.1 * np.sin(2 * np.pi * t / 3.0)
    return out


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
    check_size(size, SIZE_EXTENTS, fps)
    v, tri, n = rest_mesh()
    moved = deform(v, n, index / fps, deform_amount, turn)
    rng = np.random.default_rng((int(seed), int(index)))
    extent = float(height if height is not None else SIZE_EXTENTS[size])
    return sample_frame(v, tri, moved, _fur, rng, bit_depth=bit_depth, extent=extent,
                        points=points if points is not None else SIZE_POINTS[size], room=ROOM, name="bunny")
