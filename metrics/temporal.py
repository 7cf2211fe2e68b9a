"""Temporal consistency of a filled sequence: how steadily the fill follows the ground truth's motion.

Definition (lower is better, in coordinate units; 0 for a perfect fill, and for any fill whose error
does not change over time):

For frame f let G_f be the ground truth, R_f the result, and for a ground-truth point x of frame f
the *error vector* e_f(x) = r - x, r the nearest point of R_f to x (where the result surface lies,
seen from the true surface). Let S_f be the ground-truth points of frame f inside that frame's hole
regions (all points when no regions are given). For each consecutive pair (f, g = f + 1):

- every x in S_g is linked to its nearest ground-truth point y in G_f, and every y in S_f to its
  nearest ground-truth point x in G_g;
- each link contributes  | (e_g(x) - e_f(y)) . n |,  n the unit normal of the ground truth at the
  hole point of the link (PCA of its `NORMAL_NEIGHBOURS` nearest ground-truth points, its own frame);
- the pair's value is the mean over its links.

TC = the mean of the pair values (NaN pairs, with no hole points, left out).

True correspondences. When the sequence knows where each ground-truth point goes (a mesh sequence
sampled with shared connectivity, `bench.data.meshseq.MeshMotion.correspondences`), pass them as
``correspondences``: one (forward, backward) pair of index arrays per consecutive frame pair, forward
(N_f,) the index in frame f + 1 of each point of frame f, backward (N_{f+1},) the index in frame f of each
point of frame f + 1. The links then follow the true motion (x in S_g linked to backward[x], y in S_f to
forward[y]) instead of the nearest ground-truth point, which on fast motion can sit on another part of
the body. Everything else is unchanged.

Why: the ground truth's own motion is factored out because errors are measured against the ground
truth of each frame, and linked across frames by ground-truth proximity (real captures have no point
correspondence across frames, so the link is spatial). A fill that is wrong but steadily wrong keeps
the same error field and scores ~0 (that is the job of GPSNR); a fill that jitters, i.e. is placed
differently each frame, changes its error field and scores its jitter amplitude; a fill frozen while
the body moves scores the body's normal motion. Only the normal component counts, because the
tangential part of a nearest-point vector depends on how each frame happens to be sampled and is
noise, while the normal part is the displacement of the surface.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dpcbench.metrics.neighbours import estimate_normals
from dpcbench.metrics.pairs import build_tree, check_points
from dpcbench.metrics.types import Frames, RegionsPerFrame

#: one (forward, backward) pair of index arrays per consecutive frame pair (module docstring)
Correspondences = Sequence[tuple[np.ndarray, np.ndarray]]

#: Neighbours for the PCA normal of a ground-truth hole point.
NORMAL_NEIGHBOURS = 12


def _region_mask(regions, points: np.ndarray, margin: float) -> np.ndarray:
    if regions is None:
        return np.ones(len(points), dtype=bool)
    mask = np.zeros(len(points), dtype=bool)
    for region in regions:
        mask |= np.asarray(region.contains(points, margin), dtype=bool)
    return mask


class _Frame:
    """One frame's ground truth and result with their trees (built once, used by two pairs)."""

    def __init__(self, reference, result, regions, margin, index):
        self.gt = check_points(reference, f"reference frame {index}")
        self.res = check_points(result, f"result frame {index}")
        self.gt_tree = build_tree(self.gt)
        self.res_tree = build_tree(self.res)
        self.hole = np.flatnonzero(_region_mask(regions, self.gt, margin))

    def errors(self, gt_index: np.ndarray) -> np.ndarray:
        """(K, 3) error vectors e(x) = nearest result point - x for ground-truth points ``gt_index``."""
        x = self.gt[gt_index]
        _, nearest = self.res_tree.query(x, k=1, workers=-1)
        return self.res[nearest] - x


def _links(src: _Frame, dst: _Frame, mapping: np.ndarray | None = None) -> np.ndarray:
    """|(e_src(x) - e_dst(y)) . n_x| for every hole point x of ``src`` linked to y of ``dst``: its true
    correspondent ``mapping[x]`` when given, else its nearest ground-truth point."""
    if src.hole.size == 0:
        return np.empty(0)
    x = src.gt[src.hole]
    if mapping is None:
        _, y_index = dst.gt_tree.query(x, k=1, workers=-1)
    else:
        y_index = mapping[src.hole]
    # a ground truth of 1-2 points has no plane: zero normals, so its links count 0
    normals = (estimate_normals(src.gt, NORMAL_NEIGHBOURS, queries=x, tree=src.gt_tree) if len(src.gt) >= 3
               else np.zeros((len(x), 3)))
    change = src.errors(src.hole) - dst.errors(y_index)
    return np.abs(np.einsum("ij,ij->i", change, normals))


def _check_correspondences(correspondences, frames) -> list | None:
    if correspondences is None:
        return None
    correspondences = list(correspondences)
    if len(correspondences) != len(frames) - 1:
        raise ValueError(f"correspondences are given for {len(correspondences)} frame pairs but the sequence has "
                         f"{len(frames) - 1} consecutive pairs")
    out = []
    for f, pair in enumerate(correspondences):
        forward, backward = (np.asarray(m) for m in pair)
        for name, m, src, dst in (("forward", forward, f, f + 1), ("backward", backward, f + 1, f)):
            if m.shape != (len(frames[src].gt),) or m.dtype.kind not in "iu":
                raise ValueError(f"correspondences[{f}] {name}: expected ({len(frames[src].gt)},) integer indices "
                                 f"(one per point of frame {src}), got {m.dtype} {m.shape}")
            if m.size and (m.min() < 0 or m.max() >= len(frames[dst].gt)):
                raise ValueError(f"correspondences[{f}] {name}: indices must lie in 0..{len(frames[dst].gt) - 1} "
                                 f"(points of frame {dst})")
        out.append((forward, backward))
    return out


def temporal_consistency_per_pair(references: Frames, results: Frames, regions: RegionsPerFrame | None = None, *,
                                  region_margin: float = 0.0,
                                  correspondences: Correspondences | None = None) -> np.ndarray:
    """The value of each consecutive frame pair (F - 1,), NaN where no frame of the pair has hole points.

    references, results: lists of (N_f, 3) arrays, same length F >= 2. regions: None (whole frames)
    or a list of F lists of hole regions (objects with ``contains(points, margin)``). correspondences:
    None (nearest-point links) or F - 1 pairs (forward, backward) of index arrays (module docstring).
    """
    references, results = list(references), list(results)
    if len(references) != len(results):
        raise ValueError(
            f"temporal consistency needs as many result frames as reference frames; got {len(references)} "
            f"reference and {len(results)} result frames"
        )
    if len(references) < 2:
        raise ValueError(
            f"temporal consistency needs at least two frames, got {len(references)}; it measures change between frames"
        )
    if regions is not None and len(regions) != len(references):
        raise ValueError(f"regions are given for {len(regions)} frames but the sequence has {len(references)}")
    frames = [
        _Frame(ref, res, None if regions is None else regions[i], region_margin, i)
        for i, (ref, res) in enumerate(zip(references, results))
    ]
    maps = _check_correspondences(correspondences, frames)
    values = np.full(len(frames) - 1, np.nan)
    for f in range(len(frames) - 1):
        forward, backward = maps[f] if maps is not None else (None, None)
        links = np.concatenate([_links(frames[f + 1], frames[f], backward), _links(frames[f], frames[f + 1], forward)])
        if links.size:
            values[f] = float(links.mean())
    return values


def temporal_consistency(references: Frames, results: Frames, regions: RegionsPerFrame | None = None, *,
                         region_margin: float = 0.0, correspondences: Correspondences | None = None) -> float:
    """Sequence-level temporal consistency (lower = steadier); see the module docstring for the formula.

    Returns NaN when no frame has ground-truth points inside its regions.
    """
    values = temporal_consistency_per_pair(references, results, regions, region_margin=region_margin,
                                           correspondences=correspondences)
    finite = values[~np.isnan(values)]
    return float(finite.mean()) if finite.size else math.nan
