"""`dpcbench info PATH_OR_NAME`: frames, points per frame, bounding box, bit depth or resolution
(median nearest-neighbour spacing), and which attributes (colours, normals) the frames carry."""

from __future__ import annotations

import json

import numpy as np

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    parser = subparsers.add_parser("info", help="describe a sequence (folder of PLY frames or dataset name)",
                                   description=__doc__)
    parser.add_argument("source", metavar="PATH_OR_NAME", help="folder / glob / PLY file, or a dataset name")
    parser.add_argument("--frames", default=None, help="frames to read: a count (10), list (0,5) or range (0-9)")
    parser.add_argument("--param", action="append", metavar="K=V", default=[],
                        help="embedded dataset parameter (repeatable; values as in every command: see bench/core/params.py)")
    parser.add_argument("--data-dir", default=None, help="folder holding the paper's sequences")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.set_defaults(func=run)


def median_spacing(points: np.ndarray, max_queries: int = 20000) -> float:
    """Median distance from a point to its nearest other point (on an evenly strided subset)."""
    from scipy.spatial import cKDTree

    if len(points) < 2:
        return float("nan")
    step = max(1, len(points) // max_queries)
    d, _ = cKDTree(points).query(points[::step], k=2, workers=-1)
    return float(np.median(d[:, 1]))


def describe(seq) -> dict:
    counts = [len(f) for f in seq.frames]
    lo = np.min([f.points.min(0) for f in seq.frames], axis=0)
    hi = np.max([f.points.max(0) for f in seq.frames], axis=0)
    return {
        "name": seq.name,
        "frames": len(seq.frames),
        "points_per_frame": counts,
        "points_min": int(min(counts)), "points_mean": float(np.mean(counts)), "points_max": int(max(counts)),
        "bbox_min": lo.tolist(), "bbox_max": hi.tolist(),
        "bit_depth": seq.bit_depth,
        "median_spacing_frame0": median_spacing(seq.frames[0].points),
        "colors": seq.frames[0].colors is not None,
        "normals": seq.frames[0].normals is not None,
        "precision": "float64" if any(f.precision == "float64" for f in seq.frames) else "float32",
        "files": [str(p) for p in seq.files[:3]] + (["..."] if len(seq.files) > 3 else []),
        "meta": {k: v for k, v in seq.meta.items() if k not in ("description",)},
        "true_motion": getattr(seq, "motion", None) is not None,
    }


def run(args) -> int:
    from dpcbench.bench.core.params import parse_params
    from dpcbench.bench.data.datasets import load_dataset, parse_frames

    seq = load_dataset(args.source, frames=parse_frames(args.frames), data_dir=args.data_dir,
                       **parse_params(args.param))
    if not seq.frames:
        raise UserError(f"{args.source}: the sequence has no frames")
    info = describe(seq)
    if args.json:
        print(json.dumps(info, indent=2, default=str))
        return 0
    counts = info["points_per_frame"]
    shown = ", ".join(str(c) for c in counts[:12]) + (" ..." if len(counts) > 12 else "")
    lo, hi = info["bbox_min"], info["bbox_max"]
    print(f"sequence:    {info['name']}")
    print(f"frames:      {info['frames']}")
    print(f"points:      {info['points_min']}..{info['points_max']} per frame "
          f"(mean {info['points_mean']:.0f}): {shown}")
    print("bbox:        " + " .. ".join("(" + ", ".join(f"{v:.6g}" for v in corner) + ")" for corner in (lo, hi)))
    if info["bit_depth"]:
        print(f"voxelized:   {info['bit_depth']}-bit integer coordinates (0..{2 ** info['bit_depth'] - 1})")
    else:
        print("voxelized:   no (non-integer or negative coordinates)")
    print(f"resolution:  median nearest-neighbour spacing {info['median_spacing_frame0']:.4g} (frame 0)")
    if info["precision"] == "float64":
        print("precision:   double (float64) coordinates, kept as double in what dpcbench writes")
    print(f"attributes:  colours {'yes' if info['colors'] else 'no'}, normals {'yes' if info['normals'] else 'no'}")
    if info["files"]:
        print(f"files:       {', '.join(info['files'])}")
    meta = info["meta"]
    if meta.get("generator") == "mesh":
        print(f"mesh:        {meta['vertices']} vertices, {meta['faces']} faces; "
              f"{'shared connectivity' if meta['shared_connectivity'] else 'connectivity differs between frames'}; "
              f"{meta['samples_per_frame']} surface samples a frame; x_out = {meta['scale']:.6g} x + "
              f"({', '.join(f'{v:.6g}' for v in meta['offset'])})")
        print("motion:      " + ("true point correspondences and scene flow (same surface samples in every frame)"
                                 if info["true_motion"] else "none (frames sampled independently)"))
    for key in ("generator", "params", "dataset", "source", "terms"):
        if key in meta:
            print(f"{key + ':':<13}{meta[key]}")
    return 0
