"""Colour PSNR as MPEG's pc_error 0.14 computes it with ``--color=1`` (default options).

A is the reference (N points after merging duplicates), B the result (M points); each point carries
an 8-bit RGB colour. Read from the pc_error sources (mpeg-pcc-dmetric; nothing copied):

- ``--dropdups=2``: points with identical coordinates are merged before anything (as for geometry,
  `metrics.pairs`); the merged point's colour is the per-channel mean of the group's colours, rounded
  *down* (integer division of the sum by the count). With ``--neighborsProc=1`` each merged point
  then counts once (its duplicate count is only used as a weight by ``--neighborsProc=2``).
- For each a of A, the colour it is compared with is the mean of the colours of its same-distance
  nearest points of B (pc_error's ``--neighborsProc=1``, "average": the run of nearest neighbours whose
  consecutive squared distances differ by less than 1e-8, the same tie sets as D2, `metrics.pairs`),
  per channel, rounded to the nearest integer (halves away from zero) and stored as uint8.
- ``--mseSpace=1`` (default): both colours are converted to ITU-R BT.709 Y'CbCr in [0, 1], in double
  precision and then rounded to float32::

      Y  = (0.2126 R + 0.7152 G + 0.0722 B) / 255
      Cb = (-0.1146 R - 0.3854 G + 0.5 B) / 255 + 0.5
      Cr = (0.5 R - 0.4542 G - 0.0458 B) / 255 + 0.5

  and the error of a channel is (x_a - x_b)^2 computed in float32 (pc_error's float arithmetic),
  summed in float64. ``--mseSpace=0``: the error is (R_a - R_b)^2 etc. on the 0..255 values.
- MSE of a channel = mean over A of its errors (A->B); B->A likewise; symmetric MSE = the larger of
  the two, per channel (pc_error's "c[k], F"); PSNR = 10 log10(p^2 / MSE) with p = 1 in Y'CbCr and
  p = 255 in RGB: the colour peak is fixed, it does not depend on ``--resolution``. Identical colours
  give MSE 0 and PSNR +inf (pc_error prints ``inf``; `metrics.scoring` caps it like any PSNR).

Metrics (`metrics.registry`): ``cpsnr_y``, ``cpsnr_u``, ``cpsnr_v`` (pc_error's c[0], c[1], c[2]
PSNRF with ``--mseSpace=1``), ``cpsnr_r``, ``cpsnr_g``, ``cpsnr_b`` (the same with ``--mseSpace=0``)
and ``cpsnr_rgb`` = 10 log10(255^2 / max(mean over R, G, B of the A->B MSEs, the same B->A)): one
RGB figure (pc_error prints none; ours). Hole-region scope as the geometry metrics
(`metrics.geometry`): only the points inside the regions are evaluated, their neighbours are searched
in the whole other cloud; an empty direction is left out; both empty: NaN.

Sets of more than 30 equally distant neighbours are truncated to 30 as in pc_error; which 30 is the
KD-tree's (rare on real data).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from dpcbench.metrics.errors import UserError
from dpcbench.metrics.geometry import Selection
from dpcbench.metrics.pairs import CloudPair, _rows_equal, point_keys, sort_with_order

#: pc_error's ``--mseSpace`` values supported here
MSE_SPACES = {0: "RGB", 1: "BT.709 YCbCr"}
#: the colour peak of each space (pc_error's getPSNR(mse, 1.0) / getPSNR(mse, 255))
COLOUR_PEAK = {0: 255.0, 1: 1.0}


def check_colours(colours: ArrayLike, n: int, label: str) -> np.ndarray:
    """``colours`` as an (n, 3) uint8 array; a UserError naming ``label`` when the shape or range is wrong."""
    arr = np.asarray(colours)
    if arr.ndim != 2 or arr.shape != (n, 3):
        raise UserError(f"{label}: colours must be an ({n}, 3) array (one RGB triple per point), got shape {arr.shape}")
    if arr.dtype == np.uint8:
        return arr
    if arr.dtype.kind not in "iuf" or not np.isfinite(arr).all() or (arr.size and (arr.min() < 0 or arr.max() > 255)) \
            or not np.equal(np.floor(arr), arr).all():
        raise UserError(f"{label}: colours must be 8-bit integers 0..255 (uint8 RGB); convert them first")
    return arr.astype(np.uint8)


def merged_colours(points: np.ndarray, colours: np.ndarray, kept: np.ndarray | None) -> np.ndarray:
    """Colours of the deduplicated cloud: pc_error's ``--dropdups=2`` average.

    points (N, 3), colours (N, 3) uint8, kept: the input rows of the first occurrence of each distinct
    point in input order (`CloudPair.reference_index`), or None when no point is repeated. Returns
    (len(kept), 3) uint8: each distinct point's colour is the floor of the mean of the colours of
    every input point at its position. Duplicate groups are found by sorting `point_keys` and are then
    confirmed on the exact coordinates, so a hash collision never merges distinct points.
    """
    if kept is None:
        return colours
    pts = np.asarray(points, dtype=np.float64)
    n = len(pts)
    sorted_keys, order, _ = sort_with_order(point_keys(pts))
    equal_next = sorted_keys[1:] == sorted_keys[:-1]
    in_group = np.zeros(n, dtype=bool)
    in_group[1:] |= equal_next
    in_group[:-1] |= equal_next
    rows = order[in_group]
    coords = pts[rows] + 0.0
    by = np.lexsort((rows, coords[:, 2], coords[:, 1], coords[:, 0]))  # exact groups, each in row order
    rows, coords = rows[by], coords[by]
    starts = np.ones(len(rows), dtype=bool)
    starts[1:] = ~_rows_equal(coords[1:], coords[:-1])
    group = np.cumsum(starts) - 1
    first = rows[starts]  # the first occurrence of each group (kept)
    count = np.bincount(group)
    out = colours[kept].copy()
    at = np.searchsorted(kept, first)
    for c in range(3):
        sums = np.bincount(group, weights=colours[rows, c].astype(np.float64)).astype(np.int64)
        out[at, c] = (sums // count).astype(np.uint8)
    return out


def to_ycbcr(rgb: np.ndarray) -> np.ndarray:
    """(n, 3) uint8 RGB -> (n, 3) float32 BT.709 Y'CbCr in [0, 1], as pc_error converts (in float64,
    each sum taken left to right, then rounded to float32)."""
    r, g, b = (rgb[:, c].astype(np.float64) for c in range(3))
    out = np.empty((len(rgb), 3), dtype=np.float32)
    out[:, 0] = (0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0
    out[:, 1] = (-0.1146 * r - 0.3854 * g + 0.5000 * b) / 255.0 + 0.5000
    out[:, 2] = (0.5000 * r - 0.4542 * g - 0.0458 * b) / 255.0 + 0.5000
    return out


def neighbour_colours(rows: np.ndarray, cols: np.ndarray, target_colours: np.ndarray, n_queries: int) -> np.ndarray:
    """(n_queries, 3) uint8: per query, the mean colour of its same-distance targets (flat pairs ``rows``
    -> ``cols``), rounded half away from zero (pc_error's ``--neighborsProc=1``). The integer formula
    floor((2 s + k) / 2k) is that rounding of s / k exactly."""
    counts = np.bincount(rows, minlength=n_queries).astype(np.int64)
    if (counts == 0).any():
        raise AssertionError("every query has at least its nearest target among its ties")
    out = np.empty((n_queries, 3), dtype=np.uint8)
    for c in range(3):
        sums = np.bincount(rows, weights=target_colours[cols, c].astype(np.float64), minlength=n_queries)
        out[:, c] = ((2 * sums.astype(np.int64) + counts) // (2 * counts)).astype(np.uint8)
    return out


def colour_errors(query_colours: np.ndarray, compared: np.ndarray, mse_space: int) -> np.ndarray:
    """(n, 3) float32 per-point squared colour errors of each channel, pc_error's arithmetic:
    float32 differences squared in float32 (Y'CbCr), exact integers (RGB: squares <= 65025 are exact in
    float32). Sum them in float64, as pc_error does."""
    if mse_space == 1:
        d = to_ycbcr(query_colours)
        d -= to_ycbcr(compared)
        d *= d
        return d
    if mse_space == 0:
        d = query_colours.astype(np.float32)
        d -= compared.astype(np.float32)
        d *= d
        return d
    raise ValueError(f"mse_space must be 0 (RGB) or 1 (BT.709 YCbCr), got {mse_space!r}")


class ColourPair(CloudPair):
    """A `CloudPair` whose points carry 8-bit RGB colours.

    reference_colours (N_in, 3), result_colours (M_in, 3): one colour per input point (uint8, or
    integers 0..255). Other arguments as `CloudPair`. After construction ``reference_colours`` and
    ``result_colours`` are the colours of the deduplicated clouds (`merged_colours`).
    """

    def __init__(self, reference: ArrayLike, result: ArrayLike, reference_normals: ArrayLike | None = None, *,
                 reference_colours: ArrayLike, result_colours: ArrayLike, **options):
        ref_in, res_in = np.asarray(reference), np.asarray(result)
        ref_c = check_colours(reference_colours, len(ref_in), "reference")
        res_c = check_colours(result_colours, len(res_in), "result")
        super().__init__(ref_in, res_in, reference_normals, **options)
        self.reference_colours = merged_colours(ref_in, ref_c, self.reference_index)
        self.result_colours = merged_colours(res_in, res_c, self.result_index)
        self._colour_errors: dict[tuple[bool, int], np.ndarray] = {}

    @cached_property
    def _compared_forward(self) -> np.ndarray:
        nb = self.ref_to_res
        return neighbour_colours(nb.same_rows, nb.same_cols, self.result_colours, len(self.reference_colours))

    @cached_property
    def _compared_backward(self) -> np.ndarray:
        nb = self.res_to_ref
        return neighbour_colours(nb.same_rows, nb.same_cols, self.reference_colours, len(self.result_colours))

    def colour_errors(self, forward: bool, mse_space: int = 1) -> np.ndarray:
        """(N, 3) errors of each reference point against the result (``forward``), or (M, 3) of each
        result point against the reference, per channel of ``mse_space`` (computed once each)."""
        key = (forward, int(mse_space))
        if key not in self._colour_errors:
            if forward:
                self._colour_errors[key] = colour_errors(self.reference_colours, self._compared_forward, mse_space)
            else:
                self._colour_errors[key] = colour_errors(self.result_colours, self._compared_backward, mse_space)
        return self._colour_errors[key]


def colour_mse_directions(pair: CloudPair, sel: Selection, mse_space: int) -> list[np.ndarray]:
    """[A->B MSE (3,), B->A MSE (3,)] over the selected points, an empty direction left out."""
    if not isinstance(pair, ColourPair):
        raise UserError("colour metrics need colours on both clouds (reference_colours and result_colours); "
                        "these clouds have none: drop the cpsnr_* metrics or give colours")
    out = []
    for forward, mask in ((True, sel.reference), (False, sel.result)):
        errors = pair.colour_errors(forward, mse_space)
        if mask is not None:
            errors = errors[mask]
        if len(errors):
            out.append(errors.sum(axis=0, dtype=np.float64) / len(errors))
    return out


def colour_psnr(mse: float, mse_space: int) -> float:
    """10 log10(p^2 / mse), p = `COLOUR_PEAK` of the space; +inf for 0, NaN for NaN."""
    if math.isnan(mse):
        return math.nan
    if mse <= 0:
        return math.inf
    p = COLOUR_PEAK[mse_space]
    return 10.0 * math.log10(p * p / mse)


def _channel_psnr(space: int, channel: int):
    def value(pair: CloudPair, sel: Selection, settings=None) -> float:
        parts = colour_mse_directions(pair, sel, space)
        if not parts:
            return math.nan
        return colour_psnr(max(float(p[channel]) for p in parts), space)

    value.__name__ = f"cpsnr_{'rgb'[channel] if space == 0 else 'yuv'[channel]}_value"
    return value


cpsnr_y_value = _channel_psnr(1, 0)
cpsnr_u_value = _channel_psnr(1, 1)
cpsnr_v_value = _channel_psnr(1, 2)
cpsnr_r_value = _channel_psnr(0, 0)
cpsnr_g_value = _channel_psnr(0, 1)
cpsnr_b_value = _channel_psnr(0, 2)


def cpsnr_rgb_value(pair: CloudPair, sel: Selection, settings=None) -> float:
    """10 log10(255^2 / max over directions of the RGB MSE averaged over the three channels)."""
    parts = colour_mse_directions(pair, sel, 0)
    if not parts:
        return math.nan
    return colour_psnr(max(float(p.mean()) for p in parts), 0)


def pc_error_colour(reference: ArrayLike, result: ArrayLike, reference_colours: ArrayLike,
                    result_colours: ArrayLike, *, mse_space: int = 1, drop_duplicates: bool = True,
                    workers: int = -1) -> dict[str, float]:
    """Every colour figure pc_error 0.14 prints with ``--color=1 --mseSpace=<mse_space>``, under its
    names (those of golden/colour/pc_error.json): ``"c[k], 1"`` (A->B MSE of channel k), ``"c[k], 2"``
    (B->A), ``"c[k], F"`` (symmetric), ``"c[k],PSNR1"``, ``"c[k],PSNR2"``, ``"c[k],PSNRF"``. PSNRs are
    not capped (+inf for identical colours)."""
    if mse_space not in MSE_SPACES:
        raise ValueError(f"mse_space must be 0 (RGB) or 1 (BT.709 YCbCr), got {mse_space!r}")
    pair = ColourPair(reference, result, reference_colours=reference_colours, result_colours=result_colours,
                      drop_duplicates=drop_duplicates, workers=workers)
    forward, backward = colour_mse_directions(pair, Selection(), mse_space)
    out: dict[str, float] = {}
    for k in range(3):
        mses = {"1": float(forward[k]), "2": float(backward[k]), "F": float(max(forward[k], backward[k]))}
        for tag, mse in mses.items():
            out[f"c[{k}], {tag}"] = mse
            out[f"c[{k}],PSNR{tag}"] = colour_psnr(mse, mse_space)
    return out


__all__ = ["COLOUR_PEAK", "MSE_SPACES", "ColourPair", "check_colours", "colour_errors", "colour_mse_directions",
           "colour_psnr", "cpsnr_b_value", "cpsnr_g_value", "cpsnr_r_value", "cpsnr_rgb_value", "cpsnr_u_value",
           "cpsnr_v_value", "cpsnr_y_value", "merged_colours", "neighbour_colours", "pc_error_colour", "to_ycbcr"]
