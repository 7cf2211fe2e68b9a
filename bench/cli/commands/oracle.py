"""`dpcbench oracle TRUTH DAMAGED`: what fills that know the ground truth's surface score
(`bench.results.oracle`): the floor (no fill), samples on the truth's surface, the truth's points jittered
by a method's off-surface error, and the truth itself (the ceiling); with ``--refusal``, a method's result without
the fill points that lie a limit or more off the truth (what any refusal rule could reach with its fills)."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    from dpcbench.bench.results.oracle import VARIANTS

    p = subparsers.add_parser(
        "oracle", help="score oracle fills that know the ground truth's surface (a row's best achievable D1/D2)",
        description="Fill the holes of DAMAGED (a folder of PLY frames, e.g. `dpcbench damage` output or a run "
                    "folder's damaged/) from TRUTH (the ground-truth frames) and score each fill like a method: "
                    "none (no fill, the floor), surface (one sample per missing truth point, moved within the "
                    "truth's tangent plane by up to half the damaged frame's spacing), smooth (the surface samples "
                    "moved onto the truth's local quadric surface: the surface known, the samples' places and their "
                    "own offsets from it not), jitter (the missing truth points moved along the truth normal by N(0, sigma^2)) "
                    "and truth (the ceiling). With --method-result and --refusal, also that result without its fill "
                    "points a limit or more off the truth (the refusal oracle).")
    p.add_argument("truth", help="ground-truth PLY file, or folder / glob of PLY frames")
    p.add_argument("damaged", help="damaged PLY file, or folder / glob of PLY frames (same frame count)")
    p.add_argument("--variant", action="append", dest="variants", choices=VARIANTS, metavar="NAME",
                   help=f"oracle to score (repeatable; default all: {', '.join(VARIANTS)})")
    p.add_argument("--region", metavar="HOLES_JSON", default=None,
                   help="holes.json of the damage: also score inside the hole regions")
    p.add_argument("--masks", metavar="MASKS_NPZ", default=None,
                   help="removal masks of the damage (default: masks.npz in DAMAGED when there); without them the "
                        "missing points are the truth points farther than 1%% of the spacing from every damaged point")
    p.add_argument("--jitter", type=float, default=None, metavar="SIGMA",
                   help="the jitter oracle's sigma (coordinate units)")
    p.add_argument("--method-result", default=None, metavar="RESULT",
                   help="a method's inpainted frames of the same damage: sigma is its measured off-surface error "
                        "(RMS point-to-plane distance of its fill points to the truth)")
    p.add_argument("--refusal", default=None, metavar="LIMITS",
                   help="with --method-result: also score its result as it is and without the fill points at least "
                        "each of these comma-separated limits (spacings) off the truth along its normal: what a "
                        "refusal that knew each fill point's true error would score (e.g. 0.5,1)")
    p.add_argument("--by-depth", action="store_true",
                   help="with --method-result: also its fill points' off-surface error (RMS and 90th percentile "
                        "distance to the truth along its normal, spacings) by depth, their distance to the damaged "
                        "frame in bins of 0-2, 2-4, 4-8, ... spacings: whether the fill stays on the surface deep in "
                        "the holes, where no hold-out at the rim tested it")
    p.add_argument("--peak", default="intrinsic", help="PSNR peak (as `dpcbench score`)")
    p.add_argument("--seed", type=int, default=0, help="seed of the surface and jitter samples")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--break-even", action="store_true",
                   help="also find the jitter sigma at which a complete fill's D2 equals no fill's (the off-surface "
                        "error a fill must stay under for D2 at or above no fill)")
    p.add_argument("--colour", action="store_true",
                   help="also score colour (cpsnr_y/u/v): the truth's positions with the missing points coloured from "
                        "DAMAGED by each colour fill the methods have (harmonic from the rim, nearest input colour), "
                        "the best a method colouring with that fill can score; needs colour on both")
    p.set_defaults(func=main)


def _masks(args, count: int):
    import numpy as np

    path = Path(args.masks) if args.masks else Path(args.damaged) / "masks.npz"
    if not path.is_file():
        if args.masks:
            raise UserError(f"--masks {args.masks}: no such file; give the masks.npz written by `dpcbench damage`")
        return None
    with np.load(path) as data:
        keys = sorted(data.files)
        if len(keys) != count:
            raise UserError(f"{path}: {len(keys)} mask(s) for {count} frame(s); use the masks of this damage")
        return [data[k] for k in keys]


def main(args) -> int:
    import numpy as np

    from dpcbench.bench.data.sequences import load_sequence
    from dpcbench.bench.results.oracle import (
        VARIANTS,
        d2_break_even,
        off_surface_by_depth,
        off_surface_rms,
        score_oracles,
        score_refusals,
    )

    truth = load_sequence(args.truth, colors=args.colour)
    damaged = load_sequence(args.damaged, colors=args.colour)
    if len(truth) != len(damaged):
        raise UserError(f"{args.truth} has {len(truth)} frame(s), {args.damaged} has {len(damaged)}; give the truth "
                        "and the damaged frames of the same sequence")
    variants = args.variants or list(VARIANTS)
    if args.jitter is not None and args.method_result:
        raise UserError("--jitter and --method-result both set sigma; give one")
    if args.jitter is not None and not (math.isfinite(args.jitter) and args.jitter >= 0):
        raise UserError(f"--jitter {args.jitter:g}: must be a distance >= 0")
    if args.refusal is not None and not args.method_result:
        raise UserError("--refusal scores a method's result: give it with --method-result RESULT")
    if args.by_depth and not args.method_result:
        raise UserError("--by-depth measures a method's fill: give its result with --method-result RESULT")
    limits = _limits(args.refusal) if args.refusal is not None else None
    sigma, measured = args.jitter, None
    if args.method_result:
        result = load_sequence(args.method_result, colors=False)
        if len(result) != len(truth):
            raise UserError(f"--method-result {args.method_result}: {len(result)} frame(s) for {len(truth)}")
        per = [off_surface_rms(t, d, r) for t, d, r in zip(truth.points, damaged.points, result.points)]
        counts = np.array([n for _, n in per], dtype=float)
        if counts.sum() == 0:
            raise UserError(f"--method-result {args.method_result}: adds no point to the damaged frames, so it has "
                            "no off-surface error to measure")
        sigma = float(np.sqrt(sum(r ** 2 * n for r, n in per if n) / counts.sum()))
        measured = {"sigma": sigma, "fill_points": int(counts.sum())}
    if "jitter" in variants and sigma is None:
        if args.variants:
            raise UserError("--variant jitter: give its sigma with --jitter SIGMA or --method-result RESULT")
        variants = [v for v in variants if v != "jitter"]
    regions = None
    if args.region:
        from dpcbench.holes.regions import regions_from_json

        regions = regions_from_json(args.region, frame_count=len(truth), label=f"--region {args.region}")
    normals = [f.normals for f in truth.frames]
    given_normals = normals if any(n is not None for n in normals) else None
    masks = _masks(args, len(truth))
    colour = _colour_scores(args, truth, damaged, masks, regions) if args.colour else None  # refuses uncoloured first
    scores = score_oracles(truth.points, damaged.points, variants, masks=masks, regions=regions,
                           sigma=sigma or 0.0, seed=args.seed, peak=args.peak, reference_normals=given_normals)
    even = (d2_break_even(truth.points, damaged.points, masks=masks, seed=args.seed, peak=args.peak,
                          reference_normals=given_normals) if args.break_even else None)
    refusals = (score_refusals(truth.points, damaged.points, result.points, limits, regions=regions, peak=args.peak,
                               reference_normals=given_normals) if limits else None)
    by_depth = off_surface_by_depth(truth.points, damaged.points, result.points) if args.by_depth else None
    if args.json:
        payload = {"variants": {v: {scope: s["mean"] for scope, s in by.items()} for v, by in scores.items()},
                   "frames": {v: {scope: s["frames"] for scope, s in by.items()} for v, by in scores.items()},
                   "sigma": sigma, "measured": measured, "d2_break_even": even,
                   "by_depth": None if by_depth is None else [  # the last bin's open end as null (JSON has no inf)
                       {**row, "high": row["high"] if math.isfinite(row["high"]) else None} for row in by_depth],
                   "refusal": None if refusals is None else {label: {scope: s["mean"] for scope, s in by.items()}
                                                             for label, by in refusals.items()},
                   "colour": None if colour is None else {f: {scope: s["mean"] for scope, s in by.items()}
                                                          for f, by in colour.items()}}
        sys.stdout.write(json.dumps(payload, default=lambda x: None if not math.isfinite(x) else x) + "\n")
        return 0
    _print_table("oracle", scores)
    print(f"means over {len(truth)} frame(s); peak {args.peak}"
          + (f"; jitter sigma {sigma:.6g}" + (f" (measured on {measured['fill_points']} fill points of "
                                              f"{args.method_result})" if measured else "") if sigma is not None else ""))
    if even is not None:
        print(f"D2 break-even: a complete fill within {even['sigma']:.4g} units ({even['sigma'] / even['spacing']:.3g} "
              f"spacings) RMS of the truth along its normal scores no fill's D2 ({even['none_d2']:.2f} dB, mean over "
              "the frames; jitter oracle, seed "
              f"{args.seed}); farther off, even a complete fill scores less")
    if by_depth is not None:
        print(f"\n{args.method_result}: its fill points' distance to the truth along its normal by their depth (the "
              "distance to the damaged frame), in spacings of each damaged frame, over every frame")
        _print_depth_table(by_depth)
    if refusals is not None:
        print(f"\nrefusal oracle: {args.method_result} as it is, and without its fill points at least the limit off "
              "the truth along its normal (spacings of each damaged frame): what a refusal that knew each fill "
              "point's true error would score")
        _print_table("result", refusals)
    if colour is not None:
        print("\ncolour oracle: the truth's positions, the missing points coloured from the damaged frames by the fill "
              "named (dB; a method colouring with that fill scores about this with perfect geometry)")
        _print_table("colour fill", colour)
    return 0


def _limits(text: str) -> list[float]:
    """``--refusal``'s comma-separated limits, each a finite number > 0."""
    limits = []
    for part in text.split(","):
        try:
            value = float(part)
        except ValueError:
            value = float("nan")
        if not (math.isfinite(value) and value > 0):
            raise UserError(f"--refusal {text}: {part.strip()!r} is no limit; give comma-separated distances > 0 in "
                            "spacings, e.g. 0.5,1")
        limits.append(value)
    return limits


def _colour_scores(args, truth, damaged, masks, regions) -> dict:
    from dpcbench.bench.results.oracle import score_colour_oracles

    for label, seq in ((args.truth, truth), (args.damaged, damaged)):
        if any(c is None for c in seq.colors):
            raise UserError(f"--colour: {label} has frames without colour; give coloured frames or drop --colour")
    return score_colour_oracles(truth.points, truth.colors, damaged.points, damaged.colors, masks=masks,
                                regions=regions)


def _print_depth_table(rows: list[dict]) -> None:
    """`off_surface_by_depth`'s bins, one line each."""
    print("depth (s)   points   off RMS (s)   off p90 (s)")
    for row in rows:
        print(f"{row['low']:>4g}-{row['high']:<5g} {row['points']:>8d}  {row['off_rms']:>12.3f}  {row['off_p90']:>12.3f}")


def _print_table(first: str, scores: dict) -> None:
    """One row per oracle of ``scores`` (name -> scope -> `score_sequence` result), a column per metric and scope."""
    names = list(next(iter(scores.values()))["frame"]["mean"])
    scopes = list(next(iter(scores.values())))
    header = [first] + [f"{n} ({scope})" for scope in scopes for n in names]
    rows = [[v] + [f"{by[scope]['mean'].get(n, float('nan')):.6g}" for scope in scopes for n in names]
            for v, by in scores.items()]
    widths = [max(len(r[c]) for r in [header, *rows]) for c in range(len(header))]
    for row in [header, *rows]:
        print("  ".join([row[0].ljust(widths[0])] + [x.rjust(w) for x, w in zip(row[1:], widths[1:])]))
