"""The state temporal-fusion's stages pass to each other: small frozen records. Arrays inside them are never
written after construction; a stage that changes the state returns a new record."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion

EMPTY = np.zeros((0, 3))


class Motion(NamedTuple):
    """A frame's motion to frame f: x -> x @ rotation.T + translation, then the rim's displacement field
    (anchors (K, 3), displacement (K, 3)), or None when not deformed."""

    rotation: np.ndarray
    translation: np.ndarray
    field: tuple[np.ndarray, np.ndarray] | None


class Candidate(NamedTuple):
    """Frame g's points inside R moved to frame f, with the rim residual of its alignment; sorted by
    (rim residual, |g - f|, g). ``colours``: the moved points' RGB (P, 3) float64 from frame g, None when the run
    tracks no colour (`colours`)."""

    residual: float
    gap: int
    frame: int
    points: np.ndarray
    colours: np.ndarray | None = None


class Aligned(NamedTuple):
    """One frame's alignment (stage align): its points round R (``source`` (K, 3), their ``rows`` in frame g and
    their k-d tree), the motion to frame f and the rim residual."""

    source: np.ndarray
    tree: cKDTree
    rotation: np.ndarray
    translation: np.ndarray
    residual: float
    rows: np.ndarray


@dataclass(frozen=True)
class SequenceData:
    """What every stage reads of the whole sequence: the damaged frames (F arrays (N_f, 3)), their hole regions,
    a k-d tree per frame (``tree_of(g)``, cached), the point spacing s, the spatial fill's grid step, whether the
    data is voxelized, and the fit sizes (``neighbours`` for voxel decisions, ``projection_neighbours`` for MLS
    projections); ``colours``: the frames' RGB (F arrays (N_f, 3) float64) when the run tracks colour, else None."""

    frames: Sequence[np.ndarray]
    regions: Sequence[Sequence[HoleRegion]]
    tree_of: Callable[[int], cKDTree]
    spacing: float
    step: float
    voxelized: bool
    neighbours: int
    projection_neighbours: int
    colours: Sequence[np.ndarray] | None = None


@dataclass(frozen=True)
class Crop:
    """Stage crop's output for frame f and region R: ``local`` frame f's points within r + 2 shell of R in the
    frame's order, its k-d tree, ``rim`` those within the shell of R, the shell width and the crop's reach."""

    local: np.ndarray
    tree: cKDTree
    rim: np.ndarray
    shell: float
    reach: float


@dataclass(frozen=True)
class Alignments:
    """Stage align's output: ``candidates`` (frames that saw all of R), ``partial`` (frames with their own hole
    near R: what they saw of it), ``motions`` (frame -> `Motion` of every source, f's identity included),
    ``carried`` (f-1's motion where it carries its fill but is no source) and ``next_motion`` (f+1's motion to f,
    for the back-fill)."""

    candidates: tuple[Candidate, ...]
    partial: tuple[Candidate, ...]
    motions: Mapping[int, Motion]
    carried: Motion | None
    next_motion: Motion | None


@dataclass(frozen=True)
class Fused:
    """Stage fuse's output: the fused copies (P, 3), ``full_copy`` whether any copy was fused before the
    re-voxelization (its frame saw all of R: no spatial fill), the candidates in fusion order, and the copies'
    colours (P, 3) (None without colour)."""

    points: np.ndarray
    full_copy: bool
    candidates: tuple[Candidate, ...]
    colours: np.ndarray | None = None


@dataclass(frozen=True)
class RegionFill:
    """One region's fill: ``points`` (P, 3) to add, ``next_motion`` f+1's motion where R stayed open (for the
    back-fill), ``not_reused`` the parts frame f+1 must not reuse (partial copies, caps, membranes) and
    ``from_previous`` the parts reused from frame f-1 (the back-fill does not carry them back); ``colours`` (P, 3)
    the points' carried colours (NaN rows: spatial fill; None without colour)."""

    points: np.ndarray
    next_motion: Motion | None = None
    not_reused: tuple[np.ndarray, ...] = ()
    from_previous: tuple[np.ndarray, ...] = ()
    colours: np.ndarray | None = None


@dataclass(frozen=True)
class FrameFill:
    """One frame's fill: ``added`` (A, 3) the points added, ``reusable`` those frame f+1 may reuse, ``found`` those
    of the latter frame f found itself (what the back-fill carries to f-1), and ``next_motions`` one per region;
    ``colours`` (A, 3) the added points' carried colours (NaN rows: spatial fill; None without colour) and the rows
    of ``added`` that ``reusable`` and ``found`` are."""

    added: np.ndarray
    reusable: np.ndarray
    found: np.ndarray
    next_motions: tuple[Motion | None, ...]
    colours: np.ndarray | None = None
    reusable_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    found_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
