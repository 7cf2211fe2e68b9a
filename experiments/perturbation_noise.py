"""How far a method's scores move when its input is moved by an amount no capture could tell apart: its decision
noise, the floor below which a paired difference between two versions says nothing about either.

Runs the method on a `dpcbench damage` folder as it is, then on the same frames and hole regions translated by
``--shift`` spacings along each axis in turn (a rigid move: every distance, every point spacing and the truth move
with it, so a method whose rules are in spacings should score the same), moves each output back and scores every
frame against the truth (whole-frame D1 / D2, pc_error's conventions: `metrics.pairs.CloudPair`, the truth's PLY
normals or estimated ones as `dpcbench score` does). Per perturbation it prints the new points added and the
paired difference (moved - as is) over the frames, mean with its 95 % bootstrap interval
(`bench.results.stats.paired`), and "beyond noise" where the interval excludes 0: a change that this moves beyond
noise is in the method's decisions, not in its data.

    .venv/bin/python experiments/perturbation_noise.py TRUTH DAMAGED [--method temporal-fusion]
        [--shift 0.001] [--param name=value ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from fill_audit import frame_psnr, truth_frames_or_exit

from dpcbench.bench.core.params import parse_params
from dpcbench.bench.data.plyio import read_ply
from dpcbench.bench.results.stats import paired
from dpcbench.methods.registry import get_method
from dpcbench.metrics import resolve_peak
from dpcbench.metrics.neighbours import point_spacing
from dpcbench.metrics.pairs import CloudPair


def scores(outputs: list[np.ndarray], truths: list[tuple[np.ndarray, np.ndarray | None]]) -> dict:
    """{"D1": {frame: dB}, "D2": {frame: dB}} of ``outputs`` against ``truths`` ((points, normals or None) a frame)."""
    out: dict = {"D1": {}, "D2": {}}
    for f, (result, (truth, normals)) in enumerate(zip(outputs, truths)):
        pair = CloudPair(truth, result, normals)
        out["D1"][f], out["D2"][f] = frame_psnr(pair, resolve_peak("intrinsic", pair))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the undamaged frames: a PLY file or a folder of PLY frames")
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--method", default="temporal-fusion")
    parser.add_argument("--shift", type=float, default=0.001, help="the translation, in point spacings (0.001)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE", help="a method parameter")
    args = parser.parse_args(argv)
    _, frames, regions = load_damage_or_exit(args.damaged)
    truths = []
    for path in truth_frames_or_exit(args.truth, args.damaged, len(frames)):
        cloud = read_ply(path)
        truths.append((np.asarray(cloud.points, dtype=np.float64), cloud.normals))
    spacing = point_spacing(max(frames, key=len))
    params = parse_params(args.param)

    def run(offset: np.ndarray) -> tuple[list[np.ndarray], dict]:
        moved = [f + offset for f in frames]
        moved_regions = [[dataclasses.replace(r, center=r.center + offset) for r in rs] for rs in regions]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outputs = get_method(args.method, **params).inpaint(moved, moved_regions)
        back = [o - offset for o in outputs]
        return back, scores(back, truths)

    base, base_scores = run(np.zeros(3))
    added = [len(o) - len(f) for o, f in zip(base, frames)]
    print(f"{args.method} on {args.damaged} ({len(frames)} frames, spacing {spacing:.4g}): as is, {sum(added)} points "
          f"added; D1 {np.mean(list(base_scores['D1'].values())):.2f}, D2 {np.mean(list(base_scores['D2'].values())):.2f}")
    for axis in range(3):
        offset = np.zeros(3)
        offset[axis] = args.shift * spacing
        outputs, moved_scores = run(offset)
        new = sum(len(o) - len(f) for o, f in zip(outputs, frames))
        same = all(len(a) == len(b) and np.allclose(a, b, rtol=0, atol=1e-6 * spacing) for a, b in zip(outputs, base))
        parts = []
        for metric in ("D1", "D2"):
            c = paired(moved_scores[metric], base_scores[metric])
            if c.n < 2:
                parts.append(f"{metric} {c.mean_difference:+.3f} (one frame: no interval)")
                continue
            verdict = "beyond noise" if c.low > 0 or c.high < 0 else "within noise"
            parts.append(f"{metric} {c.mean_difference:+.3f} [{c.low:+.3f}, {c.high:+.3f}] {verdict}")
        print(f"  moved {args.shift:g} s along {'xyz'[axis]}: {new} points added, "
              f"{'the same output' if same else 'a different output'}; moved - as is, n {len(frames)}: "
              + "; ".join(parts))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
