"""Procedural human figure in motion, voxelized like the 8i Voxelized Full Bodies.

The body is a smooth union (polynomial smooth-min, blend radius ``BLEND_M``) of round cones (limbs,
neck, hands, feet) and ellipsoids (pelvis, abdomen, chest, head, hair cap, nose) attached to a
skeleton of 21 joints. Forward kinematics: a joint's world rotation is its parent's world rotation
times its own local rotation (a function of time for the chosen motion), and a child joint sits at
``P_child = P_joint + R_world(joint) @ (rest_child - rest_joint)``. After posing, the figure is moved
vertically so the lowest foot touches the floor.

Voxelization: the figure (in metres) is scaled so its rest height is ``height`` voxels, centred in x
and z in the grid [0, 2^bit_depth)^3, its feet at ``FLOOR`` of the grid height. A frame's points are
the integer indices of the voxels whose cube the zero level set crosses (one point per occupied
surface voxel, as in 8i data). Each frame is voxelized independently, so there is no point
correspondence between frames.

Colours: each surface voxel takes the material of its nearest primitive (skin, shirt, trousers, hair,
shoes; sleeves end half-way down the upper arm, the shirt has stripes in the chest's frame, so the
pattern moves with the body), plus per-voxel noise from ``numpy.random.default_rng((seed, frame))``.

Normals: the exact outward unit normal of the body's field at each output point (the integer voxel
index written to the PLY), n = grad f / |grad f|, from the analytic gradients of the primitives and of
the smooth minimum (`bench.data.standins.sdf.SmoothUnion.normals`). They are written into the frames' PLY
files (float nx, ny, nz), so that D2 uses them, as pc_error does with the reference's normals.
"""

from __future__ import annotations

import numpy as np

from dpcbench.bench.data.standins.sdf import Ellipsoid, RoundCone, SmoothUnion, surface_voxels

#: bump when the output for the same parameters changes (part of the cache key); 5: frames carry normals
GENERATOR_VERSION = 5

MOTIONS = ("walk", "dance", "wave")
#: figure height (rest pose, voxels) per size preset; None -> a fraction of the grid, see frame_params
SIZE_HEIGHTS = {"tiny": 180, "small": 360, "default": None}
DEFAULT_HEIGHT_FRACTION = 0.86  # 8i figures fill most of the 1024 height; raised arms need headroom
FLOOR = 0.02
BLEND_M = 0.02  # smooth-union blend radius, metres

# joint: (parent, rest position in metres; x = the figure's left, y = up, z = forward)
JOINTS: dict[str, tuple[str | None, tuple[float, float, float]]] = {
    "root": (None, (0.0, 0.97, 0.0)),
    "spine": ("root", (0.0, 1.10, 0.0)),
    "chest": ("spine", (0.0, 1.30, 0.0)),
    "neck": ("chest", (0.0, 1.50, 0.0)),
    "head": ("neck", (0.0, 1.59, 0.0)),
}
for _side, _x in (("l", 1.0), ("r", -1.0)):
    JOINTS.update({
        f"shoulder_{_side}": ("chest", (0.175 * _x, 1.44, 0.0)),
        f"elbow_{_side}": (f"shoulder_{_side}", (0.215 * _x, 1.16, -0.01)),
        f"wrist_{_side}": (f"elbow_{_side}", (0.235 * _x, 0.92, 0.02)),
        f"fingers_{_side}": (f"wrist_{_side}", (0.24 * _x, 0.83, 0.03)),
        f"hip_{_side}": ("root", (0.095 * _x, 0.93, 0.0)),
        f"knee_{_side}": (f"hip_{_side}", (0.10 * _x, 0.52, 0.01)),
        f"ankle_{_side}": (f"knee_{_side}", (0.10 * _x, 0.09, -0.01)),
        f"toe_{_side}": (f"ankle_{_side}", (0.105 * _x, 0.035, 0.15)),
    })

SKIN, SHIRT, TROUSERS, HAIR, SHOES = range(5)
MATERIAL_NAMES = ("skin", "shirt", "trousers", "hair", "shoes")
BASE_COLORS = np.array([
    [224, 172, 140],  # skin
    [52, 96, 168],    # shirt (blue)
    [62, 58, 54],     # trousers (dark grey-brown)
    [70, 44, 28],     # hair (dark brown)
    [30, 30, 32],     # shoes
], dtype=np.float64)
STRIPE_COLOR = np.array([228, 228, 220], dtype=np.float64)

# parts: ("cone", joint_a, joint_b, r_a, r_b, material) or
#        ("ellipsoid", joint, centre offset from the joint (rest, metres), radii, material)
PARTS: list[tuple] = [
    ("ellipsoid", "root", (0.0, -0.01, 0.0), (0.165, 0.12, 0.105), TROUSERS),
    ("ellipsoid", "spine", (0.0, 0.02, 0.0), (0.14, 0.14, 0.095), SHIRT),
    ("ellipsoid", "chest", (0.0, 0.03, 0.0), (0.175, 0.16, 0.105), SHIRT),
    ("cone", "neck", "head", 0.052, 0.048, SKIN),
    ("ellipsoid", "head", (0.0, 0.11, 0.012), (0.082, 0.112, 0.098), SKIN),
    ("ellipsoid", "head", (0.0, 0.135, -0.005), (0.088, 0.1, 0.1), HAIR),
    ("ellipsoid", "head", (0.0, 0.095, 0.105), (0.014, 0.022, 0.016), SKIN),  # nose
]
for _side in ("l", "r"):
    PARTS += [
        ("cone", f"shoulder_{_side}", f"elbow_{_side}", 0.05, 0.04, SHIRT),  # sleeve rule below
        ("cone", f"elbow_{_side}", f"wrist_{_side}", 0.038, 0.028, SKIN),
        ("cone", f"wrist_{_side}", f"fingers_{_side}", 0.03, 0.02, SKIN),
        ("cone", f"hip_{_side}", f"knee_{_side}", 0.08, 0.055, TROUSERS),
        ("cone", f"knee_{_side}", f"ankle_{_side}", 0.052, 0.036, TROUSERS),
        ("cone", f"ankle_{_side}", f"toe_{_side}", 0.042, 0.034, SHOES),
    ]


def rotation(axis: str, degrees: float) -> np.ndarray:
    """3x3 rotation about the x, y or z axis (right-handed)."""
    t = np.radians(degrees)
    c, s = np.cos(t), np.sin(t)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _swing(deg: float) -> np.ndarray:
    """Hip/shoulder flexion: a limb hanging down swings forward (+z) for deg > 0."""
    return rotation("x", -deg)


def _bend(deg: float) -> np.ndarray:
    """Knee flexion: the shin swings backward for deg > 0."""
    return rotation("x", deg)


def _abduct(side: str, deg: float) -> np.ndarray:
    """Raise a hanging arm/leg sideways, away from the body, by deg."""
    return rotation("z", deg if side == "l" else -deg)


def pose(motion: str, t: float, phase: float) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Local joint rotations and the root offset (metres) at time t seconds.

    Walk: in place (treadmill), 1.1 s stride cycle: hips +-25 deg, knees bend in swing, arms swing
    opposite the legs with bent elbows, pelvis/chest counter-twist. Dance: 1.0 s cycle, arms raised
    and swaying, alternating knee bends, hip sway, torso twist. Wave: right arm raised, forearm waving
    +-25 deg at 1.7 Hz, weight shifting, head turning.
    """
    R: dict[str, np.ndarray] = {}
    offset = np.zeros(3)
    if motion == "walk":
        p = 2 * np.pi * t / 1.1 + phase
        s, c = np.sin(p), np.cos(p)
        R["root"] = rotation("y", 6 * s)
        R["chest"] = rotation("y", -10 * s) @ rotation("x", 4)
        R["head"] = rotation("y", 4 * s) @ rotation("x", -3)
        for side, sign in (("l", 1.0), ("r", -1.0)):
            leg = sign * s
            swing_phase = sign * c  # > 0 while this leg moves forward (swing)
            R[f"hip_{side}"] = _swing(25 * leg)
            R[f"knee_{side}"] = _bend(6 + 45 * max(0.0, swing_phase) ** 1.5)
            R[f"ankle_{side}"] = rotation("x", 12 * leg)
            R[f"shoulder_{side}"] = _swing(-22 * leg) @ _abduct(side, 7)
            R[f"elbow_{side}"] = rotation("x", -(20 + 18 * max(0.0, -leg)))
            R[f"wrist_{side}"] = rotation("x", -5)
        offset[0] = 0.02 * s
    elif motion == "dance":
        p = 2 * np.pi * t / 1.0 + phase
        s, c = np.sin(p), np.cos(p)
        R["root"] = rotation("y", 18 * s) @ rotation("z", 6 * c)
        R["spine"] = rotation("z", -5 * c)
        R["chest"] = rotation("y", -12 * s)
        R["head"] = rotation("z", 10 * s) @ rotation("x", 8 * c)
        for side, sign in (("l", 1.0), ("r", -1.0)):
            bend = 0.5 + 0.5 * sign * c
            R[f"hip_{side}"] = _swing(10 + 25 * bend) @ _abduct(side, 6)
            R[f"knee_{side}"] = _bend(10 + 45 * bend)
            R[f"ankle_{side}"] = rotation("x", -15 * bend)
            R[f"shoulder_{side}"] = _abduct(side, 95 + 35 * sign * s) @ _swing(20 * c)
            R[f"elbow_{side}"] = rotation("z", (1 if side == "l" else -1) * (45 + 35 * np.sin(p + sign)))
            R[f"wrist_{side}"] = rotation("x", 20 * s)
        offset[0] = 0.05 * c
    elif motion == "wave":
        p = 2 * np.pi * t * 1.7 + phase
        slow = 2 * np.pi * t / 3.0 + phase
        R["root"] = rotation("z", 3 * np.sin(slow))
        R["chest"] = rotation("z", -3 * np.sin(slow)) @ rotation("y", 8 * np.sin(slow))
        R["head"] = rotation("y", 20 * np.sin(slow)) @ rotation("z", 6 * np.sin(p))
        R["shoulder_r"] = _abduct("r", 95) @ _swing(15)
        R["elbow_r"] = rotation("z", -(80 + 25 * np.sin(p)))
        R["wrist_r"] = rotation("z", -10 * np.sin(p))
        R["shoulder_l"] = _swing(5 * np.sin(slow)) @ _abduct("l", 6)
        R["elbow_l"] = rotation("x", -25)
        for side, sign in (("l", 1.0), ("r", -1.0)):
            R[f"hip_{side}"] = _abduct(side, 4 + 3 * sign * np.sin(slow))
            R[f"knee_{side}"] = _bend(4 + 8 * max(0.0, sign * np.sin(slow)))
        offset[0] = 0.03 * np.sin(slow)
    else:
        raise ValueError(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    return R, offset


def forward_kinematics(local: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """World positions (metres) and world rotations of every joint for local rotations ``local``."""
    pos: dict[str, np.ndarray] = {}
    rot: dict[str, np.ndarray] = {}
    for name, (parent, rest_m) in JOINTS.items():  # parents are listed before children
        rest = np.asarray(rest_m, dtype=np.float64)
        if parent is None:
            pos[name] = rest.copy()
            rot[name] = local.get(name, np.eye(3))
        else:
            parent_rest = np.asarray(JOINTS[parent][1], dtype=np.float64)
            pos[name] = pos[parent] + rot[parent] @ (rest - parent_rest)
            rot[name] = rot[parent] @ local.get(name, np.eye(3))
    return pos, rot


def rest_height_m() -> float:
    """Height of the rest pose, floor to top of the hair, in metres."""
    top = max(JOINTS[p[1]][1][1] + p[2][1] + p[3][1] for p in PARTS if p[0] == "ellipsoid")
    bottom = min(JOINTS[p[1]][1][1] - p[3] for p in PARTS if p[0] == "cone")
    return top - bottom


def build_body(motion: str, t: float, phase: float, scale: float, origin: np.ndarray):
    """The posed body as (SmoothUnion in voxel units, per-part materials, joint frames in voxels)."""
    local, offset = pose(motion, t, phase)
    pos_m, rot = forward_kinematics(local)
    # feet on the floor: the lowest point of the foot cones touches y = 0
    lowest = min(pos_m[j][1] - r for side in ("l", "r")
                 for j, r in ((f"ankle_{side}", 0.042), (f"toe_{side}", 0.034)))
    shift = offset - np.array([0.0, lowest, 0.0])
    pos = {j: origin + scale * (p + shift) for j, p in pos_m.items()}
    primitives: list[RoundCone | Ellipsoid] = []
    materials = []
    for part in PARTS:
        if part[0] == "cone":
            _, a, b, ra, rb, material = part
            pa, pb = pos[a], pos[b]
            if a == b:  # sphere: a zero-length cone is degenerate, offset b by a hair
                pb = pa + np.array([0.0, 1e-3, 0.0])
            primitives.append(RoundCone(pa, pb, scale * ra, scale * rb))
        else:
            _, joint, centre, radii, material = part
            c = pos[joint] + scale * (rot[joint] @ np.asarray(centre))
            primitives.append(Ellipsoid(c, scale * np.asarray(radii, dtype=np.float64), rot[joint]))
        materials.append(material)
    frames = {"pos": pos, "rot": rot}
    return SmoothUnion(primitives, scale * BLEND_M), np.array(materials), frames


def resolve_height(size: str, bit_depth: int, height: float | None) -> float:
    """Figure height in voxels from the size preset, or the explicit ``height``."""
    if size not in SIZE_HEIGHTS:
        raise ValueError(f"unknown size {size!r}; choose one of {', '.join(SIZE_HEIGHTS)}")
    grid = 2 ** bit_depth
    h = height if height is not None else SIZE_HEIGHTS[size]
    if h is None:
        h = DEFAULT_HEIGHT_FRACTION * grid
    if not 16 <= h <= grid * DEFAULT_HEIGHT_FRACTION + 1e-9:
        raise ValueError(
            f"figure height {h:g} voxels does not fit a {bit_depth}-bit grid ({grid} voxels): use a height "
            f"between 16 and {DEFAULT_HEIGHT_FRACTION * grid:g}, or a larger bit_depth"
        )
    return float(h)


def generate_frame(index: int, *, motion: str = "walk", bit_depth: int = 10, size: str = "default",
                   height: float | None = None, fps: float = 30.0,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame ``index`` of the sequence: (points (N, 3) float64 integer-valued in [0, 2^bit_depth),
    colours (N, 3) uint8, unit outward normals (N, 3) float64 of the body's field at the points).

    The seed sets the motion's starting phase (uniform in [0, 2 pi)) and the colour noise.
    """
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; choose one of {', '.join(MOTIONS)}")
    if not 4 <= int(bit_depth) <= 16:
        raise ValueError(f"bit_depth must be an integer in 4..16, got {bit_depth!r}")
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps!r}")
    bit_depth = int(bit_depth)
    grid = 2 ** bit_depth
    h = resolve_height(size, bit_depth, height)
    scale = h / rest_height_m()
    origin = np.array([grid / 2.0, FLOOR * grid, grid / 2.0])
    phase = float(np.random.default_rng(seed).uniform(0.0, 2 * np.pi))
    body, materials, joint_frames = build_body(motion, index / fps, phase, scale, origin)
    if body.lo.min() < 0 or body.hi.max() > grid:  # never cut the figure at the grid's edge silently
        raise ValueError(f"frame {index}: the posed figure leaves the {bit_depth}-bit grid; lower height")
    voxels = surface_voxels(body, grid)
    if len(voxels) == 0:
        raise ValueError("the figure has no surface voxel in the grid; increase height or bit_depth")
    _, nearest = body.evaluate(voxels + 0.5, 2.0)
    colours = _colours(voxels + 0.5, nearest, materials, body, joint_frames, scale, seed, index)
    points = voxels.astype(np.float64)
    return points, colours, body.normals(points)


def _colours(centres, nearest, materials, body, joint_frames, scale, seed, index) -> np.ndarray:
    """Material colour per voxel, with sleeves, shirt stripes and seeded per-voxel noise."""
    material = materials[np.maximum(nearest, 0)].copy()
    # sleeves: the upper-arm cones are shirt near the shoulder, skin past 60% of the way to the elbow
    for i, part in enumerate(PARTS):
        if part[0] == "cone" and part[1].startswith("shoulder_") and part[2].startswith("elbow_"):
            sel = nearest == i
            prim = body.primitives[i]
            ab = prim.b - prim.a
            along = (centres[sel] - prim.a) @ ab / (ab @ ab)
            material[np.flatnonzero(sel)[along > 0.6]] = SKIN
    colour = BASE_COLORS[material]
    shirt = material == SHIRT
    if shirt.any():
        # horizontal stripes in the chest frame, 4 cm period, so the pattern moves with the torso
        local = (centres[shirt] - joint_frames["pos"]["chest"]) @ joint_frames["rot"]["chest"] / scale
        stripe = (np.sin(local[:, 1] * 2 * np.pi / 0.04) > 0.55)[:, None]
        colour[shirt] = np.where(stripe, STRIPE_COLOR, colour[shirt])
    rng = np.random.default_rng((int(seed), int(index)))
    colour = colour * rng.uniform(0.9, 1.1, size=(len(colour), 1)) + rng.normal(0.0, 4.0, size=colour.shape)
    return np.clip(np.rint(colour), 0, 255).astype(np.uint8)
