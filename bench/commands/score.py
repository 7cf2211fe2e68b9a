"""`dpcbench score REFERENCE RESULT`: geometry metrics of a result against its ground truth.

REFERENCE and RESULT are two PLY files or two sequence folders (or globs) with the same number of
frames. Normals stored in the reference PLY are used for D2 (else they are estimated). Prints a
table (one row per frame and the mean), or with --json the object
{"frames": [{"frame": i, "<metric>": value, ...}], "mean": {...}, "capped": [...], "settings": {...}}
(NaN, an undefined value, is written as null).
"""

from __future__ import annotations

import json
import math
import sys

from bench.errors import UserError


def register(subparsers) -> None:
    from metrics.registry import DEFAULT_METRICS, METRICS

    parser = subparsers.add_parser(
        "score",
        help="score a result (PLY file or sequence folder) against the reference: GPSNR, NSHD, ...",
        description=__doc__.split("\n", 2)[2] if __doc__ else None,
    )
    parser.add_argument("reference", help="ground-truth PLY file, or folder / glob of PLY frames")
    parser.add_argument("result", help="result PLY file, or folder / glob of PLY frames")
    parser.add_argument("--metric", action="append", dest="metrics", metavar="NAME", choices=list(METRICS),
                        help=f"metric to compute (repeatable; default: {' '.join(DEFAULT_METRICS)}); "
                             f"available: {', '.join(METRICS)}")
    parser.add_argument("--peak", default="intrinsic",
                        help="PSNR peak: 'intrinsic' (pc_error's default: largest nearest-neighbour distance in the "
                             "reference), 'bitdepth:B' (2^B - 1; 'bitdepth' alone uses the reference's bit depth), "
                             "or a number such as 1023 (default: intrinsic)")
    parser.add_argument("--region", metavar="HOLES_JSON", default=None,
                        help="holes.json with the hole regions per frame: score only inside them")
    parser.add_argument("--region-margin", type=float, default=0.0,
                        help="grow the regions by this distance (coordinate units; default 0)")
    parser.add_argument("--fscore-threshold", type=float, default=None,
                        help="F-score distance threshold (default: 2 x median point spacing of the reference)")
    parser.add_argument("--max-psnr", type=float, default=None,
                        help="cap for infinite PSNRs of identical clouds, in dB (default 200)")
    parser.add_argument("--jobs", type=int, default=-1, metavar="N",
                        help="threads for the nearest-neighbour queries (default -1: all cores); the values do not "
                             "depend on it")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(func=run)


def run(args) -> int:
    import metrics
    from metrics.scoring import DEFAULT_MAX_PSNR

    from bench.sequences import load_sequence

    if not (args.jobs >= 1 or args.jobs == -1):
        raise UserError(f"--jobs {args.jobs}: give a positive number of threads, or -1 for all cores")
    reference = load_sequence(args.reference, colors=False)
    result = load_sequence(args.result, colors=False)
    if len(reference) != len(result):
        raise UserError(
            f"mismatched frame counts: {args.reference} has {len(reference)} frame(s), {args.result} has "
            f"{len(result)}; score sequences of the same length"
        )
    peak = args.peak
    bit_depth = None
    if peak.strip().lower() == "bitdepth":
        if reference.bit_depth is None:
            raise UserError(
                f"--peak bitdepth: {args.reference} is not voxelized (non-integer coordinates), so it has no bit "
                "depth; give it explicitly (--peak bitdepth:10) or use a number"
            )
        bit_depth = reference.bit_depth
    regions = None
    if args.region:
        from holes.regions import regions_from_json

        try:
            regions = regions_from_json(args.region)
        except FileNotFoundError:
            raise UserError(f"{args.region}: no such holes file") from None
        except (ValueError, KeyError, TypeError) as err:
            raise UserError(f"{args.region}: not a valid holes.json ({err})") from None
        if len(regions) != len(reference):
            raise UserError(
                f"{args.region} describes {len(regions)} frame(s) but the sequences have {len(reference)}; "
                "use the holes.json written with this damaged sequence"
            )
    normals = [f.normals for f in reference.frames]
    options = {"max_psnr": DEFAULT_MAX_PSNR if args.max_psnr is None else args.max_psnr, "workers": args.jobs}
    if args.fscore_threshold is not None:
        options["fscore_threshold"] = args.fscore_threshold
    if bit_depth is not None:
        options["bit_depth"] = bit_depth
    try:
        scores = metrics.score_sequence(
            reference.points, result.points, args.metrics, peak=peak,
            reference_normals=None if all(n is None for n in normals) else normals,
            regions=regions, region_margin=args.region_margin, **options,
        )
    except (ValueError, KeyError) as err:
        raise UserError(str(err).strip("'\"")) from None
    scores["settings"] = {
        "reference": args.reference,
        "result": args.result,
        "peak": peak if bit_depth is None else f"bitdepth:{bit_depth}",
        "scope": "holes" if regions is not None else "frame",
        "region_margin": args.region_margin if regions is not None else None,
        "reference_normals": "given" if any(n is not None for n in normals) else "estimated",
    }
    if args.json:
        sys.stdout.write(json.dumps(_clean(scores)) + "\n")
        return 0
    _print_table(scores)
    return 0


def _clean(obj):
    """The object with NaN (undefined) and +-inf (only with --max-psnr inf) replaced by None, so that
    the JSON is standard."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_clean(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _print_table(scores: dict) -> None:
    import pandas as pd

    table = pd.DataFrame(scores["frames"]).set_index("frame")
    if len(table) > 1:
        table.loc["mean"] = pd.Series(scores["mean"])
    with pd.option_context("display.max_columns", None, "display.width", 160, "display.float_format", "{:.6g}".format):
        print(table.to_string())
    for name, value in scores.get("sequence", {}).items():
        print(f"{name} (sequence): {value:.6g}")
    settings = scores["settings"]
    print(f"peak: {settings['peak']}; scope: {settings['scope']}; reference normals: {settings['reference_normals']}")
    if scores["capped"]:
        print(f"note: {len(scores['capped'])} PSNR value(s) of identical clouds capped (see --max-psnr)")
