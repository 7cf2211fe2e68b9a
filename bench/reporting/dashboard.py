"""The regression dashboard: one self-contained HTML page (`dpcbench dashboard`), plus a page per
method configuration and per run beside it (`bench.reporting.dashboard_pages`).

Input: the results store's tidy table (one or several stores, concatenated, plus the summaries of a
history folder such as results/history/, one per commit: `read_history`, `summary_as_results`),
optionally its runs table, a baseline summary, and pytest-benchmark runs (`bench.results.benchsuite`).
Output: an HTML file with inline CSS and interactive charts (plotly.js inlined once at the end of
the page, each chart's figure as an inline JSON block). Nothing is fetched from outside the file,
so it opens from disk, from a CI artifact, or by mail, offline.

Sections:
  cards        commits tracked, runs done/failed, regressions in the latest comparison, benchmarks
  comparison   the newest code version against a baseline summary (the CLI's default: the committed
               results/regression-baseline.csv where it covers the store) or else the previous
               version: every row beyond tolerance first (REGRESSED rows in red), the full table folded
  quality      a filter bar (sequence, holes, metric, scope) and one chart per (sequence, holes,
               metric, scope): x = code versions in time order, one line per method configuration
               (`bench.reporting.palette` colours), the paper's value dashed where the sequence is one of the
               paper's; hover gives value, std, n, commit, date and machine; drag zooms
  paper        temporal-graph's gains over the paper's other columns beside the paper's own
  latest       the newest code version's means per method (best per column in bold)
  speed        wall and CPU time per frame over code versions (one chart per sequence and holes),
               and the pytest-benchmark history (median seconds per session, one chart per group,
               log scale) with the newest figures; a change of machine is marked on each
  pages        links to a page per method configuration and per run (`bench.reporting.dashboard_pages`)
  runs         code versions with their dates, run counts and the runs' summed wall and CPU time
               (the runs table; "-" where no run recorded CPU time), and failed runs with their messages

A code version is the store's ``code_version`` (git commit); versions are ordered by the time of
their first run (a history summary's time is its commit's date). Summaries come from
`bench.results.compare.summarize`, one per code version. The machine of a version (`machine_name`) comes
from its runs' env or its summary's meta.

Code: `prepare_page` computes what the sections share (the history, colours, latest comparison)
into a `Page`; each section is one function of it (`cards_section`, `comparison_section`,
`quality_section`, `paper_section`, `latest_section`, `speed_section`, `pages_section`, `runs_section`; `SECTIONS`
lists them in page order); `render_dashboard` joins them. Charts are `Chart`s (plotly figures as
plain JSON data, built by `quality_charts` / `time_charts` / `benchmark_charts`); the page's script (`DASHBOARD_JS`)
draws those the filters let through, each once. The style sheet is the package data file
bench/static/dashboard.css, inlined (`stylesheet`). The paper's values come from `bench.core.paper_facts`.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import html
import math
import os
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import pandas as pd

from dpcbench.bench.core.paper_facts import PAPER_SEQUENCES
from dpcbench.bench.reporting import palette
from dpcbench.bench.reporting.labels import METRIC_NAMES, SHOWN_UNITS, metric_label  # noqa: F401  (re-exported)
from dpcbench.bench.reporting.tables import FLOOR_MARK, FLOOR_METHOD
from dpcbench.bench.results import compare
from dpcbench.metrics import registry as _registry

QUALITY_ORDER = ["gpsnr_d1", "gpsnr_d2", "nshd", "hausdorff", "chamfer", "fscore", "temporal_consistency"]
#: the methods of the paper's columns first, so that their colours never change when other methods come and go
METHOD_ORDER = ["temporal-graph", "fu-nonlocal", "lozes-pde", "meshlab", "temporal-copy", "none"]


#: short column titles of the latest-results table (so that it fits 1400 px), keyed in `metric_key`
SHORT_NAMES = {"gpsnr_d1": "D1", "gpsnr_d2": "D2", "hausdorff": "Haus.", "chamfer": "Cham.", "fscore": "F",
               "temporal_consistency": "TC", "time_s": "s/frame", "cpu_time_s": "CPU s/frame", "peak_mem_mb": "MB"}


def short_metric_label(metric: str) -> str:
    """A short column title as HTML: an <abbr> with the full `metric_label` as its tooltip."""
    short = SHORT_NAMES.get(metric)
    if short is None:
        return html.escape(metric_label(metric))
    unit = " (dB)" if metric in ("gpsnr_d1", "gpsnr_d2") else ""
    return f'<abbr title="{html.escape(metric_label(metric))}">{html.escape(short + unit)}</abbr>'


def metric_key(metrics) -> str:
    """The key of the short column titles used for ``metrics`` ('D1: GPSNR D1 (dB) · ...')."""
    return " · ".join(f"{SHORT_NAMES[m]}: {metric_label(m)}" for m in dict.fromkeys(metrics) if m in SHORT_NAMES)


def paper_reference() -> pd.DataFrame:
    """The paper's values as rows (sequence, method, metric, value, source); metric gpsnr_d1 / nshd.

    From `bench.core.paper_facts` (Tables 1-2), with each paper column mapped to the registry method of
    `bench.reporting.paper.PAPER_METHODS`. The paper's GPSNR is plotted against our gpsnr_d1 (point-to-point,
    as pc_error's D1), and its NSHD (printed x1e-7) against our nshd.
    """
    from dpcbench.bench.core import paper_facts
    from dpcbench.bench.reporting.paper import PAPER_METHODS

    methods = [name for name, _, _ in PAPER_METHODS]
    name_of = {label: name for name, label in paper_facts.PAPER_SEQUENCES.items()}
    rows = []
    for metric, table, scale in (("gpsnr_d1", paper_facts.TABLE1_GPSNR, 1.0),
                                 ("nshd", paper_facts.TABLE2_NSHD_E7, paper_facts.NSHD_SCALE)):
        for label, values in table.items():
            for method, value in zip(methods, values):
                rows.append({"sequence": name_of[label], "method": method, "metric": metric,
                             "value": float(value) * scale, "source": "dpcbench.bench.core.paper_facts"})
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
    #: code version -> the machine its runs ran on ("node, x86_64, 2 cpus"), where known (`machine_name`)
    version_machines: dict[str, str] = field(default_factory=dict)


#: run ids of the rows `summary_as_results` makes ("<prefix>:<cell>", prefix summary, summary0, history3, ...)
SUMMARY_RUN = re.compile(r"^(summary|history)\d*:")


def from_summary(run_ids: pd.Series) -> pd.Series:
    """True where a results row comes from a summary file (`summary_as_results`), not from a run."""
    return run_ids.astype(str).str.match(SUMMARY_RUN)


def summary_values(mean: float, std: float, n: int) -> list[float]:
    """``n`` values whose mean is ``mean`` and population std is ``std`` (the statistics a summary
    keeps of a cell's frames), so that `compare.summarize` of them gives the summary's row back:
    n even: mean ± std alternately; n odd: mean, then mean ± std * sqrt(n / (n - 1)) alternately
    (squared deviations sum to n std²). A NaN std, or n < 2, gives n copies of the mean (at least one)."""
    n = max(int(n), 1)
    if n < 2 or std is None or math.isnan(std) or std == 0:
        return [float(mean)] * n
    if n % 2 == 0:
        return [float(mean + (std if i % 2 == 0 else -std)) for i in range(n)]
    step = std * math.sqrt(n / (n - 1))
    return [float(mean)] + [float(mean + (step if i % 2 == 0 else -step)) for i in range(n - 1)]


def summary_as_results(summary: pd.DataFrame, meta: dict, *, run_prefix: str = "summary") -> pd.DataFrame:
    """A summary file's rows as store-shaped results, so a committed baseline or a history folder's
    summary joins the history as one code version: one run per cell, its frames `summary_values`
    (the cell's mean, std and frame count are kept; its per-frame values are not in a summary).
    The code version is the meta's (the last one where it lists several), the time its commit_date
    (the commit's own date, as asv orders by commit), else its run_date (its newest run), else its
    date (when the file was written)."""
    version = str(meta.get("code_version") or "unknown").split(",")[-1]
    when = str(meta.get("commit_date") or meta.get("run_date") or meta.get("date", ""))
    rows = []
    for row in summary.itertuples(index=False):
        run_id = f"{run_prefix}:{row.sequence}|{row.holes}|{row.holes_params}|{row.method}|{row.method_params}"
        mean = float(row.mean) if not pd.isna(row.mean) else float("nan")
        values = [mean] if math.isnan(mean) else summary_values(mean, float(row.std), int(row.n_frames))
        for frame, value in enumerate(values):
            rows.append({"run_id": run_id, "sequence": row.sequence, "holes": row.holes,
                         "holes_params": row.holes_params, "method": row.method, "method_params": row.method_params,
                         "metric": row.metric, "scope": row.scope, "peak": row.peak, "frame": frame, "value": value})
    columns = ["run_id", "sequence", "holes", "holes_params", "method", "method_params", "metric", "scope", "peak",
               "frame", "value"]
    from dpcbench.bench.results.store import RESULT_COLUMNS

    table = pd.DataFrame(rows, columns=columns)
    return table.assign(experiment=str(meta.get("experiment", "")), seed=0, method_version="", code_version=version,
                        created_at=when)[RESULT_COLUMNS]


HISTORY_SUFFIXES = (".csv", ".json")


def read_history(folder: str | os.PathLike) -> list[tuple[pd.DataFrame, dict, Path]]:
    """Every summary (.csv/.json, the format `compare.write_summary` writes) in ``folder``, by file
    name: [(table, meta, path)]. A file there that is not a summary is a `UserError` naming it."""
    from dpcbench.bench.core.errors import UserError

    folder = Path(folder)
    if not folder.is_dir():
        raise UserError(f"{folder}: no such history folder; give a folder of summaries written by "
                        "`dpcbench dashboard --save-history DIR` (or `dpcbench compare --save-current`)")
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in HISTORY_SUFFIXES)
    return [(*compare.read_summary(path), path) for path in files]


def history_file_name(meta: dict) -> str:
    """The file of a commit's summary in a history folder: '<time>_<commit>.csv', the time as
    `summary_as_results` orders by (sorting by name is sorting by time; one file per commit)."""
    version = str(meta.get("code_version") or "unknown")
    when = str(meta.get("commit_date") or meta.get("run_date") or meta.get("date") or "")
    when = when[:19].replace(":", "").replace("-", "")
    safe = re.sub(r"[^0-9A-Za-z+]", "_", version)[:48]
    return f"{when}_{safe}.csv" if when else f"{safe}.csv"


def commit_date(version: str, repo: str | os.PathLike | None = None) -> str:
    """The committer date (ISO 8601) of ``version`` ("+dirty" stripped) in the git checkout ``repo``
    (default: this source tree), or '' when git cannot tell."""
    import subprocess

    cwd = Path(repo) if repo else Path(__file__).resolve().parents[2]
    commit = re.sub(r"[+-]dirty$", "", str(version))
    if not re.fullmatch(r"[0-9a-f]{7,40}", commit):
        return ""
    try:
        text = subprocess.run(["git", "show", "-s", "--format=%cI", commit], cwd=cwd, capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        # in UTC, as the store's times: the history sorts times as text
        return _dt.datetime.fromisoformat(text).astimezone(_dt.timezone.utc).isoformat()
    except (OSError, subprocess.SubprocessError, ValueError):
        return ""


def history_summary(results: pd.DataFrame, runs: pd.DataFrame | None, environment: dict | None = None,
                    **extra) -> tuple[pd.DataFrame, dict]:
    """(summary, meta) of a store's results for a history folder: `compare.summarize` of the newest
    run per cell; meta code_version = the code version of the newest run (the commit the summary
    stands for), code_versions = all of them, run_date the newest run's time, commit_date from git
    where it knows the commit, the runs' environment (`environment`: flat, e.g. env.node / env.cpus:
    the machine)."""
    summary = compare.summarize(results)
    newest = results.sort_values("created_at")["code_version"].dropna().astype(str)
    version = newest.iloc[-1] if len(newest) else "unknown"
    last_run = str(results["created_at"].dropna().max()) if results["created_at"].notna().any() else ""
    meta = compare.summary_meta(version, environment=environment, run_date=last_run,
                                code_versions=",".join(sorted(set(newest))), **extra)
    when = commit_date(version)
    if when:
        meta["commit_date"] = when
    return summary, meta


def short_version(version: str) -> str:
    """'0123456789abcdef...+dirty' -> '01234567+' (a trailing + marks uncommitted changes)."""
    version = str(version)
    match = re.fullmatch(r"(.*?)[+-]dirty", version)
    dirty = match is not None
    core = match.group(1) if match is not None else version
    short = core[:8] if re.fullmatch(r"[0-9a-f]{9,}", core) else core[:12]
    return short + ("+" if dirty else "")


def method_label(method: str, params_json: str) -> str:
    return method if params_json in ("", "{}") else f"{method} ({compare.short_params(params_json, 32)})"


def build_history(results: pd.DataFrame, machines: dict[str, str] | None = None) -> History:
    """Summarize the results table at each code version (see History); ``machines``: code version ->
    machine (`version_machines`)."""
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
    known = {v: m for v, m in (machines or {}).items() if v in dates and m}
    return History(versions, dates, table[columns], known)


def machine_name(env: dict) -> str:
    """A machine as the history compares them: 'node, arch, N cpus[, processor]' from a run's env
    (``{"machine": {"node", "arch", "cpus"}}``) or a summary's meta (``env.node``, ``env.arch``,
    ``env.cpus``; or ``env.machine`` and ``env.processor`` as `provenance.summary_environment` writes
    them); '' when neither says."""
    machine = env.get("machine") if isinstance(env.get("machine"), dict) else None
    if machine is not None:
        parts = [machine.get("node"), machine.get("arch"), machine.get("cpus") and f"{machine['cpus']} cpus"]
    elif env.get("env.node") or env.get("env.cpus"):
        parts = [env.get("env.node"), env.get("env.arch"), env.get("env.cpus") and f"{env['env.cpus']} cpus"]
    else:
        parts = [env.get("env.machine"), env.get("env.processor")]
    return ", ".join(str(p) for p in parts if p)


def run_machines(runs: pd.DataFrame | None) -> dict[str, str]:
    """Code version -> the machine most of its runs ran on (the runs table's env JSON); versions
    whose runs recorded none are left out."""
    from dpcbench.bench.experiment.records import run_env

    if runs is None or runs.empty or "env" not in runs.columns:
        return {}
    names: dict[str, list[str]] = {}
    for version, env_text in zip(runs["code_version"].fillna("unknown").astype(str), runs["env"]):
        name = machine_name(run_env(env_text))
        if name:
            names.setdefault(version, []).append(name)
    return {v: max(set(found), key=found.count) for v, found in names.items()}


def method_colours(labels) -> dict[str, str]:
    """A fixed colour per method configuration (`bench.reporting.palette`: by the method's registry name, so the
    same in every figure and report; further configurations of a method in darker shades of its hue)."""
    def rank(label: str):
        method = label.split(" (")[0]
        return (METHOD_ORDER.index(method) if method in METHOD_ORDER else len(METHOD_ORDER), label)

    ordered = sorted(set(labels), key=rank)
    return palette.configuration_colours((label, label.split(" (")[0]) for label in ordered)


# ---------------------------------------------------------------------------------------------
# the benchmark suite's chart
def benchmark_charts(benchmarks: pd.DataFrame) -> list[Chart]:
    """Median seconds per pytest-benchmark session (x: sessions in time order, 'commit date'), one
    chart per group (a benchmark without a group joins the others of its test function, so no chart
    gathers dozens of lines), one line per benchmark, log scale; a session on another machine than
    the one before it is marked as on the time charts."""
    if benchmarks is None or benchmarks.empty:
        return []
    sessions = benchmarks.drop_duplicates(["datetime", "commit"]).sort_values("datetime")
    ticks, used = {}, set()
    for d, c in zip(sessions["datetime"], sessions["commit"]):
        label = f"{short_version(c)} {str(d)[5:16].replace('T', ' ')}"
        while label in used:
            label += "'"
        used.add(label)
        ticks[(d, c)] = label
    machine_of = {(d, c): str(m) for d, c, m in zip(sessions["datetime"], sessions["commit"], sessions["machine"])}
    changed, previous = {}, None
    for key in ticks:
        if machine_of.get(key) and previous and machine_of[key] != previous:
            changed[key] = f"machine changed: {previous} → {machine_of[key]}"
        previous = machine_of.get(key) or previous
    function = benchmarks["fullname"].str.split("::").str[-1].str.split("[").str[0]
    group = benchmarks["group"].fillna("").where(benchmarks["group"].fillna("") != "", function)
    charts: list[Chart] = []
    for name, rows in benchmarks.assign(group=group).groupby("group", sort=True):
        traces = []
        for i, (fullname, line) in enumerate(rows.groupby("fullname", sort=True)):
            line = line.sort_values("datetime")
            keys = list(zip(line["datetime"], line["commit"]))
            text = [f"<b>{html.escape(fullname.split('::')[-1])}</b><br>median {r.median:.4g} s, min {r.min:.4g} s, "
                    f"{int(r.rounds)} rounds<br>commit {html.escape(str(r.commit))}<br>{html.escape(str(r.datetime)[:19])}"
                    f"<br>machine: {html.escape(str(r.machine))}"
                    + (f"<br><b>{html.escape(changed[k])}</b>" if k in changed else "")
                    for r, k in zip(line.itertuples(index=False), keys)]
            colour = palette.EXTRA_COLOURS[i % len(palette.EXTRA_COLOURS)]  # colour-blind safe
            traces.append({"type": "scatter", "mode": "lines+markers", "name": fullname.split("::")[-1],
                           "x": [ticks[k] for k in keys], "y": [float(v) for v in line["median"]], "text": text,
                           "hovertemplate": "%{text}<extra></extra>", "line": {"color": colour, "width": 1.6},
                           "marker": {"color": colour, "size": 6}})
        layout = _layout(f"{name}: median seconds", "median seconds (s)", {k: v for k, v in zip(ticks, ticks.values())},
                         bool((rows["median"] > 0).all()))
        layout["xaxis"]["title"]["text"] = "benchmark session (oldest → newest)"
        layout["showlegend"] = True
        layout["legend"] = {"font": {"size": 9.5}, "orientation": "h", "y": -0.45}
        layout["height"] = 340
        layout["margin"]["b"] = 110
        layout["shapes"] = [{"type": "line", "xref": "x", "yref": "paper", "x0": ticks[k], "x1": ticks[k], "y0": 0,
                             "y1": 1, "line": {"color": "#b45309", "width": 1.5, "dash": "dash"}} for k in changed]
        layout["annotations"] = [{"xref": "x", "yref": "paper", "x": ticks[k], "y": 1.0, "yanchor": "bottom",
                                  "text": "machine changed", "showarrow": False,
                                  "font": {"size": 10, "color": "#b45309"}} for k in changed]
        charts.append(Chart(f"bench-{len(charts)}", name, {"data": traces, "layout": layout}, {}))
    return charts


# ---------------------------------------------------------------------------------------------
# interactive charts (plotly.js, inlined once per page; figures as JSON beside their <div>)
#: the id of the page's one inline copy of plotly.js (`external_references` skips its text: the URLs
#: in it are map-tile attributions and the "made with" link of features this page does not use)
PLOTLY_SCRIPT_ID = "plotly-js"
#: the marker of a chart's box in a section's HTML (a page with none gets no plotly.js)
PLOT_BOX = 'class="plot-box"'
#: plotly options for every chart: no logo link, no "edit in chart studio", resized with the window
PLOTLY_CONFIG = {"displaylogo": False, "responsive": True, "showLink": False, "showSendToCloud": False,
                 "modeBarButtonsToRemove": ["sendDataToCloud", "lasso2d", "select2d"]}
#: where values are positive, these metrics span decades: a log axis
LOG_METRICS = ("nshd", "hausdorff", "chamfer", "time_s", "cpu_time_s")


@dataclass
class Chart:
    """One interactive chart: ``figure`` is a plotly figure as plain JSON data ({"data", "layout"});
    ``filters`` are the values the page's filters match (sequence, holes, metric, scope)."""

    key: str
    title: str
    figure: dict
    filters: dict[str, str]


def plotly_library() -> str:
    """plotly.js of the installed plotly package (``plotly.offline.get_plotlyjs``), minified, ~4.8 MB."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


def holes_key(holes: str, holes_params: str) -> str:
    """A hole configuration as the page names it: 'region (count=2, preset=medium)'."""
    return holes + ("" if holes_params in ("", "{}") else f" ({compare.short_params(holes_params, 60)})")


def version_ticks(history: History) -> dict[str, str]:
    """Code version -> its x-axis label (`short_version`, made unique with '#k' if two collide)."""
    ticks, used = {}, set()
    for version in history.versions:
        label = short_version(version)
        k = 2
        while label in used:
            label, k = f"{short_version(version)}#{k}", k + 1
        used.add(label)
        ticks[version] = label
    return ticks


def t_interval(mean: float, std: float, n: int, level: float = 0.95) -> tuple[float, float] | None:
    """Student-t interval of the mean from a summary's population std over n values:
    mean ± t_{(1+level)/2, n-1} · s / sqrt(n), s = std · sqrt(n / (n - 1)); None for n < 2 or no std."""
    from scipy.stats import t

    if n is None or n < 2 or std is None or math.isnan(std) or math.isnan(mean):
        return None
    half = float(t.ppf((1 + level) / 2, n - 1)) * std * math.sqrt(n / (n - 1)) / math.sqrt(n)
    return mean - half, mean + half


def _spread(std, n, mean=float("nan")) -> str:
    """'± 0.12 std, 95 % CI [a, b], n = 3' (the std over frames and seeds, the t-interval of the
    mean, and how many values they are over)."""
    known_n = n is not None and not (isinstance(n, float) and math.isnan(n))
    n_text = f"n = {int(n)}" if known_n else "n = ?"
    if std is None or (isinstance(std, float) and math.isnan(std)):
        return n_text
    interval = t_interval(float(mean), float(std), int(n)) if known_n else None
    ci = f", 95 % CI [{_fmt(interval[0])}, {_fmt(interval[1])}]" if interval else ""
    return f"± {_fmt(std)} std{ci}, {n_text}"


def _point_text(history: History, label: str, row, note: str = "") -> str:
    """The hover text of one point: method, value ± std and n, commit, date, machine."""
    version = row.code_version
    machine = history.version_machines.get(version, "")
    carried = "" if bool(row.measured) else "<br><i>carried over: not rerun at this version</i>"
    return (f"<b>{html.escape(label)}</b><br>{_fmt(row.mean)} ({_spread(row.std, row.n_frames, row.mean)})<br>"
            f"commit {html.escape(str(version))}<br>{html.escape(history.version_dates.get(version, ''))}"
            + (f"<br>machine: {html.escape(machine)}" if machine else "") + carried + note)


def _trace(history: History, label: str, rows: pd.DataFrame, colour: str, ticks: dict[str, str], *,
           dash: str = "solid", notes: dict[str, str] | None = None, name: str | None = None) -> dict:
    """One method's line over code versions (in version order): filled markers where measured at that
    version, hollow where carried over from an earlier one; hover as `_point_text`."""
    order = {v: i for i, v in enumerate(history.versions)}
    rows = rows.assign(_x=rows["code_version"].map(order)).sort_values("_x")
    notes = notes or {}
    return {
        "type": "scatter", "mode": "lines+markers", "name": name or label,
        "x": [ticks[v] for v in rows["code_version"]],
        "y": [None if pd.isna(v) else float(v) for v in rows["mean"]],
        "text": [_point_text(history, label, r, notes.get(r.code_version, "")) for r in rows.itertuples(index=False)],
        "hovertemplate": "%{text}<extra></extra>",
        "line": {"color": colour, "width": 2, "dash": dash},
        "marker": {"color": colour, "size": 7,
                   "symbol": ["circle" if m else "circle-open" for m in rows["measured"].astype(bool)]},
    }


def _layout(title: str, y_title: str, ticks: dict[Any, str], log: bool) -> dict:
    # ticks: x key (a code version, or a benchmark session's (datetime, commit)) -> its label, in x order
    return {
        "title": {"text": title, "font": {"size": 12.5}, "x": 0.01, "xanchor": "left"},
        "height": 290, "margin": {"l": 62, "r": 14, "t": 34, "b": 62}, "showlegend": False,
        "hovermode": "closest", "font": {"family": "system-ui, DejaVu Sans, sans-serif", "size": 11},
        "paper_bgcolor": "#ffffff", "plot_bgcolor": "#ffffff",
        "xaxis": {"type": "category", "categoryorder": "array", "categoryarray": list(ticks.values()),
                  "tickangle": -30, "title": {"text": "code version (oldest → newest)", "font": {"size": 10.5}},
                  "gridcolor": "#e5e7eb"},
        "yaxis": {"type": "log" if log else "linear", "title": {"text": y_title, "font": {"size": 10.5}},
                  "gridcolor": "#e5e7eb", "zeroline": False,
                  **({"dtick": 1, "tickformat": "~g"} if log else {})},  # log: 0.01, 0.1, 1 (decades only)
    }


def quality_charts(history: History, colours: dict[str, str], metrics: list[str], paper: pd.DataFrame) -> list[Chart]:
    """One chart per (sequence, holes, metric, scope): x = code versions, one line per method
    configuration (dotted for a PSNR peak other than the default), the paper's value for the
    sequence as a dashed line in the method's colour."""
    ticks = version_ticks(history)
    charts: list[Chart] = []
    table = history.table
    keys = table[["sequence", "holes", "holes_params"]].drop_duplicates().sort_values(["sequence", "holes", "holes_params"])
    for sequence, holes, holes_params in keys.itertuples(index=False):
        sub = table[(table["sequence"] == sequence) & (table["holes"] == holes) & (table["holes_params"] == holes_params)]
        scopes = [s for s in ("frame", "holes") if s in set(sub["scope"])] + sorted(set(sub["scope"]) - {"frame", "holes"})
        paper_rows = paper[paper["sequence"] == sequence.lower()]
        for metric in metrics:
            for scope in scopes:
                cell = sub[(sub["scope"] == scope) & (sub["metric"] == metric)]
                if cell.empty:
                    continue
                traces = []
                for label in sorted(set(cell["label"]), key=list(colours).index):
                    for peak, line in cell[cell["label"] == label].groupby("peak", sort=True):
                        default_peak = peak in ("", "intrinsic")
                        traces.append(_trace(history, label, line, colours[label], ticks,
                                             dash="solid" if default_peak else "dot",
                                             name=label if default_peak else f"{label} @peak {peak}"))
                for ref in paper_rows[paper_rows["metric"] == metric].itertuples(index=False):
                    colour = next((v for k, v in colours.items() if k.split(" (")[0] == ref.method), "#6b7280")
                    traces.append({"type": "scatter", "mode": "lines", "name": f"paper: {ref.method}",
                                   "x": list(ticks.values()), "y": [ref.value] * len(ticks),
                                   "line": {"color": colour, "width": 1, "dash": "dash"}, "opacity": 0.7,
                                   "hovertemplate": f"paper (Tables 1-2): {html.escape(ref.method)} "
                                                    f"{_fmt(ref.value)}<extra></extra>"})
                log = metric in LOG_METRICS and bool((cell["mean"] > 0).all())
                title = f"{metric_label(metric)} · {scope}"
                charts.append(Chart(f"quality-{len(charts)}", title,
                                    {"data": traces, "layout": _layout(title, metric_label(metric), ticks, log)},
                                    {"sequence": sequence, "holes": holes_key(holes, holes_params),
                                     "metric": metric, "scope": scope}))
    return charts


def machine_changes(history: History) -> dict[str, str]:
    """Code version -> 'machine changed: A → B' where its machine differs from the previous version's
    (both known); versions are in `history.versions` order."""
    changes, previous = {}, None
    for version in history.versions:
        machine = history.version_machines.get(version)
        if machine and previous and machine != previous:
            changes[version] = f"machine changed: {previous} → {machine}"
        if machine:
            previous = machine
    return changes


def time_charts(history: History, colours: dict[str, str], metric: str = "time_s") -> list[Chart]:
    """Time per frame (``metric``: "time_s" wall, "cpu_time_s" CPU) over code versions, one chart per
    (sequence, holes), one line per method; a version run on another machine than the one before it
    gets a dashed vertical line, a label and a line in every hover that says so (times across
    machines are not comparable)."""
    ticks = version_ticks(history)
    changes = machine_changes(history)
    times = history.table[history.table["metric"] == metric]
    charts: list[Chart] = []
    for (sequence, holes, holes_params), rows in times.groupby(["sequence", "holes", "holes_params"], sort=True):
        notes = {v: f"<br><b>{html.escape(text)}</b>: not comparable with the point before" for v, text in changes.items()}
        traces = [_trace(history, label, rows[rows["label"] == label], colours[label], ticks, notes=notes)
                  for label in sorted(set(rows["label"]), key=list(colours).index)]
        shown = set(rows["code_version"])
        shapes = [{"type": "line", "xref": "x", "yref": "paper", "x0": ticks[v], "x1": ticks[v], "y0": 0, "y1": 1,
                   "line": {"color": "#b45309", "width": 1.5, "dash": "dash"}} for v in changes if v in shown]
        annotations = [{"xref": "x", "yref": "paper", "x": ticks[v], "y": 1.0, "yanchor": "bottom",
                        "text": "machine changed", "showarrow": False, "font": {"size": 10, "color": "#b45309"}}
                       for v in changes if v in shown]
        what = "CPU seconds per frame" if metric == "cpu_time_s" else "seconds per frame"
        title = f"{sequence} · {holes}: {what}"
        layout = _layout(title, f"{what} (s)", ticks, bool((rows["mean"] > 0).all()))
        layout.update(shapes=shapes, annotations=annotations)
        charts.append(Chart(f"{metric}-{len(charts)}", title, {"data": traces, "layout": layout},
                            {"sequence": sequence, "holes": holes_key(holes, holes_params)}))
    return charts


def _json_script(data, css_class: str) -> str:
    """``data`` as an inline JSON <script> (never executed; "</" escaped so it cannot end the element)."""
    import json

    text = json.dumps(data, separators=(",", ":"), allow_nan=False, default=str).replace("</", "<\\/")
    return f'<script type="application/json" class="{css_class}">{text}</script>'


def charts_html(charts: list[Chart], kind: str) -> str:
    """The charts as a grid of boxes (each with its filter values as data- attributes and an empty
    plot <div> that the page's script draws) and their figures as one JSON block."""
    boxes = []
    for chart in charts:
        attrs = "".join(f' data-{k}="{_e(v)}"' for k, v in chart.filters.items())
        caption = " · ".join(_e(chart.filters[k]) for k in ("sequence", "holes") if k in chart.filters)
        boxes.append(f'<figure class="plot-box" data-kind="{_e(kind)}"{attrs}><figcaption>{caption}</figcaption>'
                     f'<div class="plot" id="{_e(chart.key)}" data-fig="{_e(chart.key)}"></div></figure>')
    figures = {chart.key: chart.figure for chart in charts}
    return f'<div class="plots" data-chart="{_e(kind)}">{"".join(boxes)}</div>{_json_script(figures, "dash-figures")}'


def colour_key(labels, colours: dict[str, str]) -> str:
    """The methods' colours as a line of swatches (the charts carry no legend of their own)."""
    items = "".join(f'<span class="key-item"><span class="swatch" style="background:{colours[label]}"></span>'
                    f'{_e(label)}</span>' for label in sorted(set(labels), key=list(colours).index))
    return f'<p class="key">{items}</p>'


def filters_html(history: History, metrics: list[str]) -> str:
    """The filter bar: one <select> per filter (sequence, holes, metric, scope; '' = all). The page
    starts on the first quality metric so that it does not draw every chart at once."""
    table = history.table
    holes = sorted({holes_key(h, p) for h, p in zip(table["holes"], table["holes_params"])})
    scopes = [s for s in ("frame", "holes") if s in set(table["scope"])] + sorted(set(table["scope"]) - {"frame", "holes"})
    options = {"sequence": sorted(set(table["sequence"])), "holes": holes, "metric": metrics, "scope": scopes}
    start = {"metric": metrics[0] if metrics else ""}
    parts = []
    for name, values in options.items():
        items = [f'<option value=""{"" if start.get(name) else " selected"}>all</option>']
        for value in values:
            label = metric_label(value) if name == "metric" else value
            selected = " selected" if start.get(name) == value else ""
            items.append(f'<option value="{_e(value)}"{selected}>{_e(label)}</option>')
        parts.append(f'<label>{name} <select data-filter="{name}">{"".join(items)}</select></label>')
    return (f'<div class="filters" id="filters">{"".join(parts)}<span class="note" id="filter-count"></span>'
            f'</div>')


#: the page's behaviour: draw the charts the filters let through (each once, on first show), hide the others
DASHBOARD_JS = """
(function () {
  var figures = {};
  document.querySelectorAll('script.dash-figures').forEach(function (s) {
    var part = JSON.parse(s.textContent);
    for (var k in part) { figures[k] = part[k]; }
  });
  var config = %CONFIG%;
  function draw(div) {
    if (div.dataset.drawn) { Plotly.Plots.resize(div); return; }
    var f = figures[div.dataset.fig];
    Plotly.newPlot(div, f.data, f.layout, config);
    div.dataset.drawn = '1';
  }
  function apply() {
    var chosen = {};
    document.querySelectorAll('select[data-filter]').forEach(function (s) { chosen[s.dataset.filter] = s.value; });
    var shown = 0, total = 0;
    document.querySelectorAll('.plot-box').forEach(function (box) {
      var show = Object.keys(chosen).every(function (k) {
        var v = box.dataset[k];
        return chosen[k] === '' || v === undefined || v === chosen[k];
      });
      box.hidden = !show;
      total += 1;
      if (show) { shown += 1; draw(box.querySelector('.plot')); }
    });
    var count = document.getElementById('filter-count');
    if (count) { count.textContent = shown + ' of ' + total + ' charts shown'; }
  }
  document.querySelectorAll('select[data-filter]').forEach(function (s) { s.addEventListener('change', apply); });
  window.dashboardFilter = function (name, value) {
    var s = document.querySelector('select[data-filter="' + name + '"]');
    s.value = value; apply();
  };
  apply();
})();
"""


def page_scripts(with_plots: bool) -> str:
    """plotly.js (once) and the page's script, for the end of <body>; '' for a page without charts."""
    import json

    if not with_plots:
        return ""
    return (f'<script id="{PLOTLY_SCRIPT_ID}">{plotly_library()}</script>'
            f'<script>{DASHBOARD_JS.replace("%CONFIG%", json.dumps(PLOTLY_CONFIG))}</script>')


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
    configuration bench.reporting.paper gives its column (the paper configuration: variant=paper for the two
    graph methods, meshlab output=whole) where the store holds it, else at its defaults (for the
    graph methods: our tuned variant, not the paper configuration). ``runs`` (the store's runs
    table) supplies the labels that experiment configs gave to hole configurations ("coherent holes")."""
    from dpcbench.bench.reporting.paper import PAPER_METHODS
    from dpcbench.bench.reporting.tables import config_labels, given_labels

    proposed = "temporal-graph"
    others = [m for m in paper["method"].drop_duplicates() if m != proposed]
    # each method in its paper column's configuration (bench.reporting.paper), else at its defaults
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
                 and (described := _registry.describe(r.metric)) is not None and described.higher_is_better is not None}
        any_below = False
        best = {}
        for column in columns:
            metric = column[0]
            cell = sub[(sub["metric"] == metric) & (sub["scope"] == column[1]) & (sub["peak"] == column[2])]
            cell = cell.dropna(subset=["mean"])
            if len(cell) and metric not in compare.TIME_METRICS:
                best[column] = cell["mean"].max() if compare.higher_is_better(metric) else cell["mean"].min()
        head = "".join(f"<th>{short_metric_label(m)}<br><span class='note'>{_e(s)}"
                       f"{_e(' @' + p if p not in ('', 'intrinsic') else '')}</span></th>"
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
    #: the folder of the method and run pages, relative to the page ('' when they are not written)
    pages_dir: str = ""


def prepare_page(results: pd.DataFrame, runs: pd.DataFrame | None, benchmarks: pd.DataFrame | None,
                 baseline: tuple[pd.DataFrame, dict] | None, tolerances: dict[str, float] | None,
                 machines: dict[str, str] | None = None) -> Page:
    """The history, colours, metrics and latest comparison that the sections share; ``machines``
    (code version -> machine, e.g. of history summaries) adds to those of the runs table. Runs group by
    their cell (`compare.with_cells`: the run's identity minus its seed), never by a label alone."""
    if runs is not None and len(runs) and "run_id" in results.columns:
        results = compare.with_cells(results, runs)
    history = build_history(results, {**run_machines(runs), **(machines or {})})
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
            where = f" {base_meta['path']}" if base_meta.get("path") else ""
            compared_what = (f"code {short_version(history.versions[-1])} against the baseline summary "
                             f"(code {short_version(base_meta.get('code_version', '?'))}, {base_meta.get('date', '?')})"
                             f"{where}")
        else:
            base = history.table[history.table["code_version"] == history.versions[-2]]
            compared_what = (f"code {short_version(history.versions[-1])} against the previous version "
                             f"{short_version(history.versions[-2])}")
        comparison = compare.compare_summaries(base, current, tolerances)

    n_failed = 0
    if runs is not None and len(runs):
        n_failed = int(runs.loc[runs["status"] == "failed", "run_id"].nunique())
    n_bench = int(benchmarks["fullname"].nunique()) if benchmarks is not None and len(benchmarks) else 0
    n_sessions = int(benchmarks.drop_duplicates(["datetime", "commit"]).shape[0]) if benchmarks is not None and n_bench else 0
    return Page(results, runs, benchmarks, history, paper_reference(), colours, metrics_present, quality_metrics,
                comparison, compared_what, n_failed, n_bench, n_sessions)


def cards_section(page: Page) -> str:
    """The summary cards: code versions, runs (failed ones), regressions, best GPSNR D1, benchmarks."""
    history, results = page.history, page.results
    n_done = int(results.loc[~from_summary(results["run_id"]), "run_id"].nunique()) if len(results) else 0
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
        scope = "holes"
        if latest.empty:
            latest = history.table[(history.table["code_version"] == history.versions[-1])
                                   & (history.table["metric"] == "gpsnr_d1")]
            scope = "/".join(sorted(set(latest["scope"])))
        if len(latest):
            by_method = latest.groupby("label")["mean"].mean().sort_values(ascending=False)
            where = "in the holes (scope holes)" if scope == "holes" else f"scope {scope}"
            cards.append(_card("best GPSNR D1", by_method.index[0],
                               f"{by_method.iloc[0]:.2f} dB {where}, mean over sequences"))
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
    """The filter bar and one interactive chart per (sequence, holes, metric, scope) over code
    versions, the paper's values dashed."""
    history, paper = page.history, page.paper
    if not history.versions:
        return ""
    charts = quality_charts(history, page.colours, page.quality_metrics, paper)
    has_paper = bool(set(history.table["sequence"].str.lower()) & set(paper["sequence"]))
    paper_note = ("Dashed lines: the paper's Table 1 (GPSNR) and Table 2 (NSHD) values for this sequence."
                  if has_paper else
                  f"The paper's values (Tables 1-2) are for its own sequences ({', '.join(PAPER_SEQUENCES.values())}); "
                  "none is in this store, so no reference lines are drawn.")
    return (f'<section id="quality"><h2>Quality over code versions</h2><p class="note">Mean over frames (and seeds) '
            f'of the newest run per cell, per code version in time order; hover a point for its value, std, '
            f'number of values, commit, date and machine; drag to zoom, double-click to reset. Hollow points are '
            f'carried over from an earlier version (not rerun). Scope "frame" scores whole frames, "holes" only '
            f'the hole regions. {_e(paper_note)}</p>{filters_html(history, page.quality_metrics)}'
            f'{colour_key(history.table["label"], page.colours)}{charts_html(charts, "quality")}</section>')


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
        from dpcbench.bench.reporting.tables import d2_normals_note

        done = runs[runs["status"] == "done"]
        newest = done[done["code_version"].astype(str) == history.versions[-1]]
        normals_note = d2_normals_note(newest if len(newest) else done)  # the runs of the newest version
    peaks = sorted(p for p in set(history.table["peak"]) if p not in ("", "intrinsic"))
    peaks_note = "".join(f'"@{p}": PSNR with peak {p} (else the intrinsic peak). ' for p in peaks)
    return (f'<section id="latest"><h2>Latest results: {_e(short_version(history.versions[-1]))}</h2>'
            f'<p class="note">Mean ± std over frames; best per column in bold. {_e(peaks_note)}Columns: '
            f'{_e(metric_key(page.quality_metrics + list(compare.TIME_METRICS)))}. {_e(normals_note)}</p>'
            f'{latest_table(history, page.colours, page.quality_metrics)}</section>')


def speed_section(page: Page) -> str:
    """Time per frame over code versions and the pytest-benchmark history; '' when there is neither."""
    history, benchmarks = page.history, page.benchmarks
    speed = []
    changes = machine_changes(history) if history.versions else {}
    machine_note = (f' Dashed orange lines mark a change of machine ({len(changes)}): times on either side of one '
                    f'are not comparable.' if changes else '')
    charts = time_charts(history, page.colours) if history.versions else []
    if charts:
        speed.append(f'<h3>Inpainting time per frame (results store)</h3><p class="note">Wall seconds per frame, '
                     f'log scale; the filters above choose sequence and holes.{_e(machine_note)}</p>'
                     f'{charts_html(charts, "time")}')
    cpu_charts = time_charts(history, page.colours, "cpu_time_s") if history.versions else []
    if cpu_charts:
        speed.append(f'<h3>Inpainting CPU time per frame (results store)</h3><p class="note">user + system, all '
                     f'threads: on a loaded machine the wall time grows with the load, the CPU time barely does.</p>'
                     f'{charts_html(cpu_charts, "cpu-time")}')
    if page.n_bench:
        from dpcbench.bench.results import benchsuite

        bench_charts = benchmark_charts(benchmarks)
        latest_bench = benchsuite.latest_per_benchmark(benchmarks)
        rows = "".join(
            f'<tr><td>{_e(r.group or "")}</td><td>{_e(r.fullname)}</td><td class="num">{r.median:.4g}</td>'
            f'<td class="num">{r.min:.4g}</td><td class="num">{int(r.rounds)}</td>'
            f'<td>{_e(short_version(r.commit))}</td><td>{_e(str(r.datetime)[:16])}</td></tr>'
            for r in latest_bench.itertuples(index=False))
        speed.append(f'<h3>Benchmark suite (pytest-benchmark)</h3>'
                     f'<p class="note">{page.n_sessions} session(s); machines are shared and noisy: read trends, '
                     f'not single points.</p><div class="figure" data-chart="benchmarks" '
                     f'data-sessions="{page.n_sessions}">{charts_html(bench_charts, "benchmarks")}</div>'
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
    sums: dict[str, dict[str, float]] = {}
    for column in ("wall_time_s", "cpu_time_s"):
        if column not in once.columns:
            sums[column] = {}
            continue
        values = pd.to_numeric(once[column], errors="coerce")
        grouped = values.groupby(once["code_version"])
        sums[column] = {v: float(total) for v, total in grouped.sum(min_count=1).items() if not math.isnan(total)}
    return sums["wall_time_s"], sums["cpu_time_s"]


def readable_seconds(seconds: float | None) -> str:
    """A duration for people: '-' when unknown, '850 ms', '12.3 s', '4.5 min', '2.25 h'."""
    if seconds is None or (isinstance(seconds, float) and math.isnan(seconds)):
        return "-"
    seconds = float(seconds)
    if seconds < 1:
        return f"{seconds * 1000:.3g} ms"
    if seconds < 60:
        return f"{seconds:.3g} s"
    if seconds < 3600:
        return f"{seconds / 60:.3g} min"
    return f"{seconds / 3600:.3g} h"


def runs_section(page: Page) -> str:
    """Code versions with their dates, run counts and summed run times, and the failed runs with their messages."""
    history, results, runs = page.history, page.results, page.runs
    if not history.versions:
        return ""
    summarized = from_summary(results["run_id"])
    counts = results[~summarized].groupby("code_version")["run_id"].nunique()
    summaries = set(results.loc[summarized, "code_version"])
    wall, cpu = _run_seconds(runs)
    version_rows = "".join(
        f'<tr><td>{_e(short_version(v))}</td><td>{_e(v)}</td><td>{_e(history.version_dates[v])}</td>'
        f'<td>{_e(" + ".join(k for k, has in (("store", v in counts.index), ("summary", v in summaries)) if has))}</td>'
        f'<td class="num">{int(counts.get(v, 0))}</td><td class="num">{_e(readable_seconds(wall.get(v)))}</td>'
        f'<td class="num">{_e(readable_seconds(cpu.get(v)))}</td>'
        f'<td>{_e(history.version_machines.get(v, "-"))}</td></tr>' for v in reversed(history.versions))
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
            f'</th><th>first run (UTC)</th><th>from</th><th>runs</th><th>wall time</th><th>CPU time</th>'
            f'<th>machine</th></tr></thead>'
            f'<tbody>{version_rows}</tbody>'
            f'</table>{failed_html}</section>')


def _slug(text: str, limit: int = 48) -> str:
    slug = re.sub(r"[^0-9A-Za-z]+", "-", str(text)).strip("-").lower()[:limit]
    return f"{slug}-{hashlib.sha256(str(text).encode()).hexdigest()[:8]}"


def method_file(label: str) -> str:
    """The file name of a method configuration's page ('method-temporal-graph-1a2b3c4d.html')."""
    return f"method-{_slug(label)}.html"


def run_file(run_id: str) -> str:
    """The file name of a run's page."""
    return f"run-{_slug(run_id, 32)}.html"


def _runs_of(runs: pd.DataFrame | None, label: str | None = None) -> pd.DataFrame:
    """The runs (one row each), newest first; only those of method configuration ``label`` if given."""
    if runs is None or runs.empty:
        return pd.DataFrame(columns=[] if runs is None else runs.columns)
    once = runs.drop_duplicates("run_id").sort_values("created_at", ascending=False)
    if label is None:
        return once
    labels = [method_label(m, p or "{}") for m, p in zip(once["method"], once["method_params"])]
    return once[[lab == label for lab in labels]]


def runs_table(runs: pd.DataFrame, prefix: str) -> str:
    """One row per run with a link to its page (``prefix``: the pages' folder as seen from the page
    holding the table, '' from a page inside it)."""
    rows = []
    for r in runs.itertuples(index=False):
        label = method_label(r.method, r.method_params or "{}")
        status = "regressed" if r.status == "failed" else ""
        holes = holes_key(r.holes, compare._canonical_json(r.holes_params or "{}"))
        rows.append(f'<tr class="{status}"><td><a href="{_e(prefix + run_file(r.run_id))}">{_e(label)}</a></td>'
                    f'<td>{_e(r.sequence)}</td><td>{_e(holes)}</td><td class="num">{_e(r.seed)}</td>'
                    f'<td>{_e(short_version(r.code_version))}</td><td>{_e(str(r.created_at)[:16])}</td>'
                    f'<td>{_e(r.status)}</td><td class="num">{_e(readable_seconds(r.wall_time_s))}</td></tr>')
    return ("<table class='runs'><thead><tr><th>method</th><th>sequence</th><th>holes</th><th>seed</th><th>code</th>"
            "<th>finished (UTC)</th><th>status</th><th>wall time</th></tr></thead><tbody>" + "".join(rows)
            + "</tbody></table>")


def pages_section(page: Page) -> str:
    """The main page's links to the method and run pages; '' when the pages are not written."""
    if not page.pages_dir or not page.history.versions:
        return ""
    prefix = page.pages_dir + "/"
    labels = sorted(set(page.history.table["label"]), key=list(page.colours).index)
    methods = "".join(f'<li><span class="swatch" style="background:{page.colours[lab]}"></span>'
                      f'<a href="{_e(prefix + method_file(lab))}">{_e(lab)}</a></li>' for lab in labels)
    runs = _runs_of(page.runs)
    run_html = (f"<details><summary>all {len(runs)} runs of the store</summary>{runs_table(runs, prefix)}</details>"
                if len(runs) else '<p class="note">No runs table (the history comes from summaries only).</p>')
    return (f'<section id="pages"><h2>Methods and runs</h2><p class="note">A page per method configuration (its '
            f'values at every code version) and per run (per-frame values, a thumbnail of the fill, links to the '
            f'run folder and log).</p><ul class="methods">{methods}</ul>{run_html}</section>')


#: the sections of the page, in order (each returns '' when it has nothing to show)
SECTIONS = (comparison_section, quality_section, paper_section, latest_section, speed_section, pages_section,
            runs_section)


def stylesheet() -> str:
    """The page's CSS, a package data file (bench/static/dashboard.css) inlined in every page."""
    return resources.files("dpcbench.bench").joinpath("static").joinpath("dashboard.css").read_text(encoding="utf-8")


def render_dashboard(results: pd.DataFrame, *, runs: pd.DataFrame | None = None,
                     benchmarks: pd.DataFrame | None = None,
                     baseline: tuple[pd.DataFrame, dict] | None = None,
                     tolerances: dict[str, float] | None = None, title: str = "dpcbench regression dashboard",
                     sources: list[str] | None = None, machines: dict[str, str] | None = None,
                     pages_dir: str = "", prepared: Page | None = None) -> str:
    """The dashboard page as one HTML string (see the module docstring for its sections); with
    ``pages_dir`` (relative to the page) it links the method and run pages written there."""
    page = prepared or prepare_page(results, runs, benchmarks, baseline, tolerances, machines)
    page.pages_dir = pages_dir
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
        "<footer>dpcbench · self-contained page: every chart, number and script is inside this file"
        f"</footer></main>{page_scripts(any(PLOT_BOX in part for part in sections))}</body></html>\n"
    )


def shares_rows(summary: pd.DataFrame, results: pd.DataFrame) -> bool:
    """Whether a summary has a row of a cell the results have (same `compare.KEY_COLUMNS`), i.e.
    whether comparing them says anything (a baseline of other data would only list missing rows)."""
    if summary.empty or results.empty:
        return False
    mine = compare.summarize(results)[compare.KEY_COLUMNS]
    theirs = compare._normalize_keys(summary)[compare.KEY_COLUMNS]
    return len(mine.merge(theirs.drop_duplicates(), on=compare.KEY_COLUMNS)) > 0


def external_references(page: str) -> list[str]:
    """URLs the page would fetch (src/href/url() to http(s) or protocol-relative); [] for a static page.
    SVG namespace declarations (xmlns=...) are identifiers, not requests, and are not counted."""
    pattern = r"""(?:src|href)\s*=\s*["'](?:https?:)?//[^"']+|url\(\s*["']?(?:https?:)?//[^)]+\)|@import"""
    # the inlined plotly.js is not searched: its URLs are attributions of map layers this page never draws
    page = re.sub(rf'<script id="{PLOTLY_SCRIPT_ID}">.*?</script>', "", page, flags=re.DOTALL)
    return re.findall(pattern, page, flags=re.IGNORECASE)
