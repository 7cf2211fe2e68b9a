"""Regression summaries and their comparison (`dpcbench compare`).

A **summary** condenses the results store into one row per
(sequence, holes, holes_params, method, method_params, metric, scope, peak):

    mean     = (1/n) * sum_f value_f           over the n stored values (frames x seeds)
    std      = sqrt((1/n) * sum_f (value_f - mean)^2)   (population std, 0 for one value)
    n_frames = n

Only the latest run of each cell and seed enters (a cell: the run's canonical identity minus its
seed, `cell_identity`, where `with_cells` has read the runs' specs; else RUN_KEY minus the seed), so a
store holding several code versions summarizes the newest unless `code_version` is given; two
different cells that share a sequence label get labels that tell them apart (`with_cells`).
Frame-level values (frame >= 0) and sequence-level values (frame = -1) of the same metric are not
mixed: a (run, metric, scope, peak) with frame-level values uses only those; one without uses its
sequence-level value (e.g. temporal_consistency). Time is "time per frame": the runner stores
``time_s`` (wall) and ``cpu_time_s`` (CPU, user + system) per frame for per-frame methods, but only
the sequence total at frame -1 for methods that use neighbouring frames; such a total is divided by
the run's frame count.

A summary is saved as CSV (a ``# key: value`` header block, then the rows) or JSON
(``{"format": "dpcbench-summary", "meta": {...}, "rows": [...]}``); both carry ``meta`` with the
code version (git commit), the date and the environment that produced it. results/README.md
documents the format.

**Comparison** (`compare_summaries`): rows are matched on the key columns, and per metric kind
    "delta" (PSNR in dB, F-score):        change = current - baseline
    "ratio" (NSHD, Hausdorff, Chamfer,
             time, memory):               change = current / baseline   (0/0 -> 1)
A row REGRESSED when the change passes its tolerance in the bad direction (direction and change
kind from ``metrics.registry.describe(name)``, the one source of metric facts); improved when it
passes it in the good direction. Resource metrics
(time_s, cpu_time_s, peak_mem_mb) are compared and shown; time fails the gate only with
``gate_time=True``, memory (the worker's peak RSS, interpreter included) never.
**Which time is judged**: where a row's key has ``cpu_time_s`` on both sides, the CPU time is the
speed check (it barely moves with the machine's load, the wall time mostly measures the load) and
that key's ``time_s`` row is shown but never gated; elsewhere (a baseline or a store from before
CPU time was recorded) ``time_s`` is judged as before.
**The floor**: the text table marks (`FLOOR_MARK`, column "floor") each row whose current value is
worse than that of method `FLOOR_METHOD` ("none": the damaged input, holes left open) on the same
sequence, holes, metric, scope and peak (`below_floor`); the mark is information, never gated.
A row present in the baseline and absent from the current summary is MISSING and fails the gate
(a method that started crashing must not pass silently). Metrics without a tolerance, and
INFO_METRICS (facts about the damaged input, such as removed_fraction), are shown as "changed" or
✓ and never gated.
"""

from __future__ import annotations

import datetime as _dt
import io
import json
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from dpcbench.bench.core.atomic import atomic_write_text
from dpcbench.bench.core.canonical import sorted_json
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.execution.provenance import git_commit, summary_environment
from dpcbench.metrics import registry as _registry

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10, as bench.experiment.config
    import tomli as tomllib

#: what identifies one summary row (besides the metric values)
KEY_COLUMNS = ["sequence", "holes", "holes_params", "method", "method_params", "metric", "scope", "peak"]
SUMMARY_COLUMNS = KEY_COLUMNS + ["mean", "std", "n_frames"]
#: a run is one (data, damage, method) cell; the newest of each enters a summary
RUN_KEY = ["sequence", "holes", "holes_params", "seed", "method", "method_params"]
#: metrics that measure cost, not quality: gated only on request (machines are noisy)
RESOURCE_METRICS = tuple(_registry.RESOURCE_METRICS)
#: used when the tolerances file does not name a metric. PSNR in dB; ratios as factors (1.10 = 10 %).
DEFAULT_TOLERANCES = {
    "gpsnr_d1": 0.1, "gpsnr_d2": 0.1, "fscore": 0.01, "cpsnr_y": 0.1, "cpsnr_u": 0.1, "cpsnr_v": 0.1,
    "cpsnr_rgb": 0.1,
    "nshd": 1.10, "hausdorff": 1.10, "chamfer": 1.10, "temporal_consistency": 1.10,
    "time_s": 1.5, "cpu_time_s": 1.5, "peak_mem_mb": 1.5,
}
#: the time metrics (slower / faster, gated with --gate-time); the CPU time is preferred where both sides have it
TIME_METRICS = ("time_s", "cpu_time_s")
#: facts about the input, not the method (e.g. the share of points the holes removed): compared and
#: shown, never gated; a change means the data or the damage changed, which the table should show
INFO_METRICS = tuple(_registry.INPUT_METRICS)
#: per-frame times below this (seconds) are too noisy to gate on; compared but never REGRESSED
TIME_FLOOR_S = 0.05

STATUS_OK, STATUS_IMPROVED, STATUS_REGRESSED = "✓", "improved", "REGRESSED"
STATUS_MISSING, STATUS_NEW, STATUS_SLOWER, STATUS_FASTER = "MISSING", "new", "slower", "faster"
STATUS_CHANGED = "changed"
STATUS_MORE_MEMORY, STATUS_LESS_MEMORY = "more memory", "less memory"

SUMMARY_FORMAT = "dpcbench-summary"
#: the floor of every comparison: the registry method that leaves the damaged input as it is, and its mark
#: (the same as `bench.reporting.tables.FLOOR_METHOD` / `FLOOR_MARK`)
FLOOR_METHOD, FLOOR_MARK = "none", "▽"
#: the mark of a cell tied with the row's best (Markdown text; `bench.reporting.latex_tables.latex_escape` turns both marks
#: into LaTeX)
TIED_MARK = "†"


# ---------------------------------------------------------------------------------------------
# metric facts (metrics.registry is their one source)
def higher_is_better(metric: str) -> bool:
    """Direction of a metric, from `metrics.registry.describe`; UserError for a metric without one."""
    entry = _registry.describe(metric)
    if entry is None or entry.higher_is_better is None:
        known = [*_registry.METRICS, *_registry.RESOURCE_METRICS]
        raise UserError(f"metric {metric!r}: unknown direction (higher or lower is better); the metrics with "
                        f"a direction are those of metrics.registry: {', '.join(known)}")
    return entry.higher_is_better


def change_kind(metric: str) -> str:
    """'delta' for dB-valued and bounded scores, 'ratio' for distances, time and memory (a metric
    metrics.registry does not know is compared as a ratio)."""
    entry = _registry.describe(metric)
    return entry.change if entry is not None else "ratio"


# ---------------------------------------------------------------------------------------------
# summaries
def _canonical_json(text) -> str:
    """Parameters as canonical JSON text (sorted keys), so equal parameters always match."""
    if text is None or (isinstance(text, float) and math.isnan(text)) or text == "":
        return "{}"
    value = json.loads(text) if isinstance(text, str) else text
    return sorted_json(value)


def _normalize_keys(df: pd.DataFrame) -> pd.DataFrame:
    df = df.copy()
    for column in ("holes_params", "method_params"):
        df[column] = df[column].map(_canonical_json)
    for column in ("sequence", "holes", "method", "metric", "scope", "peak"):
        df[column] = df[column].fillna("").astype(str)
    return df


def _spec_identity(spec_text) -> dict | None:
    """`bench.experiment.config.RunSpec.identity` of a stored spec (what its ids hash, labels excluded), with the
    sequence's ``path`` kept (two folders are two sequences); None for a spec without sequence,
    holes and method (test stores, stores of old failures)."""
    from dpcbench.bench.experiment.config import RunSpec

    try:
        spec = json.loads(spec_text) if isinstance(spec_text, str) else dict(spec_text or {})
    except (TypeError, ValueError):
        return None
    if not all(isinstance(spec.get(k), dict) and spec.get(k) for k in ("sequence", "holes", "method")):
        return None
    fields = {"run_id": "", "inpaint_key": "", "experiment": "", "metrics": {}, "protocol": {}, "versions": {}}
    run = RunSpec(**{**fields, **{k: spec[k] for k in ("sequence", "holes", "method", "metrics", "protocol",
                                                       "versions") if k in spec}})
    identity = run.identity()
    identity["sequence"]["path"] = spec["sequence"].get("path")
    return identity


def cell_identity(spec_text) -> str | None:
    """A run's cell: the hash (`bench.experiment.config.stable_hash`) of its canonical identity
    (`RunSpec.identity`, the part of the run id that is not labels) minus the hole seed and minus
    the code versions, so that the seeds of one cell pool and a newer method version replaces an
    older one; None where the spec does not say (see `_spec_identity`)."""
    from dpcbench.bench.experiment.config import stable_hash

    identity = _spec_identity(spec_text)
    if identity is None:
        return None
    identity["holes"].pop("seed", None)
    identity.pop("versions", None)
    return stable_hash(identity)


def _flat(value, prefix: str = "") -> dict:
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flat(v, f"{prefix}{k}."))
        return out
    return {prefix[:-1]: json.dumps(value, sort_keys=True)}


def with_cells(results: pd.DataFrame, runs: pd.DataFrame | None) -> pd.DataFrame:
    """``results`` with a column ``cell`` (`cell_identity` of each run's stored spec; runs without a
    spec fall back to RUN_KEY minus the seed) and a ``sequence`` that tells different data apart: where
    runs that show one sequence label and one damage (holes and their parameters) differ in their
    sequence or protocol (e.g. two `human` with motion walk and dance), the label gets the settings
    that differ appended (``human (motion=dance)``).
    Tables, summaries, `compare` and the dashboard group by these, never by a label alone."""
    df = results.copy()
    if runs is None or runs.empty or "spec" not in runs.columns or df.empty:
        return df
    specs = runs.drop_duplicates("run_id").set_index("run_id")["spec"]
    identities = {rid: _spec_identity(specs.get(rid)) for rid in df["run_id"].unique() if rid in specs.index}
    cells = {rid: cell_identity(specs.get(rid)) for rid in identities}
    df["cell"] = df["run_id"].map(cells)
    # data part of a run: its sequence (name, params, frames, path) and protocol (regions, detection)
    data_part = {rid: _flat({"": ident["sequence"], "protocol": ident["protocol"]}) for rid, ident in identities.items()
                 if ident is not None}
    per_label = df.drop_duplicates("run_id")[["run_id", "sequence", "holes", "holes_params"]].copy()
    per_label["holes_params"] = per_label["holes_params"].map(_canonical_json)
    rename = {}
    # a table row (and a summary block) is a sequence label with one damage: different data there
    # would be averaged together, so that is where labels must differ
    for (label, _, _), group in per_label.groupby(["sequence", "holes", "holes_params"], sort=False):
        parts = {rid: data_part[rid] for rid in group["run_id"] if rid in data_part}
        distinct = {json.dumps(p, sort_keys=True) for p in parts.values()}
        if len(distinct) < 2:
            continue
        keys = sorted({k for p in parts.values() for k in p})
        varying = [k for k in keys if len({p.get(k) for p in parts.values()}) > 1]
        for rid, part in parts.items():
            shown = ", ".join(f"{k[len('.params.'):] if k.startswith('.params.') else k.lstrip('.')}="
                              f"{json.loads(part[k]) if k in part else '-'}" for k in varying)
            rename[rid] = f"{label} ({shown})"
    if rename:
        df["sequence"] = [rename.get(rid, seq) for rid, seq in zip(df["run_id"], df["sequence"])]
    return df


def newest_runs(results: pd.DataFrame) -> pd.DataFrame:
    """The rows of the newest run of each cell and seed, each run counted once. A cell is the
    ``cell`` column where `with_cells` added one (the run's identity minus the seed), else RUN_KEY
    minus the seed (data label, damage, method and parameters). A store keeps the runs of older code
    versions (a method's version changes its run ids), which must not be averaged with the current ones."""
    # a run in two experiments appears once per experiment in the store's table: count it once
    df = _normalize_keys(results.drop_duplicates(["run_id", "frame", "metric", "scope", "peak"]))
    key = RUN_KEY
    if "cell" in df.columns:
        # runs without a stored spec keep RUN_KEY (minus the seed) as their cell
        fallback = df[[k for k in RUN_KEY if k != "seed"]].astype(str).agg("|".join, axis=1)
        df["cell"] = df["cell"].where(df["cell"].notna(), "key:" + fallback)
        key = ["cell", "seed"]
    # the newest run per cell: its first created_at stands for the run
    run_times = df.groupby("run_id", sort=False, dropna=False).agg(created=("created_at", "min"),
                                                     **{k: (k, "first") for k in key})
    newest = run_times.sort_values("created").groupby(key, sort=False, dropna=False).tail(1).index
    return df[df["run_id"].isin(newest)]


def _population_std(values: pd.Series) -> float:
    """sqrt(mean((v - mean(v))^2)) over the non-NaN values; NaN when none is left or one is infinite."""
    finite = values.dropna().to_numpy(dtype=float)
    if len(finite) == 0 or not np.isfinite(finite).all():
        return math.nan
    return float(np.std(finite))


def _frame_level_values(df: pd.DataFrame) -> pd.DataFrame:
    """Per (run, metric, scope, peak): the frame-level rows if any, else the sequence-level ones,
    with a sequence-total time_s turned into seconds per frame (total / frames in the run)."""
    cell = ["run_id", "metric", "scope", "peak"]
    has_frames = df["frame"] >= 0
    covered = df.loc[has_frames, cell].drop_duplicates()
    sequence_level = df[~has_frames].merge(covered, on=cell, how="left", indicator="side")
    sequence_level = sequence_level[sequence_level["side"] == "left_only"].drop(columns="side")
    frame_counts = df.loc[has_frames].groupby("run_id")["frame"].nunique()
    is_total_time = sequence_level["metric"].isin(TIME_METRICS)
    # float even when empty (an empty map is of dtype object, which a float column refuses)
    counts = sequence_level.loc[is_total_time, "run_id"].map(frame_counts).astype(float).fillna(1).clip(lower=1)
    sequence_level.loc[is_total_time, "value"] = sequence_level.loc[is_total_time, "value"] / counts
    return pd.concat([df[has_frames], sequence_level], ignore_index=True)


def summarize(results: pd.DataFrame, *, experiment: str | None = None,
              code_version: str | None = None) -> pd.DataFrame:
    """One row per KEY_COLUMNS: mean, std (population) and count of the stored values.

    results: the store's tidy table (`ResultsStore.results_frame()`), columns at least RUN_KEY +
             run_id, metric, scope, peak, value, created_at (+ experiment, code_version to filter).
    Keeps, per RUN_KEY, only the run with the newest created_at, then averages over frames and seeds.
    Values that are NaN are left out of mean/std; n_frames counts the finite and infinite ones.
    Frame-level vs sequence-level values: see the module docstring.
    """
    required = set(RUN_KEY) | {"run_id", "metric", "scope", "peak", "value", "created_at"}
    missing = sorted(required - set(results.columns))
    if missing:
        raise UserError(f"results table lacks the columns {missing}; pass ResultsStore(path).results_frame()")
    df = results
    if experiment is not None:
        df = df[df["experiment"] == experiment]
    if code_version is not None:
        df = df[df["code_version"] == code_version]
    if df.empty:
        what = " and ".join(f"{k} {v!r}" for k, v in (("experiment", experiment), ("code version", code_version)) if v)
        raise UserError(f"no results to summarize{' for ' + what if what else ''}; run the experiment first "
                         "(dpcbench run CONFIG)")
    df = _frame_level_values(newest_runs(df))
    grouped = df.groupby(KEY_COLUMNS, sort=True)["value"]
    summary = grouped.agg(mean="mean", std=_population_std, n_frames="count").reset_index()
    summary["n_frames"] = summary["n_frames"].astype(int)
    return summary[SUMMARY_COLUMNS]


def summary_meta(code_version: str | None = None, *, results: pd.DataFrame | None = None,
                 environment: dict | None = None, **extra) -> dict:
    """The header block: code version, date (UTC, ISO), environment, plus any extra fields."""
    if code_version is None and results is not None and "code_version" in results.columns and len(results):
        versions = results["code_version"].dropna().unique()
        code_version = ",".join(sorted(map(str, versions)))
    meta = {
        "code_version": code_version or git_commit(),
        "date": _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
    }
    env = environment if environment is not None else summary_environment()
    meta.update({f"env.{k}": str(v) for k, v in env.items()})
    meta.update({k: str(v) for k, v in extra.items()})
    return meta


def write_summary(summary: pd.DataFrame, path: str | os.PathLike, meta: dict | None = None) -> Path:
    """Write a summary as .csv (``# key: value`` header lines, then the table) or .json; atomic."""
    path = Path(path)
    meta = dict(meta or {})
    summary = summary[SUMMARY_COLUMNS]
    if path.suffix.lower() == ".json":
        rows = json.loads(summary.to_json(orient="records", double_precision=15))
        text = json.dumps({"format": SUMMARY_FORMAT, "version": 1, "meta": meta, "rows": rows}, indent=1)
    elif path.suffix.lower() == ".csv":
        header = [f"# format: {SUMMARY_FORMAT} 1"] + [f"# {k}: {v}" for k, v in meta.items()]
        buffer = io.StringIO()
        summary.to_csv(buffer, index=False, float_format="%.12g", lineterminator="\n")
        text = "\n".join(header) + "\n" + buffer.getvalue()
    else:
        raise UserError(f"{path}: a summary file must end in .csv or .json")
    return atomic_write_text(path, text)  # a reader never sees half a file


def read_summary(path: str | os.PathLike) -> tuple[pd.DataFrame, dict]:
    """(summary table, meta) from a file written by `write_summary`."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: no such summary file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a text file, so not a summary; give a .csv/.json written by "
                        "`dpcbench compare --save-current`") from None
    if path.suffix.lower() == ".json":
        try:
            payload = json.loads(text)
        except json.JSONDecodeError as err:
            raise UserError(f"{path}: not valid JSON ({err}); regenerate it with dpcbench compare --save") from None
        if not isinstance(payload, dict) or payload.get("format") != SUMMARY_FORMAT:
            raise UserError(f"{path}: not a dpcbench summary (no \"format\": \"{SUMMARY_FORMAT}\")")
        table = pd.DataFrame(payload.get("rows", []), columns=SUMMARY_COLUMNS)
        meta = dict(payload.get("meta", {}))
    elif path.suffix.lower() == ".csv":
        lines = text.splitlines()
        meta = {}
        body_start = next((i for i, line in enumerate(lines) if not line.startswith("# ")), len(lines))
        for line in lines[:body_start]:
            key, _, value = line[2:].partition(": ")
            meta[key] = value
        if meta.get("format", "").split(" ")[0] != SUMMARY_FORMAT:
            raise UserError(f"{path}: not a dpcbench summary (first line must be '# format: {SUMMARY_FORMAT} 1')")
        meta.pop("format")
        body = "\n".join(lines[body_start:])
        try:
            table = pd.read_csv(io.StringIO(body), dtype={c: str for c in KEY_COLUMNS}, keep_default_na=False,
                                na_values={"mean": ["", "nan", "NaN"], "std": ["", "nan", "NaN"]})
        except (pd.errors.ParserError, pd.errors.EmptyDataError) as err:
            raise UserError(f"{path}: the table under the header is not valid CSV ({' '.join(str(err).split())}); "
                            "regenerate it with `dpcbench compare --save-current`") from None
    else:
        raise UserError(f"{path}: a summary file must end in .csv or .json")
    absent = [c for c in SUMMARY_COLUMNS if c not in table.columns]
    if absent:
        raise UserError(f"{path}: summary lacks the columns {absent}")
    table = _normalize_keys(table)
    table["mean"] = pd.to_numeric(table["mean"], errors="coerce")
    table["std"] = pd.to_numeric(table["std"], errors="coerce")
    table["n_frames"] = pd.to_numeric(table["n_frames"], errors="coerce").fillna(0).astype(int)
    return table[SUMMARY_COLUMNS], meta


# ---------------------------------------------------------------------------------------------
# tolerances
def load_tolerances(path: str | os.PathLike | None = None) -> dict[str, float]:
    """DEFAULT_TOLERANCES updated with the ``[tolerances]`` table of a TOML file (if given).

    Values: dB for "delta" metrics (0.1 = a PSNR drop of more than 0.1 dB regresses), factors > 1
    for "ratio" metrics (1.10 = more than 10 % worse regresses).
    """
    tolerances = dict(DEFAULT_TOLERANCES)
    if path is None:
        return tolerances
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise UserError(f"{path}: tolerances file not found") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a folder; give the tolerances TOML file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise UserError(f"{path}: not valid TOML ({err})") from None
    table = data.get("tolerances")
    if table is None:
        raise UserError(f"{path}: has no [tolerances] table; add e.g. '[tolerances]' then 'gpsnr_d1 = 0.1'")
    if not isinstance(table, dict):
        raise UserError(f"{path}: 'tolerances' must be a table of metric = number")
    for metric, value in table.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise UserError(f"{path}: tolerances.{metric}: expected a number, got {value!r}")
        if change_kind(metric) == "ratio" and value < 1:
            raise UserError(f"{path}: tolerances.{metric}: a ratio tolerance is a factor >= 1 (1.10 = 10 %), "
                             f"got {value}")
        if change_kind(metric) == "delta" and value < 0:
            raise UserError(f"{path}: tolerances.{metric}: a difference tolerance must be >= 0, got {value}")
        tolerances[metric] = float(value)
    return tolerances


# ---------------------------------------------------------------------------------------------
# comparison
def _change(kind: str, baseline: float, current: float) -> float:
    if kind == "delta":
        if math.isinf(baseline) and math.isinf(current) and baseline == current:
            return 0.0  # e.g. both PSNR inf (identical clouds)
        return current - baseline
    if baseline == 0:
        return 1.0 if current == 0 else math.inf
    return current / baseline


def _status(metric: str, kind: str, change: float, tolerance: float, baseline: float) -> str:
    """Status of one matched row; see the module docstring for the rule."""
    if math.isnan(change):
        return STATUS_REGRESSED  # a defined value became undefined (or the reverse): never pass silently
    better_high = higher_is_better(metric)
    if kind == "delta":
        worse, better = (change < -tolerance, change > tolerance) if better_high else (change > tolerance,
                                                                                      change < -tolerance)
    else:
        worse, better = (change < 1 / tolerance, change > tolerance) if better_high else (change > tolerance,
                                                                                         change < 1 / tolerance)
    if metric in TIME_METRICS:
        if abs(baseline) < TIME_FLOOR_S:
            return STATUS_OK
        return STATUS_SLOWER if worse else STATUS_FASTER if better else STATUS_OK
    if metric in RESOURCE_METRICS:
        return STATUS_MORE_MEMORY if worse else STATUS_LESS_MEMORY if better else STATUS_OK
    return STATUS_REGRESSED if worse else STATUS_IMPROVED if better else STATUS_OK


@dataclass
class Comparison:
    """The outcome of `compare_summaries`.

    table: one row per key present in either summary: KEY_COLUMNS + baseline, current, kind,
           change, tolerance, status, gated (True when this row can fail the comparison).
    failed: True when a gated row REGRESSED (or slower with gate_time) or is MISSING.
    """

    table: pd.DataFrame
    gate_time: bool = False
    baseline_meta: dict = field(default_factory=dict)
    current_meta: dict = field(default_factory=dict)

    @property
    def failures(self) -> pd.DataFrame:
        bad = self.table["status"].isin([STATUS_REGRESSED, STATUS_MISSING])
        if self.gate_time:
            bad |= self.table["status"] == STATUS_SLOWER
        return self.table[bad & self.table["gated"]]

    @property
    def failed(self) -> bool:
        return not self.failures.empty

    def counts(self) -> dict[str, int]:
        return {str(k): int(v) for k, v in self.table["status"].value_counts().items()}

    def format(self, *, only_changes: bool = False, width: int = 160) -> str:
        """A readable text table (see `format_comparison`)."""
        return format_comparison(self, only_changes=only_changes, width=width)


def compare_summaries(baseline: pd.DataFrame, current: pd.DataFrame, tolerances: dict[str, float] | None = None,
                      *, gate_time: bool = False) -> Comparison:
    """Match two summaries on KEY_COLUMNS and rate each change against its tolerance."""
    tolerances = dict(DEFAULT_TOLERANCES if tolerances is None else tolerances)
    base = _normalize_keys(baseline)[KEY_COLUMNS + ["mean"]].rename(columns={"mean": "baseline"})
    cur = _normalize_keys(current)[KEY_COLUMNS + ["mean"]].rename(columns={"mean": "current"})
    for name, table in (("baseline", base), ("current", cur)):
        duplicated = table.duplicated(KEY_COLUMNS)
        if duplicated.any():
            raise UserError(f"the {name} summary repeats {int(duplicated.sum())} key(s); "
                             "summaries have one row per (sequence, holes, method, params, metric, scope, peak)")
    merged = base.merge(cur, on=KEY_COLUMNS, how="outer", indicator="side")
    # keys (all but the metric) whose CPU time is known on both sides: there the CPU time is judged
    cpu = merged[(merged["metric"] == "cpu_time_s") & merged["baseline"].notna() & merged["current"].notna()]
    judged_by_cpu = set(map(tuple, cpu[[c for c in KEY_COLUMNS if c != "metric"]].itertuples(index=False)))
    rows = []
    for row in merged.itertuples(index=False):
        record = {c: getattr(row, c) for c in KEY_COLUMNS}
        metric = record["metric"]
        kind = change_kind(metric)
        informative = metric in INFO_METRICS or metric not in tolerances
        tolerance = math.nan if informative else tolerances[metric]
        b, c = float(row.baseline), float(row.current)
        if row.side == "left_only":
            change, status = math.nan, STATUS_MISSING
        elif row.side == "right_only":
            change, status = math.nan, STATUS_NEW
        elif math.isnan(b) and math.isnan(c):
            change, status = math.nan, STATUS_OK
        elif informative:
            change = _change(kind, b, c)
            status = STATUS_OK if math.isclose(b, c, rel_tol=1e-9, abs_tol=1e-12) else STATUS_CHANGED
        else:
            change = _change(kind, b, c)
            status = _status(metric, kind, change, tolerance, b)
        # time fails the comparison only on request, judged on the CPU time where both sides have it
        # (a missing CPU time falls back to the wall time, it does not fail); memory (process RSS,
        # interpreter included) never
        if metric == "time_s":
            key = tuple(record[c] for c in KEY_COLUMNS if c != "metric")
            gated = not informative and gate_time and key not in judged_by_cpu
        elif metric == "cpu_time_s":
            gated = not informative and gate_time and status != STATUS_MISSING
        else:
            gated = not informative and metric not in RESOURCE_METRICS
        record.update(baseline=b, current=c, kind=kind, change=change, tolerance=tolerance,
                      status=status, gated=gated)
        rows.append(record)
    table = pd.DataFrame(rows, columns=KEY_COLUMNS + ["baseline", "current", "kind", "change", "tolerance",
                                                      "status", "gated"])
    table = table.sort_values(["sequence", "holes", "method", "method_params", "scope", "metric", "peak"],
                              kind="stable").reset_index(drop=True)
    return Comparison(table=table, gate_time=gate_time)


# ---------------------------------------------------------------------------------------------
# text output
def _fmt_value(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    magnitude = abs(value)
    if magnitude != 0 and (magnitude < 1e-3 or magnitude >= 1e6):
        return f"{value:.4g}"
    return f"{value:.4f}" if magnitude < 100 else f"{value:.2f}"


def format_change(kind: str, change: float, metric: str = "") -> str:
    """'+0.12 dB' / '-0.012' for differences, 'x1.25' for ratios, '-' when undefined."""
    if change is None or math.isnan(change):
        return "-"
    if kind == "delta":
        unit = " dB" if metric.startswith("gpsnr") else ""
        return f"{0.0 if abs(change) < 5e-4 else change:+.3f}{unit}"  # no "-0.000"
    return "x inf" if math.isinf(change) else f"x{change:.3f}"


def format_tolerance(kind: str, tolerance: float, metric: str = "") -> str:
    if math.isnan(tolerance):
        return "info"
    if kind == "delta":
        return f"±{tolerance:g}{' dB' if metric.startswith('gpsnr') else ''}"
    return f"x{tolerance:g}"


def short_params(params_json: str, limit: int = 40) -> str:
    """Compact 'k=v, k=v' form of a params JSON text for tables."""
    try:
        params = json.loads(params_json) if params_json else {}
    except (TypeError, json.JSONDecodeError):
        return str(params_json)[:limit]
    if not isinstance(params, dict):
        return str(params)[:limit]
    text = ", ".join(f"{k}={v}" for k, v in params.items())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def format_comparison(comparison: Comparison, *, only_changes: bool = False, width: int = 160) -> str:
    """The comparison as text: one aligned table per (sequence, holes) block, then a verdict line.

    Columns: method (+ params), metric (@peak), scope, baseline, current, change, tolerance,
    floor (`FLOOR_MARK` where `below_floor`), status; the column widths are shared by all blocks so that they line up.
    """
    table = comparison.table
    below = below_floor(table)
    if only_changes:
        table = table[table["status"] != STATUS_OK]
        below = below[table.index]
    display = pd.DataFrame({
        "method": [m + (f" ({short_params(p)})" if p != "{}" else "") for m, p in
                   zip(table["method"], table["method_params"])],
        "metric": [m + (f"@{p}" if p else "") for m, p in zip(table["metric"], table["peak"])],
        "scope": table["scope"],
        "baseline": table["baseline"].map(_fmt_value),
        "current": table["current"].map(_fmt_value),
        "change": [format_change(k, c, m) for k, c, m in zip(table["kind"], table["change"], table["metric"])],
        "tolerance": [format_tolerance(k, t, m) for k, t, m in
                      zip(table["kind"], table["tolerance"], table["metric"])],
        "floor": [FLOOR_MARK if b else "" for b in below],
        "status": [s if g or s in (STATUS_OK, STATUS_NEW) else f"{s} (not gated)"
                   for s, g in zip(table["status"], table["gated"])],
    }, index=table.index)
    lines = []
    if display.empty:
        lines.append("(no rows)" if not only_changes else "(no changes beyond tolerance)")
    else:
        widths = {c: max(len(c), int(display[c].str.len().max())) for c in display.columns}
        left = {"method", "metric", "scope", "status", "floor"}

        def row_text(values: dict) -> str:
            cells = [str(values[c]).ljust(widths[c]) if c in left else str(values[c]).rjust(widths[c])
                     for c in display.columns]
            return "  ".join(cells).rstrip()

        blocks = table.groupby(["sequence", "holes", "holes_params"], sort=False)
        for (sequence, holes, holes_params), block in blocks:
            params = f" ({short_params(holes_params, 80)})" if holes_params != "{}" else ""
            lines.append(f"== {sequence} · holes: {holes}{params}")
            lines.append(row_text({c: c for c in display.columns}))
            for index in block.index:
                lines.append(row_text(display.loc[index].to_dict()))
            lines.append("")
    counts = comparison.counts()
    failures = comparison.failures
    verdict = (f"FAILED: {len(failures)} regression(s) beyond tolerance" if comparison.failed
               else "PASSED: no quality metric regressed beyond tolerance")
    summary = ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
    time_rows = comparison.table[comparison.table["metric"].isin(TIME_METRICS)]
    by_cpu = int(((time_rows["metric"] == "cpu_time_s") & time_rows["baseline"].notna()
                  & time_rows["current"].notna()).sum())
    judged = (f"; speed judged on CPU time for {by_cpu} of {int((time_rows['metric'] == 'time_s').sum())} "
              "time rows, on wall time for the others" if by_cpu else "")
    time_note = (judged if comparison.gate_time else f" (time compared, not gated: use --gate-time{judged})")
    if below.any():
        lines.append(f"{FLOOR_MARK} (column floor): the current value is worse than method `{FLOOR_METHOD}` (the damaged "
                     f"input, holes left open) on the same data: worse than not filling at all ({int(below.sum())} rows).")
    lines.append(f"{verdict}; {len(comparison.table)} rows: {summary}{time_note}")
    return "\n".join(lines)


def below_floor(table: pd.DataFrame) -> pd.Series:
    """Per row of a comparison table: whether its current value is worse (in the metric's direction)
    than the current value of method `FLOOR_METHOD` (no fill, default parameters) with the same
    sequence, holes, metric, scope and peak. Metrics without a direction, resources and input facts
    are never below the floor."""
    out = pd.Series(False, index=table.index)
    if table.empty:
        return out
    floor_rows = table[(table["method"] == FLOOR_METHOD) & (table["method_params"] == "{}")]
    keys = ["sequence", "holes", "holes_params", "metric", "scope", "peak"]
    floor = {tuple(r[k] for k in keys): r["current"] for _, r in floor_rows.iterrows()}
    for index, row in table.iterrows():
        metric = row["metric"]
        entry = _registry.describe(metric)
        if (row["method"] == FLOOR_METHOD or metric in RESOURCE_METRICS or metric in INFO_METRICS or entry is None
                or entry.higher_is_better is None):
            continue
        f = floor.get(tuple(row[k] for k in keys))
        c = row["current"]
        if f is None or c is None or math.isnan(f) or math.isnan(c):
            continue
        out[index] = c < f if entry.higher_is_better else c > f
    return out
