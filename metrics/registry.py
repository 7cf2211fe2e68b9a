"""The metrics by name, with the facts a results table needs about each: the one place that says
whether higher is better, in which unit a value is, how a change between two values is measured,
and whether a value depends on the PSNR peak. Results tables, `dpcbench compare`, the dashboard and
the runner ask `describe` instead of keeping their own lists.

Three families, all `Metric`:

- ``METRICS``: the quality metrics this package computes. ``fn`` of a frame-level metric takes
  ``(pair: CloudPair, selection: Selection, settings: Settings)`` and returns a float (see
  `metrics.geometry`); ``fn`` of the sequence-level metric takes
  ``(references, results, regions=None, *, region_margin=0.0, correspondences=None)``.
- ``RESOURCE_METRICS``: what a run costs (``time_s``, ``cpu_time_s``, ``peak_mem_mb``), measured by the harness
  (``fn`` None, level "run").
- ``INPUT_METRICS``: facts about the damaged input, not the method (``removed_fraction``): no
  direction (``higher_is_better`` None), never a regression.

``version`` changes whenever a definition changes, so stored results say which definition made them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from dpcbench.metrics import colour, geometry
from dpcbench.metrics.lazy import EntryTypeError, ObjectRegistry
from dpcbench.metrics.temporal import temporal_consistency


@dataclass(frozen=True)
class Metric:
    """One metric's facts.

    higher_is_better: the direction (None: a fact about the input, no direction).
    change:           how two values are compared: "delta" = current - baseline (dB, bounded scores),
                      "ratio" = current / baseline (distances, time, memory).
    level:            "frame", "sequence" (one value per sequence), "run" (a resource measured by the
                      harness) or "input" (a fact about the damaged input).
    """

    name: str
    higher_is_better: bool | None
    unit: str
    version: str
    description: str
    fn: Callable | None
    level: str = "frame"
    uses_peak: bool = False  # a PSNR: its value depends on the peak (record the peak with it)
    is_psnr: bool = False  # +inf for identical clouds; capped in score_frame
    change: str = "ratio"


def _m(name: str, higher: bool | None, unit: str, description: str, fn: Callable | None, **kw) -> Metric:
    return Metric(name, higher, unit, "1", description, fn, **kw)


def _check_metric(name: str, obj: Any) -> None:
    if not isinstance(obj, Metric) or obj.fn is None or obj.level not in ("frame", "sequence"):
        raise EntryTypeError(f"metric {name!r} is {obj!r}, not a dpcbench.metrics.registry.Metric with a function "
                        "and level 'frame' or 'sequence'")


#: the built-in quality metrics, the entry points of group ``dpcbench.metrics`` (each a `Metric`) and
#: import paths ``"package.module:attr"`` naming one (`metrics.lazy.ObjectRegistry`)
METRICS: ObjectRegistry = ObjectRegistry("metric", {
    m.name: m
    for m in [
        _m(
            "gpsnr_d1",
            True,
            "dB",
            "point-to-point geometry PSNR, pc_error 0.14 D1: 10 log10(3 p^2 / max(MSE A->B, MSE B->A))",
            geometry.gpsnr_d1_value,
            uses_peak=True,
            is_psnr=True,
            change="delta",
        ),
        _m(
            "gpsnr_d2",
            True,
            "dB",
            "point-to-plane geometry PSNR, pc_error 0.14 D2 (reference normals, given or estimated)",
            geometry.gpsnr_d2_value,
            uses_peak=True,
            is_psnr=True,
            change="delta",
        ),
        _m("d1_mse", False, "units^2", "symmetric point-to-point MSE (pc_error mseF p2point)", geometry.d1_mse),
        _m("d2_mse", False, "units^2", "symmetric point-to-plane MSE (pc_error mseF p2plane)", geometry.d2_mse),
        _m(
            "hausdorff",
            False,
            "units",
            "symmetric Hausdorff distance H = max(h(A,B), h(B,A))",
            geometry.hausdorff_value,
        ),
        _m(
            "hausdorff_sq",
            False,
            "units^2",
            "squared symmetric Hausdorff distance (pc_error d1 h. p2point)",
            geometry.hausdorff_sq,
        ),
        _m(
            "hausdorff_psnr",
            True,
            "dB",
            "pc_error's Hausdorff PSNR: 10 log10(3 p^2 / H^2)",
            geometry.hausdorff_psnr_value,
            uses_peak=True,
            is_psnr=True,
            change="delta",
        ),
        _m(
            "nshd",
            False,
            "1",
            "normalized symmetric Hausdorff distance H^2 / (D^2 N), D reference bbox diagonal, N reference points",
            geometry.nshd_value,
        ),
        _m(
            "chamfer",
            False,
            "units^2",
            "Chamfer distance: mean squared NN distance A->B plus mean squared NN distance B->A",
            geometry.chamfer_value,
        ),
        _m(
            "fscore",
            True,
            "1",
            "F-score at distance tau (default 2 x median reference spacing)",
            geometry.fscore_value,
            change="delta",
        ),
        *[
            _m(
                f"cpsnr_{ch}",
                True,
                "dB",
                f"colour PSNR of {label}, pc_error 0.14 --color=1 --mseSpace={space} c[{k}] PSNRF: "
                f"10 log10({peak}^2 / max(MSE A->B, MSE B->A)), nearest-neighbour colours (needs colours)",
                fn,
                is_psnr=True,
                change="delta",
            )
            for ch, label, space, k, peak, fn in (
                ("y", "luma Y (BT.709)", 1, 0, 1, colour.cpsnr_y_value),
                ("u", "chroma Cb (BT.709)", 1, 1, 1, colour.cpsnr_u_value),
                ("v", "chroma Cr (BT.709)", 1, 2, 1, colour.cpsnr_v_value),
                ("r", "red", 0, 0, 255, colour.cpsnr_r_value),
                ("g", "green", 0, 1, 255, colour.cpsnr_g_value),
                ("b", "blue", 0, 2, 255, colour.cpsnr_b_value),
            )
        ],
        _m(
            "cpsnr_rgb",
            True,
            "dB",
            "colour PSNR of RGB: 10 log10(255^2 / max over directions of the mean R, G, B MSE) (needs colours)",
            colour.cpsnr_rgb_value,
            is_psnr=True,
            change="delta",
        ),
        _m(
            "temporal_consistency",
            False,
            "units",
            "mean frame-to-frame change of the normal error of the fill against the ground truth (hole regions)",
            temporal_consistency,
            level="sequence",
        ),
    ]
}, group="dpcbench.metrics", check=_check_metric)

#: What a run costs, measured by the harness around the method (not computed here).
RESOURCE_METRICS: dict[str, Metric] = {
    m.name: m
    for m in [
        _m("time_s", False, "s", "inpainting time per frame (a sequence method's total divided by its frames)",
           None, level="run"),
        _m("cpu_time_s", False, "s", "inpainting CPU time (user + system, all threads) per frame (a sequence "
           "method's total divided by its frames)", None, level="run"),
        _m("peak_mem_mb", False, "MB", "peak resident memory of the run's worker process, interpreter included",
           None, level="run"),
    ]
}

#: Facts about the damaged input, stored beside the scores: compared and shown, never gated.
INPUT_METRICS: dict[str, Metric] = {
    m.name: m
    for m in [
        _m("removed_fraction", None, "1", "share of the frame's points the hole generator removed", None,
           level="input"),
    ]
}

#: The colour metrics (`metrics.colour`): computed only when both clouds carry colours.
COLOUR_METRICS: tuple[str, ...] = ("cpsnr_y", "cpsnr_u", "cpsnr_v", "cpsnr_r", "cpsnr_g", "cpsnr_b", "cpsnr_rgb")
#: What `dpcbench score` adds to its defaults when both clouds have colours.
DEFAULT_COLOUR_METRICS: tuple[str, ...] = ("cpsnr_y", "cpsnr_u", "cpsnr_v")

#: What `score_frame` computes when no metric is named (the keys of `dpcbench score --json`).
DEFAULT_METRICS: tuple[str, ...] = ("gpsnr_d1", "gpsnr_d2", "nshd", "hausdorff", "chamfer", "fscore")


def get_metric(name: str) -> Metric:
    """The registered quality metric ``name``; KeyError listing the valid names otherwise."""
    if name not in METRICS:
        raise KeyError(f"unknown metric {name!r}; available: {', '.join(METRICS)}")
    return METRICS[name]


def describe(name: str) -> Metric | None:
    """The facts of any stored metric (quality, resource or input), None for a name none of the
    three families has (e.g. a metric of a newer code version read from an old store)."""
    try:
        found = METRICS.get(name)
    except ImportError:  # a plug-in metric that does not load here: no facts
        found = None
    return found or RESOURCE_METRICS.get(name) or INPUT_METRICS.get(name)
