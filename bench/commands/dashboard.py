"""`dpcbench dashboard --out FILE.html`: the regression dashboard as one static HTML page."""

from __future__ import annotations

from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "dashboard",
        help="write the regression dashboard (one self-contained HTML page)",
        description="History of the runs in the results store across code versions, the latest comparison "
                    "with regressions flagged, the paper's values as reference lines, and the benchmark "
                    "suite's speed history. No server, no network: everything is inside the page.",
    )
    parser.add_argument("--out", required=True, help="HTML file to write")
    parser.add_argument("--store", action="append", default=None, metavar="PATH",
                        help="results store (repeat to merge several, e.g. one per commit; "
                             "default: DPCBENCH_STORE or ~/.cache/dpcbench/results.sqlite)")
    parser.add_argument("--experiment", default=None, help="only this experiment's runs (default: all)")
    parser.add_argument("--benchmarks", action="append", default=None, metavar="DIR_OR_JSON",
                        help="pytest-benchmark JSON file or storage folder (repeatable; default: ./.benchmarks "
                             "when it exists)")
    parser.add_argument("--summary", action="append", default=None, metavar="FILE",
                        help="a summary .csv/.json (e.g. an older results/regression-baseline.csv from git) added "
                             "to the history as one more code version; repeatable")
    parser.add_argument("--baseline", default=None,
                        help="compare the newest code version against this summary .csv/.json instead of "
                             "the previous code version")
    parser.add_argument("--tolerances", default=None, help="TOML file with a [tolerances] table")
    parser.add_argument("--title", default="dpcbench regression dashboard")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing FILE.html that dpcbench did not write")
    parser.set_defaults(func=run)


def load_stores(paths, experiment):
    """(results, runs) of one or several stores, concatenated."""
    import pandas as pd

    from dpcbench.bench.store import ResultsStore

    results, runs = [], []
    paths = paths or [None]
    for i, path in enumerate(paths):
        store = ResultsStore(path, readonly=True, verify=True)
        store_results = store.results_frame(experiment)
        store_runs = store.runs_frame(experiment)
        if len(paths) > 1:
            # run ids hash the spec, not the commit: the same run in two stores (e.g. one per commit)
            # is two runs here
            store_results["run_id"] = f"{i}:" + store_results["run_id"]
            store_runs["run_id"] = f"{i}:" + store_runs["run_id"]
        results.append(store_results)
        runs.append(store_runs)
    return pd.concat(results, ignore_index=True), pd.concat(runs, ignore_index=True)


def run(args) -> int:
    import pandas as pd

    from dpcbench.bench import benchsuite, compare, dashboard
    from dpcbench.bench.commands.compare import TOLERANCES_FILE
    from dpcbench.bench.outputs import Outputs, record_written
    from dpcbench.bench.store import RESULT_COLUMNS

    guard = Outputs(args.overwrite, inputs=(args.store or []) + (args.summary or []) + (args.benchmarks or []))
    out = guard.file(args.out, "--out", suffixes=(".html", ".htm"))
    if args.summary and not args.store:
        results, runs = pd.DataFrame(columns=RESULT_COLUMNS), None
    else:
        results, runs = load_stores(args.store, args.experiment)
    for i, path in enumerate(args.summary or []):
        table, meta = compare.read_summary(path)
        results = pd.concat([results, dashboard.summary_as_results(table, meta, run_prefix=f"summary{i}")],
                            ignore_index=True)
    benchmarks = None
    bench_paths = args.benchmarks or ([".benchmarks"] if Path(".benchmarks").is_dir() else [])
    if bench_paths:
        benchmarks = benchsuite.load_benchmark_runs(bench_paths)
    baseline = compare.read_summary(args.baseline) if args.baseline else None
    tolerance_file = args.tolerances or (TOLERANCES_FILE if TOLERANCES_FILE.is_file() else None)
    tolerances = compare.load_tolerances(tolerance_file)
    sources = [str(p) for p in (args.store or ["default results store"])] + [str(p) for p in bench_paths]
    written = dashboard.write_dashboard(out, results, runs=runs, benchmarks=benchmarks, baseline=baseline,
                                        tolerances=tolerances, title=args.title, sources=sources)
    record_written([written])
    n_versions = results["code_version"].nunique() if len(results) else 0
    print(f"dashboard written to {written} ({n_versions} code version(s), {results['run_id'].nunique()} runs"
          f"{', ' + str(benchmarks['fullname'].nunique()) + ' benchmarks' if benchmarks is not None else ''})")
    return 0
