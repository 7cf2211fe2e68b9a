"""Load saved pytest-benchmark runs (the speed history the dashboard plots).

pytest-benchmark writes one JSON document per session, with ``--benchmark-json=FILE`` or with
``--benchmark-autosave`` into its storage folder (``.benchmarks/<machine>/NNNN_<commit>_<date>.json``).
Each document holds ``machine_info``, ``commit_info`` (id, time, dirty, branch), ``datetime`` and a
list of ``benchmarks``, each with name, fullname, group, params, extra_info and ``stats`` (seconds:
min, max, mean, stddev, median, iqr, rounds, ops = 1/mean).

`load_benchmark_runs(paths)` flattens every benchmark of every document into one tidy row; the
dashboard groups rows by ``fullname`` and orders them by ``datetime``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd

from dpcbench.bench.core.errors import UserError

BENCHMARK_COLUMNS = [
    "source", "datetime", "commit", "commit_time", "dirty", "branch", "machine",
    "name", "fullname", "group", "param", "extra_info",
    "min", "max", "mean", "median", "stddev", "iqr", "rounds", "ops",
]
STAT_FIELDS = ("min", "max", "mean", "median", "stddev", "iqr", "rounds", "ops")


def benchmark_files(paths) -> list[Path]:
    """Every *.json below the given files/folders (a folder is searched recursively), sorted."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    files: list[Path] = []
    for entry in paths:
        entry = Path(entry)
        if entry.is_dir():
            files.extend(sorted(p for p in entry.rglob("*.json") if p.is_file()))
        elif entry.is_file():
            files.append(entry)
        else:
            raise UserError(f"{entry}: no such benchmark file or folder; run the suite with "
                             "`pytest tests/benchmarks --benchmark-only --benchmark-autosave` first")
    return files


def _is_benchmark_document(payload) -> bool:
    return isinstance(payload, dict) and isinstance(payload.get("benchmarks"), list) and "machine_info" in payload


def read_benchmark_json(path: str | os.PathLike) -> list[dict]:
    """The rows (see BENCHMARK_COLUMNS) of one pytest-benchmark JSON document.

    Raises ValueError for a file that is not JSON or not a pytest-benchmark document.
    """
    path = Path(path)
    try:
        payload = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise UserError(f"{path}: not a readable JSON file ({err})") from None
    if not _is_benchmark_document(payload):
        raise UserError(f"{path}: not a pytest-benchmark JSON document (no 'benchmarks' / 'machine_info')")
    commit = payload.get("commit_info") or {}
    machine_info = payload.get("machine_info") or {}
    cpu = machine_info.get("cpu") or {}
    machine = " ".join(str(x) for x in (machine_info.get("node"), cpu.get("brand_raw") or machine_info.get("machine"),
                                        f"{cpu.get('count')} cpus" if cpu.get("count") else None) if x)
    rows = []
    for bench in payload["benchmarks"]:
        stats = bench.get("stats") or {}
        row = {
            "source": str(path),
            "datetime": payload.get("datetime"),
            "commit": str(commit.get("id") or "unknown"),
            "commit_time": commit.get("time") or commit.get("author_time"),
            "dirty": bool(commit.get("dirty", False)),
            "branch": commit.get("branch"),
            "machine": machine,
            "name": bench.get("name"),
            "fullname": bench.get("fullname") or bench.get("name"),
            "group": bench.get("group") or "",
            "param": bench.get("param") or "",
            "extra_info": json.dumps(bench.get("extra_info") or {}, sort_keys=True),
        }
        row.update({field: stats.get(field) for field in STAT_FIELDS})
        rows.append(row)
    return rows


def load_benchmark_runs(paths, *, skip_invalid: bool = True) -> pd.DataFrame:
    """All benchmarks of all documents under ``paths`` as one DataFrame (BENCHMARK_COLUMNS).

    skip_invalid: ignore JSON files that are not pytest-benchmark documents (a storage folder may
    hold other files); with False they raise ValueError. ``datetime`` is parsed to UTC timestamps.
    """
    rows: list[dict] = []
    for path in benchmark_files(paths):
        try:
            rows.extend(read_benchmark_json(path))
        except UserError:  # a file that is not a pytest-benchmark document
            if not skip_invalid:
                raise
    df = pd.DataFrame(rows, columns=BENCHMARK_COLUMNS)
    # the same session saved twice (--benchmark-json and --benchmark-autosave) counts once
    df = df.drop_duplicates(["datetime", "commit", "fullname"])
    df["datetime"] = pd.to_datetime(df["datetime"], utc=True, errors="coerce", format="ISO8601")
    for field in STAT_FIELDS:
        df[field] = pd.to_numeric(df[field], errors="coerce")
    return df.sort_values(["datetime", "fullname"], kind="stable").reset_index(drop=True)


def latest_per_benchmark(runs: pd.DataFrame) -> pd.DataFrame:
    """The newest row of every benchmark (by fullname), sorted by group then name."""
    if runs.empty:
        return runs
    latest = runs.sort_values("datetime", kind="stable").groupby("fullname", sort=False).tail(1)
    return latest.sort_values(["group", "fullname"], kind="stable").reset_index(drop=True)


def format_benchmarks(runs: pd.DataFrame) -> str:
    """The newest figure of every benchmark as an aligned text table (median, min, rounds)."""
    latest = latest_per_benchmark(runs)
    if latest.empty:
        return "(no benchmarks)"
    table = pd.DataFrame({
        "benchmark": latest["fullname"],
        "median_s": latest["median"].map(lambda v: f"{v:.4g}"),
        "min_s": latest["min"].map(lambda v: f"{v:.4g}"),
        "rounds": latest["rounds"].astype("Int64"),
        "commit": latest["commit"].str[:10],
    })
    return table.to_string(index=False)
