"""Processed copies of a real coloured frame for comparing colour PSNR with pc_error (issue 54): a damaged copy, a
filled copy and a recoloured copy, each a deterministic function of the frame (seeded), so a test can rebuild them
and compare with the figures pc_error printed on the same copies (tests/benchmarks/pc_error_compare.py writes them
as PLY files and runs pc_error). Fixtures only, not a test."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the real frames the comparison uses, under ../shared/data
FRAMES = {"longdress": "8i_longdress_1300/longdress_vox10_1300.ply", "ricardo9": "mvub_ricardo9/ricardo9_frame0001.ply"}
#: the copies, in order
KINDS = ("damaged", "filled", "recoloured")


def processed_copies(points: np.ndarray, colours: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """kind -> (points (M, 3) float64, colours (M, 3) uint8) of the frame ``points`` (N, 3) / ``colours`` (N, 3):

    - ``damaged``: medium region holes, seed 21 (`holes` "region", as experiments/one_frame.sh damages a frame);
    - ``filled``: the damaged copy plus every removed point moved by a seeded offset in {-1, 0, 1}^3 voxels (seed 0;
      points landing on a kept or another filled voxel are duplicates, which pc_error averages) with the colour of
      its nearest kept point (the nearest-input colour fill);
    - ``recoloured``: the frame's geometry with each colour channel plus seeded N(0, 6^2) noise (seed 1), rounded
      and clipped to 0..255."""
    from dpcbench.holes.registry import get_generator

    points = np.asarray(points, dtype=np.float64)
    damage = get_generator("region", preset="medium").damage([points], 21, colors=[colours])
    kept, kept_colours, removed = damage.frames[0], damage.colors[0], damage.removed[0]
    lost = points[removed]
    moved = lost + np.random.default_rng(0).integers(-1, 2, lost.shape)
    _, nearest = cKDTree(kept).query(moved, workers=-1)
    noise = np.random.default_rng(1).normal(0.0, 6.0, colours.shape)
    return {
        "damaged": (kept, kept_colours),
        "filled": (np.vstack([kept, moved]), np.vstack([kept_colours, kept_colours[nearest]])),
        "recoloured": (points, np.clip(np.rint(colours + noise), 0, 255).astype(np.uint8)),
    }
