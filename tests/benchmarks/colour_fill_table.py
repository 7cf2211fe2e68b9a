"""Hole-region colour PSNR of every method and colour fill on coloured sequences (not a test).

    DPCBENCH_CACHE=/tmp/x .venv/bin/python tests/benchmarks/colour_fill_table.py human
    .venv/bin/python tests/benchmarks/colour_fill_table.py ../shared/data/mvub_ricardo9 --methods none,temporal-copy
    .venv/bin/python tests/benchmarks/colour_fill_table.py ../shared/data/8i_longdress_1300

Each sequence (an embedded name such as ``human``, with ``--frames`` frames at ``--size``, or a folder
of coloured PLY frames) is damaged with ``region`` holes (preset medium, seed 0, coherent unless ``--independent``), every
method fills it (``inpaint_with_colours``, once per fill in ``--fills``: the geometry is computed once,
the fills recolour it; a method that colours its output itself, `methods.base.colours_itself`, runs once per fill
and its fill's CPU seconds include the method), and the mean over frames of the hole-region cpsnr_y / cpsnr_u / cpsnr_v (pc_error
BT.709, `metrics.colour`) against the undamaged frames is printed as a Markdown table, with the CPU
seconds of each method and of each fill.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

METHODS = ("none", "temporal-copy", "lozes-pde", "meshlab", "fu-nonlocal", "temporal-graph", "temporal-fusion")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", help="embedded stand-in name (human, bunny) or a folder of PLY frames")
    parser.add_argument("--frames", type=int, default=3, help="frames of an embedded stand-in (default 3)")
    parser.add_argument("--size", default="tiny", help="size of an embedded stand-in (default tiny)")
    parser.add_argument("--methods", default=",".join(METHODS), help="comma-separated method names")
    parser.add_argument("--fills", default="nearest,harmonic,auto", help="comma-separated colour fills")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--independent", action="store_true",
                        help="independent holes in each frame (default: coherent, the same patch in consecutive frames)")
    args = parser.parse_args()

    import dpcbench.metrics as metrics
    from dpcbench.bench.data.sequences import load_sequence
    from dpcbench.holes.registry import get_generator
    from dpcbench.methods._colour import colour_outputs
    from dpcbench.methods.base import colours_itself
    from dpcbench.methods.registry import get_method

    if Path(args.sequence).exists():
        seq = load_sequence(args.sequence)
    else:
        from dpcbench.bench.data.datasets import load_dataset

        seq = load_dataset(args.sequence, frames=args.frames, size=args.size, progress=False)
    truth = seq.frames
    assert all(f.colors is not None for f in truth), f"{args.sequence}: frames carry no colours"
    damage = get_generator("region", preset="medium", coherent=not args.independent).damage(
        [f.points for f in truth], args.seed, [f.colors for f in truth])
    print(f"{args.sequence}: {len(truth)} frame(s), {[len(f.points) for f in truth]} points, removed "
          f"{np.mean(damage.removed_fraction):.2%}, {sum(len(r) for r in damage.regions)} regions")
    fills = args.fills.split(",")
    print("\n| method | " + " | ".join(f"Y {f}" for f in fills) + " | U / V (" + fills[-1] + ") | method CPU s | "
          + " | ".join(f"{f} CPU s" for f in fills) + " |")
    print("|---" * (2 * len(fills) + 3) + "|")
    for name in args.methods.split(","):
        method = get_method(name)
        start = time.process_time()
        try:
            outputs, sources = method.inpaint_with_sources(damage.frames, damage.regions)
        except Exception as err:  # a method that cannot run here (missing pymeshlab, ...): say so, go on
            print(f"| {name} | failed: {type(err).__name__}: {str(err)[:80]} |")
            continue
        method_cpu = time.process_time() - start
        ys, cpu, last = [], [], None
        for fill in fills:
            start = time.process_time()
            if colours_itself(method):
                outputs, colours = method.inpaint_with_colours(damage.frames, damage.colors, damage.regions, fill=fill)
            else:
                colours = colour_outputs(damage.frames, damage.colors, outputs, sources, fill)
            cpu.append(time.process_time() - start)
            scores = metrics.score_sequence(
                [f.points for f in truth], outputs, ["cpsnr_y", "cpsnr_u", "cpsnr_v"], regions=damage.regions,
                reference_colours=[f.colors for f in truth], result_colours=colours)
            ys.append(scores["mean"]["cpsnr_y"])
            last = scores["mean"]
        print(f"| {name} | " + " | ".join(f"{y:.2f}" for y in ys) + f" | {last['cpsnr_u']:.2f} / {last['cpsnr_v']:.2f} | "
              f"{method_cpu:.1f} | " + " | ".join(f"{c:.1f}" for c in cpu) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
