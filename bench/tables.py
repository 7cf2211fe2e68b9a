"""Method comparison tables in the paper's layout (rows = sequences, columns = methods), shared by
`reproduce-paper` and `report`.

A cell is the mean ± standard deviation over frames (every frame of every run of that sequence and
method: several seeds pool their frames) of one metric in one scope with one PSNR peak, read from the
results store's tidy table (`bench.store.ResultsStore.results_frame`). Standard deviation is the
sample one (ddof=1; a cell of a single value shows the value alone). The best mean of each row is bold (highest for
higher-is-better metrics, lowest otherwise). The paper's published values, when given, are printed
as extra rows "<sequence> (paper)" with their own best in bold. The conventions (metric, peak,
scope, scale, frames) are printed under every table.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field

import pandas as pd


def higher_is_better(metric: str) -> bool | None:
    """The metric's direction from `metrics.registry.describe` (its one source); None for a metric
    without one (a fact about the input, or a name the registry does not know): no cell is bold."""
    from dpcbench.metrics.registry import describe

    entry = describe(metric)
    return None if entry is None else entry.higher_is_better


def config_labels(names: pd.Series, params: pd.Series, display: dict[str, str] | None = None,
                  given: dict | None = None) -> pd.Series:
    """A label per row for (name, canonical params JSON) pairs: the ``given`` label of the pair when
    the config named one, else the display name plus the parameters that this configuration sets
    and that differ between the configurations of the same name (``temporal-graph (beta=0.25)``;
    a configuration on the defaults keeps the bare name)."""
    display, given = display or {}, given or {}
    labels = {}
    frame = pd.DataFrame({"name": names, "params": params})
    pairs = set(zip(frame["name"], frame["params"]))
    # a label given to a grid (several configurations) is shared: those configurations keep it and
    # add their distinguishing parameters, so that they are never merged into one column or row
    shared = {lab for lab in {given.get(pair) for pair in pairs} - {None}
              if sum(given.get(pair) == lab for pair in pairs) > 1}
    for name, group in frame.groupby("name"):
        configs = sorted(group["params"].unique())
        parsed = {c: json.loads(c) for c in configs}
        keys = sorted({k for p in parsed.values() for k in p})
        varying = [k for k in keys if len({json.dumps(p.get(k)) for p in parsed.values()}) > 1]
        for c, p in parsed.items():
            shown = ", ".join(f"{k}={p[k]}" for k in varying if k in p)
            base = given.get((name, c)) or display.get(name, name)
            if given.get((name, c)) in shared or not given.get((name, c)):
                base = f"{base} ({shown})" if shown else base
            labels[(name, c)] = base
    return pd.Series([labels[(n, p)] for n, p in zip(names, params)], index=names.index)


def method_labels(df: pd.DataFrame, names: dict[str, str] | None = None, given: dict | None = None) -> pd.Series:
    """A label per row of ``df`` for its method (see `config_labels`)."""
    return config_labels(df["method"], df["method_params"], names, given)


def given_labels(runs: pd.DataFrame, part: str) -> dict:
    """(name, params JSON) -> the label the experiment config gave to that ``part`` ("method" or
    "holes"), read from the stored run specs."""
    params = "method_params" if part == "method" else "holes_params"  # both canonical JSON in the store
    out = {}
    for spec, name, p in zip(runs["spec"], runs[part], runs[params]):
        label = (json.loads(spec).get(part) or {}).get("label") if spec else None
        if label:
            out[(name, p)] = label
    return out


@dataclass
class ComparisonTable:
    """rows x columns of mean/std/n; ``paper``: row -> column -> value (already in display scale)."""

    title: str
    metric: str
    scope: str
    peak: str
    higher_is_better: bool | None  # None: no direction (a fact about the input), nothing in bold
    rows: list[str]
    columns: list[str]
    mean: dict
    std: dict
    n: dict
    scale: float = 1.0
    unit: str = ""
    decimals: int | None = 2
    paper: dict | None = None
    notes: list[str] = field(default_factory=list)

    def best(self, row: str, values: dict) -> str | None:
        present = {c: values[(row, c)] for c in self.columns if (row, c) in values and not math.isnan(values[(row, c)])}
        if not present or self.higher_is_better is None:
            return None
        pick = max if self.higher_is_better else min
        return pick(present, key=present.get)

    def _cell(self, row, col, bold: bool, fmt_bold) -> str:
        if (row, col) not in self.mean:
            return "–"
        m, s = self.mean[(row, col)] * self.scale, self.std[(row, col)] * self.scale
        # one value (e.g. a sequence-level metric of one run) has no spread to show
        text = self._fmt(m) if self.n[(row, col)] < 2 else f"{self._fmt(m)} ± {self._fmt(s)}"
        return fmt_bold(text) if bold else text

    def _fmt(self, x: float) -> str:
        """``decimals`` fixed decimals; with decimals=None, 2 decimals for |x| >= 1, else 3 significant digits."""
        if self.decimals is not None:
            return f"{x:.{self.decimals}f}"
        return f"{x:.2f}" if abs(x) >= 1 or x == 0 else f"{x:.3g}"

    def _paper_rows(self):
        for row in self.paper or {}:
            values = self.paper[row]
            pick = max if self.higher_is_better else min
            best = pick(values, key=values.get) if values and self.higher_is_better is not None else None
            yield row, values, best

    def conventions(self) -> str:
        peak = f", PSNR peak {self.peak}" if self.peak else ""
        scale = f", in units of {1 / self.scale:.0e}".replace("e-0", "e-") if self.scale != 1 else ""
        direction = {True: "higher is better", False: "lower is better", None: "no better direction"}[
            self.higher_is_better]
        return (f"Metric `{self.metric}` ({direction}){peak}, scope `{self.scope}` "
                f"({'whole frame' if self.scope == 'frame' else 'hole regions only'}){scale}; "
                "mean ± std over frames (all frames of all seeds); best of each row in bold.")

    def markdown(self) -> str:
        out = [f"**{self.title}**", "", "| Sequence | " + " | ".join(self.columns) + " |",
               "|---|" + "---|" * len(self.columns)]
        for row in self.rows:
            best = self.best(row, self.mean)
            out.append(f"| {row} | " + " | ".join(self._cell(row, c, c == best, lambda t: f"**{t}**")
                                               for c in self.columns) + " |")
        for row, values, best in self._paper_rows():
            cells = [("–" if c not in values else (f"**{values[c]:.4f}**" if c == best else f"{values[c]:.4f}"))
                     for c in self.columns]
            out.append(f"| *{row} (paper)* | " + " | ".join(cells) + " |")
        out += ["", f"_{self.conventions()}_"] + [f"_{note}_" for note in self.notes]
        return "\n".join(out) + "\n"

    def latex(self) -> str:
        def esc(t: str) -> str:
            return t.replace("_", r"\_").replace("±", r"$\pm$").replace("&", r"\&")

        out = [r"\begin{table}[t]", r"\centering", rf"\caption{{{esc(self.title)}}}",
               r"\begin{tabular}{l" + "c" * len(self.columns) + "}", r"\hline",
               "Sequence & " + " & ".join(esc(c) for c in self.columns) + r" \\", r"\hline"]
        for row in self.rows:
            best = self.best(row, self.mean)
            cells = []
            for c in self.columns:
                text = esc(self._cell(row, c, False, str))
                cells.append(r"\textbf{" + text + "}" if c == best else text)
            out.append(esc(row) + " & " + " & ".join(cells) + r" \\")
        for row, values, best in self._paper_rows():
            cells = ["--" if c not in values else (rf"\textbf{{{values[c]:.4f}}}" if c == best else f"{values[c]:.4f}")
                     for c in self.columns]
            out.append(rf"\textit{{{esc(row)} (paper)}} & " + " & ".join(cells) + r" \\")
        out += [r"\hline", r"\end{tabular}", "", r"\smallskip", r"{\footnotesize " + esc(self.conventions())
                + "".join(" " + esc(n) for n in self.notes) + "}", r"\end{table}"]
        return "\n".join(out) + "\n"

    def csv(self) -> str:
        buf = io.StringIO()
        writer = csv.writer(buf)
        writer.writerow(["sequence", "source", "method", "mean", "std", "n_frames", "metric", "scope", "peak", "scale"])
        for row in self.rows:
            for c in self.columns:
                if (row, c) in self.mean:
                    writer.writerow([row, "ours", c, self.mean[(row, c)] * self.scale, self.std[(row, c)] * self.scale,
                                     self.n[(row, c)], self.metric, self.scope, self.peak, self.scale])
        for row, values, _ in self._paper_rows():
            for c, v in values.items():
                writer.writerow([row, "paper", c, v, "", "", self.metric, self.scope, self.peak, self.scale])
        return buf.getvalue()


def uses_d2(metric: str) -> bool:
    """Whether a metric is a point-to-plane (D2) figure, whose value depends on the reference normals."""
    return metric in ("gpsnr_d2", "d2_mse")


def d2_normals_note(runs: pd.DataFrame, run_ids=None) -> str:
    """One sentence for table captions: which normals D2 used, read from the runs' stored
    ``env["d2_normals"]`` (`bench.provenance.d2_normals_source`): "normals from file" or "estimated by
    PCA of 12 neighbours", per sequence when they differ; "" when ``runs`` is empty."""
    from dpcbench.bench.provenance import D2_NORMALS_TEXT

    if runs is None or runs.empty:
        return ""
    runs = runs.drop_duplicates("run_id")
    if run_ids is not None:
        runs = runs[runs["run_id"].isin(set(run_ids))]
    by_sequence: dict[str, set] = {}
    for sequence, env in zip(runs["sequence"], runs["env"]):
        try:
            source = json.loads(env).get("d2_normals") if isinstance(env, str) else None
        except ValueError:
            source = None
        by_sequence.setdefault(str(sequence), set()).add(source or "unknown")
    sources = set().union(*by_sequence.values()) if by_sequence else set()
    if not sources:
        return ""
    text = {**D2_NORMALS_TEXT, "unknown": "normals not recorded (runs made before dpcbench recorded them)"}
    if len(sources) == 1:
        return f"D2 (point-to-plane): {text[next(iter(sources))]}."
    parts = [f"{seq}: {' / '.join(text[s] for s in sorted(src))}" for seq, src in sorted(by_sequence.items())]
    return "D2 (point-to-plane): " + "; ".join(parts) + "."


def frame_values(df: pd.DataFrame, metric: str, scope: str, peak: str = "") -> pd.DataFrame:
    """The per-frame rows (frame >= 0) of one metric/scope/peak."""
    sel = df[(df["metric"] == metric) & (df["scope"] == scope) & (df["frame"] >= 0)]
    if peak:
        sel = sel[sel["peak"] == peak]
    return sel


def comparison_table(df: pd.DataFrame, metric: str, scope: str = "frame", peak: str = "", *,
                     title: str | None = None, column_of=None, columns: list[str] | None = None,
                     rows: list[str] | None = None, scale: float = 1.0, decimals: int | None = 2,
                     paper: dict | None = None, notes: list[str] | None = None) -> ComparisonTable:
    """Build the table from the tidy results ``df``.

    column_of: function(df) -> Series of column labels (default: `method_labels`).
    columns/rows: order (default: as first seen). Missing cells print as "–".
    """
    sel = frame_values(df, metric, scope, peak).copy()
    sel["column"] = column_of(sel) if column_of else method_labels(sel)
    grouped = sel.groupby(["sequence", "column"])["value"]
    stats = grouped.agg(["mean", "std", "count"]).reset_index()
    mean = {(r.sequence, r.column): float(r["mean"]) for _, r in stats.iterrows()}
    std = {(r.sequence, r.column): (0.0 if r["count"] < 2 else float(r["std"])) for _, r in stats.iterrows()}
    n = {(r.sequence, r.column): int(r["count"]) for _, r in stats.iterrows()}
    rows = rows or list(dict.fromkeys(sel["sequence"]))
    columns = columns or list(dict.fromkeys(sel["column"]))
    return ComparisonTable(title or f"{metric} ({scope})", metric, scope, peak, higher_is_better(metric),
                           [r for r in rows if any((r, c) in mean for c in columns)], columns, mean, std, n,
                           scale=scale, decimals=decimals, paper=paper, notes=list(notes or []))


def runtime_table(df: pd.DataFrame, column_of=None) -> pd.DataFrame:
    """Seconds per frame, wall (sequence-level time_s / frames) and CPU (sequence-level cpu_time_s /
    frames; NaN for runs recorded before CPU time was measured), and peak memory, per method and
    sequence (means over the runs)."""
    columns = ["sequence", "method", "s_per_frame", "cpu_s_per_frame", "peak_mem_mb"]
    seq = df[(df["metric"] == "time_s") & (df["frame"] == -1)].copy()
    if seq.empty:
        return pd.DataFrame(columns=columns)
    frames = df[df["frame"] >= 0].groupby("run_id")["frame"].nunique()
    seq["frames"] = seq["run_id"].map(frames).fillna(1)
    seq["s_per_frame"] = seq["value"] / seq["frames"]
    cpu = df[(df["metric"] == "cpu_time_s") & (df["frame"] == -1)].drop_duplicates("run_id").set_index("run_id")["value"]
    seq["cpu_s_per_frame"] = seq["run_id"].map(cpu).astype(float) / seq["frames"]
    mem = df[(df["metric"] == "peak_mem_mb") & (df["frame"] == -1)].drop_duplicates("run_id").set_index("run_id")["value"]
    seq["peak_mem_mb"] = seq["run_id"].map(mem)
    seq["method"] = column_of(seq) if column_of else method_labels(seq)
    return seq.groupby(["sequence", "method"])[columns[2:]].mean().reset_index()
