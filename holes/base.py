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

import inspect
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from holes.regions import HoleRegion


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


class HoleGenerator:
    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    version: ClassVar[str] = "1"

    def get_params(self) -> dict:
        sig = inspect.signature(type(self).__init__)
        kinds = (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
        return {p.name: getattr(self, p.name) for p in sig.parameters.values() if p.name != "self" and p.kind in kinds}

    def damage(self, frames: list[np.ndarray], seed, colors=None) -> DamageResult:
        raise NotImplementedError


def as_generator(seed) -> np.random.Generator:
    """A numpy Generator from an int seed (or pass a Generator through)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        raise ValueError("a seed is required: pass an int so that the damage is reproducible")
    return np.random.default_rng(seed)
