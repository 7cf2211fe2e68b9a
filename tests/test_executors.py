"""The Dask executor against a real scheduler: `dask scheduler` + 2 `dask worker` processes reached
through ``--scheduler tcp://...``, and the shared-storage check (a worker that cannot read or write
the run folder fails the sweep with a message that says so)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.execution.executors import (
    SHARED_MARKER_PREFIX,
    SharedStorageError,
    check_shared_runs_dir,
)
from dpcbench.bench.execution.runner import run_experiment
from dpcbench.bench.experiment.config import parse_config
from dpcbench.bench.results.store import ResultsStore
from tests import runner_fixtures as helpers

REPO = Path(__file__).resolve().parents[1]

pytest.importorskip("distributed")


def _cfg(seq, methods):
    return {
        "experiment": {"name": "t", "timeout_s": 120},
        "sequences": [{"path": str(seq), "label": "sphere"}],
        "holes": [{"generator": "test-ball", "params": {"radius": 0.3}, "seed": 1}],
        "methods": methods,
        "metrics": {"names": ["gpsnr_d1", "nshd"], "peaks": ["intrinsic"], "scopes": ["frame", "holes"]},
    }


@pytest.fixture
def env(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=3, n_points=600)
    return {"seq": seq, "tmp": tmp_path}


@pytest.fixture
def tcp_cluster(tmp_path):
    """A `dask scheduler` and 2 single-threaded `dask worker` processes; yields the tcp:// address."""
    dask = Path(sys.executable).parent / "dask"
    if not dask.exists():
        pytest.skip("the dask command-line tool is not installed")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    sched_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([str(dask), "scheduler", "--scheduler-file", str(sched_file), "--port", "0",
                               "--no-dashboard", "--host", "127.0.0.1"], cwd=REPO, env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert sched_file.exists(), "the dask scheduler did not start within 60 s"
        address = json.loads(sched_file.read_text())["address"]
        for i in range(2):
            procs.append(subprocess.Popen([str(dask), "worker", address, "--nthreads", "1", "--no-dashboard",
                                           "--name", f"w{i}", "--local-directory", str(tmp_path / f"w{i}")],
                                          cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        # killed, not terminated: nothing of theirs is kept, and a worker's graceful close after a failed
        # client.run took 8 s
        for proc in reversed(procs):
            proc.kill()
        for proc in procs:
            proc.wait(timeout=20)


def test_tcp_scheduler_runs_a_grid_on_two_workers(env, tcp_cluster, tmp_path):
    specs = parse_config(_cfg(env["seq"], [{"name": "test-identity", "params": {"shift": [0.0, 0.01, 0.02]}},
                                           {"name": "test-raises"}])).expand()
    store = ResultsStore(tmp_path / "store.sqlite")
    runs_dir = tmp_path / "runs"
    summary = run_experiment(specs, store, executor="pool", scheduler=tcp_cluster, quiet=True, runs_dir=runs_dir)
    assert len(summary.done) == 3 and len(summary.failed) == 1
    assert "deliberate failure" in summary.errors[summary.failed[0]]
    df = store.results_frame()
    d1 = df[(df.metric == "gpsnr_d1") & (df.scope == "frame") & (df.frame >= 0)]
    assert len(d1) == 3 * 3  # 3 done runs x 3 frames
    # shift 0 returns the damaged frames: the whole-frame D1 is finite and the shifted runs score lower
    by_run = d1.groupby("run_id").value.mean()
    assert by_run.nunique() == 3
    # every done run wrote its frames into the shared run folder, and the sweep's marker is gone
    for run_id in summary.done:
        out = Path(store.runs_frame().set_index("run_id").loc[run_id, "output_dir"])
        assert (out / "manifest.json").is_file() and out.parent == runs_dir.resolve()
    assert not list(runs_dir.glob(f"{SHARED_MARKER_PREFIX}*"))
    # the runs were tasks of the `dask worker` processes (their own logs of executed task keys)
    from distributed import Client

    def executed_run_keys(dask_worker) -> set:  # local, so cloudpickle ships it by value
        return {entry[0] for entry in dask_worker.state.log
                if isinstance(entry[0], str) and entry[0].startswith("dpcbench-") and "memory" in entry[1:3]}

    with Client(tcp_cluster, timeout="30s") as client:
        executed = client.run(executed_run_keys)
    assert len(executed) == 2
    ran = set().union(*executed.values())
    assert ran == {f"dpcbench-{s.run_id}" for s in specs}


def test_worker_that_cannot_see_the_run_folder_stops_the_sweep(env, tcp_cluster, tmp_path, monkeypatch):
    """The driver's marker is not where the workers look (as on a machine without the shared mount):
    every worker fails the check, nothing runs, and the message says what to do."""
    from dpcbench.bench.execution import executors

    real_unlink = Path.unlink
    # the driver writes its marker, then it vanishes before the workers look: what a worker on another
    # machine sees when the run folder is a local directory of the driver
    monkeypatch.setattr(executors.DaskExecutor, "_check_workers", _checking_after_removing_markers(
        executors.DaskExecutor._check_workers, real_unlink))
    specs = parse_config(_cfg(env["seq"], [{"name": "test-identity"}])).expand()
    store = ResultsStore(tmp_path / "store.sqlite")
    with pytest.raises(UserError) as info:
        run_experiment(specs, store, executor="dask", scheduler=tcp_cluster, quiet=True, runs_dir=tmp_path / "runs")
    message = str(info.value)
    assert "cannot see the run folder" in message and "nothing was run" in message
    assert "every Dask worker reaches" in message
    assert message.count("tcp://") == 2  # both workers named
    assert store.statuses() == {}  # nothing was recorded
    assert not list((tmp_path / "runs").glob("*/manifest.json"))


def _checking_after_removing_markers(check, unlink):
    def patched(client, runs_dir, token):
        for marker in Path(runs_dir).glob(f"{SHARED_MARKER_PREFIX}*"):
            unlink(marker)
        return check(client, runs_dir, token)

    return staticmethod(patched)


def test_check_shared_runs_dir(tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / f"{SHARED_MARKER_PREFIX}abc").write_text("abc")
    assert check_shared_runs_dir(str(runs), "abc")  # returns the host name
    assert sorted(p.name for p in runs.iterdir()) == [f"{SHARED_MARKER_PREFIX}abc"]  # the probe is removed
    with pytest.raises(SharedStorageError, match="cannot see the run folder"):
        check_shared_runs_dir(str(runs), "other-token")
    (runs / f"{SHARED_MARKER_PREFIX}def").write_text("xyz")
    with pytest.raises(SharedStorageError, match="reads a different"):
        check_shared_runs_dir(str(runs), "def")


def test_check_shared_runs_dir_not_writable(tmp_path, monkeypatch):
    """A read-only mount: the marker is readable, the probe write fails."""
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / f"{SHARED_MARKER_PREFIX}abc").write_text("abc")
    real_write = Path.write_text

    def read_only(self, *args, **kwargs):
        if self.name.startswith(".dpcbench-probe-"):
            raise OSError(30, "Read-only file system", str(self))
        return real_write(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", read_only)
    with pytest.raises(SharedStorageError, match="cannot write into the run folder .*Read-only file system"):
        check_shared_runs_dir(str(runs), "abc")
