"""The SQLite results store: schema, one-transaction idempotent writes, concurrency, corrupt files."""

from __future__ import annotations

import json
import multiprocessing
import sqlite3

import pandas as pd
import pytest

from dpcbench.bench.results.store import RESULT_COLUMNS, RUN_COLUMNS, ResultsStore, default_store_path


def _record(method="none", seed=0):
    return {"sequence": "human", "holes": "region", "holes_params": {"preset": "small"}, "seed": seed,
            "method": method, "method_params": {"k": 1}, "method_version": "1", "code_version": "abc",
            "spec": {"method": method}, "wall_time_s": 1.5, "peak_mem_mb": 100.0, "env": {"machine": "x"},
            "output_dir": "/tmp/x"}


def _results(n_frames=3, offset=0.0):
    rows = []
    for f in range(n_frames):
        rows.append({"frame": f, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic",
                     "value": 30.0 + f + offset})
        rows.append({"frame": f, "metric": "nshd", "scope": "holes", "peak": "", "value": 1e-7 * (f + 1)})
    rows.append({"frame": -1, "metric": "temporal_consistency", "scope": "holes", "peak": "", "value": 0.5})
    return rows


def test_default_location_is_env_or_user_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("DPCBENCH_STORE", str(tmp_path / "s.sqlite"))
    assert default_store_path() == tmp_path / "s.sqlite"
    monkeypatch.delenv("DPCBENCH_STORE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert default_store_path() == tmp_path / "cache" / "dpcbench" / "results.sqlite"


def test_round_trip_columns_and_wal(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    store.record_run("run1", _record(), _results(), experiments=["exp"])
    df = store.results_frame()
    assert list(df.columns) == RESULT_COLUMNS
    assert len(df) == 7
    assert set(df["frame"]) == {-1, 0, 1, 2}
    row = df[(df.metric == "gpsnr_d1") & (df.frame == 2)].iloc[0]
    assert row.value == 32.0 and row.peak == "intrinsic" and row.experiment == "exp"
    assert json.loads(row.holes_params) == {"preset": "small"}
    runs = store.runs_frame()
    assert list(runs.columns) == RUN_COLUMNS
    assert runs.iloc[0].status == "done" and runs.iloc[0].wall_time_s == 1.5
    with sqlite3.connect(tmp_path / "r.sqlite") as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_rerun_replaces_never_duplicates(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    store.record_run("run1", _record(), _results(3), experiments=["exp"])
    store.record_run("run1", _record(), _results(2, offset=5.0), experiments=["exp"])
    df = store.results_frame()
    assert len(df) == 5  # only the second write's rows
    assert df[(df.metric == "gpsnr_d1") & (df.frame == 0)].value.tolist() == [35.0]
    assert len(store.runs_frame()) == 1


def test_failure_drops_stale_results_and_keeps_message(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    store.record_run("run1", _record(), _results())
    store.record_failure("run1", _record(), "RuntimeError: boom")
    assert store.statuses() == {"run1": "failed"}
    assert store.results_frame().empty
    assert store.runs_frame().iloc[0].error == "RuntimeError: boom"


def test_experiments_share_runs(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    store.record_run("run1", _record(), _results(1), experiments=["a"])
    store.add_to_experiment("b", ["run1"])
    assert store.experiments() == ["a", "b"]
    assert len(store.results_frame("b")) == len(store.results_frame("a")) == 3
    assert len(store.results_frame()) == 6  # one row per experiment membership


def test_transaction_is_all_or_nothing(tmp_path):
    """A failure in the middle of a write (forced by a trigger) leaves the earlier state untouched."""
    path = tmp_path / "r.sqlite"
    store = ResultsStore(path)
    store.record_run("run1", _record(), _results(2))
    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TRIGGER boom BEFORE INSERT ON results WHEN NEW.metric = 'boom' "
                     "BEGIN SELECT RAISE(ABORT, 'forced failure'); END")
    bad = _results(3, offset=9.0) + [{"frame": 0, "metric": "boom", "scope": "frame", "peak": "", "value": 1.0}]
    with pytest.raises(sqlite3.IntegrityError):
        store.record_run("run1", _record(), bad)
    with pytest.raises(sqlite3.IntegrityError):
        store.record_run("run2", _record(), bad)
    assert store.statuses() == {"run1": "done"}
    df = store.results_frame()
    assert len(df) == 5 and df[(df.metric == "gpsnr_d1") & (df.frame == 0)].value.tolist() == [30.0]


def _writer(path, worker):
    store = ResultsStore(path)
    for i in range(10):
        store.record_run(f"w{worker}-{i}", _record(seed=i), _results(2), experiments=["conc"])


def test_concurrent_writers_do_not_corrupt(tmp_path):
    path = tmp_path / "r.sqlite"
    ResultsStore(path)
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_writer, args=(path, w)) for w in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    store = ResultsStore(path, readonly=True)
    assert len(store.statuses()) == 30
    assert len(store.results_frame()) == 30 * 5


def test_corrupt_or_foreign_file_gives_clear_error(tmp_path):
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is not sqlite at all" * 100)
    with pytest.raises(ValueError, match="move it aside"):
        ResultsStore(junk)
    foreign = tmp_path / "foreign.sqlite"
    with sqlite3.connect(foreign) as conn:
        conn.execute("CREATE TABLE t (x)")
    with pytest.raises(ValueError, match="not a dpcbench results store"):
        ResultsStore(foreign)
    with pytest.raises(ValueError, match="no results store there"):
        ResultsStore(tmp_path / "missing.sqlite", readonly=True)
    with pytest.raises(ValueError, match="is a folder"):
        ResultsStore(tmp_path)


def test_readonly_reader_sees_frames(tmp_path):
    ResultsStore(tmp_path / "r.sqlite").record_run("run1", _record(), _results(1))
    df = ResultsStore(tmp_path / "r.sqlite", readonly=True).results_frame()
    assert isinstance(df, pd.DataFrame) and len(df) == 3
