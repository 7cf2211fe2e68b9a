"""`dpcbench inpaint INPUT --method NAME [--param k=v ...] [--regions holes.json] --out DIR`.

INPUT is an embedded dataset name (e.g. ``human``), a paper sequence name (with --data-dir), or a
folder / glob / file of PLY frames (typically the output folder of `dpcbench damage`). With
``--regions`` the method gets the hole regions of every frame (the default protocol); without it,
the blind protocol: the method finds the missing data itself (methods that cannot say so).

DIR receives the inpainted frames ``<name>_0000.ply ...`` (binary PLY; when the input has normals, every
output point carries one: a kept point its input normal, a new point a PCA normal of the output oriented like
its nearest input point's (`methods._normals`), so renders of the input, the result and the ground truth are
shaded alike; when the input has colours,
every output point carries one: the method's colours, `InpaintingMethod.inpaint_with_colours`, with the
fill chosen by ``--colour``: captured points keep theirs, new points take the colour the method gives them
(temporal-copy its source point's, temporal-fusion its copies' fused colours, temporal-graph and fu-nonlocal
colour solved on their graph, meshlab MeshLab's vertex colours), else a harmonic interpolation from the
hole's rim; ``--colour nearest`` gives every new point its nearest input point's colour) and ``inpaint.json``
(method, parameters, input, regions file, colour fill, seconds per frame). DIR may not be INPUT, nor
lie inside it.
"""

from __future__ import annotations

import json
import time

import numpy as np

from dpcbench.bench.cli.options import add_input_options, load_input
from dpcbench.bench.core.errors import RECORDED, UserError
from dpcbench.bench.core.params import parse_params


def register(subparsers) -> None:
    from dpcbench.methods.registry import METHODS

    parser = subparsers.add_parser(
        "inpaint",
        help="fill the holes of a sequence with a method; writes the inpainted PLY frames",
        description=__doc__.split("\n", 2)[2],
    )
    parser.add_argument("input", help="embedded name (human, bunny, cow), paper sequence, or PLY folder/glob/file")
    parser.add_argument("--method", required=True, help=f"method: {', '.join(sorted(METHODS))}")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE",
                        help="method parameter (repeatable), e.g. --param beta=0.5 --param known_points=free; values: "
                             "true/false, none, numbers, JSON lists, else text (see bench/core/params.py)")
    parser.add_argument("--regions", metavar="HOLES_JSON", default=None,
                        help="hole regions per frame (holes.json of `dpcbench damage`); omit for the blind protocol")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder (not INPUT)")
    parser.add_argument("--colour", default="auto", choices=["auto", "nearest", "harmonic", "source"],
                        help="colour of the new points when the input has colours: auto (the method's own colour "
                             "where it gives one, else harmonic; default), nearest (nearest input point), "
                             "harmonic (graph-harmonic interpolation from the hole's rim), source (source, else "
                             "nearest)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing files in DIR that dpcbench did not write")
    add_input_options(parser)
    parser.set_defaults(func=run)


def make_method(name: str, params: dict):
    """The configured method, its parameters checked (`validate_params`); UserError for an unknown
    name or a bad parameter."""
    from dpcbench.bench.core.params import check_param_types
    from dpcbench.methods.registry import METHODS, method_class

    if name not in METHODS:
        raise UserError(f"--method: unknown method {name!r}; known methods: {', '.join(sorted(METHODS))} "
                        "(see `dpcbench list`)")
    try:
        cls = method_class(name)
    except ImportError as err:  # an optional dependency of this method is missing here
        raise UserError(f"--method {name}: cannot be used here: {err}") from None
    check_param_types(cls, params, f"--method {name}")
    return cls(**params).validate_params()


def run(args) -> int:
    from dpcbench.bench.data.outputs import Outputs
    from dpcbench.bench.data.plyio import PointCloud
    from dpcbench.bench.data.sequences import Sequence, check_regions_frames, save_sequence, sequence_file_names
    from dpcbench.holes.regions import regions_from_json
    from dpcbench.methods.base import check_sequence

    method = make_method(args.method, parse_params(args.param))
    seq = load_input(args.input, args.frames, args.data_dir, parse_params(args.dataset_param, "--dataset-param"))
    regions = None
    if args.regions:
        regions = regions_from_json(args.regions, frame_count=len(seq), label=f"--regions {args.regions}")
        check_regions_frames(args.regions, seq, f"--regions {args.regions}")
    elif getattr(method, "needs_regions", False) or not getattr(method, "detects_holes", True):
        raise UserError(f"--method {args.method} needs the hole regions: pass --regions HOLES_JSON (from "
                        "`dpcbench damage` or `dpcbench detect-holes`)")
    check_sequence(seq.points, regions, method=args.method)
    names = sequence_file_names(seq.name, len(seq)) + ["inpaint.json"]
    guard = Outputs(args.overwrite, inputs=[args.input, args.regions])
    out = guard.folder(args.out, "--out", names, sequence=True)
    started = time.perf_counter()
    results, colours = _inpaint_with_progress(method, seq, regions, args.colour)
    seconds = time.perf_counter() - started
    normals = _carried_normals(seq, results)
    frames = [PointCloud(np.asarray(points, dtype=np.float64), cols, nrm, precision=frame.precision)
              for frame, points, cols, nrm in zip(seq.frames, results, colours, normals)]
    with guard.staged(out) as stage:  # the frames and inpaint.json appear together, or not at all
        files = save_sequence(Sequence(seq.name, frames, seq.bit_depth, meta=dict(seq.meta)), stage)
        _write_record(args, method, regions, seconds, files, results, seq, stage)
    added = sum(len(p) for p in results) - sum(len(f.points) for f in seq.frames)
    print(f"{args.method}: {len(files)} frames -> {out} ({added:+d} points, {seconds:.1f} s)")
    return 0


def _inpaint_with_progress(method, seq, regions, colour_fill: str) -> tuple[list, list]:
    """(points, colours or Nones) per frame: the method's output, with a per-frame progress bar on stderr
    fed by the method (`methods.progress`; a method that reports nothing shows the bar at 0 until it ends)."""
    from dpcbench.bench.core.progress import progress_bar
    from dpcbench.methods.progress import report_frames_to

    with progress_bar(total=len(seq), desc=f"{method.name or type(method).__name__}", unit="frame") as bar:
        def advance(done: int, total: int) -> None:
            bar.update(max(0, min(done, len(seq)) - bar.n))

        with report_frames_to(advance):
            if all(frame.colors is not None for frame in seq.frames):
                return method.inpaint_with_colours(seq.points, [f.colors for f in seq.frames], regions,
                                                   fill=colour_fill)
            return method.inpaint(seq.points, regions), [None] * len(seq)


def _carried_normals(seq, results) -> list:
    """Per frame the output's normals when every input frame carries normals (`methods._normals`: the
    input's for kept points, estimated and oriented for new ones), else None."""
    from dpcbench.methods._normals import output_normals

    if not all(frame.normals is not None for frame in seq.frames):
        return [None] * len(seq)
    return [output_normals(frame.points, frame.normals, points)
            for frame, points in zip(seq.frames, results)]


def _write_record(args, method, regions, seconds, files, results, seq, stage) -> None:
    """inpaint.json (module doc) into the staging folder."""
    from dpcbench.bench.core.atomic import atomic_write_text

    record = {
        "method": args.method,
        "method_version": type(method).version,
        "params": method.get_params(),
        "input": str(args.input),
        "regions": str(args.regions) if args.regions else None,
        "protocol": "regions" if regions is not None else "blind",
        "colour": args.colour if all(f.colors is not None for f in seq.frames) else None,
        "seconds": seconds,
        "seconds_per_frame": seconds / max(1, len(files)),
        "points": [int(len(p)) for p in results],
        "input_points": [int(len(f.points)) for f in seq.frames],
        "files": [p.name for p in files],
    }
    if RECORDED:
        record["warnings"] = list(RECORDED)
    atomic_write_text(stage / "inpaint.json", json.dumps(record, indent=1, default=str))
