"""The sweep driver: runs every spec of an experiment not yet in the results store, and records each.

`run_experiment` decides what to run (stored runs are skipped, failed ones redone on request), hands
the runs to an executor (`bench.executors`: serial, a local pool, or Dask), each of which runs one
spec per worker process (`bench.worker`), and writes each outcome to the store as it arrives. The
driver alone writes the store (`bench.store`), so store writes never race with a worker being killed.

Layout of the modules a run goes through (each imports only those after it):

    bench.runner (this: the sweep)  ->  bench.executors (where)  ->  bench.worker (one run, one process)
                                                                 ->  bench.provenance (run folders, environment)
"""

from __future__ import annotations

import os
from pathlib import Path

from dpcbench.bench.config import RunSpec
from dpcbench.bench.executors import make_executor
from dpcbench.bench.provenance import clean_stale_temp, git_commit
from dpcbench.bench.records import RunRecord, run_record


class RunSummary:
    """What a sweep did: run ids per outcome ("done" now, "cached" before, "failed" now or before)."""

    def __init__(self) -> None:
        self.done: list[str] = []
        self.cached: list[str] = []
        self.failed: list[str] = []
        self.errors: dict[str, str] = {}

    def __repr__(self) -> str:
        return f"RunSummary(done={len(self.done)}, cached={len(self.cached)}, failed={len(self.failed)})"


def default_runs_dir(store_path: Path) -> Path:
    """Run folders live beside the store: ``<store folder>/runs``."""
    return Path(store_path).resolve().parent / "runs"


def _failure_record(spec: RunSpec, outcome: dict, error: str) -> RunRecord:
    """The record of a failed run: the worker's timing, its log and traceback as the environment."""
    return run_record(spec, status="failed", error=error, code_version=git_commit(),
                      wall_time_s=outcome.get("wall_time_s"), cpu_time_s=outcome.get("cpu_time_s"),
                      env={"log": outcome.get("log"), "traceback": outcome.get("traceback")})


def warm_caches(specs: list[RunSpec], quiet: bool = True) -> None:
    """Generate, once and before the runs, each distinct sequence of ``specs`` whose source writes the
    on-disk frame cache (embedded stand-ins, mesh sequences: ``SequenceSource.cached``), each in a child
    process. Why: the first worker to load such a sequence would generate it, and its memory figure would
    then count what generating left behind (the libraries it imported; the bunny stand-in imports open3d:
    `none` measured 329 MB against 77 MB from a warm cache), so a run's ``peak_mem_mb`` would depend on
    whether the cache was warm. Two workers of a pool starting on the same sequence no longer both
    generate it either. A sequence that fails here is left to its runs, which record the error."""
    import json
    import subprocess
    import sys

    from dpcbench.bench.datasets import run_sequence_source

    done = set()
    for spec in specs:
        sequence = spec.sequence
        key = json.dumps(sequence, sort_keys=True, default=str)
        if key in done:
            continue
        done.add(key)
        try:
            source = run_sequence_source(sequence)
        except Exception:  # an unknown or missing sequence: its runs report it
            continue
        if not getattr(source, "cached", False) or sequence.get("params", {}).get("cache", True) is False:
            continue
        if not quiet:
            print(f"generating {spec.sequence_label} (once, into the frame cache)", file=sys.stderr, flush=True)
        code = ("import json, sys; from dpcbench.bench.datasets import load_run_sequence; "
                "load_run_sequence(json.loads(sys.argv[1]))")
        try:
            subprocess.run([sys.executable, "-c", code, key], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           timeout=spec.timeout_s, check=False)
        except subprocess.TimeoutExpired:
            continue


def run_experiment(specs: list[RunSpec], store, *, runs_dir: str | os.PathLike | None = None,
                   executor: str = "pool", jobs: int | None = None, scheduler: str | None = None,
                   force: bool = False, retry_failed: bool = False, quiet: bool = False,
                   timeout_s: float | None = None) -> RunSummary:
    """Execute the runs not yet in ``store`` (a `bench.store.ResultsStore`) and record each as it ends.

    Stored runs are skipped ('done' and 'failed' alike); ``retry_failed`` redoes failed ones,
    ``force`` redoes everything (frames included). Each finished run is written to the store at
    once, in one transaction, so an interrupted sweep keeps all finished runs and loses only those
    in flight, which the next call redoes.
    """
    from dpcbench.bench.progress import progress_bar  # tqdm loads only when a sweep runs

    runs_path = Path(runs_dir).resolve() if runs_dir else default_runs_dir(store.path)
    runs_path.mkdir(parents=True, exist_ok=True)
    clean_stale_temp(runs_path)
    summary = RunSummary()
    statuses = store.statuses([s.run_id for s in specs])
    todo = []
    experiments: dict[str, set[str]] = {}
    for spec in specs:
        experiments.setdefault(spec.experiment, set()).add(spec.run_id)
        status = statuses.get(spec.run_id)
        if force or status is None or (status == "failed" and retry_failed):
            todo.append(spec)
        elif status == "done":
            summary.cached.append(spec.run_id)
        else:
            summary.failed.append(spec.run_id)
            summary.errors[spec.run_id] = "failed in an earlier sweep (use --retry-failed to redo)"
    for name, ids in experiments.items():  # cached runs join this experiment too
        store.add_to_experiment(name, sorted(ids & set(statuses)))
    if timeout_s:
        for spec in todo:
            spec.timeout_s = float(timeout_s)
    if not todo:
        return summary
    warm_caches(todo, quiet)
    runner = make_executor(executor, jobs, scheduler)
    # runs already in the store start the bar (`initial`), so its rate and ETA count only runs computed now
    bar = progress_bar(total=len(specs), desc=f"runs ({runner.name} x{runner.jobs})", unit="run", quiet=quiet,
                       initial=len(summary.cached) + len(summary.failed))

    def show():
        bar.set_postfix_str(f"done {len(summary.done)}, cached {len(summary.cached)}, failed {len(summary.failed)}")

    show()
    try:
        for spec, outcome in runner.execute(todo, runs_path, force):
            if outcome.get("status") == "done":
                record = RunRecord.from_facts(spec.run_id, outcome["record"], "done")
                store.record_run(spec.run_id, record, outcome["results"], [spec.experiment])
                summary.done.append(spec.run_id)
            else:
                error = outcome.get("error", "unknown error")
                store.record_failure(spec.run_id, _failure_record(spec, outcome, error), error, [spec.experiment])
                summary.failed.append(spec.run_id)
                summary.errors[spec.run_id] = error
                if not quiet:
                    bar.write(f"run {spec.run_id} ({spec.method['name']} on {spec.sequence_label}) failed: "
                              f"{error.splitlines()[0]}")
            bar.update(1)
            show()
    finally:
        bar.close()
    return summary
