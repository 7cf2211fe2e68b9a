"""Nearest-neighbour relations between a reference cloud and a result cloud, computed once per frame.

Every geometry metric of this package (GPSNR D1/D2, Hausdorff, NSHD, Chamfer, F-score, and their
hole-region variants) is a reduction of a few per-point arrays:

- ``ref_to_res``: for every reference point a_i, its nearest result point and the squared distance;
- ``res_to_ref``: for every result point b_j, its nearest reference point and the squared distance;
- the point-to-plane errors of both directions (which need the equal-distance neighbours and the
  normals transferred from the reference to the result, as MPEG's pc_error does);
- the reference's own nearest-neighbour spacing (pc_error's "intrinsic resolution").

`CloudPair` builds the two KD-trees (scipy ``cKDTree``) and runs each query once, lazily, so that a
frame scored with all metrics queries each tree at most once per direction.

Shortcuts that change no value (they skip work whose result is known exactly):

- a point that occurs exactly in the other cloud (most points of a damaged or inpainted frame)
  has its nearest neighbour at distance 0; exact matches are found by hashing coordinates
  (`point_keys`, `SortedKeys`) and only the other points are queried in the tree;
- on integer (voxelized) data distinct points are at least 1 apart, so a point with one of its 6
  face neighbours present has nearest-neighbour distance exactly 1 (`face_neighbour_mask`), and
  no exact match has a second neighbour within the 1e-8 tolerance;
- the tie sets below are computed only when D2 or the normal transfer asks for them.

pc_error conventions reproduced here (mpeg-pcc-dmetric 0.14, default options):

- ``--dropdups=2``: points with identical coordinates are merged before anything is measured (the
  first occurrence in file order is kept, with its normal), in both clouds.
- Equal-distance neighbours (``--averageNormals=1``, ``--neighborsProc=1``): a query first asks for
  10 neighbours, and asks for 15, 20, 25, 30 while the last of them is still exactly as close as the
  first. The "same-distance" set of a point is then the run of neighbours, from the nearest on, whose
  squared distance differs from the previous one by less than 1e-8. Point-to-plane errors are
  averaged over that set. Normal transfer (pc_error's ``scaleNormals``) uses the neighbours at
  exactly the nearest squared distance.
- Squared distances are summed in pc_error's order, ``(dx*dx + dy*dy) + dz*dz`` in float64, so ties
  are detected on the same numbers.

Sets of more than 30 tied neighbours are truncated to 30, as in pc_error; which 30 depends on the
KD-tree, so such points (rare: far from any surface on a voxel grid) may differ from pc_error in the
last digits of D2.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from dpcbench.metrics.errors import UserError
from dpcbench.metrics.grid import GridCloud, GridFrame, face_neighbours, is_integer_grid, nearest

# the one normal estimator and point check (re-exported: metrics.pairs.estimate_normals is public API)
from dpcbench.metrics.neighbours import DEFAULT_NORMAL_NEIGHBOURS, check_points, estimate_normals
from dpcbench.metrics.types import Region

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

#: pc_error's ``similarPointThreshold``: consecutive neighbours whose squared distances differ by less
#: than this are "at the same distance".
SIMILAR_SQ_DISTANCE = 1e-8
#: pc_error's neighbour-count schedule for equal-distance neighbours (first query, increments, cap).
_NEIGHBOUR_SCHEDULE = (10, 15, 20, 25, 30)
#: Squared self-distance below which pc_error ignores a point when measuring the intrinsic resolution.
_INTRINSIC_MIN_SQ = 1e-10


def _mix64(z: np.ndarray) -> np.ndarray:
    """splitmix64's finalizer on uint64 values (in place): every input bit reaches every output bit."""
    z ^= z >> np.uint64(30)
    z *= np.uint64(0xBF58476D1CE4E5B9)
    z ^= z >> np.uint64(27)
    z *= np.uint64(0x94D049BB133111EB)
    z ^= z >> np.uint64(31)
    return z


def point_keys(points: np.ndarray) -> np.ndarray:
    """(N,) uint64 hash of each point's exact coordinates (the bits of the three float64 values).

    Equal points have equal keys (``+ 0.0`` maps -0.0 to 0.0 first, as pc_error's ``==`` equates
    them); different points almost never do, and every use of the keys checks the coordinates of
    the points it pairs, so a collision costs time, never correctness.
    """
    bits = np.ascontiguousarray(points + 0.0).view(np.uint64)
    key = _mix64(bits[:, 0].copy())
    key ^= bits[:, 1]
    key = _mix64(key)
    key ^= bits[:, 2]
    return _mix64(key)


def first_occurrences(points: np.ndarray) -> np.ndarray | None:
    """Indices of the first occurrence of each distinct point, in input order; None when all are distinct.

    Points are grouped by sorting their `point_keys` (one uint64 column, ~0.05 s for 1M points, and
    no pandas import); only the points of groups of equal keys are then compared coordinate by
    coordinate, so a key collision never merges distinct points.
    """
    return distinct_points(points)[0]


def _rows_equal(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) bool: a[i] == b[i] for (n, 3) arrays (column by column: cheaper than ``.all(axis=1)``)."""
    same = a[:, 0] == b[:, 0]
    same &= a[:, 1] == b[:, 1]
    same &= a[:, 2] == b[:, 2]
    return same


def _index_bits(n: int) -> int:
    return max(1, int(n - 1).bit_length())


def sort_with_order(keys: np.ndarray, key_bits: int = 64) -> tuple[np.ndarray, np.ndarray, int]:
    """(sorted keys, order, shift): ``order`` sorts ``keys`` (uint64, each < 2**key_bits), ties in index order.

    Each key and its index are packed into one uint64 and sorted with `np.sort` (a SIMD sort, ~5x
    faster than `np.argsort` on 1M values); keys too wide to share 64 bits with the index lose
    their ``shift`` lowest bits (the sorted keys returned are ``keys >> shift``). Callers that need
    exact keys check ``shift == 0``.
    """
    n = len(keys)
    bits = _index_bits(n)
    shift = max(0, key_bits + bits - 64)
    mask = np.uint64((1 << bits) - 1)
    packed = (keys >> np.uint64(shift)) << np.uint64(bits)
    packed |= np.arange(n, dtype=np.uint64)
    packed.sort()
    order = (packed & mask).astype(np.intp)
    packed >>= np.uint64(bits)
    return packed, order, shift


def distinct_points(points: np.ndarray) -> tuple[np.ndarray | None, SortedKeys]:
    """(first occurrences as `first_occurrences`, the `SortedKeys` of the distinct points)."""
    n = len(points)
    sorted_keys, order, shift = sort_with_order(point_keys(points))
    equal_next = sorted_keys[1:] == sorted_keys[:-1]
    if not equal_next.any():
        return None, SortedKeys(sorted_keys, order, shift)
    in_group = np.zeros(n, dtype=bool)
    in_group[1:] |= equal_next
    in_group[:-1] |= equal_next
    positions = np.flatnonzero(in_group)
    rows = order[positions]  # within a key group in index order
    coords = np.take(points, rows, axis=0) + 0.0
    # exact grouping of the few grouped rows; lexsort is stable, so a group's first row is its first occurrence
    by_coords = np.lexsort((coords[:, 2], coords[:, 1], coords[:, 0], sorted_keys[positions]))
    coords, rows = coords[by_coords], rows[by_coords]
    duplicated = np.zeros(n, dtype=bool)
    duplicated[rows[1:][_rows_equal(coords[1:], coords[:-1])]] = True
    if not duplicated.any():
        return None, SortedKeys(sorted_keys, order, shift)
    kept = np.flatnonzero(~duplicated)
    new_row = np.cumsum(~duplicated) - 1
    keep_sorted = ~duplicated[order]
    return kept, SortedKeys(sorted_keys[keep_sorted], new_row[order[keep_sorted]], shift)


def squared_distances(queries: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances between matching rows, summed as pc_error sums them.

    ``queries`` (..., 3) and ``targets`` (..., 3) broadcast together; returns (...). The order
    ``(dx*dx + dy*dy) + dz*dz`` makes ties on the voxel grid and float data identical to pc_error's.
    """
    d = queries - targets
    return (d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) + d[..., 2] * d[..., 2]


def on_integer_grid(points: np.ndarray) -> bool:
    """True when every coordinate is an integer (voxelized data): distinct points are then at least
    1 apart, so no two lie within pc_error's 1e-8 squared-distance tolerance."""
    return bool(np.equal(np.floor(points), points).all())


class SortedKeys:
    """The `point_keys` of a cloud's distinct points in sorted order, to find which points of another
    cloud occur in it exactly.

    keys: (K,) uint64 sorted, each a point key shifted right by ``shift`` bits; order: (K,) the row
    of each (``keys == point_keys(points)[order] >> shift``). Equal keys may belong to different
    points (a collision): every match is confirmed on the coordinates, and a query whose match is
    missed that way is simply searched in the KD-tree, so values never depend on collisions.
    """

    def __init__(self, keys: np.ndarray, order: np.ndarray, shift: int = 0):
        self.keys, self.order, self.shift = keys, order, shift

    def exact_matches(
        self, other: SortedKeys, queries: np.ndarray, targets: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(hit (n,) bool, index (n,) int): which ``queries`` (the cloud of ``other``) equal a point of
        ``targets`` (the cloud of ``self``), and that point's row (meaningful where hit). The queries
        are looked up in key order (numpy's binary search is several times faster on sorted
        queries)."""
        n = len(queries)
        hit = np.zeros(n, dtype=bool)
        index = np.zeros(n, dtype=np.intp)
        if len(self.keys) == 0 or n == 0:
            return hit, index
        shift = max(self.shift, other.shift)  # compare at the coarser of the two (a monotone map: order kept)
        mine = self.keys >> np.uint64(shift - self.shift) if shift > self.shift else self.keys
        theirs = other.keys >> np.uint64(shift - other.shift) if shift > other.shift else other.keys
        pos = np.searchsorted(mine, theirs)
        np.minimum(pos, len(mine) - 1, out=pos)
        found = mine[pos] == theirs
        rows, cols = other.order[found], self.order[pos[found]]
        for start in range(0, rows.size, _CHUNK):
            r, c = rows[start:start + _CHUNK], cols[start:start + _CHUNK]
            same = _rows_equal(np.take(targets, c, axis=0), np.take(queries, r, axis=0))
            hit[r[same]] = True
            index[r[same]] = c[same]
        return hit, index


#: Integer-grid clouds take the numpy path of `metrics.grid` (False: always the KD-tree; the tests
#: compare the two paths by switching this)
GRID_PATH = True

#: Query rows handled per block: bounds the (rows, k, 3) temporaries of `_sorted_query` (~25 MB at k = 10).
_CHUNK = 1 << 17


def _sorted_query(tree: cKDTree, targets: np.ndarray, queries: np.ndarray, rows: np.ndarray, k: int, workers: int = -1):
    """k nearest targets of ``queries[rows]`` as (index (m, k), squared distance (m, k)), each row
    sorted by the recomputed squared distance (cKDTree sorts on its own rounding of the distance).
    Queried in blocks of `_CHUNK` rows so that memory stays bounded."""
    m = len(rows)
    out_idx = np.empty((m, k), dtype=np.intp)
    out_sq = np.empty((m, k))
    for start in range(0, m, _CHUNK):
        block = np.take(queries, rows[start:start + _CHUNK], axis=0)
        _, idx = tree.query(block, k=k, workers=workers)
        idx = idx.reshape(len(block), k)
        sq = squared_distances(block[:, None, :], np.take(targets, idx, axis=0))
        if k == 2:  # a swap is enough, and much cheaper than argsort
            swap = sq[:, 1] < sq[:, 0]
            idx[swap] = idx[swap][:, ::-1]
            sq[swap] = sq[swap][:, ::-1]
        elif k > 2:
            order = np.argsort(sq, axis=1, kind="stable")
            idx = np.take_along_axis(idx, order, axis=1)
            sq = np.take_along_axis(sq, order, axis=1)
        out_idx[start:start + len(block)] = idx
        out_sq[start:start + len(block)] = sq
    return out_idx, out_sq


def build_tree(points: np.ndarray) -> cKDTree:
    """The KD-tree used for every query. ``balanced_tree=False, leafsize=32`` measured fastest for
    two builds + three 2-neighbour queries on the 100k golden pair: 0.30 s CPU against 0.35 s with
    scipy's defaults (leafsize 8: 0.40 s; compact_nodes=False: 0.39 s). The tree shares ``points``
    (float64, C order) instead of copying it."""
    from scipy.spatial import cKDTree  # imported here: integer-grid scoring never needs it (~40 MiB, 0.4 s)

    return cKDTree(points, leafsize=32, balanced_tree=False)


class _TiePairs:
    """The tie-pair attributes shared by `Neighbours` and `GridNeighbours`, read from their cached ``_ties``:
    (exact rows, exact cols, same rows, same cols), or (rows, cols) on the grid, where the same-distance
    run is the exact tie set."""

    @property
    def exact_rows(self) -> np.ndarray:
        return self._ties[0]  # type: ignore[attr-defined]

    @property
    def exact_cols(self) -> np.ndarray:
        return self._ties[1]  # type: ignore[attr-defined]

    @property
    def same_rows(self) -> np.ndarray:
        return self._ties[-2]  # type: ignore[attr-defined]

    @property
    def same_cols(self) -> np.ndarray:
        return self._ties[-1]  # type: ignore[attr-defined]


class Neighbours(_TiePairs):
    """Nearest neighbours of each query point in a target cloud, with pc_error's tie sets.

    sq_dist: (N,) float64, the squared distance of each query point to its nearest target point.
    index:   (N,) int, that nearest target point.
    exact_rows, exact_cols: flat pairs (query i, target j) of every target point at exactly the
        nearest squared distance (at least the nearest itself for each query point).
    same_rows, same_cols: flat pairs of pc_error's "same-distance" run (consecutive squared distances
        within `SIMILAR_SQ_DISTANCE`), a superset of the exact pairs.

    ``sq_dist`` is computed on construction (all D1 needs); ``index`` and the tie sets on first use
    (D2 and the normal transfer), so D1 alone never pays for the tie queries.

    Construction: ``order`` is a permutation of the queries that keeps spatially close queries
    together (the leaf order of the queries' own KD-tree; ~30% faster by cache locality on
    unordered files). ``matched`` (N,) bool / ``matched_index`` (N,) mark the queries equal to a
    target point (`SortedKeys.exact_matches`; only valid when the targets are distinct): their
    nearest distance is 0 without a tree query. ``separated_targets``: no two targets lie within
    the 1e-8 tolerance (integer grid), so a matched query has no tie either. The other queries
    first ask for 2 neighbours; those whose two are within the tolerance are asked again, lazily,
    with pc_error's 10..30 schedule.
    """

    def __init__(self, tree: cKDTree, targets: np.ndarray, queries: np.ndarray, order: np.ndarray | None = None, *,
                 matched: np.ndarray | None = None, matched_index: np.ndarray | None = None,
                 separated_targets: bool = False, workers: int = -1):
        n = len(queries)
        self._tree, self._targets, self._queries, self._workers = tree, targets, queries, workers
        if order is None:
            order = np.arange(n)
        nearest = np.empty(n, dtype=np.intp)
        nearest_sq = np.empty(n)
        check = np.empty(0, dtype=np.intp)
        if matched is not None and matched_index is not None and matched.any():
            nearest[matched] = matched_index[matched]
            nearest_sq[matched] = 0.0
            order = order[~matched[order]]
            if not separated_targets and tree.n > 1:
                check = np.flatnonzero(matched)  # a target within 1e-8 of the match would join its run
        k0 = min(2, tree.n)
        idx, sq = _sorted_query(tree, targets, queries, order, k0, workers)
        nearest[order] = idx[:, 0]
        nearest_sq[order] = sq[:, 0]
        self._nearest = nearest
        self.sq_dist = nearest_sq
        if k0 == 1:
            self._tie_rows = np.empty(0, dtype=np.intp)
        else:
            self._tie_rows = order[sq[:, 1] - sq[:, 0] < SIMILAR_SQ_DISTANCE]
        self._check_rows = check

    @property
    def index(self) -> np.ndarray:
        _ = self._ties  # resolving the ties rewrites _nearest: tied queries take pc_error's first neighbour
        return self._nearest

    @cached_property
    def _ties(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        tree, targets, queries = self._tree, self._targets, self._queries
        n = len(queries)
        nearest = self._nearest
        pending = self._tie_rows
        if self._check_rows.size:
            _, sq = _sorted_query(tree, targets, queries, self._check_rows, 2, self._workers)
            pending = np.concatenate([pending, self._check_rows[sq[:, 1] - sq[:, 0] < SIMILAR_SQ_DISTANCE]])
        single = np.ones(n, dtype=bool)
        single[pending] = False
        single_rows = np.flatnonzero(single)
        exact_r, exact_c = [single_rows], [nearest[single_rows]]
        same_r, same_c = [single_rows], [nearest[single_rows]]
        for step, k in enumerate(_NEIGHBOUR_SCHEDULE):
            if pending.size == 0:
                break
            k_eff = min(k, tree.n)
            nb_idx, nb_sq = _sorted_query(tree, targets, queries, pending, k_eff, self._workers)
            last_step = step == len(_NEIGHBOUR_SCHEDULE) - 1 or k_eff < k
            # pc_error asks again while the k-th neighbour is exactly as close as the first
            again = (nb_sq[:, -1] == nb_sq[:, 0]) if not last_step else np.zeros(len(pending), dtype=bool)
            done = ~again
            rows, nb_idx, nb_sq = pending[done], nb_idx[done], nb_sq[done]
            nearest[rows] = nb_idx[:, 0]
            exact = nb_sq == nb_sq[:, :1]
            close = np.abs(np.diff(nb_sq, axis=1)) < SIMILAR_SQ_DISTANCE
            same = np.concatenate([np.ones((len(rows), 1), dtype=bool), np.logical_and.accumulate(close, axis=1)],
                                  axis=1)
            row_grid = np.broadcast_to(rows[:, None], nb_idx.shape)
            exact_r.append(row_grid[exact])
            exact_c.append(nb_idx[exact])
            same_r.append(row_grid[same])
            same_c.append(nb_idx[same])
            pending = pending[again]
        return np.concatenate(exact_r), np.concatenate(exact_c), np.concatenate(same_r), np.concatenate(same_c)



def query_neighbours(tree: cKDTree, targets: np.ndarray, queries: np.ndarray, order: np.ndarray | None = None,
                     workers: int = -1) -> Neighbours:
    """Nearest neighbours of ``queries`` in ``targets`` (indexed by ``tree``) with pc_error's tie
    sets, without the exact-match shortcut (see `Neighbours`)."""
    return Neighbours(tree, targets, queries, order, workers=workers)


class GridNeighbours(_TiePairs):
    """`Neighbours` of integer-grid clouds, found by `metrics.grid` (numpy, sorted keys) instead of a KD-tree.

    Same attributes and values as `Neighbours` (``sq_dist``, ``index``, ``exact_rows`` ... ``same_cols``):
    on the grid distinct squared distances differ by at least 1, so pc_error's "same-distance" run and
    the exact ties are one set, all the targets at the nearest distance. Three kinds of queries are
    handed to the KD-tree (``kd_neighbours(rows)`` returns a `Neighbours` that answers those rows), so
    that every value stays the KD-tree path's: queries the grid search leaves unsettled (farther than
    ~100 voxels: `grid.nearest`); queries with more than 30 targets at the nearest
    distance (pc_error keeps 30 of them, and which 30 is the KD-tree's choice); and, only when
    ``index`` is read, the queries with 2 to 30 tied nearest targets (which of them is "the" nearest
    is the KD-tree's order too; only the estimated-normal transfer reads it).

    Only the distances (all D1 needs) are computed on construction; the tie pairs on first use.
    """

    def __init__(self, targets: GridCloud, queries: GridCloud, frame: GridFrame, kd_neighbours):
        self._targets, self._queries, self._frame, self._kd_neighbours = targets, queries, frame, kd_neighbours
        miss = np.flatnonzero(~self._matches()[0])  # positions in the queries' key order
        ball = nearest(targets, frame, queries.keys[miss])
        rows = queries.rows[miss]
        settled = ball.sq >= 0
        kd = ~settled | (ball.count > _NEIGHBOUR_SCHEDULE[-1])
        self._kd_rows = np.sort(rows[kd])
        self._kd = None
        sq_rows, sq_values = [rows[settled]], [ball.sq[settled].astype(np.float64)]
        if self._kd_rows.size:
            self._kd = kd_neighbours(self._kd_rows)
            sq_rows.append(self._kd_rows)
            sq_values.append(self._kd.sq_dist[self._kd_rows])
        # only the non-zero distances are kept (the unmatched queries: a few percent); `sq_dist` expands them
        self._sq_rows, self._sq_values = np.concatenate(sq_rows), np.concatenate(sq_values)
        # tie pairs of the settled queries (kept: a few per unmatched query), as query rows and target rows
        keep = ~kd[ball.tie_query]
        self._pair_rows, self._pair_cols = rows[ball.tie_query[keep]], ball.tie_target[keep]
        self._tied_rows = np.sort(rows[settled & ~kd & (ball.count > 1)])

    @property
    def sq_dist(self) -> np.ndarray:
        """(N,) float64 squared distance of each query to its nearest target (made on each read: the
        pair stores only the non-zero ones, so that a frame's D1 holds no N-sized float arrays)."""
        sq = np.zeros(len(self._queries))
        sq[self._sq_rows] = self._sq_values
        return sq

    def _matches(self) -> tuple[np.ndarray, np.ndarray]:
        """(hit (K,) bool, position (K,)) in key order: which queries are a target, and where in the targets."""
        keys = self._targets.keys
        pos = np.searchsorted(keys, self._queries.keys)
        np.minimum(pos, len(keys) - 1, out=pos)
        return keys[pos] == self._queries.keys, pos

    @cached_property
    def index(self) -> np.ndarray:
        """(N,) the nearest target of each query (for tied ones: the KD-tree's first, as `Neighbours`)."""
        hit, pos = self._matches()
        nearest = np.full(len(self._queries), -1, dtype=np.intp)
        nearest[self._queries.rows[hit]] = self._targets.rows[pos[hit]]
        nearest[self._pair_rows] = self._pair_cols  # tied queries: overwritten below
        for rows, nb in ((self._tied_rows, None), (self._kd_rows, self._kd)):
            if rows.size:
                nb = nb if nb is not None else self._kd_neighbours(rows)
                nearest[rows] = nb.index[rows]
        return nearest

    def unmatched_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """(query rows, target rows) of the tie pairs of the queries that are not a target point
        (a few percent of a damaged or inpainted frame); a matched query's only pair is its match."""
        rows, cols = [self._pair_rows], [self._pair_cols]
        if self._kd is not None:  # its rows' pairs; its other rows are placeholders
            mine = np.zeros(len(self._queries), dtype=bool)
            mine[self._kd_rows] = True
            take = mine[self._kd.exact_rows]
            rows.append(self._kd.exact_rows[take])
            cols.append(self._kd.exact_cols[take])
        return np.concatenate(rows).astype(np.intp), np.concatenate(cols).astype(np.intp)

    def matched_rows(self, target_rows: np.ndarray) -> np.ndarray:
        """For target rows (T,), the query row at the same point, -1 where no query is there."""
        keys = self._queries.keys
        wanted = self._targets.keys_by_row[target_rows]
        pos = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
        return np.where(keys[pos] == wanted, self._queries.rows[pos], -1)

    @cached_property
    def _ties(self) -> tuple[np.ndarray, np.ndarray]:
        hit, pos = self._matches()
        pair_rows, pair_cols = self.unmatched_pairs()
        rows = [self._queries.rows[hit], pair_rows]
        cols = [self._targets.rows[pos[hit]], pair_cols]
        del hit, pos
        small = np.int32 if max(len(self._queries), len(self._targets)) < 2**31 else np.intp
        return np.concatenate(rows).astype(small), np.concatenate(cols).astype(small)  # int32: half the memory



def face_neighbour_mask(points: np.ndarray) -> np.ndarray | None:
    """(N,) bool: which points of distinct integer ``points`` have another point at distance exactly
    1 (one of their 6 face neighbours on the grid); None when the grid is too large for int64 keys.

    Distinct integer points are at least 1 apart, so these points' nearest-neighbour distance is 1
    without a tree query. Points get linear keys (x, y, z) -> (x * ny + y) * nz + z on a grid
    padded by one cell; z-neighbours are adjacent in key order, y and x ones are looked up with
    `np.searchsorted`, only for the points not yet settled.
    """
    lo = points.min(axis=0)
    extent = (points.max(axis=0) - lo + 3).astype(np.int64)
    if float(extent[0]) * float(extent[1]) * float(extent[2]) >= 2.0**62:
        return None
    keys = (points[:, 0] - (lo[0] - 1)).astype(np.int64)
    for axis in (1, 2):
        keys *= extent[axis]
        keys += (points[:, axis] - (lo[axis] - 1)).astype(np.int64)
    sorted_keys, order, shift = sort_with_order(keys.view(np.uint64), int(keys.max()).bit_length())
    if shift:  # grid too large to share 64 bits with the indices
        order = np.argsort(keys, kind="stable")  # duplicates in row order on every CPU
    sorted_keys = keys[order]
    has = np.zeros(len(points), dtype=bool)
    adjacent = np.flatnonzero(sorted_keys[1:] - sorted_keys[:-1] == 1)
    has[order[adjacent]] = True
    has[order[adjacent + 1]] = True
    last = len(sorted_keys) - 1
    for step in (extent[2], extent[1] * extent[2]):
        for sign in (1, -1):
            rest = order[~has[order]]  # in key order: sorted lookups are much faster
            if rest.size == 0:
                return has
            wanted = keys[rest] + sign * step
            pos = np.minimum(np.searchsorted(sorted_keys, wanted), last)
            has[rest[sorted_keys[pos] == wanted]] = True
    return has


def _grid_candidate(points: np.ndarray) -> bool:
    """Whether ``points`` can take the integer-grid path: a non-empty numeric (N, 3) array of integer
    values (anything else takes the float path, whose checks give the error messages)."""
    return (points.ndim == 2 and points.shape[1] == 3 and len(points) > 0 and points.dtype.kind in "iuf"
            and is_integer_grid(points))


class CloudPair:
    """A reference frame and a result frame with the neighbour queries every metric shares.

    reference: (N, 3) ground truth; result: (M, 3) cloud to score.
    reference_normals: (N, 3) normals of the reference for D2, or None to estimate them
        (`estimate_normals` with ``normal_neighbours`` neighbours).
    drop_duplicates: merge identical points first, as pc_error does by default.
    workers: threads for the KD-tree queries (scipy's ``workers``; -1 = all cores).

    Attributes after construction: ``reference``, ``result`` (deduplicated float64 arrays),
    ``reference_index`` / ``result_index`` (the kept input rows, or None when nothing was dropped).
    """

    def __init__(
        self,
        reference: ArrayLike,
        result: ArrayLike,
        reference_normals: ArrayLike | None = None,
        *,
        drop_duplicates: bool = True,
        normal_neighbours: int = DEFAULT_NORMAL_NEIGHBOURS,
        workers: int = -1,
    ):
        if not (isinstance(workers, (int, np.integer)) and (workers >= 1 or workers == -1)):
            raise ValueError(f"workers must be a positive number of threads or -1 (all cores), got {workers!r}")
        self.workers = int(workers)
        self.drop_duplicates = bool(drop_duplicates)
        self.normal_neighbours = int(normal_neighbours)
        self._ref_keys = self._res_keys = None
        self.reference_index = self.result_index = None
        self._grid: tuple[GridFrame, GridCloud, GridCloud] | None = None
        ref_in, res_in = np.asarray(reference), np.asarray(result)
        if (GRID_PATH and self.drop_duplicates and _grid_candidate(ref_in) and _grid_candidate(res_in)
                and GridFrame.fits(ref_in, res_in)):
            # integer grid: numpy-only neighbours on packed keys (`metrics.grid`); the pair keeps the keys
            # only (no float64 copies, nor the inputs) and decodes the coordinates if a metric asks for them
            frame = GridFrame(ref_in, res_in)
            self._grid = (frame, GridCloud(ref_in, frame), GridCloud(res_in, frame))
            self.reference_index, self.result_index = self._grid[1].kept, self._grid[2].kept
            self._reference = self._result = None
            shape = ref_in.shape
        else:
            ref = check_points(reference, "reference")
            res = check_points(result, "result")
            if self.drop_duplicates:
                self.reference_index, self._ref_keys = distinct_points(ref)
                self.result_index, self._res_keys = distinct_points(res)
            self._reference = np.ascontiguousarray(ref if self.reference_index is None else ref[self.reference_index])
            self._result = np.ascontiguousarray(res if self.result_index is None else res[self.result_index])
            shape = ref.shape
        normals = None
        if reference_normals is not None:
            normals = np.asarray(reference_normals)
            if normals.dtype.kind != "f":
                normals = normals.astype(np.float64)
            if normals.shape != shape:
                raise ValueError(
                    f"reference normals must have the shape of the reference points {shape}, got {normals.shape}"
                )
            # float32 normals (as PLY files store them) are kept as float32: every use promotes them to
            # float64 exactly, so the values are those of a float64 copy, at half the memory
            normals = normals if self.reference_index is None else normals[self.reference_index]
        self._given_normals = normals
        self._planes: dict[bool, Any] = {}  # plane errors by direction: (rows or None for all, values)

    @property
    def _grid_parts(self) -> tuple[GridFrame, GridCloud, GridCloud]:
        """(frame, reference, result) of the grid path; only read on that path."""
        if self._grid is None:
            raise RuntimeError("not on the integer-grid path")
        return self._grid

    @property
    def reference(self) -> np.ndarray:
        """(N, 3) float64, the deduplicated reference (on the grid path: made on first use)."""
        if self._reference is None:
            self._reference = self._grid_parts[1].points(self._grid_parts[0])
        return self._reference

    @property
    def result(self) -> np.ndarray:
        """(M, 3) float64, the deduplicated result (on the grid path: made on first use)."""
        if self._result is None:
            self._result = self._grid_parts[2].points(self._grid_parts[0])
        return self._result

    # -- trees and queries ------------------------------------------------------------------
    @cached_property
    def reference_tree(self) -> cKDTree:
        return build_tree(self.reference)

    @cached_property
    def result_tree(self) -> cKDTree:
        return build_tree(self.result)

    @cached_property
    def reference_on_grid(self) -> bool:
        return self._grid is not None or on_integer_grid(self.reference)

    @cached_property
    def result_on_grid(self) -> bool:
        return self._grid is not None or on_integer_grid(self.result)

    def _kd_neighbours(self, direction: str):
        """For `GridNeighbours`: rows -> the KD-tree `Neighbours` of those query rows only."""
        def build(rows: np.ndarray) -> Neighbours:
            if direction == "ref_to_res":
                tree, targets, queries = self.result_tree, self.result, self.reference
            else:
                tree, targets, queries = self.reference_tree, self.reference, self.result
            others = np.ones(len(queries), dtype=bool)
            others[rows] = False  # marked "matched" so that only ``rows`` are queried; their values are ignored
            return Neighbours(tree, targets, queries, matched=others, matched_index=np.zeros(len(queries), np.intp),
                              separated_targets=True, workers=self.workers)
        return build

    def _matches(self, queries, query_keys, targets, target_keys):
        """Exact matches of the queries in the (deduplicated) targets, or (None, None) without deduplication:
        duplicated targets would tie at distance 0."""
        if not self.drop_duplicates:
            return None, None
        return target_keys.exact_matches(query_keys, queries, targets)

    @cached_property
    def ref_to_res(self) -> Neighbours | GridNeighbours:
        """For each reference point, its nearest result point(s)."""
        if self._grid is not None:
            frame, ref, res = self._grid
            return GridNeighbours(res, ref, frame, self._kd_neighbours("ref_to_res"))
        hit, index = self._matches(self.reference, self._ref_keys, self.result, self._res_keys)
        nb = Neighbours(self.result_tree, self.result, self.reference, self.reference_tree.indices,
                        matched=hit, matched_index=index, separated_targets=self.result_on_grid, workers=self.workers)
        self._release_keys("res_to_ref")
        return nb

    @cached_property
    def res_to_ref(self) -> Neighbours | GridNeighbours:
        """For each result point, its nearest reference point(s)."""
        if self._grid is not None:
            frame, ref, res = self._grid
            return GridNeighbours(ref, res, frame, self._kd_neighbours("res_to_ref"))
        hit, index = self._matches(self.result, self._res_keys, self.reference, self._ref_keys)
        nb = Neighbours(self.reference_tree, self.reference, self.result, self.result_tree.indices,
                        matched=hit, matched_index=index, separated_targets=self.reference_on_grid,
                        workers=self.workers)
        self._release_keys("ref_to_res")
        return nb

    def _release_keys(self, other_direction: str) -> None:
        """Free the sorted keys (4 arrays of N) once both directions have used them."""
        if other_direction in self.__dict__:
            self._ref_keys = self._res_keys = None

    @cached_property
    def reference_spacing(self) -> np.ndarray:
        """(N,) distance of each reference point to its nearest other reference point (inf if alone).

        On distinct integer points, those with a face neighbour (`face_neighbour_mask`) are at 1
        exactly and skip the tree query.
        """
        if self._grid is not None:
            return self._grid_spacing(full=True)
        n = len(self.reference)
        if n < 2:
            return np.full(n, np.inf)
        spacing = np.empty(n)
        order = self.reference_tree.indices
        settled = None
        if self.drop_duplicates and self.reference_on_grid:
            settled = face_neighbour_mask(self.reference)
        if settled is not None:
            spacing[settled] = 1.0
            order = order[~settled[order]]
        _, sq = _sorted_query(self.reference_tree, self.reference, self.reference, order, 2, self.workers)
        spacing[order] = np.sqrt(sq[:, 1])
        return spacing

    def _grid_spacing(self, full: bool) -> np.ndarray:
        """Nearest-other-point distances on the grid path: (N,) with ``full``, else those of the points
        without a face neighbour plus one 1.0 when some point has one (enough for the maximum)."""
        frame, ref, _ = self._grid_parts
        n = len(ref)
        if n < 2:
            return np.full(n, np.inf)
        face = face_neighbours(ref, frame)  # in key order; distance exactly 1
        rest = np.flatnonzero(~face)
        ball = nearest(ref, frame, ref.keys[rest], ties=False)
        rows = ref.rows[rest]
        found = ball.sq >= 0
        far = rows[~found]
        spacing = np.ones(n) if full else np.ones(len(rows) + 1)
        at = rows if full else np.arange(len(rows))
        spacing[at[found]] = np.sqrt(ball.sq[found].astype(np.float64))
        if far.size:  # beyond the ball search: the KD-tree, as the other path
            by_row = np.sort(far)
            _, sq = _sorted_query(self.reference_tree, self.reference, self.reference, by_row, 2, self.workers)
            spacing[at[~found]] = np.sqrt(sq[np.searchsorted(by_row, far), 1])
        if not full and not face.any():
            spacing = spacing[:-1]
        return spacing

    @cached_property
    def intrinsic_resolution(self) -> float:
        """pc_error's default peak: the largest nearest-neighbour distance inside the reference.

        Points whose neighbour lies closer than 1e-5 (squared 1e-10) are ignored, as in pc_error.
        """
        if self._grid is not None and "reference_spacing" not in self.__dict__:
            spacing = self._grid_spacing(full=False)  # the points without a face neighbour (the max is 1 or theirs)
        else:
            spacing = self.reference_spacing
        valid = spacing[spacing * spacing > _INTRINSIC_MIN_SQ]
        valid = valid[np.isfinite(valid)]
        if valid.size == 0:
            raise UserError(
                "the intrinsic-resolution peak needs at least two distinct reference points; "
                "pass a numeric peak (e.g. peak=1023) instead"
            )
        return float(valid.max())

    # -- normals and per-point errors --------------------------------------------------------
    @cached_property
    def reference_normals(self) -> np.ndarray:
        """(N, 3) the given reference normals, or estimated ones (`estimate_normals`)."""
        if self._given_normals is not None:
            return self._given_normals
        return estimate_normals(self.reference, self.normal_neighbours)

    @property
    def normals_estimated(self) -> bool:
        return self._given_normals is None

    @cached_property
    def result_normals(self) -> np.ndarray:
        """(M, 3) reference normals carried onto the result, as pc_error's ``scaleNormals``.

        Each reference point adds its normal to every result point at exactly its nearest distance;
        a result point receiving normals takes their mean. A result point receiving none takes the
        mean normal of the reference points at exactly its own nearest distance. Means are not
        renormalized (pc_error does not either).

        The sign of a normal does not change a squared point-to-plane error, but it does change a
        mean of normals: normals of mixed signs cancel. Given normals are used exactly as given (that
        is what pc_error does; on the golden hole case, whose normals are unoriented, this shrinks
        D2 to 0.053 from 0.128 with aligned signs). Estimated normals have arbitrary signs, so each
        one is first flipped to agree with the normal of the result point's nearest reference
        point, which makes D2 independent of their orientation.
        """
        n_res = self._size("result")
        ref_normals = self.reference_normals
        fwd, back = self.ref_to_res, self.res_to_ref

        def contributions(rows_res, cols_ref):
            normals = ref_normals[cols_ref]
            if self.normals_estimated:
                anchor = ref_normals[back.index[rows_res]]
                flip = np.einsum("ij,ij->i", normals, anchor) < 0
                normals = np.where(flip[:, None], -normals, normals)
            sums = np.stack([np.bincount(rows_res, weights=normals[:, c], minlength=n_res) for c in range(3)], axis=1)
            return sums, np.bincount(rows_res, minlength=n_res)

        if not self.normals_estimated:
            return self._carried_normals(ref_normals, fwd, back, n_res)
        sums, counts = contributions(fwd.exact_cols, fwd.exact_rows)
        normals = np.zeros((n_res, 3))
        got = counts > 0
        normals[got] = sums[got] / counts[got, None]
        if not got.all():
            sel = ~got[back.exact_rows]
            sums, counts = contributions(back.exact_rows[sel], back.exact_cols[sel])
            miss = ~got
            normals[miss] = sums[miss] / counts[miss, None]
        return normals

    @staticmethod
    def _carried_normals(ref_normals, fwd, back, n_res: int) -> np.ndarray:
        """`result_normals` for given normals, one coordinate at a time (no (T, 3) or second (M, 3)
        temporaries; the same sums and quotients, so the same bits)."""
        normals = np.zeros((n_res, 3))
        counts = np.bincount(fwd.exact_cols, minlength=n_res)
        got = counts > 0
        for c in range(3):
            sums = np.bincount(fwd.exact_cols, weights=ref_normals[:, c][fwd.exact_rows], minlength=n_res)
            np.divide(sums, counts, out=normals[:, c], where=got)  # the quotients of sums[got] / counts[got]
        if not got.all():
            sel = ~got[back.exact_rows]
            rows_res, cols_ref = back.exact_rows[sel], back.exact_cols[sel]
            counts = np.bincount(rows_res, minlength=n_res)
            miss = ~got
            for c in range(3):
                sums = np.bincount(rows_res, weights=ref_normals[:, c][cols_ref], minlength=n_res)
                np.divide(sums, counts, out=normals[:, c], where=miss)
        return normals

    def _size(self, side: str) -> int:
        """Points in the deduplicated reference or result (``side``), without making its coordinates."""
        if self._grid is not None:
            return len(self._grid[1] if side == "reference" else self._grid[2])
        return len(self.reference if side == "reference" else self.result)

    def _coordinates(self, side: str, rows: np.ndarray) -> np.ndarray:
        """(len(rows), 3) float64 coordinates of ``rows`` of the deduplicated reference or result
        (``side``); on the grid path decoded from the keys (exact) unless the full array exists."""
        full = self._reference if side == "reference" else self._result
        if full is not None:
            return full[rows]
        frame, ref, res = self._grid_parts
        return frame.decode((ref if side == "reference" else res).keys_by_row[rows])

    def _plane_errors(self, query_side: str, target_side: str, target_normals, rows, cols, n_queries,
                      normal_rows: np.ndarray | None = None) -> Any:
        """Mean over each query's same-distance targets of ((q - t) . n_t)^2, shape (n_queries,).

        A target whose normal has a NaN component contributes the squared point-to-point distance
        instead (pc_error's non-averaging branch does this; its averaging branch adds the signed sum
        of the coordinate differences, which we take for a bug and do not reproduce).

        Pairs are taken in blocks of `_CHUNK` (bounded temporaries); bincount adds each block's
        per-query sums in pair order, so the totals are those of one pass. ``normal_rows`` (grid path):
        the row of each pair's normal in ``target_normals``; the pairs then cover only some queries
        (the others, equal to their target, get 0) and are summed per query present, without
        N-sized temporaries; returns (rows present, their errors) then.
        """
        if normal_rows is not None:  # sparse rows (grid path): (rows present, their errors)
            present, rows = np.unique(rows, return_inverse=True)
            return present, self._plane_sums(query_side, target_side, target_normals, rows, cols, len(present),
                                             normal_rows, present)
        return self._plane_sums(query_side, target_side, target_normals, rows, cols, n_queries, None, None)

    def _plane_sums(self, query_side, target_side, target_normals, rows, cols, n, normal_rows, row_ids):
        """Mean error per row 0..n-1 of ``rows`` (see `_plane_errors`); ``row_ids`` maps them to query rows."""
        total = np.zeros(n)
        for start in range(0, len(rows), _CHUNK):
            r, c = rows[start:start + _CHUNK], cols[start:start + _CHUNK]
            diff = self._coordinates(query_side, r if row_ids is None else row_ids[r])
            diff -= self._coordinates(target_side, c)
            normal = target_normals[c if normal_rows is None else normal_rows[start:start + _CHUNK]]
            proj = diff[:, 0] * normal[:, 0] + diff[:, 1] * normal[:, 1] + diff[:, 2] * normal[:, 2]
            err = proj * proj
            bad = np.isnan(err)
            if bad.any():
                d = diff[bad]
                err[bad] = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]
            total += np.bincount(r, weights=err, minlength=n)
        return total / np.bincount(rows, minlength=n)

    def _grid_plane_errors(self, forward: bool) -> np.ndarray:
        """`plane_ref_to_res` (``forward``) or `plane_res_to_ref` on the grid path with given normals.

        A query equal to a target point has that point as its only tie (distinct grid points are >= 1
        apart) and error ((q - t) . n)^2 = 0 (or the squared distance 0 for a NaN normal), so only the
        pairs of the unmatched queries are evaluated, and the carried normals only at their targets:
        no (N,)-sized pair arrays, no (M, 3) normals. The target's carried normal is the mean of the
        normals of the reference points that have it among their nearest: the reference point at the
        same position (if any) and the unmatched ones whose ties include it (it has at least one, so
        `result_normals`' second branch never applies there).
        """
        nb = self.ref_to_res if forward else self.res_to_ref
        assert isinstance(nb, GridNeighbours)  # the grid path's neighbours
        rows, cols = nb.unmatched_pairs()
        n = self._size("reference" if forward else "result")
        ref_normals = self.reference_normals
        if forward:
            at, local = np.unique(cols, return_inverse=True)
            same = nb.matched_rows(at)  # the reference point at each target, or -1
            has = same >= 0
            contrib_local = np.concatenate([np.flatnonzero(has), local])
            contrib_ref = np.concatenate([same[has], rows])
            counts = np.bincount(contrib_local, minlength=len(at))
            normals = np.empty((len(at), 3))
            for c in range(3):
                sums = np.bincount(contrib_local, weights=ref_normals[:, c][contrib_ref], minlength=len(at))
                normals[:, c] = sums / counts
            sparse = self._plane_errors("reference", "result", normals, rows, cols, n, normal_rows=local)
        else:
            sparse = self._plane_errors("result", "reference", ref_normals, rows, cols, n, normal_rows=cols)
        frame, ref, res = self._grid_parts
        ref.release_rows()  # the row -> key maps of the decoding: 4 bytes a point each, not kept
        res.release_rows()
        return sparse

    @property
    def plane_ref_to_res(self) -> np.ndarray:
        """(N,) point-to-plane error of each reference point against the result (result normals).

        Computed once; on the grid path with given normals only the non-zero errors are kept, and the
        (N,) array is made on each read (as `GridNeighbours.sq_dist`)."""
        return self._plane(forward=True)

    @property
    def plane_res_to_ref(self) -> np.ndarray:
        """(M,) point-to-plane error of each result point against the reference (reference normals)."""
        return self._plane(forward=False)

    def _plane(self, forward: bool) -> np.ndarray:
        n = self._size("reference" if forward else "result")
        if forward not in self._planes:
            grid = self._grid is not None and not self.normals_estimated
            if forward and grid and "result_normals" not in self.__dict__:
                self._planes[forward] = self._grid_plane_errors(forward=True)
            elif not forward and grid:
                self._planes[forward] = self._grid_plane_errors(forward=False)
            elif forward:
                nb = self.ref_to_res
                self._planes[forward] = (None, self._plane_errors("reference", "result", self.result_normals,
                                                                  nb.same_rows, nb.same_cols, n))
            else:
                nb = self.res_to_ref
                self._planes[forward] = (None, self._plane_errors("result", "reference", self.reference_normals,
                                                                  nb.same_rows, nb.same_cols, n))
        present, values = self._planes[forward]
        if present is None:
            return values
        out = np.zeros(n)
        out[present] = values
        return out

    # -- region masks -------------------------------------------------------------------------
    def masks(self, regions: Sequence[Region], margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Boolean masks (N,), (M,) of the reference and result points inside any of ``regions``.

        ``regions`` is a list of objects with ``contains(points, margin) -> (K,) bool`` (e.g.
        `holes.regions.HoleRegion`).
        """
        ref_mask = np.zeros(len(self.reference), dtype=bool)
        res_mask = np.zeros(len(self.result), dtype=bool)
        for region in regions:
            ref_mask |= np.asarray(region.contains(self.reference, margin), dtype=bool)
            res_mask |= np.asarray(region.contains(self.result, margin), dtype=bool)
        return ref_mask, res_mask
