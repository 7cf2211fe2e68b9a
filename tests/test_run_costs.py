"""What a run cost and what made it: CPU time per run and per frame (worker, children, failures),
the store's schema-1 -> 2 migration, `dpcbench cost`, CPU time in reports / dashboard / compare,
and detected-region runs keyed by the detector's version and parameters."""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path

import pandas as pd
import pytest

from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.execution.runner import run_experiment
from dpcbench.bench.experiment.config import parse_config, stable_hash
from dpcbench.bench.results import compare
from dpcbench.bench.results.costs import cost_table, format_duration
from dpcbench.bench.results.store import SCHEMA_VERSION, ResultsStore
from dpcbench.holes.detection import DETECT_HOLES_VERSION
from tests import runner_fixtures as helpers

REPO = Path(__file__).resolve().parents[1]

# The schema of version 1 exactly as dpcbench wrote it before cpu_time_s (bench/results/store.py at df51db7).
SCHEMA_V1 = """
CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS runs (
    run_id TEXT PRIMARY KEY,
    status TEXT NOT NULL CHECK (status IN ('done', 'failed')),
    error TEXT,
    sequence TEXT, holes TEXT, holes_params TEXT, seed INTEGER,
    method TEXT, method_params TEXT, method_version TEXT, code_version TEXT,
    spec TEXT NOT NULL,
    wall_time_s REAL, peak_mem_mb REAL, env TEXT,
    created_at TEXT NOT NULL, finished_at TEXT, output_dir TEXT
);
CREATE TABLE IF NOT EXISTS experiment_runs (
    experiment TEXT NOT NULL,
    run_id TEXT NOT NULL,
    PRIMARY KEY (experiment, run_id)
);
CREATE TABLE IF NOT EXISTS results (
    run_id TEXT NOT NULL,
    frame INTEGER NOT NULL,
    metric TEXT NOT NULL,
    scope TEXT NOT NULL,
    peak TEXT NOT NULL DEFAULT '',
    value REAL,
    PRIMARY KEY (run_id, frame, metric, scope, peak)
);
CREATE INDEX IF NOT EXISTS results_run ON results (run_id);
"""


def make_v1_store(path: Path) -> None:
    """A store as the schema-1 code left it: two done runs (one method each) and a failed one."""
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA journal_mode = WAL")
    with conn:
        conn.executescript(SCHEMA_V1)
        conn.execute("INSERT INTO schema_version (version) VALUES (1)")
        runs = [("r1", "done", None, "none", 2.0, "2026-01-01T10:00:00+00:00", "2026-01-01T10:00:02+00:00"),
                ("r2", "done", None, "lozes-pde", 30.0, "2026-01-01T10:00:01+00:00", "2026-01-01T10:00:31+00:00"),
                ("r3", "failed", "RuntimeError: boom", "lozes-pde", 5.0, "2026-01-01T10:01:00+00:00",
                 "2026-01-01T10:01:05+00:00")]
        for run_id, status, error, method, wall, created, finished in runs:
            conn.execute("INSERT INTO runs VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                         (run_id, status, error, "human", "region", '{"preset":"small"}', 0, method, "{}", "1",
                          "old", '{"method":"x"}', wall, 100.0, "{}", created, finished, "/tmp/x"))
            conn.execute("INSERT INTO experiment_runs VALUES ('exp', ?)", (run_id,))
            if status == "done":
                conn.executemany("INSERT INTO results VALUES (?,?,?,?,?,?)",
                                 [(run_id, f, "gpsnr_d1", "frame", "intrinsic", 30.0 + f) for f in range(2)]
                                 + [(run_id, -1, "time_s", "frame", "", wall / 2)])
    conn.close()


def _schema_version(path: Path) -> int:
    conn = sqlite3.connect(path)
    try:
        return conn.execute("SELECT MAX(version) FROM schema_version").fetchone()[0]
    finally:
        conn.close()


# -- the store: schema 1 -> 2 -------------------------------------------------------------------------
def test_old_store_reads_read_only_unchanged_and_migrates_on_a_writable_open(tmp_path):
    path = tmp_path / "old.sqlite"
    make_v1_store(path)

    # read-only (reports, dashboard, compare, cost): every row, CPU time NULL, the file left at version 1
    old = ResultsStore(path, readonly=True, verify=True)
    assert old.schema_version == 1
    runs = old.runs_frame("exp")
    assert sorted(runs["run_id"]) == ["r1", "r2", "r3"] and runs["cpu_time_s"].isna().all()
    assert sorted(runs["wall_time_s"]) == [2.0, 5.0, 30.0]
    results_before = old.results_frame()
    assert len(results_before) == 6
    assert _schema_version(path) == 1

    # a writable open migrates in place and keeps every row
    store = ResultsStore(path)
    assert store.schema_version == SCHEMA_VERSION == 2 and _schema_version(path) == 2
    conn = sqlite3.connect(path)
    assert "cpu_time_s" in {r[1] for r in conn.execute("PRAGMA table_info(runs)")}
    conn.close()
    after = store.runs_frame("exp")
    pd.testing.assert_frame_equal(after.drop(columns="cpu_time_s"), runs.drop(columns="cpu_time_s"))
    assert after["cpu_time_s"].isna().all()
    pd.testing.assert_frame_equal(store.results_frame(), results_before)
    assert store.statuses() == {"r1": "done", "r2": "done", "r3": "failed"}

    # new runs carry their CPU time beside the old ones' NULL; a second open finds nothing to migrate
    store.record_run("r4", {"method": "none", "wall_time_s": 3.0, "cpu_time_s": 2.5, "spec": {}},
                     [{"frame": 0, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic", "value": 1.0}], ["exp"])
    again = ResultsStore(path, readonly=True)
    cpu = again.runs_frame("exp").set_index("run_id")["cpu_time_s"]
    assert cpu["r4"] == 2.5 and cpu[["r1", "r2", "r3"]].isna().all()
    assert ResultsStore(path).schema_version == 2 and _schema_version(path) == 2


def test_store_newer_than_the_code_is_refused(tmp_path):
    path = tmp_path / "new.sqlite"
    ResultsStore(path)
    conn = sqlite3.connect(path)
    with conn:
        conn.execute("UPDATE schema_version SET version = 3")
    conn.close()
    for readonly in (True, False):
        with pytest.raises(ValueError, match="schema version 3, this dpcbench reads versions 1, 2"):
            ResultsStore(path, readonly=readonly)


def test_cost_of_an_old_store_shows_unknown_cpu(tmp_path, capsys):
    path = tmp_path / "old.sqlite"
    make_v1_store(path)
    assert cli_main(["cost", str(path)]) == 0
    out = capsys.readouterr().out
    assert "3 stored run(s)" in out
    total = [line for line in out.splitlines() if line.startswith("total")][0]
    # 3 runs, 1 failed, wall 37 s, CPU unknown for all 3, elapsed 10:00:00 -> 10:01:05
    assert total.split()[:3] == ["total", "3", "1"] and "37.0 s" in total and "- (3 without)" in total
    assert "1 min 05 s" in total
    assert _schema_version(path) == 1  # `cost` only reads


# -- the costs table ---------------------------------------------------------------------------------------
def test_cost_table_sums_spans_and_counts_each_run_once():
    runs = pd.DataFrame({
        "run_id": ["a", "a", "b", "c"], "experiment": ["x", "y", "x", "x"], "status": ["done", "done", "done", "failed"],
        "method": ["m1", "m1", "m1", "m2"], "method_params": ["{}", "{}", "{}", '{"k":2}'],
        "wall_time_s": [10.0, 10.0, 20.0, 4.0], "cpu_time_s": [8.0, 8.0, math.nan, 3.0],
        "created_at": ["2026-01-01T00:00:00+00:00"] * 2 + ["2026-01-01T00:00:05+00:00", "2026-01-01T01:00:00+00:00"],
        "finished_at": ["2026-01-01T00:00:10+00:00"] * 2 + ["2026-01-01T00:00:25+00:00", "2026-01-01T01:00:04+00:00"],
    })
    table = cost_table(runs).set_index("method")
    assert list(table.index) == ["m1", "m2 (k=2)", "total"]
    m1, m2, total = table.loc["m1"], table.loc["m2 (k=2)"], table.loc["total"]
    assert (m1.runs, m1.done, m1.failed, m1.wall_s, m1.cpu_s, m1.cpu_missing, m1.span_s) == (2, 2, 0, 30.0, 8.0, 1, 25.0)
    assert (m2.runs, m2.failed, m2.wall_s, m2.cpu_s, m2.span_s) == (1, 1, 4.0, 3.0, 4.0)
    assert (total.runs, total.wall_s, total.cpu_s, total.cpu_missing) == (3, 34.0, 11.0, 1)
    assert total.span_s == 3604.0
    assert [format_duration(s) for s in (None, 4.25, 187.0, 7500.0)] == ["-", "4.2 s", "3 min 07 s", "2 h 05 min"]


# -- real runs -------------------------------------------------------------------------------------------
@pytest.fixture
def env(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)  # workers import tests.runner_fixtures from the repo root
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=400)
    return {"seq": seq, "store": ResultsStore(tmp_path / "store.sqlite"), "tmp": tmp_path}


def _cfg(seq, methods, *, regions="given", detection=None, name="t"):
    experiment = {"name": name, "timeout_s": 120, "regions": regions}
    if detection:
        experiment["detection"] = detection
    return {"experiment": experiment,
            "sequences": [{"path": str(seq), "label": "sphere"}],
            "holes": [{"generator": "test-ball", "params": {"radius": 0.3}, "seed": 1}],
            "methods": methods,
            "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]}}


def test_cpu_time_is_recorded_per_run_and_per_frame_with_children_and_failures(env):
    burn, child_burn, sleep = 0.3, 0.3, 0.5
    specs = parse_config(_cfg(env["seq"], [
        {"name": "test-costly", "params": {"burn": burn}, "label": "burns"},
        {"name": "test-costly", "params": {"child_burn": child_burn}, "label": "child"},
        {"name": "test-costly", "params": {"sleep": sleep}, "label": "sleeps"},
        {"name": "test-raises"},
        {"name": "test-crashes", "params": {"how": "exit"}},
    ])).expand()
    summary = run_experiment(specs, env["store"], executor="serial", quiet=True)
    assert len(summary.done) == 3 and len(summary.failed) == 2
    runs = env["store"].runs_frame("t").set_index("run_id")
    results = env["store"].results_frame("t")
    by_label = {s.method["label"]: s.run_id for s in specs if s.method.get("label")}

    def frame_values(run_id, metric):
        rows = results[(results["run_id"] == run_id) & (results["metric"] == metric)]
        return rows[rows["frame"] >= 0].sort_values("frame")["value"].to_numpy(), \
            float(rows[rows["frame"] == -1]["value"].iloc[0])

    # busy loop in the worker: every frame's CPU time is at least the burn; the run holds both frames
    per_frame, total = frame_values(by_label["burns"], "cpu_time_s")
    assert len(per_frame) == 2 and (per_frame >= burn).all() and total == pytest.approx(per_frame.sum())
    assert runs.loc[by_label["burns"], "cpu_time_s"] >= 2 * burn
    # a child process's CPU time counts too (RUSAGE_CHILDREN)
    per_frame, _ = frame_values(by_label["child"], "cpu_time_s")
    assert (per_frame >= child_burn).all() and runs.loc[by_label["child"], "cpu_time_s"] >= 2 * child_burn
    # sleeping takes wall time, not CPU time
    wall, _ = frame_values(by_label["sleeps"], "time_s")
    cpu, _ = frame_values(by_label["sleeps"], "cpu_time_s")
    assert (wall >= sleep).all() and (cpu < sleep / 2).all()
    assert runs.loc[by_label["sleeps"], "wall_time_s"] >= 2 * sleep
    assert runs.loc[by_label["sleeps"], "cpu_time_s"] < runs.loc[by_label["sleeps"], "wall_time_s"]
    # failures are timed too: a Python error by the worker, a crash by the driver (os.wait4)
    failed = runs[runs["status"] == "failed"]
    assert len(failed) == 2 and (failed["cpu_time_s"] > 0).all() and (failed["wall_time_s"] > 0).all()

    # the report and the dashboard show the CPU time beside the wall time
    from dpcbench.bench.reporting.dashboard import render_dashboard
    from dpcbench.bench.reporting.reports import write_comparison_report

    report = write_comparison_report(results, env["store"].runs_frame("t"), env["tmp"] / "report", title="t")
    text = report.read_text()
    assert "| Method | s / frame (mean over sequences) | CPU s / frame | peak RSS (MiB) |" in text
    burns_row = [line for line in text.splitlines() if line.startswith("| burns |")][0]
    assert float(burns_row.split("|")[3]) >= burn
    page = render_dashboard(results, runs=env["store"].runs_frame())
    assert 'data-chart="cpu-time"' in page and "CPU time per frame (s)" in page
    assert "<th>wall time</th><th>CPU time</th>" in page


def test_cost_command_on_a_real_sweep(env, capsys):
    config = _cfg(env["seq"], [{"name": "test-costly", "params": {"burn": [0.1, 0.2]}}, {"name": "test-identity"}])
    specs = parse_config(config).expand()
    run_experiment(specs, env["store"], executor="pool", jobs=2, quiet=True)
    store_path = str(env["store"].path)
    runs = env["store"].runs_frame("t")
    assert cli_main(["cost", store_path, "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    rows = {r["method"]: r for r in payload["rows"]}
    assert set(rows) == {"test-costly (burn=0.1)", "test-costly (burn=0.2)", "test-identity", "total"}
    assert payload["stored_runs"] == 3 and rows["total"]["runs"] == 3 and rows["total"]["cpu_missing"] == 0
    assert rows["total"]["wall_s"] == pytest.approx(runs["wall_time_s"].sum())
    assert rows["total"]["cpu_s"] == pytest.approx(runs["cpu_time_s"].sum())
    assert rows["test-costly (burn=0.2)"]["cpu_s"] >= 2 * 0.2  # two frames
    start = pd.to_datetime(runs["created_at"], format="ISO8601").min()
    finish = pd.to_datetime(runs["finished_at"], format="ISO8601").max()
    assert rows["total"]["span_s"] == (finish - start).total_seconds()
    # --config counts exactly the runs the config expands to (one more method: 3 of 4 stored)
    config["methods"].append({"name": "test-identity", "params": {"shift": 1.0}})
    toml = env["tmp"] / "c.toml"
    toml.write_text(_toml(config))
    assert cli_main(["cost", store_path, "--config", str(toml)]) == 0
    out = capsys.readouterr().out
    assert "3 stored run(s) of the 4 it expands to" in out and "test-identity" in out
    assert cli_main(["cost", store_path, "--experiment", "nope"]) == 2
    assert "no experiment 'nope'" in capsys.readouterr().err


def _toml(cfg: dict) -> str:
    def value(v):
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return json.dumps(v)

    lines = ["[experiment]"] + [f"{k} = {value(v)}" for k, v in cfg["experiment"].items()]
    for table in ("sequences", "holes", "methods"):
        for item in cfg[table]:
            lines += ["", f"[[{table}]]"] + [f"{k} = {value(v)}" for k, v in item.items()]
    lines += ["", "[metrics]"] + [f"{k} = {value(v)}" for k, v in cfg["metrics"].items()]
    return "\n".join(lines) + "\n"


# -- compare: the speed check on CPU time -----------------------------------------------------------------
def _summary(rows: list[tuple[str, float]], method: str = "m") -> pd.DataFrame:
    return pd.DataFrame([{"sequence": "s", "holes": "region", "holes_params": "{}", "method": method,
                          "method_params": "{}", "metric": metric, "scope": "frame", "peak": "", "mean": value,
                          "std": 0.0, "n_frames": 3} for metric, value in rows])


def test_speed_check_uses_cpu_time_where_both_sides_have_it():
    base = _summary([("gpsnr_d1", 30.0), ("time_s", 1.0), ("cpu_time_s", 1.0)])
    # wall time doubled by the load, CPU time unchanged: no regression even with --gate-time
    loaded = _summary([("gpsnr_d1", 30.0), ("time_s", 2.0), ("cpu_time_s", 1.05)])
    result = compare.compare_summaries(base, loaded, gate_time=True)
    rows = result.table.set_index("metric")
    assert rows.loc["time_s", "status"] == compare.STATUS_SLOWER and not rows.loc["time_s", "gated"]
    assert rows.loc["cpu_time_s", "status"] == compare.STATUS_OK and rows.loc["cpu_time_s", "gated"]
    assert not result.failed
    assert "speed judged on CPU time for 1 of 1 time rows" in result.format()
    # the method really got slower: CPU time doubled
    slower = _summary([("gpsnr_d1", 30.0), ("time_s", 1.0), ("cpu_time_s", 2.0)])
    result = compare.compare_summaries(base, slower, gate_time=True)
    assert result.failed and list(result.failures["metric"]) == ["cpu_time_s"]
    assert not compare.compare_summaries(base, slower).failed  # time is gated only on request
    # a baseline from before CPU time was recorded: the wall time is judged, a missing CPU row does not fail
    old_base = _summary([("gpsnr_d1", 30.0), ("time_s", 1.0)])
    result = compare.compare_summaries(old_base, loaded, gate_time=True)
    assert result.failed and list(result.failures["metric"]) == ["time_s"]
    current_without_cpu = _summary([("gpsnr_d1", 30.0), ("time_s", 1.0)])
    result = compare.compare_summaries(base, current_without_cpu, gate_time=True)
    rows = result.table.set_index("metric")
    assert rows.loc["cpu_time_s", "status"] == compare.STATUS_MISSING and not result.failed
    assert rows.loc["time_s", "gated"]


def test_summary_has_cpu_time_per_frame_and_saves_it(env, tmp_path):
    specs = parse_config(_cfg(env["seq"], [{"name": "test-costly", "params": {"burn": 0.2}}])).expand()
    run_experiment(specs, env["store"], executor="serial", quiet=True)
    summary = compare.summarize(env["store"].results_frame(), experiment="t")
    row = summary[summary["metric"] == "cpu_time_s"]
    assert len(row) == 1 and row["mean"].iloc[0] >= 0.2 and row["n_frames"].iloc[0] == 2
    written = compare.write_summary(summary, tmp_path / "base.csv", {"code_version": "x"})
    back, _ = compare.read_summary(written)
    assert back[back["metric"] == "cpu_time_s"]["mean"].iloc[0] == pytest.approx(row["mean"].iloc[0])
    # a sequence method's CPU total (frame -1 only) becomes seconds per frame, as its wall time does
    results = env["store"].results_frame()
    seq_only = results[~((results["metric"].isin(["time_s", "cpu_time_s"])) & (results["frame"] >= 0))]
    per_frame = compare.summarize(seq_only, experiment="t").set_index("metric")["mean"]
    total = results[(results["metric"] == "cpu_time_s") & (results["frame"] == -1)]["value"].iloc[0]
    assert per_frame["cpu_time_s"] == pytest.approx(total / 2)


# -- detected-region runs: the detector is part of the run's key -------------------------------------------
def test_a_detector_version_bump_reruns_detected_runs_and_only_those(env, monkeypatch):
    import dpcbench.holes.detection as detection

    methods = [{"name": "test-identity"}]
    detected = _cfg(env["seq"], methods, regions="detected", name="det")
    given = _cfg(env["seq"], methods, regions="given", name="giv")
    first = parse_config(detected).expand() + parse_config(given).expand()
    summary = run_experiment(first, env["store"], executor="serial", quiet=True)
    assert len(summary.done) == 2
    again = parse_config(detected).expand() + parse_config(given).expand()
    summary = run_experiment(again, env["store"], executor="serial", quiet=True)
    assert len(summary.cached) == 2 and not summary.done  # nothing changed: nothing re-run

    monkeypatch.setattr(detection, "DETECT_HOLES_VERSION", "2-test")
    bumped = parse_config(detected).expand()
    assert bumped[0].versions["detector"] == "2-test"
    assert bumped[0].run_id != first[0].run_id and bumped[0].inpaint_key != first[0].inpaint_key
    assert parse_config(given).expand()[0].run_id == first[1].run_id  # given regions: same key
    summary = run_experiment(bumped + parse_config(given).expand(), env["store"], executor="serial", quiet=True)
    assert summary.done == [bumped[0].run_id] and summary.cached == [first[1].run_id]
    # the new run made its own frames (a new run folder), from regions the detector computed again
    runs_dir = env["store"].path.parent / "runs"
    manifest = json.loads((runs_dir / bumped[0].inpaint_key / "manifest.json").read_text())
    assert manifest["regions_mode"] == "detected" and manifest["spec"]["versions"]["detector"] == "2-test"
    assert (runs_dir / first[0].inpaint_key).is_dir()

    # a changed detection parameter re-runs too
    tuned = parse_config(_cfg(env["seq"], methods, regions="detected", detection={"min_points": 4}, name="det"))
    summary = run_experiment(tuned.expand(), env["store"], executor="serial", quiet=True)
    assert len(summary.done) == 1


def test_given_region_keys_are_unchanged(monkeypatch):
    """The ids of given-region runs are those dpcbench computed before the detector entered the keys
    (values computed at df51db7): stored runs stay cached and the run folders are reused."""
    import dpcbench.bench.data.datasets as datasets

    helpers.register(monkeypatch)
    monkeypatch.setattr(datasets, "DATASETS_VERSION", "golden")
    cfg = {"experiment": {"name": "g", "regions": "given"},
           "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 2}],
           "holes": [{"generator": "test-ball", "params": {"radius": 0.3}, "seed": 1}],
           "methods": [{"name": "test-identity", "params": {"shift": 0.5}}],
           "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]}}
    spec = parse_config(cfg).expand()[0]
    assert spec.protocol == {"regions": "given"} and "detector" not in spec.versions
    assert spec.inpaint_key == "1a71151e471e7c22"
    assert spec.run_id == stable_hash({"inpaint": spec.inpaint_key, "metrics": spec.metrics,
                                       "metric_versions": spec.versions["metrics"]})
    # blind runs: each method runs detect_holes itself, so since detect_holes 2 their keys carry the
    # detector's version and differ from the key computed before (9f9f9367178929d4 at df51db7)
    cfg["experiment"]["regions"] = "none"
    blind = parse_config(cfg).expand()[0]
    assert blind.versions["detector"] == DETECT_HOLES_VERSION and blind.inpaint_key != "9f9f9367178929d4"
