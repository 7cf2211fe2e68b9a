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

Two more candidates that temporal-fusion does not have, with ``--extra``, each under the same hold-out:
- ``mirror``: the frame's bilateral mirror image (the reflection across the PCA plane through the centroid whose
  ICP fit to the frame is best: the least RMS over the pairs within 10 spacings per share paired), its part round
  the hole aligned onto the hole's rim by ICP (`methods._geometry.icp_align`, `MirrorPatch`): a person's or an
  animal's other side;
- ``nonlocal``: fu-nonlocal's fill of the hole from the rest of the frame (its cubes' most similar cube elsewhere,
  Hu et al.), the frame round the crop kept as it is.

With ``--capacity``, for each hole whose rim is a height field: the heights' RMS miss at the hidden truth points of
the rim's thin-plate spline (`rim_surface_fill`'s frame, kernel and smoothing) and of the same spline fitted to the
rim and the hidden truth points together: the first is what the rim tells of the hidden surface, the second what the
spline could represent. Where the second is small and the first large, the hole hides a shape its rim does not show
(a dent, a fold, a limb's end).

Usage (after `dpcbench damage TRUTH --out DAMAGED ...`):

    .venv/bin/python experiments/candidate_accuracy.py TRUTH DAMAGED [--frames 0] [--break-even]
        [--extra mirror,nonlocal] [--capacity]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from fill_audit import truth_frames
from scipy.spatial import cKDTree

from dpcbench.bench.data.plyio import read_ply
from dpcbench.methods._geometry import icp_align, sampling_step
from dpcbench.methods._spatial_fill.best import candidates, holdout_miss
from dpcbench.methods._spatial_fill.cap import cap_fill
from dpcbench.methods._spatial_fill.common import SURFACE_POINTS
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


class MirrorPatch:
    """The ``mirror`` candidate (module docstring) of one damaged frame (N, 3) with spacing ``spacing``."""

    def __init__(self, damaged: np.ndarray, spacing: float) -> None:
        self.spacing = spacing
        centre = damaged.mean(axis=0)
        sample = damaged[:: max(1, len(damaged) // 30000)]
        sample_tree, reach = cKDTree(sample), 10 * spacing
        best = None
        for axis in np.linalg.svd(damaged - centre, full_matrices=False)[2]:
            reflection = np.eye(3) - 2.0 * np.outer(axis, axis)
            reflected = (sample - centre) @ reflection.T + centre
            rotation, translation = icp_align(reflected, sample, reach, max_iterations=60)
            # the fit's RMS over the pairs within reach, per share of the sample paired (open3d's inlier RMSE / fitness)
            distance = sample_tree.query(reflected @ rotation.T + translation, distance_upper_bound=reach)[0]
            paired = np.isfinite(distance)
            cost = np.sqrt(np.mean(distance[paired] ** 2)) / max(paired.mean(), 1e-3) if paired.any() else np.inf
            if best is None or cost < best[0]:
                best = (cost, reflection, rotation, translation)
        _, reflection, rotation, translation = best
        self.mirrored = ((damaged - centre) @ reflection.T + centre) @ rotation.T + translation
        self.tree = cKDTree(self.mirrored)

    def candidate(self, crop: np.ndarray, region, shell: float):
        """(support, fill): the mirror image's points within the crop's reach of ``region``, aligned on what of the
        support lies outside the region, kept inside it and off ``covered``."""

        def fill(support, region, covered):
            rim = support[~region.contains(support)]
            patch = self.mirrored[self.tree.query_ball_point(region.center, region.bounding_radius + 2 * shell)]
            if len(rim) < 12 or len(patch) < 12:
                return np.zeros((0, 3))
            rotation, translation = icp_align(patch, rim, 3 * self.spacing, max_iterations=60)
            moved = patch @ rotation.T + translation
            moved = moved[region.contains(moved)]
            return moved if covered is None else moved[covered.query(moved)[0] > self.spacing]

        return crop, fill


def nonlocal_candidate(damaged: np.ndarray, crop_rows: np.ndarray, crop: np.ndarray, region, spacing: float):
    """(support, fill): the ``nonlocal`` candidate (module docstring); ``crop_rows`` the rows of ``damaged`` the crop
    holds. The fill's region grown by the hold-out's ring is a ball of the grown radius."""
    import dataclasses

    from dpcbench.methods.registry import get_method

    rest = np.delete(damaged, crop_rows, axis=0)

    def fill(support, grown, covered):
        frame = np.vstack([rest, support])
        margin = getattr(grown, "margin", 0.0)
        hole = region if not margin else dataclasses.replace(region, radius=region.radius + margin)
        out = get_method("fu-nonlocal").inpaint([frame], [[hole]])[0]
        new = out[cKDTree(frame).query(out)[0] > 1e-6 * spacing]  # its output keeps no row order: new by position
        new = new[grown.contains(new)]
        return new if covered is None else new[covered.query(new)[0] > spacing]

    return crop, fill


def capacity_line(rim: np.ndarray, hidden: np.ndarray, spacing: float) -> str:
    """``--capacity``'s line for one hole (module docstring)."""
    from dpcbench.methods._spatial_fill.common import MAX_STEEP, even_subset, fit_height_field
    from dpcbench.methods._spatial_fill.spline import height_spline

    if len(rim) < 12 or not len(hidden):
        return "  capacity: too few points"
    centre, axes, _, _, steep = fit_height_field(rim)
    if steep > MAX_STEEP:
        return f"  capacity: the rim is no height field ({steep:.0%} steep normals)"

    def heights_miss(known: np.ndarray) -> float:
        known = even_subset(known, SURFACE_POINTS)
        uv, h = (known - centre) @ axes[:2].T / spacing, (known - centre) @ axes[2] / spacing
        spline = height_spline(uv, h)
        at = (hidden - centre) @ axes[:2].T / spacing
        return float(np.sqrt(np.mean((spline(at) - (hidden - centre) @ axes[2] / spacing) ** 2)))

    return (f"  capacity: the rim's spline misses the hidden heights by {heights_miss(rim):.2f} s RMS, "
            f"the same spline fitted with them by {heights_miss(np.vstack([rim, hidden])):.2f} s")


def frame_lines(truth: np.ndarray, truth_normals: np.ndarray | None, damaged: np.ndarray, regions,
                extra: tuple[str, ...] = (), capacity: bool = False) -> list[str]:
    """The report lines of one frame (module docstring)."""
    integer = np.array_equal(damaged, np.round(damaged))
    spacing = 1.0 if integer else point_spacing(damaged)
    step = spacing if integer else sampling_step(damaged)
    tree, truth_tree = cKDTree(damaged), cKDTree(truth)
    normals = truth_normals if truth_normals is not None else estimate_normals(truth, 12)
    mirror = MirrorPatch(damaged, spacing) if "mirror" in extra else None
    lines = []
    for k, region in enumerate(regions):
        crop, shell, surfaces = region_candidates(damaged, tree, region, spacing, step, integer)
        if mirror is not None:
            surfaces["mirror"] = mirror.candidate(crop, region, shell)
        if "nonlocal" in extra:
            rows = np.asarray(tree.query_ball_point(region.center, region.bounding_radius + 2 * shell), dtype=np.int64)
            surfaces["nonlocal"] = nonlocal_candidate(damaged, rows, crop, region, spacing)
        hidden = truth[region.contains(truth) & (tree.query(truth)[0] > 1e-6 * spacing)]
        lines.append(f"region {k} ({np.round(region.center, 1).tolist()}, r {region.bounding_radius:.1f}): "
                     f"{len(hidden)} hidden points")
        if capacity:
            lines.append(capacity_line(crop[region.contains(crop, margin=shell)], hidden, spacing))
        for name, (support, fill) in surfaces.items():
            points = fill(support, region, cKDTree(crop))
            if not len(points):
                lines.append(f"  {name:8s} adds nothing")
                continue
            _, nearest = truth_tree.query(points)
            off = np.einsum("ij,ij->i", points - truth[nearest], normals[nearest]) / spacing
            covered = np.mean(cKDTree(points).query(hidden)[0] <= 2 * spacing) if len(hidden) else 1.0
            miss = "     –" if name == "cap" else f"{holdout_miss((support, fill), region, shell / 2) / spacing:6.2f}"
            lines.append(f"  {name:8s} {len(points):6d} points  hold-out miss {miss} s  off the truth "
                         f"{np.sqrt(np.mean(off ** 2)):6.2f} s RMS  hidden covered {covered:4.0%}")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the undamaged frames: a PLY file or a folder of PLY frames")
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--frames", default="0", help="comma-separated frames (default 0)")
    parser.add_argument("--break-even", action="store_true", help="also the frames' D2 break-even")
    parser.add_argument("--extra", default="", help="comma-separated candidates to add: mirror, nonlocal")
    parser.add_argument("--capacity", action="store_true", help="also the rim's spline against the same spline "
                        "fitted with the hidden truth")
    args = parser.parse_args(argv)
    extra = tuple(name for name in args.extra.split(",") if name)
    unknown = set(extra) - {"mirror", "nonlocal"}
    if unknown:
        parser.error(f"unknown --extra candidate(s) {sorted(unknown)}; use mirror, nonlocal")
    loaded = load_damage_or_exit(args.damaged)
    _, frames, regions = loaded
    files = truth_frames(args.truth, args.damaged)
    for f in (int(x) for x in args.frames.split(",")):
        cloud = read_ply(files[f])
        truth = np.asarray(cloud.points, dtype=np.float64)
        print(f"frame {f}")
        print("\n".join(frame_lines(truth, cloud.normals, frames[f], regions[f], extra, args.capacity)))
        if args.break_even:
            from dpcbench.bench.results.oracle import d2_break_even

            even = d2_break_even([truth], [frames[f]], reference_normals=[cloud.normals])
            print(f"D2 break-even: {even['sigma'] / even['spacing']:.2f} s (no fill's D2 {even['none_d2']:.2f} dB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
