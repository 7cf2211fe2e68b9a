"""`dpcbench margins STORE --method NAME`: a method's margins against its targets, tuning and held-out
data side by side (`bench.reporting.margins`)."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "margins", help="a method's margins (D1 vs the best other, D2 vs no fill, NSHD, temporal consistency) "
                        "per row, on tuning and held-out data side by side",
        description="Per row (sequence x holes) of every experiment read: the method's whole-frame D1 minus the best "
                    "other method's, D2 minus no fill's, the best other NSHD minus its NSHD and the best other "
                    "temporal consistency in the holes minus its own, each with its bootstrap 95% interval (whole "
                    "seeds resampled, each with all its frames), "
                    "n (frames x seeds) and whether the target is met beyond noise; then a count per target and data "
                    "role (experiment.data_role: tuning or heldout). Markdown on stdout; with --out also "
                    "margins.md and margins.csv.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("store", help="results store (SQLite file) or a folder holding results.sqlite")
    p.add_argument("--method", default="temporal-fusion", help="the method whose margins are measured (a registry "
                   "name, or a configuration's label when the store holds several)")
    p.add_argument("--experiments", nargs="+", default=None, metavar="NAME",
                   help="experiments to read (default: every one holding a run of the method)")
    p.add_argument("--oracle", action="store_true",
                   help="also score the smooth-surface oracle (samples on the ground truth's own smooth surface, "
                        "`dpcbench oracle --variant smooth`) "
                        "on every row's damaged frames: its D1 - best other and D2 - no fill show which targets are "
                        "out of reach of any fill; loads every sequence again (minutes on a full grid)")
    p.add_argument("--out", default=None, help="folder for margins.md and margins.csv")
    p.add_argument("--overwrite", action="store_true",
                   help="replace existing files in the output folder that dpcbench did not write")
    p.set_defaults(func=main)


def main(args) -> int:
    from dpcbench.bench.cli.options import resolve_store
    from dpcbench.bench.data.outputs import Outputs
    from dpcbench.bench.reporting.margins import margins_from_store
    from dpcbench.bench.results.store import ResultsStore

    store = ResultsStore(resolve_store(args.store), readonly=True, verify=True)
    guard = Outputs(args.overwrite, inputs=[store.path])
    out = guard.folder(args.out, "--out", names=["margins.md", "margins.csv"]) if args.out else None
    report = margins_from_store(store, args.method, args.experiments, oracle=args.oracle)
    words = ["dpcbench", "margins", str(args.store), "--method", args.method]
    if args.experiments:
        words += ["--experiments", *args.experiments]
    if args.oracle:
        words.append("--oracle")
    text = report.markdown(" ".join(shlex.quote(w) for w in words))
    print(text, end="")
    if out is not None:
        with guard.staged(out) as staged:
            (Path(staged) / "margins.md").write_text(text, encoding="utf-8")
            (Path(staged) / "margins.csv").write_text(report.csv(), encoding="utf-8")
        print(f"margins: {out / 'margins.md'}, {out / 'margins.csv'}")
    return 0
