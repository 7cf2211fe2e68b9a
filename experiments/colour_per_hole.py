"""Hole-region colour PSNR (BT.709 Y) of one-frame fills, hole by hole and direction by direction.

For each method folder that `experiments/colour_one_frame.sh` wrote (OUTDIR/METHOD/*.ply, the damage in
OUTDIR/damaged), prints the Y PSNR of the reference-to-result direction (each truth point in the holes against the
colour of its nearest result point) and of the result-to-reference direction (each result point in the holes against
its nearest truth point), over all holes and for each hole alone, with the number of points each direction
evaluates. The name ``oracle`` among the METHODs stands for the colour oracle of `dpcbench oracle --colour`: the
truth's own positions, the missing points coloured from the damaged frame by the methods' harmonic fill.
`cpsnr_y` is the lower of the two (pc_error's symmetric figure, `metrics.colour`). A direction with no
point in a hole (no fill there) is printed as "-".

Usage (after `experiments/colour_one_frame.sh FRAME.ply PRESET SEED OUTDIR`):

    .venv/bin/python experiments/colour_per_hole.py FRAME.ply OUTDIR [METHOD ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dpcbench.bench.data.plyio import read_ply
from dpcbench.holes.regions import regions_from_json
from dpcbench.metrics.colour import ColourPair, colour_psnr
from dpcbench.metrics.geometry import Selection

METHODS = ("none", "lozes-pde", "meshlab", "fu-nonlocal", "temporal-graph", "temporal-fusion")


def direction_psnrs(pair: ColourPair, regions) -> tuple[str, str, int, int]:
    """(reference->result Y PSNR, result->reference Y PSNR, their point counts) inside ``regions``."""
    sel = Selection.of(pair, regions)
    cells = []
    for forward, mask in ((True, sel.reference), (False, sel.result)):
        errors = pair.colour_errors(forward, 1)[mask]
        cells.append((f"{colour_psnr(errors[:, 0].sum(dtype=float) / len(errors), 1):.2f}" if len(errors) else "-", len(errors)))
    return cells[0][0], cells[1][0], cells[0][1], cells[1][1]


def one_frame(folder: Path):
    files = sorted(folder.glob("*.ply"))
    if len(files) != 1:
        sys.exit(f"{folder}: expected one PLY frame, found {len(files)}")
    frame = read_ply(files[0])
    return frame.points, frame.colors


def oracle(truth, outdir: Path):
    """The truth's positions (damaged plus every missing truth point) with the methods' harmonic colours."""
    import numpy as np

    from dpcbench.bench.results.oracle import oracle_fill
    from dpcbench.methods._colour import colour_frame

    damaged_points, damaged_colours = one_frame(outdir / "damaged")
    points = oracle_fill(truth.points, damaged_points, "truth")
    return points, colour_frame(np.asarray(damaged_points, dtype=float), damaged_colours, points, fill="harmonic")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the undamaged frame (PLY with colours)")
    parser.add_argument("outdir", type=Path, help="colour_one_frame.sh's OUTDIR (damaged/ and one folder a method)")
    parser.add_argument("methods", nargs="*", help=f"method folders to read (default: those of {', '.join(METHODS)} "
                                                   "that exist)")
    args = parser.parse_args(argv)
    truth = read_ply(args.truth)
    if truth.colors is None:
        sys.exit(f"{args.truth}: no colours; colour PSNR needs a coloured frame")
    regions = regions_from_json(args.outdir / "damaged" / "holes.json", frame_count=1, label="holes.json")[0]
    methods = args.methods or [m for m in METHODS if (args.outdir / m).is_dir()]
    print("| method | hole | truth points | result points | Y ref->result | Y result->ref |")
    print("|---|---|---|---|---|---|")
    for method in methods:
        points, colours = oracle(truth, args.outdir) if method == "oracle" else one_frame(args.outdir / method)
        pair = ColourPair(truth.points, points, reference_colours=truth.colors, result_colours=colours)
        for label, regs in [("all", regions)] + [(str(i), [r]) for i, r in enumerate(regions)]:
            forward, backward, n_ref, n_res = direction_psnrs(pair, regs)
            print(f"| {method} | {label} | {n_ref} | {n_res} | {forward} | {backward} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
