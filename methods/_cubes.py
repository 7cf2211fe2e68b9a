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

import numpy as np


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
        return self.cell * self.cells_per_cube

    def cell_of(self, points: np.ndarray) -> np.ndarray:
        """Integer cell index (N, 3) of each point (may lie outside [0, shape))."""
        return np.floor((np.asarray(points) - self.origin) / self.cell).astype(np.int64)

    def inside(self, cells: np.ndarray) -> np.ndarray:
        return ((cells >= 0) & (cells < self.shape)).all(axis=1)

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
    rel = np.asarray(points) - lower
    return ((rel >= 0) & (rel < size)).all(axis=1)


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
