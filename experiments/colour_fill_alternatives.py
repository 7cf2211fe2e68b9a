"""Hole-region colour PSNR (BT.709 Y) of one-frame colour fills other than the methods' harmonic fill, on
the truth's own positions (the colour oracle of `dpcbench oracle --colour`) and on methods' fills.

For OUTDIR as written by `experiments/colour_one_frame.sh FRAME.ply PRESET SEED OUTDIR` (OUTDIR/damaged and
OUTDIR/METHOD/*.ply), each geometry (``oracle``: the damaged frame plus every missing truth point; then each
METHOD's output points) is coloured anew from the damaged frame alone, its kept points keeping their colours, by:

- ``harmonic kK``: the methods' harmonic fill (`methods._colour.colour_frame`) on a K-neighbour graph (8: the
  methods' own);
- ``smooth kK``: the same, the input colours first averaged over each input point's K nearest input points
  (a rim denoised before it is interpolated);
- ``idw kK pP``: inverse-distance weighting of the K nearest input colours, weights 1 / d^P;
- ``nearest``: the nearest input colour.

and scored as `cpsnr_y` in the hole regions (the lower of the two directions). Usage:

    .venv/bin/python experiments/colour_fill_alternatives.py FRAME.ply OUTDIR [METHOD ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import dpcbench.methods._colour as colour_fill
from dpcbench.bench.data.plyio import read_ply
from dpcbench.bench.results.oracle import oracle_fill
from dpcbench.holes.regions import regions_from_json
from dpcbench.metrics.colour import ColourPair, colour_mse_directions, colour_psnr
from dpcbench.metrics.geometry import Selection


def hole_y(truth, points: np.ndarray, colours: np.ndarray, regions) -> float:
    pair = ColourPair(truth.points, points, reference_colours=truth.colors, result_colours=colours)
    mses = colour_mse_directions(pair, Selection.of(pair, regions), 1)
    return min(colour_psnr(m[0], 1) for m in mses)


def fills(damaged, points: np.ndarray):
    """(name, (N', 3) uint8 colours of ``points``) for every fill of the module docstring."""
    tree = cKDTree(damaged.points)
    kept = colour_fill.kept_index(damaged.points, points)
    new = kept < 0
    default_k = colour_fill.HARMONIC_NEIGHBOURS
    try:
        for k in (4, 8, 16, 32):
            colour_fill.HARMONIC_NEIGHBOURS = k
            yield f"harmonic k{k}", colour_fill.colour_frame(damaged.points, damaged.colors, points, fill="harmonic")
    finally:
        colour_fill.HARMONIC_NEIGHBOURS = default_k
    for k in (8, 32, 128):
        _, near = tree.query(damaged.points, k=k, workers=-1)
        smooth = np.rint(damaged.colors[near].astype(float).mean(axis=1)).astype(np.uint8)
        out = colour_fill.colour_frame(damaged.points, smooth, points, fill="harmonic")
        out[~new] = damaged.colors[kept[~new]]
        yield f"smooth k{k}", out
    nearest = colour_fill.colour_frame(damaged.points, damaged.colors, points, fill="nearest")
    for k in (8, 64):
        dist, near = tree.query(points[new], k=k, workers=-1)
        for power in (2, 4):
            weight = 1.0 / np.maximum(dist, 1e-9) ** power
            mean = (damaged.colors[near] * weight[..., None]).sum(axis=1) / weight.sum(axis=1)[:, None]
            out = nearest.copy()  # kept points keep their colours
            out[new] = np.clip(np.rint(mean), 0, 255).astype(np.uint8)
            yield f"idw k{k} p{power}", out
    yield "nearest", nearest


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("frame", help="the ground-truth PLY frame")
    parser.add_argument("outdir", help="the folder colour_one_frame.sh wrote")
    parser.add_argument("methods", nargs="*", help="method folders in OUTDIR whose geometry is coloured too")
    args = parser.parse_args(argv)
    out = Path(args.outdir)
    truth = read_ply(args.frame)
    damaged = read_ply(next((out / "damaged").glob("*.ply")))
    regions = regions_from_json(str(out / "damaged" / "holes.json"), frame_count=1, label="holes.json")[0]
    geometries = {"oracle": oracle_fill(truth.points, damaged.points, "truth")}
    for method in args.methods:
        geometries[method] = read_ply(next((out / method).glob("*.ply"))).points
    rows = {name: dict((fill, hole_y(truth, points, c, regions)) for fill, c in fills(damaged, points))
            for name, points in geometries.items()}
    names = list(next(iter(rows.values())))
    print("| geometry | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for geometry, by in rows.items():
        print(f"| {geometry} | " + " | ".join(f"{by[n]:.2f}" for n in names) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
