"""Point cloud quality metrics on numpy arrays: a frame is an (N, 3) float array, a sequence a list.

Geometry PSNR (D1 point-to-point, D2 point-to-plane) reproduces MPEG's pc_error 0.14 (default options:
duplicates merged, equal-distance neighbours averaged, normals of the reference carried onto the
result); see `metrics.pairs` for the conventions and `metrics.geometry` for every formula, including
the Hausdorff family, NSHD, Chamfer, F-score and the hole-region variants. Temporal consistency:
`metrics.temporal`. Aggregation and the infinite-PSNR cap: `metrics.scoring`.

Public API::

    score_frame(reference, result, metrics=None, *, peak="intrinsic", reference_normals=None,
                regions=None, region_margin=0.0, **options) -> {name: value}
    score_sequence(references, results, metrics=None, **same) -> {"frames": [...], "mean": {...}, ...}
    temporal_consistency(references, results, regions=None) -> float
    gpsnr_d1, gpsnr_d2, d1_mse, d2_mse, hausdorff, hausdorff_psnr, nshd, chamfer, fscore  (one metric each)
    pc_error(reference, result, reference_normals=None, peak=...) -> pc_error's figures
    METRICS (name -> Metric), DEFAULT_METRICS
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from numpy.typing import ArrayLike

from dpcbench.metrics.geometry import psnr, resolve_peak
from dpcbench.metrics.pairs import CloudPair, estimate_normals
from dpcbench.metrics.registry import DEFAULT_METRICS, METRICS, Metric, get_metric
from dpcbench.metrics.scoring import (
    DEFAULT_MAX_PSNR,
    make_pair,
    pc_error,
    score_frame,
    score_frame_scopes,
    score_pair,
    score_sequence,
)
from dpcbench.metrics.temporal import temporal_consistency, temporal_consistency_per_pair
from dpcbench.metrics.types import Region


def _single(name: str) -> Callable[..., float]:
    def fn(reference: ArrayLike, result: ArrayLike, *, peak: str | float = "intrinsic",
           reference_normals: ArrayLike | None = None, regions: Sequence[Region] | None = None,
           region_margin: float = 0.0, **options: Any) -> float:
        return score_frame(
            reference, result, [name], peak=peak, reference_normals=reference_normals, regions=regions,
            region_margin=region_margin, **options,
        )[name]

    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = (
        f"{METRICS[name].description} [{METRICS[name].unit}].\n\n"
        "reference (N, 3), result (M, 3); keyword arguments as `score_frame`. For several metrics of one "
        "frame call `score_frame`, which shares the neighbour queries."
    )
    return fn


gpsnr_d1 = _single("gpsnr_d1")
gpsnr_d2 = _single("gpsnr_d2")
d1_mse = _single("d1_mse")
d2_mse = _single("d2_mse")
hausdorff = _single("hausdorff")
hausdorff_psnr = _single("hausdorff_psnr")
nshd = _single("nshd")
chamfer = _single("chamfer")
fscore = _single("fscore")

__all__ = [
    "CloudPair",
    "DEFAULT_MAX_PSNR",
    "DEFAULT_METRICS",
    "METRICS",
    "Metric",
    "chamfer",
    "d1_mse",
    "d2_mse",
    "estimate_normals",
    "fscore",
    "get_metric",
    "gpsnr_d1",
    "gpsnr_d2",
    "hausdorff",
    "hausdorff_psnr",
    "make_pair",
    "nshd",
    "pc_error",
    "psnr",
    "resolve_peak",
    "score_frame",
    "score_frame_scopes",
    "score_pair",
    "score_sequence",
    "temporal_consistency",
    "temporal_consistency_per_pair",
]
