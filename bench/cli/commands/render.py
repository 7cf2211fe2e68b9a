"""`dpcbench render PATH_OR_NAME --out FILE.png`: frames side by side, coloured (or shaded by
normals when the frames have no colours), with an optional magnified zoom box; `--holes` paints
the holes red (the removed points of a `dpcbench damage` folder on its ground truth, or the points
inside the regions of a holes.json)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from dpcbench.bench.core.errors import UserError


def register(subparsers) -> None:
    parser = subparsers.add_parser("render", help="draw frames of a sequence side by side into a PNG",
                                   description=__doc__)
    parser.add_argument("source", metavar="PATH_OR_NAME", help="folder / glob / PLY file, or a dataset name")
    parser.add_argument("--out", required=True, help="PNG file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing PNG that dpcbench did not write")
    parser.add_argument("--frames", default=None,
                        help="frame indices: a list (0,6,12), a range (0-3) or one index (5); default: the first 4")
    parser.add_argument("--zoom", default=None, metavar="X0,Y0,Z0,X1,Y1,Z1",
                        help="3D box to magnify in a row under the frames")
    parser.add_argument("--view", default="front", help="front, back, left, right, top, or AZIMUTH,ELEVATION degrees")
    parser.add_argument("--shading", default="auto", choices=("auto", "color", "normal", "shaded"),
                        help="auto: colours when present, else normals; shaded: colours lit by the normals")
    parser.add_argument("--point-size", type=int, default=None, help="splat radius in pixels (default: automatic)")
    parser.add_argument("--height", type=int, default=480, help="panel height in pixels (default 480)")
    parser.add_argument("--holes", default=None, metavar="DIR_OR_FILE",
                        help="paint holes red: a `dpcbench damage` output folder or its masks.npz (render the "
                             "ground truth it was made from: the removed points turn red), or a holes.json "
                             "(the points inside its regions turn red, e.g. the rims found by detect-holes)")
    parser.add_argument("--param", action="append", metavar="K=V", default=[],
                        help="embedded dataset parameter (repeatable; values as in every command: see bench/core/params.py)")
    parser.add_argument("--data-dir", default=None, help="folder holding the paper's sequences")
    parser.set_defaults(func=run)


DEFAULT_FRAMES = 4


def _frame_count(source: str) -> int:
    """Frames available (for the default selection): dataset names have at least DEFAULT_FRAMES."""
    from dpcbench.bench.data.datasets import EMBEDDED, PAPER
    from dpcbench.bench.data.sequences import list_frame_files

    if source.lower() in EMBEDDED or source.lower() in PAPER:
        return DEFAULT_FRAMES
    if not Path(source).exists() and not any(ch in source for ch in "*?["):
        return DEFAULT_FRAMES  # load_dataset explains what is wrong with the name
    return len(list_frame_files(source))


def _numbers(text: str, count: int | None, option: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or (count is not None and len(values) != count):
        raise UserError(f"{option} {text!r}: give {count or 'comma-separated'} numbers separated by commas")
    return values


def run(args) -> int:
    from dpcbench.bench.core.params import parse_params
    from dpcbench.bench.data.datasets import load_dataset, parse_frames
    from dpcbench.bench.data.outputs import Outputs, record_written
    from dpcbench.bench.reporting.render import VIEWS, render_clouds

    frames = parse_frames(args.frames)
    if isinstance(frames, int):
        frames = [frames]  # one number is one frame index here
    if frames is None:
        frames = list(range(min(DEFAULT_FRAMES, _frame_count(args.source))))
    view = args.view if args.view in VIEWS else _numbers(args.view, 2, "--view")
    zoom = _numbers(args.zoom, 6, "--zoom") if args.zoom else None
    if zoom is not None and not all(lo < hi for lo, hi in zip(zoom[:3], zoom[3:])):
        raise UserError(f"--zoom {args.zoom}: give the box as X0,Y0,Z0,X1,Y1,Z1 with each lower corner value "
                        "below the upper one")
    if args.point_size is not None and not 0 <= args.point_size <= 20:
        raise UserError(f"--point-size must be in 0..20 pixels, got {args.point_size}")
    if not 32 <= args.height <= 4000:
        raise UserError(f"--height must be in 32..4000 pixels, got {args.height}")
    guard = Outputs(args.overwrite, inputs=[args.source, args.holes])
    out = guard.file(args.out, "--out", suffixes=(".png",))
    seq = load_dataset(args.source, frames=frames, data_dir=args.data_dir, **parse_params(args.param))
    indices = seq.meta.get("frame_indices") or frames
    titles = [f"{seq.name} frame {i}" for i in indices]
    highlight = _hole_masks(args.holes, seq.points, indices) if args.holes else None
    written = render_clouds(seq.frames, out, titles=titles, zoom=zoom, view=view, shading=args.shading,
                            point_size=args.point_size, panel_height=args.height, highlight=highlight)
    record_written([written])
    print(f"wrote {written} ({len(seq.frames)} frames)")
    return 0


def _hole_masks(source: str, points: list, indices: list[int]) -> list:
    """Per rendered frame the mask of the points to paint red, from a damage folder / masks.npz
    (the removed points: the rendered frames must be the ground truth) or a holes.json (the
    points inside the regions)."""
    from dpcbench.holes.regions import regions_from_json, union_mask

    path = Path(source)
    if path.is_dir():
        path = path / "masks.npz" if (path / "masks.npz").is_file() else path / "holes.json"
    if not path.is_file():
        raise UserError(f"--holes {source}: no such file (give a `dpcbench damage` folder, its masks.npz, "
                        "or a holes.json)")
    if path.suffix == ".npz":
        try:
            with np.load(path) as data:
                masks = {key: data[key] for key in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:  # a corrupt or foreign .npz
            raise UserError(f"--holes {path}: not a readable masks file ({type(err).__name__}: {err}); give the "
                            "masks.npz written by `dpcbench damage`") from None
        out = []
        for i, pts in zip(indices, points):
            mask = masks.get(f"frame_{i:04d}")
            if mask is None:
                raise UserError(f"--holes {path}: has no mask for frame {i} (it has {len(masks)} frames)")
            if mask.shape != (len(pts),):
                raise UserError(f"--holes {path}: frame {i} has {len(pts)} points but its mask {mask.size}; "
                                "render the ground truth the damage was made from, not the damaged frames")
            out.append(mask.astype(bool))
        return out
    regions = regions_from_json(path, label=f"--holes {path}")
    for i in indices:
        if i >= len(regions):
            raise UserError(f"--holes {path}: has no regions for frame {i} (it has {len(regions)} frames)")
    return [union_mask(regions[i], pts) for i, pts in zip(indices, points)]
