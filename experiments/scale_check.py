"""Whether a method's output depends on the unit of length: the same damage in other units, each output moved back.

A capture in metres is the same capture as in millimetres, so a method whose rules are stated in point spacings
must give the same output scaled. This runs each method on a `dpcbench damage` folder as it is and with every
coordinate (points and hole regions) multiplied by each ``--scale`` (default 2^-10 and 2^10: powers of two, so
the scaled input is exact in floating point and any difference is the method's, not the rescaling's rounding),
moves each output back, and prints per frame:
- ``identical`` when the output is bit-identical, else the largest distance from an output point to the nearest
  point of the unscaled output (both ways) and how many points lie more than 0.01 spacings from it, in spacings;
- with ``--truth``, whole-frame D1 / D2 of each (pc_error's conventions, as `experiments/fill_audit.py` scores).

A few points may move at a scale where none of the method's rules depends on the unit: a decision at a threshold
(a hold-out bound, a plane test) can flip on the last bits of a LAPACK routine, which are not exactly scaled
(`experiments/perturbation_noise.py` measures such decision noise). A unit dependence shows as more points, and
as a score that moves with the scale.

Usage (on float data: voxelized frames are integers, and a scaled copy is no longer voxelized):

    .venv/bin/python experiments/scale_check.py DAMAGED METHOD [METHOD ...] [--frames 2] [--truth TRUTH]
        [--scale 0.0009765625 --scale 1024]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from fill_audit import frame_psnr, truth_frames_or_exit
from scipy.spatial import cKDTree

from dpcbench.bench.data.plyio import read_ply
from dpcbench.methods.registry import get_method
from dpcbench.metrics import resolve_peak
from dpcbench.metrics.neighbours import point_spacing
from dpcbench.metrics.pairs import CloudPair

#: a point farther than this many spacings from the unscaled output counts as moved
MOVED_SPACINGS = 0.01


def deviation(reference: np.ndarray, other: np.ndarray, spacing: float) -> str:
    """``identical``, or the largest two-way nearest-point distance and the moved points' count, in spacings."""
    if reference.shape == other.shape and np.array_equal(reference, other):
        return "identical"
    if not len(reference) or not len(other):
        return f"{len(reference)} vs {len(other)} points"
    there = cKDTree(reference).query(other)[0] / spacing
    back = cKDTree(other).query(reference)[0] / spacing
    return (f"{len(reference)} vs {len(other)} points, max {max(there.max(), back.max()):.3g} s, "
            f"{int((there > MOVED_SPACINGS).sum())} moved > {MOVED_SPACINGS} s")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("methods", nargs="+", help="registered method names")
    parser.add_argument("--frames", type=int, default=2, help="the first N frames (default 2)")
    parser.add_argument("--truth", type=Path, help="the undamaged frames, to score each output")
    parser.add_argument("--scale", type=float, action="append", help="a factor (repeatable; default 2^-10, 2^10)")
    args = parser.parse_args(argv)
    _, frames, regions = load_damage_or_exit(args.damaged)
    truth_files = truth_frames_or_exit(args.truth, args.damaged, len(frames)) if args.truth else None
    frames, regions = frames[:args.frames], regions[:args.frames]
    spacing = point_spacing(max(frames, key=len))
    truths = None if truth_files is None else [np.asarray(read_ply(p).points, dtype=np.float64)
                                               for p in truth_files[:len(frames)]]
    for name in args.methods:
        runs = {}
        for scale in [1.0] + (args.scale or [2.0 ** -10, 2.0 ** 10]):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the methods' own notices (one frame, no source), the same each run
                outputs = get_method(name).inpaint([f * scale for f in frames],
                                                   [[r.scaled(scale) for r in rr] for rr in regions])
            runs[scale] = [np.asarray(out, dtype=np.float64) / scale for out in outputs]
        for scale, outputs in runs.items():
            cells = []
            for f, out in enumerate(outputs):
                cell = "as given" if scale == 1.0 else deviation(runs[1.0][f], out, spacing)
                if truths is not None:
                    pair = CloudPair(truths[f], out)
                    d1, d2 = frame_psnr(pair, resolve_peak("intrinsic", pair))
                    cell += f", D1 {d1:.2f} D2 {d2:.2f}"
                cells.append(f"frame {f}: {cell}")
            print(f"{name} x {scale:g}: " + "; ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
