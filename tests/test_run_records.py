"""Run records (bench.experiment.records.RunRecord): what the store's `runs` table holds about a run, built in one
place for finished and failed runs, its columns the store's; rows round trip; and what a sweep stores
is what main stored (tests/data/run_rows_golden.json, written by main's code before RunRecord)."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from dpcbench.bench.execution.runner import _failure_record, run_experiment
from dpcbench.bench.experiment.config import parse_config
from dpcbench.bench.experiment.records import COLUMNS, RunRecord, run_record
from dpcbench.bench.results import store as store_module
from dpcbench.bench.results.store import ResultsStore
from tests import runner_fixtures as helpers

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "tests" / "data" / "run_rows_golden.json"
_ISO = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00$")


def _sweep(tmp_path: Path) -> Path:
    """A done and a failed run of a 2-frame sphere folder through the runner (serial); the store's path.
    The frames' modification times are fixed, so the data fingerprint and with it the run ids are too."""
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=300)
    for frame in seq.iterdir():
        os.utime(frame, ns=(1_700_000_000_000_000_000, 1_700_000_000_000_000_000))
    cfg = {"experiment": {"name": "t", "timeout_s": 120}, "sequences": [{"path": str(seq), "label": "sphere"}],
           "holes": [{"generator": "test-ball", "params": {"radius": 0.3}, "seed": 1}],
           "methods": [{"name": "test-identity", "params": {"shift": 0.5}}, {"name": "test-raises"}],
           "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]}}
    store = ResultsStore(tmp_path / "s.sqlite")
    run_experiment(parse_config(cfg).expand(), store, executor="serial", quiet=True)
    return store.path


def stored_rows(tmp_path: Path) -> dict:
    """The runs table of `_sweep`'s store with what varies between sweeps masked: the folder, the git
    commit, times and the machine (their SQLite types are kept), the traceback's frames (its last line kept)."""
    path = _sweep(tmp_path)
    conn = sqlite3.connect(path)
    try:
        schema = conn.execute("SELECT sql FROM sqlite_master WHERE name = 'runs'").fetchone()[0]
        cur = conn.execute("SELECT * FROM runs ORDER BY method")
        columns = [d[0] for d in cur.description]
        rows = [dict(zip(columns, r)) for r in cur.fetchall()]
        types = conn.execute("SELECT " + ", ".join(f"typeof({c})" for c in columns) + " FROM runs ORDER BY method")
        types = [dict(zip(columns, t)) for t in types.fetchall()]
    finally:
        conn.close()
    commit = rows[0]["code_version"]
    out = []
    for row in rows:
        masked = {}
        for column, value in row.items():
            if isinstance(value, str):
                value = value.replace(str(tmp_path.resolve()), "<tmp>").replace(str(tmp_path), "<tmp>")
                value = value.replace(commit, "<commit>")
            if column in ("created_at", "finished_at"):
                assert _ISO.match(value), value
                value = "<iso time>"
            elif column in ("wall_time_s", "cpu_time_s", "peak_mem_mb") and value is not None:
                value = "<number>"
            elif column == "env":
                env = json.loads(value)
                if "traceback" in env:
                    env["traceback"] = env["traceback"].strip().splitlines()[-1]
                else:  # the machine, packages and versions vary; which facts are recorded does not
                    env = {k: (v if k in ("frames_reused", "d2_normals", "git_commit") else "<machine>")
                           for k, v in env.items()}
                value = env
            masked[column] = value
        out.append(masked)
    return {"schema": schema, "columns": columns, "rows": out, "types": types}


def test_a_sweep_stores_what_main_stored(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)  # workers import tests.runner_fixtures from the repo root
    assert stored_rows(tmp_path) == json.loads(GOLDEN.read_text())


def _spec(tmp_path):
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=100)
    cfg = {"experiment": {"name": "t"}, "sequences": [{"path": str(seq), "label": "sphere"}],
           "holes": [{"generator": "test-ball", "params": {"radius": 0.25}, "seed": 3}],
           "methods": [{"name": "test-identity", "params": {"shift": 1.0}}],
           "metrics": {"names": ["gpsnr_d1"]}}
    return parse_config(cfg).expand()[0]


def _record(**changes) -> RunRecord:
    base = dict(run_id="r1", status="done", error=None, sequence="Human", holes="region",
                holes_params={"preset": "medium", "count": 2}, seed=0, method="none", method_params={"k": 1.0},
                method_version="1", code_version="abc", spec={"run_id": "r1", "nested": {"b": [1, 2.5]}},
                wall_time_s=1.5, cpu_time_s=1.25, peak_mem_mb=80.0, env={"git_commit": "abc", "frames_reused": False},
                created_at="2026-12-03T08:00:00+00:00", finished_at="2026-12-03T08:00:02+00:00", output_dir="/x/r1")
    return RunRecord(**{**base, **changes})


def test_columns_are_the_fields_and_the_tables(tmp_path):
    assert COLUMNS == tuple(f.name for f in dataclasses.fields(RunRecord))
    assert store_module._RUN_TABLE_COLUMNS == list(COLUMNS)
    assert store_module.RUN_COLUMNS == ["run_id", "experiment", *COLUMNS[1:]]
    store = ResultsStore(tmp_path / "s.sqlite")
    conn = sqlite3.connect(store.path)
    try:
        table = [r[1] for r in conn.execute("PRAGMA table_info(runs)")]
    finally:
        conn.close()
    assert table == list(COLUMNS)
    assert list(store.runs_frame().columns) == store_module.RUN_COLUMNS


@pytest.mark.parametrize("record", [_record(), _record(status="failed", error="E: boom", output_dir=None,
                                                       peak_mem_mb=None, env={"log": None, "traceback": "T"})])
def test_rows_round_trip(record, tmp_path):
    row = record.to_row()
    assert len(row) == len(COLUMNS)
    assert row[COLUMNS.index("holes_params")] == '{"count":2,"preset":"medium"}'
    assert row[COLUMNS.index("method_params")] == '{"k":1.0}'  # stored as given, not normalised
    assert RunRecord.from_row(row) == record
    # through the store: the row read back is the row written
    store = ResultsStore(tmp_path / "s.sqlite")
    store.record_run(record.run_id, record, [])
    if record.status == "failed":
        store.record_failure(record.run_id, record, record.error)
    conn = sqlite3.connect(store.path)
    conn.row_factory = sqlite3.Row
    try:
        stored = conn.execute("SELECT * FROM runs").fetchone()
    finally:
        conn.close()
    assert tuple(stored) == row
    assert RunRecord.from_row(stored) == record


def test_from_facts_fills_what_the_store_always_filled():
    record = RunRecord.from_facts("r2", {"sequence": "s", "output_dir": Path("/a/b"), "seed": np.int64(4)}, "failed",
                                  "E: x")
    assert (record.holes_params, record.method_params, record.spec, record.env) == ({}, {}, {}, {})
    assert record.output_dir == "/a/b" and record.method is None
    assert _ISO.match(record.created_at) and _ISO.match(record.finished_at)
    with pytest.raises(ValueError, match="unknown run facts experiment"):
        RunRecord.from_facts("r3", {"experiment": "e"}, "done")
    with pytest.raises(ValueError, match="status 'running'"):
        _record(status="running")


def test_done_and_failed_records_say_the_same_of_the_spec(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    spec = _spec(tmp_path)
    done = run_record(spec, status="done", code_version="c", wall_time_s=1.0, cpu_time_s=0.5, env={})
    failed = _failure_record(spec, {"wall_time_s": 2.0, "cpu_time_s": None, "log": "l", "traceback": "t"}, "E: x")
    from_spec = ("run_id", "sequence", "holes", "holes_params", "seed", "method", "method_params", "method_version",
                 "spec")
    assert {k: getattr(done, k) for k in from_spec} == {k: getattr(failed, k) for k in from_spec}
    assert (done.sequence, done.holes, done.holes_params, done.seed, done.method, done.method_params) == (
        "sphere", "test-ball", {"radius": 0.25}, 3, "test-identity", {"shift": 1.0})
    assert done.spec == spec.to_dict() and done.run_id == spec.run_id
    assert (failed.status, failed.error, failed.env, failed.wall_time_s) == ("failed", "E: x", {"log": "l", "traceback": "t"},
                                                                            2.0)


if __name__ == "__main__":  # writes the golden file: python -m tests.test_run_records (only on main's code)
    import tempfile

    helpers.register_global()
    with tempfile.TemporaryDirectory() as tmp:
        GOLDEN.write_text(json.dumps(stored_rows(Path(tmp)), indent=1, sort_keys=True) + "\n")


def test_run_env_reads_a_stored_env_and_gives_an_empty_dict_for_anything_else():
    from dpcbench.bench.experiment.records import run_env

    assert run_env('{"isa": "x86_64; unpinned", "machine": {"cpus": 2}}') == {"isa": "x86_64; unpinned",
                                                                              "machine": {"cpus": 2}}
    assert run_env(None) == run_env("") == run_env("{not json") == run_env("[1, 2]") == run_env(float("nan")) == {}
