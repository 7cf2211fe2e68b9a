"""The same runs in two results stores, score by score: which runs came out the same and how far the others moved.

A run id names what a run computes (data, damage, method and version, metrics), not where: two stores can hold the same
id computed on two machines, or pinned to one instruction set and not (`bench/core/isa.py`, ``pin_isa``). For every
run id finished in both stores, each whole-frame score (D1, D2 with the intrinsic peak, NSHD) of every frame is
compared; per method it prints the runs compared, how many have every score identical (to 1e-9 relative), and over the
others the largest change of a frame's D1 and of a run's mean D1 (over its frames), in dB.

    .venv/bin/python experiments/run_diff.py A.sqlite B.sqlite [--methods fu-nonlocal,temporal-graph]
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import defaultdict
from pathlib import Path

METRICS = ("gpsnr_d1", "gpsnr_d2", "nshd")


def scores(path: Path) -> dict[str, tuple[str, dict[tuple[str, int], float | None]]]:
    """run id -> (method, {(metric, frame): value, None where not finite}) of the finished runs of the store at
    ``path``, opened read-only (`ResultsStore.results_frame`; a run in several experiments counted once)."""
    from dpcbench.bench.results.store import ResultsStore

    if not path.is_file():
        sys.exit(f"{path}: no such results store; give two SQLite stores written by dpcbench run")
    table = ResultsStore(path, readonly=True).results_frame()
    table = table[(table["scope"] == "frame") & (table["frame"] >= 0) & table["metric"].isin(METRICS)
                  & table["peak"].fillna("").isin(["", "intrinsic"])]
    out: dict[str, tuple[str, dict[tuple[str, int], float | None]]] = {}
    for run_id, method, metric, frame, value in table[["run_id", "method", "metric", "frame", "value"]].itertuples(
            index=False):
        out.setdefault(run_id, (method, {}))[1][(metric, int(frame))] = value if math.isfinite(value) else None
    return out


def same(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return a is b
    return a == b or abs(a - b) <= 1e-9 * max(1.0, abs(b))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    parser.add_argument("--methods", help="comma-separated method names (default: every method with a run in both)")
    args = parser.parse_args()
    first, second = scores(args.first), scores(args.second)
    wanted = set(args.methods.split(",")) if args.methods else None
    by_method: dict[str, list[tuple[bool, float, float]]] = defaultdict(list)
    for run_id in sorted(first.keys() & second.keys()):
        method, a = first[run_id]
        if wanted is not None and method not in wanted:
            continue
        b = second[run_id][1]
        keys = a.keys() & b.keys()
        identical = all(same(a[k], b[k]) for k in keys)
        d1 = [(a[k], b[k]) for k in keys if k[0] == "gpsnr_d1" and a[k] is not None and b[k] is not None]
        frame_change = max((abs(y - x) for x, y in d1), default=0.0)
        mean_change = abs(sum(y - x for x, y in d1) / len(d1)) if d1 else 0.0
        by_method[method].append((identical, frame_change, mean_change))
    if not by_method:
        print("no finished run id is in both stores")
        return 1
    print(f"{'method':16s} {'runs':>5s} {'identical':>9s} {'differ':>6s}  {'max |dD1| frame':>15s}  "
          f"{'max |dD1| run mean':>18s}")
    for method, runs in sorted(by_method.items()):
        differ = [r for r in runs if not r[0]]
        print(f"{method:16s} {len(runs):5d} {len(runs) - len(differ):9d} {len(differ):6d}  "
              f"{max((r[1] for r in differ), default=0.0):15.2f}  {max((r[2] for r in differ), default=0.0):18.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
