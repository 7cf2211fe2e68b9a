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

from bench.errors import UserError


def parse_params(items: list[str] | None) -> dict:
    """``["k=v", ...]`` -> dict; values parsed as JSON (numbers, true/false, lists) else kept as text."""
    params = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--param {item!r}: expected KEY=VALUE, e.g. --param preset=large")
        try:
            params[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            params[key.strip()] = value
    return params


def load_input(source: str, frames=None, data_dir=None, dataset_params=None):
    """The input sequence: an embedded/paper dataset name or a PLY folder/glob/file.

    frames: the text of --frames (a count "10", a list "0,5,9" or a range "0-9"; None: all).
    """
    from bench.datasets import load_dataset, parse_frames

    try:
        return load_dataset(source, frames=parse_frames(frames), data_dir=data_dir, **(dataset_params or {}))
    except (ValueError, KeyError) as err:
        raise UserError(f"{source}: {err}") from None


def add_input_options(parser) -> None:
    """--frames, --data-dir, --dataset-param: shared with `dpcbench detect-holes`."""
    parser.add_argument("--frames", default=None,
                        help="frames to use: a count (10), a list (0,5,9) or a range (0-9); default all")
    parser.add_argument("--data-dir", default=None, help="folder holding the paper sequences")
    parser.add_argument("--dataset-param", action="append", metavar="KEY=VALUE",
                        help="parameter of an embedded dataset (repeatable), e.g. --dataset-param size=tiny")


def register(subparsers) -> None:
    from holes.registry import GENERATORS

    parser = subparsers.add_parser(
        "damage",
        help="punch holes into a sequence (ground truth kept): damaged PLYs, masks.npz, holes.json",
        description=__doc__.split("\n", 2)[2],
    )
    parser.add_argument("input", help="embedded name (human, bunny), paper sequence, or PLY folder/glob/file")
    parser.add_argument("--holes", required=True, metavar="GENERATOR",
                        help=f"hole generator: {', '.join(sorted(GENERATORS))}")
    parser.add_argument("--param", action="append", metavar="KEY=VALUE",
                        help="generator parameter (repeatable), e.g. --param preset=large --param coherent=true")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0): same seed, same holes")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_input_options(parser)
    parser.add_argument("--overwrite", action="store_true", help="replace an existing holes.json in DIR")
    parser.set_defaults(func=run)


def run(args) -> int:
    from bench.sequences import Sequence, save_sequence
    import inspect

    from holes.registry import generator_class
    from holes.regions import regions_to_json

    out = Path(args.out)
    if (out / "holes.json").exists() and not args.overwrite:
        raise UserError(f"{out} already holds a holes.json; choose another --out or pass --overwrite")
    params = parse_params(args.param)
    try:
        cls = generator_class(args.holes)
    except KeyError as err:
        raise UserError(str(err).strip("\"'")) from None
    valid = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    unknown = sorted(set(params) - set(valid))
    if unknown:
        raise UserError(f"--holes {args.holes}: unknown parameter(s) {', '.join(unknown)}; "
                        f"valid parameters: {', '.join(valid)}")
    generator = cls(**params)
    seq = load_input(args.input, args.frames, args.data_dir, parse_params(args.dataset_param))
    colors = seq.colors if seq.frames[0].colors is not None else None
    try:
        result = generator.damage(seq.points, args.seed, colors=colors)
    except ValueError as err:
        raise UserError(str(err)) from None
    damaged = Sequence(seq.name, [frame.subset(~mask) for frame, mask in zip(seq.frames, result.removed)],
                       seq.bit_depth, meta=dict(seq.meta))
    files = save_sequence(damaged, out)
    np.savez_compressed(out / "masks.npz", **{f"frame_{i:04d}": m for i, m in enumerate(result.removed)})
    fractions = result.removed_fraction
    record = regions_to_json(
        result.regions,
        generator=args.holes,
        generator_version=type(generator).version,
        params=generator.get_params(),
        seed=args.seed,
        source=str(args.input),
        removed_fraction=fractions,
        per_frame=[
            {"points": int(len(m)), "removed": int(m.sum()), "removed_fraction": frac, "file": p.name}
            for m, frac, p in zip(result.removed, fractions, files)
        ],
    )
    tmp = out / "holes.json.tmp"
    tmp.write_text(json.dumps(record, indent=1, default=_jsonable))
    tmp.replace(out / "holes.json")
    print(f"{len(files)} frames -> {out}: removed {np.mean(fractions):.2%} of the points on average "
          f"(min {min(fractions):.2%}, max {max(fractions):.2%}), "
          f"{sum(len(r) for r in result.regions)} hole regions")
    return 0


def _jsonable(value):
    """numpy scalars/arrays and tuples in params -> JSON."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serializable: {type(value).__name__}")
