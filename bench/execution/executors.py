"""Executors: where runs execute. Every one runs each run in its own worker process with a timeout
(`bench.execution.worker.run_isolated`), so a crash, a hang or a kill -9 inside a method is one failed run.

- ``serial``: one run at a time.
- ``pool`` (default): up to ``jobs`` runs at once (default: all cores). Driver threads each start
  and watch one worker process; a process per run keeps crashes and memory isolated and makes the
  timeout a plain kill.
- ``dask``: runs are tasks on a Dask distributed cluster: ``scheduler`` ADDRESS connects to an
  existing one, otherwise a LocalCluster with ``jobs`` single-threaded workers is started. A task
  starts the worker process on its Dask worker's machine and returns the outcome to the driver.
  Task keys are ``dpcbench-<run_id>``, so a resubmitted run is the same task, and only the driver
  writes the store: a retried or duplicated task cannot duplicate rows. The run folders
  (``runs_dir``) must be on a filesystem the Dask workers share with the driver, at the same path
  (README, "Shared storage"): the driver writes a marker file with a fresh token into ``runs_dir``,
  and every worker checks that it reads that token and can write there, once before the sweep
  (`check_shared_runs_dir` on every worker; a failure stops the sweep with a `UserError` naming the
  workers) and again at the start of each task (for workers that join later). Without the check a
  worker on another machine would create an empty ``runs_dir`` of its own and write the frames
  where neither the driver nor the other workers find them.

Each executor's ``execute(specs, runs_dir, force)`` yields ``(spec, outcome)`` as runs finish.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
import re
import socket
import uuid
from collections.abc import Iterator
from pathlib import Path

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.execution.worker import kill_live_workers, run_isolated
from dpcbench.bench.experiment.config import RunSpec

EXECUTORS = ("serial", "pool", "dask")

#: name prefix of the marker files the Dask driver writes into the run folder (one per sweep)
SHARED_MARKER_PREFIX = ".dpcbench-shared-"


#: how long the driver waits for a first worker of an existing cluster (seconds; env override)
WORKER_WAIT_ENV = "DPCBENCH_DASK_WORKER_WAIT_S"
DEFAULT_WORKER_WAIT_S = 60.0
_ADDRESS = re.compile(r"^(?:(tcp|tls|ucx|ws|wss)://)?(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+)(?::(\d{1,5}))?/?$")


def check_scheduler_address(address: str) -> str:
    """``address`` when it has the form of a Dask scheduler address (``[tcp|tls|ucx|ws|wss://]host[:port]``,
    port 1..65535, or ``inproc://host/pid/n``); UserError otherwise. (The driver unpickles the results of whatever cluster the
    address reaches: give only a cluster you trust.)"""
    if isinstance(address, str) and re.fullmatch(r"inproc://[A-Za-z0-9_.:-]+(/\d+)+", address.strip()):
        return address.strip()  # a scheduler in this process (tests, notebooks)
    match = _ADDRESS.match(address.strip()) if isinstance(address, str) else None
    port = match.group(3) if match else None
    if match is None or (port is not None and not 1 <= int(port) <= 65535):
        raise UserError(f"--scheduler {address!r}: not a Dask scheduler address; give e.g. tcp://host:8786 "
                        "(protocol tcp, tls, ucx, ws or wss; port 1..65535)")
    return address.strip()


def worker_wait_s() -> float:
    """Seconds to wait for a first worker (``$DPCBENCH_DASK_WORKER_WAIT_S``, default 60)."""
    try:
        value = float(os.environ.get(WORKER_WAIT_ENV, DEFAULT_WORKER_WAIT_S))
    except ValueError:
        value = DEFAULT_WORKER_WAIT_S
    return value if value > 0 and value == value else DEFAULT_WORKER_WAIT_S


class SharedStorageError(RuntimeError):
    """A worker cannot read the driver's run folder or cannot write into it."""


def check_shared_runs_dir(runs_dir: str, token: str) -> str:
    """On a worker: check that ``runs_dir`` is the driver's run folder and writable from here.

    Reads ``runs_dir/.dpcbench-shared-<token>`` (written by the driver; it must hold ``token``) and
    creates and removes a probe file beside it. Returns this worker's host name; raises
    `SharedStorageError` with what is wrong and what to do.
    """
    host = socket.gethostname()
    where = f"worker on host {host!r} (pid {os.getpid()})"
    advice = ("the run folders must be on storage every Dask worker reaches at the same path (e.g. an NFS "
              "mount); put --store (the run folders default to <store folder>/runs) or --runs-dir there")
    marker = Path(runs_dir) / f"{SHARED_MARKER_PREFIX}{token}"
    try:
        seen = marker.read_text().strip()
    except OSError as err:
        raise SharedStorageError(f"{where} cannot see the run folder {runs_dir} that the driver prepared "
                                 f"(missing {marker.name}: {type(err).__name__}); {advice}") from err
    if seen != token:
        raise SharedStorageError(f"{where} reads a different {marker.name} in {runs_dir} than the driver wrote; {advice}")
    probe = Path(runs_dir) / f".dpcbench-probe-{host}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    try:
        probe.write_text("probe")
        probe.unlink()
    except OSError as err:
        raise SharedStorageError(f"{where} cannot write into the run folder {runs_dir} "
                                 f"({type(err).__name__}: {err}); {advice}") from err
    return host


def run_on_dask_worker(spec_dict: dict, runs_dir: str, force: bool, token: str) -> dict:
    """The Dask task: the shared-storage check, then `run_isolated` on this worker's machine."""
    check_shared_runs_dir(runs_dir, token)
    return run_isolated(spec_dict, runs_dir, force, None)


def _failed(spec: RunSpec, err: BaseException) -> dict:
    """The failure record of a run whose worker could not even report (a harness bug or a lost
    worker): the traceback is kept, as for failures inside the worker, so the bug can be found."""
    import traceback

    return {"run_id": spec.run_id, "status": "failed", "error": f"{type(err).__name__}: {err}",
            "traceback": "".join(traceback.format_exception(err))[-4000:]}


class SerialExecutor:
    name = "serial"

    def __init__(self, jobs: int | None = None):
        self.jobs = 1

    def execute(self, specs: list[RunSpec], runs_dir: Path, force: bool = False) -> Iterator[tuple[RunSpec, dict]]:
        try:
            for spec in specs:
                yield spec, run_isolated(spec.to_dict(), str(runs_dir), force, threads=None)
        finally:
            kill_live_workers()


class PoolExecutor:
    name = "pool"

    def __init__(self, jobs: int | None = None):
        self.jobs = max(1, int(jobs or os.cpu_count() or 1))

    def execute(self, specs: list[RunSpec], runs_dir: Path, force: bool = False) -> Iterator[tuple[RunSpec, dict]]:
        # each worker gets its share of the cores for BLAS/OpenMP threads, so jobs x threads <= cores
        threads = max(1, (os.cpu_count() or 1) // self.jobs)
        pool = cf.ThreadPoolExecutor(max_workers=self.jobs, thread_name_prefix="dpcbench-run")
        futures = {pool.submit(run_isolated, s.to_dict(), str(runs_dir), force, threads): s for s in specs}
        pending = set(futures)
        try:
            while pending:
                # a short wait keeps Ctrl-C responsive in the main thread
                done, pending = cf.wait(pending, timeout=0.5, return_when=cf.FIRST_COMPLETED)
                for fut in done:
                    spec = futures[fut]
                    try:
                        yield spec, fut.result()
                    except Exception as err:  # run_isolated itself failed (e.g. cannot start python)
                        yield spec, _failed(spec, err)
        finally:
            pool.shutdown(wait=False, cancel_futures=True)
            kill_live_workers()


class DaskExecutor:
    name = "dask"

    def __init__(self, jobs: int | None = None, scheduler: str | None = None):
        try:
            import distributed  # noqa: F401  (imported only to refuse early when it is missing)
        except ImportError as err:
            raise UserError("the dask executor needs dask and distributed: pip install 'dpcbench[dask]'") from err
        self.jobs = max(1, int(jobs or os.cpu_count() or 1))
        self.scheduler = scheduler

    def execute(self, specs: list[RunSpec], runs_dir: Path, force: bool = False) -> Iterator[tuple[RunSpec, dict]]:
        from distributed import Client, LocalCluster, as_completed

        cluster = None
        if self.scheduler:
            try:
                client = Client(self.scheduler, timeout="20s")
            except (OSError, ValueError, TypeError) as err:  # unreachable, or an address distributed cannot parse
                raise UserError(f"cannot reach the Dask scheduler at {self.scheduler} ({err}); "
                                 "check the address (e.g. tcp://host:8786) and that the scheduler runs") from err
        else:
            cluster = LocalCluster(n_workers=self.jobs, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
        token = uuid.uuid4().hex
        marker = Path(runs_dir) / f"{SHARED_MARKER_PREFIX}{token}"
        try:
            if self.scheduler:
                self._wait_for_a_worker(client)
            marker.write_text(token)
            self._check_workers(client, str(runs_dir), token)
            futures = {}
            for spec in specs:
                fut = client.submit(run_on_dask_worker, spec.to_dict(), str(runs_dir), force, token,
                                    key=f"dpcbench-{spec.run_id}", pure=False)
                futures[fut.key] = (spec, fut)
            for fut in as_completed([f for _, f in futures.values()]):
                spec = futures[fut.key][0]
                try:
                    yield spec, fut.result()
                except Exception as err:  # the task failed on the worker (e.g. worker lost)
                    yield spec, _failed(spec, err)
        finally:
            marker.unlink(missing_ok=True)
            client.close()
            if cluster is not None:
                cluster.close()

    def _wait_for_a_worker(self, client) -> None:
        """UserError when the cluster has no worker within `worker_wait_s` (the sweep would wait forever)."""
        wait = worker_wait_s()
        try:
            client.wait_for_workers(1, timeout=wait)
        except (TimeoutError, OSError) as err:
            raise UserError(f"the Dask scheduler at {self.scheduler} has no worker (waited {wait:g} s); start workers "
                            f"(`dask worker {self.scheduler}`) or raise ${WORKER_WAIT_ENV}; nothing was run") from err

    @staticmethod
    def _check_workers(client, runs_dir: str, token: str) -> None:
        """Run `check_shared_runs_dir` on every connected worker; any failure stops the sweep."""
        answers = client.run(check_shared_runs_dir, runs_dir, token, on_error="return")
        problems = [f"{addr}: {ans}" for addr, ans in sorted(answers.items()) if isinstance(ans, BaseException)]
        if problems:
            raise UserError("Dask workers cannot use the run folder; nothing was run:\n  " + "\n  ".join(problems))


def make_executor(name: str, jobs: int | None = None, scheduler: str | None = None):
    if scheduler is not None:
        scheduler = check_scheduler_address(scheduler)
    if scheduler and name != "dask":
        name = "dask"  # --scheduler only makes sense for Dask
    if name == "serial":
        return SerialExecutor(jobs)
    if name == "pool":
        return PoolExecutor(jobs)
    if name == "dask":
        return DaskExecutor(jobs, scheduler)
    raise UserError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
