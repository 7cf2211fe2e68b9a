"""Types shared by the numpy API's signatures: a frame, a sequence, and what a hole region must offer.

``metrics`` is the lowest layer, so it cannot name `holes.regions.HoleRegion`; the metrics need only
its ``contains`` method, which `Region` states (HoleRegion satisfies it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

#: one point cloud: an (N, 3) float array
Frame = np.ndarray
#: a sequence of frames (list of (N_f, 3) arrays)
Frames = Sequence[np.ndarray]


class Region(Protocol):
    """A hole region: which points lie inside it, grown by ``margin``."""

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask (N,) of the (N, 3) ``points`` inside the region grown by ``margin``."""
        ...


#: hole regions of each frame of a sequence
RegionsPerFrame = Sequence[Sequence[Region]]
