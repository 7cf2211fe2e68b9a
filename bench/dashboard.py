"""The regression dashboard: one self-contained static HTML page (`dpcbench dashboard`).

Input: the results store's tidy table (one or several stores, concatenated), optionally its runs
table, a baseline summary, and pytest-benchmark runs (`bench.benchsuite`). Output: an HTML file
with inline CSS and inline SVG charts (matplotlib, text kept as text) and no script, link or
request to anything outside the file, so it opens from disk, from a CI artifact, or by mail.

Sections:
  cards        commits tracked, runs done/failed, regressions in the latest comparison, benchmarks
  comparison   the newest code version against the previous one (or against a baseline summary):
               every row beyond tolerance first (REGRESSED rows in red), the full table folded
  quality      per (sequence, holes): rows = scopes, columns = quality metrics, x = code versions
               in time order, one line per method configuration (same colour everywhere), the
               paper's value as a dashed line where the sequence is one of the paper's
  paper        temporal-graph's gains over the paper's other columns beside the paper's own
  latest       the newest code version's means per method (best per column in bold)
  speed        wall and CPU time per frame over code versions (from the store) and the pytest-benchmark
               history (median seconds per session, log scale) with the newest figures
  runs         code versions with their dates, run counts and the runs' summed wall and CPU time
               (the runs table; "-" where no run recorded CPU time), and failed runs with their messages

A code version is the store's ``code_version`` (git commit); versions are ordered by the time of
their first run. Summaries come from `bench.compare.summarize`, one per code version.

Code: `prepare_page` computes what the sections share (the history, colours, latest comparison)
into a `Page`; each section is one function of it (`cards_section`, `comparison_section`,
`quality_section`, `paper_section`, `latest_section`, `speed_section`, `runs_section`; `SECTIONS`
lists them in page order); `render_dashboard` joins them. The style sheet is the package data file
bench/static/dashboard.css, inlined (`stylesheet`). The paper's values come from `bench.paper_facts`.
"""

from __future__ import annotations

import datetime as _dt
import html
import io
import math
import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import pandas as pd

from dpcbench.bench import compare
from dpcbench.bench.paper_facts import PAPER_SEQUENCES
from dpcbench.bench.tables import FLOOR_MARK, FLOOR_METHOD
from dpcbench.metrics import registry as _registry

QUALITY_ORDER = ["gpsnr_d1", "gpsnr_d2", "nshd", "hausdorff", "chamfer", "fscore", "temporal_consistency"]
#: display names; the unit is metrics.registry's (`metric_label`)
METRIC_NAMES = {
    "gpsnr_d1": "GPSNR D1", "gpsnr_d2": "GPSNR D2", "nshd": "NSHD", "hausdorff": "Hausdorff",
    "chamfer": "Chamfer", "fscore": "F-score", "temporal_consistency": "temporal consistency",
    "time_s": "time per frame", "cpu_time_s": "CPU time per frame", "peak_mem_mb": "peak memory",
}
#: units written after a metric's name (the others are ratios or the data's own length units)
SHOWN_UNITS = ("dB", "s", "MB")
#: the methods of the paper's columns first, so that their colours never change when other methods come and go
METHOD_ORDER = ["temporal-graph", "fu-nonlocal", "lozes-pde", "meshlab", "temporal-copy", "none"]
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf"]


def metric_label(metric: str) -> str:
    """A column or panel title: the display name, with the registry's unit when it is dB, s or MB."""
    from dpcbench.metrics.registry import describe

    entry = describe(metric)
    name = METRIC_NAMES.get(metric, metric)
    return f"{name} ({entry.unit})" if entry is not None and entry.unit in SHOWN_UNITS else name


def paper_reference() -> pd.DataFrame:
    """The paper's values as rows (sequence, method, metric, value, source); metric gpsnr_d1 / nshd.

    From `bench.paper_facts` (Tables 1-2), with each paper column mapped to the registry method of
    `bench.paper.PAPER_METHODS`. The paper's GPSNR is plotted against our gpsnr_d1 (point-to-point,
    as pc_error's D1), and its NSHD (printed x1e-7) against our nshd.
    """
    from dpcbench.bench import paper_facts
    from dpcbench.bench.paper import PAPER_METHODS

    methods = [name for name, _, _ in PAPER_METHODS]
    name_of = {label: name for name, label in paper_facts.PAPER_SEQUENCES.items()}
    rows = []
    for metric, table, scale in (("gpsnr_d1", paper_facts.TABLE1_GPSNR, 1.0),
                                 ("nshd", paper_facts.TABLE2_NSHD_E7, paper_facts.NSHD_SCALE)):
        for label, values in table.items():
            for method, value in zip(methods, values):
                rows.append({"sequence": name_of[label], "method": method, "metric": metric,
                             "value": float(value) * scale, "source": "dpcbench.bench.paper_facts"})
    return pd.DataFrame(rows, columns=["sequence", "method", "metric", "value", "source"])


# ---------------------------------------------------------------------------------------------
# data preparation
@dataclass
class History:
    """Summaries per code version.

    versions: code versions, oldest first (by their first run).
    table:    `compare.summarize` rows per version plus columns code_version, label (method + short
              params) and measured. The state at version v is cumulative: each cell's newest run
              among the runs of versions up to v, so a sweep that spans several commits (or reruns
              only some cells) still shows every cell; ``measured`` is True where the cell was run
              at v itself, False where its value is carried over from an earlier version.
    """

    versions: list[str]
    version_dates: dict[str, str]
    table: pd.DataFrame


def summary_as_results(summary: pd.DataFrame, meta: dict, *, run_prefix: str = "summary") -> pd.DataFrame:
    """A summary file's rows as store-shaped results (one value per cell: its mean), so a committed
    baseline can join the history as one code version (its std and frame count are not kept)."""
    version = str(meta.get("code_version") or "unknown").split(",")[-1]
    rows = summary.assign(
        run_id=[f"{run_prefix}:{s}|{h}|{hp}|{m}|{mp}" for s, h, hp, m, mp in
                zip(summary["sequence"], summary["holes"], summary["holes_params"], summary["method"],
                    summary["method_params"])],
        experiment=str(meta.get("experiment", "")), seed=0, method_version="", code_version=version,
        frame=0, value=summary["mean"], created_at=str(meta.get("date", "")))
    return rows.drop(columns=["mean", "std", "n_frames"])


def short_version(version: str) -> str:
    """'0123456789abcdef...+dirty' -> '01234567+' (a trailing + marks uncommitted changes)."""
    version = str(version)
    match = re.fullmatch(r"(.*?)[+-]dirty", version)
    dirty = match is not None
    core = match.group(1) if dirty else version
    short = core[:8] if re.fullmatch(r"[0-9a-f]{9,}", core) else core[:12]
    return short + ("+" if dirty else "")


def method_label(method: str, params_json: str) -> str:
    return method if params_json in ("", "{}") else f"{method} ({compare.short_params(params_json, 32)})"


def build_history(results: pd.DataFrame) -> History:
    """Summarize the results table at each code version (see History)."""
    columns = compare.SUMMARY_COLUMNS + ["code_version", "label", "measured"]
    if results.empty:
        return History([], {}, pd.DataFrame(columns=columns))
    results = results.copy()
    results["code_version"] = results["code_version"].fillna("unknown").astype(str)
    first_seen = results.groupby("code_version")["created_at"].min().sort_values()
    versions = list(first_seen.index)
    parts = []
    for i, version in enumerate(versions):
        summary = compare.summarize(results[results["code_version"].isin(versions[: i + 1])])
        own = compare.summarize(results, code_version=version)[compare.KEY_COLUMNS]
        summary = summary.merge(own.assign(measured=True), on=compare.KEY_COLUMNS, how="left")
        summary["measured"] = summary["measured"].astype("boolean").fillna(False).astype(bool)
        summary["code_version"] = version
        parts.append(summary)
    table = pd.concat(parts, ignore_index=True)
    table["label"] = [method_label(m, p) for m, p in zip(table["method"], table["method_params"])]
    dates = {v: str(first_seen[v])[:16].replace("T", " ") for v in versions}
    return History(versions, dates, table[columns])


def method_colours(labels) -> dict[str, str]:
    """A fixed colour per method configuration: the paper's methods first, then by name."""
    def rank(label: str):
        method = label.split(" (")[0]
        return (METHOD_ORDER.index(method) if method in METHOD_ORDER else len(METHOD_ORDER), label)

    ordered = sorted(set(labels), key=rank)
    return {label: PALETTE[i % len(PALETTE)] for i, label in enumerate(ordered)}


# ---------------------------------------------------------------------------------------------
# charts (matplotlib -> inline SVG)
def _svg(fig) -> str:
    """The figure as an inline <svg> element scaled to its container."""
    import matplotlib.pyplot as plt

    buffer = io.StringIO()
    fig.savefig(buffer, format="svg", bbox_inches="tight")
    plt.close(fig)
    text = buffer.getvalue()
    text = text[text.index("<svg"):]  # drop the XML declaration and DOCTYPE: invalid inside HTML
    # natural size as max-width: charts shrink with the window but never blow up past their design size
    return re.sub(r'<svg([^>]*?) width="([0-9.]+)pt" height="[^"]*"', r'<svg\1 class="chart" style="max-width:\2pt"',
                  text, count=1)


def _matplotlib():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({
        "svg.fonttype": "none",  # text stays text: searchable and crisp in the page
        "svg.hashsalt": "dpcbench",  # deterministic element ids
        "font.size": 9, "axes.spines.top": False, "axes.spines.right": False,
        "axes.grid": True, "grid.color": "#e5e7eb", "grid.linewidth": 0.6,
        "axes.edgecolor": "#9ca3af", "axes.titlesize": 10, "axes.titleweight": "bold",
    })
    return plt


def _seconds_axis(axis) -> None:
    """Plain numbers (0.01, 0.5, 20) on a log axis of seconds instead of powers of ten."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _plot_line(ax, line: pd.DataFrame, colour: str, linestyle: str = "-", label: str | None = None) -> None:
    """One method's values over versions: filled markers where measured at that version, hollow
    where carried over from an earlier one."""
    ax.plot(line["x"], line["mean"], color=colour, linewidth=1.6, linestyle=linestyle, label=label, marker="o",
            markersize=4, markevery=[i for i, m in enumerate(line["measured"]) if m] or None)
    carried = line[~line["measured"].astype(bool)]
    if len(carried):
        ax.plot(carried["x"], carried["mean"], linestyle="none", marker="o", markersize=4.5,
                markerfacecolor="white", markeredgecolor=colour)


def quality_chart(history: History, sequence: str, holes: str, holes_params: str, metrics: list[str],
                  colours: dict[str, str], paper: pd.DataFrame) -> str:
    """rows = scopes, columns = metrics; x = code versions; one line per method configuration."""
    plt = _matplotlib()
    sub = history.table[(history.table["sequence"] == sequence) & (history.table["holes"] == holes)
                        & (history.table["holes_params"] == holes_params)]
    scopes = [s for s in ("frame", "holes") if s in set(sub["scope"])] + \
        sorted(set(sub["scope"]) - {"frame", "holes"})
    x_of = {v: i for i, v in enumerate(history.versions)}
    fig, axes = plt.subplots(len(scopes), len(metrics), figsize=(3.3 * len(metrics), 2.5 * len(scopes) + 0.5),
                             squeeze=False)
    paper_rows = paper[paper["sequence"] == sequence.lower()]
    for r, scope in enumerate(scopes):
        for c, metric in enumerate(metrics):
            ax = axes[r][c]
            cell = sub[(sub["scope"] == scope) & (sub["metric"] == metric)]
            for label, rows in cell.groupby("label", sort=False):
                rows = rows.assign(x=rows["code_version"].map(x_of)).sort_values("x")
                for peak, line in rows.groupby("peak"):
                    _plot_line(ax, line, colours[label], linestyle="-" if peak in ("", "intrinsic") else ":")
            for _, ref in paper_rows[paper_rows["metric"] == metric].iterrows():
                colour = next((v for k, v in colours.items() if k.split(" (")[0] == ref["method"]), "#6b7280")
                ax.axhline(ref["value"], color=colour, linestyle="--", linewidth=0.9, alpha=0.7)
            if metric in ("nshd", "hausdorff", "chamfer") and (cell["mean"] > 0).all() and len(cell):
                ax.set_yscale("log")
            ax.set_xticks(range(len(history.versions)))
            ax.set_xticklabels([short_version(v) for v in history.versions], rotation=30, ha="right",
                               fontsize=7.5)
            ax.set_xlim(-0.4, max(len(history.versions) - 0.6, 0.4))
            ax.set_title(f"{metric_label(metric)} · {scope}", loc="left")
    handles = [plt.Line2D([], [], color=colours[name], marker="o", linewidth=1.6, label=name)
               for name in sorted(set(sub["label"]), key=list(colours).index)]
    if any(p not in ("", "intrinsic") for p in set(sub["peak"])):
        handles.append(plt.Line2D([], [], color="#6b7280", linestyle=":", label="dotted: PSNR peak "
                                  + ", ".join(sorted(p for p in set(sub["peak"]) if p not in ("", "intrinsic")))))
    if not sub["measured"].all():
        handles.append(plt.Line2D([], [], color="#6b7280", marker="o", markerfacecolor="white", linestyle="none",
                                  label="carried over (not rerun)"))
    if not paper_rows.empty:
        handles.append(plt.Line2D([], [], color="#6b7280", linestyle="--", label="paper (Table 1/2)"))
    fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), 6), frameon=False,
               bbox_to_anchor=(0.5, 1.0))
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.45 / fig.get_figheight()))
    return _svg(fig)


def time_chart(history: History, colours: dict[str, str], metric: str = "time_s") -> str | None:
    """Time per frame (``metric``: "time_s" wall, "cpu_time_s" CPU) over code versions: one panel per
    sequence, one line per method."""
    plt = _matplotlib()
    times = history.table[history.table["metric"] == metric]
    if times.empty:
        return None
    groups = list(times.groupby(["sequence", "holes", "holes_params"], sort=True))
    fig, axes = plt.subplots(1, len(groups), figsize=(max(4.2 * len(groups), 6), 2.9), squeeze=False)
    x_of = {v: i for i, v in enumerate(history.versions)}
    for ax, ((sequence, holes, _), rows) in zip(axes[0], groups):
        for label, line in rows.groupby("label", sort=False):
            line = line.assign(x=line["code_version"].map(x_of)).sort_values("x")
            _plot_line(ax, line, colours[label], label=label)
        if (rows["mean"] > 0).all():
            ax.set_yscale("log")
            _seconds_axis(ax.yaxis)
        ax.set_xticks(range(len(history.versions)))
        ax.set_xticklabels([short_version(v) for v in history.versions], rotation=30, ha="right", fontsize=7.5)
        ax.set_xlim(-0.4, max(len(history.versions) - 0.6, 0.4))
        ax.set_title(f"{sequence} · {holes}: {'CPU ' if metric == 'cpu_time_s' else ''}seconds per frame", loc="left")
    handles, labels = [], []
    for ax in axes[0]:
        for h, name in zip(*ax.get_legend_handles_labels()):
            if name not in labels:
                handles.append(h)
                labels.append(name)
    order = sorted(range(len(labels)), key=lambda i: list(colours).index(labels[i]))
    handles, labels = [handles[i] for i in order], [labels[i] for i in order]
    fig.legend(handles, labels, loc="upper center", ncol=min(len(labels), 6), frameon=False,
               bbox_to_anchor=(0.5, 1.0))
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.45 / fig.get_figheight()))
    return _svg(fig)


def benchmark_chart(benchmarks: pd.DataFrame) -> str | None:
    """Median seconds per pytest-benchmark session: one panel per group, one line per benchmark;
    with a single session, horizontal bars of the figures instead."""
    plt = _matplotlib()
    if benchmarks is None or benchmarks.empty:
        return None
    sessions = benchmarks.drop_duplicates(["datetime", "commit"]).sort_values("datetime")
    session_labels = [f"{short_version(c)}\n{str(d)[5:16]}" for c, d in zip(sessions["commit"], sessions["datetime"])]
    x_of = {(d, c): i for i, (d, c) in enumerate(zip(sessions["datetime"], sessions["commit"]))}
    # a benchmark without a group joins the others of its test function (test_bench_size[...]), so
    # that no panel gathers dozens of lines and an unreadable legend
    function = benchmarks["fullname"].str.split("::").str[-1].str.split("[").str[0]
    group = benchmarks["group"].fillna("").where(benchmarks["group"].fillna("") != "", function)
    groups = list(benchmarks.assign(group=group).groupby("group", sort=True))
    if len(sessions) == 1:
        latest = benchmarks.sort_values("median")
        fig, ax = plt.subplots(figsize=(9, 0.28 * len(latest) + 1.0))
        ax.barh(range(len(latest)), latest["median"], color="#1f77b4", alpha=0.85)
        ax.set_yticks(range(len(latest)))
        ax.set_yticklabels(latest["fullname"].str.split("::").str[-1], fontsize=7.5)
        ax.set_xscale("log")
        _seconds_axis(ax.xaxis)
        ax.set_xlabel("median seconds (log scale)")
        ax.set_title(f"benchmark session {session_labels[0].replace(chr(10), ' ')}", loc="left")
        fig.tight_layout()
        return _svg(fig)
    ncols = min(2, len(groups))
    nrows = math.ceil(len(groups) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(7.0 * ncols, 3.0 * nrows), squeeze=False)
    for ax, (group, rows) in zip(axes.flat, groups):
        for i, (name, line) in enumerate(rows.groupby("fullname", sort=True)):
            xs = [x_of[(d, c)] for d, c in zip(line["datetime"], line["commit"])]
            ax.plot(xs, line["median"], marker="o", markersize=3.5, linewidth=1.3, color=PALETTE[i % len(PALETTE)],
                    label=name.split("::")[-1])
        ax.set_yscale("log")
        _seconds_axis(ax.yaxis)
        ax.set_xticks(range(len(sessions)))
        ax.set_xticklabels(session_labels, fontsize=6.5)
        ax.set_title(f"{group}: median s", loc="left")
        ax.legend(fontsize=6.5, frameon=False, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes
    for ax in list(axes.flat)[len(groups):]:
        ax.set_visible(False)
    fig.tight_layout()
    return _svg(fig)


# ---------------------------------------------------------------------------------------------
# HTML
def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _fmt(value) -> str:
    return compare._fmt_value(float(value)) if value is not None else "-"


def _card(key: str, value, sub: str = "", tone: str = "") -> str:
    return (f'<div class="card {tone}" data-card="{_e(key)}"><div class="k">{_e(key)}</div>'
            f'<div class="v">{_e(value)}</div><div class="s">{_e(sub)}</div></div>')


STATUS_CLASS = {compare.STATUS_REGRESSED: "regressed", compare.STATUS_MISSING: "missing",
                compare.STATUS_IMPROVED: "improved", compare.STATUS_SLOWER: "slower",
                compare.STATUS_FASTER: "improved", compare.STATUS_OK: "ok", compare.STATUS_NEW: "new",
                compare.STATUS_MORE_MEMORY: "slower", compare.STATUS_LESS_MEMORY: "improved"}


def comparison_table(comparison: compare.Comparison, colours: dict[str, str], rows: pd.DataFrame | None = None) -> str:
    table = comparison.table if rows is None else rows
    out = ['<table class="comparison"><thead><tr><th>sequence</th><th>holes</th><th>method</th><th>metric</th>'
           '<th>scope</th><th>baseline</th><th>current</th><th>change</th><th>tolerance</th><th>status</th>'
           '</tr></thead><tbody>']
    for row in table.itertuples(index=False):
        label = method_label(row.method, row.method_params)
        css = STATUS_CLASS.get(row.status, "")
        status = row.status if row.gated or row.status in (compare.STATUS_OK, compare.STATUS_NEW) \
            else f"{row.status} (not gated)"
        metric = row.metric + (f" @{row.peak}" if row.peak else "")
        out.append(
            f'<tr class="{css}" data-status="{_e(row.status)}"><td>{_e(row.sequence)}</td><td>{_e(row.holes)}</td>'
            f'<td><span class="swatch" style="background:{colours.get(label, "#999")}"></span>{_e(label)}</td>'
            f'<td>{_e(metric)}</td><td>{_e(row.scope)}</td><td class="num">{_e(_fmt(row.baseline))}</td>'
            f'<td class="num">{_e(_fmt(row.current))}</td>'
            f'<td class="num">{_e(compare.format_change(row.kind, row.change, row.metric))}</td>'
            f'<td class="num">{_e(compare.format_tolerance(row.kind, row.tolerance, row.metric))}</td>'
            f'<td>{_e(status)}</td></tr>')
    out.append("</tbody></table>")
    return "".join(out)


def paper_gaps(history: History, paper: pd.DataFrame, runs: pd.DataFrame | None = None) -> str:
    """The paper's claim as a reproduction can test it on any data: temporal-graph's GPSNR D1 gain
    (dB) over each other method of the paper's columns, and the NSHD ratio fu-nonlocal /
    temporal-graph, at the newest version, per sequence, hole configuration (generator and
    parameters: e.g. the independent and the temporally coherent holes of `reproduce-paper` are two
    rows) and scope, beside the paper's average over its five sequences. Each method in the
    configuration bench.paper gives its column (the paper configuration: variant=paper for the two
    graph methods, meshlab output=whole) where the store holds it, else at its defaults (for the
    graph methods: our tuned variant, not the paper configuration). ``runs`` (the store's runs
    table) supplies the labels that experiment configs gave to hole configurations ("coherent holes")."""
    from dpcbench.bench.paper import PAPER_METHODS
    from dpcbench.bench.tables import config_labels, given_labels

    proposed = "temporal-graph"
    others = [m for m in paper["method"].drop_duplicates() if m != proposed]
    # each method in its paper column's configuration (bench.paper), else at its defaults
    paper_params = {name: compare._canonical_json(params) for name, _, params in PAPER_METHODS}
    table = history.table
    as_in_paper = [p == "{}" or paper_params.get(m) == p for m, p in zip(table["method"], table["method_params"])]
    latest = table[(table["code_version"] == history.versions[-1]) & pd.Series(as_in_paper, index=table.index)
                   & (table["peak"].isin(["", "intrinsic"]))]
    latest = latest.sort_values("method_params", key=lambda p: p != "{}").drop_duplicates(
        ["sequence", "holes", "holes_params", "scope", "metric", "method"], keep="last")
    if proposed not in set(latest["method"]):
        return ""
    ref = paper.pivot_table(index="sequence", columns=["metric", "method"], values="value")
    paper_gain = {m: float((ref[("gpsnr_d1", proposed)] - ref[("gpsnr_d1", m)]).mean()) for m in others}
    paper_ratio = float((ref[("nshd", "fu-nonlocal")] / ref[("nshd", proposed)]).mean())
    # a hole configuration is named by its generator plus the parameters that tell it from the
    # generator's other configurations in the table ("region (coherent=True)")
    given = given_labels(runs, "holes") if runs is not None and len(runs) else {}
    latest = latest.assign(holes_label=config_labels(latest["holes"], latest["holes_params"], given=given))
    rows = []
    for (sequence, holes, _, scope), sub in latest.groupby(["sequence", "holes_label", "holes_params", "scope"],
                                                          sort=True):
        psnr = sub[sub["metric"] == "gpsnr_d1"].set_index("method")["mean"]
        nshd = sub[sub["metric"] == "nshd"].set_index("method")["mean"]
        if proposed not in psnr.index:
            continue
        cells = []
        for m in others:
            if m in psnr.index:
                gain = psnr[proposed] - psnr[m]
                css = "num" + (" bad" if gain < 0 else "")
                cells.append(f'<td class="{css}">{gain:+.2f} dB</td>')
            else:
                cells.append('<td class="num">-</td>')
        if proposed in nshd.index and "fu-nonlocal" in nshd.index and nshd[proposed] > 0:
            cells.append(f'<td class="num">x{nshd["fu-nonlocal"] / nshd[proposed]:.2f}</td>')
        else:
            cells.append('<td class="num">-</td>')
        rows.append(f"<tr><td>{_e(sequence)}</td><td>{_e(holes)}</td><td>{_e(scope)}</td>{''.join(cells)}</tr>")
    if not rows:
        return ""
    head = "".join(f"<th>vs {_e(m)}</th>" for m in others) + "<th>NSHD fu-nonlocal / temporal-graph</th>"
    paper_row = "".join(f'<td class="num">{paper_gain[m]:+.2f} dB</td>' for m in others) + \
        f'<td class="num">x{paper_ratio:.2f}</td>'
    return (f"<table class='gaps'><thead><tr><th>sequence</th><th>holes</th><th>scope</th>{head}</tr></thead><tbody>"
            f"<tr class='paper'><td colspan='3'>paper: mean over its 5 sequences (Tables 1-2)</td>{paper_row}</tr>"
            f"{''.join(rows)}</tbody></table>")


def latest_table(history: History, colours: dict[str, str], metrics: list[str]) -> str:
    """Newest version's means: one table per (sequence, holes), rows = methods, columns = metric x
    scope x peak (the PSNR peak is named when it is not pc_error's default, "intrinsic")."""
    latest = history.table[history.table["code_version"] == history.versions[-1]]
    parts = []
    for (sequence, holes, holes_params), sub in latest.groupby(["sequence", "holes", "holes_params"], sort=True):
        present = set(zip(sub["metric"], sub["scope"], sub["peak"]))
        peaks = sorted(set(sub["peak"]), key=lambda p: (p not in ("", "intrinsic"), p))
        columns = [(m, s, p) for s in ("frame", "holes") for m in metrics + ["time_s", "cpu_time_s"] for p in peaks
                   if (m, s, p) in present]
        values = sub.set_index(["label", "metric", "scope", "peak"])
        # the floor: method "none" (the damaged input, holes left open) in the same block
        floor_rows = sub[(sub["method"] == FLOOR_METHOD) & (sub["method_params"] == "{}")]
        floor = {(r.metric, r.scope, r.peak): float(r.mean) for r in floor_rows.itertuples(index=False)
                 if r.metric not in compare.RESOURCE_METRICS and r.metric not in compare.INFO_METRICS
                 and _registry.describe(r.metric) is not None and _registry.describe(r.metric).higher_is_better is not None}
        any_below = False
        best = {}
        for column in columns:
            metric = column[0]
            cell = sub[(sub["metric"] == metric) & (sub["scope"] == column[1]) & (sub["peak"] == column[2])]
            cell = cell.dropna(subset=["mean"])
            if len(cell) and metric not in compare.TIME_METRICS:
                best[column] = cell["mean"].max() if compare.higher_is_better(metric) else cell["mean"].min()
        head = "".join(f"<th>{_e(metric_label(m))}<br><span class='note'>{_e(s)}"
                       f"{_e(' · peak ' + p if p not in ('', 'intrinsic') else '')}</span></th>"
                       for m, s, p in columns)
        body = []
        for label in sorted(set(sub["label"]), key=list(colours).index):
            cells = []
            for column in columns:
                key = (label,) + column
                if key not in values.index:
                    cells.append('<td class="num">-</td>')
                    continue
                mean, std = float(values.loc[key, "mean"]), float(values.loc[key, "std"])
                css = "num best" if best.get(column) == mean else "num"
                spread = f" ± {_fmt(std)}" if std and not math.isnan(std) else ""
                below = column in floor and (mean < floor[column] if compare.higher_is_better(column[0])
                                             else mean > floor[column])
                any_below |= below
                mark = f' <span class="floor" title="below the floor: worse than no fill">{FLOOR_MARK}</span>' if below else ""
                cells.append(f'<td class="{css}">{_e(_fmt(mean))}{_e(spread)}{mark}</td>')
            body.append(f'<tr><td><span class="swatch" style="background:{colours[label]}"></span>{_e(label)}</td>'
                        + "".join(cells) + "</tr>")
        params = "" if holes_params == "{}" else f" ({compare.short_params(holes_params, 60)})"
        parts.append(f"<h3>{_e(sequence)} · {_e(holes)}{_e(params)}</h3>"
                     f"<table class='latest'><thead><tr><th>method</th>{head}</tr></thead>"
                     f"<tbody>{''.join(body)}</tbody></table>"
                     + (f"<p class='note'>{FLOOR_MARK}: below the floor, a mean worse than method "
                        f"<code>{FLOOR_METHOD}</code> (the damaged input, holes left open) on the same data: worse "
                        "than not filling at all.</p>" if any_below else ""))
    return "".join(parts)


# ---------------------------------------------------------------------------------------------
# the page: one function per section, each taking the Page it is built from
@dataclass
class Page:
    """What the sections of one dashboard page are built from (prepared once by `prepare_page`).

    comparison:      the latest comparison (`compare.compare_summaries`) or None when there is
                     neither a baseline nor two code versions; compared_what says what it compares.
    quality_metrics: the quality metrics present, in `QUALITY_ORDER` then by name.
    """

    results: pd.DataFrame
    runs: pd.DataFrame | None
    benchmarks: pd.DataFrame | None
    history: History
    paper: pd.DataFrame
    colours: dict[str, str]
    metrics_present: set[str]
    quality_metrics: list[str]
    comparison: compare.Comparison | None
    compared_what: str
    n_failed: int
    n_bench: int
    n_sessions: int


def prepare_page(results: pd.DataFrame, runs: pd.DataFrame | None, benchmarks: pd.DataFrame | None,
                 baseline: tuple[pd.DataFrame, dict] | None, tolerances: dict[str, float] | None) -> Page:
    """The history, colours, metrics and latest comparison that the sections share. Runs group by
    their cell (`compare.with_cells`: the run's identity minus its seed), never by a label alone."""
    if runs is not None and len(runs) and "run_id" in results.columns:
        results = compare.with_cells(results, runs)
    history = build_history(results)
    colours = method_colours(history.table["label"]) if len(history.table) else {}
    metrics_present = set(history.table["metric"]) if len(history.table) else set()
    quality_metrics = [m for m in QUALITY_ORDER if m in metrics_present] + \
        sorted(metrics_present - set(QUALITY_ORDER) - set(compare.RESOURCE_METRICS) - set(compare.INFO_METRICS))

    # the latest comparison: newest version vs the previous one, or vs a given baseline
    comparison, compared_what = None, ""
    if history.versions and (baseline is not None or len(history.versions) >= 2):
        current = history.table[history.table["code_version"] == history.versions[-1]]
        if baseline is not None:
            base, base_meta = baseline
            compared_what = (f"code {short_version(history.versions[-1])} against the baseline summary "
                             f"(code {short_version(base_meta.get('code_version', '?'))}, {base_meta.get('date', '?')})")
        else:
            base = history.table[history.table["code_version"] == history.versions[-2]]
            compared_what = (f"code {short_version(history.versions[-1])} against the previous version "
                             f"{short_version(history.versions[-2])}")
        comparison = compare.compare_summaries(base, current, tolerances)

    n_failed = 0
    if runs is not None and len(runs):
        n_failed = int(runs.loc[runs["status"] == "failed", "run_id"].nunique())
    n_bench = int(benchmarks["fullname"].nunique()) if benchmarks is not None and len(benchmarks) else 0
    n_sessions = int(benchmarks.drop_duplicates(["datetime", "commit"]).shape[0]) if n_bench else 0
    return Page(results, runs, benchmarks, history, paper_reference(), colours, metrics_present, quality_metrics,
                comparison, compared_what, n_failed, n_bench, n_sessions)


def cards_section(page: Page) -> str:
    """The summary cards: code versions, runs (failed ones), regressions, best GPSNR D1, benchmarks."""
    history, results = page.history, page.results
    n_done = int(results["run_id"].nunique()) if len(results) else 0
    cards = [
        _card("code versions", len(history.versions),
              f"{short_version(history.versions[0])} → {short_version(history.versions[-1])}" if history.versions else "none"),
        _card("runs", n_done, f"{page.n_failed} failed (see Code versions)" if page.n_failed else "none failed",
              "warn" if page.n_failed else ""),
    ]
    if page.comparison is not None:
        n_bad = len(page.comparison.failures)
        n_improved = int((page.comparison.table["status"] == compare.STATUS_IMPROVED).sum())
        cards.append(_card("regressions", n_bad, f"{n_improved} improved · latest comparison",
                           "bad" if n_bad else "good"))
    else:
        cards.append(_card("regressions", "–", "needs two code versions or a baseline"))
    if history.versions:
        latest = history.table[(history.table["code_version"] == history.versions[-1])
                               & (history.table["metric"] == "gpsnr_d1") & (history.table["scope"] == "holes")]
        if latest.empty:
            latest = history.table[(history.table["code_version"] == history.versions[-1])
                                   & (history.table["metric"] == "gpsnr_d1")]
        if len(latest):
            by_method = latest.groupby("label")["mean"].mean().sort_values(ascending=False)
            cards.append(_card("best GPSNR D1", by_method.index[0], f"{by_method.iloc[0]:.2f} dB mean over sequences"))
    cards.append(_card("benchmarks", page.n_bench, f"{page.n_sessions} session(s)" if page.n_bench else "no JSON given"))
    return f"<div class=\"cards\">{''.join(cards)}</div>"


def comparison_section(page: Page) -> str:
    """Rows beyond tolerance first (the bad news first), the full comparison folded; '' without one."""
    comparison = page.comparison
    if comparison is None:
        return ""
    flagged = comparison.table[~comparison.table["status"].isin([compare.STATUS_OK, compare.STATUS_NEW])]
    n_new = int((comparison.table["status"] == compare.STATUS_NEW).sum())
    severity = {compare.STATUS_REGRESSED: 0, compare.STATUS_MISSING: 1, compare.STATUS_SLOWER: 2,
                compare.STATUS_IMPROVED: 3, compare.STATUS_FASTER: 4}
    flagged = flagged.assign(_rank=flagged["status"].map(severity).fillna(5)).sort_values(
        "_rank", kind="stable").drop(columns="_rank")
    verdict = ('<span class="badge bad">FAILED</span>' if comparison.failed
               else '<span class="badge good">PASSED</span>')
    body = (comparison_table(comparison, page.colours, flagged) if len(flagged)
            else "<p>Every row is within tolerance.</p>")
    if n_new:
        body += f'<p class="note">{n_new} row(s) are new in this version (no earlier value to compare).</p>'
    return (f'<section id="comparison"><h2>Latest comparison {verdict}</h2>'
            f'<p class="note">{_e(page.compared_what)}. Changes: dB for PSNR, ratios for NSHD, distances and time; '
            f'a row regresses when its change passes the tolerance in the bad direction. Time is shown but '
            f'not gated.</p>{body}<details><summary>all {len(comparison.table)} rows</summary>'
            f'{comparison_table(comparison, page.colours)}</details></section>')


def quality_section(page: Page) -> str:
    """One chart per (sequence, holes): quality over code versions, the paper's values dashed."""
    history, paper = page.history, page.paper
    if not history.versions:
        return ""
    charts = []
    keys = history.table[["sequence", "holes", "holes_params"]].drop_duplicates().sort_values(
        ["sequence", "holes", "holes_params"])
    for sequence, holes, holes_params in keys.itertuples(index=False):
        params = "" if holes_params == "{}" else f" ({compare.short_params(holes_params, 60)})"
        chart = quality_chart(history, sequence, holes, holes_params, page.quality_metrics, page.colours, paper)
        charts.append(f'<h3>{_e(sequence)} · {_e(holes)}{_e(params)}</h3>'
                      f'<div class="figure" data-chart="quality" data-sequence="{_e(sequence)}" '
                      f'data-commits="{len(history.versions)}">{chart}</div>')
    has_paper = bool(set(history.table["sequence"].str.lower()) & set(paper["sequence"]))
    paper_note = ("Dashed lines: the paper's Table 1 (GPSNR) and Table 2 (NSHD) values for this sequence."
                  if has_paper else
                  f"The paper's values (Tables 1-2) are for its own sequences ({', '.join(PAPER_SEQUENCES.values())}); "
                  "none is in this store, so no reference lines are drawn.")
    return (f'<section id="quality"><h2>Quality over code versions</h2><p class="note">Mean over frames (and seeds) '
            f'of the newest run per cell, per code version in time order. Scope "frame" scores whole frames, '
            f'"holes" only the hole regions. {_e(paper_note)}</p>{"".join(charts)}</section>')


def paper_section(page: Page) -> str:
    """temporal-graph's gains over the paper's other columns beside the paper's; '' when it has no run."""
    if not page.history.versions:
        return ""
    gaps = paper_gaps(page.history, page.paper, page.runs)
    if not gaps:
        return ""
    return ('<section id="paper"><h2>Against the paper</h2><p class="note">GPSNR D1 gain of temporal-graph '
            'over each method of the paper\'s columns at the newest version, and how many times lower its NSHD '
            'is than fu-nonlocal\'s (the paper: at least 3x). temporal-graph and fu-nonlocal are taken in the '
            'paper configuration (variant=paper) where the store holds it, else at their defaults, which are '
            'our tuned variant and not the paper configuration. On stand-in data the absolute values differ '
            'from the paper\'s; the ranking and the size of the gaps are what a reproduction is held to. '
            'Negative gains in red.</p>' + gaps + '</section>')


def latest_section(page: Page) -> str:
    """The newest code version's means per method (`latest_table`), with how D2 got its normals."""
    history, runs = page.history, page.runs
    if not history.versions:
        return ""
    normals_note = ""
    if runs is not None and len(runs) and "gpsnr_d2" in page.metrics_present:
        from dpcbench.bench.tables import d2_normals_note

        done = runs[runs["status"] == "done"]
        newest = done[done["code_version"].astype(str) == history.versions[-1]]
        normals_note = d2_normals_note(newest if len(newest) else done)  # the runs of the newest version
    return (f'<section id="latest"><h2>Latest results: {_e(short_version(history.versions[-1]))}</h2>'
            f'<p class="note">Mean ± std over frames; best per column in bold. {_e(normals_note)}</p>'
            f'{latest_table(history, page.colours, page.quality_metrics)}</section>')


def speed_section(page: Page) -> str:
    """Time per frame over code versions and the pytest-benchmark history; '' when there is neither."""
    history, benchmarks = page.history, page.benchmarks
    speed = []
    chart = time_chart(history, page.colours) if history.versions else None
    if chart:
        speed.append(f'<h3>Inpainting time per frame (results store)</h3>'
                     f'<div class="figure" data-chart="time" data-commits="{len(history.versions)}">{chart}</div>')
    cpu_chart = time_chart(history, page.colours, "cpu_time_s") if history.versions else None
    if cpu_chart:
        speed.append(f'<h3>Inpainting CPU time per frame (results store)</h3><p class="note">user + system, all '
                     f'threads: on a loaded machine the wall time grows with the load, the CPU time barely does.</p>'
                     f'<div class="figure" data-chart="cpu-time" data-commits="{len(history.versions)}">{cpu_chart}</div>')
    if page.n_bench:
        from dpcbench.bench import benchsuite

        bench_chart = benchmark_chart(benchmarks)
        latest_bench = benchsuite.latest_per_benchmark(benchmarks)
        rows = "".join(
            f'<tr><td>{_e(r.group or "")}</td><td>{_e(r.fullname)}</td><td class="num">{r.median:.4g}</td>'
            f'<td class="num">{r.min:.4g}</td><td class="num">{int(r.rounds)}</td>'
            f'<td>{_e(short_version(r.commit))}</td><td>{_e(str(r.datetime)[:16])}</td></tr>'
            for r in latest_bench.itertuples(index=False))
        speed.append(f'<h3>Benchmark suite (pytest-benchmark)</h3>'
                     f'<p class="note">{page.n_sessions} session(s); machines are shared and noisy: read trends, '
                     f'not single points.</p><div class="figure" data-chart="benchmarks" '
                     f'data-sessions="{page.n_sessions}">{bench_chart}</div>'
                     f'<details><summary>newest figure of each of the {page.n_bench} benchmarks</summary>'
                     f'<table class="benchmarks"><thead><tr><th>group</th><th>benchmark</th><th>median s</th>'
                     f'<th>min s</th><th>rounds</th><th>commit</th><th>date</th></tr></thead><tbody>{rows}</tbody>'
                     f'</table></details>')
    return f'<section id="speed"><h2>Speed</h2>{"".join(speed)}</section>' if speed else ""


def _run_seconds(runs: pd.DataFrame | None) -> tuple[dict, dict]:
    """Per code version: the summed wall_time_s and cpu_time_s of its runs (each run once; a sum is
    left out where no run of that version recorded the figure)."""
    if runs is None or runs.empty or "wall_time_s" not in runs.columns:
        return {}, {}
    once = runs.drop_duplicates("run_id").assign(code_version=lambda d: d["code_version"].fillna("unknown").astype(str))
    sums = {}
    for column in ("wall_time_s", "cpu_time_s"):
        if column not in once.columns:
            sums[column] = {}
            continue
        values = pd.to_numeric(once[column], errors="coerce")
        grouped = values.groupby(once["code_version"])
        sums[column] = {v: float(total) for v, total in grouped.sum(min_count=1).items() if not math.isnan(total)}
    return sums["wall_time_s"], sums["cpu_time_s"]


def _hours(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds / 3600:.3g}"


def runs_section(page: Page) -> str:
    """Code versions with their dates, run counts and summed run times, and the failed runs with their messages."""
    history, results, runs = page.history, page.results, page.runs
    if not history.versions:
        return ""
    counts = results.groupby("code_version")["run_id"].nunique()
    wall, cpu = _run_seconds(runs)
    version_rows = "".join(
        f'<tr><td>{_e(short_version(v))}</td><td>{_e(v)}</td><td>{_e(history.version_dates[v])}</td>'
        f'<td class="num">{int(counts.get(v, 0))}</td><td class="num">{_e(_hours(wall.get(v)))}</td>'
        f'<td class="num">{_e(_hours(cpu.get(v)))}</td></tr>' for v in reversed(history.versions))
    failed_html = ""
    if runs is not None and page.n_failed:
        failed = runs[runs["status"] == "failed"].drop_duplicates("run_id")
        failed_html = ("<h3>Failed runs</h3><table><thead><tr><th>method</th><th>sequence</th><th>code</th>"
                       "<th>error</th></tr></thead><tbody>" + "".join(
                           f'<tr class="regressed"><td>{_e(method_label(r.method, r.method_params or "{}"))}</td>'
                           f'<td>{_e(r.sequence)}</td><td>{_e(short_version(r.code_version))}</td>'
                           f'<td>{_e(str(r.error)[:300])}</td></tr>' for r in failed.itertuples(index=False))
                       + "</tbody></table>")
    return (f'<section id="runs"><h2>Code versions</h2><table><thead><tr><th>short</th><th>code version'
            f'</th><th>first run (UTC)</th><th>runs</th><th>wall (h)</th><th>CPU (h)</th></tr></thead>'
            f'<tbody>{version_rows}</tbody>'
            f'</table>{failed_html}</section>')


#: the sections of the page, in order (each returns '' when it has nothing to show)
SECTIONS = (comparison_section, quality_section, paper_section, latest_section, speed_section, runs_section)


def stylesheet() -> str:
    """The page's CSS, a package data file (bench/static/dashboard.css) inlined in every page."""
    return resources.files(__package__).joinpath("static", "dashboard.css").read_text(encoding="utf-8")


def render_dashboard(results: pd.DataFrame, *, runs: pd.DataFrame | None = None,
                     benchmarks: pd.DataFrame | None = None,
                     baseline: tuple[pd.DataFrame, dict] | None = None,
                     tolerances: dict[str, float] | None = None, title: str = "dpcbench regression dashboard",
                     sources: list[str] | None = None) -> str:
    """The dashboard page as one HTML string (see the module docstring for its sections)."""
    page = prepare_page(results, runs, benchmarks, baseline, tolerances)
    sections = [html_text for html_text in (section(page) for section in SECTIONS) if html_text]
    if not sections:
        sections.append('<section><h2>No results yet</h2><p>Run <code>dpcbench run bench/presets/regression.toml'
                        '</code>, then build this page again.</p></section>')
    generated = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    source_text = "; ".join(sources or []) or "results store"
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{_e(title)}</title>"
        f"<style>\n{stylesheet()}</style></head><body><header><h1>{_e(title)}</h1>"
        f"<p>3D dynamic point cloud inpainting · generated {generated} from {_e(source_text)}</p></header><main>"
        f"{cards_section(page)}{''.join(sections)}"
        "<footer>dpcbench · static page: every chart and number is inside this file</footer></main></body></html>\n"
    )


def write_dashboard(out: str | os.PathLike, results: pd.DataFrame, **kwargs) -> Path:
    """Render and write the page atomically; returns its path."""
    from dpcbench.bench.atomic import atomic_write_text

    return atomic_write_text(out, render_dashboard(results, **kwargs))


def external_references(page: str) -> list[str]:
    """URLs the page would fetch (src/href/url() to http(s) or protocol-relative); [] for a static page.
    SVG namespace declarations (xmlns=...) are identifiers, not requests, and are not counted."""
    pattern = r"""(?:src|href)\s*=\s*["'](?:https?:)?//[^"']+|url\(\s*["']?(?:https?:)?//[^)]+\)|@import"""
    return re.findall(pattern, page, flags=re.IGNORECASE)
