"""`dpcbench report RESULTS`: a method comparison report (Markdown + figures) from a results store."""

from __future__ import annotations

import argparse
from pathlib import Path

from dpcbench.bench.cli.options import choose_experiment, resolve_store
from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "report", help="method comparison report (Markdown, LaTeX, CSV tables and figures) from a results store",
        description="Tables (rows = sequences, columns = methods, the mean over frames x seeds and its 95% interval "
                    "over whole damages (seeds); bold: best beyond every other's interval, paired Wilcoxon "
                    "signed-rank with Holm; the no-fill floor marked) for every metric and scope of an experiment, "
                    "bar charts, per-frame curves, runtime, failures.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("results", help="results store (SQLite file) or a folder holding results.sqlite")
    p.add_argument("--experiment", default=None, help="experiment name (default: the only one, else required)")
    p.add_argument("--metrics", default=None, help="comma-separated metrics (default: all stored)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--labels", default=None, metavar="CONFIG",
                   help="experiment config (TOML) whose [labels] table renames methods in the tables and figures "
                        '("method label" = "name in the paper")')
    p.add_argument("--overwrite", action="store_true",
                   help="replace existing files in the output folder that dpcbench did not write")
    p.set_defaults(func=main)


def main(args) -> int:
    from dpcbench.bench.data.outputs import Outputs
    from dpcbench.bench.reporting.reports import write_comparison_report
    from dpcbench.bench.results.store import ResultsStore

    display_names = None
    if args.labels:
        from dpcbench.bench.experiment.config import load_labels

        display_names = load_labels(args.labels)  # before the store is read: a bad table fails at once
    store = ResultsStore(resolve_store(args.results), readonly=True, verify=True)
    experiment = choose_experiment(store, args.experiment)
    df = store.results_frame(experiment)
    runs = store.runs_frame(experiment)
    if df.empty:
        raise UserError(
            f"experiment {experiment!r} has no finished run ({len(runs)} failed); see `dpcbench run` output")
    metrics = [m.strip() for m in args.metrics.split(",")] if args.metrics else None
    if metrics:
        unknown = [m for m in metrics if m not in set(df["metric"])]
        if unknown:
            raise UserError(f"--metrics: {', '.join(unknown)} not stored for {experiment!r}; stored: "
                            f"{', '.join(sorted(set(df['metric'])))}")
    guard = Outputs(args.overwrite, inputs=[store.path])
    out = guard.folder(args.out, "--out")
    with guard.staged(out) as staged:  # written aside, moved in once no file of the user's would be replaced
        report = write_comparison_report(df, runs, staged, title=f"Method comparison: experiment {experiment}",
                                         metrics=metrics, store_path=store.path, display_names=display_names)
    print(f"report: {out / Path(report).relative_to(staged)}")
    return 0
