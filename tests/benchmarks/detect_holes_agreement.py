"""``detect_holes`` before/after a change: the same boundary mask and regions, and the time of each.

    python tests/benchmarks/detect_holes_agreement.py                      # the 1M human stand-in
    python tests/benchmarks/detect_holes_agreement.py --standins human:small,bunny:small --repeats 1
    python tests/benchmarks/detect_holes_agreement.py --ply /work/shared/data/8i_longdress_1300/*.ply

"Before" is ``holes/detection.py`` as of the git revision ``--before`` (default 7b20ac4, the version
before the leaf-order neighbour query), loaded from ``git show`` as a module next to the current
one; both use the current ``holes.geometry`` / ``metrics.neighbours``. Frames: the stand-ins named by
``--standins`` (name:size, or name:1m for the benchmark suite's 1,009,042-point embedded human) with
"region" holes (preset medium, seed 0) punched into frame 0, and/or the PLY files of ``--ply`` as
they are (captured frames, their own holes).

Prints, per frame: points, boundary points of each version and whether the masks are identical
(``boundary_points(..., interior_values=False)``), the regions of each and whether they are identical
(centre, radius, rim_points, inward compared exactly), and the wall time of ``detect_holes`` per
version (min of ``--repeats``, after one untimed warm-up call that pays open3d's import) and its
process CPU time (all threads; less sensitive than wall time to other jobs on a shared machine).
Exit status 1 when any frame differs.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: the benchmark suite's 1M frame (tests/benchmarks/conftest.py SIZES["1m"])
ONE_MILLION = {"bit_depth": 11, "height": 1165}


def load_before(revision: str):
    """holes/detection.py at ``revision`` as a module named ``detection_before``."""
    source = subprocess.run(["git", "-C", str(REPO), "show", f"{revision}:holes/detection.py"],
                            check=True, capture_output=True, text=True).stdout
    spec = importlib.util.spec_from_loader("detection_before", loader=None)
    module = importlib.util.module_from_spec(spec)
    exec(compile(source, f"{revision}:holes/detection.py", "exec"), module.__dict__)
    return module


def frames(standins: list[str], plys: list[str]):
    """(label, (N, 3) frame) for each requested stand-in and PLY file."""
    for item in standins:
        from dpcbench.bench.data.datasets import load_dataset
        from dpcbench.holes.registry import get_generator

        name, _, size = item.partition(":")
        kwargs = dict(ONE_MILLION) if size == "1m" else {"size": size or "small"}
        seq = load_dataset(name, frames=1, seed=0, progress=False, **kwargs).points
        damaged = get_generator("region", preset="medium").damage([seq[0]], 0).frames[0]
        yield f"{name}:{size} + medium holes", damaged
    for path in plys:
        from dpcbench.bench.data.plyio import read_ply

        yield os.path.basename(path), np.asarray(read_ply(path).points, dtype=np.float64)


def timed(fn, frame, repeats: int):
    """(least wall seconds, least process CPU seconds (all threads), result) over ``repeats`` calls."""
    wall, cpu, out = float("inf"), float("inf"), None
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        out = fn(frame)
        wall, cpu = min(wall, time.perf_counter() - start), min(cpu, time.process_time() - start_cpu)
    return wall, cpu, out


def same_regions(a, b) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.center, y.center) and x.radius == y.radius and x.extra == y.extra for x, y in zip(a, b))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--standins", default="human:1m", help="comma-separated name:size ('' for none)")
    parser.add_argument("--ply", nargs="*", default=[], help="PLY frames to compare as well")
    parser.add_argument("--before", default="7b20ac4", help="git revision of the 'before' holes/detection.py")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)

    from dpcbench.holes import detection as after

    before = load_before(args.before)
    warm = np.random.default_rng(0).normal(size=(2000, 3))
    after.detect_holes(warm)  # pays open3d's import outside the timings
    differs = False
    print(f"load average {os.getloadavg()[0]:.2f} at start (2-core machine: times are min of {args.repeats})")
    standins = [s for s in args.standins.split(",") if s]
    for label, frame in frames(standins, args.ply):
        masks = [mod.boundary_points(frame, interior_values=False)[0] for mod in (before, after)]
        t_before, cpu_before, r_before = timed(before.detect_holes, frame, args.repeats)
        t_after, cpu_after, r_after = timed(after.detect_holes, frame, args.repeats)
        same_mask, same = bool(np.array_equal(*masks)), same_regions(r_before, r_after)
        differs |= not (same_mask and same)
        print(f"{label}: {len(frame):,} points | boundary points {masks[0].sum():,} / {masks[1].sum():,} "
              f"identical={same_mask} | regions {len(r_before)} / {len(r_after)} identical={same} | "
              f"detect_holes wall {t_before:.2f} s -> {t_after:.2f} s (x{t_before / t_after:.2f}), "
              f"CPU {cpu_before:.2f} s -> {cpu_after:.2f} s")
    print(f"load average {os.getloadavg()[0]:.2f} at end")
    return 1 if differs else 0


if __name__ == "__main__":
    sys.exit(main())
