"""Scoring a frame or a sequence with several metrics at once, sharing one set of neighbour queries.

Aggregation over a sequence follows MPEG practice: every metric is computed per frame, and the
sequence value is the plain mean of the per-frame values (for PSNRs: the mean of per-frame PSNRs, not
the PSNR of the mean MSE). Frames where a metric is undefined (NaN: e.g. the hole-region variant of a
frame whose regions hold no point on either side) are left out of that mean.

Infinite PSNR: identical clouds have MSE 0 and PSNR +inf (pc_error prints ``inf``). To keep means
and JSON finite, `score_frame` caps every PSNR at ``max_psnr`` (default `DEFAULT_MAX_PSNR` = 200 dB,
far above any real error: with p = 1023 it is an MSE of 3e-14, with the intrinsic peak of 10-bit data
about 1e-19) and `score_sequence` lists the capped (frame, metric) pairs under ``"capped"``.
``max_psnr=None`` keeps +inf.
"""

from __future__ import annotations

import math
from collections import abc
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dpcbench.metrics import geometry
from dpcbench.metrics.colour import ColourPair
from dpcbench.metrics.geometry import Selection, Settings, psnr, resolve_peak
from dpcbench.metrics.pairs import DEFAULT_NORMAL_NEIGHBOURS, CloudPair
from dpcbench.metrics.points import as_points
from dpcbench.metrics.registry import DEFAULT_METRICS, METRICS, get_metric
from dpcbench.metrics.types import Frames, Region, RegionsPerFrame

#: metric names: one name, several, or None for `DEFAULT_METRICS`
MetricNames = str | Sequence[str] | None
#: the PSNR peak: "intrinsic", "bitdepth:B", or a number (see `metrics.geometry.resolve_peak`)
Peak = str | float

DEFAULT_MAX_PSNR = 200.0
_OPTIONS = ("bit_depth", "fscore_threshold", "normal_neighbours", "drop_duplicates", "max_psnr", "workers")


def _frame_metric_names(metrics) -> list[str]:
    names = list(DEFAULT_METRICS if metrics is None else ([metrics] if isinstance(metrics, str) else metrics))
    for name in names:
        if get_metric(name).level != "frame":
            raise ValueError(f"{name!r} is a sequence-level metric; use score_sequence or metrics.{name}")
    return names


def _split_options(options: dict, peak="intrinsic") -> tuple[Settings, dict, float | None]:
    """(metric settings, CloudPair keyword arguments, max_psnr) from score_frame's options; the peak's
    syntax is checked here so that a bad peak fails even when no PSNR is asked for."""
    unknown = sorted(set(options) - set(_OPTIONS))
    if unknown:
        raise ValueError(f"unknown scoring option(s) {unknown}; valid options: peak, {', '.join(_OPTIONS)}")
    if not (isinstance(peak, str) and peak.strip().lower() == "intrinsic"):
        resolve_peak(peak, None, options.get("bit_depth"))
    settings = Settings(
        peak=peak,
        bit_depth=options.get("bit_depth"),
        fscore_threshold=options.get("fscore_threshold"),
    )
    pair_kw = {
        "drop_duplicates": bool(options.get("drop_duplicates", True)),
        "normal_neighbours": int(options.get("normal_neighbours", DEFAULT_NORMAL_NEIGHBOURS)),
        "workers": options.get("workers", -1),
    }
    return settings, pair_kw, options.get("max_psnr", DEFAULT_MAX_PSNR)


def _evaluate(pair: CloudPair, names, selection: Selection, settings: Settings, max_psnr) -> tuple[dict, list[str]]:
    """(values by name, names whose PSNR was capped)."""
    values, capped = {}, []
    for name in names:
        metric = METRICS[name]
        assert metric.fn is not None  # every METRICS entry is computed (only resource metrics have no fn)
        value = float(metric.fn(pair, selection, settings))
        if metric.is_psnr and max_psnr is not None and value > max_psnr:
            value = float(max_psnr)
            capped.append(name)
        values[name] = value
    return values, capped


def make_pair(reference: ArrayLike, result: ArrayLike, reference_normals: ArrayLike | None = None,
              reference_colours: ArrayLike | None = None, result_colours: ArrayLike | None = None,
              **options: Any) -> CloudPair:
    """A `CloudPair` built with the pair-related scoring options (drop_duplicates, normal_neighbours);
    a `metrics.colour.ColourPair` (which the cpsnr_* metrics need) when both clouds' colours are given.
    ``reference`` and ``result`` may be arrays of any real dtype or open3d point clouds
    (`metrics.points.as_points`)."""
    _, pair_kw, _ = _split_options(options)
    if reference_colours is not None and result_colours is not None:
        return ColourPair(as_points(reference), as_points(result), reference_normals,
                          reference_colours=reference_colours, result_colours=result_colours, **pair_kw)
    return CloudPair(as_points(reference), as_points(result), reference_normals, **pair_kw)


def score_pair(pair: CloudPair, metrics: MetricNames = None, *, peak: Peak = "intrinsic",
               regions: Sequence[Region] | None = None, region_margin: float = 0.0,
               **options: Any) -> tuple[dict[str, float], list[str]]:
    """Like `score_frame` on an existing `CloudPair` (reuse it for several scopes or peaks); returns
    (values by name, names of the PSNRs capped at ``max_psnr``)."""
    names = _frame_metric_names(metrics)
    settings, _, max_psnr = _split_options(options, peak)
    selection = Selection.of(pair, regions, region_margin)
    return _evaluate(pair, names, selection, settings, max_psnr)


def score_frame(reference: ArrayLike, result: ArrayLike, metrics: MetricNames = None, *, peak: Peak = "intrinsic",
                reference_normals: ArrayLike | None = None, regions: Sequence[Region] | None = None,
                region_margin: float = 0.0, reference_colours: ArrayLike | None = None,
                result_colours: ArrayLike | None = None, **options: Any) -> dict[str, float]:
    """Score one result frame against its reference frame.

    reference: (N, 3) ground truth; result: (M, 3) (arrays of any real dtype, or open3d point
    clouds: `metrics.points.as_points`); metrics: names from `METRICS` (default
    `DEFAULT_METRICS`); peak: "intrinsic" | "bitdepth:B" | number (see `resolve_peak`);
    reference_normals: (N, 3) or None (estimated for D2); regions: None for the whole frame, or the
    frame's hole regions for the hole-region variant (see `metrics.geometry`), grown by
    ``region_margin``. options: ``bit_depth``, ``fscore_threshold``, ``normal_neighbours`` (default
    12), ``drop_duplicates`` (default True, as pc_error), ``max_psnr`` (default 200 dB, None = keep inf),
    ``workers`` (threads of the neighbour queries, default -1 = all cores; values do not depend on it).
    reference_colours (N, 3), result_colours (M, 3): uint8 RGB per point, needed by the cpsnr_* metrics
    (`metrics.colour`).

    Returns {metric name: value}. The KD-trees and neighbour queries are built once and shared by all
    metrics.
    """
    pair = make_pair(reference, result, reference_normals, reference_colours, result_colours, **options)
    values, _ = score_pair(pair, metrics, peak=peak, regions=regions, region_margin=region_margin, **options)
    return values


def score_frame_scopes(reference: ArrayLike, result: ArrayLike, metrics: MetricNames = None, *,
                       regions: Sequence[Region], peak: Peak = "intrinsic", reference_normals: ArrayLike | None = None,
                       region_margin: float = 0.0, **options: Any) -> dict[str, dict[str, float]]:
    """Both scopes of one frame from one set of neighbour queries: {"frame": whole-frame values,
    "holes": hole-region values}."""
    pair = make_pair(reference, result, reference_normals, **options)
    whole, _ = score_pair(pair, metrics, peak=peak, **options)
    holes, _ = score_pair(pair, metrics, peak=peak, regions=regions, region_margin=region_margin, **options)
    return {"frame": whole, "holes": holes}


def _nanmean(values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


def score_sequence(references: Frames, results: Frames, metrics: MetricNames = None, *, peak: Peak = "intrinsic",
                   reference_normals: Sequence[ArrayLike | None] | None = None, regions: RegionsPerFrame | None = None,
                   region_margin: float = 0.0, reference_colours: Sequence[ArrayLike | None] | None = None,
                   result_colours: Sequence[ArrayLike | None] | None = None, **options: Any) -> dict[str, Any]:
    """Score a result sequence frame by frame, then average.

    references, results: lists of (N_f, 3) arrays of the same length; reference_normals: None or a
    list of per-frame (N_f, 3) arrays (None entries allowed); regions: None or a list of per-frame
    region lists. ``metrics`` may include the sequence-level "temporal_consistency".
    reference_colours, result_colours: None or per-frame (N_f, 3) uint8 colours (for the cpsnr_* metrics).

    Returns {"frames": [{"frame": i, name: value, ...}], "mean": {name: mean over frames},
    "capped": [{"frame": i, "metric": name}] (PSNRs capped at max_psnr), and, when a sequence-level
    metric is asked for, "sequence": {name: value}}.
    """
    # a Sequence is used as it is (indexed, never copied into a list), so that a caller can hand frames
    # out one at a time: a frame is then only held while its pair is built (see `dpcbench score`)
    references = references if isinstance(references, abc.Sequence) else list(references)
    results = results if isinstance(results, abc.Sequence) else list(results)
    if len(references) != len(results):
        raise ValueError(
            f"mismatched frame counts: {len(references)} reference frames and {len(results)} result frames; "
            "score sequences of the same length"
        )
    if not references:
        raise ValueError("no frames to score")
    names = list(DEFAULT_METRICS if metrics is None else ([metrics] if isinstance(metrics, str) else metrics))
    for name in names:
        get_metric(name)
    frame_names = [n for n in names if METRICS[n].level == "frame"]
    sequence_names = [n for n in names if METRICS[n].level == "sequence"]
    for label, per_frame in (("reference_normals", reference_normals), ("regions", regions),
                             ("reference_colours", reference_colours), ("result_colours", result_colours)):
        if per_frame is not None and len(per_frame) != len(references):
            raise ValueError(f"{label} given for {len(per_frame)} frames but the sequence has {len(references)}")

    _split_options(options, peak)  # a bad option or peak fails before any frame is scored
    frames, capped = [], []
    for i in range(len(references)):
        pair = None  # the previous frame's pair is freed before this frame's is built
        try:  # the frames are not bound to names: the pair (which keeps what it needs) is their only holder
            pair = make_pair(references[i], results[i], None if reference_normals is None else reference_normals[i],
                             None if reference_colours is None else reference_colours[i],
                             None if result_colours is None else result_colours[i], **options)
            values, capped_names = score_pair(
                pair, frame_names, peak=peak, regions=None if regions is None else regions[i],
                region_margin=region_margin, **options,
            ) if frame_names else ({}, [])
        except ValueError as err:  # same class (a refusal stays a metrics.errors.UserError), frame named
            raise type(err)(f"frame {i}: {err}") from err
        frames.append({"frame": i, **values})
        capped += [{"frame": i, "metric": n} for n in capped_names]
    out = {
        "frames": frames,
        "mean": {n: _nanmean([f[n] for f in frames]) for n in frame_names},
        "capped": capped,
    }
    if sequence_names:
        references = [as_points(r) for r in references]
        results = [as_points(r) for r in results]
        out["sequence"] = {
            n: _sequence_fn(n)(references, results, regions, region_margin=region_margin) for n in sequence_names
        }
    return out


def pc_error(reference: ArrayLike, result: ArrayLike, reference_normals: ArrayLike | None = None, *,
             peak: Peak = "intrinsic", **options: Any) -> dict[str, float]:
    """The geometry figures pc_error 0.14 prints for a pair, under the names of golden/pc_error.json:
    d1_mse, d1_psnr, d2_mse, d2_psnr, d1_hausdorff_sq, d1_hausdorff_psnr, peak. PSNRs are not capped
    (+inf for identical clouds, as pc_error). D2 is computed with estimated normals when
    ``reference_normals`` is None (pc_error would skip D2 then)."""
    pair = make_pair(reference, result, reference_normals, **options)
    settings, _, _ = _split_options(options, peak)
    p = resolve_peak(peak, pair, settings.bit_depth)
    whole = Selection()
    d1 = geometry.d1_mse(pair, whole)
    d2 = geometry.d2_mse(pair, whole)
    h2 = geometry.hausdorff_sq(pair, whole)
    return {
        "d1_mse": d1,
        "d1_psnr": psnr(d1, p),
        "d2_mse": d2,
        "d2_psnr": psnr(d2, p),
        "d1_hausdorff_sq": h2,
        "d1_hausdorff_psnr": psnr(h2, p),
        "peak": p,
    }


def _sequence_fn(name: str) -> Callable[..., Any]:
    """The function of a sequence metric (every METRICS entry has one; only resource metrics have none)."""
    fn = METRICS[name].fn
    assert fn is not None, name
    return fn
