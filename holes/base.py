"""The interface of hole generators.

``HoleGenerator(**params).damage(frames, seed, colors=None) -> DamageResult``:
  frames: list of F arrays (N_f, 3), the intact sequence (ground truth). Never modified.
  seed:   int or numpy.random.Generator; the same seed gives the same damage.
  colors: optional list of F (N_f, 3) uint8 arrays, damaged alongside the points.

``__init__`` only stores its keyword parameters (scikit-learn convention); validation of
parameters against the data happens in `damage`, which raises ValueError with a clear message for
parameters that would remove all points, or none, or do not fit the frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.params import Parameterized

#: a seed: an int, or a numpy Generator passed through
Seed = int | np.random.Generator
#: optional per-frame colours: F arrays (N_f, 3) uint8 (an entry may be None), or None
Colors = Sequence[np.ndarray | None] | None


@dataclass
class DamageResult:
    """frames[f] == original[f][~removed[f]] exactly (same row order)."""

    frames: list[np.ndarray]
    removed: list[np.ndarray]
    regions: list[list[HoleRegion]]
    colors: list[np.ndarray | None] | None = None

    @property
    def removed_fraction(self) -> list[float]:
        return [float(mask.mean()) for mask in self.removed]


class HoleGenerator(Parameterized):
    """A hole generator: ``__init__`` stores keyword parameters; `damage` does the work.

    ``get_params`` / ``validate_params`` come from `metrics.params.Parameterized`; a generator's
    own parameter checks go in ``_check_params`` (or ``_check``), run by ``validate_params``.
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    version: ClassVar[str] = "1"
    _kind: ClassVar[str] = "hole generator"
    _param_hooks: ClassVar[tuple[str, ...]] = ("_check_params", "_check")
    #: False for `NoHoles` only: the input is the data as captured, with no ground truth apart from
    #: itself, so there is nothing to score a fill against, and the seed plays no part
    removes_points: ClassVar[bool] = True

    def damage(self, frames: list[np.ndarray], seed: Seed, colors: Colors = None) -> DamageResult:
        raise NotImplementedError


class NoHoles(HoleGenerator):
    """Remove nothing: the data's own (real) holes are the holes, as in the real-hole protocol, where
    a method fills the gaps of a captured sequence and only its output (and time) can be looked at.

    ``damage`` returns copies of the frames (and colours), no removed point and no region; the seed
    is not used. The counterpart of the ``none`` method (`methods.reference.NoFill`).
    """

    name = "none"
    summary = "no damage: the data's own (real) holes; nothing removed, so no quality score"
    version = "1"
    removes_points = False

    def __init__(self):
        pass

    def damage(self, frames: list[np.ndarray], seed=None, colors=None) -> DamageResult:
        frames = list(frames)
        return DamageResult([np.array(f, copy=True) for f in frames], [np.zeros(len(f), bool) for f in frames],
                            [[] for _ in frames], colors)


def as_generator(seed: Seed | None) -> np.random.Generator:
    """A numpy Generator from an int seed (or pass a Generator through)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        raise UserError("a seed is required: pass an int so that the damage is reproducible")
    return np.random.default_rng(seed)


def check_sequence_input(frames: Sequence[np.ndarray], colors: Colors = None,
                         what: str = "hole generator") -> tuple[list[np.ndarray], list | None]:
    """Validate a sequence for damage: a non-empty list of finite (N_f, 3) arrays with optional
    matching (N_f, 3) colours. Returns float64 frames and the colours (or None). ValueError otherwise."""
    from dpcbench.holes.geometry import check_frame

    if isinstance(frames, np.ndarray) and frames.ndim == 2:
        raise UserError(f"{what}: expected a list of frames (a sequence), got one (N, 3) array; wrap it in a list")
    frames = [check_frame(f, f"{what}: frame {i}") for i, f in enumerate(frames)]
    if not frames:
        raise UserError(f"{what}: the sequence has no frames")
    if colors is not None:
        colors = list(colors)
        if len(colors) != len(frames):
            raise UserError(f"{what}: {len(colors)} colour arrays for {len(frames)} frames")
        for i, (pts, col) in enumerate(zip(frames, colors)):
            if col is not None and len(col) != len(pts):
                raise UserError(f"{what}: frame {i} has {len(pts)} points but {len(col)} colours")
    return frames, colors


def make_result(
    frames: list[np.ndarray],
    removed: list[np.ndarray],
    regions: list[list[HoleRegion]],
    colors: Colors = None,
    *,
    what: str = "hole generator",
    max_fraction: float = 1.0,
) -> DamageResult:
    """Apply the removal masks and refuse damage that removes nothing or too much.

    frames[f][~removed[f]] becomes the damaged frame f (row order kept), likewise its colours.
    ValueError when a frame loses no point, loses every point, or loses more than ``max_fraction``.
    """
    for i, (pts, mask) in enumerate(zip(frames, removed)):
        lost = int(mask.sum())
        if lost == 0:
            raise UserError(
                f"{what}: frame {i} would lose no point (holes smaller than the point spacing?); "
                "use larger holes or a higher fraction"
            )
        if lost == len(pts):
            raise UserError(f"{what}: frame {i} would lose all its {len(pts)} points; use fewer or smaller holes")
        if lost > max_fraction * len(pts):
            raise UserError(
                f"{what}: frame {i} would lose {lost / len(pts):.1%} of its points, more than "
                f"max_fraction={max_fraction:.0%}; use fewer or smaller holes (or raise max_fraction)"
            )
    damaged = [pts[~mask] for pts, mask in zip(frames, removed)]
    damaged_colors = None
    if colors is not None:
        damaged_colors = [None if col is None else np.asarray(col)[~mask] for col, mask in zip(colors, removed)]
    return DamageResult(damaged, removed, regions, damaged_colors)
