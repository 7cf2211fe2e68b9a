"""The runner: worker processes, failures recorded while others finish, caching and resume after a
kill, timeouts, frame reuse for new metrics, and the Dask executor against serial."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dpcbench.bench.execution.provenance import read_run_folder
from dpcbench.bench.execution.runner import run_experiment
from dpcbench.bench.experiment.config import parse_config
from dpcbench.bench.results.store import ResultsStore
from tests import runner_fixtures as helpers

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def env(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)  # workers import tests.runner_fixtures from the repo root
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=3, n_points=600)
    return {"seq": seq, "store": ResultsStore(tmp_path / "store.sqlite"), "tmp": tmp_path}


def _cfg(seq, methods, *, timeout=120, metrics=("gpsnr_d1", "nshd")):
    return {
        "experiment": {"name": "t", "timeout_s": timeout},
        "sequences": [{"path": str(seq), "label": "sphere"}],
        "holes": [{"generator": "test-ball", "params": {"radius": 0.3}, "seed": 1}],
        "methods": methods,
        "metrics": {"names": list(metrics), "peaks": ["intrinsic"], "scopes": ["frame", "holes"]},
    }


def test_failures_are_recorded_while_others_finish(env):
    specs = parse_config(_cfg(env["seq"], [
        {"name": "test-identity", "params": {"shift": [0.0, 0.01]}},
        {"name": "test-raises"},
        {"name": "test-crashes", "params": {"how": ["exit", "kill"]}},
    ])).expand()
    store = env["store"]
    summary = run_experiment(specs, store, executor="pool", jobs=2, quiet=True)
    assert len(summary.done) == 2 and len(summary.failed) == 3
    runs = store.runs_frame().set_index("method")
    errors = store.runs_frame().set_index("run_id")["error"]
    assert "RuntimeError: deliberate failure" in runs.loc["test-raises", "error"]
    crash_errors = sorted(errors[r] for r in summary.failed if "deliberate" not in errors[r])
    assert any("exited with code 7" in e for e in crash_errors)
    assert any("killed by signal SIGKILL" in e for e in crash_errors)

    df = store.results_frame()
    identity = df[(df.metric == "gpsnr_d1") & (df.scope == "frame") & (df.frame >= 0)]
    assert len(identity) == 2 * 3  # 2 runs x 3 frames
    # shifting the result must lower the score of every frame
    by_shift = identity.assign(shift=identity.method_params.map(lambda p: json.loads(p)["shift"]))
    pivot = by_shift.pivot_table(index="frame", columns="shift", values="value")
    assert (pivot[0.0] > pivot[0.01]).all()
    assert set(df.metric) >= {"gpsnr_d1", "nshd", "time_s", "peak_mem_mb", "removed_fraction"}
    times = df[(df.metric == "time_s") & (df.frame >= 0)]
    assert len(times) == 2 * 3 and (times.value >= 0).all()
    holes = df[(df.metric == "nshd") & (df.scope == "holes")]
    assert len(holes) == 2 * 3

    # frames are on disk: damaged frames lack the removed points, results as written
    done = store.runs_frame()
    folder = Path(done[done.status == "done"].iloc[0].output_dir)
    content = read_run_folder(folder)
    assert len(content["inpainted"]) == 3 and len(content["regions"]) == 3
    assert all(len(d) < 600 for d in content["damaged"])
    # the stored scores are metrics.score_frame of the frames as written, against the ground truth
    import dpcbench.metrics as metrics
    from dpcbench.bench.data.sequences import load_sequence

    truth = load_sequence(env["seq"]).points
    run_id = done[done.status == "done"].iloc[0].run_id
    stored = df[(df.run_id == run_id) & (df.metric == "gpsnr_d1")].set_index(["frame", "scope"])["value"]
    for f in range(3):
        whole = metrics.score_frame(truth[f], content["inpainted"][f], ["gpsnr_d1"], peak="intrinsic")["gpsnr_d1"]
        holes = metrics.score_frame(truth[f], content["inpainted"][f], ["gpsnr_d1"], peak="intrinsic",
                                    regions=content["regions"][f])["gpsnr_d1"]
        assert stored[(f, "frame")] == pytest.approx(whole, rel=1e-12)
        assert stored[(f, "holes")] == pytest.approx(holes, rel=1e-12)

    # rerun: everything cached (failures too), no new rows; --retry-failed redoes only the failures
    before = len(store.results_frame())
    again = run_experiment(specs, store, executor="serial", quiet=True)
    assert len(again.cached) == 2 and len(again.failed) == 3 and not again.done
    assert len(store.results_frame()) == before
    retried = run_experiment(specs, store, executor="serial", quiet=True, retry_failed=True)
    assert len(retried.cached) == 2 and len(retried.failed) == 3
    assert len(store.results_frame()) == before


def test_timeout_kills_a_hanging_run(env):
    flag = env["tmp"] / "hang.flag"
    flag.write_text("hang")
    # (that the other runs of a sweep still finish is shown by the failure test above)
    specs = parse_config(_cfg(env["seq"], [{"name": "test-hang", "params": {"flag": str(flag)}}], timeout=3)).expand()
    summary = run_experiment(specs, env["store"], executor="pool", jobs=2, quiet=True)  # the flag stays: killed
    assert summary.failed == [specs[0].run_id]
    assert "timed out after 3 s" in summary.errors[specs[0].run_id]
    assert env["store"].statuses() == {specs[0].run_id: "failed"}


def test_new_metric_reuses_frames_and_force_redoes(env):
    store = env["store"]
    specs = parse_config(_cfg(env["seq"], [{"name": "test-identity"}], metrics=("gpsnr_d1",))).expand()
    run_experiment(specs, store, executor="serial", quiet=True)
    more = parse_config(_cfg(env["seq"], [{"name": "test-identity"}], metrics=("gpsnr_d1", "chamfer"))).expand()
    assert more[0].run_id != specs[0].run_id and more[0].inpaint_key == specs[0].inpaint_key
    folder = Path(store.runs_frame().iloc[0].output_dir)
    stamp = (folder / "manifest.json").stat().st_mtime_ns
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["method_params_resolved"] == {"shift": 0.0}  # every parameter, defaults included
    run_experiment(more, store, executor="serial", quiet=True)
    runs = store.runs_frame().set_index("run_id")
    assert json.loads(runs.loc[more[0].run_id, "env"])["frames_reused"] is True
    assert (folder / "manifest.json").stat().st_mtime_ns == stamp
    df = store.results_frame()
    first = df[(df.run_id == specs[0].run_id) & (df.metric == "gpsnr_d1")].value.tolist()
    second = df[(df.run_id == more[0].run_id) & (df.metric == "gpsnr_d1")].value.tolist()
    assert first == second and "chamfer" in set(df[df.run_id == more[0].run_id].metric)
    forced = run_experiment(more, store, executor="serial", quiet=True, force=True)
    assert forced.done == [more[0].run_id]
    assert json.loads(store.runs_frame().set_index("run_id").loc[more[0].run_id, "env"])["frames_reused"] is False
    assert len(store.results_frame(status="done")[lambda d: d.run_id == more[0].run_id]) == len(
        df[df.run_id == more[0].run_id])


def _write_toml(path: Path, cfg: dict) -> Path:
    def value(v):
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return repr(v)

    lines = ["[experiment]"] + [f"{k} = {value(v)}" for k, v in cfg["experiment"].items()]
    for table in ("sequences", "holes", "methods"):
        for entry in cfg[table]:
            lines += ["", f"[[{table}]]"] + [f"{k} = {value(v)}" for k, v in entry.items()]
    lines += ["", "[metrics]"] + [f"{k} = {value(v)}" for k, v in cfg["metrics"].items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_kill_9_mid_sweep_then_rerun_loses_and_duplicates_nothing(env):
    """The driver is killed (SIGKILL) while one run hangs and another has finished; the rerun keeps
    the finished run untouched, redoes the rest, and stores each run exactly once."""
    tmp, store = env["tmp"], env["store"]
    flag = tmp / "hang.flag"
    flag.write_text("hang")
    cfg = _cfg(env["seq"], [{"name": "test-identity"}, {"name": "test-hang", "params": {"flag": str(flag)}},
                            {"name": "test-identity", "params": {"shift": 0.02}}])
    config = _write_toml(tmp / "exp.toml", cfg)
    cmd = [sys.executable, "-m", "tests.runner_fixtures", "run", str(config), "--store", str(store.path),
           "--executor", "serial", "--quiet"]
    driver = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    deadline = time.time() + 60
    logs = store.path.parent / "runs" / "logs"
    # wait until the first run is stored and the hanging run's worker has started
    while time.time() < deadline and not (len(store.statuses()) == 1 and len(list(logs.glob("*.log"))) == 2):
        time.sleep(0.2)
    assert len(store.statuses()) == 1, driver.communicate(timeout=5)[0] if driver.poll() is not None else "timeout"
    first = store.runs_frame().iloc[0]
    os.kill(driver.pid, signal.SIGKILL)
    driver.wait()
    flag.unlink()
    rerun = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    assert "2 run(s) done, 1 cached, 0 failed" in rerun.stdout
    runs = store.runs_frame()
    assert len(runs) == 3 and set(runs.status) == {"done"}
    again = runs.set_index("run_id").loc[first.run_id]
    assert again.finished_at == first.finished_at  # the finished run was not redone
    df = store.results_frame()
    assert not df.duplicated(["run_id", "frame", "metric", "scope", "peak"]).any()
    assert len(df[(df.metric == "gpsnr_d1") & (df.scope == "frame") & (df.frame >= 0)]) == 3 * 3
    runs_dir = store.path.parent / "runs"
    assert not list(runs_dir.glob(".tmp-*"))  # the killed run's temporary folder was cleaned


def test_two_sweeps_on_one_store_compute_each_run_once(env):
    """A second sweep of the same experiment, started while the first computes, computes nothing:
    it waits for the first's runs and returns them as cached; each run is stored once."""
    import threading

    tmp, store = env["tmp"], env["store"]
    flag = tmp / "hang.flag"
    flag.write_text("hang")
    cfg = _cfg(env["seq"], [{"name": "test-identity"}, {"name": "test-hang", "params": {"flag": str(flag)}}])
    config = _write_toml(tmp / "exp.toml", cfg)
    cmd = [sys.executable, "-m", "tests.runner_fixtures", "run", str(config), "--store", str(store.path),
           "--executor", "serial", "--quiet"]
    first = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    specs = parse_config(cfg).expand()
    deadline = time.time() + 60
    while time.time() < deadline and len(store.claims()) < 2:  # the first sweep has claimed both runs
        time.sleep(0.1)
    assert {h.pid for h in store.claims().values()} == {first.pid}
    second: dict = {}
    thread = threading.Thread(target=lambda: second.update(summary=run_experiment(
        specs, ResultsStore(store.path), executor="serial", quiet=True, poll_s=0.1)))
    thread.start()
    time.sleep(1.5)
    assert thread.is_alive()  # waiting on the hanging run the first sweep holds
    flag.unlink()
    thread.join(timeout=120)
    out = first.communicate(timeout=120)[0]
    assert first.returncode == 0 and "2 run(s) done, 0 cached, 0 failed" in out, out
    summary = second["summary"]
    assert not summary.done and sorted(summary.cached) == sorted(s.run_id for s in specs)
    assert len(store.runs_frame()) == 2 and store.claims() == {}


def test_a_sweep_takes_over_the_runs_of_a_sweep_that_died(env):
    """Runs claimed by a sweep whose process is gone (kill -9) are computed by the next sweep, also
    when the holder dies while the next sweep is waiting for it."""
    import threading

    from dpcbench.bench.execution.claims import ClaimHolder, process_start_time

    specs = parse_config(_cfg(env["seq"], [{"name": "test-identity", "params": {"shift": [0.0, 0.01]}}])).expand()
    holder_proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    try:
        holder = ClaimHolder(token="other", host=__import__("socket").gethostname(), pid=holder_proc.pid,
                             started=process_start_time(holder_proc.pid))
        env["store"].claim_runs([specs[0].run_id], holder)
        result: dict = {}
        thread = threading.Thread(target=lambda: result.update(summary=run_experiment(
            specs, env["store"], executor="serial", quiet=True, poll_s=0.1)))
        thread.start()
        deadline = time.time() + 60
        while time.time() < deadline and specs[1].run_id not in env["store"].statuses():
            time.sleep(0.1)
        time.sleep(0.5)
        assert thread.is_alive() and specs[0].run_id not in env["store"].statuses()  # not computed: held
    finally:
        holder_proc.kill()
        holder_proc.wait()
    thread.join(timeout=120)
    assert sorted(result["summary"].done) == sorted(s.run_id for s in specs)
    assert env["store"].claims() == {}


def test_dask_local_cluster_matches_serial(env, tmp_path):
    distributed = pytest.importorskip(
        "distributed", reason="optional dependency: the dask executor needs `pip install 'dpcbench[dask]'`")
    cfg = _cfg(env["seq"], [{"name": "test-identity", "params": {"shift": [0.0, 0.01]}}, {"name": "test-raises"}])
    specs = parse_config(cfg).expand()
    serial_store = env["store"]
    run_experiment(specs, serial_store, executor="serial", quiet=True, runs_dir=tmp_path / "serial-runs")
    dask_store = ResultsStore(tmp_path / "dask.sqlite")
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=2,
                                  dashboard_address=None) as cluster:
        summary = run_experiment(specs, dask_store, executor="dask", scheduler=cluster.scheduler_address,
                                 quiet=True, runs_dir=tmp_path / "dask-runs")
    assert len(summary.done) == 2 and len(summary.failed) == 1
    cols = ["run_id", "frame", "metric", "scope", "peak", "value"]
    a = serial_store.results_frame()
    b = dask_store.results_frame()
    a = a[~a.metric.isin(["time_s", "cpu_time_s", "peak_mem_mb"])][cols].sort_values(cols[:5]).reset_index(drop=True)
    b = b[~b.metric.isin(["time_s", "cpu_time_s", "peak_mem_mb"])][cols].sort_values(cols[:5]).reset_index(drop=True)
    assert len(a) > 0
    assert a.equals(b)
    assert dask_store.statuses() == serial_store.statuses()


def test_cli_dry_run_and_bad_config(env, tmp_path):
    config = _write_toml(tmp_path / "exp.toml", _cfg(env["seq"], [{"name": "test-identity"}]))
    # the CLI process does not see the monkeypatched registry: use a real method there
    text = config.read_text().replace('"test-identity"', '"none"').replace('"test-ball"', '"region"').replace(
        "radius = 0.3", 'preset = "small"')
    config.write_text(text)
    out = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", "run", str(config), "--store", str(env["store"].path),
                          "--dry-run"], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "1 runs in experiment 't': 1 to do" in out.stdout
    config.write_text(text.replace('name = "none"', 'name = "no-such-method"'))
    bad = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", "run", str(config), "--store", str(env["store"].path)],
                         cwd=REPO, capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "methods[0].name: unknown method 'no-such-method'" in bad.stderr
    assert "Traceback" not in bad.stderr
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"\0garbage" * 200)
    config.write_text(text)
    corrupt = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", "run", str(config), "--store", str(junk)],
                             cwd=REPO, capture_output=True, text=True, timeout=60)
    assert corrupt.returncode == 2 and "move it aside" in corrupt.stderr


def test_stand_in_d2_uses_the_ground_truth_normals_as_pc_error_would(tmp_path, monkeypatch, capsys):
    """On a stand-in, the stored D2 is the one pc_error computes from the files: the ground truth as
    `dpcbench generate` writes it (with the stand-in's exact normals as float nx ny nz) against the
    run's inpainted PLY. The run records that D2 used the normals from file; estimated normals would
    give another value."""
    import dpcbench.metrics as metrics
    from dpcbench.bench.cli import main as cli_main
    from dpcbench.bench.data.plyio import read_ply
    from dpcbench.bench.data.sequences import list_frame_files

    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(REPO)
    cfg = {
        "experiment": {"name": "normals", "timeout_s": 300},
        "sequences": [{"name": "human", "frames": 2, "params": {"size": "tiny"}}],
        "holes": [{"generator": "region", "params": {"preset": "small", "count": 2}, "seed": 0}],
        "methods": [{"name": "temporal-copy"}],
        "metrics": {"names": ["gpsnr_d2", "d2_mse"], "peaks": ["intrinsic"], "scopes": ["frame"]},
    }
    specs = parse_config(cfg).expand()
    store = ResultsStore(tmp_path / "store.sqlite")
    summary = run_experiment(specs, store, executor="serial", quiet=True)
    assert len(summary.done) == 1, store.runs_frame()["error"].tolist()
    run = store.runs_frame().iloc[0]
    assert json.loads(run["env"])["d2_normals"] == "file"

    assert cli_main(["generate", "human", "--frames", "2", "--param", "size=tiny", "--out", str(tmp_path / "gt")]) == 0
    capsys.readouterr()
    truth_files = list_frame_files(tmp_path / "gt")
    results = store.results_frame()
    for f, truth_file in enumerate(truth_files):
        truth = read_ply(truth_file)
        assert truth.normals is not None  # written as float nx ny nz, as pc_error reads them
        result = read_ply(Path(run["output_dir"]) / "inpainted" / f"frame_{f:04d}.ply").points
        figures = metrics.pc_error(truth.points, result, truth.normals, peak="intrinsic")
        stored = results[(results["frame"] == f) & (results["metric"] == "gpsnr_d2")]["value"].item()
        assert stored == pytest.approx(figures["d2_psnr"], rel=1e-12)
        estimated = metrics.pc_error(truth.points, result, None, peak="intrinsic")
        assert abs(estimated["d2_mse"] / figures["d2_mse"] - 1) > 1e-3


def test_generated_sequences_are_cached_before_the_runs_so_no_worker_pays_for_generating(tmp_path, monkeypatch):
    """`warm_caches` generates each stand-in of the runs once, in a child process, into the frame cache
    (a worker that generated it would count what generating left loaded in its peak memory); a sequence
    read from files is not loaded ahead, nor one with the cache turned off."""
    from dpcbench.bench.execution.runner import warm_caches

    cache = tmp_path / "cache"
    monkeypatch.setenv("DPCBENCH_CACHE", str(cache))
    monkeypatch.chdir(REPO)
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=300)
    cfg = {
        "experiment": {"name": "warm", "timeout_s": 300},
        "sequences": [{"name": "bunny", "frames": 2, "params": {"size": "tiny"}},
                      {"name": "human", "frames": 2, "params": {"size": "tiny", "cache": False}},
                      {"path": str(seq), "label": "sphere"}],
        "holes": [{"generator": "region", "params": {"preset": "small", "count": 1}, "seed": 0}],
        "methods": [{"name": "none"}],
        "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]},
    }
    warm_caches(parse_config(cfg).expand())
    # neither the uncached human nor the files' frames (only their content digests, `bench.data.file_digest`)
    assert sorted(p.name for p in cache.iterdir()) == ["bunny", "file-digests"]
    assert len(list((cache / "file-digests").iterdir())) == 2  # one per frame file of the sphere folder
    assert len(list((cache / "bunny").glob("*.npz"))) == 2
