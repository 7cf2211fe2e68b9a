"""`dpcbench score REFERENCE RESULT`: geometry and colour metrics of a result against its ground truth.

REFERENCE and RESULT are two PLY files or two sequence folders (or globs) with the same number of
frames. Normals stored in the reference PLY are used for D2 (else they are estimated). When both
carry colours, colour PSNR (cpsnr_y, cpsnr_u, cpsnr_v: pc_error's BT.709 Y'CbCr figures) is added to
the default metrics; when only one does, a note says so. Prints a
table (one row per frame and the mean), or with --json the object
{"frames": [{"frame": i, "<metric>": value, ...}], "mean": {...}, "capped": [...], "settings": {...},
"warnings": [...]} (warnings: the one-line notes also printed on stderr, e.g. frames whose regions hold no point)
(NaN, an undefined value, is written as null).
"""

from __future__ import annotations

import json
import math
import sys
from collections import abc

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    from dpcbench.metrics.registry import DEFAULT_METRICS, METRICS

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
    import numpy as np

    import dpcbench.metrics as metrics
    from dpcbench.bench.core.errors import RECORDED, warn
    from dpcbench.bench.data.sequences import load_sequence
    from dpcbench.metrics.registry import METRICS
    from dpcbench.metrics.scoring import DEFAULT_MAX_PSNR

    _return_freed_memory()
    _check_options(args)
    # compact: float32 files stay float32 (the metrics take them as they are: on the integer grid
    # without a float64 copy), half the memory of a frame pair
    # colours are read only when a colour metric may be computed (the defaults, or a cpsnr_* named)
    colours = not args.metrics or any(n.startswith("cpsnr_") for n in args.metrics)
    reference = load_sequence(args.reference, colors=colours, compact=True)
    result = load_sequence(args.result, colors=colours, compact=True)
    if len(reference) != len(result):
        raise UserError(
            f"mismatched frame counts: {args.reference} has {len(reference)} frame(s), {args.result} has "
            f"{len(result)}; score sequences of the same length"
        )
    peak, bit_depth = _peak(args, reference)
    regions, empty = _regions(args, reference)
    names, colour_note = _with_colour_metrics(args, reference, result) if colours else (args.metrics, "not asked")
    ref_colours: abc.Sequence | None = None  # lists of per-frame arrays, or their `_HandOver`
    res_colours: abc.Sequence | None = None
    if any(n.startswith("cpsnr_") for n in names or []):
        ref_colours, res_colours = [f.colors for f in reference.frames], [f.colors for f in result.frames]
    normals: abc.Sequence = [f.normals for f in reference.frames]
    given_normals = any(n is not None for n in normals)
    ref_points: abc.Sequence = reference.points
    res_points: abc.Sequence = result.points
    if not any(METRICS[n].level == "sequence" for n in (args.metrics or [])):
        # every frame is used once: hand each over to the metrics and forget it here, so that a scored
        # frame's coordinates are freed as soon as its pair holds what it needs (on the integer grid:
        # packed keys, a third of a float32 frame); see metrics.scoring.score_sequence
        ref_points, res_points, normals = _HandOver(ref_points), _HandOver(res_points), _HandOver(normals)
        if ref_colours is not None:
            ref_colours, res_colours = _HandOver(ref_colours), _HandOver(res_colours)
        reference.frames.clear()
        result.frames.clear()
    options = {"max_psnr": DEFAULT_MAX_PSNR if args.max_psnr is None else args.max_psnr, "workers": args.jobs}
    if args.fscore_threshold is not None:
        options["fscore_threshold"] = args.fscore_threshold
    if bit_depth is not None:
        options["bit_depth"] = bit_depth
    scores = metrics.score_sequence(
        ref_points, res_points, names, peak=peak,
        reference_normals=normals if given_normals else None,
        regions=regions, region_margin=args.region_margin,
        reference_colours=ref_colours, result_colours=res_colours, **options,
    )
    scores["settings"] = {
        "reference": args.reference,
        "result": args.result,
        "peak": peak if bit_depth is None else f"bitdepth:{bit_depth}",
        "scope": "holes" if regions is not None else "frame",
        "region_margin": args.region_margin if regions is not None else None,
        "reference_normals": "given" if given_normals else "estimated",
        "colour": colour_note,
    }
    undefined = sorted({k for f in scores["frames"] for k, v in f.items()
                        if k != "frame" and isinstance(v, float) and np.isnan(v)})
    if undefined and not empty:
        warn(f"undefined (NaN) values of {', '.join(undefined)} in some frames; they are left out of the mean")
    scores["warnings"] = list(RECORDED)
    if args.json:
        sys.stdout.write(json.dumps(_clean(scores)) + "\n")
        return 0
    _print_table(scores)
    return 0


def _check_options(args) -> None:
    """Refuse option values that cannot mean anything (before any file is read)."""
    if not (args.jobs >= 1 or args.jobs == -1):
        raise UserError(f"--jobs {args.jobs}: give a positive number of threads, or -1 for all cores")
    if not (math.isfinite(args.region_margin) and args.region_margin >= 0):
        raise UserError(f"--region-margin {args.region_margin:g}: must be a distance >= 0 (coordinate units); "
                        "a negative margin would shrink the regions and score nothing")
    if args.region_margin and not args.region:
        raise UserError("--region-margin: only used with --region HOLES_JSON")
    if args.fscore_threshold is not None and not (math.isfinite(args.fscore_threshold) and args.fscore_threshold > 0):
        raise UserError(f"--fscore-threshold {args.fscore_threshold:g}: must be a positive distance")
    if args.max_psnr is not None and not args.max_psnr > 0:
        raise UserError(f"--max-psnr {args.max_psnr:g}: must be a positive number of dB (or inf)")


def _peak(args, reference) -> tuple[str, int | None]:
    """(the --peak text, the reference's bit depth when the peak is ``bitdepth`` alone); a peak that is
    neither ``intrinsic`` nor a finite distance up to the coordinate limit is refused."""
    from dpcbench.metrics.geometry import resolve_peak

    peak = args.peak
    bit_depth = None
    if peak.strip().lower() == "bitdepth":
        if reference.bit_depth is None:
            raise UserError(
                f"--peak bitdepth: {args.reference} is not voxelized (non-integer coordinates), so it has no bit "
                "depth; give it explicitly (--peak bitdepth:10) or use a number"
            )
        bit_depth = reference.bit_depth
    elif peak.strip().lower() != "intrinsic":
        try:
            value = resolve_peak(peak, None, None)  # parses the text: its ValueError is a refusal of --peak
        except ValueError as err:
            raise UserError(f"--peak {peak}: {err}") from None
        from dpcbench.holes.regions import COORD_LIMIT

        if not (math.isfinite(value) and value <= COORD_LIMIT):
            raise UserError(f"--peak {peak}: must be a finite distance up to {COORD_LIMIT:g} (a larger peak puts every "
                            "PSNR above the cap, as if the clouds were identical)")
    return peak, bit_depth


def _regions(args, reference) -> tuple[list | None, list[int]]:
    """(the --region regions per frame or None, the frames whose regions hold no reference point); a
    holes.json whose regions hold no reference point in any frame is refused."""
    from dpcbench.bench.core.errors import warn

    empty: list[int] = []
    regions = None
    if args.region:
        from dpcbench.holes.regions import regions_from_json, union_mask

        regions = regions_from_json(args.region, frame_count=len(reference), label=f"--region {args.region}")
        from dpcbench.bench.data.sequences import check_regions_frames

        check_regions_frames(args.region, reference, f"--region {args.region}")
        empty = [i for i, (frame, regs) in enumerate(zip(reference.frames, regions))
                 if regs and not union_mask(regs, frame.points, args.region_margin).any()]
        holeless = [i for i, regs in enumerate(regions) if not regs]
        if len(empty) + len(holeless) == len(regions):
            why = "; ".join(part for part in (
                f"the regions of frame(s) {_frames(empty)} contain none" if empty else "",
                f"frame(s) {_frames(holeless)} have no region" if holeless else "") if part)
            raise UserError(
                f"--region {args.region}: no frame has a reference point inside its regions ({why}), so there is "
                "nothing to score; use the holes.json made for this reference (or grow --region-margin)")
        if empty:
            warn(f"--region {args.region}: the regions of frame(s) {_frames(empty)} contain no reference point, so "
                 "their in-hole scores are undefined (NaN) and left out of the mean; is this the holes.json made "
                 "for this reference?")
    return regions, empty


def _with_colour_metrics(args, reference, result) -> tuple[list[str] | None, str]:
    """(metric names to compute, a note on colour). Without --metric: the default metrics, plus the
    colour PSNRs (`DEFAULT_COLOUR_METRICS`) when both sequences carry colours; a note (also a warning
    when exactly one has colours) says when they are left out. A colour metric named with --metric on
    a sequence without colours is refused."""
    from dpcbench.bench.core.errors import warn
    from dpcbench.metrics.registry import DEFAULT_COLOUR_METRICS, DEFAULT_METRICS

    missing = [label for label, seq in (("reference", reference), ("result", result)) if seq.frames[0].colors is None]
    asked = [n for n in (args.metrics or []) if n.startswith("cpsnr_")]
    if asked and missing:
        which = " and ".join(f"the {m} ({args.reference if m == 'reference' else args.result})" for m in missing)
        raise UserError(f"--metric {asked[0]}: {which} has no colours (red/green/blue); colour PSNR needs colours "
                        "on both; drop the cpsnr_* metrics")
    if not missing:
        names = args.metrics if args.metrics else [*DEFAULT_METRICS, *DEFAULT_COLOUR_METRICS]
        return names, "both clouds have colours" + ("" if any(n.startswith("cpsnr_") for n in names)
                                                     else " (no colour metric asked)")
    if len(missing) == 2:
        return args.metrics, "none (neither cloud has colours)"
    note = f"no colour PSNR: the {missing[0]} has no colours"
    if not args.metrics:
        warn(f"{note} ({args.reference if missing[0] == 'reference' else args.result}); geometry metrics only")
    return args.metrics, note


def _return_freed_memory() -> None:
    """Have glibc serve every allocation of 1 MiB or more by its own memory map, given back to the
    system when freed. By default glibc raises that threshold (up to 32 MiB) after the first large
    free and then serves large numpy temporaries from its heap, whose freed blocks it keeps: on the
    858k-point Longdress pair that was 4-5 MiB of peak memory held and unused (68 -> 64 MiB for D1,
    78 -> 74 MiB for D1 + D2, same time). No effect where the C library is not glibc."""
    import ctypes

    try:
        ctypes.CDLL(None).mallopt(-3, 1 << 20)  # M_MMAP_THRESHOLD (glibc's malloc.h): fixed, 1 MiB
    except (OSError, AttributeError):  # not glibc: nothing to tune
        pass


class _HandOver(abc.Sequence):
    """A list whose items are forgotten once read (``seq[i]`` returns the item and drops it): frames
    handed to `metrics.score_sequence`, which reads each frame once, so that this list does not keep
    them alive while they are scored."""

    def __init__(self, items):
        self._items = list(items)

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, i):  # iterating reads (and drops) every item too
        item, self._items[i] = self._items[i], None
        return item


def _cell(value) -> str:
    return "NaN" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)


def _frames(indices: list[int]) -> str:
    shown = ", ".join(str(i) for i in indices[:8])
    return (shown + (" ..." if len(indices) > 8 else "")) if indices else "none"


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
    """One row per frame (and the mean when there are several), values as ``{:.6g}``. Formatted by
    hand rather than with pandas: importing pandas alone costs ~30 MiB and 0.3 s, more than the rest
    of an integer-grid `score` run needs."""
    frames = scores["frames"]
    names = [k for k in (frames[0] if frames else {}) if k != "frame"]
    rows = [[str(f["frame"])] + [_cell(f.get(n)) for n in names] for f in frames]
    if len(rows) > 1:
        rows.append(["mean"] + [_cell(scores["mean"].get(n)) for n in names])
    header = ["frame"] + names
    widths = [max(len(r[c]) for r in [header, *rows]) for c in range(len(header))]
    for row in [header, *rows]:
        print("  ".join([row[0].ljust(widths[0])] + [v.rjust(w) for v, w in zip(row[1:], widths[1:])]))
    for name, value in scores.get("sequence", {}).items():
        print(f"{name} (sequence): {value:.6g}")
    settings = scores["settings"]
    print(f"peak: {settings['peak']}; scope: {settings['scope']}; reference normals: {settings['reference_normals']}; "
          f"colour: {settings['colour']}")
    if scores["capped"]:
        print(f"note: {len(scores['capped'])} PSNR value(s) of identical clouds capped (see --max-psnr)")
