"""Display names of metrics for tables, figures and the dashboard."""

from __future__ import annotations

#: display names; the unit is metrics.registry's (`metric_label`)
METRIC_NAMES = {
    "gpsnr_d1": "GPSNR D1", "gpsnr_d2": "GPSNR D2", "nshd": "NSHD", "hausdorff": "Hausdorff",
    "chamfer": "Chamfer", "fscore": "F-score", "temporal_consistency": "temporal consistency",
    "time_s": "time per frame", "cpu_time_s": "CPU time per frame", "peak_mem_mb": "peak memory",
    "cpsnr_y": "colour PSNR Y", "cpsnr_u": "colour PSNR Cb", "cpsnr_v": "colour PSNR Cr",
    "cpsnr_r": "colour PSNR R", "cpsnr_g": "colour PSNR G", "cpsnr_b": "colour PSNR B", "cpsnr_rgb": "colour PSNR RGB",
}
#: units written after a metric's name (the others are ratios or the data's own length units)
SHOWN_UNITS = ("dB", "s", "MB")


def metric_label(metric: str) -> str:
    """A column or panel title: the display name, with the registry's unit when it is dB, s or MB."""
    from dpcbench.metrics.registry import describe

    entry = describe(metric)
    name = METRIC_NAMES.get(metric, metric)
    return f"{name} ({entry.unit})" if entry is not None and entry.unit in SHOWN_UNITS else name
