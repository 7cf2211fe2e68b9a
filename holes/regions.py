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
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from dpcbench.holes._blas import rows_times
from dpcbench.metrics.errors import UserError

if TYPE_CHECKING:  # imported where used: every CLI command loads this module, few need scipy
    from scipy.spatial import cKDTree

#: the largest |coordinate| a region (and a frame, `bench.data.plyio.check_cloud`) may have: beyond it squared
#: distances leave float32's range and integer keys int64's, so scores would be silently wrong
COORD_LIMIT = 1e15
#: how far R^T R of a box rotation may be from the identity (entry-wise)
ROTATION_TOLERANCE = 1e-6

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

    def __post_init__(self) -> None:
        """The one check of region values, wherever a region comes from (a holes.json, a generator,
        a detector): finite centre within `COORD_LIMIT`; ball: finite radius in (0, COORD_LIMIT];
        box: finite half extents in (0, COORD_LIMIT] and an orthonormal rotation (R^T R = I within
        `ROTATION_TOLERANCE`; its columns are the box axes). UserError otherwise."""
        object.__setattr__(self, "center", np.asarray(self.center, dtype=np.float64).reshape(3))
        if not np.isfinite(self.center).all():
            raise UserError("hole region centre must be finite")
        if np.abs(self.center).max() > COORD_LIMIT:
            raise UserError(f"hole region centre {self.center.tolist()} lies beyond +-{COORD_LIMIT:g}, the coordinate "
                            "range dpcbench scores correctly; translate the frames and regions closer to the origin")
        if self.shape == "ball":
            if not (self.radius > 0 and np.isfinite(self.radius)):
                raise UserError(f"ball hole region needs a positive, finite radius, got {self.radius}")
            if self.radius > COORD_LIMIT:
                raise UserError(f"ball hole region radius {self.radius:g} exceeds {COORD_LIMIT:g}")
        elif self.shape == "box":
            if self.half_extents is None:
                raise UserError("box hole region needs half_extents")
            he = np.asarray(self.half_extents, dtype=np.float64).reshape(3)
            if not (np.isfinite(he).all() and (he > 0).all() and (he <= COORD_LIMIT).all()):
                raise UserError(f"box hole region needs positive, finite half_extents (at most {COORD_LIMIT:g}), "
                                f"got {he.tolist()}")
            rot = np.eye(3) if self.rotation is None else np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)
            if not np.isfinite(rot).all() or not np.allclose(rot.T @ rot, np.eye(3), rtol=0, atol=ROTATION_TOLERANCE):
                raise UserError(f"box hole region rotation {np.round(rot, 6).tolist()} is not orthonormal (its columns "
                                "must be unit, mutually perpendicular box axes)")
            object.__setattr__(self, "half_extents", he)
            object.__setattr__(self, "rotation", rot)
        else:
            raise UserError(f"unknown hole region shape {self.shape!r}; use 'ball' or 'box'")

    @classmethod
    def ball(cls, center: ArrayLike, radius: float, **extra: Any) -> HoleRegion:
        return cls("ball", np.asarray(center), radius=float(radius), extra=extra)

    @classmethod
    def box(cls, center: ArrayLike, half_extents: ArrayLike, rotation: ArrayLike | None = None,
            **extra: Any) -> HoleRegion:
        return cls("box", np.asarray(center), half_extents=np.asarray(half_extents),
                   rotation=None if rotation is None else np.asarray(rotation), extra=extra)

    @property
    def bounding_radius(self) -> float:
        """Radius of a ball around the centre that encloses the region."""
        return self.radius if self.shape == "ball" else float(np.linalg.norm(self._box()[0]))

    def _box(self) -> tuple[np.ndarray, np.ndarray]:
        """(half_extents, rotation) of a box region (``__post_init__`` sets both for every box)."""
        if self.half_extents is None or self.rotation is None:
            raise TypeError(f"a {self.shape} region has no box extents")
        return self.half_extents, self.rotation

    def support(self, direction: ArrayLike) -> float:
        """The region's support function: max over its points p of p . u, u = ``direction`` (3,) made unit length.
        Ball: c . u + r; box: c . u + sum_i h_i |a_i . u| (a_i its axes, h_i its half extents)."""
        unit = np.asarray(direction, dtype=np.float64).reshape(3)
        unit = unit / np.linalg.norm(unit)
        if self.shape == "ball":
            return float(self.center @ unit + self.radius)
        half_extents, rotation = self._box()
        return float(self.center @ unit + half_extents @ np.abs(rotation.T @ unit))

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask (N,) of the points inside the region grown by ``margin``."""
        d = np.asarray(points, dtype=np.float64) - self.center
        if self.shape == "ball":
            return np.einsum("ij,ij->i", d, d) <= (self.radius + margin) ** 2
        half_extents, rotation = self._box()
        return (np.abs(rows_times(d, rotation)) <= half_extents + margin).all(axis=1)

    def grown(self, margin: float) -> HoleRegion:
        """The region grown by ``margin`` >= 0: the region whose `contains` is ``contains(points, margin)`` (a ball's
        radius, a box's half extents each plus the margin; rotation and extra keys kept)."""
        if self.shape == "ball":
            return HoleRegion("ball", self.center, radius=self.radius + margin, extra=dict(self.extra))
        half_extents, rotation = self._box()
        return HoleRegion("box", self.center, half_extents=half_extents + margin, rotation=rotation,
                          extra=dict(self.extra))

    def scaled(self, factor: float) -> HoleRegion:
        """The region with every length multiplied by ``factor`` > 0 (its centre, radius or half extents; its
        rotation and extra keys kept): this region in another unit of length."""
        if self.shape == "ball":
            return HoleRegion("ball", self.center * factor, radius=self.radius * factor, extra=dict(self.extra))
        half_extents, rotation = self._box()
        return HoleRegion("box", self.center * factor, half_extents=half_extents * factor, rotation=rotation,
                          extra=dict(self.extra))

    def to_dict(self) -> dict:
        out = {"shape": self.shape, "center": self.center.tolist()}
        if self.shape == "ball":
            out["radius"] = float(self.radius)
        else:
            half_extents, rotation = self._box()
            out["half_extents"] = half_extents.tolist()
            out["rotation"] = rotation.tolist()
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, data: dict, where: str = "hole region") -> HoleRegion:
        """A region from its JSON form; UserError naming ``where`` and the missing or bad key."""
        if not isinstance(data, dict):
            raise UserError(f"{where}: expected an object like {{\"shape\": \"ball\", \"center\": [x, y, z], "
                            f"\"radius\": r}}, got {type(data).__name__} {_short(data)}")
        data = dict(data)
        shape = data.pop("shape", None)
        center = data.pop("center", None)
        if shape is None or center is None:
            raise UserError(f"{where}: needs 'shape' and 'center', got keys {sorted(data)}")
        center = _numbers(center, 3, f"{where}.center")
        try:
            if shape == "ball":
                if "radius" not in data:
                    raise UserError(f"{where}: a ball region needs 'radius'")
                radius = data.pop("radius")
                if not _is_number(radius):
                    raise UserError(f"{where}.radius: expected a number, got {_short(radius)}")
                return cls("ball", center, radius=float(radius), extra=data)
            if shape == "box":
                if "half_extents" not in data:
                    raise UserError(f"{where}: a box region needs 'half_extents' (three numbers)")
                half = _numbers(data.pop("half_extents"), 3, f"{where}.half_extents")
                rotation = data.pop("rotation", None)
                if rotation is not None:
                    rotation = _numbers(rotation, 9, f"{where}.rotation").reshape(3, 3)
                return cls("box", center, half_extents=half, rotation=rotation, extra=data)
            raise UserError(f"{where}.shape: {_short(shape)} is not a region shape; use \"ball\" or \"box\"")
        except UserError as err:
            if str(err).startswith(where):
                raise
            raise UserError(f"{where}: {err}") from None


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _short(value) -> str:
    text = json.dumps(value) if isinstance(value, (dict, list, str, int, float, bool, type(None))) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _numbers(value, count: int, where: str) -> np.ndarray:
    """``count`` finite numbers (a flat or nested list) as a float array; UserError otherwise."""
    flat = np.asarray(value, dtype=object).ravel() if isinstance(value, list) else None
    if flat is None or len(flat) != count or not all(_is_number(v) for v in flat):
        raise UserError(f"{where}: expected {count} numbers, got {_short(value)}")
    out = np.asarray(flat, dtype=np.float64)
    if not np.isfinite(out).all():
        raise UserError(f"{where}: the numbers must be finite, got {_short(value)}")
    return out


def union_mask(regions: list[HoleRegion], points: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Mask (N,) of the points inside any of ``regions`` (grown by ``margin``)."""
    mask = np.zeros(len(points), dtype=bool)
    for region in regions:
        mask |= region.contains(points, margin)
    return mask


def check_regions_near(frame: np.ndarray, regions: list[HoleRegion], reach: float | list[float], *,
                       tree: cKDTree | None = None,
                       who: str = "hole regions", frame_index: int = 0) -> None:
    """Refuse regions that do not belong to this cloud (UserError).

    A hole region lies on the surface it removed points from, so the point of ``frame`` (N, 3)
    nearest to its centre is at most ``bounding_radius + reach`` away (``reach``: one float, or one
    per region). A region farther away would add nothing, or points in empty space: the sign of a
    holes.json made for another sequence, another frame order, or other coordinates.
    """
    if not regions:
        return
    if tree is None:
        from scipy.spatial import cKDTree

        tree = cKDTree(frame)
    reaches = list(reach) if isinstance(reach, (list, tuple, np.ndarray)) else [reach] * len(regions)
    dist, _ = tree.query(np.array([r.center for r in regions]))
    for region, d, r in zip(regions, np.atleast_1d(dist), reaches):
        limit = region.bounding_radius + r
        if d > limit:
            raise UserError(
                f"{who}: frame {frame_index}: hole region centred at {np.round(region.center, 3).tolist()} is "
                f"{d:.3g} away from the nearest point, farther than its size plus the method's reach "
                f"({limit:.3g}); the regions do not belong to this cloud (wrong holes.json or wrong frame order?)")


def regions_to_json(regions_per_frame: list[list[HoleRegion]], **info: Any) -> dict:
    """The holes.json object: per frame the list of regions; ``info`` adds top-level keys
    (generator, params, seed, removed_fraction per frame, ...)."""
    frames = [{"frame": i, "regions": [r.to_dict() for r in regs]} for i, regs in enumerate(regions_per_frame)]
    per_frame = info.pop("per_frame", None)
    if per_frame:
        if len(per_frame) != len(frames):
            raise UserError(f"per_frame has {len(per_frame)} entries for {len(frames)} frames")
        for entry, extra in zip(frames, per_frame):
            clash = {"frame", "regions"} & set(extra)
            if clash:
                raise UserError(f"per_frame entries may not use the reserved keys {sorted(clash)}")
            entry.update(extra)
    return {"format": HOLES_FORMAT, "version": HOLES_VERSION, **info, "frames": frames}


def regions_from_json(data: dict | str | Path, frame_count: int | None = None, *,
                      label: str | None = None) -> list[list[HoleRegion]]:
    """Regions per frame from a holes.json object or file path, in frame order.

    The ``frame`` indices must be distinct integers >= 0; with ``frame_count`` (the frames of the
    sequence the regions are for) they must be exactly 0 .. frame_count-1, so that regions are never
    applied to a frame they were not made for. Any problem is a `metrics.errors.UserError` that names
    the file (or ``label``) and the entry (``frames[2].regions[0].radius: expected a number, got "a"``).
    """
    if isinstance(data, (str, Path)):
        path = Path(data)
        label = label or str(path)
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise UserError(f"{label}: no such holes file") from None
        except IsADirectoryError:
            raise UserError(f"{label}: is a folder; give the holes.json file inside it") from None
        except UnicodeDecodeError:
            raise UserError(f"{label}: not a text file, so not a holes.json") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise UserError(f"{label}: not valid JSON ({err.msg} at line {err.lineno}, column {err.colno}); "
                            "give the holes.json written by `dpcbench damage` or `dpcbench detect-holes`") from None
    label = label or "holes.json"
    if not isinstance(data, dict):
        raise UserError(f"{label}: holds a JSON {type(data).__name__}, not a holes.json object "
                            f"({{\"format\": \"{HOLES_FORMAT}\", \"frames\": [...]}}); give the holes.json written by "
                            "`dpcbench damage` or `dpcbench detect-holes`")
    if data.get("format") != HOLES_FORMAT:
        raise UserError(f"{label}: not a holes file: 'format' is {data.get('format')!r}, expected {HOLES_FORMAT!r}")
    frames = data.get("frames")
    if not isinstance(frames, list):
        raise UserError(f"{label}: 'frames' must be a list of {{\"frame\": i, \"regions\": [...]}} entries, got "
                        f"{_short(frames)}")
    entries = {}
    for k, entry in enumerate(frames):
        where = f"{label}: frames[{k}]"
        if not isinstance(entry, dict):
            raise UserError(f"{where}: expected an object with 'frame' and 'regions', got {_short(entry)}")
        index = entry.get("frame")
        if not isinstance(index, int) or isinstance(index, bool) or index < 0:
            raise UserError(f"{where}.frame: expected a frame index (an integer >= 0), got {_short(index)}")
        if index in entries:
            raise UserError(f"{where}.frame: frame {index} is listed twice; give each frame once")
        regions = entry.get("regions")
        if not isinstance(regions, list):
            raise UserError(f"{where}.regions: expected a list of regions, got {_short(regions)}")
        entries[index] = [HoleRegion.from_dict(r, f"{where}.regions[{j}]") for j, r in enumerate(regions)]
    order = sorted(entries)
    if frame_count is not None and order != list(range(frame_count)):
        missing = [i for i in range(frame_count) if i not in entries]
        extra = [i for i in order if i >= frame_count]
        detail = (f"frame(s) {_index_list(extra)} do not exist in the sequence (frames 0..{frame_count - 1})"
                  if extra else f"it has no entry for frame(s) {_index_list(missing)}")
        raise UserError(f"{label}: describes {len(order)} frame(s) ({_index_list(order)}) but the sequence has "
                        f"{frame_count} frame(s): {detail}; use the holes.json made for these frames (same --frames)")
    if frame_count is None and order != list(range(len(order))):
        raise UserError(f"{label}: frame indices {_index_list(order)} are not 0..{len(order) - 1}; a holes.json "
                        "lists every frame of its sequence from 0")
    return [entries[i] for i in order]


def _index_list(indices: list[int]) -> str:
    shown = ", ".join(str(i) for i in indices[:6])
    return shown + (f" ... ({len(indices)} in all)" if len(indices) > 6 else "") if indices else "none"
