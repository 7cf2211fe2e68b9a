"""Every registered method on small, degenerate and unusual sequences: whether it fills, refuses with a one-line
error, or fails otherwise (a traceback is a defect), and with ``--score`` how well.

    .venv/bin/python experiments/edge_inputs.py [METHOD ...]          # default: every registered method
    .venv/bin/python experiments/edge_inputs.py --score [METHOD ...]  # and D1 / D2 against the truth

Cases (bumpy spheres of `dpcbench.testing`, radius 50, unvoxelized unless said): a region far from every point; a
region that swallows most of the object; 40- and 200-point frames; a voxelized plane; 500 duplicated points; every
coordinate offset by 1e6; two frames of ~20k points rounded to integers (spacing ~2.5: no voxelization); three frames
of which one has a third of the points and no hole; a box region; one frame; points on a line. Prints one line per
(method, case): the points added per frame and the CPU seconds, or the error's type and first line. With
``--score``, also the whole-frame D1 / D2 (dB, intrinsic peak, `metrics.score_frame`) of the output against the
frames before damage, averaged over the frames, and those of the damaged input (no fill): a case's quality, not
a benchmark (tiny synthetic damages, one seed).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.registry import available_methods, get_method
from dpcbench.testing import bumpy_sphere


def _ball(center, radius) -> HoleRegion:
    return HoleRegion(shape="ball", center=np.asarray(center, dtype=float), radius=float(radius))


def _damaged(frames, regions):
    """The frames without the points inside their regions, the regions, and the frames (the truth)."""
    out = [f[~np.any([r.contains(f) for r in rs], axis=0)] if rs else f for f, rs in zip(frames, regions)]
    return out, regions, frames


def _spheres(points: int, count: int, offset: float = 0.0, scale: float = 1.0, voxelized: bool = False):
    frames = [bumpy_sphere(points, i) * scale + offset for i in range(count)]
    return [np.unique(np.floor(f + 0.5), axis=0) for f in frames] if voxelized else frames


def cases() -> dict:
    out = {}
    fs = _spheres(2000, 3)
    out["region far from every point"] = (fs, [[_ball([500, 500, 500], 5)]] * 3, fs)
    out["region swallowing most"] = _damaged(_spheres(2000, 3), [[_ball([0, 0, 52], 60)]] * 3)
    for n in (40, 200):
        fs = _spheres(n, 3)
        out[f"{n}-point frames"] = _damaged(fs, [[_ball(f[0], 15)] for f in fs])
    grid = np.stack(np.meshgrid(np.arange(60.0), np.arange(60.0), indexing="ij"), -1).reshape(-1, 2)
    plane = np.c_[grid, np.zeros(len(grid))]
    out["voxelized plane"] = _damaged([plane, plane.copy()], [[_ball([30, 30, 0], 8)]] * 2)
    fs = [np.vstack([f, f[:500]]) for f in _spheres(2000, 2)]
    out["500 duplicated points"] = _damaged(fs, [[_ball(f[3], 12)] for f in fs])
    fs = _spheres(2000, 2, offset=1e6)
    out["offset 1e6"] = _damaged(fs, [[_ball(f[3], 12)] for f in fs])
    fs = _spheres(20000, 2, scale=2.0, voxelized=True)
    out["sparse integer, 2 frames"] = _damaged(fs, [[_ball(f[5], 10), _ball(f[900], 10)] for f in fs])
    fs = _spheres(3000, 3)
    fs[1] = fs[1][::3]
    out["uneven density"] = _damaged(fs, [[_ball(fs[0][3], 12)], [], [_ball(fs[2][3], 12)]])
    fs = _spheres(3000, 2)
    box = HoleRegion(shape="box", center=fs[0][7], half_extents=np.array([10.0, 5.0, 3.0]), rotation=np.eye(3))
    out["box region"] = _damaged(fs, [[box]] * 2)
    fs = _spheres(3000, 1)
    out["one frame"] = _damaged(fs, [[_ball(fs[0][7], 12)]])
    line = np.c_[np.arange(200.0), np.zeros(200), np.zeros(200)]
    out["points on a line"] = _damaged([line, line.copy()], [[_ball([100, 0, 0], 5)]] * 2)
    return out


def _quality(truth, output, damaged) -> str:
    """'D1 / D2 x / y (no fill x0 / y0)': whole-frame means over the frames, or why they could not be scored."""
    from dpcbench.metrics import score_frame

    try:
        means = []
        for frames in (output, damaged):
            values = [score_frame(t, f, ["gpsnr_d1", "gpsnr_d2"]) for t, f in zip(truth, frames)]
            means.append([float(np.mean([v[m] for v in values])) for m in ("gpsnr_d1", "gpsnr_d2")])
    except Exception as error:  # noqa: BLE001  (a degenerate case that no metric scores: said, not fatal)
        return f"not scored ({type(error).__name__}: {str(error).splitlines()[0][:80]})"
    (d1, d2), (n1, n2) = means
    return f"D1 / D2 {d1:.2f} / {d2:.2f} (no fill {n1:.2f} / {n2:.2f})"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("methods", nargs="*", help="registered names (default: all)")
    parser.add_argument("--score", action="store_true", help="also D1 / D2 against the truth, and no fill's")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    inputs = cases()
    for name in args.methods or list(available_methods()):
        for case, (frames, regions, truth) in inputs.items():
            start = time.process_time()
            try:
                out = get_method(name).inpaint([f.copy() for f in frames], regions)
                added = [len(o) - len(f) for o, f in zip(out, frames)]
                seconds = time.process_time() - start
                quality = f"; {_quality(truth, out, frames)}" if args.score else ""
                print(f"{name:16s} {case:28s} added {added}, {seconds:.1f} s CPU{quality}", flush=True)
            except Exception as error:  # noqa: BLE001  (every failure is reported, by its type)
                first = f"{type(error).__name__}: {error}".splitlines()[0][:150]
                print(f"{name:16s} {case:28s} {first}", flush=True)


if __name__ == "__main__":
    main()
