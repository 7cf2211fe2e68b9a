"""`dpcbench cost [STORE]`: what an experiment's (or a config's) runs cost, per method and in total.

Reads the results store's runs table only (read-only; nothing is run or written): per method
configuration the number of runs, the summed wall and CPU time, and the elapsed span from the first
run's start to the last run's finish (`bench.results.costs`).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "cost", help="an experiment's cost from a results store: runs, wall and CPU time, elapsed span per method",
        description="Per method configuration and in total: the stored runs of an experiment (done and failed), "
                    "their summed wall time and CPU time (user + system, all threads of each run's worker), and the "
                    "elapsed time from the first run's start to the last run's finish. Runs recorded before CPU "
                    "time was stored are counted apart. With --config, exactly the runs that config (or preset) "
                    "expands to now, whichever experiment they were stored under.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("store", nargs="?", default=None,
                   help="results store (SQLite file) or a folder holding results.sqlite; default $DPCBENCH_STORE "
                        "or ~/.cache/dpcbench/results.sqlite")
    p.add_argument("--experiment", default=None,
                   help="experiment name (default: the only one in the store, else required unless --config)")
    p.add_argument("--config", default=None, metavar="CONFIG",
                   help="experiment TOML or preset name (e.g. paper): count exactly the runs it expands to")
    p.add_argument("--data-dir", default=None, help="with --config: folder holding the paper's sequences")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.set_defaults(func=main)


def _runs_of_config(store, args):
    from dpcbench.bench.cli.options import resolve_config_path
    from dpcbench.bench.experiment.config import load_config

    overrides = {"experiment": {"data_dir": args.data_dir}} if args.data_dir else None
    cfg = load_config(resolve_config_path(args.config), overrides)
    ids = {s.run_id for s in cfg.expand()}
    runs = store.runs_frame()
    runs = runs[runs["run_id"].isin(ids)]
    return f"config {cfg.name!r} ({cfg.source})", runs, len(ids)


def main(args) -> int:
    from dpcbench.bench.cli.options import resolve_store
    from dpcbench.bench.results.costs import cost_table, format_cost_table
    from dpcbench.bench.results.store import ResultsStore, default_store_path

    path = resolve_store(args.store) if args.store else default_store_path()
    if not Path(path).is_file():
        raise UserError(f"{path}: no results store there; pass the store (or run `dpcbench run CONFIG` first)")
    store = ResultsStore(path, readonly=True, verify=True)
    expected = None
    if args.config:
        if args.experiment:
            raise UserError("give --experiment or --config, not both (--config picks the runs by their ids)")
        what, runs, expected = _runs_of_config(store, args)
    else:
        from dpcbench.bench.cli.options import choose_experiment

        experiment = choose_experiment(store, args.experiment, " (or give --config)")
        what, runs = f"experiment {experiment!r}", store.runs_frame(experiment)
    table = cost_table(runs)
    stored = int(runs["run_id"].nunique())
    if args.json:
        payload = {"store": str(store.path), "selection": what, "stored_runs": stored, "expected_runs": expected,
                   "rows": json.loads(table.to_json(orient="records"))}
        print(json.dumps(payload, indent=1))
        return 0
    counted = f"{stored} stored run(s)" + (f" of the {expected} it expands to" if expected is not None else "")
    print(f"cost of {what}: {counted}; store {store.path}")
    print(format_cost_table(table))
    if stored:
        print("wall / CPU: summed over the runs (each run's worker: load, damage, inpaint, score); elapsed: first "
              "run's start to last run's finish, pauses between sweeps included.")
    return 0
