"""Synthetic holes with ground truth: region holes (the paper's synthetic experiments) and dropouts.

Sizes are relative to the cube size M of the proposed method (`holes.geometry.cube_size`:
M = min(20 point spacings, 20 * largest bounding-box side / 1024); both are the paper's M = 20 on
the 8i 10-bit bodies), so a preset gives holes of the same size relative to the body on sparse or
small data, and relative to the method's cube on data denser than the paper's.

``region`` presets (ball radius, or half side of a cube, in units of M; holes per frame) and the
fraction of points they removed per frame (mean [min-max] over 5 frames x 3 seeds; measured once
with a script that was not kept, as it read data outside the repository):

=======  =====  ========  ===========================  ===========================
preset   count  radius    DFAUST punching, M = 20.0    embedded human small, M = 7.3
=======  =====  ========  ===========================  ===========================
small    3      0.75 M    ball 0.29 % [0.24-0.40]      ball 0.43 % [0.41-0.45]
medium   4      1.5 M     ball 1.52 % [1.33-1.73]      ball 2.37 % [2.25-2.49]
                          cube 2.28 % [1.98-2.65]      cube 3.30 % [3.00-3.48]
large    5      3 M       ball 8.1 % [6.8-10.0]        ball 13.5 % [11.5-15.6]
=======  =====  ========  ===========================  ===========================

"medium" is what the method comparisons evaluate on (1-3 % of the points in 4 holes of 1.5 M, like
holes a cube-based method must bridge); "large" gives the bigger, more complex holes of the
paper's Soldier figure; "small" holes fit inside one cube. "paper" (3 holes of 0.625 M = 12.5 point
spacings on the paper's data; 0.2 % of the Longdress frame) is the paper's protocol as calibrated on
the Longdress frame (docs/paper-reading.md, "The calibrated protocol").
"""

from __future__ import annotations

import numpy as np
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
from dpcbench.holes.geometry import cube_size, regions_mask
from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.errors import UserError

#: preset -> (holes per frame, radius in units of M)
REGION_PRESETS: dict[str, tuple[int, float]] = {
    "small": (3, 0.75),
    "medium": (4, 1.5),
    "large": (5, 3.0),
    # the paper's protocol, calibrated (docs/paper-reading.md): 3 balls of radius 12.5 point spacings a
    # frame (M = 20 spacings on the paper's 10-bit bodies), the setting of a grid of 3 or 6 balls of
    # 10-15 spacings under which Meshlab and Lozes land nearest the paper's Longdress values
    "paper": (3, 12.5 / 20.0),
}

#: how many random surface points are tried as hole centres before giving up on placing a hole
_PLACEMENT_TRIES = 2000


def _make_hole(shape: str, center: np.ndarray, size: float, **extra) -> HoleRegion:
    """A ball of radius ``size`` or an axis-aligned cube of half side ``size`` around ``center``."""
    if shape == "ball":
        return HoleRegion.ball(center, size, **extra)
    return HoleRegion.box(center, np.full(3, size), np.eye(3), **extra)


def _size_for_points(tree: cKDTree, center: np.ndarray, shape: str, n_points: int) -> float:
    """Radius (ball, Euclidean) or half side (axis-aligned cube, Chebyshev) holding as close to
    ``n_points`` nearest points of ``center`` as ties allow: on voxelized data many points share a
    distance, so the size is the distinct neighbour distance whose count is closest to n_points."""
    k = min(tree.n, int(n_points * 1.5) + 16)
    dist, _ = tree.query(center, k=k, p=2 if shape == "ball" else np.inf)
    levels, counts = np.unique(dist, return_counts=True)
    inside = np.cumsum(counts)  # points within each distinct distance
    best = int(np.argmin(np.abs(inside - n_points)))
    return float(levels[best]) * (1 + 1e-9) + 1e-12


def _separated(shape: str, center: np.ndarray, size: float, centers: list, sizes: list) -> bool:
    """True when the new hole does not intersect any accepted one."""
    if not centers:
        return True
    diff = np.asarray(centers) - center
    if shape == "ball":
        gap = np.linalg.norm(diff, axis=1)
    else:  # axis-aligned cubes are disjoint iff their Chebyshev distance exceeds the half sides' sum
        gap = np.abs(diff).max(axis=1)
    return bool((gap > np.asarray(sizes) + size).all())


def track_point(
    center: np.ndarray, source: np.ndarray, source_tree: cKDTree, target: np.ndarray, target_tree: cKDTree,
    patch_radius: float, iterations: int = 20, max_patch: int = 2000,
) -> np.ndarray:
    """Carry a surface point from one frame to the next, following the local surface motion.

    The patch of ``source`` points within ``patch_radius`` of ``center`` is registered onto
    ``target`` by translation-only ICP (t <- mean over the patch of NN_target(p + t) - p, from t = 0,
    at most ``iterations`` steps or until t moves less than 1e-6 of the patch radius; patches of more
    than ``max_patch`` points are regularly subsampled to that size); the result is
    the ``target`` point nearest to ``center + t`` (so it lies on the next frame's surface).
    Works without point correspondences (real captures shuffle point order).
    """
    patch = source[np.sort(np.asarray(source_tree.query_ball_point(center, patch_radius), dtype=np.int64))]
    if len(patch) > max_patch:
        # the shift is a mean: a regular subsample of the patch estimates it as well, much faster
        patch = patch[:: int(np.ceil(len(patch) / max_patch))]
    shift = np.zeros(3)
    if len(patch):
        for _ in range(iterations):
            _, nn = target_tree.query(patch + shift, workers=-1)
            new_shift = (target[nn] - patch).mean(axis=0)
            done = np.linalg.norm(new_shift - shift) < 1e-6 * patch_radius
            shift = new_shift
            if done:
                break
    _, idx = target_tree.query(center + shift)
    return target[idx]


def hole_overlap(frames: list[np.ndarray], removed: list[np.ndarray]) -> float:
    """Frame-to-frame overlap of removed surface, for comparing coherent and independent holes.

    For each pair (f, f+1): every point of the intact frame f+1 is mapped to its nearest
    neighbour in the intact frame f (no point correspondence needed); A = removed[f+1],
    B = removed[f] at those neighbours; IoU = |A and B| / |A or B|. Returns the mean IoU over the
    F-1 pairs (1.0: the same surface is missing in every frame; about 0 for independent holes).
    """
    if len(frames) < 2:
        raise UserError("hole_overlap needs at least two frames")
    ious = []
    for f in range(len(frames) - 1):
        _, nn = cKDTree(frames[f]).query(frames[f + 1], workers=-1)
        a, b = removed[f + 1], removed[f][nn]
        union = np.logical_or(a, b).sum()
        ious.append(np.logical_and(a, b).sum() / union if union else 1.0)
    return float(np.mean(ious))


class RegionHoles(HoleGenerator):
    """Several ball or cube holes a frame, centred on surface points (the paper's synthetic holes).

    Parameters
    ----------
    preset:    "small" | "medium" | "large" | "paper" (see REGION_PRESETS); sets count and radius.
    count:     holes per frame (overrides the preset).
    radius:    ball radius / cube half side in units of M (overrides the preset).
    fraction:  if given, the total fraction of points to remove per frame instead of ``radius``:
               each hole is sized to hold ``round(fraction * N / count)`` nearest points of its
               centre, so the fraction is met up to ties at the hole boundary (and, with
               ``coherent=True``, up to density changes after frame 0, where the size is fixed).
    shape:     "ball" or "cube" (axis-aligned, like the method's cubes).
    coherent:  False: new random holes in every frame. True: the holes of frame 0 follow the
               moving surface (`track_point`), keeping their size: the same surface region is
               missing in every frame, as when a body part stays occluded.
    cube_size: M in coordinate units; default `holes.geometry.cube_size` of frame 0.
    max_fraction: refuse damage that removes more than this fraction of a frame.

    Holes never intersect each other when placed (ball-ball distance > r_i + r_j; cubes by the
    Chebyshev distance); ValueError when ``count`` such holes do not fit on the frame.
    Tracked (coherent) holes may drift into each other later; they are kept as they are.
    Regions carry ``hole`` (the hole's index, stable across frames when coherent).
    """

    name = "region"
    summary = "synthetic ball/cube holes sized in units of the method's cube M (presets small/medium/large/paper)"
    version = "1"

    def __init__(self, preset: str = "medium", count: int | None = None, radius: float | None = None,
                 fraction: float | None = None, shape: str = "ball", coherent: bool = False,
                 cube_size: float | None = None, max_fraction: float = 0.5):
        self.preset = preset
        self.count = count
        self.radius = radius
        self.fraction = fraction
        self.shape = shape
        self.coherent = coherent
        self.cube_size = cube_size
        self.max_fraction = max_fraction

    def _resolved(self) -> tuple[int, float]:
        if self.preset not in REGION_PRESETS:
            raise UserError(f"region holes: unknown preset {self.preset!r}; use one of {sorted(REGION_PRESETS)}")
        count, radius = REGION_PRESETS[self.preset]
        count = count if self.count is None else self.count
        radius = radius if self.radius is None else self.radius
        if int(count) != count or count < 1:
            raise UserError(f"region holes: count must be a positive integer, got {count!r}")
        if not radius > 0:
            raise UserError(f"region holes: radius (in units of M) must be positive, got {radius!r}")
        if self.shape not in ("ball", "cube"):
            raise UserError(f"region holes: shape must be 'ball' or 'cube', got {self.shape!r}")
        if self.fraction is not None and not 0 < self.fraction < 1:
            raise UserError(f"region holes: fraction must be in (0, 1), got {self.fraction!r}")
        if self.fraction is not None and self.fraction > self.max_fraction:
            raise UserError(f"region holes: fraction {self.fraction} exceeds max_fraction {self.max_fraction}; "
                             "ask for less (or raise max_fraction)")
        if self.cube_size is not None and not self.cube_size > 0:
            raise UserError(f"region holes: cube_size must be positive, got {self.cube_size!r}")
        if not 0 < self.max_fraction <= 1:
            raise UserError(f"region holes: max_fraction must be in (0, 1], got {self.max_fraction!r}")
        return int(count), float(radius)

    def _check_params(self) -> None:
        self._resolved()

    def _place(self, points, tree, rng, count, size, frame_index):
        """Random non-intersecting holes on one frame: (centres, sizes)."""
        n_per_hole = None
        if self.fraction is not None:
            n_per_hole = max(1, int(round(self.fraction * len(points) / count)))
            if n_per_hole * count >= len(points):
                raise UserError(
                    f"region holes: frame {frame_index} has {len(points)} points, too few for {count} holes "
                    f"removing {self.fraction:.1%}; use fewer holes or a smaller fraction"
                )
        if count > len(points):
            raise UserError(f"region holes: {count} holes requested but frame {frame_index} has {len(points)} points")
        centers, sizes = [], []
        for idx in rng.permutation(len(points))[:_PLACEMENT_TRIES]:
            center = points[idx]
            hole_size = size if n_per_hole is None else _size_for_points(tree, center, self.shape, n_per_hole)
            if _separated(self.shape, center, hole_size, centers, sizes):
                centers.append(center)
                sizes.append(hole_size)
                if len(centers) == count:
                    return centers, sizes
        raise UserError(
            f"region holes: could place only {len(centers)} of {count} non-overlapping holes of size "
            f"{max(sizes, default=size):.4g} on frame {frame_index} (extent "
            f"{np.ptp(points, axis=0).max():.4g}); use fewer or smaller holes"
        )

    def damage(self, frames: list[np.ndarray], seed: Seed, colors: Colors = None) -> DamageResult:
        frames, colors = check_sequence_input(frames, colors, "region holes")
        count, radius_m = self._resolved()
        rng = as_generator(seed)
        trees = [cKDTree(pts) for pts in frames]
        m = self.cube_size if self.cube_size is not None else cube_size(frames[0], tree=trees[0])
        size = radius_m * m
        regions, removed = [], []
        centers: list = []
        sizes: list = []
        for f, (pts, tree) in enumerate(zip(frames, trees)):
            if f == 0 or not self.coherent:
                centers, sizes = self._place(pts, tree, rng, count, size, f)
            else:
                centers = [
                    track_point(c, frames[f - 1], trees[f - 1], pts, tree, patch_radius=2 * s)
                    for c, s in zip(centers, sizes)
                ]
            frame_regions = [_make_hole(self.shape, c, s, hole=h) for h, (c, s) in enumerate(zip(centers, sizes))]
            regions.append(frame_regions)
            removed.append(regions_mask(frame_regions, pts, tree))
        return make_result(frames, removed, regions, colors, what="region holes", max_fraction=self.max_fraction)


class DropoutHoles(HoleGenerator):
    """Fragmentary dropout: many small holes at random places, like missing samples of a sensor.

    Parameters
    ----------
    fraction:    fraction of the points to remove per frame (holes are added until it is reached,
                 so the result is within one hole, about ``1.5 * hole_points / N``, above it).
    hole_points: mean points per hole; each hole is the ball holding the n nearest points of a
                 random centre, n drawn uniformly from [0.5, 1.5] * hole_points. Holes may overlap
                 (dropouts cluster in real captures too); the ball radius follows the local density.
    max_fraction: refuse parameters that would remove more than this.
    Independent per frame (sensor dropouts are not temporally coherent).
    """

    name = "dropout"
    summary = "many small holes at random places (sensor dropouts)"
    version = "1"

    def __init__(self, fraction: float = 0.02, hole_points: int = 20, max_fraction: float = 0.5):
        self.fraction = fraction
        self.hole_points = hole_points
        self.max_fraction = max_fraction

    def _check_params(self) -> None:
        if not 0 < self.fraction < 1:
            raise UserError(f"dropout holes: fraction must be in (0, 1), got {self.fraction!r}")
        if self.fraction > self.max_fraction:
            raise UserError(f"dropout holes: fraction {self.fraction} exceeds max_fraction {self.max_fraction}")
        if int(self.hole_points) != self.hole_points or self.hole_points < 1:
            raise UserError(f"dropout holes: hole_points must be a positive integer, got {self.hole_points!r}")

    def damage(self, frames: list[np.ndarray], seed: Seed, colors: Colors = None) -> DamageResult:
        frames, colors = check_sequence_input(frames, colors, "dropout holes")
        self._check_params()
        rng = as_generator(seed)
        regions, removed = [], []
        for f, pts in enumerate(frames):
            n = len(pts)
            target = int(np.ceil(self.fraction * n))
            if 1.5 * self.hole_points >= n - target:
                raise UserError(
                    f"dropout holes: frame {f} has {n} points, too few for holes of ~{self.hole_points} points "
                    f"removing {self.fraction:.1%}; use smaller holes or a lower fraction"
                )
            tree = cKDTree(pts)
            mask = np.zeros(n, dtype=bool)
            lost = 0
            frame_regions = []
            while lost < target:
                # a batch of holes, then keep only as many as needed to reach the target
                batch = max(8, int(1.2 * (target - lost) / self.hole_points))
                centers = pts[rng.integers(0, n, batch)]
                sizes = rng.integers(max(1, int(0.5 * self.hole_points)), int(1.5 * self.hole_points) + 1, batch)
                dists, _ = tree.query(centers, k=int(sizes.max()), workers=-1)
                for center, k, dist in zip(centers, sizes, dists):
                    region = HoleRegion.ball(center, float(dist[k - 1]) * (1 + 1e-9) + 1e-12)
                    cand = np.asarray(tree.query_ball_point(center, region.radius * (1 + 1e-9)), dtype=np.int64)
                    inside = cand[region.contains(pts[cand])]
                    lost += int((~mask[inside]).sum())
                    mask[inside] = True
                    frame_regions.append(region)
                    if lost >= target:
                        break
            regions.append(frame_regions)
            removed.append(mask)
        return make_result(frames, removed, regions, colors, what="dropout holes", max_fraction=self.max_fraction)
