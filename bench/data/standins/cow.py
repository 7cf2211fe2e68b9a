"""A walking cow: the cow of pymeshlab's sample meshes (a four-legged animal, 2,903 vertices) with its legs swinging
in a walk, its head nodding and its tail swishing while it turns, resampled independently for every frame. A shape
and a motion that no default of any method was judged on: thin limbs that swing past one another, a head and a tail
standing out of the body.

Per frame at time t = index / fps (seconds), with the mesh normalized to unit extent (its length along z, the
head at +z, up +y, its lowest point at y = 0), every angle times ``deform_amount``, smoothstep(s) = 3 s^2 - 2 s^3
on s clipped to [0, 1], and R_a(theta) the rotation about axis a through a pivot p, applied as
v += w(v) (R_a(theta) (v - p) - (v - p)) with the weight w in [0, 1]:

1. legs: each leg L (centre (x_L, z_L) of its lowest points: x_L = +-0.095, z_L = -0.362 hind and 0.119 front)
   swings about the x axis through its hip or shoulder p_L = (x_L, 0.30, z_L) by 22 deg sin(2 pi t / 1.1 + phi_L),
   the diagonal pairs in phase (phi = 0 front left and hind right, pi the others: a walk's trot);
   w = smoothstep((0.24 - y) / 0.10) smoothstep((0.09 - d_L) / 0.045), d_L the distance from the leg's axis in
   (x, z): the leg below the belly rigidly, blending into the flank above it;
2. head: nods about the x axis through the neck (0, 0.45, 0.25) by 12 deg sin(2 pi t / 2.2),
   w = smoothstep((z - 0.20) / 0.10);
3. tail: swishes about the z axis through its root (0, 0.50, -0.46) by 25 deg sin(2 pi t / 0.9),
   w = smoothstep((-0.42 - z) / 0.04) smoothstep((0.52 - y) / 0.10);
4. rigid: rotation about the vertical axis by ``turn`` deg/s * t, a sway of 0.1 extent sin(2 pi t / 3) in x and a
   step bob of 0.01 extent sin(2 pi t / 0.55) in y.

Resampling, voxelization and normals: `moving_mesh.sample_frame`, as the bunny's (``numpy.random.default_rng((seed,
frame))``; voxelized at ``bit_depth`` with the cow ``height`` voxels long, or ``points`` float samples scaled by
1000). Colours: a Holstein pattern of the rest position (white with black patches, a pink muzzle, dark hooves), so
it moves with the surface, plus per-point noise.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from dpcbench.bench.data.standins.moving_mesh import check_size, normalized_mesh, rot_y, sample_frame, sample_mesh_path

#: bump when the output for the same parameters changes (part of the cache key)
GENERATOR_VERSION = 1
#: the cow's length in voxels: about 24k, 100k and 600k points a frame at 10 bits (measured, `generate_frame`)
SIZE_EXTENTS = {"tiny": 140, "small": 286, "default": 700}
SIZE_POINTS = {"tiny": 20_000, "small": 100_000, "default": 600_000}  # samples when not voxelized
#: the moving cow stays within 0.65 lengths of the vertical axis (0.62 over 300 frames at the defaults): a length of
#: 0.7 of the grid leaves it room (a larger deform_amount that leaves the grid is refused, `sample_frame`)
ROOM = 0.7
#: (x, z) of each leg's axis (the centre of its points below y = 0.08), with its phase in the walk
LEGS = (((-0.095, 0.119), 0.0), ((0.095, -0.362), 0.0), ((0.095, 0.119), np.pi), ((-0.095, -0.362), np.pi))


def cow_path() -> str:
    """Path of pymeshlab's sample ``cow.obj``."""
    return sample_mesh_path("cow.obj")


@lru_cache(maxsize=1)
def rest_mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (T, 3) int, vertex normals (V, 3)): the cow with its lowest point at y = 0,
    centred in x and z, scaled to unit largest extent (its length)."""
    return normalized_mesh(cow_path(), "cow")


def _smoothstep(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _rot_x(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _turned(v: np.ndarray, weight: np.ndarray, rotation: np.ndarray, pivot) -> np.ndarray:
    """v + w (R (v - p) - (v - p)): ``v`` (V, 3) turned by ``rotation`` about ``pivot``, each vertex by its
    ``weight`` (V,)."""
    rel = v - np.asarray(pivot, dtype=np.float64)
    return v + weight[:, None] * (rel @ rotation.T - rel)


def deform(v: np.ndarray, t: float, amount: float, turn: float) -> np.ndarray:
    """Moved vertices (V, 3) at time t (the module docstring's formulas), from the rest vertices ``v``."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    out = v.copy()
    below_belly = _smoothstep((0.24 - y) / 0.10)
    for (leg_x, leg_z), phase in LEGS:
        near = _smoothstep((0.09 - np.hypot(x - leg_x, z - leg_z)) / 0.045)
        angle = 22.0 * amount * np.sin(2 * np.pi * t / 1.1 + phase)
        out = _turned(out, below_belly * near, _rot_x(angle), (leg_x, 0.30, leg_z))
    out = _turned(out, _smoothstep((z - 0.20) / 0.10), _rot_x(12.0 * amount * np.sin(2 * np.pi * t / 2.2)),
                  (0.0, 0.45, 0.25))
    out = _turned(out, _smoothstep((-0.42 - z) / 0.04) * _smoothstep((0.52 - y) / 0.10),
                  _rot_z(25.0 * amount * np.sin(2 * np.pi * t / 0.9)), (0.0, 0.50, -0.46))
    out = out @ rot_y(turn * t).T
    out[:, 0] += 0.1 * np.sin(2 * np.pi * t / 3.0)
    out[:, 1] += 0.01 * np.sin(2 * np.pi * t / 0.55)
    return out


def _holstein(rest: np.ndarray) -> np.ndarray:
    """Procedural colour (n, 3) float of rest positions: white with black patches, a pink muzzle, dark hooves."""
    x, y, z = rest[:, 0], rest[:, 1], rest[:, 2]
    patches = (np.sin(23 * x + 1) * np.sin(17 * y + 2) * np.sin(19 * z)) > 0.2
    colour = np.where(patches[:, None], [34.0, 30.0, 30.0], [236.0, 234.0, 228.0])
    colour[(z > 0.44) & (y < 0.50)] = [224.0, 168.0, 160.0]
    colour[y < 0.02] = [60.0, 52.0, 48.0]
    return colour


def generate_frame(index: int, *, bit_depth: int | None = 10, size: str = "default", height: float | None = None,
                   points: int | None = None, fps: float = 30.0, deform_amount: float = 1.0, turn: float = 12.0,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame ``index``: (points (N, 3) float64, colours (N, 3) uint8, unit outward normals (N, 3) float64).
    Voxelized (integer-valued in [0, 2^bit_depth)) unless ``bit_depth`` is None; ``height``: the cow's length in
    voxels (default by ``size``)."""
    check_size(size, SIZE_EXTENTS, fps)
    v, tri, _ = rest_mesh()
    moved = deform(v, index / fps, deform_amount, turn)
    rng = np.random.default_rng((int(seed), int(index)))
    extent = float(height if height is not None else SIZE_EXTENTS[size])
    return sample_frame(v, tri, moved, _holstein, rng, bit_depth=bit_depth, extent=extent,
                        points=points if points is not None else SIZE_POINTS[size], room=ROOM, name="cow")
