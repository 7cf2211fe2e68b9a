"""Colour bookkeeping of temporal-fusion: every new point's colour decided the way its position was.

A run that tracks colour carries, beside each array of new points, an (P, 3) float64 RGB array (NaN rows where a
point has no carried colour: the spatial fills'); a run without colour carries None and every function here
returns None. Rows kept by a mask keep their colour; where a stage replaces points by voxels, each voxel takes the
mean colour of the points that decided it:

- `pooled`: the voxels `voxels.surface_voxels` keeps (stage fuse, settle): the mean of the coloured points within
  the reach its candidates were chosen by (every kept voxel has one; one without takes its nearest point's colour);
- `rounded`: points rounded to the grid (`voxels.snap_to_voxels`, `_spatial_fill.unique_voxels`): the mean of
  the coloured points that round to the voxel, NaN where none of them is coloured.

The mean, not the nearest: the points within a voxel's reach are the same surface seen by one or more captures
(f-1's and f+1's copies where both were sources), so their mean averages the captures' colour noise and their
alignment errors, as the voxel's fit averages their positions."""

from __future__ import annotations

from typing import overload

import numpy as np
from scipy.spatial import cKDTree


def no_colour(count: int) -> np.ndarray:
    """(count, 3) NaN: points with no carried colour."""
    return np.full((count, 3), np.nan)


def stacked(parts: list[np.ndarray | None], counts: list[int]) -> np.ndarray | None:
    """The colours of ``parts`` stacked (None parts as NaN rows of their ``counts``); None when all are None."""
    if all(part is None for part in parts):
        return None
    return np.vstack([no_colour(n) if part is None else part for part, n in zip(parts, counts)]) if parts \
        else no_colour(0)


def masked(colours: np.ndarray | None, keep: np.ndarray) -> np.ndarray | None:
    """``colours[keep]`` (None stays None)."""
    return None if colours is None else colours[keep]


@overload
def pooled(points: np.ndarray, colours: np.ndarray, targets: np.ndarray, reach: float) -> np.ndarray: ...
@overload
def pooled(points: np.ndarray, colours: None, targets: np.ndarray, reach: float) -> None: ...
@overload
def pooled(points: np.ndarray, colours: np.ndarray | None, targets: np.ndarray, reach: float) -> np.ndarray | None: ...
def pooled(points: np.ndarray, colours: np.ndarray | None, targets: np.ndarray, reach: float) -> np.ndarray | None:
    """(T, 3) the mean colour of the coloured ``points`` (P, 3) within ``reach`` (ties included) of each of
    ``targets`` (T, 3); a target with none within reach takes its nearest coloured point's colour, NaN when no
    point is coloured."""
    if colours is None:
        return None
    known = np.isfinite(colours).all(axis=1)
    if not len(targets) or not known.any():
        return no_colour(len(targets))
    points, colours = points[known], colours[known]
    tree = cKDTree(points)
    # (a sparse distance matrix would drop the pairs at distance 0: a voxel on a copied point)
    within = tree.query_ball_point(targets, reach * (1 + 1e-9))
    count = np.fromiter((len(w) for w in within), dtype=np.intp, count=len(targets))
    rows = np.repeat(np.arange(len(targets)), count)
    cols = np.fromiter((j for w in within for j in w), dtype=np.intp, count=int(count.sum()))
    count = count.astype(np.float64)
    out = np.column_stack([np.bincount(rows, weights=colours[cols, c], minlength=len(targets)) for c in range(3)])
    alone = count == 0
    out[~alone] /= count[~alone, None]
    if alone.any():
        out[alone] = colours[tree.query(targets[alone])[1]]
    return out


@overload
def rounded(points: np.ndarray, colours: np.ndarray, voxels: np.ndarray) -> np.ndarray: ...
@overload
def rounded(points: np.ndarray, colours: None, voxels: np.ndarray) -> None: ...
@overload
def rounded(points: np.ndarray, colours: np.ndarray | None, voxels: np.ndarray) -> np.ndarray | None: ...
def rounded(points: np.ndarray, colours: np.ndarray | None, voxels: np.ndarray) -> np.ndarray | None:
    """(V, 3) the mean colour of the coloured ``points`` (P, 3) that round (half up) to each of ``voxels`` (V, 3;
    integer), NaN where none does."""
    if colours is None:
        return None
    out = no_colour(len(voxels))
    known = np.isfinite(colours).all(axis=1)
    if not len(voxels) or not known.any():
        return out
    grid = np.floor(points[known] + 0.5)
    _, code = np.unique(np.vstack([np.asarray(voxels, dtype=np.float64), grid]), axis=0, return_inverse=True)
    code = code.ravel()
    voxel_of = np.full(code.max() + 1, -1, dtype=np.intp)
    voxel_of[code[:len(voxels)]] = np.arange(len(voxels))
    at = voxel_of[code[len(voxels):]]
    hit = at >= 0
    count = np.bincount(at[hit], minlength=len(voxels)).astype(np.float64)
    sums = np.column_stack([np.bincount(at[hit], weights=colours[known][hit, c], minlength=len(voxels))
                            for c in range(3)])
    filled = count > 0
    out[filled] = sums[filled] / count[filled, None]
    return out


def as_sources(kept: int, colours: np.ndarray) -> np.ndarray:
    """An output frame's colours as `methods._colour.colour_frame` takes a method's colours: (kept + P, 3) int16,
    -1 rows for the ``kept`` input points first (they keep their own colour) and where one of the P new points
    carries no colour (``colours`` (P, 3), NaN rows), the others rounded and clipped to 0..255."""
    out = np.full((kept + len(colours), 3), -1, dtype=np.int16)
    known = np.isfinite(colours).all(axis=1)
    out[kept:][known] = np.clip(np.rint(colours[known]), 0, 255).astype(np.int16)
    return out
