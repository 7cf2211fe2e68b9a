"""How far off the truth each spatial surface temporal-fusion has would fill each hole of a damaged frame.

For every hole region of the chosen frames of a `dpcbench damage` folder, each candidate surface of the last resort
(`methods._spatial_fill.best.candidates`: the rim's spline, the same on the hole's own sheet, the crop's screened
Poisson surface; none with its refusal tests) fills the region from the damaged frame alone, as the last resort
sees it (crop and rim as temporal-fusion's stage crop takes them). On voxelized input the harmonic cap (step 6d,
`cap_fill` on the crop) is shown too, with its own loop test, as the cascade runs it ("adds nothing" where the
test refuses the loop; no hold-out miss: the cap spans a loop, which a held-out ring would cut).

Per candidate it prints the points it adds, its hold-out miss (the last resort's predicted error, in spacings), its
true off-surface error (RMS point-to-plane distance of its points to the truth, the truth's PLY normals or PCA normals
of 12 neighbours; in spacings), and the share of the hidden truth points with a fill point within 2 spacings. With
``--break-even`` it also prints the frame's D2 break-even (`bench.results.oracle.d2_break_even`): a fill whose
off-surface error exceeds it cannot score no fill's D2 even where it is complete.

Usage (after `dpcbench damage TRUTH --out DAMAGED ...`):

    .venv/bin/python experiments/candidate_accuracy.py TRUTH DAMAGED [--frames 0] [--break-even]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from fill_audit import truth_frames
from scipy.spatial import cKDTree

from dpcbench.bench.data.plyio import read_ply
from dpcbench.methods._geometry import sampling_step
from dpcbench.methods._spatial_fill.best import candidates, holdout_miss
from dpcbench.methods._spatial_fill.cap import cap_fill
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.metrics.neighbours import estimate_normals, point_spacing


def region_candidates(damaged: np.ndarray, tree: cKDTree, region, spacing: float, step: float, integer: bool):
    """(crop (K, 3), shell, the candidate surfaces by name) of one hole ``region`` of a damaged frame, as the last
    resort builds them (crop and rim as temporal-fusion's stage crop takes them)."""
    cfg = FusionConfig()
    shell = cfg.shell(region, spacing)
    crop = damaged[np.asarray(tree.query_ball_point(region.center, region.bounding_radius + 2 * shell,
                                                    return_sorted=True), dtype=np.int64)]
    rim = crop[region.contains(crop, margin=shell)]
    surfaces = candidates(rim, crop, region, spacing, voxelized=integer, step=step, gap_spacings=cfg.fill_gap_spacings,
                          ring=shell / 2)
    if integer and cfg.cap:
        def cap(support, region, covered):
            return cap_fill(support, region, covered, spacing, voxelized=True, step=step,
                            gap_spacings=cfg.fill_gap_spacings, harmonic=cfg.harmonic_cap)

        surfaces["cap"] = (crop, cap)
    return crop, shell, surfaces


def frame_lines(truth: np.ndarray, truth_normals: np.ndarray | None, damaged: np.ndarray, regions) -> list[str]:
    """The report lines of one frame (module docstring)."""
    integer = np.array_equal(damaged, np.round(damaged))
    spacing = 1.0 if integer else point_spacing(damaged)
    step = spacing if integer else sampling_step(damaged)
    tree, truth_tree = cKDTree(damaged), cKDTree(truth)
    normals = truth_normals if truth_normals is not None else estimate_normals(truth, 12)
    lines = []
    for k, region in enumerate(regions):
        crop, shell, surfaces = region_candidates(damaged, tree, region, spacing, step, integer)
        hidden = truth[region.contains(truth) & (tree.query(truth)[0] > 1e-6 * spacing)]
        lines.append(f"region {k} ({np.round(region.center, 1).tolist()}, r {region.bounding_radius:.1f}): "
                     f"{len(hidden)} hidden points")
        for name, (support, fill) in surfaces.items():
            points = fill(support, region, cKDTree(crop))
            if not len(points):
                lines.append(f"  {name:7s} adds nothing")
                continue
            _, nearest = truth_tree.query(points)
            off = np.einsum("ij,ij->i", points - truth[nearest], normals[nearest]) / spacing
            covered = np.mean(cKDTree(points).query(hidden)[0] <= 2 * spacing) if len(hidden) else 1.0
            miss = "     –" if name == "cap" else f"{holdout_miss((support, fill), region, shell / 2) / spacing:6.2f}"
            lines.append(f"  {name:7s} {len(points):6d} points  hold-out miss {miss} s  off the truth "
                         f"{np.sqrt(np.mean(off ** 2)):6.2f} s RMS  hidden covered {covered:4.0%}")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the undamaged frames: a PLY file or a folder of PLY frames")
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--frames", default="0", help="comma-separated frames (default 0)")
    parser.add_argument("--break-even", action="store_true", help="also the frames' D2 break-even")
    args = parser.parse_args(argv)
    loaded = load_damage_or_exit(args.damaged)
    _, frames, regions = loaded
    files = truth_frames(args.truth, args.damaged)
    for f in (int(x) for x in args.frames.split(",")):
        cloud = read_ply(files[f])
        truth = np.asarray(cloud.points, dtype=np.float64)
        print(f"frame {f}")
        print("\n".join(frame_lines(truth, cloud.normals, frames[f], regions[f])))
        if args.break_even:
            from dpcbench.bench.results.oracle import d2_break_even

            even = d2_break_even([truth], [frames[f]], reference_normals=[cloud.normals])
            print(f"D2 break-even: {even['sigma'] / even['spacing']:.2f} s (no fill's D2 {even['none_d2']:.2f} dB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
