"""Hole regions: the simple geometry that tells a method *where* data is missing.

Like the mask of an image inpainting benchmark, a region is handed to methods; the removed points
(the ground truth) never are. Two shapes:

- ``ball``: centre (3,) and ``radius``; contains p iff ||p - centre|| <= radius.
- ``box``:  centre (3,), ``half_extents`` (3,) and ``rotation`` (3, 3) whose columns are the box
  axes in world coordinates; contains p iff |R^T (p - centre)|_i <= half_extents_i for every i.

JSON form of one region: ``{"shape": "ball", "center": [x, y, z], "radius": r}`` or
``{"shape": "box", "center": [...], "half_extents": [...], "rotation": [[...], [...], [...]]}``.
A ``holes.json`` file is ``{"format": "dpcbench-holes", "version": 1, "frames": [{"frame": i,
"regions": [region, ...], ...}, ...], ...}`` (see `regions_to_json`). Regions may carry extra
keys (kept in ``HoleRegion.extra``): ``hole`` (index of a synthetic hole, stable across frames for
coherent holes), ``point_count`` (removed points in an occlusion piece), ``rim_points`` and
``inward`` (detected holes).

Written by ``dpcbench damage`` (top-level keys): ``generator`` (registry name), ``generator_version``,
``params`` (all generator parameters), ``seed``, ``source`` (the INPUT given), ``removed_fraction``
(list, one per frame); per frame entry: ``points`` (points of the original frame), ``removed``
(how many were removed), ``removed_fraction``, ``file`` (the damaged PLY beside it). The removed
points themselves are in ``masks.npz`` beside it: key ``frame_0000`` ... -> bool array over the
original frame's points (True = removed; ``original[~mask]`` is the damaged frame, same order).

Written by ``dpcbench detect-holes``: ``detector``, ``params`` (the detector parameters given),
``source``; per frame entry: ``points``, ``region_count``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HOLES_FORMAT = "dpcbench-holes"
HOLES_VERSION = 1


@dataclass(frozen=True)
class HoleRegion:
    shape: str
    center: np.ndarray
    radius: float = 0.0
    half_extents: np.ndarray | None = None
    rotation: np.ndarray | None = None
    extra: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "center", np.asarray(self.center, dtype=np.float64).reshape(3))
        if self.shape == "ball":
            if not self.radius > 0:
                raise ValueError(f"ball hole region needs a positive radius, got {self.radius}")
        elif self.shape == "box":
            if self.half_extents is None:
                raise ValueError("box hole region needs half_extents")
            he = np.asarray(self.half_extents, dtype=np.float64).reshape(3)
            if not (he > 0).all():
                raise ValueError(f"box hole region needs positive half_extents, got {he}")
            rot = np.eye(3) if self.rotation is None else np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)
            object.__setattr__(self, "half_extents", he)
            object.__setattr__(self, "rotation", rot)
        else:
            raise ValueError(f"unknown hole region shape {self.shape!r}; use 'ball' or 'box'")
        if not np.isfinite(self.center).all():
            raise ValueError("hole region centre must be finite")

    @classmethod
    def ball(cls, center, radius: float, **extra) -> "HoleRegion":
        return cls("ball", np.asarray(center), radius=float(radius), extra=extra)

    @classmethod
    def box(cls, center, half_extents, rotation=None, **extra) -> "HoleRegion":
        return cls("box", np.asarray(center), half_extents=np.asarray(half_extents), rotation=rotation, extra=extra)

    @property
    def bounding_radius(self) -> float:
        """Radius of a ball around the centre that encloses the region."""
        return self.radius if self.shape == "ball" else float(np.linalg.norm(self.half_extents))

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask (N,) of the points inside the region grown by ``margin``."""
        d = np.asarray(points, dtype=np.float64) - self.center
        if self.shape == "ball":
            return np.einsum("ij,ij->i", d, d) <= (self.radius + margin) ** 2
        local = d @ self.rotation
        return (np.abs(local) <= self.half_extents + margin).all(axis=1)

    def to_dict(self) -> dict:
        out = {"shape": self.shape, "center": self.center.tolist()}
        if self.shape == "ball":
            out["radius"] = float(self.radius)
        else:
            out["half_extents"] = self.half_extents.tolist()
            out["rotation"] = self.rotation.tolist()
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "HoleRegion":
        data = dict(data)
        shape = data.pop("shape", None)
        center = data.pop("center", None)
        if shape is None or center is None:
            raise ValueError(f"hole region needs 'shape' and 'center', got keys {sorted(data)}")
        if shape == "ball":
            return cls("ball", center, radius=float(data.pop("radius")), extra=data)
        return cls("box", center, half_extents=data.pop("half_extents"), rotation=data.pop("rotation", None), extra=data)


def union_mask(regions: list[HoleRegion], points: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Mask (N,) of the points inside any of ``regions`` (grown by ``margin``)."""
    mask = np.zeros(len(points), dtype=bool)
    for region in regions:
        mask |= region.contains(points, margin)
    return mask


def regions_to_json(regions_per_frame: list[list[HoleRegion]], **info) -> dict:
    """The holes.json object: per frame the list of regions; ``info`` adds top-level keys
    (generator, params, seed, removed_fraction per frame, ...)."""
    frames = [{"frame": i, "regions": [r.to_dict() for r in regs]} for i, regs in enumerate(regions_per_frame)]
    per_frame = info.pop("per_frame", None)
    if per_frame:
        if len(per_frame) != len(frames):
            raise ValueError(f"per_frame has {len(per_frame)} entries for {len(frames)} frames")
        for entry, extra in zip(frames, per_frame):
            clash = {"frame", "regions"} & set(extra)
            if clash:
                raise ValueError(f"per_frame entries may not use the reserved keys {sorted(clash)}")
            entry.update(extra)
    return {"format": HOLES_FORMAT, "version": HOLES_VERSION, **info, "frames": frames}


def regions_from_json(data: dict | str | Path) -> list[list[HoleRegion]]:
    """Regions per frame from a holes.json object or file path."""
    if not isinstance(data, dict):
        data = json.loads(Path(data).read_text())
    if data.get("format") != HOLES_FORMAT:
        raise ValueError(f"not a holes file: 'format' is {data.get('format')!r}, expected {HOLES_FORMAT!r}")
    frames = sorted(data["frames"], key=lambda f: f["frame"])
    return [[HoleRegion.from_dict(r) for r in f["regions"]] for f in frames]
