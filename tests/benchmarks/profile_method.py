"""Where a method's time goes: cProfile of one method on the benchmark data (not a test).

    .venv/bin/python tests/benchmarks/profile_method.py temporal-graph --size 800k
    .venv/bin/python tests/benchmarks/profile_method.py fu-nonlocal --size 100k --top 30
    .venv/bin/python tests/benchmarks/profile_method.py temporal-fusion --case longdress-occlusion \
        --param poisson_in_boxes=false --sort tottime

Without ``--case``: runs the method once on the 3 frames of the benchmark suite's data at that size
(`conftest.py`: embedded human, 5 medium coherent region holes a frame, seed 0). With ``--case``: on one of
temporal-fusion's paper-scale benchmark inputs (`fusion_cases.py`: coherent-800k, longdress-region,
longdress-occlusion). Prints the wall and process CPU time, then the functions of this project (methods/,
holes/, metrics/) by cumulative time, or with ``--sort tottime`` every function (open3d's and numpy's included)
by its own time.
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
from fusion_cases import CASES  # noqa: E402


def _param(text: str) -> tuple[str, object]:
    """``key=value`` with the value read as a bool, int, float or string."""
    key, _, value = text.partition("=")
    lowered = value.lower()
    if lowered in ("true", "false"):
        return key, lowered == "true"
    for kind in (int, float):
        try:
            return key, kind(value)
        except ValueError:
            pass
    return key, value


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("method", help="registered method name, e.g. temporal-graph")
    parser.add_argument("--size", default="800k", choices=sorted(SIZES))
    parser.add_argument("--case", choices=sorted(CASES), help="a temporal-fusion benchmark input instead of --size")
    parser.add_argument("--param", action="append", default=[], type=_param, help="method parameter key=value")
    parser.add_argument("--top", type=int, default=25, help="rows of the profile to print")
    parser.add_argument("--sort", default="cumulative", choices=["cumulative", "tottime"])
    args = parser.parse_args()

    from dpcbench.methods.registry import get_method

    if args.case:
        _, frames, regions = CASES[args.case]()
    else:
        damaged = damage(bench_sequence(args.size).points)
        frames, regions = damaged.frames, damaged.regions
    method = get_method(args.method, **dict(args.param))
    profile = cProfile.Profile()
    start, cpu = time.perf_counter(), time.process_time()
    profile.enable()
    method.inpaint(frames, regions)
    profile.disable()
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    points = ", ".join(f"{len(f):,}" for f in frames)
    print(f"{args.method}: {seconds:.2f} s wall, {cpu:.2f} s CPU under cProfile for {len(frames)} frames of "
          f"{points} points")
    stats = pstats.Stats(profile).sort_stats(args.sort)
    if args.sort == "tottime":
        stats.print_stats(args.top)
    else:
        stats.print_stats(r"(methods|holes|metrics)/", args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
