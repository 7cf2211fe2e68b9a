"""What a set of stored runs cost: run counts, summed wall and CPU time, and the elapsed span
(`dpcbench cost`, the dashboard's code-version table).

From the store's runs table (`bench.results.store.ResultsStore.runs_frame`), one row per method
configuration and a total:

    runs     = stored runs (done + failed), each run once (a run in two experiments counts once)
    wall_s   = sum of wall_time_s over them (the run's span in its worker: load, damage, inpaint,
               write, score; a crashed or timed-out run: its whole worker process)
    cpu_s    = sum of cpu_time_s (user + system over the same span, every thread and child of
               the worker); runs without it (recorded before schema version 2, or whose CPU time
               could not be measured) are counted in ``cpu_missing`` and left out of the sum
    span_s   = last finished_at - first created_at: the elapsed time from the first run's start to
               the last run's finish. It includes the pauses between sweeps when the runs were made
               by several sweeps, and with parallel runs it is below wall_s (wall_s / span_s is the
               mean number of runs in flight).

Times in the store have one-second resolution (ISO timestamps), so span_s is exact to about 1 s.
"""

from __future__ import annotations

import math

import pandas as pd

#: columns of `cost_table`, in order
COST_COLUMNS = ["method", "runs", "done", "failed", "wall_s", "cpu_s", "cpu_missing", "first_start",
                "last_finish", "span_s"]
TOTAL = "total"


def _method_label(method: str, params_json) -> str:
    from dpcbench.bench.results.compare import short_params

    params = params_json if isinstance(params_json, str) else "{}"
    return method if params in ("", "{}") else f"{method} ({short_params(params, 48)})"


def _row(label: str, runs: pd.DataFrame) -> dict:
    wall = pd.to_numeric(runs["wall_time_s"], errors="coerce")
    cpu = pd.to_numeric(runs["cpu_time_s"], errors="coerce")
    start = pd.to_datetime(runs["created_at"], utc=True, errors="coerce", format="ISO8601")
    finish = pd.to_datetime(runs["finished_at"], utc=True, errors="coerce", format="ISO8601")
    first, last = start.min(), finish.max()
    span = (last - first).total_seconds() if not (pd.isna(first) or pd.isna(last)) else math.nan
    return {
        "method": label, "runs": len(runs), "done": int((runs["status"] == "done").sum()),
        "failed": int((runs["status"] == "failed").sum()),
        "wall_s": float(wall.sum(min_count=1)), "cpu_s": float(cpu.sum(min_count=1)),
        "cpu_missing": int(cpu.isna().sum()),
        "first_start": None if pd.isna(first) else first.isoformat(),
        "last_finish": None if pd.isna(last) else last.isoformat(),
        "span_s": span,
    }


def cost_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per method configuration (name + parameters, in order of first appearance) and a
    last row ``method == "total"``; columns `COST_COLUMNS` (see the module docstring). NaN sums
    where no run recorded the figure."""
    if runs.empty:
        return pd.DataFrame(columns=COST_COLUMNS)
    once = runs.drop_duplicates("run_id").copy()
    once["label"] = [_method_label(m, p) for m, p in zip(once["method"].fillna("?"), once["method_params"])]
    rows = [_row(label, group) for label, group in once.groupby("label", sort=False)]
    rows.append(_row(TOTAL, once))
    return pd.DataFrame(rows, columns=COST_COLUMNS)


def format_duration(seconds: float | None) -> str:
    """'-' (unknown), '4.2 s', '3 min 07 s', '2 h 05 min'."""
    if seconds is None or (isinstance(seconds, float) and math.isnan(seconds)):
        return "-"
    if seconds < 60:
        return f"{seconds:.1f} s"
    whole = int(round(seconds))
    if whole < 3600:
        return f"{whole // 60} min {whole % 60:02d} s"
    minutes = int(round(seconds / 60))
    return f"{minutes // 60} h {minutes % 60:02d} min"


def format_cost_table(table: pd.DataFrame) -> str:
    """The cost table as aligned text (durations humanised; CPU marked with how many runs lack it)."""
    if table.empty:
        return "(no runs)"
    shown = pd.DataFrame({
        "method": table["method"],
        "runs": table["runs"].astype(int).astype(str),
        "failed": table["failed"].astype(int).astype(str),
        "wall (sum)": table["wall_s"].map(format_duration),
        "CPU (sum)": [format_duration(c) + (f" ({m} without)" if m else "")
                      for c, m in zip(table["cpu_s"], table["cpu_missing"])],
        "CPU / wall": [f"{c / w:.2f}" if w and not (math.isnan(c) or math.isnan(w)) else "-"
                       for c, w in zip(table["cpu_s"], table["wall_s"])],
        "elapsed (first start -> last finish)": table["span_s"].map(format_duration),
    })
    widths = {c: max(len(c), int(shown[c].str.len().max())) for c in shown.columns}
    left = {"method"}

    def line(values) -> str:
        return "  ".join(str(v).ljust(widths[c]) if c in left else str(v).rjust(widths[c])
                         for c, v in zip(shown.columns, values)).rstrip()

    lines = [line(shown.columns)]
    for i, values in enumerate(shown.itertuples(index=False)):
        if table["method"].iloc[i] == TOTAL:
            lines.append(line("-" * widths[c] for c in shown.columns))
        lines.append(line(values))
    return "\n".join(lines)
