"""The cost of Membrane's test (1) in temporal-fusion's spatial cascade: fill a `dpcbench damage` folder with
temporal-fusion as it is, except that test (1) keeps every seed (``_within_hull_of`` answers True), and write the
result as PLY frames for `dpcbench score`. A measurement of the refusal rule, not a method. Usage:

    .venv/bin/python experiments/membrane_no_hull.py out/ld-medium/damaged out/ld-medium/no-hull
    .venv/bin/dpcbench score ../shared/data/8i_longdress_1300/longdress_vox10_1300.ply out/ld-medium/no-hull
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`

from dpcbench.bench.data.plyio import write_ply
from dpcbench.methods._spatial_fill import membrane
from dpcbench.methods.temporal_fusion.method import TemporalFusion


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("out", type=Path, help="folder for the filled PLY frames")
    args = parser.parse_args(argv)
    loaded = load_damage_or_exit(args.damaged)
    files, frames, regions = loaded
    membrane._within_hull_of = lambda points, inside, anchors: np.ones(len(points), dtype=bool)
    out = TemporalFusion().inpaint(frames, regions)
    args.out.mkdir(parents=True, exist_ok=True)
    for path, frame, filled in zip(files, frames, out):
        write_ply(args.out / path.name, filled)
        print(f"{path.name}: +{len(filled) - len(frame)} points")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
