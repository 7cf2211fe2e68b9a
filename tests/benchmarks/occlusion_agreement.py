"""Occlusion generator: the z-buffer visibility (version 2's default) against open3d's hidden point
removal (version 1), on the stand-ins: agreement of the removed (occluded) sets and the time of each.

    python tests/benchmarks/occlusion_agreement.py --size small --frames 2
    python tests/benchmarks/occlusion_agreement.py --ply /work/shared/data/8i_longdress_1300/*.ply
    python tests/benchmarks/occlusion_agreement.py --size 1m --frames 1 --rigs stage --skip-hpr --repeats 3

Prints, per frame and rig: points, removed by each operator, IoU = |A & B| / |A | B| of the removed
sets, the share of each set the other also removes, and the CPU time (user + sys of this process,
all threads) and wall time of ``damage`` (min of ``--repeats`` each; a warm-up call first, so imports
are not counted). Both operators share every other step (normals, grazing test, ``seen_within``).
``--size 1m``: the benchmark suite's 1,009,042-point human (tests/benchmarks/conftest.py SIZES["1m"]).
Which operator is *right* is measured by occlusion_truth.py (ray casting on meshes).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


#: the benchmark suite's 1M frame (tests/benchmarks/conftest.py SIZES["1m"])
ONE_MILLION = {"bit_depth": 11, "height": 1165}


def removed_mask(gen, frame) -> tuple[np.ndarray, float, float]:
    """(removed (N,), CPU seconds, wall seconds) of ``gen.damage`` on one frame."""
    c0, t0 = time.process_time(), time.perf_counter()
    result = gen.damage([frame], seed=0)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    return np.asarray(result.removed[0], dtype=bool), cpu, wall


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sequences", default="human,bunny")
    parser.add_argument("--size", default="small", help="stand-in size (tiny, small, default) or 1m")
    parser.add_argument("--frames", type=int, default=2)
    parser.add_argument("--ply", nargs="*", default=None, help="PLY frames to use instead of the stand-ins")
    parser.add_argument("--rigs", default="stage,sphere8")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--skip-hpr", action="store_true", help="time the z-buffer only")
    args = parser.parse_args(argv)
    from dpcbench.holes.occlusion import OcclusionHoles

    frames: list[tuple[str, np.ndarray]] = []
    if args.ply:
        from dpcbench.bench.data.plyio import read_ply

        for path in args.ply:
            frames.append((Path(path).stem, np.asarray(read_ply(path, colors=False).points, dtype=np.float64)))
    else:
        from dpcbench.bench.data.datasets import load_dataset

        for name in args.sequences.split(","):
            sizing = dict(ONE_MILLION) if args.size == "1m" else {"size": args.size}
            seq = load_dataset(name, frames=args.frames, progress=False, **sizing)
            frames += [(f"{name}[{i}]", f) for i, f in enumerate(seq.points)]
    rigs = {"stage": {"rig": "stage"}, "sphere8": {"rig": "sphere", "count": 8}}
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; min of {args.repeats} run(s)")
    print(f"{'frame':16s} {'rig':8s} {'points':>8s} {'hpr rm':>7s} {'zbuf rm':>7s} {'IoU':>6s} "
          f"{'zb&h/h':>7s} {'zb&h/zb':>7s} {'hpr cpu':>7s} {'zb cpu':>7s} {'hpr s':>7s} {'zbuf s':>7s}")
    OcclusionHoles(rig="sphere", count=4).damage([np.random.default_rng(0).normal(size=(500, 3))], 0)  # warm-up
    for label, frame in frames:
        for rig in args.rigs.split(","):
            params = {**rigs[rig], "max_fraction": 0.9}
            zb_times, hpr_times = [], []
            for _ in range(args.repeats):
                zb, *t = removed_mask(OcclusionHoles(visibility="zbuffer", **params), frame)
                zb_times.append(t)
            zb_cpu, zb_wall = (min(t[i] for t in zb_times) for i in (0, 1))
            if args.skip_hpr:
                print(f"{label:16s} {rig:8s} {len(frame):8d} {'':>7s} {zb.sum():7d} {'':>6s} {'':>7s} {'':>7s} "
                      f"{'':>7s} {zb_cpu:7.2f} {'':>7s} {zb_wall:7.2f}", flush=True)
                continue
            for _ in range(args.repeats):
                hpr, *t = removed_mask(OcclusionHoles(visibility="hpr", **params), frame)
                hpr_times.append(t)
            hpr_cpu, hpr_wall = (min(t[i] for t in hpr_times) for i in (0, 1))
            both = (zb & hpr).sum()
            union = (zb | hpr).sum()
            iou = both / union if union else 1.0
            print(f"{label:16s} {rig:8s} {len(frame):8d} {hpr.sum():7d} {zb.sum():7d} {iou:6.3f} "
                  f"{both / max(hpr.sum(), 1):7.3f} {both / max(zb.sum(), 1):7.3f} {hpr_cpu:7.2f} {zb_cpu:7.2f} "
                  f"{hpr_wall:7.2f} {zb_wall:7.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
