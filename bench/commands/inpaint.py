"""`dpcbench inpaint INPUT --method NAME [--param k=v ...] [--regions holes.json] --out DIR`.

INPUT is an embedded dataset name (e.g. ``human``), a paper sequence name (with --data-dir), or a
folder / glob / file of PLY frames (typically the output folder of `dpcbench damage`). With
``--regions`` the method gets the hole regions of every frame (the default protocol); without it,
the blind protocol: the method finds the missing data itself (methods that cannot say so).

DIR receives the inpainted frames ``<name>_0000.ply ...`` (binary PLY; when the input has colours,
every output point takes the colour of its nearest input point) and ``inpaint.json`` (method,
parameters, input, regions file, seconds per frame). DIR may not be INPUT, nor lie inside it.
"""

from __future__ import annotations

import inspect
import json
import time
from pathlib import Path

import numpy as np

from bench.commands.damage import add_input_options, load_input, parse_params
from bench.errors import UserError


def register(subparsers) -> None:
    from methods.registry import METHODS

    parser = subparsers.add_parser(
        "inpaint",
        help="fill the holes of a sequence with a method; writes the inpainted PLY frames",
        description=__doc__.split("\n", 2)[2],
    )
    parser.add_argument("input", help="embedded name (human, bunny), paper sequence, or PLY folder/glob/file")
    parser.add_argument("--method", required=True, help=f"method: {', '.join(sorted(METHODS))}")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE",
                        help="method parameter (repeatable; values read as JSON when they parse: numbers, "
                             "true/false, null), e.g. --param beta=0.5 --param known_points=free")
    parser.add_argument("--regions", metavar="HOLES_JSON", default=None,
                        help="hole regions per frame (holes.json of `dpcbench damage`); omit for the blind protocol")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (not INPUT)")
    add_input_options(parser)
    parser.set_defaults(func=run)


def _refuse_input_folder(source: str, out: Path) -> None:
    """UserError when ``out`` is the input folder (or a folder inside it, or the folder of an input file)."""
    path = Path(source)
    if not path.exists():
        return  # a dataset name or a glob: nothing on disk to protect by that name
    folder = (path if path.is_dir() else path.parent).resolve()
    target = out.resolve()
    if target == folder or folder in target.parents:
        raise UserError(f"--out {out} is inside the input {source}; the input is never overwritten: "
                        "choose another output folder")


def make_method(name: str, params: dict):
    """The configured method; UserError for an unknown name or parameter."""
    from methods.registry import METHODS, method_class

    try:
        cls = method_class(name)
    except KeyError:
        raise UserError(f"unknown method {name!r}; known methods: {', '.join(sorted(METHODS))} "
                        "(see `dpcbench list`)") from None
    except ImportError as err:
        raise UserError(f"method {name!r} cannot be used here: {err}") from None
    valid = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    unknown = sorted(set(params) - set(valid))
    if unknown:
        raise UserError(f"--method {name}: unknown parameter(s) {', '.join(unknown)}; "
                        f"valid parameters: {', '.join(valid) or '(none)'}")
    return cls(**params)


def run(args) -> int:
    from bench.plyio import PointCloud
    from bench.sequences import Sequence, save_sequence
    from holes.regions import regions_from_json

    out = Path(args.out)
    _refuse_input_folder(args.input, out)
    method = make_method(args.method, parse_params(args.param))
    seq = load_input(args.input, args.frames, args.data_dir, parse_params(args.dataset_param))
    regions = None
    if args.regions:
        try:
            regions = regions_from_json(args.regions)
        except (OSError, ValueError, KeyError, json.JSONDecodeError) as err:
            raise UserError(f"--regions {args.regions}: cannot read hole regions ({err})") from None
        if len(regions) != len(seq):
            raise UserError(f"--regions {args.regions} describes {len(regions)} frames but {args.input} has "
                            f"{len(seq)}; use the holes.json made for these frames (or the same --frames)")
    started = time.perf_counter()
    try:
        results = method.inpaint(seq.points, regions)
    except (ValueError, KeyError) as err:
        raise UserError(str(err).strip("\"'")) from None
    seconds = time.perf_counter() - started
    frames = []
    for frame, points in zip(seq.frames, results):
        colors = None
        if frame.colors is not None:
            from scipy.spatial import cKDTree

            _, nearest = cKDTree(frame.points).query(points, workers=-1)
            colors = frame.colors[nearest]
        frames.append(PointCloud(np.asarray(points, dtype=np.float64), colors))
    files = save_sequence(Sequence(seq.name, frames, seq.bit_depth, meta=dict(seq.meta)), out)
    record = {
        "method": args.method,
        "method_version": type(method).version,
        "params": method.get_params(),
        "input": str(args.input),
        "regions": str(args.regions) if args.regions else None,
        "protocol": "regions" if regions is not None else "blind",
        "seconds": seconds,
        "seconds_per_frame": seconds / max(1, len(files)),
        "points": [int(len(p)) for p in results],
        "input_points": [int(len(f.points)) for f in seq.frames],
        "files": [p.name for p in files],
    }
    tmp = out / "inpaint.json.tmp"
    tmp.write_text(json.dumps(record, indent=1, default=str))
    tmp.replace(out / "inpaint.json")
    added = sum(record["points"]) - sum(record["input_points"])
    print(f"{args.method}: {len(files)} frames -> {out} ({added:+d} points, {seconds:.1f} s)")
    return 0
