"""Run claims in the store (`bench.execution.claims`, `ResultsStore.claim_runs`): disjoint claims, live holders
kept, dead and reused-pid holders taken over, claims dropped when a run is recorded or a sweep ends."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time

import pytest

from dpcbench.bench.execution.claims import FOREIGN_CLAIM_TTL_S, ClaimHolder, process_start_time
from dpcbench.bench.results.store import ResultsStore


@pytest.fixture
def store(tmp_path):
    return ResultsStore(tmp_path / "store.sqlite")


@pytest.fixture
def sleeper():
    """A live process of this host (another sweep's stand-in), killed after the test."""
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    yield proc
    proc.kill()
    proc.wait()


def _holder(pid: int, *, token: str = "other", host: str | None = None, started: str | None = None) -> ClaimHolder:
    return ClaimHolder(token=token, host=host or socket.gethostname(), pid=pid,
                       started=process_start_time(pid) if started is None else started)


def test_a_live_holder_keeps_its_runs_and_the_rest_are_claimed(store, sleeper):
    other = _holder(sleeper.pid)
    assert store.claim_runs(["a", "b"], other).held == {}
    me = ClaimHolder.this_sweep()
    claimed = store.claim_runs(["a", "b", "c"], me)
    assert claimed.mine == ["c"] and set(claimed.held) == {"a", "b"} and claimed.held["a"] == other
    assert store.claims() == {"a": other, "b": other, "c": me}
    # claiming again is idempotent for the holder itself
    assert store.claim_runs(["c"], me).mine == ["c"]


def test_dead_holder_and_reused_pid_are_taken_over(store, sleeper):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    store.claim_runs(["a"], _holder(dead.pid, token="dead"))
    # the sleeper's pid with another start time: the process that claimed is gone, its pid reused
    store.claim_runs(["b"], _holder(sleeper.pid, token="reused", started="1"))
    me = ClaimHolder.this_sweep()
    claimed = store.claim_runs(["a", "b"], me)
    assert claimed.mine == ["a", "b"] and not claimed.held


def test_claims_from_another_host_count_until_their_ttl(store, monkeypatch):
    elsewhere = _holder(1, token="far", host="another-host.invalid", started="")
    store.claim_runs(["a"], elsewhere)
    me = ClaimHolder.this_sweep()
    assert set(store.claim_runs(["a"], me).held) == {"a"}
    later = time.time() + FOREIGN_CLAIM_TTL_S + 1
    monkeypatch.setattr("dpcbench.bench.results.store.time.time", lambda: later)
    assert store.claim_runs(["a"], me).mine == ["a"]


def test_stored_runs_are_not_claimed_unless_redone(store):
    me = ClaimHolder.this_sweep()
    store.record_run("done", {}, [])
    store.record_failure("failed", {}, "boom")
    claimed = store.claim_runs(["done", "failed", "new"], me)
    assert claimed.stored == {"done": "done", "failed": "failed"} and claimed.mine == ["new"]
    assert store.claim_runs(["done", "failed"], me, redo_failed=True).mine == ["failed"]
    assert store.claim_runs(["done", "failed"], me, redo_done=True, redo_failed=True).mine == ["done", "failed"]


def test_recording_a_run_drops_its_claim_and_release_drops_the_rest(store):
    me = ClaimHolder.this_sweep()
    other = ClaimHolder.this_sweep()  # a second sweep of this process (a thread): told apart by its token
    store.claim_runs(["a", "b"], me)
    store.claim_runs(["c"], other)
    assert set(store.claim_runs(["a", "c"], other).held) == {"a"}
    store.record_run("a", {}, [])
    assert set(store.claims()) == {"b", "c"}
    store.release_claims(me)
    assert set(store.claims()) == {"c"}


def test_concurrent_claims_are_disjoint(tmp_path):
    """Eight threads, each with its own connection and holder, claim the same 200 runs at once:
    every run ends up with exactly one of them."""
    path = tmp_path / "store.sqlite"
    ResultsStore(path)
    ids = [f"run{i:03d}" for i in range(200)]
    got: dict[int, list[str]] = {}
    barrier = threading.Barrier(8)

    def claim(k: int) -> None:
        store = ResultsStore(path)
        holder = ClaimHolder.this_sweep()
        barrier.wait()
        got[k] = store.claim_runs(ids[k * 10:] + ids[:k * 10], holder).mine

    threads = [threading.Thread(target=claim, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(got) == 8  # no thread failed (a deferred BEGIN fails here: one snapshot goes stale)
    claimed = [r for mine in got.values() for r in mine]
    assert sorted(claimed) == ids  # each run once, none lost


def test_a_store_without_the_claims_table_gets_it_on_a_writable_open(tmp_path):
    import sqlite3

    path = tmp_path / "store.sqlite"
    ResultsStore(path)
    with sqlite3.connect(path) as conn:
        conn.execute("DROP TABLE run_claims")  # as a store written before claims existed
    assert ResultsStore(path, readonly=True).claims() == {}
    store = ResultsStore(path)
    assert store.claim_runs(["a"], ClaimHolder.this_sweep()).mine == ["a"]


def test_process_start_time_names_this_process():
    if not os.path.exists("/proc/self/stat"):
        pytest.skip("no /proc on this system: claims fall back to the pid alone")
    assert process_start_time(os.getpid()) == process_start_time(os.getpid()) != ""
    assert process_start_time(2 ** 22 + 12345) == ""  # above Linux's pid limit: no such process
