"""Figures for reports (matplotlib, Agg backend, PNG): bar charts of comparison tables, per-frame
curves, and the paper-style subjective figures (Fig. 3: real/detected holes; Fig. 4: synthetic holes),
which draw point clouds through `bench.reporting.render.render_zoom_grid`.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")  # before pyplot is imported (no display on servers): hence the E402s below
# labels are user text (sequence and method names, "$HOME"), never TeX: a "$...$" must print as written
matplotlib.rcParams["text.parse_math"] = False
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from dpcbench.bench.reporting import palette  # noqa: E402
from dpcbench.bench.reporting.tables import ComparisonTable, frame_values  # noqa: E402
from dpcbench.metrics.neighbours import median_neighbour_distance  # noqa: E402


def bar_chart(table: ComparisonTable, out_png: str | Path, *, subtitle: str = "", names: dict[str, str] | None = None,
              width_in: float | None = None) -> Path:
    """Grouped bars for print (one group per table row, one bar per column) with the cells' 95%
    intervals (`ComparisonTable.interval`, clipped at the metric's lower bound 0 for distances and
    NSHD); the floor column (`table.floor`, no fill) is a dashed black line across each group rather
    than a bar, and a bar below it carries the table's floor mark. The paper's values, when the table
    has them, are a second panel on the same y scale (its own, said in its title, when the two ranges
    differ by more than 4x). Rows with names over `MAX_TICK_CHARS` are lettered, with a key below. Colours follow the methods' registry names
    (``names``: column label -> registry name; default: the label up to " ("), `bench.reporting.palette`.
    Written as PNG (300 dpi) and PDF beside it, at double-column width unless ``width_in``."""
    from dpcbench.bench.reporting.labels import metric_label
    from dpcbench.bench.reporting.tables import FLOOR_MARK

    names = names or {}
    columns = [c for c in table.columns if c != table.floor]
    colours = palette.configuration_colours((c, names.get(c, c.split(" (")[0])) for c in columns)
    panels = [("this run", table.rows)]
    if table.paper:
        panels.append(("paper (published)", list(table.paper)))
    lower_bound = 0.0 if table.metric in ("nshd", "hausdorff", "chamfer") else -math.inf
    width_in = width_in or DOUBLE_COLUMN_IN
    with plt.rc_context(print_style()):
        # one y scale for both panels, unless the paper's values dwarf this run's (stand-ins' NSHD is 100x
        # smaller): then each panel has its own, said in its title
        ours_max = max((abs(v) * table.scale for v in table.mean.values() if math.isfinite(v)), default=0.0)
        paper_max = max((abs(v) for row in (table.paper or {}).values() for v in row.values()), default=0.0)
        shared = not table.paper or (ours_max > 0 and paper_max > 0 and max(ours_max, paper_max) / min(
            ours_max, paper_max) <= 4.0)
        fig, axes = plt.subplots(1, len(panels), figsize=(width_in, 2.9), squeeze=False, sharey=shared,
                                 gridspec_kw={"width_ratios": [max(1, len(rows)) * (1.0 if source == "this run" else 0.8)
                                                               for source, rows in panels]})
        width = 0.8 / max(1, len(columns))
        cap = psnr_cap(table.metric)
        capped_any = cut_any = False
        for ax, (source, rows) in zip(axes[0], panels):
            drawn: list[tuple[float, float]] = []  # (x, mean) of every bar of this panel
            ends: list[float] = []  # the interval ends of this panel's bars
            x = np.arange(len(rows))
            for k, col in enumerate(columns):
                means, low, high = [], [], []
                for r in rows:
                    if source == "this run":
                        m = table.mean.get((r, col))
                        lo, hi = table.interval(r, col) if m is not None else (math.nan, math.nan)
                        m, lo, hi = (math.nan if v is None else v * table.scale for v in (m, lo, hi))
                    else:
                        m = table.paper[r].get(col, math.nan) if table.paper else math.nan
                        lo = hi = math.nan
                    lo = max(lo, lower_bound) if not math.isnan(lo) else lo
                    means.append(m)
                    low.append(0.0 if math.isnan(lo) else m - lo)
                    high.append(0.0 if math.isnan(hi) else hi - m)
                offsets = x + (k - (len(columns) - 1) / 2) * width
                ax.bar(offsets, means, width, yerr=[low, high] if source == "this run" else None, label=col,
                       color=colours[col], hatch="//" if source != "this run" else None, capsize=1.5,
                       edgecolor="black", linewidth=0.3, error_kw={"linewidth": 0.6})
                drawn += list(zip(offsets, means))
                ends += [m - d for m, d in zip(means, low)] + [m + d for m, d in zip(means, high)]
                if source == "this run":
                    for xo, r, m in zip(offsets, rows, means):
                        if table.below_floor(r, col):
                            ax.annotate(FLOOR_MARK, (xo, m), ha="center", va="bottom", fontsize=MIN_TEXT_PT)
            capped, cut = _limit_bar_panel(ax, drawn, ends, cap)
            capped_any, cut_any = capped_any or capped, cut_any or cut
            if source == "this run" and table.floor:
                for i, r in enumerate(rows):
                    f = table.mean.get((r, table.floor))
                    if f is not None:
                        ax.hlines(f * table.scale, i - 0.45, i + 0.45, colors="black", linestyles="--", linewidth=1.0,
                                  label=table.floor if i == 0 else None)
            ax.set_xticks(x)
            if source == "this run":
                ax.set_xticklabels(tick_labels(rows)[0])
            else:
                ax.set_xticklabels(rows, rotation=30, ha="right")
            ax.set_title(source + ("" if shared else " (own y scale)"), loc="left")
            ax.grid(axis="y", alpha=0.3)
        scale = f" (x{1 / table.scale:.0e})".replace("e-0", "e-") if table.scale != 1 else ""
        for ax in axes[0] if not shared else axes[0][:1]:
            ax.set_ylabel(metric_label(table.metric) + scale)
        handles, labels = axes[0][0].get_legend_handles_labels()
        fig.suptitle(table.title + (f"\n{subtitle}" if subtitle else ""))
        fig.tight_layout()
        key_lines = [cap_note(cap)] if capped_any and cap is not None else []
        if cut_any:
            key_lines.append("An interval reaching past the axis is cut at its edge.")
        # a legend only of labelled artists: one without any draws an empty box (and, called without
        # handles, warns "No artists with labels found")
        legend = None
        if handles:
            legend = fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=3, frameon=False)
        key = key_lines + tick_labels(table.rows)[1]
        if key:  # the rows' full names under the legend, for the short tick labels (and the cap's mark)
            fig.canvas.draw()
            bottom = 0.0 if legend is None else legend.get_window_extent().transformed(fig.transFigure.inverted()).y0
            fig.text(0.02, bottom - 0.02, "\n".join(_wrap(line, 130) for line in key), ha="left", va="top",
                     fontsize=MIN_TEXT_PT)
        return save_figure(fig, out_png)


#: tick labels longer than this are replaced by letters, with a key of the full names under the figure
MAX_TICK_CHARS = 14


def tick_labels(rows: list[str]) -> tuple[list[str], list[str]]:
    """(tick labels, key lines): the rows themselves when every one is at most `MAX_TICK_CHARS` long,
    else the letters A, B, ... and the key ["A: <row>", ...]."""
    if all(len(str(r)) <= MAX_TICK_CHARS for r in rows):
        return [str(r) for r in rows], []
    letters = [chr(ord("A") + i) if i < 26 else f"R{i + 1}" for i in range(len(rows))]
    return letters, [f"{letter}: {row}" for letter, row in zip(letters, rows)]


def _wrap(text: str, width: int) -> str:
    """``text`` broken into lines of at most ``width`` characters (at spaces)."""
    import textwrap

    return "\n".join(textwrap.wrap(str(text), width)) or str(text)


#: the mark of a value at the PSNR cap (the result equals the reference), drawn at the top of its axis
CAP_MARK = "▲"


def psnr_cap(metric: str) -> float | None:
    """The value a PSNR metric is capped at when the result equals the reference (`metrics.scoring`'s
    ``DEFAULT_MAX_PSNR``, 200 dB), None for a metric that is no PSNR."""
    from dpcbench.metrics.registry import describe
    from dpcbench.metrics.scoring import DEFAULT_MAX_PSNR

    entry = describe(metric)
    return DEFAULT_MAX_PSNR if entry is not None and entry.unit == "dB" else None


def capped_limits(values, cap: float | None, *, from_zero: bool) -> tuple[float, float] | None:
    """y limits of a curve panel that leave capped values out of the scale: None unless some of ``values``
    reach ``cap`` (one 200 dB frame squashes every other value into the bottom tenth), else (bottom, top)
    around the finite values below the cap, 12% padding, from 0 when ``from_zero``. The capped values are
    drawn at the top with a triangle."""
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if cap is None or not any(v >= cap for v in vals):
        return None
    below = [v for v in vals if v < cap]
    if not below:
        return None
    lo, hi = min(below), max(below)
    pad = 0.12 * ((hi - lo) or abs(hi) or 1.0)
    bottom = min(0.0, lo - pad) if from_zero else lo - pad
    return bottom, hi + pad


def bar_limits(means, lows, highs, cap: float | None) -> tuple[float, float] | None:
    """y limits of a bar panel when its intervals or a capped bar would set the scale, else None (matplotlib's).

    The bars (``means`` below ``cap``) and 0 set the range R; the axis reaches 25% of R beyond them, and an
    interval (``lows``, ``highs``: its ends) reaching farther is cut at the axis edge: the intervals of a mean
    over frames of which some equal the reference (200 dB) span hundreds of dB and would flatten every bar.
    A bar at the cap is drawn at the top with `CAP_MARK`."""
    finite = [float(m) for m in means if m is not None and math.isfinite(float(m))]
    bars = [m for m in finite if cap is None or m < cap]
    if not bars:
        return None
    bottom_bar, top_bar = min(0.0, min(bars)), max(0.0, max(bars))
    reach = 0.25 * ((top_bar - bottom_bar) or 1.0)
    ends = [float(v) for v in (*lows, *highs) if v is not None and math.isfinite(float(v))]
    capped = cap is not None and any(m >= cap for m in finite)
    if not capped and all(bottom_bar - reach <= v <= top_bar + reach for v in ends):
        return None
    low_end = min(ends, default=bottom_bar)
    return (bottom_bar if low_end >= bottom_bar else max(low_end, bottom_bar - reach)), top_bar + reach


def _limit_bar_panel(ax, drawn: list[tuple[float, float]], ends: list[float], cap: float | None) -> tuple[bool, bool]:
    """Apply `bar_limits` to one bar panel (``drawn``: (x, mean) per bar; ``ends``: the interval ends) and mark
    the capped bars at the top; (any bar capped, any interval cut)."""
    limits = bar_limits([m for _, m in drawn], ends, [], cap)
    if limits is None:
        return False, False
    ax.set_ylim(*limits)
    capped = False
    for xo, m in drawn:
        if cap is not None and math.isfinite(m) and m >= cap:
            capped = True
            ax.annotate(CAP_MARK, (xo, limits[1]), ha="center", va="top", fontsize=MIN_TEXT_PT, annotation_clip=False)
    return capped, any(v < limits[0] or v > limits[1] for v in ends if math.isfinite(v))


def cap_note(cap: float) -> str:
    """The line saying what `CAP_MARK` means."""
    return f"{CAP_MARK} at the top: the result equals the reference there (PSNR capped at {cap:g} dB)"


#: print widths (inches) of an IEEE-style page: one column and the full text width
SINGLE_COLUMN_IN = 3.5
DOUBLE_COLUMN_IN = 7.2
#: figures are written at this resolution (PNG) and as vector PDF beside it
PRINT_DPI = 300
#: the smallest text size at print width (points)
MIN_TEXT_PT = 7
#: metrics shown in a scaled unit, as the tables show them (NSHD in units of 1e-7, like the paper's Table 2)
DISPLAY_SCALE = {"nshd": 1e7}


def print_style() -> dict:
    """matplotlib rc settings for figures printed at page width: text at least `MIN_TEXT_PT` points."""
    return {"font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "xtick.labelsize": MIN_TEXT_PT,
            "ytick.labelsize": MIN_TEXT_PT, "legend.fontsize": MIN_TEXT_PT, "figure.titlesize": 9,
            "axes.spines.top": False, "axes.spines.right": False, "pdf.fonttype": 42}


def column_colours(sel: pd.DataFrame, columns: list[str]) -> dict[str, str]:
    """A colour per column label from `bench.reporting.palette`, by the registry name of the method behind it
    (``sel`` has the ``column`` and ``method`` columns)."""
    name_of = sel.drop_duplicates("column").set_index("column")["method"].to_dict() if "method" in sel else {}
    return palette.configuration_colours((c, str(name_of.get(c, c))) for c in columns)


def save_figure(fig, out_png: str | Path) -> Path:
    """Write ``fig`` as PNG (`PRINT_DPI`) and, beside it, as vector PDF (same stem)."""
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=PRINT_DPI, bbox_inches="tight")
    fig.savefig(out.with_suffix(".pdf"), bbox_inches="tight")
    plt.close(fig)
    return out


def per_frame_curves(df: pd.DataFrame, metric: str, scope: str, peak: str, out_png: str | Path, *,
                     column_of=None, columns: list[str] | None = None, title: str = "",
                     width_in: float = DOUBLE_COLUMN_IN) -> Path:
    """One panel per sequence row, in a grid of two columns at double-column width (one at single-column
    width): the metric against frame index, one line per method (mean over seeds), coloured by method
    (`bench.reporting.palette`), the no-fill floor (method ``none``) dashed black. Lines that coincide stay visible
    (distinct markers, decreasing line widths); the legend sits below the panels, outside the data."""
    from dpcbench.bench.reporting.labels import metric_label
    from dpcbench.bench.reporting.tables import method_labels

    sel = frame_values(df, metric, scope, peak).copy()
    sel["column"] = column_of(sel) if column_of else method_labels(sel)
    sequences = list(dict.fromkeys(sel["sequence"]))
    columns = columns or list(dict.fromkeys(sel["column"]))
    colours = column_colours(sel, columns)
    scale = DISPLAY_SCALE.get(metric, 1.0)
    unit = f" (x{1 / scale:.0e})".replace("e-0", "e-") if scale != 1 else ""
    ncols = 1 if width_in <= SINGLE_COLUMN_IN else min(2, max(1, len(sequences)))
    nrows = max(1, -(-len(sequences) // ncols))
    markers = "osD^vP*Xh<>"
    with plt.rc_context(print_style()):
        fig, axes = plt.subplots(nrows, ncols, figsize=(width_in, 1.9 * nrows + 0.6), squeeze=False)
        for ax in axes.flat[len(sequences):]:
            ax.set_visible(False)
        method_of = sel.drop_duplicates("column").set_index("column")["method"].to_dict() if "method" in sel else {}
        cap = psnr_cap(metric)
        capped_any = False
        # about 16 characters of 8 pt title text per inch of panel: a longer title wraps instead of
        # running into its neighbour's
        title_chars = max(20, int(16 * width_in / ncols))
        for ax, seq in zip(axes.flat, sequences):
            panel_values = []
            for k, col in enumerate(columns):
                curve = sel[(sel["sequence"] == seq) & (sel["column"] == col)].groupby("frame")["value"].mean()
                if curve.empty:
                    continue
                floor = method_of.get(col) == "none"
                ax.plot(curve.index, curve.values * scale, marker=markers[k % len(markers)], ms=3.5 - 0.2 * k,
                        linewidth=max(0.6, 1.6 - 0.15 * k), linestyle="--" if floor else "-",
                        color=colours[col], label=col, markerfacecolor="white" if k % 2 else colours[col])
                panel_values.append((curve, colours[col]))
            limits = capped_limits([v * scale for curve, _ in panel_values for v in curve.values], cap, from_zero=False)
            if limits is not None and cap is not None:
                ax.set_ylim(*limits)
                for curve, colour in panel_values:
                    at_cap = curve[curve.values * scale >= cap]
                    if len(at_cap):
                        capped_any = True
                        ax.plot(at_cap.index, np.full(len(at_cap), limits[1]), linestyle="none", marker="^", ms=4,
                                color=colour, clip_on=False)
            ax.set_title(_wrap(seq, title_chars), loc="left")
            ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
            ax.yaxis.get_major_formatter().set_useOffset(False)
            ax.set_xlabel("frame")
            ax.set_ylabel(metric_label(metric) + unit + (f", peak {peak}" if peak else ""))
            ax.grid(alpha=0.3)
        handles, labels = [], []
        for ax in axes.flat:
            for h, lab in zip(*ax.get_legend_handles_labels()):
                if lab not in labels:
                    handles.append(h)
                    labels.append(lab)
        fig.suptitle(title or f"{metric_label(metric)} per frame ({'whole frame' if scope == 'frame' else 'holes'})")
        fig.tight_layout()
        legend = None
        if handles:
            legend = fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                                ncol=min(len(labels), 3 if width_in <= SINGLE_COLUMN_IN else 4), frameon=False)
        if capped_any and cap is not None:
            fig.canvas.draw()
            bottom = 0.0 if legend is None else legend.get_window_extent().transformed(fig.transFigure.inverted()).y0
            fig.text(0.02, bottom - 0.01, cap_note(cap), ha="left", va="top",
                     fontsize=MIN_TEXT_PT)
        return save_figure(fig, out_png)


def facing_view(points: np.ndarray, center: np.ndarray) -> tuple[float, float]:
    """(azimuth, elevation) of a `bench.reporting.render` view that faces ``center`` from outside the cloud:
    the direction from the cloud's centroid to ``center`` (y is up; elevation clipped to ±60°: a
    hole on the crown or the shoulders faces the viewer (at ±30° the crown hole of Fig. 3 was seen
    edge-on) and the figure stays recognisable)."""
    return view_along(np.asarray(center, float) - points.mean(axis=0), max_elevation=60.0)


def view_along(direction: np.ndarray, max_elevation: float = 90.0) -> tuple[float, float]:
    """(azimuth, elevation) of a `bench.reporting.render` view whose viewer sits in ``direction`` (3,) from
    what it looks at (y is up; elevation clipped to +-``max_elevation`` degrees)."""
    d = np.asarray(direction, float)
    azimuth = -float(np.degrees(np.arctan2(d[0], d[2])))
    elevation = float(np.clip(np.degrees(np.arctan2(d[1], np.hypot(d[0], d[2]))), -max_elevation, max_elevation))
    return (azimuth, elevation)


def hole_view(points: np.ndarray, region) -> tuple[float, float]:
    """(azimuth, elevation) that looks straight into a hole region: along the normal of the surface
    around it (the least principal axis of the points of ``points`` within 1.5 bounding radii of its
    centre), on the side away from the cloud's centroid. `facing_view` (the centroid's direction)
    sees a hole on the side of a limb edge-on; the local normal does not. `facing_view` when fewer
    than 10 points are that near."""
    points = np.asarray(points, float)
    centre = np.asarray(region.center, float)
    near = points[np.linalg.norm(points - centre, axis=1) <= 1.5 * region.bounding_radius]
    if len(near) < 10:
        return facing_view(points, centre)
    normal = np.linalg.eigh(np.cov(near.T))[1][:, 0]
    if normal @ (centre - points.mean(axis=0)) < 0:
        normal = -normal
    return view_along(normal)


def flattest_region(points: np.ndarray, regions: list) -> int:
    """Index of the region whose points (of ``points``, (N, 3)) lie closest to a plane: the smallest
    lambda_min / (lambda_1 + lambda_2 + lambda_3) of their covariance (regions with fewer than 10
    points count as not flat). A hole cut into an open surface patch (a torso) reads as a hole from
    one viewpoint; one that wraps around a thin limb (a ball through an ankle) does not. 0 when no
    region has 10 points."""
    best, best_score = 0, np.inf
    for i, region in enumerate(regions):
        inside = np.asarray(points)[region.contains(points)]
        if len(inside) < 10:
            continue
        eig = np.linalg.eigvalsh(np.cov(inside.T))
        score = float(eig[0] / max(eig.sum(), 1e-300))
        if score < best_score:
            best, best_score = i, score
    return best


def zoom_box(regions: list, pad: float = 1.3) -> tuple:
    """An axis-aligned box (x0, y0, z0, x1, y1, z1) around hole regions (their bounding balls grown by ``pad``)."""
    lo = np.min([r.center - pad * r.bounding_radius for r in regions], axis=0)
    hi = np.max([r.center + pad * r.bounding_radius for r in regions], axis=0)
    return tuple(lo) + tuple(hi)


def subjective_grid(columns: list[tuple[str, list[np.ndarray]]], frame_labels: list[str], out_png: str | Path, *,
                    hole_regions: list[list] | None = None, column_colours: list | None = None,
                    highlight_from_column: int = 2, view=None, title: str = "",
                    width_in: float = DOUBLE_COLUMN_IN):
    """A paper-style subjective figure (Fig. 3/4): one column per (label, frames) entry (ground truth,
    with holes, then every method), in the order given, titled in ``column_colours`` (None: black);
    per frame a row of whole bodies shaded by normals, then one zoom row per hole region of that
    frame: the hole magnified in every column, seen straight on from outside the body (`hole_view`)
    (`bench.reporting.render.render_zoom_grid`). Returns its `bench.reporting.render.ComparisonFigure`.

    hole_regions:          per frame, its hole regions: each one outlined, numbered and magnified,
                           and its points tinted red in the columns from ``highlight_from_column``
                           on (default 2: not in the ground truth nor the damaged input). One
                           magnification for every zoom: a square of side 2 x 2 x the largest region's
                           bounding radius (at least 16 point spacings of the first column's first frame).
    view:                  of the body rows; None = facing the flattest hole of the first frame that
                           has one (`flattest_region`).
    Printed ``width_in`` wide (PNG at `PRINT_DPI` and PDF), text at `MIN_TEXT_PT` or more.
    """
    from dpcbench.bench.reporting.render import Zoom, render_zoom_grid
    from dpcbench.holes.regions import union_mask

    n_frames = len(frame_labels)
    if not columns or any(len(frames) != n_frames for _, frames in columns):
        raise ValueError(f"columns: give (label, frames) entries with one frame per frame label ({n_frames})")
    hole_regions = [list(r or []) for r in hole_regions] if hole_regions is not None else [[] for _ in range(n_frames)]
    if len(hole_regions) != n_frames:
        raise ValueError(f"hole_regions: give one list of regions per frame ({n_frames}), got {len(hole_regions)}")
    grid = [[np.asarray(frames[f], float) for _, frames in columns] for f in range(n_frames)]
    highlight = [[union_mask(hole_regions[f], grid[f][c]) if hole_regions[f] and c >= highlight_from_column
                  else None for c in range(len(columns))] for f in range(n_frames)]
    first = grid[0][0]
    spacing = median_neighbour_distance(first, sample=None) if len(first) > 1 else 1.0
    present = [z for regions in hole_regions for z in regions]
    half = max([2.0 * z.bounding_radius for z in present] + [8.0 * spacing])
    if view is None:
        f = next((f for f in range(n_frames) if hole_regions[f]), None)
        view = "front" if f is None else facing_view(
            grid[f][0], hole_regions[f][flattest_region(grid[f][0], hole_regions[f])].center)
    zooms = [[Zoom(np.asarray(z.center, float), hole_view(grid[f][0], z)) for z in hole_regions[f]]
             for f in range(n_frames)]
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    return render_zoom_grid(grid, out, column_labels=[label for label, _ in columns], row_labels=list(frame_labels),
                            zooms=zooms, zoom_half=half, highlight=highlight, view=view, shading="normal",
                            column_colours=column_colours, width_in=width_in, dpi=PRINT_DPI, title=title or None)
