"""`dpcbench run CONFIG`: expand an experiment config into runs and execute the missing ones."""

from __future__ import annotations

import argparse
import os

from dpcbench.bench.cli.options import add_pin_option, pinned_workers, resolve_config_path
from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run", help="run an experiment config (resumable; finished runs are cached)",
        description="Expand CONFIG (TOML: sequences x holes x method parameter grids) into runs and execute "
                    "those not yet in the results store. Each run is a worker process with a timeout; a crash "
                    "is recorded as a failed run and the sweep goes on. Interrupt at any time and rerun: "
                    "finished runs are kept, unfinished ones are redone.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("config", help="experiment TOML file, or a preset name from bench/presets (e.g. paper-quick)")
    p.add_argument("--dry-run", action="store_true", help="list the runs and whether they are cached; run nothing")
    p.add_argument("--store", default=None,
                   help="results store (SQLite); default $DPCBENCH_STORE or ~/.cache/dpcbench/results.sqlite")
    p.add_argument("--runs-dir", default=None, help="where run folders (frames) go; default: runs/ beside the store")
    p.add_argument("--executor", choices=("serial", "pool", "dask"), default="pool")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="Dask scheduler address (tcp://host:8786); implies --executor dask")
    p.add_argument("--jobs", type=int, default=None, help="parallel runs; None = all cores")
    p.add_argument("--timeout", type=float, default=None, help="seconds per run (overrides experiment.timeout_s)")
    p.add_argument("--data-dir", default=None, help="folder holding the paper's sequences (longdress, ...)")
    p.add_argument("--force", action="store_true", help="redo every run, frames included")
    p.add_argument("--retry-failed", action="store_true", help="redo runs that failed before")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_pin_option(p)
    p.set_defaults(func=main)


def main(args) -> int:
    from dpcbench.bench.data.outputs import user_path
    from dpcbench.bench.execution.runner import run_experiment
    from dpcbench.bench.experiment.config import load_config
    from dpcbench.bench.results.store import ResultsStore, default_store_path

    if args.jobs is not None and args.jobs < 1:
        raise UserError("--jobs: must be at least 1")
    if args.timeout is not None and args.timeout <= 0:
        raise UserError("--timeout: must be a positive number of seconds")
    overrides = {"experiment": {"data_dir": args.data_dir}} if args.data_dir else None
    cfg = load_config(resolve_config_path(args.config), overrides)
    specs = cfg.expand()
    if args.dry_run:  # reads the store if there is one; creates nothing
        path = user_path(args.store) if args.store else default_store_path()
        ResultsStore.check_path(path)
        store = ResultsStore(path, readonly=True, verify=True) if path.is_file() else None
        statuses = store.statuses([s.run_id for s in specs]) if store is not None else {}
        for spec in specs:
            print(f"{statuses.get(spec.run_id, 'todo'):7s} {spec.summary()}")
        todo = sum(1 for s in specs if s.run_id not in statuses)
        print(f"{len(specs)} runs in experiment {cfg.name!r}: {todo} to do, {len(specs) - todo} stored; store {path}"
              f"{'' if store is not None else ' (not created yet)'}")
        return 0
    if args.runs_dir is not None:
        _check_runs_dir(args.runs_dir)
    store = ResultsStore(args.store, verify=True)
    quiet = args.quiet or os.environ.get("DPCBENCH_QUIET", "") not in ("", "0")
    # the workers start inside, with the pin in their environment before numpy loads; the caller's comes back after
    with pinned_workers(cfg.pin_isa or args.pin_isa, f"experiment {cfg.name!r}"):
        summary = run_experiment(specs, store, runs_dir=args.runs_dir, executor=args.executor, jobs=args.jobs,
                                 scheduler=args.scheduler, force=args.force, retry_failed=args.retry_failed,
                                 quiet=quiet, timeout_s=args.timeout)
    print(f"experiment {cfg.name!r}: {len(summary.done)} run(s) done, {len(summary.cached)} cached, "
          f"{len(summary.failed)} failed; store {store.path}")
    for run_id in summary.failed:
        error = summary.errors.get(run_id) or ""
        print(f"  failed {run_id}: {error.splitlines()[0] if error else ''}")
    return 1 if summary.failed else 0


def _check_runs_dir(text: str) -> None:
    """UserError unless --runs-dir is (or can be created as) a folder this process can write in."""
    from dpcbench.bench.data.outputs import _check_writable_folder, _existing_ancestor, _resolvable, user_path

    path = user_path(text)
    _resolvable(path, "--runs-dir", text)
    if path.exists() and not path.is_dir():
        raise UserError(f"--runs-dir {text}: is a file, not a folder; give a folder for the run folders")
    base = _existing_ancestor(path)
    if not base.is_dir():
        raise UserError(f"--runs-dir {text}: {base} is a file, not a folder; give a folder for the run folders")
    _check_writable_folder(path, "--runs-dir", text)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UserError(f"--runs-dir {text}: cannot create it ({err.strerror or err}); give a folder you can "
                        "write to") from None
