"""Frame-level geometry metrics, each a reduction of the shared neighbour arrays of a `CloudPair`.

Notation: A is the reference (ground truth, N points after merging duplicates), B the result (M
points); d(a, B) is the distance from a to its nearest point of B; p is the PSNR peak.

Whole-frame definitions:

- ``d1_mse``   = max( mean_a d(a,B)^2 , mean_b d(b,A)^2 )                     (pc_error "mseF p2point")
- ``d2_mse``   = max( mean_a e2(a,B) , mean_b e2(b,A) )                        (pc_error "mseF p2plane"),
  e2(q, T) = mean over q's same-distance nearest points t of ((q - t) . n_t)^2, with n_t the
  reference normals (B->A) or the reference normals carried onto B (A->B); see `metrics.pairs`.
- ``gpsnr_d1`` = 10 log10(3 p^2 / d1_mse) dB,  ``gpsnr_d2`` = 10 log10(3 p^2 / d2_mse) dB.
- ``hausdorff_sq`` = max( max_a d(a,B)^2 , max_b d(b,A)^2 )                   (pc_error "h. p2point")
- ``hausdorff`` = sqrt(hausdorff_sq), the symmetric Hausdorff distance H, in coordinate units.
- ``hausdorff_psnr`` = 10 log10(3 p^2 / hausdorff_sq) dB                        (pc_error "h.,PSNR p2point")
- ``nshd`` = H^2 / (D^2 * N), D the diagonal of A's axis-aligned bounding box (see `nshd`).
- ``chamfer`` = mean_a d(a,B)^2 + mean_b d(b,A)^2: squared distances, mean per direction, the two
  directions SUMMED (the PCN / PointNet++ convention; some papers halve it, some use unsquared
  distances: this one is squared, summed).
- ``fscore`` = 2 P R / (P + R) with precision P = fraction of b with d(b,A) <= tau and recall
  R = fraction of a with d(a,B) <= tau; 0 when P + R = 0. Default tau = 2 x the median
  nearest-neighbour spacing of A (2 voxels on voxelized data), set with ``fscore_threshold``.

Hole-region variants (``regions`` given): only the reference points inside the regions (grown by
``region_margin``), A_R, and the result points inside them, B_R, are *evaluated*; their nearest
neighbours are still searched in the whole other cloud. So a method that leaves a hole empty is
scored by how far the hole's ground truth lies from the nearest result points (the hole border):
a finite, honest penalty, and no undefined value. A direction with no point to evaluate (B_R empty:
nothing was put in the hole; A_R empty: the region holds no ground truth) is left out of the max /
sum; when both are empty every metric is NaN (nothing to score). F-score is 0 when exactly one side
is empty. The peak and the NSHD normalisation always come from the whole reference frame: they
describe the object, not the hole.

PSNR values are +inf when the error is exactly 0 (identical clouds), as pc_error prints them;
`metrics.scoring` caps them at a documented ceiling so that averages and JSON stay finite.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dpcbench.metrics.errors import UserError
from dpcbench.metrics.pairs import CloudPair
from dpcbench.metrics.types import Region

#: Default F-score threshold, in multiples of the reference's median nearest-neighbour spacing.
FSCORE_SPACING_FACTOR = 2.0


@dataclass(frozen=True)
class Selection:
    """Which points each direction evaluates: boolean masks over ``pair.reference`` (N,) and
    ``pair.result`` (M,), or None for all points (whole frame)."""

    reference: np.ndarray | None = None
    result: np.ndarray | None = None

    @classmethod
    def of(cls, pair: CloudPair, regions: Sequence[Region] | None = None, margin: float = 0.0) -> Selection:
        if regions is None:
            return cls()
        ref_mask, res_mask = pair.masks(regions, margin)
        return cls(ref_mask, res_mask)

    @property
    def is_whole(self) -> bool:
        return self.reference is None and self.result is None


def _pick(values: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    return values if mask is None else values[mask]


def psnr(error: float, peak: float) -> float:
    """10 log10(3 peak^2 / error) in dB (pc_error's geometry PSNR); +inf when error == 0, NaN for NaN."""
    if math.isnan(error):
        return math.nan
    if error <= 0:
        return math.inf
    return 10.0 * math.log10(3.0 * peak * peak / error)


def resolve_peak(peak: str | float, pair: CloudPair | None = None, bit_depth: int | None = None) -> float:
    """The PSNR peak p as a number.

    ``peak`` is one of: ``"intrinsic"`` (pc_error's default ``--resolution=0``: the largest
    nearest-neighbour distance inside the reference, see `CloudPair.intrinsic_resolution`; needs
    ``pair``), ``"bitdepth:B"`` or ``"bitdepth"`` with ``bit_depth=B`` (p = 2^B - 1, e.g. 1023 for
    10-bit data as MPEG's common test conditions use), a positive number, or a numeric string.
    """
    if isinstance(peak, str):
        text = peak.strip().lower()
        if text == "intrinsic":
            if pair is None:
                raise ValueError("peak='intrinsic' needs the reference cloud")
            return pair.intrinsic_resolution
        if text.startswith("bitdepth"):
            given = text.partition(":")[2] or bit_depth
            try:
                depth = int(str(given))  # no depth given: int("None") raises, refused below
            except (TypeError, ValueError):
                raise ValueError(
                    f"peak {peak!r}: give the bit depth as 'bitdepth:10' (or bit_depth=10); got {given!r}"
                ) from None
            if not 1 <= depth <= 32:
                raise ValueError(f"peak {peak!r}: bit depth must be in 1..32, got {depth}")
            return float(2**depth - 1)
        try:
            value = float(text)
        except ValueError:
            raise ValueError(
                f"unknown peak {peak!r}; use 'intrinsic', 'bitdepth:B' (e.g. 'bitdepth:10') or a number such as 1023"
            ) from None
    else:
        try:
            value = float(peak)
        except (TypeError, ValueError):
            raise ValueError(f"unknown peak {peak!r}; use 'intrinsic', 'bitdepth:B' or a positive number") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"peak must be a positive finite number, got {peak!r}")
    return value


# -- per-metric reductions ------------------------------------------------------------------------
# Each takes (pair, selection, settings) and returns a float; `settings` is a `Settings`.


@dataclass(frozen=True)
class Settings:
    """Parameters shared by the metrics of one frame."""

    peak: str | float = "intrinsic"
    bit_depth: int | None = None
    fscore_threshold: float | None = None


def _reduce_directions(pair: CloudPair, name: str, sel: Selection, reduce) -> list[float]:
    """``reduce`` of the per-point values of each non-empty direction, [A->B, B->A] minus empty ones;
    ``name`` "sq" (nearest squared distances) or "plane" (point-to-plane errors). One direction's
    array at a time: on the integer-grid path each read makes an (N,) array, not kept."""
    getters = ((lambda: pair.ref_to_res.sq_dist, lambda: pair.res_to_ref.sq_dist) if name == "sq"
               else (lambda: pair.plane_ref_to_res, lambda: pair.plane_res_to_ref))
    out = []
    for get, mask in zip(getters, (sel.reference, sel.result)):
        values = _pick(get(), mask)
        if values.size:
            out.append(float(reduce(values)))
        del values  # before the other direction's array is made
    return out


def d1_mse(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    parts = _reduce_directions(pair, "sq", sel, np.mean)
    return max(parts) if parts else math.nan


def d2_mse(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    parts = _reduce_directions(pair, "plane", sel, np.mean)
    return max(parts) if parts else math.nan


def hausdorff_sq(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    parts = _reduce_directions(pair, "sq", sel, np.max)
    return max(parts) if parts else math.nan


def gpsnr_d1_value(pair: CloudPair, sel: Selection, settings: Settings) -> float:
    return psnr(d1_mse(pair, sel), resolve_peak(settings.peak, pair, settings.bit_depth))


def gpsnr_d2_value(pair: CloudPair, sel: Selection, settings: Settings) -> float:
    return psnr(d2_mse(pair, sel), resolve_peak(settings.peak, pair, settings.bit_depth))


def hausdorff_psnr_value(pair: CloudPair, sel: Selection, settings: Settings) -> float:
    return psnr(hausdorff_sq(pair, sel), resolve_peak(settings.peak, pair, settings.bit_depth))


def hausdorff_value(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    return math.sqrt(hausdorff_sq(pair, sel))


def bounding_box_diagonal(points: np.ndarray) -> float:
    """Length of the diagonal of the axis-aligned bounding box of (N, 3) ``points``."""
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def nshd_value(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    """Normalized symmetric Hausdorff distance: NSHD = H^2 / (D^2 * N).

    H: symmetric Hausdorff distance (``hausdorff``; restricted to the hole regions in the region
    variant), D: diagonal of the reference frame's bounding box, N: number of (distinct) reference
    points. Both D and N come from the whole reference frame in the region variant too.

    Why this form: no formula is published (Dinesh et al., VCIP 2017 report raw Hausdorff
    distances). H^2 / N is the share of the worst point in a mean-squared error over the cloud, and
    dividing by D^2 makes it independent of the coordinate unit (scaling the cloud leaves NSHD
    unchanged), so frames of different bit depths compare. The paper's 1e-7 values fit a squared
    distance over such a normalisation; its exact constant cannot be recovered, so compare rankings
    and ratios, not absolute values. A single-point reference (D = 0) gives NaN.
    """
    h2 = hausdorff_sq(pair, sel)
    diag = bounding_box_diagonal(pair.reference)
    if diag == 0 or math.isnan(h2):
        return math.nan
    return h2 / (diag * diag * len(pair.reference))


def chamfer_value(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    parts = _reduce_directions(pair, "sq", sel, np.mean)
    return float(sum(parts)) if parts else math.nan


def fscore_threshold(pair: CloudPair, settings: Settings | None = None) -> float:
    """The F-score distance threshold tau: ``settings.fscore_threshold`` or 2 x the median
    nearest-neighbour spacing of the reference."""
    if settings is not None and settings.fscore_threshold is not None:
        tau = float(settings.fscore_threshold)
        if not (math.isfinite(tau) and tau > 0):
            raise ValueError(f"fscore_threshold must be a positive distance, got {settings.fscore_threshold!r}")
        return tau
    spacing = pair.reference_spacing
    spacing = spacing[np.isfinite(spacing)]
    if spacing.size == 0:
        raise UserError("the default F-score threshold needs at least two reference points; pass fscore_threshold")
    return FSCORE_SPACING_FACTOR * float(np.median(spacing))


def fscore_value(pair: CloudPair, sel: Selection, settings: Settings | None = None) -> float:
    tau_sq = fscore_threshold(pair, settings) ** 2
    recall_d = _pick(pair.ref_to_res.sq_dist, sel.reference)
    precision_d = _pick(pair.res_to_ref.sq_dist, sel.result)
    if recall_d.size == 0 and precision_d.size == 0:
        return math.nan
    if recall_d.size == 0 or precision_d.size == 0:
        return 0.0
    recall = float(np.mean(recall_d <= tau_sq))
    precision = float(np.mean(precision_d <= tau_sq))
    if precision + recall == 0:
        return 0.0
    return 2.0 * precision * recall / (precision + recall)
