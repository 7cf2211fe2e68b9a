"""`dpcbench damage INPUT --holes GENERATOR [--param k=v ...] --seed S --out DIR`: punch holes with ground truth.

INPUT is an embedded dataset name (e.g. ``human``), a paper sequence name (with --data-dir), or a
folder / glob / file of PLY frames. DIR receives:

- ``<name>_0000.ply ...``: the damaged frames (binary PLY, colours and normals kept);
- ``masks.npz``: one boolean array per frame, key ``frame_0000`` ..., True for the points of the
  *original* frame that were removed (``original[~mask]`` is the damaged frame, row order kept);
- ``holes.json``: the hole regions per frame and the damage record (format in `holes.regions`):
  ``generator``, ``params``, ``seed``, ``source``, ``removed_fraction`` (list per frame), and per
  frame entry ``points`` (original count), ``removed`` (count), ``removed_fraction``, ``file``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dpcbench.bench.cli.options import add_input_options, load_input
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.core.params import parse_params


def register(subparsers) -> None:
    from dpcbench.holes.registry import GENERATORS

    parser = subparsers.add_parser(
        "damage",
        help="punch holes into a sequence (ground truth kept): damaged PLYs, masks.npz, holes.json",
        description=__doc__.split("\n", 2)[2],
    )
    parser.add_argument("input", help="embedded name (human, bunny, cow), paper sequence, or PLY folder/glob/file")
    parser.add_argument("--holes", required=True, metavar="GENERATOR",
                        help=f"hole generator: {', '.join(sorted(GENERATORS))}")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE",
                        help="generator parameter (repeatable), e.g. --param preset=large --param coherent=true; "
                             "values: true/false, none, numbers, JSON lists, else text (see bench/core/params.py)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0): same seed, same holes")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_input_options(parser)
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing files in DIR that dpcbench did not write (files it wrote are "
                             "replaced anyway)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from dpcbench.bench.core.atomic import atomic_path, atomic_write_text
    from dpcbench.bench.data.outputs import Outputs
    from dpcbench.bench.data.sequences import Sequence, frames_record, save_sequence, sequence_file_names
    from dpcbench.holes.regions import regions_to_json
    from dpcbench.holes.registry import GENERATORS, generator_class

    if args.holes not in GENERATORS:
        raise UserError(f"--holes: unknown hole generator {args.holes!r}; known: {', '.join(sorted(GENERATORS))} "
                        "(see `dpcbench list`)")
    if not 0 <= args.seed < 2**32:
        raise UserError(f"--seed {args.seed}: give a whole number in 0..{2**32 - 1}")
    try:
        cls = generator_class(args.holes)
    except ImportError as err:  # an optional dependency or a plug-in's module missing or broken here
        raise UserError(f"--holes {args.holes}: cannot be used here: {err}") from None
    generator = cls(**_known_params(cls, parse_params(args.param), f"--holes {args.holes}"))
    generator.validate_params()
    seq = load_input(args.input, args.frames, args.data_dir, parse_params(args.dataset_param, "--dataset-param"))
    if (Path(args.out) / "holes.json").exists() and not args.overwrite:
        # even one dpcbench wrote: it is the ground truth of whatever was inpainted and scored from it
        raise UserError(f"--out {args.out} already holds a holes.json (the ground truth of an earlier damage); "
                        "choose another --out or pass --overwrite")
    names = sequence_file_names(seq.name, len(seq)) + ["masks.npz", "holes.json"]
    guard = Outputs(args.overwrite, inputs=[args.input])
    out = guard.folder(args.out, "--out", names, sequence=True)
    colors = seq.colors if seq.frames[0].colors is not None else None
    result = generator.damage(seq.points, args.seed, colors=colors)
    damaged = Sequence(seq.name, [frame.subset(~mask) for frame, mask in zip(seq.frames, result.removed)],
                       seq.bit_depth, meta=dict(seq.meta))
    with guard.staged(out) as stage:  # frames, masks and record appear together, or not at all
        files = save_sequence(damaged, stage)
        with atomic_path(stage / "masks.npz") as tmp:
            np.savez_compressed(tmp, **{f"frame_{i:04d}": m for i, m in enumerate(result.removed)})
        fractions = result.removed_fraction
        record = regions_to_json(
            result.regions,
            generator=args.holes,
            generator_version=type(generator).version,
            params=generator.get_params(),
            seed=args.seed,
            source=str(args.input),
            removed_fraction=fractions,
            **frames_record(seq),
            per_frame=[
                {"points": int(len(m)), "removed": int(m.sum()), "removed_fraction": frac, "file": p.name}
                for m, frac, p in zip(result.removed, fractions, files)
            ],
        )
        from dpcbench.bench.core.errors import RECORDED

        if RECORDED:
            record["warnings"] = list(RECORDED)  # the notes printed while it was made (e.g. which input was taken)
        atomic_write_text(stage / "holes.json", json.dumps(record, indent=1, default=_jsonable))
    print(f"{len(files)} frames -> {out}: removed {np.mean(fractions):.2%} of the points on average "
          f"(min {min(fractions):.2%}, max {max(fractions):.2%}), "
          f"{sum(len(r) for r in result.regions)} hole regions")
    return 0


def _known_params(cls, params: dict, who: str) -> dict:
    """``params`` when every name is a parameter of ``cls``; UserError listing the valid ones otherwise."""
    from dpcbench.bench.core.params import check_param_types

    check_param_types(cls, params, who)
    return params


def _jsonable(value):
    """numpy scalars/arrays and tuples in params -> JSON."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serializable: {type(value).__name__}")
