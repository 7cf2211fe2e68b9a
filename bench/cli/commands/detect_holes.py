"""`dpcbench detect-holes INPUT --out holes.json`: find the holes of captured frames (no ground truth).

Runs `holes.detection.detect_holes` on every frame of INPUT (embedded name, paper sequence or PLY
folder/glob/file) and writes a holes.json (format in `holes.regions`) with the detected ball regions
per frame, the detector parameters (``params``), and per frame ``points`` and ``region_count``.
The file can be handed to methods like the regions of a damaged sequence ("blind" protocol).
"""

from __future__ import annotations

import json

from dpcbench.bench.cli.options import add_input_options, load_input
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.core.params import parse_params


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "detect-holes",
        help="detect holes in captured frames (boundary rims -> ball regions) and write holes.json",
        description=__doc__.split("\n", 2)[2],
    )
    parser.add_argument("input", help="embedded name, paper sequence, or PLY folder/glob/file")
    parser.add_argument("--out", required=True, metavar="FILE", help="holes.json to write (a .json file)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing FILE that dpcbench did not write")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE",
                        help="detector parameter (repeatable): k, gap, link, min_points, min_inward, max_radius")
    add_input_options(parser)
    parser.set_defaults(func=run)


def run(args) -> int:
    from dpcbench.bench.core.atomic import atomic_write_text
    from dpcbench.bench.core.params import check_param_types
    from dpcbench.bench.core.progress import progress_bar
    from dpcbench.bench.data.outputs import Outputs, record_written
    from dpcbench.holes.detection import detect_holes
    from dpcbench.holes.regions import regions_to_json

    params = parse_params(args.param)
    if "points" in params:  # the first argument of detect_holes, not a parameter
        raise UserError("--param points: not a detector parameter (the points are the input frames); "
                        "parameters: k, gap, link, min_points, min_inward, max_radius")
    check_param_types(detect_holes, params, "--param (detector)")
    seq = load_input(args.input, args.frames, args.data_dir, parse_params(args.dataset_param, "--dataset-param"))
    out = Outputs(args.overwrite, inputs=[args.input]).file(args.out, "--out", suffixes=(".json",))
    regions = []
    for points in progress_bar(seq.points, desc="detecting holes", unit="frame"):
        regions.append(detect_holes(points, **params))
    record = regions_to_json(
        regions,
        detector="dpcbench.holes.detection.detect_holes",
        params=params,
        source=str(args.input),
        per_frame=[{"points": int(len(p)), "region_count": len(r)} for p, r in zip(seq.points, regions)],
    )
    from dpcbench.bench.core.errors import RECORDED

    if RECORDED:
        record["warnings"] = list(RECORDED)  # the notes printed while it was made
    atomic_write_text(out, json.dumps(record, indent=1))
    record_written([out])
    print(f"{len(regions)} frames: {sum(len(r) for r in regions)} hole regions "
          f"({', '.join(str(len(r)) for r in regions[:10])}{' ...' if len(regions) > 10 else ''} per frame) -> {out}")
    return 0
