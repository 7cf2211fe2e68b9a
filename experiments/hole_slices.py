"""Slices through one hole of a damaged frame: what the frame keeps round it, the hidden truth, and each candidate
surface of temporal-fusion's last resort (`experiments/candidate_accuracy.py`'s, without refusal tests), so that a
hole the candidates fill badly can be seen (a fold, a second layer, the end of a limb inside the hole).

    .venv/bin/python experiments/hole_slices.py TRUTH DAMAGED --region K --out slices.png [--frame 0] [--axis 1]

Three slices one third of the radius apart, through the region's centre, across ``--axis`` (0, 1, 2 = x, y, z), each
1.5 spacings thick; the dashed circle is the hole's ball where the slice cuts it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from candidate_accuracy import region_candidates
from fill_audit import truth_frames
from scipy.spatial import cKDTree

from dpcbench.bench.data.plyio import read_ply
from dpcbench.methods._geometry import sampling_step
from dpcbench.metrics.neighbours import point_spacing


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the undamaged frames: a PLY file or a folder of PLY frames")
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--region", type=int, required=True, help="the hole's index in the frame's regions")
    parser.add_argument("--frame", type=int, default=0)
    parser.add_argument("--axis", type=int, default=1, choices=(0, 1, 2), help="the axis the slices cut across")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args(argv)
    _, frames, regions = load_damage_or_exit(args.damaged)
    if not 0 <= args.region < len(regions[args.frame]):
        parser.error(f"--region: frame {args.frame} has {len(regions[args.frame])} regions")
    truth = np.asarray(read_ply(truth_frames(args.truth, args.damaged)[args.frame]).points, dtype=np.float64)
    damaged, region = frames[args.frame], regions[args.frame][args.region]
    integer = np.array_equal(damaged, np.round(damaged))
    spacing = 1.0 if integer else point_spacing(damaged)
    step = spacing if integer else sampling_step(damaged)
    tree = cKDTree(damaged)
    crop, _, surfaces = region_candidates(damaged, tree, region, spacing, step, integer)
    hidden = truth[region.contains(truth) & (tree.query(truth)[0] > 1e-6 * spacing)]
    fills = {name: fill(support, region, cKDTree(crop)) for name, (support, fill) in surfaces.items()}

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    centre, radius = np.asarray(region.center, dtype=float), float(region.bounding_radius)
    u, v = [a for a in range(3) if a != args.axis]
    fig, axes = plt.subplots(1, 3, figsize=(18, 6))
    colours = {"spline": "tab:green", "sheet": "tab:orange", "closed": "tab:blue"}
    for ax, offset in zip(axes, (-radius / 3, 0.0, radius / 3)):
        level = centre[args.axis] + offset

        layers = [("kept", crop, "0.6"), ("hidden truth", hidden, "red")]
        layers += [(name, points, colours.get(name, "k")) for name, points in fills.items()]
        for name, points, colour in layers:
            part = points[np.abs(points[:, args.axis] - level) <= 0.75 * spacing]
            ax.scatter(part[:, u], part[:, v], s=3, c=colour, label=f"{name} ({len(points)})")
        if region.shape == "ball":
            ax.add_patch(plt.Circle((centre[u], centre[v]), np.sqrt(max(radius ** 2 - offset ** 2, 0.0)), fill=False,
                                    ls="--"))
        ax.set_aspect("equal")
        ax.set_title(f"{'xyz'[args.axis]} = {level:.1f}")
        ax.legend(fontsize=8)
    fig.suptitle(f"{args.damaged.name}, frame {args.frame}, region {args.region}")
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
