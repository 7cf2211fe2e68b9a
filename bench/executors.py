"""Executors: where runs execute. Every one runs each run in its own worker process with a timeout
(`bench.worker.run_isolated`), so a crash, a hang or a kill -9 inside a method is one failed run.

- ``serial``: one run at a time.
- ``pool`` (default): up to ``jobs`` runs at once (default: all cores). Driver threads each start
  and watch one worker process; a process per run keeps crashes and memory isolated and makes the
  timeout a plain kill.
- ``dask``: runs are tasks on a Dask distributed cluster: ``scheduler`` ADDRESS connects to an
  existing one, otherwise a LocalCluster with ``jobs`` single-threaded workers is started. A task
  starts the worker process on its Dask worker's machine and returns the outcome to the driver.
  Task keys are ``dpcbench-<run_id>``, so a resubmitted run is the same task, and only the driver
  writes the store: a retried or duplicated task cannot duplicate rows. The run folders
  (``runs_dir``) must be on a filesystem the Dask workers share with the driver.

Each executor's ``execute(specs, runs_dir, force)`` yields ``(spec, outcome)`` as runs finish.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
from collections.abc import Iterator
from pathlib import Path

from bench.config import RunSpec
from bench.errors import UserError
from bench.worker import kill_live_workers, run_isolated

EXECUTORS = ("serial", "pool", "dask")


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
            except OSError as err:
                raise UserError(f"cannot reach the Dask scheduler at {self.scheduler} ({err}); "
                                 "check the address (e.g. tcp://host:8786) and that the scheduler runs") from err
        else:
            cluster = LocalCluster(n_workers=self.jobs, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
        try:
            futures = {}
            for spec in specs:
                fut = client.submit(run_isolated, spec.to_dict(), str(runs_dir), force, None,
                                    key=f"dpcbench-{spec.run_id}", pure=False)
                futures[fut.key] = (spec, fut)
            for fut in as_completed([f for _, f in futures.values()]):
                spec = futures[fut.key][0]
                try:
                    yield spec, fut.result()
                except Exception as err:  # the task failed on the worker (e.g. worker lost)
                    yield spec, _failed(spec, err)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


def make_executor(name: str, jobs: int | None = None, scheduler: str | None = None):
    if scheduler and name != "dask":
        name = "dask"  # --scheduler only makes sense for Dask
    if name == "serial":
        return SerialExecutor(jobs)
    if name == "pool":
        return PoolExecutor(jobs)
    if name == "dask":
        return DaskExecutor(jobs, scheduler)
    raise UserError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
