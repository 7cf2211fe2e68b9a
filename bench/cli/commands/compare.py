"""`dpcbench compare [BASELINE] [CURRENT]`: quality and speed against a committed baseline.

BASELINE: a summary file (.csv/.json); default results/regression-baseline.csv of the source tree.
CURRENT:  a summary file, or a results store (.sqlite/.db) whose latest runs of `--experiment` are
          summarized now; default the store of `--store` / DPCBENCH_STORE / the runner's default.
Exit code 1 when a quality metric regressed beyond its tolerance (or time, with --gate-time),
0 otherwise, 2 for bad input.
"""

from __future__ import annotations

from pathlib import Path

from dpcbench.bench.cli.options import DEFAULT_BASELINE, DEFAULT_EXPERIMENT, REPO_ROOT, TOLERANCES_FILE, run_environment
from dpcbench.bench.core.errors import UserError

SUMMARY_SUFFIXES = (".csv", ".json")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "compare",
        help="compare results against a baseline summary (exit 1 on a quality regression)",
        description=__doc__.split("\n", 2)[2] if __doc__ else None,
    )
    parser.add_argument("baseline", nargs="?", default=None,
                        help=f"baseline summary .csv/.json (default: {DEFAULT_BASELINE.relative_to(REPO_ROOT)})")
    parser.add_argument("current", nargs="?", default=None,
                        help="current summary .csv/.json or a results store .sqlite (default: the results store)")
    parser.add_argument("--store", default=None, help="results store to summarize when CURRENT is not given")
    parser.add_argument("--experiment", default=DEFAULT_EXPERIMENT,
                        help=f"experiment to summarize from a store (default: {DEFAULT_EXPERIMENT}; '' = all)")
    parser.add_argument("--tolerances", default=None,
                        help="TOML file with a [tolerances] table (default: results/tolerances.toml)")
    parser.add_argument("--gate-time", action="store_true",
                        help="also fail when time per frame grows beyond its tolerance")
    parser.add_argument("--changes-only", action="store_true", help="print only rows that are not ✓")
    parser.add_argument("--save-current", metavar="FILE", default=None,
                        help="write the current summary (with code version and environment) to FILE; "
                             "this is how results/regression-baseline.csv is made")
    parser.add_argument("--out", metavar="FILE", default=None, help="also write the comparison table as CSV")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing --out / --save-current file that dpcbench did not write")
    parser.set_defaults(func=run)


def current_from_store(store_path, experiment: str | None):
    """(summary, meta) of the latest runs of `experiment` in a results store."""
    from dpcbench.bench.results import compare
    from dpcbench.bench.results.store import ResultsStore

    store = ResultsStore(store_path, readonly=True, verify=True)
    results = store.results_frame()
    runs = store.runs_frame()
    if results.empty:
        where = store_path or "the default results store"
        raise UserError(f"{where} holds no results; run `dpcbench run bench/presets/regression.toml` first")
    if experiment and "experiment" in results.columns and experiment not in set(results["experiment"]):
        known = ", ".join(sorted(map(str, results["experiment"].dropna().unique())))
        raise UserError(f"no runs of experiment {experiment!r} in the store (it has: {known}); "
                        "pass --experiment NAME")
    # cells by the runs' identity (minus the seed), so two different runs never merge under one label
    results = compare.with_cells(results, runs)
    summary = compare.summarize(results, experiment=experiment or None)
    chosen = results if not experiment else results[results["experiment"] == experiment]
    environment = run_environment(runs, set(chosen["run_id"]))
    meta = compare.summary_meta(results=chosen, environment=environment,
                                source=str(getattr(store, "path", store_path or "default store")),
                                experiment=experiment or "all")
    return summary, meta


def machine_line(meta: dict) -> str:
    """Which machine and instruction set made a summary, from its ``env.*`` header (the run
    environment: node, arch, cpus, isa as `bench.core.isa.describe` wrote it)."""
    node, arch, cpus = meta.get("env.node"), meta.get("env.arch"), meta.get("env.cpus")
    machine = (f"{node or '?'} ({arch or '?'}, {cpus or '?'} cpus)" if node or arch
               else meta.get("env.machine", "machine not recorded"))
    return f"made on {machine}; instruction set: {meta.get('env.isa') or 'not recorded (made before dpcbench recorded it)'}"


def _pin_part(isa: str) -> str:
    """The part of a `bench.core.isa.describe` text that decides the last bits: the dispatch (pinned or not)."""
    return isa.split("; ", 1)[-1]


def load_side(path: str | None, *, store: str | None, experiment: str | None, role: str):
    from dpcbench.bench.results import compare

    if path is not None and Path(path).suffix.lower() in SUMMARY_SUFFIXES:
        return compare.read_summary(path)
    if path is not None and not Path(path).exists():
        raise UserError(f"{path}: no such {role} file; give a summary .csv/.json or a results store")
    return current_from_store(path if path is not None else store, experiment)


def run(args) -> int:
    from dpcbench.bench.data.outputs import Outputs, record_written
    from dpcbench.bench.results import compare

    baseline_path = args.baseline or str(DEFAULT_BASELINE)
    if Path(baseline_path).suffix.lower() not in SUMMARY_SUFFIXES:
        raise UserError(f"{baseline_path}: BASELINE must be a summary .csv or .json")
    guard = Outputs(args.overwrite, inputs=[p for p in (args.baseline, args.current) if p])
    if args.save_current:
        guard.file(args.save_current, "--save-current", suffixes=SUMMARY_SUFFIXES)
    if args.out:
        guard.file(args.out, "--out", suffixes=(".csv",))
    current, current_meta = load_side(args.current, store=args.store, experiment=args.experiment, role="current")
    if args.save_current:
        written = compare.write_summary(current, args.save_current, current_meta)
        record_written([written])
        print(f"current summary ({len(current)} rows, code {current_meta.get('code_version')}) written to {written}")
        if args.baseline is None and not DEFAULT_BASELINE.is_file():
            return 0  # making the first baseline: nothing to compare against yet
    if args.baseline is None and not DEFAULT_BASELINE.is_file():
        raise UserError(f"no baseline at {DEFAULT_BASELINE}; give BASELINE, or make one with "
                        "`dpcbench compare --save-current results/regression-baseline.csv` after a regression run")
    baseline, baseline_meta = load_side(baseline_path, store=None, experiment=None, role="baseline")

    tolerance_file = args.tolerances or (TOLERANCES_FILE if TOLERANCES_FILE.is_file() else None)
    tolerances = compare.load_tolerances(tolerance_file)
    result = compare.compare_summaries(baseline, current, tolerances, gate_time=args.gate_time)
    result.baseline_meta, result.current_meta = baseline_meta, current_meta

    print(f"baseline: {baseline_path}  (code {baseline_meta.get('code_version', '?')}, "
          f"{baseline_meta.get('date', '?')})")
    print(f"          {machine_line(baseline_meta)}")
    print(f"current:  {args.current or args.store or 'results store'}  (code "
          f"{current_meta.get('code_version', '?')}, {current_meta.get('date', '?')})")
    print(f"          {machine_line(current_meta)}")
    isas = (baseline_meta.get("env.isa"), current_meta.get("env.isa"))
    if None not in isas and _pin_part(isas[0]) != _pin_part(isas[1]):
        print("note: baseline and current were computed with different instruction sets; temporal-graph and "
              "fu-nonlocal can move 0.1-0.5 dB from that alone (run the regression preset, which pins itself: "
              "pin_isa in bench/presets/regression.toml)")
    print(f"tolerances: {tolerance_file or 'built-in defaults'}")
    print()
    print(result.format(only_changes=args.changes_only))
    if args.out:
        from dpcbench.bench.core.atomic import atomic_write_text

        record_written([atomic_write_text(args.out, result.table.to_csv(index=False))])
    return 1 if result.failed else 0
