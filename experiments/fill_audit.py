"""Which stage of temporal-fusion put each new point where it is, and what each stage costs in D1 and D2.

Runs `TemporalFusion.inpaint` on a `dpcbench damage` folder with every stage wrapped (nothing in the method is
changed: the wrappers record what each stage returns), attributes each new output point to the stage whose
returned point lies nearest it (within 1.5 spacings: the surface projection and the voxel snapping move points by
less), and scores every output point with the exact metric's per-point errors (`metrics.pairs.CloudPair`, pc_error's
conventions; reference normals from the truth's PLY, else estimated as `dpcbench score` does).

Per frame it prints whole-frame D1 / D2 of the result and of no fill, and per stage:
- points: new output points attributed to it;
- off RMS: RMS point-to-plane distance of those points to the truth (in spacings), and the share > 2 spacings;
- BA2: their summed point-to-plane errors against the truth (the result-to-reference term of D2);
- with ``--by-depth``, each stage's off RMS by depth: its points' distance to the damaged frame's nearest point, in
  spacings (`DEPTH_EDGES`), so a fill that is right at the rim and drifts off the surface farther in shows;
- for each hole region, AB1 / AB2 (the reference-to-result terms of D1 / D2 over the region's truth points) of the
  result against the open hole's, so a region whose fill costs more D2 than leaving it open shows;
- with ``--left-open``, for each hole region the whole-frame D1 / D2 of the result with that region's new points
  taken out (those within 2 spacings of it, as above): what leaving that one hole open would score, the rest
  filled. A refusal rule can reach D2 at or above no fill only where this shows it, and this shows its D1 cost;
- with ``--against M1,M2``, each region's AB1 of those methods' results too;
- with ``--last-resort-where-covered``, the method with its last resort (`spatial.BestSurface`) run also in a region
  that copies, the reused fill or partial copies cover in part (the method's own test asks for an emptied region);
- with ``--last-resort-in-boxes``, the method with its last resort run in every occlusion box too, filling what the
  strategies before it left open there (`last_resort_in_boxes`; measured, not kept);
- with ``--closed-surface-band bound|last-resort``, the method with its closed surface (`spatial.ClosedSurface`)
  judged in an occlusion box by the band of captured points bordering its fill rather than by the ring round the
  whole box, and kept where that hold-out passes the method's bound, or with ``last-resort`` also where it misses by
  less than the open part's predicted error (the last resort's rule) (`closed_surface_band`; measured, not kept); one
  line per box judged;
- with ``--membrane-height-field``, the method with its membrane a height field over its seeds' plane
  (`membrane_height_field`; measured, not kept);
- with ``--thin-gaps``, for each thin gap that a frame saw whole, its best copy's rim residual, the rim fill's
  hold-out miss and which of them fills it (stage rim fill's decision, `rim_fill.copy_beats_growth`); with
  ``--thin-gaps-by-scatter`` the method run with version 54's rule there instead (measured, not kept);
- with ``--last-resort``, for each hole the cascade's last resort judged (`spatial.BestSurface`), each candidate
  surface's points, hold-out miss and predicted open error (its rule, `methods._spatial_fill.best`), its points' true
  RMS point-to-plane distance to the truth and share > 2 spacings, and which candidate filled;
- with ``--depth-limit``, the whole-frame D1 / D2 with the spatial stages' new points and the reused fill (in a hole
  no frame saw, the spatial fill of the frame before, moved) kept only up to each depth of `DEPTH_LIMITS` (their
  distance to the damaged frame, in spacings), the other new points all kept: a refusal by depth, which the method could make without the truth (`depth_limit_lines`; the points are taken out of the
  result, not refused inside the method, so nothing after them is rerun);
- with ``--thin``, the whole-frame D1 / D2 with the spatial stages' new points and the reused fill thinned to one
  point a cubic cell of the damaged frame's sampling step (`thinned_lines`; measured, not kept);
- with ``--refusal-oracle``, the whole-frame D1 / D2 of the result keeping only the new points whose own
  point-to-plane error (the BA2 term above, from the truth) is under each of `ORACLE_LIMITS` spacings: what a refusal
  that knew every fill point's true error could reach, point by point, with the fills the method has. Where no
  limit gives D1 at least 1 dB over the best of the ``--against`` methods' and D2 at or above no fill's, no refusal rule (per hole or per
  point) meets both targets on that frame: it takes a closer surface. Beside it, the same for a refusal the method
  could make without the truth: each new point's disagreement, the largest point-to-plane distance from it to the
  candidate surfaces of the last resort that reach within 2 spacings of it (`candidate_accuracy.region_candidates`;
  the plane through its nearest candidate point, normal the PCA normal of its 6 nearest), new points with no
  candidate near kept; points whose disagreement is over
  each of `ORACLE_LIMITS` spacings refused.

Usage (after `dpcbench damage TRUTH --out DAMAGED ...`):

    .venv/bin/python experiments/fill_audit.py TRUTH DAMAGED [--frames 0,1] [--left-open] [--param name=value ...]
        [--against METHOD[,METHOD...]] [--refusal-oracle] [--last-resort-where-covered] [--thin-gaps]
        [--thin-gaps-by-scatter] [--last-resort] [--last-resort-in-boxes] [--closed-surface-band RULE]
        [--membrane-height-field] [--by-depth] [--depth-limit] [--thin]
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from _damaged import load_damage_or_exit  # the sibling module; these scripts run as `python experiments/X.py`
from scipy.spatial import cKDTree

from dpcbench.bench.core.params import parse_params
from dpcbench.bench.data.plyio import read_ply
from dpcbench.bench.results.oracle import DEPTH_EDGES
from dpcbench.methods._geometry import sampling_step
from dpcbench.methods.temporal_fusion import method as fusion_method
from dpcbench.methods.temporal_fusion import spatial
from dpcbench.metrics import psnr, resolve_peak
from dpcbench.metrics.neighbours import estimate_normals, point_spacing
from dpcbench.metrics.pairs import CloudPair

#: a stage's returned point within this many spacings of an output point is where that output point came from
ATTRIBUTION_SPACINGS = 1.5
#: ``--refusal-oracle``: the true off-surface errors (in spacings) under which a new point is kept, one result each
ORACLE_LIMITS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0)
#: ``--depth-limit``'s limits, in spacings of depth (a new point's distance to the damaged frame)
DEPTH_LIMITS = (1.0, 2.0, 4.0, 8.0, 16.0)


class StageLog:
    """Points each stage returned, per frame: {frame: [(stage, (P, 3) points), ...]}."""

    def __init__(self) -> None:
        self.frame = -1
        self.points: dict[int, list[tuple[str, np.ndarray]]] = defaultdict(list)

    def add(self, stage: str, points: np.ndarray) -> None:
        if points is not None and len(points):
            self.points[self.frame].append((stage, np.asarray(points, dtype=np.float64).reshape(-1, 3)))


def instrument(log: StageLog) -> None:
    """Wrap the stages `fill_region` and the back-fill call (in `methods.temporal_fusion.method`'s namespace) and
    each cascade strategy's ``fill`` so that ``log`` records what they return."""
    m = fusion_method
    originals = {name: getattr(m, name) for name in ("fill_region", "rim_fill", "fuse", "reuse_previous",
                                                      "partial_copies", "back_fill")}

    def fill_region(cfg, seq, f, *rest, **kwargs):
        log.frame = f
        return originals["fill_region"](cfg, seq, f, *rest, **kwargs)

    def rim_fill(*args, **kwargs):
        out = originals["rim_fill"](*args, **kwargs)
        log.add("rim_fill", out)
        return out

    def fuse(*args, **kwargs):
        out = originals["fuse"](*args, **kwargs)
        log.add("copy", out.points)
        return out

    def reuse_previous(*args, **kwargs):
        out = originals["reuse_previous"](*args, **kwargs)
        log.add("reuse", out[0])  # (the moved points, their rows in the previous fill)
        return out

    def partial_copies(*args, **kwargs):
        out = originals["partial_copies"](*args, **kwargs)
        log.add("partial", out[0])  # (the points, their colours or None)
        return out

    def back_fill(cfg, seq, f, *rest, **kwargs):
        log.frame = f
        out = originals["back_fill"](cfg, seq, f, *rest, **kwargs)
        log.add("back_fill", out[0])  # (the points, their colours or None)
        return out

    for name, wrapper in (("fill_region", fill_region), ("rim_fill", rim_fill), ("fuse", fuse),
                          ("reuse_previous", reuse_previous), ("partial_copies", partial_copies),
                          ("back_fill", back_fill)):
        setattr(m, name, wrapper)
    for strategy in spatial.CASCADE:
        strategy.fill = _traced(strategy, strategy.fill, log)


def copy_within_scatter(seq, region, crop, alignments) -> bool:
    """Version 54's thin-gap rule, measured and not kept (docs/temporal-fusion.md, "Version 55"): the copies fill a
    thin gap where the best copy's rim residual is at most the rim's RMS scatter about the local quadric of its 20
    nearest crop points."""
    from dpcbench.methods._spatial_fill.common import own_scatter_sq

    if not alignments.candidates:
        return False
    best = min(candidate.residual for candidate in alignments.candidates)
    return best <= float(np.sqrt(own_scatter_sq(crop.rim, crop.local)))


def trace_thin_gaps(log: StageLog, by_scatter: bool = False) -> list[tuple[int, str]]:
    """Wrap stage rim fill's decision (`rim_fill.copy_beats_growth`, in the method's namespace; with ``by_scatter``
    version 54's rule, `copy_within_scatter`, instead) so that each thin gap with a full copy records (frame, "centre:
    copy residual, growth hold-out miss -> decision"), in spacings."""
    from dpcbench.methods.temporal_fusion import rim_fill as rim_fill_stage

    lines: list[tuple[int, str]] = []
    original = copy_within_scatter if by_scatter else fusion_method.copy_beats_growth

    def copy_beats_growth(seq, region, crop, alignments):
        decision = original(seq, region, crop, alignments)
        if alignments.candidates:
            best = min(c.residual for c in alignments.candidates) / seq.spacing
            miss = rim_fill_stage.growth_holdout_miss(seq, region, crop) / seq.spacing
            centre = np.round(region.center, 1).tolist()
            lines.append((log.frame, f"  thin gap {centre}: copy residual {best:.3f}, growth hold-out miss {miss:.3f} "
                                     f"-> {'copies' if decision else 'growth'}"))
        return decision

    fusion_method.copy_beats_growth = copy_beats_growth
    return lines


def trace_last_resort(log: StageLog) -> list[tuple[int, str, list[tuple[str, np.ndarray, float, float]], list[str]]]:
    """Wrap the last resort's choice (`best_surface_fill`, in `spatial`'s namespace) so that each call records (frame,
    region centre, [(candidate, its points, hold-out miss, predicted open error)], the candidates that filled); the
    miss and the open error are the rule's own (`best.holdout_miss`; the RMS distance of the candidate's points to
    what the output holds round the hole), recomputed here to print them."""
    from dpcbench.methods._spatial_fill import best

    calls: list[tuple[int, str, list[tuple[str, np.ndarray, float, float]], list[str]]] = []
    original = spatial.best_surface_fill

    def best_surface_fill(covered, region, surfaces, ring):
        judged = []
        for name, (support, fill) in surfaces.items():
            points = fill(support, region, covered)
            if len(points):
                judged.append((name, points, best.holdout_miss(surfaces[name], region, ring),
                               float(np.sqrt(np.mean(covered.query(points)[0] ** 2)))))
        filled_by, filled = original(covered, region, surfaces, ring)
        calls.append((log.frame, str(np.round(region.center, 1).tolist()), judged,
                      [] if filled_by is None else [filled_by]))
        return filled_by, filled

    spatial.best_surface_fill = best_surface_fill
    return calls


def last_resort_lines(calls, frame: int, truth: np.ndarray, normals, spacing: float) -> list[str]:
    """The ``--last-resort`` report of ``frame``: per call of `trace_last_resort`, each candidate's miss and predicted
    open error and its points' true point-to-plane RMS (pc_error's, against ``truth``) and share > 2, in spacings."""
    lines = []
    reference = None
    for at, centre, judged, names in calls:
        if at != frame:
            continue
        if reference is None:  # the truth's normals once a frame, as the audit's pairs take them
            reference = CloudPair(truth, truth[:1], normals)
            truth_normals = reference.reference_normals
        lines.append(f"  last resort {centre}: filled by {', '.join(names) or 'none (left open)'}")
        for name, points, miss, open_error in judged:
            off = np.sqrt(CloudPair(reference.reference, points, truth_normals).plane_res_to_ref) / spacing
            lines.append(f"    {name:7s} points {len(points):6d} miss {miss / spacing:6.2f} open {open_error / spacing:6.2f}"
                         f"  off the truth RMS {np.sqrt(np.mean(off ** 2)):5.2f} (> 2 s: {np.mean(off > 2):4.0%})")
    return lines


def _traced(strategy, fill, log: StageLog):
    def traced(cfg, hole, state):
        out = fill(cfg, hole, state)
        if len(out.spatial) > len(state.spatial):
            log.add(strategy.__name__, out.spatial[len(state.spatial):])
        if len(out.sheet_fill) > len(state.sheet_fill):
            log.add(strategy.__name__, out.sheet_fill[len(state.sheet_fill):])
        return out

    return staticmethod(traced)


def attribute(new: np.ndarray, records: list[tuple[str, np.ndarray]], spacing: float) -> np.ndarray:
    """(P,) stage name of each of the ``new`` points: the stage whose recorded point is nearest, "unattributed"
    when none lies within `ATTRIBUTION_SPACINGS`."""
    labels = np.full(len(new), "unattributed", dtype=object)
    if not len(new) or not records:
        return labels
    names = [name for name, pts in records for _ in range(len(pts))]
    points = np.vstack([pts for _, pts in records])
    dist, idx = cKDTree(points).query(new, distance_upper_bound=ATTRIBUTION_SPACINGS * spacing)
    found = np.isfinite(dist)
    labels[found] = np.asarray(names, dtype=object)[idx[found]]
    return labels


def frame_psnr(pair: CloudPair, peak: float) -> tuple[float, float]:
    """Whole-frame (D1, D2) PSNR of ``pair``: pc_error's symmetric scores, the larger of the two directions' MSEs."""
    d1 = max(pair.ref_to_res.sq_dist.mean(), pair.res_to_ref.sq_dist.mean())
    d2 = max(pair.plane_ref_to_res.mean(), pair.plane_res_to_ref.mean())
    return psnr(d1, peak), psnr(d2, peak)


def audit_frame(truth: np.ndarray, normals: np.ndarray, damaged: np.ndarray, result: np.ndarray, regions,
                records, spacing: float, left_open: bool = False, refusal_oracle: bool = False,
                against: dict[str, np.ndarray] | None = None, by_depth: bool = False,
                depth_limit: bool = False, thin: float | None = None) -> list[str]:
    """The report lines of one frame (see the module docstring)."""
    filled, empty = CloudPair(truth, result, normals), CloudPair(truth, damaged, normals)
    peak = resolve_peak("intrinsic", filled)
    lines = []
    for label, pair in (("result", filled), ("no fill", empty)):
        d1, d2 = frame_psnr(pair, peak)
        lines.append(f"  {label:8s} D1 {d1:6.2f} D2 {d2:6.2f}  "
                     f"(AB1 {pair.ref_to_res.sq_dist.sum():10.0f} BA1 {pair.res_to_ref.sq_dist.sum():9.0f} "
                     f"AB2 {pair.plane_ref_to_res.sum():9.0f} BA2 {pair.plane_res_to_ref.sum():9.0f})")
    new = result[len(damaged):]
    labels = attribute(new, records, spacing)
    # per-point errors of the result's own rows (deduplicated rows map back through result_index)
    rows = np.arange(len(result)) if filled.result_index is None else None
    ba2 = np.zeros(len(result))
    if rows is None:
        ba2[filled.result_index] = filled.plane_res_to_ref
    else:
        ba2 = filled.plane_res_to_ref
    new_ba2 = ba2[len(damaged):]
    off = np.sqrt(new_ba2) / spacing
    deep = (by_depth or depth_limit) and len(damaged)
    depth = cKDTree(damaged).query(new)[0] / spacing if deep else np.zeros(len(new))
    for stage in sorted(set(labels)):
        at = labels == stage
        lines.append(f"  stage {stage:14s} points {at.sum():6d} off RMS {np.sqrt(np.mean(off[at] ** 2)):5.2f} s "
                     f"(> 2 s: {np.mean(off[at] > 2):4.0%})  BA2 {new_ba2[at].sum():9.0f}")
        if by_depth:
            lines += depth_lines(off[at], depth[at])
    reference = filled.reference
    others = {name: CloudPair(truth, other, normals) for name, other in (against or {}).items()}
    for k, region in enumerate(regions):
        inside = region.contains(reference, margin=2 * spacing)
        mine = region.contains(new, margin=2 * spacing)
        stages = ", ".join(f"{stage} {int((labels[mine] == stage).sum())}" for stage in sorted(set(labels[mine])))
        lines.append(f"  region {k} ({np.round(region.center, 1).tolist()}, r {region.bounding_radius:.1f}): "
                     f"AB1 {filled.ref_to_res.sq_dist[inside].sum():9.0f} (open {empty.ref_to_res.sq_dist[inside].sum():9.0f})"
                     f"  AB2 {filled.plane_ref_to_res[inside].sum():8.0f} (open {empty.plane_ref_to_res[inside].sum():8.0f})"
                     f"  BA2 {new_ba2[mine].sum():8.0f}  [{stages}]")
        if others:
            lines.append("    AB1 of " + ", ".join(f"{name} {pair.ref_to_res.sq_dist[inside].sum():.0f}"
                                                   for name, pair in others.items()))
        if left_open:
            d1, d2 = frame_psnr(CloudPair(truth, np.vstack([damaged, new[~mine]]), normals), peak)
            lines.append(f"    left open, the rest filled: D1 {d1:6.2f} D2 {d2:6.2f}")
    if thin:
        lines += thinned_lines(truth, normals, damaged, new, np.isin(labels, REFUSABLE_STAGES), thin, peak)
    if depth_limit:
        lines += depth_limit_lines(truth, normals, damaged, new, np.isin(labels, REFUSABLE_STAGES), depth, peak, empty)
    if refusal_oracle:
        lines += refusal_oracle_lines(truth, normals, damaged, new, off, peak, empty, against,
                                      disagreement(damaged, new, regions, spacing))
    return lines


def depth_lines(off: np.ndarray, depth: np.ndarray) -> list[str]:
    """``--by-depth``'s lines for one stage: its points' off RMS (``off`` (P,), spacings) by their depth (``depth``
    (P,), spacings to the damaged frame's nearest point: how far the fill reaches from what was captured), in the bins
    of `bench.results.oracle.DEPTH_EDGES` (`dpcbench oracle --by-depth` measures any method's result so); empty bins
    left out."""
    lines = []
    for low, high in zip(DEPTH_EDGES[:-1], DEPTH_EDGES[1:]):
        at = (depth >= low) & (depth < high)
        if at.any():
            lines.append(f"    depth {low:4.0f}-{high:<4.0f} s: points {at.sum():6d} off RMS "
                         f"{np.sqrt(np.mean(off[at] ** 2)):5.2f} s (> 2 s: {np.mean(off[at] > 2):4.0%})")
    return lines


def disagreement(damaged: np.ndarray, new: np.ndarray, regions, spacing: float) -> np.ndarray:
    """(P,) each of the ``new`` points' disagreement in spacings (the module docstring), 0 where no candidate reaches
    within 2 spacings of it."""
    from candidate_accuracy import region_candidates  # the sibling module (it imports this one)

    integer = np.array_equal(damaged, np.round(damaged))
    step = spacing if integer else sampling_step(damaged)
    tree, out = cKDTree(damaged), np.zeros(len(new))
    for region in regions:
        mine = np.flatnonzero(region.contains(new, margin=2 * spacing))
        if not len(mine):
            continue
        crop, _, surfaces = region_candidates(damaged, tree, region, spacing, step, integer)
        for name, (support, fill) in surfaces.items():
            points = fill(support, region, cKDTree(crop)) if name != "cap" else np.zeros((0, 3))
            if len(points) < 6:
                continue
            candidate = cKDTree(points)
            distance, nearest = candidate.query(new[mine])
            normal = estimate_normals(points, 6, queries=new[mine], tree=candidate)
            offset = np.abs(np.einsum("pi,pi->p", new[mine] - points[nearest], normal)) / spacing
            offset[distance > 2 * spacing] = 0.0
            out[mine] = np.maximum(out[mine], offset)
    return out


#: the stages `--depth-limit` may refuse: the spatial cascade's strategies (`spatial.CASCADE`) and the reused fill,
#: which in a hole no frame saw (coherent holes, occlusion boxes) is frame f-1's spatial fill moved; not the copies
#: and partial copies (what other frames saw) or the rim fill
REFUSABLE_STAGES = (*(strategy.__name__ for strategy in spatial.CASCADE), "reuse")


def depth_limit_lines(truth, normals, damaged, new, spatial_points, depth, peak, empty: CloudPair) -> list[str]:
    """``--depth-limit``'s lines: per limit L of `DEPTH_LIMITS`, the whole-frame D1 / D2 with the new points of the
    spatial stages and the reused fill (``spatial_points`` (P,) mask of ``new``, `REFUSABLE_STAGES`) kept only where
    their ``depth`` (P,), spacings to the damaged frame, is at most L, every other new point kept: a refusal by depth,
    which the method could make without the truth (the fills are trusted at the rim and drift off deeper in, "How
    deep the fills hold"). Meant for holes no frame saw: in independent holes the reused fill may be copies."""
    none_d2 = frame_psnr(empty, peak)[1]
    lines = [f"  depth limit on the spatial and reused fills ({int(spatial_points.sum())} points; no fill's D2 "
             f"{none_d2:.2f})"]
    for limit in DEPTH_LIMITS:
        keep = ~spatial_points | (depth <= limit)
        d1, d2 = frame_psnr(CloudPair(truth, np.vstack([damaged, new[keep]]), normals), peak)
        lines.append(f"    keep depth <= {limit:4.1f} s: {int((keep & spatial_points).sum()):6d} refusable points  "
                     f"D1 {d1:6.2f} D2 {d2:6.2f}")
    return lines


def thinned_lines(truth, normals, damaged, new, spatial_points, cell: float, peak) -> list[str]:
    """``--thin``'s line: the whole-frame D1 / D2 with the new points of the spatial stages and the reused fill
    (``spatial_points`` (P,) mask of ``new``) thinned to the first in each cubic cell of edge ``cell``
    (`first_in_cells`, as the closed surface thins its own fill to the capture's density), the others all kept."""
    from dpcbench.methods._spatial_fill.common import first_in_cells

    rows = np.flatnonzero(spatial_points)
    keep = ~spatial_points
    keep[rows[first_in_cells(new[rows], cell)]] = True
    d1, d2 = frame_psnr(CloudPair(truth, np.vstack([damaged, new[keep]]), normals), peak)
    return [f"  thinned to one point a cell of {cell:.3f}: {int((keep & spatial_points).sum())} of {len(rows)} "
            f"spatial and reused points kept  D1 {d1:6.2f} D2 {d2:6.2f}"]


def refusal_oracle_lines(truth, normals, damaged, new, off, peak, empty: CloudPair,
                         against: dict[str, np.ndarray] | None, disagree: np.ndarray) -> list[str]:
    """``--refusal-oracle``'s lines (the module docstring): per limit, the new points kept (those whose ``off`` (P,),
    their true off-surface errors in spacings, is under it; then those whose ``disagree`` (P,) is at most it) and the
    whole-frame D1 / D2, against no fill's D2 and, given ``against`` ({method name: its result}), the best of their
    D1 + 1 dB."""
    none_d2 = frame_psnr(empty, peak)[1]
    other = None
    if against:
        d1s = {name: frame_psnr(CloudPair(truth, result, normals), peak)[0] for name, result in against.items()}
        other = max(d1s.items(), key=lambda item: item[1])
    head = f"  refusal oracle (no fill's D2 {none_d2:.2f}"
    lines = [head + (f"; {other[0]}'s D1 {other[1]:.2f})" if other else ")")]
    for label, score, kept in (("off the truth <", off, np.less), ("disagreement <=", disagree, np.less_equal)):
        for limit in ORACLE_LIMITS:
            keep = kept(score, limit)
            d1, d2 = frame_psnr(CloudPair(truth, np.vstack([damaged, new[keep]]), normals), peak)
            both = "" if other is None else ("  both targets met" if d1 >= other[1] + 1.0 and d2 >= none_d2 else "")
            lines.append(f"    keep {label} {limit:4.2f} s: {keep.sum():6d} of {len(new)} points  "
                         f"D1 {d1:6.2f} D2 {d2:6.2f}{both}")
    return lines


def last_resort_where_covered() -> None:
    """Let `spatial.BestSurface` run wherever every strategy before it refused, outside occlusion boxes, also where
    copies, the reused fill or partial copies cover part of the region (the method's own test asks for an emptied
    region: `spatial.BestSurface.applies`)."""

    def applies(cfg, hole, state):
        return bool(cfg.best_surface and not len(state.spatial) and not len(state.sheet_fill) and not hole.in_box)

    spatial.BestSurface.applies = staticmethod(applies)


def last_resort_in_boxes() -> None:
    """Let `spatial.BestSurface` run in every occlusion box too, whatever the strategies before it put there (the
    method's own test leaves boxes out, `spatial.BestSurface.applies`), with what they put counted as covered (as it
    counts a lone membrane's points): its candidates then fill only what they left open, where the open part's
    predicted error exceeds the candidate's hold-out miss."""
    from dataclasses import replace

    fill = spatial.BestSurface.fill

    def applies(cfg, hole, state):
        return bool(cfg.best_surface and hole.in_box)

    def fill_in_box(cfg, hole, state):
        out = fill(cfg, hole, replace(state, membrane_alone=state.spatial) if len(state.spatial) else state)
        return replace(out, membrane_alone=state.membrane_alone)

    spatial.BestSurface.applies = staticmethod(applies)
    spatial.BestSurface.fill = staticmethod(fill_in_box)


#: `closed_surface_band`'s band: the captured points within this many spacings of the untested fill (the closed
#: surface's attachment reach, `poisson._poisson_points`)
BAND_SPACINGS = 3.0


def closed_surface_band(rule: str) -> None:
    """In an occlusion box (a region that keeps captured points), let `spatial.ClosedSurface` judge its surface by
    what borders its fill, not by the ring round the whole box. The method holds out every support point within the
    ring of the region, which in a box is all the captured points inside it too, so the surface is asked to predict
    the whole box from outside (the Longdress frame's box of radius 71: a miss of 24.57 voxels). Here: the untested
    fill (`poisson_surface_fill` with no ring), the band of support points within the ring of the region and within
    `BAND_SPACINGS` of that fill held out, the crop's surface rebuilt without them (one reconstruction at the
    hold-out's octree depth, `poisson.POISSON_HOLDOUT_CELL_STEPS`), and their RMS miss m to it. The fill is kept
    where m^2 - e^2 <= bound^2 (``rule`` "bound": the method's rule, e the band's own scatter), and with ``rule``
    "last-resort" also where m < o, o its points' RMS distance to what the output holds round them (the last
    resort's rule, `methods._spatial_fill.best`). Outside boxes the method is unchanged. Prints one line per box
    judged."""
    from dataclasses import replace

    from dpcbench.methods._spatial_fill import poisson
    from dpcbench.methods._spatial_fill.common import own_scatter_sq

    fill = spatial.ClosedSurface.fill

    def fill_in_box(cfg, hole, state):
        if not hole.in_box:
            return fill(cfg, hole, state)
        seq, region, ring = hole.seq, hole.region, hole.ring
        support = np.vstack([hole.crop.local, hole.accepted])
        points = poisson.poisson_surface_fill(support, region, state.covered, seq.spacing, voxelized=seq.voxelized,
                                              step=seq.step, gap_spacings=cfg.fill_gap_spacings, ring=0.0,
                                              separate_bodies=cfg.poisson_bodies, bridge_ends=cfg.poisson_bridges)
        if not len(points):
            return state
        near_fill = cKDTree(points).query(support, distance_upper_bound=BAND_SPACINGS * seq.spacing)[0]
        band = region.contains(support, margin=ring) & np.isfinite(near_fill)
        if band.sum() < 6 or (~band).sum() < 32:
            return state
        grid = seq.spacing if seq.voxelized else seq.step
        cloud, depth = poisson.poisson_input(support[~band], grid, poisson.POISSON_HOLDOUT_CELL_STEPS)
        held = poisson._mesh_samples(poisson.poisson_mesh(cloud, depth), grid, (region, ring))
        held = held[region.contains(held, margin=ring)]
        if not len(held):
            return state
        miss = float(np.sqrt(np.mean(cKDTree(held).query(support[band])[0] ** 2)))
        scatter_sq = own_scatter_sq(support[band], support)
        open_error = float(np.sqrt(np.mean(state.covered.query(points)[0] ** 2)))
        bound = cfg.surface_holdout_spacings * seq.spacing
        kept = miss ** 2 - scatter_sq <= bound ** 2 or (rule == "last-resort" and miss < open_error)
        print(f"closed surface in the box at {np.round(region.center, 1).tolist()} r={region.bounding_radius:.1f}: "
              f"{len(points)} points, band {int(band.sum())}, miss {miss:.2f}, scatter {np.sqrt(scatter_sq):.2f}, "
              f"bound {bound:.2f}, open part's error {open_error:.2f}: {'filled' if kept else 'refused'}", flush=True)
        return replace(state, spatial=points, poisson_fill=points) if kept else state

    spatial.ClosedSurface.fill = staticmethod(fill_in_box)


def membrane_height_field() -> None:
    """Make temporal-fusion's membrane (`membrane_fill`) a height field over its seeds' plane: each seed keeps its place
    on the plane and takes only the normal part of its harmonic solution (the solution of each coordinate is
    harmonic on its own, so this is the harmonic height field of the same graph). The method's membrane moves all
    three coordinates (`LozesPDE.evolve`): where the anchors bound a large open part on a few sides only, the seeds
    gather towards them (the one-frame cow's underside: 11,918 membrane points on 1,825 voxels, `cascade_trace.py --membrane`). Only the membrane's
    calls are changed: lozes-pde itself (``--against lozes-pde``) evolves as before."""
    from scipy.sparse.csgraph import connected_components

    from dpcbench.methods import lozes_pde

    class HeightFieldPDE(lozes_pde.LozesPDE):
        def evolve(self, known, seeds, spacing):
            evolved = super().evolve(known, seeds, spacing)
            # the seeds `evolve` keeps: those its graph links to a known point, in order (as it decides them)
            _, labels = connected_components(self._graph(np.vstack([known, seeds]), spacing), directed=False)
            kept = seeds[np.isin(labels[len(known):], np.unique(labels[:len(known)]))]
            normal = np.linalg.svd(known - known.mean(axis=0), full_matrices=False)[2][2]
            return kept + ((evolved - kept) @ normal)[:, None] * normal

    fill = spatial.membrane_fill

    def height_field_membrane(*args, **kwargs):
        original, lozes_pde.LozesPDE = lozes_pde.LozesPDE, HeightFieldPDE
        try:
            return fill(*args, **kwargs)
        finally:
            lozes_pde.LozesPDE = original

    spatial.membrane_fill = height_field_membrane


def truth_frames(truth: Path, damaged: Path) -> list[Path]:
    """The truth's PLY files for the damaged frames: ``truth`` itself when a file; else the files of the folder that
    the damage record (holes.json ``input_files``) names, or all of its PLY files in natural order."""
    import json

    from dpcbench.bench.data.sequences import natural_key

    if truth.is_file():
        return [truth]
    names = json.loads((damaged / "holes.json").read_text()).get("input_files")
    if names and all((truth / name).is_file() for name in names):
        return [truth / name for name in names]
    return sorted(truth.glob("*.ply"), key=lambda p: natural_key(p.name))


def truth_frames_or_exit(truth: Path, damaged: Path, count: int) -> list[Path]:
    """`truth_frames`, or a one-line error and exit status 2 when they are not ``count`` (the damaged frames)."""
    files = truth_frames(truth, damaged)
    if len(files) != count:
        print(f"error: {truth} has {len(files)} PLY frames but {damaged} has {count}; "
              "give the folder the damage was made from", file=sys.stderr)
        raise SystemExit(2)
    return files


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("truth", type=Path, help="the undamaged frames: a PLY file or a folder of PLY frames")
    parser.add_argument("damaged", type=Path, help="a `dpcbench damage` output folder (PLY frames + holes.json)")
    parser.add_argument("--frames", default=None, help="comma-separated frames to report (default: all)")
    parser.add_argument("--left-open", action="store_true",
                        help="also each region's whole-frame D1 / D2 with its new points taken out")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a temporal-fusion parameter (repeatable)")
    parser.add_argument("--refusal-oracle", action="store_true",
                        help="also the scores keeping only new points within each limit of the truth")
    parser.add_argument("--against", default=None, metavar="METHOD",
                        help="registered methods (comma-separated): their AB1 in each region, and with "
                             "--refusal-oracle their best D1 + 1 dB is the D1 target")
    parser.add_argument("--last-resort-where-covered", action="store_true",
                        help="run the cascade's last resort (BestSurface) also where copies, the reused fill or partial "
                             "copies cover part of the region (the method runs it only in an emptied region)")
    parser.add_argument("--thin-gaps", action="store_true",
                        help="print, per thin gap with a full copy, the copy's rim residual and the rim fill's hold-out "
                             "miss (spacings) and which fills it (stage rim fill's decision)")
    parser.add_argument("--last-resort", action="store_true",
                        help="print, per hole the last resort judged, each candidate's hold-out miss, predicted open "
                             "error and true distance to the truth, and which filled")
    parser.add_argument("--last-resort-in-boxes", action="store_true",
                        help="run the last resort (spatial.BestSurface) in occlusion boxes too (measured, not kept)")
    parser.add_argument("--closed-surface-band", choices=["bound", "last-resort"], default=None,
                        help="judge the closed surface in occlusion boxes by the band bordering its fill: by the "
                             "method's bound, or also by the last resort's rule (measured, not kept)")
    parser.add_argument("--membrane-height-field", action="store_true",
                        help="the membrane as a height field over its seeds' plane (measured, not kept)")
    parser.add_argument("--thin", action="store_true",
                        help="also the scores with the spatial and reused fills thinned to one point a cell of the "
                             "frame's sampling step (the capture's density)")
    parser.add_argument("--depth-limit", action="store_true",
                        help="also the scores with the spatial and reused fills' points kept only up to each depth limit")
    parser.add_argument("--by-depth", action="store_true",
                        help="each stage's off RMS by depth: spacings from the damaged frame's nearest point")
    parser.add_argument("--thin-gaps-by-scatter", action="store_true",
                        help="decide thin gaps by version 54's rule (measured, not kept): the copies where their rim "
                             "residual is at most the rim's scatter about a local quadric (implies --thin-gaps)")
    args = parser.parse_args(argv)
    if args.last_resort_where_covered:
        last_resort_where_covered()
    if args.last_resort_in_boxes:
        last_resort_in_boxes()
    if args.closed_surface_band:
        closed_surface_band(args.closed_surface_band)
    if args.membrane_height_field:
        membrane_height_field()
    _, frames, regions = load_damage_or_exit(args.damaged)
    truth_files = truth_frames_or_exit(args.truth, args.damaged, len(frames))
    log = StageLog()
    instrument(log)
    thin_gaps = trace_thin_gaps(log, args.thin_gaps_by_scatter) \
        if args.thin_gaps or args.thin_gaps_by_scatter else []
    last_resort = trace_last_resort(log) if args.last_resort else []
    params = parse_params(args.param)
    outputs = fusion_method.TemporalFusion(**params).inpaint(frames, regions)
    others = {}
    if args.against:
        from dpcbench.methods.registry import get_method

        others = {name: get_method(name).inpaint(frames, regions) for name in args.against.split(",")}
    spacing = 1.0 if all(np.array_equal(f, np.round(f)) for f in frames) else point_spacing(max(frames, key=len))
    wanted = range(len(frames)) if args.frames is None else [int(f) for f in args.frames.split(",")]
    for f in wanted:
        cloud = read_ply(truth_files[f])
        truth = np.asarray(cloud.points, dtype=np.float64)
        normals = cloud.normals  # None: CloudPair estimates them as `dpcbench score` does
        print(f"frame {f}: {len(outputs[f]) - len(frames[f])} new points")
        against = {name: result[f] for name, result in others.items()}
        print("\n".join(audit_frame(truth, normals, frames[f], outputs[f], regions[f], log.points[f], spacing,
                                     args.left_open, args.refusal_oracle, against, args.by_depth,
                                     args.depth_limit, sampling_step(frames[f]) if args.thin else None)))
        for line in (text for frame, text in thin_gaps if frame == f):
            print(line)
        for line in last_resort_lines(last_resort, f, truth, normals, spacing):
            print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
