"""`dpcbench generate NAME --frames N --out DIR`: write an embedded sequence (human, bunny) as binary
PLY frames ``<NAME>_0000.ply ...`` (float x y z, uchar red green blue)."""

from __future__ import annotations

from pathlib import Path

from bench.errors import UserError


def register(subparsers) -> None:
    parser = subparsers.add_parser("generate", help="write an embedded sequence (human, bunny) as PLY frames",
                                   description=__doc__)
    parser.add_argument("name", help="embedded sequence name (see `dpcbench list`)")
    parser.add_argument("--frames", type=int, default=None, help="number of frames (default: the dataset's)")
    parser.add_argument("--out", required=True, help="output folder (created)")
    parser.add_argument("--param", action="append", metavar="K=V", default=[],
                        help="generator parameter, repeatable: size=tiny|small|default, bit_depth=10, "
                             "motion=walk|dance|wave (human), seed=0, ...")
    parser.add_argument("--no-cache", action="store_true", help="regenerate instead of reading the frame cache")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing files in the output folder that dpcbench did not write")
    parser.set_defaults(func=run)


def run(args) -> int:
    from bench.datasets import EMBEDDED, PAPER, load_dataset
    from bench.outputs import Outputs, record_written
    from bench.params import parse_params
    from bench.sequences import save_sequence, sequence_file_names

    name = args.name.lower()
    if name not in EMBEDDED:
        hint = " (a paper sequence: it is read from --data-dir, not generated)" if name in PAPER else ""
        raise UserError(f"{args.name!r} is not an embedded sequence{hint}; choose one of {', '.join(EMBEDDED)}")
    if args.frames is not None and args.frames < 1:
        raise UserError(f"--frames must be at least 1, got {args.frames}")
    params = parse_params(args.param)
    count = args.frames if args.frames is not None else EMBEDDED[name].default_frames
    guard = Outputs(args.overwrite)
    guard.folder(args.out, "--out", sequence_file_names(name, count), sequence=True)
    seq = load_dataset(name, frames=args.frames, cache=not args.no_cache, name_only=True, **params)
    paths = save_sequence(seq, Path(args.out), prefix=name)
    record_written(paths)
    counts = [len(f) for f in seq.frames]
    depth = f", {seq.bit_depth}-bit integer coordinates" if seq.bit_depth else ""
    print(f"wrote {len(paths)} frames to {args.out} ({min(counts)}..{max(counts)} points per frame{depth})")
    return 0
