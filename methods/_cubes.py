"""Cube and grid helpers for cube-based point cloud inpainting (numpy / scipy only).

A frame is cut into axis-aligned *cells* of side ``s`` anchored at an ``origin``; a *cube* of side
``M = c * s`` is a ``c x c x c`` block of cells (c = 4 gives the paper's overlap step M/4). Every
cell index ``a`` anchors one cube (cells ``a .. a + c - 1`` on each axis), so the cubes overlap with
step ``s`` and every point lies in ``c^3`` cubes.

Per-cube sums of any per-point quantity are computed by binning the points into cells (one
``np.bincount``) and then summing ``c x c x c`` blocks of cells with a summed-volume table
(`block_sums`): O(number of cells), independent of the cube size.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dpcbench.holes.regions import HoleRegion


def block_sums(grid: np.ndarray, width: int) -> np.ndarray:
    """Sums of every ``width^3`` block of a 3D grid (trailing axes are channels, summed separately).

    grid: (X, Y, Z, ...) array. Returns (X - width + 1, Y - width + 1, Z - width + 1, ...) where
    entry [i, j, k] = sum(grid[i:i+width, j:j+width, k:k+width]). Uses a summed-volume table
    (inclusion-exclusion over the 8 corners), O(X Y Z) whatever ``width`` is.
    """
    if width < 1 or any(n < width for n in grid.shape[:3]):
        raise ValueError(f"block width {width} does not fit in a grid of shape {grid.shape[:3]}")
    dtype = np.float64 if grid.dtype.kind == "f" else np.int64
    table = np.zeros((grid.shape[0] + 1, grid.shape[1] + 1, grid.shape[2] + 1) + grid.shape[3:], dtype=dtype)
    table[1:, 1:, 1:] = grid
    for axis in range(3):
        np.cumsum(table, axis=axis, out=table)
    w = width

    def t(x0, y0, z0):
        return table[x0:table.shape[0] - w + x0, y0:table.shape[1] - w + y0, z0:table.shape[2] - w + z0]

    return (t(w, w, w) - t(0, w, w) - t(w, 0, w) - t(w, w, 0)
            + t(0, 0, w) + t(0, w, 0) + t(w, 0, 0) - t(0, 0, 0))


class CellGrid:
    """Axis-aligned cells of side ``cell`` covering a box; cubes are ``cells_per_cube^3`` blocks.

    origin: (3,) lower corner; shape: (3,) number of cells per axis. Cell (i, j, k) spans
    ``origin + [i, i+1) * cell`` (etc.). A cube "anchored" at cell a spans
    ``origin + [a, a + cells_per_cube) * cell``.
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, cell: float, cells_per_cube: int, pad: int = 0):
        if not cell > 0:
            raise ValueError(f"cell size must be positive, got {cell}")
        self.cell = float(cell)
        self.cells_per_cube = int(cells_per_cube)
        lower = np.asarray(lower, dtype=np.float64)
        upper = np.asarray(upper, dtype=np.float64)
        # pad on both sides so that cubes around the outermost points exist
        self.origin = np.floor(lower / cell) * cell - pad * cell
        top = np.floor(upper / cell) * cell + (pad + 1) * cell
        self.shape = np.maximum(np.round((top - self.origin) / cell).astype(np.int64), self.cells_per_cube)

    @property
    def cube_size(self) -> float:
        """Side M = cell * cells_per_cube of a cube."""
        return self.cell * self.cells_per_cube

    def cell_of(self, points: np.ndarray) -> np.ndarray:
        """Integer cell index (N, 3) of each point (may lie outside [0, shape))."""
        return np.floor((np.asarray(points) - self.origin) / self.cell).astype(np.int64)

    def inside(self, cells: np.ndarray) -> np.ndarray:
        """Mask (N,) of the cell indices (N, 3) that lie in the grid, 0 <= cell < shape."""
        return np.asarray(((cells >= 0) & (cells < self.shape)).all(axis=1))

    def bin(self, points: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """Per-cell sums of ``values`` (N,) or (N, C) over the points; counts when values is None.

        Returns (X, Y, Z) or (X, Y, Z, C). Points outside the grid are ignored.
        """
        cells = self.cell_of(points)
        keep = self.inside(cells)
        flat = np.ravel_multi_index(cells[keep].T, tuple(self.shape))
        size = int(np.prod(self.shape))
        if values is None:
            return np.bincount(flat, minlength=size).reshape(tuple(self.shape))
        values = np.asarray(values, dtype=np.float64)[keep]
        if values.ndim == 1:
            return np.bincount(flat, weights=values, minlength=size).reshape(tuple(self.shape))
        out = np.empty((size, values.shape[1]))
        for c in range(values.shape[1]):
            out[:, c] = np.bincount(flat, weights=values[:, c], minlength=size)
        return out.reshape(tuple(self.shape) + (values.shape[1],))

    def cube_sums(self, cell_grid: np.ndarray) -> np.ndarray:
        """Per-cube sums of a per-cell grid: entry a is the sum over the cube anchored at cell a."""
        return block_sums(cell_grid, self.cells_per_cube)

    def cube_lower(self, anchors: np.ndarray) -> np.ndarray:
        """Lower corner(s) (..., 3) of the cube(s) anchored at cell index(es) ``anchors``."""
        return self.origin + np.asarray(anchors) * self.cell

    def cubes_of_point(self, point: np.ndarray) -> np.ndarray:
        """The anchors (c^3, 3) of all cubes that contain ``point`` (some may be outside the grid)."""
        cell = self.cell_of(np.asarray(point).reshape(1, 3))[0]
        r = np.arange(self.cells_per_cube)
        offsets = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
        return cell - offsets


def in_box(points: np.ndarray, lower: np.ndarray, size: float) -> np.ndarray:
    """Mask (N,) of points with lower <= p < lower + size on every axis."""
    points, lower = np.asarray(points), np.asarray(lower)
    # axis by axis: the same test as ((rel >= 0) & (rel < size)).all(axis=1) without (N, 3) temporaries and the
    # slow reduction over a length-3 axis (this runs once per target cube on the group's points)
    mask = np.ones(len(points), dtype=bool)
    for axis in range(3):
        rel = points[:, axis] - lower[axis]
        mask &= rel >= 0
        mask &= rel < size
    return mask


def best_window(points: np.ndarray, box_lower: np.ndarray, box_size: float, window: float, unit: float
                ) -> tuple[np.ndarray, int]:
    """The cubic window of side ``window`` inside the box that holds the most of ``points``.

    The box ``[box_lower, box_lower + box_size)^3`` is cut into voxels of side ``unit``; the window
    slides with stride one voxel (the paper's stride 1 at 10 bits, where a voxel is one unit). The
    count of every window position comes from a summed-volume table over the voxel histogram:
    O(H^3) for H = box_size / unit, never O(H^3 M^3). Ties go to the position nearest the box
    centre (then the lowest index), so the co-located window wins when nothing moved.

    points: (N, 3) positions (those outside the box are ignored). Returns (lower corner of the best
    window (3,), its count).
    """
    nbox = max(1, int(np.ceil(box_size / unit - 1e-9)))
    nwin = min(nbox, max(1, int(round(window / unit))))
    cells = np.floor((np.asarray(points) - box_lower) / unit).astype(np.int64)
    keep = ((cells >= 0) & (cells < nbox)).all(axis=1)
    hist = np.bincount(np.ravel_multi_index(cells[keep].T, (nbox,) * 3), minlength=nbox ** 3).reshape((nbox,) * 3)
    counts = block_sums(hist, nwin)
    best = counts.max()
    ties = np.argwhere(counts == best)
    centre = (nbox - nwin) / 2.0
    pick = ties[np.argmin(((ties - centre) ** 2).sum(axis=1))]
    return box_lower + pick * unit, int(best)


def hole_cells(grid: CellGrid, regions: Sequence[HoleRegion]) -> np.ndarray:
    """Bool (X, Y, Z) over ``grid``: the cells that touch a hole region.

    A cell touches a region when its centre lies within the region grown by half the cell's
    diagonal (``region.contains(centre, margin=cell * sqrt(3) / 2)``): a superset of the cells the
    region overlaps, exact for balls. Only the cells in each region's bounding box are tested.
    """
    mask = np.zeros(tuple(grid.shape), dtype=bool)
    half_diag = grid.cell * np.sqrt(3.0) / 2.0
    for region in regions:
        r = region.bounding_radius + half_diag
        lo = np.clip(grid.cell_of((region.center - r)[None])[0], 0, grid.shape)
        hi = np.clip(grid.cell_of((region.center + r)[None])[0] + 1, 0, grid.shape)
        if (hi <= lo).any():
            continue
        idx = np.stack(np.meshgrid(*[np.arange(a, b) for a, b in zip(lo, hi)], indexing="ij"), -1).reshape(-1, 3)
        centres = grid.origin + (idx + 0.5) * grid.cell
        hit = idx[region.contains(centres, margin=half_diag)]
        mask[tuple(hit.T)] = True
    return mask


def region_groups(regions: Sequence[HoleRegion], reach: float) -> list[list[HoleRegion]]:
    """The regions grouped by single linkage: two regions join a group when their bounding balls
    are at most ``2 * reach`` apart (||c_i - c_j|| <= r_i + r_j + 2 reach), so that the target
    cubes of different groups never share a cell. Groups in order of their first region; regions in
    input order within a group."""
    n = len(regions)
    label = list(range(n))

    def root(i: int) -> int:
        while label[i] != i:
            label[i] = label[label[i]]
            i = label[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            gap = np.linalg.norm(regions[i].center - regions[j].center)
            if gap <= regions[i].bounding_radius + regions[j].bounding_radius + 2 * reach:
                label[root(i)] = root(j)
    groups: dict[int, list[HoleRegion]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(regions[i])
    return list(groups.values())


class TargetCubeOrder:
    """The order in which the target cubes of one group of holes are filled: from the rim inward.

    Works on a window of cells (local indices): ``pending`` (X, Y, Z) bool, the cells with missing
    data not yet covered by a filled cube; ``known`` (X, Y, Z) int, the points per cell (captured
    and filled). A cube is anchored at local cell a (cells a .. a + c - 1, c = cells_per_cube);
    there are (X - c + 1) (Y - c + 1) (Z - c + 1) of them. Per-cube sums (pending cells, known
    points, pending cells in the central (c - 2 floor(c / 4))^3 block) come from summed-volume
    tables and are refreshed only around a filled cube.

    `next` returns the anchor (3,) of the next target cube, or None when the group is done:
    among the cubes not yet tried with >= ``min_known_points`` known points (and more than when
    they were last `defer`-red), those with a pending cell in their central block when
    ``rim_centred`` (a cube centred on the rim: about half known for the matching, half missing),
    else (or when none is left) those with any pending cell; of these the one with the most known
    points, the first in C order on ties. `filled` records a fill: the cube is tried, the cells of
    its new points gain known points, its pending cells are done.
    """

    def __init__(self, pending: np.ndarray, known: np.ndarray, cells_per_cube: int, min_known_points: int,
                 rim_centred: bool):
        self.pending = pending
        self.known = known
        self.per = int(cells_per_cube)
        self.min_known_points = min_known_points
        self.rim_centred = rim_centred
        self.c0 = self.per // 4
        self.cw = self.per - 2 * self.c0
        self.n_anchor = np.array(pending.shape) - self.per + 1
        shape = tuple(self.n_anchor)
        self.pending_sums = np.zeros(shape, dtype=np.int64)
        self.known_sums = np.zeros(shape, dtype=np.int64)
        self.central_sums = np.zeros(shape, dtype=np.int64)
        self.tried = np.zeros(shape, dtype=bool)  # each cube is a target at most once
        # known count of a cube when it was put off; it is eligible again once it holds more
        self.deferred = np.full(shape, -1, dtype=np.int64)
        self._refresh(np.zeros(3, dtype=np.int64), self.n_anchor)

    def _refresh(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Recompute the per-cube sums of the anchors lo .. hi - 1 (clipped to the window)."""
        per, c0, cw = self.per, self.c0, self.cw
        lo = np.maximum(lo, 0)
        hi = np.minimum(hi, self.n_anchor)
        if (hi <= lo).any():
            return
        cells = tuple(slice(a, b + per - 1) for a, b in zip(lo, hi))
        anchors = tuple(slice(a, b) for a, b in zip(lo, hi))
        centre = tuple(slice(a + c0, b + c0 + cw - 1) for a, b in zip(lo, hi))
        self.pending_sums[anchors] = block_sums(self.pending[cells].astype(np.int64), per)
        self.known_sums[anchors] = block_sums(self.known[cells], per)
        self.central_sums[anchors] = block_sums(self.pending[centre].astype(np.int64), cw)

    def next(self) -> np.ndarray | None:
        """The local anchor (3,) of the next target cube, or None when no cube is eligible."""
        known = self.known_sums
        enough = (known >= self.min_known_points) & ~self.tried & (known > self.deferred)
        eligible = (self.central_sums > 0) & enough if self.rim_centred else np.zeros_like(enough)
        if not eligible.any():
            # no known-rich cube is centred on the hole any more (or rim_centred is off): any cube
            # with missing data
            eligible = (self.pending_sums > 0) & enough
            if not eligible.any():
                return None
        # the target cube with the most known data first: holes fill from the rim inward
        return np.array(np.unravel_index(np.argmax(np.where(eligible, known, -1)), eligible.shape))

    def block(self, anchor: np.ndarray) -> tuple[slice, ...]:
        """The cells (a slice per axis) of the cube anchored at local cell ``anchor``."""
        return tuple(slice(p, p + self.per) for p in anchor)

    def reaches_pending(self, anchor: np.ndarray) -> bool:
        """True when, inside the cube at ``anchor``, a cell holding points is a pending cell or
        touches one (26-neighbourhood): the surface reaches the missing part."""
        per = self.per
        block = self.block(anchor)
        hole = self.pending[block]
        if not hole.any():
            return False
        near = np.zeros((per + 2,) * 3, dtype=bool)
        for dx, dy, dz in itertools.product(range(3), repeat=3):
            near[dx:dx + per, dy:dy + per, dz:dz + per] |= hole
        return bool((near[1:-1, 1:-1, 1:-1] & (self.known[block] > 0)).any())

    def defer(self, anchor: np.ndarray) -> None:
        """Put the cube off until it holds more known points than now."""
        self.deferred[tuple(anchor)] = self.known_sums[tuple(anchor)]

    def filled(self, anchor: np.ndarray, new_cells: np.ndarray) -> None:
        """Record the fill of the cube at ``anchor`` whose new points lie in the local cells
        ``new_cells`` (P, 3) (those outside the window are ignored). The per-cube sums are refreshed
        for the cubes that overlap this one: a new point that the solve moved out of the target cube
        counts in its cell but not yet in the sums of the cubes beyond (kept so: outputs unchanged)."""
        self.tried[tuple(anchor)] = True
        if len(new_cells):
            keep = ((new_cells >= 0) & (new_cells < self.known.shape)).all(axis=1)
            np.add.at(self.known, tuple(new_cells[keep].T), 1)
        self.pending[self.block(anchor)] = False
        self._refresh(anchor - self.per + 1, anchor + self.per)
