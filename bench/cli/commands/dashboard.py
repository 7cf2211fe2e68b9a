"""`dpcbench dashboard --out FILE.html`: the regression dashboard, one self-contained HTML page (plus
a page per method and per run beside it), and `--save-history DIR` to add the store's summary to a
history folder."""

from __future__ import annotations

from pathlib import Path

from dpcbench.bench.cli.options import REPO_ROOT
from dpcbench.bench.core.errors import UserError

#: the committed history of the regression preset: one summary per commit
DEFAULT_HISTORY = REPO_ROOT / "results" / "history"
#: `--baseline previous`: compare the newest code version with the one before it, not a summary
PREVIOUS = "previous"


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "dashboard",
        help="write the regression dashboard (self-contained interactive HTML pages)",
        description="History of the runs in the results store and of a folder of per-commit summaries "
                    "(results/history/) across code versions, the latest comparison with regressions flagged "
                    "(against results/regression-baseline.csv when it covers the store's runs), the paper's values "
                    "as reference lines, the benchmark suite's speed history, and a page per method and per run. "
                    "No server, no network: everything is inside the pages.",
    )
    parser.add_argument("--out", default=None, help="HTML file to write (needed unless only --save-history)")
    parser.add_argument("--store", action="append", default=None, metavar="PATH",
                        help="results store (repeat to merge several, e.g. one per commit; "
                             "default: DPCBENCH_STORE or ~/.cache/dpcbench/results.sqlite)")
    parser.add_argument("--experiment", default=None, help="only this experiment's runs (default: all)")
    parser.add_argument("--history", default=None, metavar="DIR",
                        help="folder of per-commit summaries (.csv/.json) joined to the history, one code version "
                             f"each (default: {DEFAULT_HISTORY.relative_to(REPO_ROOT)} of the source tree when it "
                             "exists)")
    parser.add_argument("--no-history", action="store_true", help="no history folder, not even the default")
    parser.add_argument("--save-history", default=None, metavar="DIR",
                        help="write the store's summary (newest run per cell of --experiment, default 'regression') "
                             "to DIR as one file for its commit, replacing that commit's earlier file; with --out "
                             "the page is written too")
    parser.add_argument("--benchmarks", action="append", default=None, metavar="DIR_OR_JSON",
                        help="pytest-benchmark JSON file or storage folder (repeatable; default: ./.benchmarks "
                             "when it exists)")
    parser.add_argument("--summary", action="append", default=None, metavar="FILE",
                        help="a summary .csv/.json (e.g. an older results/regression-baseline.csv from git) added "
                             "to the history as one more code version; repeatable")
    parser.add_argument("--baseline", default=None,
                        help="compare the newest code version against this summary .csv/.json, or 'previous' for "
                             "the code version before it (default: results/regression-baseline.csv where it "
                             "shares rows with the store, else 'previous')")
    parser.add_argument("--no-pages", action="store_true", help="only the main page: no per-method and per-run pages")
    parser.add_argument("--no-thumbnails", action="store_true",
                        help="run pages without the thumbnail of frame 0 (which reads the run folder's frames)")
    parser.add_argument("--tolerances", default=None, help="TOML file with a [tolerances] table")
    parser.add_argument("--title", default="dpcbench regression dashboard")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing FILE.html that dpcbench did not write")
    parser.set_defaults(func=run)


def load_stores(paths, experiment):
    """(results, runs) of one or several stores, concatenated."""
    import pandas as pd

    from dpcbench.bench.results.store import ResultsStore

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


def save_history(folder: Path, store_paths, experiment: str | None, guard) -> Path:
    """The store's summary as `folder`/<date>_<commit>.csv (`dashboard.history_file_name`); an older
    file of the same commit there is replaced (one dpcbench did not write, e.g. a committed one, only
    with --overwrite: ``guard``, the command's `Outputs`)."""
    from dpcbench.bench.cli.options import DEFAULT_EXPERIMENT, run_environment
    from dpcbench.bench.data.outputs import record_written
    from dpcbench.bench.reporting import dashboard
    from dpcbench.bench.results import compare

    if store_paths and len(store_paths) > 1:
        raise UserError("--save-history summarizes one store: give a single --store")
    experiment = DEFAULT_EXPERIMENT if experiment is None else experiment
    results, runs = load_stores(store_paths, None)
    where = (store_paths or ["the default results store"])[0]
    if results.empty:
        raise UserError(f"{where} holds no results; run `dpcbench run regression --store {where}` first")
    if experiment:
        if experiment not in set(results["experiment"]):
            known = ", ".join(sorted(map(str, results["experiment"].dropna().unique())))
            raise UserError(f"no runs of experiment {experiment!r} in {where} (it has: {known}); pass --experiment")
        results = results[results["experiment"] == experiment]
    summary, meta = dashboard.history_summary(results, runs, run_environment(runs, set(results["run_id"])),
                                              source=str(where), experiment=experiment or "all")
    name = dashboard.history_file_name(meta)
    commit = name.split("_", 1)[-1]
    same_commit = sorted(p for p in folder.glob(f"*_{commit}") if p.name != name) if folder.is_dir() else []
    for path in [folder / name, *same_commit]:
        guard.file(path, "--save-history", suffixes=(".csv",))
    folder.mkdir(parents=True, exist_ok=True)
    for old in same_commit:
        old.unlink()  # one file per commit
    written = compare.write_summary(summary, folder / name, meta)
    record_written([written])
    print(f"summary of code {dashboard.short_version(meta['code_version'])} ({len(summary)} rows) written to {written}")
    return written


def choose_baseline(arg: str | None, results):
    """(summary, meta) to compare against, or None for the previous code version: ``arg`` a file, or
    'previous'; unset: the committed regression baseline where it shares rows with ``results``."""
    from dpcbench.bench.cli.options import DEFAULT_BASELINE
    from dpcbench.bench.reporting import dashboard
    from dpcbench.bench.results import compare

    if arg == PREVIOUS:
        return None
    if arg is not None:
        table, meta = compare.read_summary(arg)
        return table, {**meta, "path": str(arg)}
    if not DEFAULT_BASELINE.is_file() or results.empty:
        return None
    table, meta = compare.read_summary(DEFAULT_BASELINE)
    if not dashboard.shares_rows(table, results):
        return None
    return table, {**meta, "path": str(DEFAULT_BASELINE.relative_to(REPO_ROOT))}


def run(args) -> int:
    import pandas as pd

    from dpcbench.bench.cli.options import TOLERANCES_FILE
    from dpcbench.bench.data.outputs import Outputs, record_written
    from dpcbench.bench.reporting import dashboard, dashboard_pages
    from dpcbench.bench.results import benchsuite, compare
    from dpcbench.bench.results.store import RESULT_COLUMNS

    if args.out is None and args.save_history is None:
        raise UserError("give --out FILE.html (the dashboard) and/or --save-history DIR (add the store's summary)")
    if args.history and args.no_history:
        raise UserError("--history and --no-history contradict each other; give one")
    history_dir = None if args.no_history else (
        Path(args.history) if args.history else (DEFAULT_HISTORY if DEFAULT_HISTORY.is_dir() else None))
    guard = Outputs(args.overwrite, inputs=(args.store or []) + (args.summary or []) + (args.benchmarks or []))
    out = guard.file(args.out, "--out", suffixes=(".html", ".htm")) if args.out else None
    if args.save_history:
        save_history(Path(args.save_history), args.store, args.experiment, guard)
    if out is None:  # --save-history alone
        return 0
    # (table, meta, source): a history file's path, or "summary<i>" for a --summary file
    history: list[tuple[pd.DataFrame, dict, Path | str]] = []
    if history_dir is not None:
        history = list(dashboard.read_history(history_dir))  # bad input fails first
    if args.summary and not args.store:
        results, runs = pd.DataFrame(columns=RESULT_COLUMNS), None
    else:
        results, runs = load_stores(args.store, args.experiment)
    store_results = results
    extra, machines = [], {}
    for i, path in enumerate(args.summary or []):
        table, meta = compare.read_summary(path)
        history.append((table, meta, f"summary{i}"))
    for i, (table, meta, source) in enumerate(history):
        given = str(source).startswith("summary")  # --summary files join whatever their experiment
        if not given and args.experiment and meta.get("experiment") not in (None, "", args.experiment):
            continue
        prefix = str(source) if given else f"history{i}"
        part = dashboard.summary_as_results(table, meta, run_prefix=prefix)
        extra.append(part)
        machine = dashboard.machine_name(meta)
        if machine and len(part):
            machines[part["code_version"].iloc[0]] = machine
    results = pd.concat([results, *extra], ignore_index=True) if extra else results
    pages_dir = out.parent / f"{out.stem}_pages"  # the name `dashboard_pages.write_dashboard` gives it
    if not args.no_pages and pages_dir.is_dir():
        guard.folder(pages_dir, "--out", names=[p.name for p in pages_dir.glob("*.html")])
    benchmarks = None
    bench_paths = args.benchmarks or ([".benchmarks"] if Path(".benchmarks").is_dir() else [])
    if bench_paths:
        benchmarks = benchsuite.load_benchmark_runs(bench_paths)
    baseline = choose_baseline(args.baseline, store_results if len(store_results) else results)
    tolerance_file = args.tolerances or (TOLERANCES_FILE if TOLERANCES_FILE.is_file() else None)
    tolerances = compare.load_tolerances(tolerance_file)
    sources = [str(p) for p in (args.store or ["default results store"])] + [str(p) for p in bench_paths]
    n_folder = sum(not str(source).startswith("summary") for _, _, source in history)
    if n_folder:
        sources.append(f"{n_folder} summaries in {history_dir}")
    written = dashboard_pages.write_dashboard(out, results, runs=runs, benchmarks=benchmarks, baseline=baseline,
                                        tolerances=tolerances, title=args.title, sources=sources, machines=machines,
                                        pages=not args.no_pages, thumbnails=not args.no_thumbnails)
    record_written(written)
    n_versions = results["code_version"].nunique() if len(results) else 0
    pages = f", {len(written) - 1} method and run pages beside it" if len(written) > 1 else ""
    n_summaries = len(history)
    n_runs = store_results["run_id"].nunique() if len(store_results) else 0
    print(f"dashboard written to {written[0]} ({n_versions} code version(s), {n_runs} runs"
          f"{f', {n_summaries} summaries' if n_summaries else ''}"
          f"{', ' + str(benchmarks['fullname'].nunique()) + ' benchmarks' if benchmarks is not None else ''}{pages})")
    return 0
