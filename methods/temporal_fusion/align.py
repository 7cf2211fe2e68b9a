"""Stage align: every frame g within +-``window`` of f, nearest first (f-1, f+1, f-2, ...), motion-compensated
to frame f round region R.

Coverage test first: when one of g's own hole regions (moved to f by the motion of the frame one step nearer)
comes within R's rim (centre distance < r + r_g + shell), g lacks part of the patch: it is no full source, and
what it saw of R is a partial copy. Each frame is aligned by point-to-point ICP of its shell onto frame f's crop
(3 rounds, the shell re-selected where g's points land, so g's own patch never pairs with f's rim), from the
motion of the frame one step nearer, then refined point-to-plane (``refine``, pairs within 2 s), kept when the rim
residual does not grow. An alignment whose trimmed rim residual exceeds ``accept_spacings`` s is retried coarse
to fine (``coarse_retry``: pair reach halved from the crop's reach down to the shell, the crop following the
patch), the retry kept when it moved R's place in g farther than the shell and lowered the residual. Accepted
frames give a copy: g's moved points inside R, bent by the rim's normal displacement field (``deform``). f-1 (and
f+1) with its own hole near R that fails the bound is judged again on the rim it saw; within the bound its motion
still carries its fill (stages reuse and back_fill). With ``adjacent_first``, frames beyond f+-1 are aligned only
when f-1 and f+1 are not both sources (a farther frame moved more and costs as much again)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._geometry import icp_align
from dpcbench.methods._registration import alignment_residual
from dpcbench.methods._spatial_fill import even_subset
from dpcbench.methods.temporal_fusion.config import FusionConfig
from dpcbench.methods.temporal_fusion.motion import (
    deformed,
    plane_target,
    refine_point_to_plane,
    rim_displacement,
    seen_rim_residual,
)
from dpcbench.methods.temporal_fusion.records import Aligned, Alignments, Candidate, Crop, Motion, SequenceData

#: most source points an ICP call pairs: a rigid motion has 6 unknowns, and 2000 evenly spread
#: pairs pin it down as well as the 10-20k of a large hole's shell on an 800k-point frame (the
#: alignment cost is then independent of the point density)
ICP_POINTS = 2000


def align_frame(cfg: FusionConfig, seq: SequenceData, g: int, region: HoleRegion, init, schedule, follow: bool,
                crop: Crop, plane_cache: dict):
    """Frame g's points round where R lies in g, moved onto frame f's crop. One point-to-point ICP round of g's
    shell per pair reach in ``schedule``, from the motion ``init`` (frame g -> f); with ``follow`` the crop of g is
    taken again round where R lies in g under each round's motion. ``plane_cache`` holds the crop's `plane_target`
    (one normal estimate per hole). Returns the `Aligned` source, None when g has fewer than 6 points there."""
    spacing, local, rim, shell = seq.spacing, crop.local, crop.rim, crop.shell
    reach = region.bounding_radius + 2 * shell
    rotation, translation = init
    source, idx = None, np.zeros(0, dtype=np.int64)
    for max_distance in schedule:
        if source is None or follow:
            centre_g = (region.center - translation) @ rotation
            idx = np.asarray(seq.tree_of(g).query_ball_point(centre_g, reach, return_sorted=True), dtype=np.int64)
            if len(idx) < 6:
                return None
            source = seq.frames[g][idx]
        # the source's shell is re-selected where it lands after the current motion, so the
        # source's own patch inside R never pairs with frame f's rim
        moved = source @ rotation.T + translation
        in_shell = ~region.contains(moved) & region.contains(moved, margin=shell)
        rotation, translation = icp_align(even_subset(source[in_shell], ICP_POINTS), local,
                                          max_distance=max_distance, max_iterations=int(cfg.icp_iterations),
                                          init=(rotation, translation))
    if source is None:  # an empty schedule: nothing aligned
        return None
    source_tree = cKDTree(source)
    residual = alignment_residual(source_tree, rim, rotation, translation)
    if cfg.refine:
        # point-to-plane from the converged point-to-point motion, pairs within 2 s: it
        # slides the samplings onto each other where point-to-point stops at half a spacing
        moved = source @ rotation.T + translation
        in_shell = ~region.contains(moved) & region.contains(moved, margin=shell)
        if "plane" not in plane_cache:
            plane_cache["plane"] = plane_target(local)
        refined = refine_point_to_plane(even_subset(source[in_shell], ICP_POINTS), local, 2 * spacing,
                                        (rotation, translation), int(cfg.icp_iterations),
                                        target_cloud=plane_cache["plane"])
        refined_residual = alignment_residual(source_tree, rim, *refined)
        if refined_residual <= residual:
            (rotation, translation), residual = refined, refined_residual
    return Aligned(source, source_tree, rotation, translation, residual, idx)


def has_own_hole(region: HoleRegion, centre_g: np.ndarray, regions_g, shell: float) -> bool:
    """The coverage test: a hole region of frame g (``regions_g``) comes within R's rim, R's centre in g being
    ``centre_g``."""
    return any(np.linalg.norm(other.center - centre_g) < region.bounding_radius + other.bounding_radius + shell
               for other in regions_g)


def _retry(cfg, seq, g, region, init, centre_g, own_hole, aligned, crop, plane_cache):
    """The coarse-to-fine retry of a failed alignment: (the alignment to keep, the motion that only starts the
    farther frames' alignment or None)."""
    reach, shell = crop.reach, crop.shell
    schedule = [reach / 2 ** k for k in range(int(np.ceil(np.log2(reach / shell))))] + [shell] * 3
    retried = align_frame(cfg, seq, g, region, init, schedule, True, crop, plane_cache)
    # kept only where it found R farther from the start than the shell: within it, the first
    # alignment could reach the patch, and a lower residual there is one more local minimum
    moved_far = retried is not None and \
        np.linalg.norm((region.center - retried.translation) @ retried.rotation - centre_g) > shell
    if moved_far and retried.residual < aligned.residual:
        if not own_hole:
            return retried, None
        if retried.residual <= cfg.accept_spacings * seq.spacing:
            # g has its own hole near R: its coarse motion only starts the farther frames' alignment
            return aligned, (retried.rotation, retried.translation)
    return aligned, None


def align_sources(cfg: FusionConfig, seq: SequenceData, f: int, region: HoleRegion, crop: Crop) -> Alignments:
    """The `Alignments` of every frame within the window to frame f round ``region``."""
    frames, spacing = seq.frames, seq.spacing
    order = sorted((g for g in range(len(frames)) if g != f and abs(g - f) <= int(cfg.window)),
                   key=lambda g: (abs(g - f), g))
    motions: dict[int, Motion] = {f: Motion(np.eye(3), np.zeros(3), None)}
    plane_cache: dict = {}
    candidates: list[Candidate] = []
    partial: list[Candidate] = []
    carried: Motion | None = None  # f-1's motion when it carries its fill only
    next_motion: Motion | None = None
    starts: dict[int, tuple] = {}  # motions that only start the farther frames' alignment
    for g in order:
        if cfg.adjacent_first and abs(g - f) > 1 and sum(c.gap == 1 for c in candidates) == 2:
            break  # f-1 and f+1 both saw R: farther frames only moved more
        nearer = g - 1 if g > f else g + 1
        rotation0, translation0 = motions[nearer][:2] if nearer in motions else starts.get(nearer, motions[f][:2])
        centre_g = (region.center - translation0) @ rotation0
        own_hole = has_own_hole(region, centre_g, seq.regions[g], crop.shell)
        if own_hole and not (cfg.reuse_previous and g == f - 1) and not cfg.partial_sources:
            continue
        aligned = align_frame(cfg, seq, g, region, (rotation0, translation0), [crop.shell] * 3, False, crop,
                              plane_cache)
        if aligned is None:
            continue
        beyond = g + (1 if g > f else -1)
        # an own-hole frame's retry only starts the frame beyond it: none within the window, no retry
        retry_useful = not own_hole or (abs(beyond - f) <= int(cfg.window) and 0 <= beyond < len(frames))
        if cfg.coarse_retry and retry_useful and aligned.residual > cfg.accept_spacings * spacing:
            aligned, start = _retry(cfg, seq, g, region, (rotation0, translation0), centre_g, own_hole, aligned,
                                    crop, plane_cache)
            if start is not None:
                starts[g] = start
        source, source_tree, rotation, translation, residual, rows = aligned
        carries_only = False
        if residual > cfg.accept_spacings * spacing:
            # f-1 (f+1) with its own hole there: judged again on the rim it saw, its motion carries its fill
            # to f though it is no source
            carrier = (g == f - 1 and cfg.reuse_previous) or (g == f + 1 and cfg.reuse_next)
            if not (own_hole and carrier
                    and seen_rim_residual(source_tree, crop.rim, rotation, translation, seq.regions[g])
                    <= cfg.accept_spacings * spacing):
                continue
            carries_only = True
        moved = source @ rotation.T + translation
        inside = region.contains(moved)
        field = rim_displacement(crop.rim, moved[~inside], 2 * spacing) if cfg.deform else None
        motion = Motion(rotation, translation, field)
        if g == f + 1:
            next_motion = motion
        if carries_only:
            if g == f - 1:
                carried = motion
            continue
        motions[g] = motion
        if inside.any() and (not own_hole or cfg.partial_sources):
            colours = None if seq.colours is None else seq.colours[g][rows[inside]]
            copy = Candidate(residual, abs(g - f), g, deformed(moved[inside], field, cfg.deform_neighbours), colours)
            (partial if own_hole else candidates).append(copy)
    return Alignments(tuple(candidates), tuple(partial), motions, carried, next_motion)
