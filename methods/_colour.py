"""Colour for a method's output: every output point gets an 8-bit RGB colour, whatever the method.

The methods fill geometry only; this module colours their output afterwards, so that every method
and adapter carries colour without any change to its internals (`InpaintingMethod.inpaint_with_colours`).
For frame f with input points P (N, 3) and colours C (N, 3) uint8, and the method's output Q (N', 3):

1. **Kept points**: an output point equal to an input point (exact coordinates) keeps that point's
   colour (every method keeps the captured points; the first occurrence wins for repeated input points).
2. **Source points** (``fill`` "source" or "auto"): a new point the method reports as copied from
   point j of frame g (`InpaintingMethod.inpaint_with_sources`: temporal-copy does) takes C_g[j], the
   colour of the point it was copied from (motion-compensated: the copy moved with the points).
3. **The other new points**, by ``fill``:

   - ``"nearest"``: the colour of the nearest input point of frame f (the reference fill).
   - ``"harmonic"`` (and the rest of "auto"): harmonic interpolation from the hole's rim over a kNN
     graph, the discrete Laplace equation of Lozes et al.'s colour PDE with p = 2: nodes are the
     unknown new points U, and the known points K (input points, kept and source-coloured points);
     each u in U is joined to its ``k`` nearest nodes with weight w = exp(-d^2 / s^2), s^2 the median
     squared edge length (edges lighter than 1e-9 dropped); U-U weights are symmetrised ((W + W^T) / 2).
     The colours x_U solve, per channel, (D - W_UU) x_U = W_UK x_K with D the weighted degree (sum of all weights of u), i.e.
     each unknown colour is the weighted mean of its neighbours' colours, known colours fixed (the
     minimiser of sum w_ij (x_i - x_j)^2). A group of new points with no edge to a known point is
     anchored with weight 1 to each point's nearest input colour (else the system is singular).
     Solved directly (sparse LU, SuperLU, one factorisation for the three channels; conjugate gradients,
     Jacobi preconditioned, relative tolerance 1e-8, beyond 200k unknowns): the matrix is
     symmetric positive definite (diagonally dominant, every group anchored). New points within half
     the input's median neighbour distance of an input point are treated as on the captured surface:
     nearest colour, and known (whole-frame resamplings such as MeshLab's stay cheap).

Colours are rounded to the nearest integer and clipped to 0..255.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dpcbench.metrics.errors import UserError

#: the colour fills `inpaint_with_colours` accepts
FILLS = ("auto", "nearest", "harmonic", "source")
#: neighbours of the harmonic fill's graph
HARMONIC_NEIGHBOURS = 8
#: the most unknowns solved by sparse LU; more are solved by Jacobi-preconditioned conjugate gradients
_DIRECT_MAX = 200_000
#: the lightest edge of the harmonic fill's graph (weights exp(-d^2 / s^2) are at most 1): lighter ones are dropped
_MIN_WEIGHT = 1e-9
#: new points closer than this many median input spacings to an input point take its colour
_SURFACE_SPACINGS = 0.5


def check_colour_frames(frames: Sequence[np.ndarray], colours: Sequence[np.ndarray], method: str) -> list[np.ndarray]:
    """The colours as F (N_f, 3) uint8 arrays matching ``frames``; UserError naming what is wrong."""
    colours = list(colours)
    if len(colours) != len(frames):
        raise UserError(f"{method}: got colours for {len(colours)} frames but the sequence has {len(frames)}; "
                        "give one (N, 3) colour array per frame")
    out = []
    for i, (frame, col) in enumerate(zip(frames, colours)):
        arr = np.asarray(col)
        if arr.shape != (len(frame), 3):
            raise UserError(f"{method}: frame {i} has {len(frame)} points but colours of shape {arr.shape}; "
                            "give one RGB triple per point")
        if arr.dtype != np.uint8:
            if arr.dtype.kind not in "iuf" or not np.isfinite(arr).all() or arr.min() < 0 or arr.max() > 255:
                raise UserError(f"{method}: frame {i}: colours must be 8-bit RGB (0..255)")
            arr = np.clip(np.rint(arr), 0, 255).astype(np.uint8)
        out.append(arr)
    return out


def kept_index(inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """(N',) for each output point the row of the input point with exactly its coordinates (the first
    such row), -1 for a new point. Rows are matched on sorted coordinate rows (lexicographic), exact."""
    n = len(inputs)
    if n == 0 or len(outputs) == 0:
        return np.full(len(outputs), -1, dtype=np.intp)
    both = np.concatenate([np.asarray(inputs, dtype=np.float64), np.asarray(outputs, dtype=np.float64)]) + 0.0
    order = np.lexsort((np.arange(len(both)), both[:, 2], both[:, 1], both[:, 0]))
    s = both[order]
    new_group = np.ones(len(s), dtype=bool)
    new_group[1:] = np.any(s[1:] != s[:-1], axis=1)
    group = np.cumsum(new_group) - 1
    first = order[new_group]  # the smallest row of each group (the lexsort's last key breaks ties by row)
    head = first[group]  # per sorted position: its group's first row
    is_input = head < n
    index = np.full(len(outputs), -1, dtype=np.intp)
    out_pos = order >= n
    index[order[out_pos] - n] = np.where(is_input[out_pos], head[out_pos], -1)
    return index


def nearest_colours(inputs: np.ndarray, colours: np.ndarray, queries: np.ndarray, tree=None) -> np.ndarray:
    """(Q, 3) uint8: the colour of each query's nearest input point."""
    if len(queries) == 0:
        return np.zeros((0, 3), dtype=np.uint8)
    from scipy.spatial import cKDTree

    tree = tree if tree is not None else cKDTree(inputs)
    _, idx = tree.query(queries, workers=-1)
    return colours[idx]


def harmonic_colours(known_points: np.ndarray, known_colours: np.ndarray, unknown_points: np.ndarray,
                     anchor_colours: np.ndarray, k: int = HARMONIC_NEIGHBOURS) -> np.ndarray:
    """(U, 3) float64 harmonic interpolation of ``known_colours`` (K, 3) at ``unknown_points`` (U, 3) on
    the kNN graph described in the module docstring; ``anchor_colours`` (U, 3): the colour a group of
    unknowns with no known neighbour is anchored to."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    from scipy.sparse.linalg import splu
    from scipy.spatial import cKDTree

    nu, nk = len(unknown_points), len(known_points)
    if nu == 0:
        return np.zeros((0, 3))
    nodes = np.concatenate([unknown_points, known_points])
    k_eff = int(min(k + 1, len(nodes)))
    dist, idx = cKDTree(nodes).query(unknown_points, k=k_eff, workers=-1)
    dist, idx = dist.reshape(nu, k_eff)[:, 1:], idx.reshape(nu, k_eff)[:, 1:]  # the first is the point itself
    sq = dist * dist
    scale = float(np.median(sq[sq > 0])) if np.any(sq > 0) else 1.0
    weight = np.exp(-sq / scale).ravel()
    # an edge lighter than this is no edge: a part of a group joined to the rest only by such links would count as
    # reaching the known colours and yet be free in all but name (the system singular to rounding: seen, a constant
    # colour came out 229 of 255 at ten points)
    weight[weight < _MIN_WEIGHT] = 0.0
    rows = np.repeat(np.arange(nu), k_eff - 1)
    cols = idx.ravel()
    to_u = cols < nu
    w_uu = sp.coo_matrix((weight[to_u], (rows[to_u], cols[to_u])), shape=(nu, nu)).tocsr()
    w_uu = ((w_uu + w_uu.T) * 0.5).tocsr()
    w_uu.eliminate_zeros()
    w_uk = sp.coo_matrix((weight[~to_u], (rows[~to_u], cols[~to_u] - nu)), shape=(nu, nk)).tocsr()
    to_known = np.asarray(w_uk.sum(axis=1)).ravel()
    rhs = w_uk @ known_colours.astype(np.float64)
    n_groups, group = connected_components(w_uu, directed=False)
    reaches = np.bincount(group, weights=to_known, minlength=n_groups) > 0
    anchor = (~reaches[group]).astype(np.float64)
    rhs += anchor[:, None] * anchor_colours.astype(np.float64)
    degree = np.asarray(w_uu.sum(axis=1)).ravel() + to_known + anchor
    a = (sp.diags(degree) - w_uu).tocsc()
    if nu <= _DIRECT_MAX:
        return splu(a).solve(rhs)
    from scipy.sparse.linalg import cg  # very many unknowns (a whole-frame resampling): LU fill-in would be large

    out = np.empty((nu, 3))
    jacobi = sp.diags(1.0 / degree)
    for c in range(3):
        out[:, c], _ = cg(a, rhs[:, c], rtol=1e-8, atol=0.0, maxiter=20 * nu, M=jacobi)
    return out


def colour_frame(inputs: np.ndarray, colours: np.ndarray, outputs: np.ndarray, fill: str = "auto",
                 source_colours: np.ndarray | None = None) -> np.ndarray:
    """(N', 3) uint8 colours of one output frame (see the module docstring).

    inputs (N, 3) and colours (N, 3) uint8: the damaged frame; outputs (N', 3): the method's result;
    source_colours: None or (N', 3) int with -1 rows where a point has no reported source, else the
    colour of its source point."""
    if fill not in FILLS:
        raise UserError(f"unknown colour fill {fill!r}; choose one of {', '.join(FILLS)}")
    from scipy.spatial import cKDTree

    out = np.zeros((len(outputs), 3), dtype=np.uint8)
    kept = kept_index(inputs, outputs)
    old = kept >= 0
    out[old] = colours[kept[old]]
    new = ~old
    known_extra = np.zeros(len(outputs), dtype=bool)
    if source_colours is not None and fill in ("auto", "source"):
        sourced = new & (source_colours[:, 0] >= 0)
        out[sourced] = source_colours[sourced].astype(np.uint8)
        known_extra |= sourced
        new &= ~sourced
    if not new.any():
        return out
    tree = cKDTree(inputs)
    dist, near = tree.query(outputs[new], workers=-1)
    nearest = colours[near]
    if fill in ("nearest", "source"):
        out[new] = nearest
        return out
    from dpcbench.metrics.neighbours import median_neighbour_distance

    spacing = median_neighbour_distance(inputs, tree=tree) if len(inputs) > 1 else 1.0
    on_surface = dist <= _SURFACE_SPACINGS * spacing
    new_rows = np.flatnonzero(new)
    out[new_rows[on_surface]] = nearest[on_surface]
    known_extra[new_rows[on_surface]] = True
    unknown = new_rows[~on_surface]
    if unknown.size == 0:
        return out
    # only the known points among some unknown's k nearest known points can be its neighbours: the graph
    # is built on those (found in the input tree and in a tree of the other known points), not on all
    queries = outputs[unknown]
    k = int(min(HARMONIC_NEIGHBOURS, len(inputs)))
    _, near_in = tree.query(queries, k=k, workers=-1)
    parts_p, parts_c = [inputs[np.unique(near_in)]], [colours[np.unique(near_in)]]
    if known_extra.any():
        extra_p, extra_c = outputs[known_extra], out[known_extra]
        _, near_ex = cKDTree(extra_p).query(queries, k=int(min(HARMONIC_NEIGHBOURS, len(extra_p))), workers=-1)
        parts_p.append(extra_p[np.unique(near_ex)])
        parts_c.append(extra_c[np.unique(near_ex)])
    values = harmonic_colours(np.concatenate(parts_p), np.concatenate(parts_c), queries, nearest[~on_surface])
    out[unknown] = np.clip(np.rint(values), 0, 255).astype(np.uint8)
    return out


def colour_outputs(inputs: Sequence[np.ndarray], colours: Sequence[np.ndarray], outputs: Sequence[np.ndarray],
                   sources: Sequence[tuple[np.ndarray, np.ndarray]] | None = None, fill: str = "auto") -> list[np.ndarray]:
    """Colours of every output frame: `colour_frame` per frame. ``sources``: None, or per output frame
    (source frame (N',) int, source row (N',) int), -1 where a point has no source."""
    result = []
    for f, (points_in, col, points_out) in enumerate(zip(inputs, colours, outputs)):
        source_colours = None
        if sources is not None and sources[f] is not None:
            frame_of, row_of = sources[f]
            source_colours = np.full((len(points_out), 3), -1, dtype=np.int16)
            for g in np.unique(frame_of[frame_of >= 0]):
                at = frame_of == g
                source_colours[at] = colours[int(g)][row_of[at]]
        result.append(colour_frame(np.asarray(points_in, dtype=np.float64), col,
                                   np.asarray(points_out, dtype=np.float64), fill, source_colours))
    return result


__all__ = ["FILLS", "HARMONIC_NEIGHBOURS", "check_colour_frames", "colour_frame", "colour_outputs", "harmonic_colours",
           "kept_index", "nearest_colours"]
