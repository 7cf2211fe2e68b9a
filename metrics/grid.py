"""Exact nearest neighbours of integer-grid (voxelized) clouds with numpy only: no KD-tree.

Voxelized frames (8i, MPEG: every coordinate an integer) are what pc_error is mostly run on. On such
data a nearest-neighbour query is a lookup in a sorted array of packed coordinates, which needs
neither scipy (importing scipy.spatial alone costs ~40 MiB and 0.4 s, more than pc_error's whole
footprint) nor float64 copies of the clouds. `metrics.pairs.CloudPair` uses this module when both
clouds are on the integer grid and duplicates are merged; results are those of the KD-tree path
(`tests/test_metrics_grid.py` checks them against it and against brute force).

Keys. A `GridFrame` covers both clouds' bounding box padded by `MAX_COMPONENT` cells on every side;
a point (x, y, z) of the frame has the key ((x - x0) * ny + (y - y0)) * nz + (z - z0) (int64). A grid
offset o = (ox, oy, oz) with |o_i| <= `MAX_COMPONENT` adds the fixed amount (ox * ny + oy) * nz + oz
to the key of any point of the frame, without wrapping into another row (the padding), so the
neighbour of a point at offset o exists iff key + key(o) is in the sorted keys of the targets.

Search (`ball_search`). The offsets with 0 < |o|^2 <= `MAX_SQ_RADIUS` are taken in groups of equal
squared norm n = 1, 2, 3, 4, 5, 6, 8, 9, ... (ascending). A query is settled by the first group in
which any of its offsets hits a target: every closer offset has been looked up before, so n is its
exact nearest squared distance, and the hits of that group are all of its targets at exactly that
distance (its tie set; distinct grid points are >= 1 apart, so pc_error's 1e-8 "same distance" run
is the same set). Queries are looked up in key order (numpy's binary search is several times faster
on sorted queries). The cost grows with the cube of the distance (~4.2 n^1.5 lookups for a query at
squared distance n): a search stops when its lookups exceed `LOOKUP_BUDGET` (~1.5 s), or would if
the queries still pending were found before 1.5 x the present radius, or at `MAX_SQ_RADIUS`; the
queries left go to `coarse_search` (4-voxel cells visited by increasing distance bound: exact, and
~(r / 4)^3 lookups plus the targets of the nearby occupied cells), and those beyond its reach (~96
voxels) to the caller's KD-tree (`nearest` chains the two searches). Measured: an occlusion-damaged
Longdress frame (14,674 unmatched points, none farther than 16) needs 1.25e7 voxel lookups and stays
in the ball search; a region-damaged human frame (12,381 unmatched, up to 27 away: 1.07e8 lookups)
leaves 7,878 queries to the coarse search.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

#: largest squared distance the ball search looks at (32 voxels); farther queries go to `coarse_search`
MAX_SQ_RADIUS = 32 * 32
#: largest offset component, hence the padding of a `GridFrame` (no key wraps within it)
MAX_COMPONENT = 32
#: lookups one `ball_search` may spend (~0.05 s per million on sorted queries) before leaving the
#: queries still unsettled to the caller: bounds the time on clouds with deep holes (module docstring)
LOOKUP_BUDGET = 30_000_000
#: queries x offsets looked up per `np.searchsorted` call: bounds the temporaries (~3 x 4 MB)
_BLOCK = 1 << 19
#: grid points in a ball of radius r: ~(4/3) pi r^3
_BALL = 4.19
#: rows per block when packing keys
_ROWS = 1 << 16
#: coordinates must fit int32 (|x| < 2**31) for the compact paths
_INT32 = 2**31 - 1 - MAX_COMPONENT


def is_integer_grid(points: np.ndarray, block: int = 1 << 18) -> bool:
    """True when every coordinate of ``points`` (N, 3), any numeric dtype, is an integer of absolute
    value below ~2**31. Checked in blocks of rows, so a float64 input costs no (N, 3) temporaries."""
    if len(points) == 0:
        return True
    if points.dtype.kind in "iu":
        return bool(points.max() <= _INT32 and points.min() >= -_INT32)
    if points.dtype.kind != "f":
        return False
    for start in range(0, len(points), block):
        part = points[start:start + block]
        if not (np.equal(np.floor(part), part).all() and np.abs(part).max(initial=0) <= _INT32):
            return False
    return True


class GridFrame:
    """The key space shared by the clouds of a pair (see the module docstring).

    origin (3,) int64: the smallest coordinates minus the padding; dims (3,) int64: cells per axis.
    """

    def __init__(self, *clouds: np.ndarray):
        lo = np.min([np.asarray(c.min(axis=0), dtype=np.int64) for c in clouds], axis=0)
        hi = np.max([np.asarray(c.max(axis=0), dtype=np.int64) for c in clouds], axis=0)
        self.origin = lo - MAX_COMPONENT
        self.dims = hi - lo + 1 + 2 * MAX_COMPONENT
        self.cells = int(np.prod(self.dims.astype(float)))
        #: int32 keys when the padded box has fewer than 2**31 cells (any 10-bit frame: 1088**3 < 2**31):
        #: half the memory, and every key + offset stays in range (the padding), so sums never overflow
        self.dtype = np.dtype(np.int32) if self.cells < 2**31 else np.dtype(np.int64)

    @staticmethod
    def fits(*clouds: np.ndarray) -> bool:
        """Whether the keys of these clouds fit int64 (a grid of fewer than 2**62 cells)."""
        lo = np.min([c.min(axis=0) for c in clouds], axis=0).astype(float)
        hi = np.max([c.max(axis=0) for c in clouds], axis=0).astype(float)
        return float(np.prod(hi - lo + 1 + 2 * MAX_COMPONENT)) < 2.0**62

    def keys(self, points: np.ndarray, block: int = 1 << 18) -> np.ndarray:
        """(N,) int64 keys of integer-valued ``points`` (N, 3), computed in blocks (no (N, 3) copies);
        `GridCloud` stores them as ``dtype``."""
        out = np.empty(len(points), dtype=np.int64)
        for start in range(0, len(points), block):
            part = points[start:start + block]
            key = out[start:start + len(part)]
            key[:] = part[:, 0]
            key -= self.origin[0]
            for axis in (1, 2):
                key *= self.dims[axis]
                key += part[:, axis].astype(np.int64)
                key -= self.origin[axis]
        return out

    def offset_keys(self, offsets: np.ndarray) -> np.ndarray:
        """(G,) key increments (``dtype``) of grid offsets (G, 3)."""
        o = offsets.astype(np.int64)
        return ((o[:, 0] * self.dims[1] + o[:, 1]) * self.dims[2] + o[:, 2]).astype(self.dtype)

    def decode(self, keys: np.ndarray) -> np.ndarray:
        """(N, 3) float64 coordinates of keys (the inverse of `keys`)."""
        out = np.empty((len(keys), 3))
        rest = keys.astype(np.int64)
        for axis in (2, 1):
            rest, out[:, axis] = np.divmod(rest, self.dims[axis])
            out[:, axis] += self.origin[axis]
        out[:, 0] = rest + self.origin[0]
        return out


class GridCloud:
    """The distinct points of one integer cloud as sorted keys.

    keys: (K,) sorted, distinct (`GridFrame.dtype`); rows: (K,) int32 (intp beyond 2**31 points), the
    row of each key in the deduplicated cloud; kept: (K,) the input rows of the first occurrences, in
    input order (pc_error's ``--dropdups=2``:
    the first occurrence is kept), or None when no point is repeated.
    """

    def __init__(self, points: np.ndarray, frame: GridFrame):
        n = len(points)
        self._by_row: np.ndarray | None = None
        bits = max(1, int(n - 1).bit_length())
        key_bits = int(frame.cells - 1).bit_length()
        keys: np.ndarray = frame.keys(points)
        if key_bits + bits <= 63:
            # key and row packed into one int64 and sorted with np.sort (a SIMD sort, ~5x faster than
            # argsort); equal keys come out in row order, so the first of a run is the first occurrence.
            # Packed and unpacked in blocks: no full-size temporaries beside the one int64 array.
            keys <<= bits
            for start in range(0, n, _ROWS):
                keys[start:start + _ROWS] |= np.arange(start, min(n, start + _ROWS), dtype=np.int64)
            keys.sort()
            order: np.ndarray = np.empty(n, dtype=np.int32 if n < 2**31 else np.intp)
            for start in range(0, n, _ROWS):
                order[start:start + _ROWS] = keys[start:start + _ROWS] & ((1 << bits) - 1)
            keys >>= bits
            if frame.dtype == np.int32:
                # narrow in place: int32 key i goes to bytes [4i, 4i + 4), which only hold int64 keys < i,
                # already read when going forwards in blocks; then the buffer is shrunk to its first half
                # (a realloc), so no second key array is ever allocated beside the int64 one
                narrow = keys.view(np.int32)
                for start in range(0, n, _ROWS):
                    block = keys[start:start + _ROWS].astype(np.int32)
                    narrow[start:start + len(block)] = block
                del narrow, block
                keys.resize((n + 1) // 2, refcheck=False)
                keys = keys.view(np.int32)[:n]
        else:
            order = np.argsort(keys, kind="stable")
            keys = keys[order]
        keys = keys.astype(frame.dtype, copy=False)
        first = np.empty(n, dtype=bool)
        first[0] = True
        np.not_equal(keys[1:], keys[:-1], out=first[1:])
        if first.all():
            self.kept = None
            self.keys, self.rows = keys, order
            return
        self.keys = keys[first]
        starts = order[first]  # input row of each distinct key (its first occurrence)
        del keys, order, first
        # the kept rows in input order, and each distinct key's row among them (a rank), with masks and
        # an int32 running count rather than a sort and a search: fewer and narrower temporaries
        kept = np.zeros(n, dtype=bool)
        kept[starts] = True
        rank = np.cumsum(kept, dtype=starts.dtype)
        rank -= 1
        self.rows = rank[starts]
        del rank, starts
        self.kept = np.flatnonzero(kept).astype(self.rows.dtype)

    def __len__(self) -> int:
        return len(self.keys)

    @property
    def keys_by_row(self) -> np.ndarray:
        """(K,) the keys in row order (made on first use, kept: the coordinates of any rows decode from it)."""
        if self._by_row is None:
            self._by_row = np.empty_like(self.keys)
            self._by_row[self.rows] = self.keys
        return self._by_row

    def release_rows(self) -> None:
        """Forget `keys_by_row` (made again on the next use)."""
        self._by_row = None

    def points(self, frame: GridFrame) -> np.ndarray:
        """(K, 3) float64 coordinates of the distinct points in row order (decoded from the keys: exact)."""
        out = np.empty((len(self.keys), 3))
        out[self.rows] = frame.decode(self.keys)
        return out


@lru_cache(maxsize=4)
def _ball_groups(max_sq: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(offsets (G, 3) sorted by squared norm, their squared norms (G,), start of each norm group (U + 1,))
    for 0 < |o|^2 <= max_sq."""
    r = int(np.floor(np.sqrt(max_sq)))
    axis = np.arange(-r, r + 1, dtype=np.int16)  # small types: the cube has (2r + 1)^3 = 275k cells at r = 32
    o = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    norm = (o.astype(np.int32) ** 2).sum(axis=1, dtype=np.int32)
    keep = (norm > 0) & (norm <= max_sq)
    o, norm = o[keep].astype(np.int8 if r < 128 else np.int16), norm[keep]
    order = np.argsort(norm, kind="stable")
    o, norm = o[order], norm[order]
    starts = np.flatnonzero(np.r_[True, norm[1:] != norm[:-1], True])
    return o, norm, starts


class BallResult:
    """What `ball_search` found for P queries.

    sq: (P,) int64 nearest squared distance, -1 where unsettled; count: (P,) number of targets at that
    distance (0 where unsettled); tie_query (T,), tie_target (T,): every (query, target row) pair at
    the nearest distance, grouped by norm group, not sorted.
    """

    def __init__(self, sq, count, tie_query, tie_target):
        self.sq, self.count, self.tie_query, self.tie_target = sq, count, tie_query, tie_target


def ball_search(targets: GridCloud, frame: GridFrame, query_keys: np.ndarray, *, ties: bool = True,
                max_sq: int = MAX_SQ_RADIUS, budget: int | None = None) -> BallResult:
    """Nearest targets of the grid points with keys ``query_keys`` (P,) (sorted for speed), other than
    a target at the query itself (offset 0 is not looked up): see the module docstring.

    ties: also return the tie pairs (else ``tie_query``/``tie_target`` are empty).
    budget: lookups allowed (None: `LOOKUP_BUDGET`, read at call time).
    """
    budget = LOOKUP_BUDGET if budget is None else budget
    p = len(query_keys)
    sq = np.full(p, -1, dtype=np.int64)
    count = np.zeros(p, dtype=np.int64)
    tie_q: list[np.ndarray] = []
    tie_t: list[np.ndarray] = []
    offsets, norms, starts = _ball_groups(max_sq)
    offset_keys = frame.offset_keys(offsets)
    pending = np.arange(p)
    keys, last = targets.keys, len(targets.keys) - 1
    spent = 0
    if last < 0:
        return BallResult(sq, count, np.empty(0, np.intp), np.empty(0, np.intp))
    for g in range(len(starts) - 1):
        if pending.size == 0:
            break
        group = offset_keys[starts[g]:starts[g + 1]]
        spent += pending.size * group.size
        # stop when the pending queries, if found before twice the present radius, would still
        # overrun the budget: deep holes (region damage) go to the KD-tree early instead of wasting
        # the budget first; the few far queries of an occlusion-damaged frame stay here
        radius = float(np.sqrt(norms[starts[g]]))
        if spent > budget or spent + pending.size * _BALL * (1.5 * radius) ** 3 > budget:
            break
        pkeys = query_keys[pending]
        step = max(1, _BLOCK // group.size)
        found_rows, found_t = [], []
        for lo in range(0, pending.size, step):
            block = pkeys[lo:lo + step]
            wanted = group[:, None] + block[None, :]  # offset-major: each row sorted, lookups stay sorted
            pos = np.searchsorted(keys, wanted)
            np.minimum(pos, last, out=pos)
            hit = keys[pos] == wanted
            if not hit.any():
                continue
            col = np.nonzero(hit)[1]
            found_rows.append(col + lo)
            if ties:
                found_t.append(targets.rows[pos[hit]])
        if not found_rows:
            continue
        cols = np.concatenate(found_rows)
        queries = pending[cols]
        n_hits = np.bincount(cols, minlength=pending.size)
        settled = n_hits > 0
        sq[pending[settled]] = norms[starts[g]]
        count[pending[settled]] = n_hits[settled]
        if ties:
            tie_q.append(queries)
            tie_t.append(np.concatenate(found_t))
        pending = pending[~settled]
    empty = np.empty(0, dtype=np.intp)
    return BallResult(sq, count, np.concatenate(tie_q) if tie_q else empty,
                      np.concatenate(tie_t) if tie_t else empty)


def face_neighbours(cloud: GridCloud, frame: GridFrame) -> np.ndarray:
    """(K,) bool, in sorted-key order: which points of ``cloud`` have a point at distance exactly 1.

    z-neighbours are adjacent in key order; the others are looked up only for the points not yet
    settled (most surface points have a z-neighbour)."""
    keys = cloud.keys
    has = np.zeros(len(keys), dtype=bool)
    adjacent = np.diff(keys) == 1  # masks, not index arrays: no intp array of every surface point
    has[:-1] |= adjacent
    has[1:] |= adjacent
    del adjacent
    last = len(keys) - 1
    for step in (int(frame.dims[2]), int(frame.dims[1] * frame.dims[2])):
        for sign in (1, -1):
            rest = np.flatnonzero(~has)
            if rest.size == 0:
                return has
            wanted = keys[rest] + sign * step
            pos = np.minimum(np.searchsorted(keys, wanted), last)
            has[rest[keys[pos] == wanted]] = True
    return has


#: cell size of `coarse_search` (voxels) and its reach in cells (beyond: unsettled, the KD-tree's)
_CELL = 4
_CELL_REACH = 24
#: (query, candidate) pairs evaluated per block in `coarse_search`
_PAIRS = 1 << 20


@lru_cache(maxsize=2)
def _cell_groups(reach: int, cell: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cell offsets (G, 3), the least squared distance between a point of a cell and a point of the
    cell at that offset (G,), start of each group of equal bound (U + 1,)), by increasing bound.

    Per axis the points of cells o_i apart are at least (|o_i| - 1) * cell + 1 apart (0 when o_i = 0)."""
    axis = np.arange(-reach, reach + 1, dtype=np.int64)
    o = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    gap = np.where(o == 0, 0, (np.abs(o) - 1) * cell + 1)
    bound = (gap * gap).sum(axis=1)
    order = np.argsort(bound, kind="stable")
    o, bound = o[order].astype(np.int8 if reach < 128 else np.int16), bound[order]
    starts = np.flatnonzero(np.r_[True, bound[1:] != bound[:-1], True])
    return o, bound, starts


def _relative(frame: GridFrame, keys: np.ndarray) -> np.ndarray:
    """(n, 3) int64 coordinates relative to the frame's origin of keys."""
    out = np.empty((len(keys), 3), dtype=np.int64)
    rest = keys.astype(np.int64)
    for axis in (2, 1):
        rest, out[:, axis] = np.divmod(rest, frame.dims[axis])
    out[:, 0] = rest
    return out


def coarse_search(targets: GridCloud, frame: GridFrame, query_keys: np.ndarray) -> BallResult:
    """Nearest targets (exact squared distance, every tie) of far queries, by cells of `_CELL` voxels.

    For the queries `ball_search` leaves (deep holes): the targets are bucketed by cell, and the cells
    around a query are visited by increasing lower bound of their distance (`_cell_groups`); a query is
    settled when the best squared distance found is below the bound of every cell not yet visited, so
    the distance and its ties are exact. Cost per query: ~(r / cell)^3 cell lookups plus the targets of
    the occupied cells within ~r + 2 cells, instead of ~4 r^3 voxel lookups. Queries farther than
    `_CELL_REACH` cells come back unsettled (sq -1). A target at distance 0 (the query itself, for a
    search of a cloud in itself) is not a neighbour.
    """
    p = len(query_keys)
    sq = np.full(p, -1, dtype=np.int64)
    count = np.zeros(p, dtype=np.int64)
    empty = np.empty(0, dtype=np.intp)
    if p == 0 or len(targets) == 0:
        return BallResult(sq, count, empty, empty)
    reach = _CELL_REACH
    cdims = -(-frame.dims // _CELL) + 2 * reach  # cells per axis, padded by the reach (no wrapping)

    def cell_keys(rel: np.ndarray) -> np.ndarray:
        c = rel // _CELL + reach
        return (c[:, 0] * cdims[1] + c[:, 1]) * cdims[2] + c[:, 2]

    # targets bucketed by cell: positions into targets.keys sorted by cell key, and each cell's span
    tcell = np.empty(len(targets), dtype=np.int64)
    for start in range(0, len(targets), _ROWS):
        tcell[start:start + _ROWS] = cell_keys(_relative(frame, targets.keys[start:start + _ROWS]))
    by_cell = np.argsort(tcell, kind="stable")
    tcell = tcell[by_cell]
    cells, first = np.unique(tcell, return_index=True)
    del tcell
    ends = np.r_[first[1:], len(by_cell)]

    qrel = _relative(frame, query_keys)
    qcell = cell_keys(qrel)
    offsets, bounds, starts = _cell_groups(reach, _CELL)
    # the nearest cells beyond the reach are at least `beyond` away: only the groups below it are
    # visited (the cube's corners are farther than the cells outside its faces)
    beyond = (reach * _CELL + 1) ** 2
    groups = int(np.searchsorted(bounds[starts[:-1]], beyond))
    okeys = (offsets[:, 0].astype(np.int64) * cdims[1] + offsets[:, 1]) * cdims[2] + offsets[:, 2]
    best = np.full(p, np.iinfo(np.int64).max, dtype=np.int64)
    pair_q, pair_t, pair_d = [], [], []
    pending = np.arange(p)
    for g in range(groups):
        if pending.size == 0:
            break
        lo, hi = starts[g], starts[g + 1]
        # settled: nothing in this or any later group can be as close as the best found
        done = best[pending] < bounds[lo]
        pending = pending[~done]
        if pending.size == 0:
            break
        wanted = qcell[pending][None, :] + okeys[lo:hi, None]
        pos = np.minimum(np.searchsorted(cells, wanted), len(cells) - 1)
        hit = cells[pos] == wanted
        if not hit.any():
            continue
        q_of_hit = np.broadcast_to(pending[None, :], wanted.shape)[hit]
        cell_of_hit = pos[hit]
        sizes = ends[cell_of_hit] - first[cell_of_hit]
        step = max(1, _PAIRS // max(1, int(sizes.max())))
        for s0 in range(0, len(q_of_hit), step):
            qs, cs, ns = q_of_hit[s0:s0 + step], cell_of_hit[s0:s0 + step], sizes[s0:s0 + step]
            qs = np.repeat(qs, ns)
            within = np.arange(len(qs)) - np.repeat(np.cumsum(ns) - ns, ns)
            ts = by_cell[np.repeat(first[cs], ns) + within]
            d = _relative(frame, targets.keys[ts]) - qrel[qs]
            d2 = (d * d).sum(axis=1)
            keep = d2 > 0
            qs, ts, d2 = qs[keep], ts[keep], d2[keep]
            np.minimum.at(best, qs, d2)
            close = d2 <= best[qs]
            pair_q.append(qs[close])
            pair_t.append(ts[close])
            pair_d.append(d2[close])
    # every group visited: a best below `beyond` is final; the others may have a closer target outside
    # (a query left the pending set only with a best below a visited bound, itself below `beyond`)
    found = best < beyond
    if not pair_q:
        return BallResult(sq, count, empty, empty)
    qs, ts, d2 = np.concatenate(pair_q), np.concatenate(pair_t), np.concatenate(pair_d)
    tie = found[qs] & (d2 == best[qs])
    qs, ts = qs[tie], ts[tie]
    sq[found] = best[found]
    count[:] = np.bincount(qs, minlength=p)
    return BallResult(sq, count, qs, targets.rows[ts].astype(np.intp))


def nearest(targets: GridCloud, frame: GridFrame, query_keys: np.ndarray, *, ties: bool = True) -> BallResult:
    """`ball_search`, then `coarse_search` for the queries it leaves (far ones): the exact nearest squared
    distance and ties of every query within ~`_CELL_REACH` cells; farther ones stay unsettled (sq -1)."""
    ball = ball_search(targets, frame, query_keys, ties=ties)
    left = np.flatnonzero(ball.sq < 0)
    if left.size == 0:
        return ball
    far = coarse_search(targets, frame, query_keys[left])
    ball.sq[left], ball.count[left] = far.sq, far.count
    if not ties:
        return ball
    return BallResult(ball.sq, ball.count, np.concatenate([ball.tie_query, left[far.tie_query]]),
                      np.concatenate([ball.tie_target, far.tie_target]))
