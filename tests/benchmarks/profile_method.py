"""Where a method's time goes: cProfile of one method on the benchmark data (not a test).

    .venv/bin/python tests/benchmarks/profile_method.py temporal-graph --size 800k
    .venv/bin/python tests/benchmarks/profile_method.py fu-nonlocal --size 100k --top 30

Runs the method once on the 3 frames of the benchmark suite's data at that size (`conftest.py`:
embedded human, 5 medium coherent region holes a frame, seed 0) under cProfile and prints the wall
time, then the functions of this project (methods/, holes/, metrics/) by cumulative time.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

# run as a script: the benchmarks' conftest is importable only once its folder is on sys.path (line above)
from conftest import SIZES, bench_sequence, damage  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("method", help="registered method name, e.g. temporal-graph")
    parser.add_argument("--size", default="800k", choices=sorted(SIZES))
    parser.add_argument("--top", type=int, default=25, help="rows of the profile to print")
    args = parser.parse_args()

    from dpcbench.methods.registry import get_method

    damaged = damage(bench_sequence(args.size).points)
    method = get_method(args.method)
    profile = cProfile.Profile()
    start = time.perf_counter()
    profile.enable()
    method.inpaint(damaged.frames, damaged.regions)
    profile.disable()
    seconds = time.perf_counter() - start
    points = ", ".join(f"{len(f):,}" for f in damaged.frames)
    print(f"{args.method}: {seconds:.2f} s under cProfile for 3 frames of {points} points")
    stats = pstats.Stats(profile).sort_stats("cumulative")
    stats.print_stats(r"(methods|holes|metrics)/", args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
