"""Method comparison tables in the paper's layout (rows = sequences, columns = methods), shared by
`reproduce-paper` and `report`.

A cell is the mean over the values of one metric in one scope with one PSNR peak, one value per
(frame, seed) of the row's sequence and damage (several seeds pool their frames), read from the
results store's tidy table (`bench.results.store.ResultsStore.results_frame`), with the Student-t 95%
interval of that mean over whole damages (`bench.results.stats.mean_interval` with the seeds as ``groups``: the
frames of one seed share its holes, so the seed is the unit; one seed: over its frames). Columns are compared paired, on the same
(frame, seed) pairs (`bench.results.stats.row_verdict`): bold marks the row's best when it is better than
every other column beyond its interval (Wilcoxon signed-rank, Holm-corrected, and a bootstrap interval that
resamples whole damages: a seed with all its frames), `TIED_MARK` every column not distinguishable from the best; a row with too few pairs for
any claim has no bold and the caption says why. `FLOOR_MARK` marks a cell worse than the floor
(`FLOOR_METHOD`, the damaged input left as it is). Every value of a table has the same number of
decimals, the paper's published values too: when given, they are printed as extra rows
"<sequence> (paper)" with their own best in bold (the CSV keeps them as printed). The conventions (metric, peak, scope, scale, n, the test) are printed
under every table. Labels are escaped for each format (`md_escape`, `latex_escape`, `csv_safe`).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from dpcbench.bench.experiment.records import run_env
from dpcbench.bench.reporting.latex_tables import latex_escape  # noqa: F401  (re-exported)
from dpcbench.bench.results import stats
from dpcbench.bench.results.compare import FLOOR_MARK, FLOOR_METHOD, TIED_MARK  # noqa: F401  (re-exported; their one source)


def damage_of(key: tuple[int, int]) -> int:
    """The damage of a table's pair key (frame, seed): its hole seed. The comparisons resample whole damages
    (`bench.results.stats.mean_difference_interval`)."""
    return key[1]


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


def md_escape(text) -> str:
    """A label as one Markdown table cell: backslash, ``|``, ``*``, ``_`` and backtick escaped, ``<``
    as ``&lt;`` (so no raw HTML starts), line breaks as spaces."""
    text = " ".join(str(text).splitlines())
    for ch in ("\\", "|", "*", "_", "`"):
        text = text.replace(ch, "\\" + ch)
    return text.replace("<", "&lt;")




def csv_safe(value):
    """A CSV field that a spreadsheet will not run as a formula: text starting with ``= + - @``, a tab
    or a carriage return gets a ``'`` prefix (numbers are left as they are)."""
    if isinstance(value, str) and value[:1] in ("=", "+", "-", "@", "\t", "\r"):
        return "'" + value
    return value


@dataclass
class ComparisonTable:
    """rows x columns of one metric; ``paper``: row -> column -> value (already in display scale).

    mean / std / n: per (row, column), the mean, the sample standard deviation (ddof=1) and the
    count of the cell's values; observations: per (row, column), {(frame, seed): value} (unscaled),
    the pairs `bench.results.stats` compares; ``floor``: the column that leaves the holes open (no fill).
    A cell shows its mean and the Student-t 95% interval of the mean over whole damages (`interval`).
    """

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
    observations: dict = field(default_factory=dict)
    floor: str | None = None

    def best(self, row: str, values: dict) -> str | None:
        """The column of the row's best mean (no statistics: see `verdict`)."""
        present = {c: values[(row, c)] for c in self.columns if (row, c) in values and not math.isnan(values[(row, c)])}
        if not present or self.higher_is_better is None:
            return None
        pick = max if self.higher_is_better else min
        return pick(present, key=present.__getitem__)

    def verdict(self, row: str) -> stats.RowVerdict:
        """`bench.results.stats.row_verdict` of the row's columns, over their (frame, seed) pairs."""
        cache = self.__dict__.setdefault("_verdicts", {})
        if row not in cache:
            cache[row] = stats.row_verdict({c: self.observations[(row, c)] for c in self.columns
                                            if (row, c) in self.observations}, self.higher_is_better,
                                           damage=damage_of)
        return cache[row]

    def interval(self, row: str, col: str) -> tuple[float, float]:
        """The 95% interval of the cell's mean, unscaled ((nan, nan) for fewer than 2 values): Student t with the
        damages (`damage_of`) as the unit, `bench.results.stats.mean_interval` with ``groups``."""
        pairs = self.observations.get((row, col), {})
        return stats.mean_interval(list(pairs.values()), groups=[damage_of(key) for key in pairs])

    def below_floor(self, row: str, col: str) -> bool:
        """Whether the cell's mean is worse than the floor column's mean of its row."""
        if (self.floor is None or col == self.floor or self.higher_is_better is None
                or (row, col) not in self.mean or (row, self.floor) not in self.mean):
            return False
        m, f = self.mean[(row, col)], self.mean[(row, self.floor)]
        return m < f if self.higher_is_better else m > f

    def _digits(self) -> int:
        """Decimals of every value of the table: ``decimals``, or (None) enough for 3 significant
        digits of the smallest non-zero mean, at least 2 and at most 6."""
        if self.decimals is not None:
            return self.decimals
        values = [abs(v * self.scale) for v in self.mean.values() if v and math.isfinite(v)]
        if not values:
            return 2
        return int(min(6, max(2, 2 - math.floor(math.log10(min(values))))))

    def _fmt(self, x: float) -> str:
        return f"{x:.{self._digits()}f}"

    def cell_text(self, row, col) -> str:
        """mean [low, high] (scaled), or the mean alone for a single value; "–" for no value."""
        if (row, col) not in self.mean:
            return "–"
        m = self.mean[(row, col)] * self.scale
        lo, hi = self.interval(row, col)
        if math.isnan(lo):
            return self._fmt(m)
        return f"{self._fmt(m)} [{self._fmt(lo * self.scale)}, {self._fmt(hi * self.scale)}]"

    def marks(self, row, col) -> tuple[bool, str]:
        """(bold, suffix marks) of a cell: bold for the best beyond every other's interval,
        `TIED_MARK` for a column not distinguishable from the best, `FLOOR_MARK` below the floor."""
        if (row, col) not in self.mean:
            return False, ""
        v = self.verdict(row)
        suffix = (TIED_MARK if v.verdicts.get(col) == stats.TIED else "") + (FLOOR_MARK if self.below_floor(row, col) else "")
        return v.bold == col, suffix

    def _paper_rows(self):
        for row in self.paper or {}:
            values = self.paper[row]
            pick = max if self.higher_is_better else min
            best = pick(values, key=values.get) if values and self.higher_is_better is not None else None
            yield row, values, best

    def sample_size(self) -> str:
        """n of the cells as frames x seeds ("3 frames x 3 seeds = 9 pairs"), or a range when cells differ."""
        sizes = set()
        for pairs in self.observations.values():
            frames, seeds = {k[0] for k in pairs}, {k[1] for k in pairs}
            sizes.add((len(frames), len(seeds), len(pairs)))
        if not sizes:
            return "n not recorded"
        text = [f"{f} frame{'s' * (f != 1)} x {s} seed{'s' * (s != 1)}" + (f" = {n} pairs" if n != f * s else
                                                                            f" = {n}") for f, s, n in sorted(sizes)]
        return "n = " + " or ".join(text)

    def conventions(self, latex: bool = False) -> str:
        """The table's conventions in words, for the Markdown table (cells ``mean [low, high]``, the
        paper's rows marked "(paper)") or with ``latex`` for `latex` (``mean ± half-width``, the
        paper's rows in italics)."""
        peak = f", PSNR peak {self.peak}" if self.peak else ""
        scale = f", in units of {1 / self.scale:.0e}".replace("e-0", "e-") if self.scale != 1 else ""
        direction = {True: "higher is better", False: "lower is better", None: "no better direction"}[
            self.higher_is_better]
        text = (f"Metric `{self.metric}` ({direction}){peak}, scope `{self.scope}` "
                f"({'whole frame' if self.scope == 'frame' else 'hole regions only'}){scale}. "
                + ("Cells: mean ± half-width of the 95% interval of the mean" if latex
                   else "Cells: mean [95% interval of the mean]")
                + " (Student t over whole damages: a seed's frames share its holes, so the seeds are the unit, with "
                  "their count - 1 degrees of freedom; one seed: over its frames)"
                + f"; {self.sample_size()} per cell (all frames of all seeds).")
        if self.paper:
            text += (f" Rows {'in italics' if latex else 'marked (paper)'}: the paper's published values, rounded to "
                     f"the table's {self._digits()} decimals (the CSV keeps them as printed).")
        if self.higher_is_better is not None and self.observations:
            text += (f" Bold: the row's best, beyond every other column ({stats.TEST_NAME}; a column is worse "
                     f"when its interval excludes 0 and its adjusted p <= {stats.ALPHA}); {TIED_MARK}: tied-best, "
                     "not distinguishable from the row's best (the best itself carries it when it cannot be "
                     "told apart from another).")
        if self.floor is not None and self.higher_is_better is not None:
            text += (f" {FLOOR_MARK}: below the floor, i.e. a mean worse than the `{self.floor}` column (the damaged "
                     "input with its holes left open): such a method makes the frame worse than doing nothing.")
        small = sorted({(v.n, len(v.comparisons)) for v in (self.verdict(r) for r in self.rows) if v.too_small})
        for n, k in small:
            text += " " + stats.too_small_text(n, k)
        return text

    def markdown(self) -> str:
        out = [f"**{md_escape(self.title)}**", "", "| Sequence | " + " | ".join(md_escape(c) for c in self.columns) + " |",
               "|---|" + "---|" * len(self.columns)]
        for row in self.rows:
            cells = []
            for c in self.columns:
                bold, suffix = self.marks(row, c)
                text = self.cell_text(row, c)
                cells.append((f"**{text}**" if bold else text) + suffix)
            out.append(f"| {md_escape(row)} | " + " | ".join(cells) + " |")
        for row, values, best in self._paper_rows():
            cells = [("–" if c not in values else (f"**{self._fmt(values[c])}**" if c == best else self._fmt(values[c])))
                     for c in self.columns]
            out.append(f"| *{md_escape(row)} (paper)* | " + " | ".join(cells) + " |")
        out += ["", f"_{self.conventions()}_"] + [f"_{note}_" for note in self.notes if note]
        return "\n".join(out) + "\n"

    def latex(self) -> str:
        """The table as a LaTeX float for a two-column paper (booktabs rules, short labels with a key,
        ``table`` or ``table*`` by its estimated width): `bench.reporting.latex_tables.comparison_latex`."""
        from dpcbench.bench.reporting.latex_tables import comparison_latex

        return comparison_latex(self)

    def csv(self) -> str:
        """One line per cell: mean, std, the 95% interval, n, the verdict (`bench.results.stats`), whether it is
        below the floor, and the conventions; the paper's values as source "paper". Text fields
        pass through `csv_safe`."""
        buf = io.StringIO()
        writer = csv.writer(buf)
        writer.writerow(["sequence", "source", "method", "mean", "std", "ci95_low", "ci95_high", "n_frames",
                         "verdict", "below_floor", "metric", "scope", "peak", "scale"])
        for row in self.rows:
            verdict = self.verdict(row)
            for c in self.columns:
                if (row, c) in self.mean:
                    lo, hi = self.interval(row, c)
                    writer.writerow([csv_safe(row), "ours", csv_safe(c), self.mean[(row, c)] * self.scale,
                                     self.std[(row, c)] * self.scale, lo * self.scale, hi * self.scale,
                                     self.n[(row, c)], verdict.verdicts.get(c, ""), self.below_floor(row, c),
                                     self.metric, self.scope, self.peak, self.scale])
        for row, values, _ in self._paper_rows():
            for c, v in values.items():
                writer.writerow([csv_safe(row), "paper", csv_safe(c), v, "", "", "", "", "", "", self.metric,
                                 self.scope, self.peak, self.scale])
        return buf.getvalue()


def uses_d2(metric: str) -> bool:
    """Whether a metric is a point-to-plane (D2) figure, whose value depends on the reference normals."""
    return metric in ("gpsnr_d2", "d2_mse")


def d2_normals_note(runs: pd.DataFrame, run_ids=None) -> str:
    """One sentence for table captions: which normals D2 used, read from the runs' stored
    ``env["d2_normals"]`` (`bench.execution.provenance.d2_normals_source`): "normals from file" or "estimated by
    PCA of 12 neighbours", per sequence when they differ; "" when ``runs`` is empty."""
    from dpcbench.bench.execution.provenance import D2_NORMALS_TEXT

    if runs is None or runs.empty:
        return ""
    runs = runs.drop_duplicates("run_id")
    if run_ids is not None:
        runs = runs[runs["run_id"].isin(set(run_ids))]
    by_sequence: dict[str, set] = {}
    for sequence, env in zip(runs["sequence"], runs["env"]):
        source = run_env(env).get("d2_normals")
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
                     paper: dict | None = None, notes: list[str] | None = None,
                     floor: str | None = None) -> ComparisonTable:
    """Build the table from the tidy results ``df`` (columns sequence, method, frame, seed, value, ...).

    column_of: function(df) -> Series of column labels (default: `method_labels`).
    columns/rows: order (default: as first seen). Missing cells print as "–".
    floor: the no-fill column's label (default: the column of registry method `FLOOR_METHOD`, if any).
    """
    sel = frame_values(df, metric, scope, peak).copy()
    sel["column"] = column_of(sel) if column_of else method_labels(sel)
    if "seed" not in sel:
        sel["seed"] = 0
    # one value per (cell, frame, seed): the pairs the statistics compare (duplicates, e.g. a run
    # listed in two experiments, are one value)
    per_pair = sel.groupby(["sequence", "column", "frame", "seed"])["value"].mean().reset_index()
    observations: dict = {}
    for r in per_pair.itertuples(index=False):
        observations.setdefault((r.sequence, r.column), {})[(int(r.frame), int(r.seed))] = float(r.value)
    mean = {k: float(np.mean(list(v.values()))) for k, v in observations.items()}
    std = {k: (float(np.std(list(v.values()), ddof=1)) if len(v) > 1 else 0.0) for k, v in observations.items()}
    n = {k: len(v) for k, v in observations.items()}
    rows = rows or list(dict.fromkeys(sel["sequence"]))
    columns = columns or list(dict.fromkeys(sel["column"]))
    if floor is None:
        registry = "registry_method" if "registry_method" in sel else "method"  # the name before any relabelling
        floor_rows = sel[sel[registry] == FLOOR_METHOD] if registry in sel else sel.iloc[:0]
        floor = floor_rows["column"].iloc[0] if len(floor_rows) else None
    return ComparisonTable(title or f"{metric} ({scope})", metric, scope, peak, higher_is_better(metric),
                           [r for r in rows if any((r, c) in mean for c in columns)], columns, mean, std, n,
                           scale=scale, decimals=decimals, paper=paper, notes=list(notes or []),
                           observations=observations, floor=floor if floor in columns else None)


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


def write_table(table: ComparisonTable, out_dir: Path, stem: str) -> dict[str, Path]:
    """``stem``.md / .tex / .csv in ``out_dir``; returns the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"md": out_dir / f"{stem}.md", "tex": out_dir / f"{stem}.tex", "csv": out_dir / f"{stem}.csv"}
    paths["md"].write_text(table.markdown())
    paths["tex"].write_text(table.latex())
    paths["csv"].write_text(table.csv())
    return paths


def hole_rows(df: pd.DataFrame, runs: pd.DataFrame) -> pd.DataFrame:
    """With more than one hole configuration in ``df``, a table row is a sequence and a hole
    configuration (``Human · coherent holes``: the config's label, else the generator and its
    distinguishing parameters), so that different damage is never averaged together."""
    df = df.copy()
    holes = config_labels(df["holes"], df["holes_params"], given=given_labels(runs, "holes"))
    if holes.nunique() > 1:
        df["sequence"] = df["sequence"] + " · " + holes
    return df
