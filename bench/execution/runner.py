"""The sweep driver: runs every spec of an experiment not yet in the results store, and records each.

`run_experiment` decides what to run (stored runs are skipped, failed ones redone on request), hands
the runs to an executor (`bench.execution.executors`: serial, a local pool, or Dask), each of which runs one
spec per worker process (`bench.execution.worker`), and writes each outcome to the store as it arrives. The
driver alone writes the store (`bench.results.store`), so store writes never race with a worker being killed.

Layout of the modules a run goes through (each imports only those after it):

    bench.execution.runner (this: the sweep)  ->  bench.execution.executors (where)  ->  bench.execution.worker (one run, one process)
                                                                 ->  bench.execution.provenance (run folders, environment)
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

from dpcbench.bench.execution.claims import ClaimHolder
from dpcbench.bench.execution.executors import make_executor
from dpcbench.bench.execution.provenance import clean_stale_temp, git_commit
from dpcbench.bench.experiment.config import RunSpec
from dpcbench.bench.experiment.records import RunRecord, run_record


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

    from dpcbench.bench.data.datasets import run_sequence_source

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
        code = ("import json, sys; from dpcbench.bench.data.datasets import load_run_sequence; "
                "load_run_sequence(json.loads(sys.argv[1]))")
        try:
            subprocess.run([sys.executable, "-c", code, key], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           timeout=spec.timeout_s, check=False)
        except subprocess.TimeoutExpired:
            continue


def run_experiment(specs: list[RunSpec], store, *, runs_dir: str | os.PathLike | None = None,
                   executor: str = "pool", jobs: int | None = None, scheduler: str | None = None,
                   force: bool = False, retry_failed: bool = False, quiet: bool = False,
                   timeout_s: float | None = None, poll_s: float = 2.0) -> RunSummary:
    """Execute the runs not yet in ``store`` (a `bench.results.store.ResultsStore`) and record each as it ends.

    Stored runs are skipped ('done' and 'failed' alike); ``retry_failed`` redoes failed ones,
    ``force`` redoes everything (frames included). Each finished run is written to the store at
    once, in one transaction, so an interrupted sweep keeps all finished runs and loses only those
    in flight, which the next call redoes. Runs are claimed before they are computed
    (`bench.execution.claims`): runs another live sweep on the same store is computing are not computed
    again; this sweep waits for them (polling every ``poll_s`` seconds) after its own, and computes
    those whose sweep died.
    """
    runs_path = Path(runs_dir).resolve() if runs_dir else default_runs_dir(store.path)
    runs_path.mkdir(parents=True, exist_ok=True)
    clean_stale_temp(runs_path)
    by_id = {spec.run_id: spec for spec in specs}
    holder = ClaimHolder.this_sweep()
    sweep = _Sweep(store, runs_path, specs, force=force, quiet=quiet, timeout_s=timeout_s,
                   executor=(executor, jobs, scheduler))
    try:
        claimed = store.claim_runs(list(by_id), holder, redo_done=force, redo_failed=retry_failed or force)
        sweep.note_stored(claimed.stored, by_another=False)
        while claimed.mine or claimed.held:
            sweep.compute([by_id[r] for r in claimed.mine])
            if claimed.held:
                sweep.note_waiting(claimed.held)
                time.sleep(poll_s)
                claimed = store.claim_runs(list(claimed.held), holder)  # stored now, or its sweep died
                sweep.note_stored(claimed.stored, by_another=True)
            else:
                break
    finally:
        store.release_claims(holder)
        sweep.close()
    return sweep.summary


class _Sweep:
    """One sweep's state: its summary, its progress bar and executor (both made when the first run
    is computed), and the store writes of each outcome."""

    def __init__(self, store, runs_path: Path, specs: list[RunSpec], *, force: bool, quiet: bool,
                 timeout_s: float | None, executor: tuple[str, int | None, str | None]):
        self.store, self.runs_path, self.specs = store, runs_path, specs
        self.force, self.quiet, self.timeout_s, self.executor_args = force, quiet, timeout_s, executor
        self.summary = RunSummary()
        self.experiments: dict[str, set[str]] = {}
        for spec in specs:
            self.experiments.setdefault(spec.experiment, set()).add(spec.run_id)
        self.runner: Any = None  # an executor of `bench.execution.executors`, made by `_start`
        self.bar: Any = None
        self.waiting_for: set[str] = set()

    def note_stored(self, stored: dict[str, str], *, by_another: bool) -> None:
        """Runs found in the store: 'cached' when done, 'failed' (with why) when failed; they join
        this sweep's experiments too."""
        for run_id, status in stored.items():
            if status == "done":
                self.summary.cached.append(run_id)
            else:
                self.summary.failed.append(run_id)
                self.summary.errors[run_id] = (f"failed in {'another' if by_another else 'an earlier'} sweep "
                                               "(use --retry-failed to redo)")
        for name, ids in self.experiments.items():
            if ids & set(stored):
                self.store.add_to_experiment(name, sorted(ids & set(stored)))
        if self.bar is not None and stored:
            self.bar.update(len(stored))
            self._show()

    def note_waiting(self, held: dict) -> None:
        """Say once per run that another sweep is computing it."""
        new = set(held) - self.waiting_for
        if new and not self.quiet:
            holders = sorted({h.describe() for h in held.values()})
            print(f"{len(new)} run(s) are being computed by another sweep on this store ({', '.join(holders)}); "
                  "waiting for them (Ctrl-C stops waiting; they stay with that sweep)", file=sys.stderr, flush=True)
        self.waiting_for |= new

    def compute(self, specs: list[RunSpec]) -> None:
        """Run ``specs`` (claimed by this sweep) and record each outcome as it arrives."""
        if not specs:
            return
        if self.timeout_s:
            for spec in specs:
                spec.timeout_s = float(self.timeout_s)
        warm_caches(specs, self.quiet)
        if self.runner is None:
            self._start()
        assert self.runner is not None
        for spec, outcome in self.runner.execute(specs, self.runs_path, self.force):
            self._record(spec, outcome)

    def _start(self) -> None:
        from dpcbench.bench.core.progress import progress_bar  # tqdm loads only when a sweep runs

        runner = self.runner = make_executor(*self.executor_args)
        # runs already in the store start the bar (`initial`), so its rate and ETA count only runs computed now
        self.bar = progress_bar(total=len(self.specs), desc=f"runs ({runner.name} x{runner.jobs})",
                                unit="run", quiet=self.quiet,
                                initial=len(self.summary.cached) + len(self.summary.failed))
        self._show()

    def _record(self, spec: RunSpec, outcome: dict) -> None:
        summary, bar = self.summary, self.bar
        if outcome.get("status") == "done":
            record = RunRecord.from_facts(spec.run_id, outcome["record"], "done")
            self.store.record_run(spec.run_id, record, outcome["results"], [spec.experiment])
            summary.done.append(spec.run_id)
        else:
            error = outcome.get("error", "unknown error")
            self.store.record_failure(spec.run_id, _failure_record(spec, outcome, error), error, [spec.experiment])
            summary.failed.append(spec.run_id)
            summary.errors[spec.run_id] = error
            if not self.quiet and bar is not None:
                bar.write(f"run {spec.run_id} ({spec.method['name']} on {spec.sequence_label}) failed: "
                          f"{error.splitlines()[0]}")
        if bar is not None:
            bar.update(1)
            self._show()

    def _show(self) -> None:
        if self.bar is not None:
            s = self.summary
            self.bar.set_postfix_str(f"done {len(s.done)}, cached {len(s.cached)}, failed {len(s.failed)}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
