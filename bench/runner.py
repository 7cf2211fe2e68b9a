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


class RunSummary:
    """What a sweep did: run ids per outcome ("done" now, "cached" before, "failed" now or before)."""

    def __init__(self):
        self.done: list[str] = []
        self.cached: list[str] = []
        self.failed: list[str] = []
        self.errors: dict[str, str] = {}

    def __repr__(self) -> str:
        return f"RunSummary(done={len(self.done)}, cached={len(self.cached)}, failed={len(self.failed)})"


def default_runs_dir(store_path: Path) -> Path:
    """Run folders live beside the store: ``<store folder>/runs``."""
    return Path(store_path).resolve().parent / "runs"


def _failure_record(spec: RunSpec, outcome: dict) -> dict:
    return {"sequence": spec.sequence_label, "holes": spec.holes["generator"], "holes_params": spec.holes["params"],
            "seed": spec.holes["seed"], "method": spec.method["name"], "method_params": spec.method["params"],
            "method_version": spec.versions["method"], "code_version": git_commit(), "spec": spec.to_dict(),
            "wall_time_s": outcome.get("wall_time_s"), "cpu_time_s": outcome.get("cpu_time_s"), "env": {"log": outcome.get("log"),
                                                              "traceback": outcome.get("traceback")}}


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
    runner = make_executor(executor, jobs, scheduler)
    bar = progress_bar(total=len(specs), desc=f"runs ({runner.name} x{runner.jobs})", unit="run", quiet=quiet)
    bar.update(len(summary.cached) + len(summary.failed))

    def show():
        bar.set_postfix_str(f"done {len(summary.done)}, cached {len(summary.cached)}, failed {len(summary.failed)}")

    show()
    try:
        for spec, outcome in runner.execute(todo, runs_path, force):
            if outcome.get("status") == "done":
                store.record_run(spec.run_id, outcome["record"], outcome["results"], [spec.experiment])
                summary.done.append(spec.run_id)
            else:
                error = outcome.get("error", "unknown error")
                store.record_failure(spec.run_id, _failure_record(spec, outcome), error, [spec.experiment])
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
