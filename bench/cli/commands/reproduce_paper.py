"""`dpcbench reproduce-paper`: the paper's protocol end to end, tables, figures and REPORT.md."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

from dpcbench.bench.cli.options import add_pin_option, pinned_workers
from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reproduce-paper", help="run the paper's protocol and write its Tables 1-2, figures and REPORT.md",
        description="Fu, Hu, Guo (ICME 2020): Meshlab, Lozes, Hu and the proposed temporal method over synthetic "
                    "holes. With --data-dir, on the paper's sequences found there (longdress, loot, redandblack, "
                    "soldier, ulliwegner); otherwise on the embedded stand-ins (human, bunny), labelled as such "
                    "in every output. Runs are cached in the results store: rerunning only redoes what is missing. "
                    "The tables' columns: the paper's four (Meshlab, Lozes, Hu, Proposed) in the paper configuration, "
                    "then ours (tuned temporal-graph, temporal-fusion) and the temporal-copy reference "
                    "(bench/reporting/paper.py TABLE_COLUMNS). --quick: human and bunny at size tiny (10-30k points a frame), "
                    "3 frames each, three seeds (9 pairs a cell: the fewest at which a claim over 8 columns can pass "
                    "Holm at 0.05), plus 3 frames with acquisition holes for the real-hole figure (target: "
                    "under 10 minutes on 2 cores; MeshLab dominates). The full preset (two stand-ins of 570-640k "
                    "points, 10 frames, 3 seeds: 96 runs) took 51 min on 2 cores, 1.26 CPU-h (measured; "
                    "bench/presets/paper.toml), plus the real-captured-motion rows (D-FAUST punching, samba) when their "
                    "data is found (the D-FAUST rows about double the quick preset's CPU time).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--data-dir", default=None, help="folder holding local copies of the paper's sequences")
    p.add_argument("--quick", action="store_true", help="the small preset (paper-quick.toml)")
    p.add_argument("--size", choices=("tiny", "small", "default"), default=None,
                   help="override the stand-ins' size preset (e.g. tiny for a smoke test)")
    p.add_argument("--frames", type=int, default=None, help="override the number of frames per sequence")
    p.add_argument("--seeds", default=None, metavar="LIST",
                   help="hole seeds of the synthetic-hole runs, e.g. 0,1,2 or 0-2 (default: the preset's)")
    p.add_argument("--out", default="dpcbench-paper", help="folder for tables, figures and REPORT.md")
    p.add_argument("--overwrite", action="store_true",
                   help="replace existing files in the output folder that dpcbench did not write")
    p.add_argument("--store", default=None,
                   help="results store; default $DPCBENCH_STORE or ~/.cache/dpcbench/results.sqlite")
    p.add_argument("--executor", choices=("serial", "pool", "dask"), default="pool")
    p.add_argument("--scheduler", default=None, metavar="ADDR", help="Dask scheduler address (implies dask)")
    p.add_argument("--jobs", type=int, default=None, help="parallel runs; None = all cores")
    p.add_argument("--force", action="store_true", help="redo every run")
    p.add_argument("--retry-failed", action="store_true", help="redo runs that failed before")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--no-run", action="store_true",
                   help="run nothing: tabulate the protocol's runs the store already holds (e.g. a sweep stopped "
                        "part-way); missing cells print as '-' and REPORT.md counts the missing runs")
    add_pin_option(p)
    p.set_defaults(func=main)


def _parse_seeds(text: str | None) -> list[int] | None:
    """"0,1,2" or "0-2" (or a mix, "0-2,5") -> [0, 1, 2]; None -> None."""
    if text is None:
        return None
    seeds = []
    try:
        for part in text.split(","):
            lo, sep, hi = part.strip().partition("-")
            seeds += list(range(int(lo), int(hi) + 1)) if sep else [int(lo)]
    except ValueError:
        raise UserError(f"--seeds {text!r}: give integers, e.g. --seeds 0,1,2 or --seeds 0-2") from None
    if not seeds:
        raise UserError(f"--seeds {text!r}: no seed given; e.g. --seeds 0-2")
    return seeds


def main(args) -> int:
    from dpcbench.bench.data.outputs import Outputs
    from dpcbench.bench.execution.runner import run_experiment
    from dpcbench.bench.reporting import paper
    from dpcbench.bench.results.store import ResultsStore

    t0 = time.perf_counter()
    if args.jobs is not None and args.jobs < 1:
        raise UserError("--jobs: must be at least 1")
    quiet = args.quiet or os.environ.get("DPCBENCH_QUIET", "") not in ("", "0")
    protocol = paper.paper_protocol(quick=args.quick, data_dir=args.data_dir, size=args.size, frames=args.frames,
                                    seeds=_parse_seeds(args.seeds))
    guard = Outputs(args.overwrite)
    out = guard.folder(args.out, "--out")
    store = ResultsStore(args.store, verify=True)
    specs = protocol.synthetic + protocol.real
    if not quiet:
        where = "embedded STAND-INS (not the paper's data)" if protocol.standins else "the paper's sequences"
        print(f"reproduce-paper ({protocol.preset}): {len(protocol.synthetic)} synthetic-hole runs and "
              f"{len(protocol.real)} real-hole runs on {where}; store {store.path}", file=sys.stderr)
    if args.no_run:
        from dpcbench.bench.execution.runner import RunSummary

        summary = RunSummary()
    else:
        pin = args.pin_isa or bool(protocol.config["experiment"].get("pin_isa", False))
        with pinned_workers(pin, f"reproduce-paper ({protocol.preset})"):
            summary = run_experiment(specs, store, executor=args.executor, jobs=args.jobs, scheduler=args.scheduler,
                                     force=args.force, retry_failed=args.retry_failed, quiet=quiet)
    results = store.results_frame()
    runs = store.runs_frame()
    synthetic_ids = {s.run_id for s in protocol.synthetic}
    real_ids = {s.run_id for s in protocol.real}
    df = results[results["run_id"].isin(synthetic_ids)].drop_duplicates(["run_id", "frame", "metric", "scope", "peak"])
    real_df = results[results["run_id"].isin(real_ids)].drop_duplicates(["run_id", "frame", "metric", "scope", "peak"])
    run_rows = runs[runs["run_id"].isin(synthetic_ids | real_ids)].drop_duplicates("run_id")
    if df.empty:
        raise UserError("no synthetic-hole run finished, so there is nothing to tabulate; see the failed runs above "
                        f"and their logs in {Path(store.path).parent / 'runs' / 'logs'}")
    missing = len((synthetic_ids | real_ids) - set(results["run_id"]))
    with guard.staged(out) as staged:  # written aside, moved in once no file of the user's would be replaced
        _write_outputs(args, protocol, store, staged, df, run_rows, real_df, t0, computed=set(summary.done),
                       missing=missing)
    print(f"{len(summary.done)} run(s) done, {len(summary.cached)} cached, {len(summary.failed)} failed"
          + (f", {missing} of the protocol's {len(specs)} not in the store (--no-run)" if args.no_run else ""))
    print((out / "tables" / "table1_gpsnr.md").read_text())
    print((out / "tables" / "table2_nshd.md").read_text())
    print(f"report: {out / 'REPORT.md'}")
    return 1 if summary.failed else 0


def _write_outputs(args, protocol, store, out: Path, df, run_rows, real_df, t0, computed=None, missing: int = 0) -> None:
    from dpcbench.bench.reporting import paper
    from dpcbench.bench.reporting.reports import write_paper_report

    figure_notes = paper.paper_figures(protocol, store, out / "figures")
    command = "dpcbench reproduce-paper" + "".join(
        f" {flag}" + ("" if value is True else f" {shlex.quote(str(value))}")
        for flag, value in [("--quick", args.quick), ("--data-dir", args.data_dir), ("--size", args.size),
                            ("--frames", args.frames), ("--seeds", args.seeds), ("--out", args.out),
                            ("--no-run", args.no_run), ("--pin-isa", args.pin_isa)] if value)
    from dpcbench.bench.reporting.paper_ablation import ablation_frame, ablation_markdown

    # the ablation of the paper configuration (`dpcbench run paper-ablation`), where this store holds it
    ablation = store.results_frame("paper-ablation")
    table = ablation_frame(ablation) if len(ablation) else None
    ablation_md = ablation_markdown(table) if table is not None else ""
    write_paper_report(df, run_rows, out, standins=protocol.standins, preset=protocol.preset,
                       command=command, elapsed_s=time.perf_counter() - t0, figure_notes=figure_notes,
                       real_df=real_df, store_path=store.path, computed=computed, ablation_md=ablation_md,
                       ablation=table, missing=missing)
