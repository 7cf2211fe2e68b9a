"""Step 6e (`Membrane` of `methods.temporal_fusion.spatial`): lozes-pde's harmonic graph fill anchored at the data
round and inside the hole, with its height-field, sag, hold-out and agreement tests."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill.common import (
    _flat_anchors,
    _link_components,
    far_from,
    fit_height_field,
    grown_agreeing,
    holdout_passes,
    plane_offsets,
)
from dpcbench.metrics.neighbours import estimate_normals


def membrane_fill(captured: np.ndarray, region: HoleRegion, covered: cKDTree | None, spacing: float, *,
                  step: float, accepted: np.ndarray | None = None, partial: np.ndarray | None = None,
                  gap_spacings: float = 1.0,
                  ring_spacings: float = 3.0, max_holdout_spacings: float = 1.0,
                  agree_spacings: float = 1.0, max_steep: float = 0.5) -> np.ndarray:
    """Membrane fill (step 6e of `methods.temporal_fusion`) of the parts of ``region`` that no point of
    ``covered`` is within ``gap_spacings * spacing`` of: `lozes_pde.LozesPDE`'s harmonic (p = 2) graph fill
    anchored at every point of ``captured`` (C, 3; the frame's own points round the hole) and ``accepted``
    (A, 3; points other steps put there) within ``ring_spacings * step`` of the region, inside included, and
    at the points of ``partial`` (Q, 3; copies from frames with their own hole near the region) where the
    anchors without them pass test (0) below: in a large box those copies hold what the frames round f saw,
    but a copy of one side of a box wrapped round a limb makes it look flat (samba's widest box: 54 % of the
    anchors steep without the copies, 50 % with, and a membrane 2.3 s RMS off the truth).
    Returns (P, 3) points; (0, 3) when the membrane is not trusted.

    Seeds: LozesPDE's grid of step ``step`` on the anchors' PCA plane, where the plane is farther than 0.8
    step from every projected anchor (the open part of the hole's footprint); each seed is then the
    weighted mean of its graph neighbours (10-NN, Gaussian weights of one step), anchors fixed: the
    membrane interpolates between the data round and inside the region.

    Trust, four tests. (0) A height field over the seeds' plane: at most ``max_steep`` of the anchors' PCA
    normals more than 60 degrees off the plane's normal (`fit_height_field`'s fraction; step 6's test, with a
    majority bound): the seeds lie on that plane, and a box wrapped round a limb (samba's widest, 55 % steep)
    got a membrane 2 spacings off the truth that the tests below pass. Anchors that fail it are tried once on
    their sheet: the anchors whose normal passes the test's 60 degrees (`_flat_anchors`) are the anchors, the
    others a surface crossing the sheet (legs through a skirt's closing sheet), and of the seeds on the sheet's
    plane only the open parts that border the sheet more than the crossing surface are kept (`_sheet_bounded`:
    a tube's inside borders its wall alone); the tests below then judge that membrane, (0) included.
    (1) Interpolation or a flat opening:
    where `membrane_sag` of the anchors over the widest open disc among them (`_open_radius`; over the
    region's radius up to temporal-fusion 33, which left the open band between a box's edge and the data
    inside it to nothing) exceeds ``max_holdout_spacings`` spacings (the bound of test 2), only
    the seeds inside the convex hull (on the anchors' plane) of the ``captured`` points inside the region are
    kept, so the membrane spans gaps enclosed by data and never extends it (step 6's rule for its grid):
    across an emptied disc of radius 7 on a cylinder of radius 8 the membrane lies 1.5-2 spacings inside the
    surface (sag 1.5), and the tests below pass it. Where the sag is within the bound, every seed is
    kept. (2) Hold-out (step 6's test, with the same bound): the anchors that border the open part (on the
    anchors' plane, within LozesPDE's seed gap + ``ring_spacings / 2`` steps of a kept seed) are left out,
    the membrane of the others is built the same way, and the left-out points' RMS distance to the local
    planes of that membrane and its anchors (8 nearest within 3 s, `plane_offsets`; points with fewer are
    not judged) must be at most ``max_holdout_spacings`` spacings, less in quadrature the left-out points' own
    scatter about a smooth surface (`holdout_passes`: a noisy capture misses any surface by its noise; on MVUB
    ricardo9's occlusion boxes the raw miss refused three of radius 36-44, docs/temporal-fusion.md "Version
    49"). The band is that of step 6's hold-out round the open part, not round the region: an occlusion box keeps data inside, and leaving all of it
    out tested a membrane across the whole box, which the fill never spans (it refused D-FAUST boxes whose
    fills lay 0.26 s RMS off the truth at a hold-out of 1.27 s). (3) Agreement (step 4's rule,
    `grown_agreeing`): grown from the anchors, each point must lie within ``agree_spacings`` spacings of
    their local plane, and not between two layers of them (`between_layers`, same reach and tolerance: the
    local plane of two sheets' mixed points passes a point half-way between them); the others are dropped.
    Regions too large for LozesPDE's seed cap are left open."""
    from dpcbench.methods.lozes_pde import LozesPDE
    from dpcbench.metrics.errors import UserError

    membrane = LozesPDE(p=2.0, ring_spacings=ring_spacings)
    captured = np.asarray(captured, dtype=np.float64)
    support = captured if accepted is None or not len(accepted) else np.vstack([captured, accepted])
    if partial is not None and len(partial):
        own = support[region.contains(support, margin=ring_spacings * step)]  # `seed_hole`'s anchors
        if len(own) >= 12 and fit_height_field(own)[4] <= max_steep:
            support = np.vstack([support, partial])
    try:
        seeds, anchors = membrane.seed_hole(support, region, step)
        crossing = None  # the anchors of a second surface through the hole's sheet
        if len(anchors) >= 12 and fit_height_field(anchors)[4] > max_steep:
            flat = _flat_anchors(anchors)
            if flat.sum() >= 12:
                crossing, support = anchors[~flat], anchors[flat]
                seeds, anchors = membrane.seed_hole(support, region, step)
                seeds = seeds[_sheet_bounded(seeds, anchors, crossing, membrane.gap_spacings * step, step)]
        if len(anchors) >= 12 and membrane_sag(anchors, region, _open_radius(seeds, anchors)) > max_holdout_spacings * spacing:
            seeds = seeds[_within_hull_of(seeds, captured[region.contains(captured)], anchors)]
        if len(seeds) == 0 or len(anchors) < 12 or fit_height_field(anchors)[4] > max_steep:
            return np.zeros((0, 3))
        # held out: the anchors bordering the open part, within ring_spacings / 2 steps of its edge (the seeds
        # stop LozesPDE's gap short of the anchors), measured on the anchors' plane as the seeds were placed
        centre = anchors.mean(axis=0)
        tangent = np.linalg.svd(anchors - centre, full_matrices=False)[2][:2]
        reach = (membrane.gap_spacings + ring_spacings / 2) * step
        distance = cKDTree((seeds - centre) @ tangent.T).query((support - centre) @ tangent.T, distance_upper_bound=reach)[0]
        inner = (distance <= reach) & region.contains(support, margin=ring_spacings * step)
        held_seeds, held_anchors = membrane.seed_hole(support[~inner], region, step)
        if crossing is not None:
            held_seeds = held_seeds[_sheet_bounded(held_seeds, held_anchors, crossing, membrane.gap_spacings * step, step)]
        if len(held_anchors) < 12 or len(held_seeds) == 0:
            return np.zeros((0, 3))
        outer_membrane = np.vstack([membrane.evolve(held_anchors, held_seeds, step), held_anchors])
        judged, offset = plane_offsets(support[inner], outer_membrane, 3 * spacing)
        held = support[inner][judged]
        if not judged.any() or not holdout_passes(offset[judged], held, support, max_holdout_spacings * spacing):
            return np.zeros((0, 3))
        points = membrane.evolve(anchors, seeds, step)
    except UserError:  # more seeds than LozesPDE's cap: a region that size is no gap to span
        return np.zeros((0, 3))
    points = points[region.contains(points)]
    # step 4's rule: grown from the anchors, a point must continue their local surface
    points = points[grown_agreeing(points, anchors, 3 * spacing, agree_spacings * spacing)]
    points = points[~between_layers(points, anchors, 3 * spacing, agree_spacings * spacing)]
    return points[far_from(points, covered, gap_spacings * spacing)]


def _sheet_bounded(seeds: np.ndarray, anchors: np.ndarray, crossing: np.ndarray, gap: float, step: float
                   ) -> np.ndarray:
    """Mask (S,) of ``seeds`` (on the PCA plane of ``anchors``) in open parts that border ``anchors`` more than
    ``crossing``.

    On that plane: seeds within ``gap`` of a projected ``crossing`` point are dropped; the others are linked
    into open parts (grid neighbours, links of 1.5 ``step``), and a part is kept when at least half of its seeds
    lie nearer to a projected anchor than to a projected crossing point. Seeds, not bordering points, are
    counted: a wall across the plane projects many points onto one place."""
    if len(seeds) == 0 or len(crossing) == 0:
        return np.ones(len(seeds), dtype=bool)
    centre = anchors.mean(axis=0)
    tangent = np.linalg.svd(anchors - centre, full_matrices=False)[2][:2]
    seeds_2d = (seeds - centre) @ tangent.T
    to_crossing = cKDTree((crossing - centre) @ tangent.T).query(seeds_2d)[0]
    to_anchor = cKDTree((anchors - centre) @ tangent.T).query(seeds_2d)[0]
    keep = to_crossing > gap
    rows = np.flatnonzero(keep)
    if not len(rows):
        return keep
    _, labels = _link_components(np.column_stack([seeds_2d[rows], np.zeros(len(rows))]), 1.5 * step)
    nearer = np.bincount(labels, weights=(to_anchor[rows] <= to_crossing[rows]).astype(float))
    keep[rows] = (nearer >= 0.5 * np.bincount(labels))[labels]
    return keep


def between_layers(points: np.ndarray, anchors: np.ndarray, reach: float, tolerance: float,
                   neighbours: int = 16) -> np.ndarray:
    """Mask (P,) of ``points`` that lie between two layers of ``anchors`` (K, 3): among its (up to)
    ``neighbours`` nearest anchors within ``reach``, some lie more than ``tolerance`` on one side of the point
    and some more than ``tolerance`` on the other, along the normal of its nearest anchor (PCA of that
    anchor's 10 nearest anchors, `fit_height_field`'s estimate). Why: a point half-way between two sheets
    (the two sides of a fold, an arm over the torso) sits on the plane of its mixed neighbours, so the
    agreement rule (`grown_agreeing`) passes it; on one sheet, tilted or curved, its neighbours lie within a
    fraction of a spacing of the tangent plane, and at a fold's inner corner all on one side."""
    out = np.zeros(len(points), dtype=bool)
    if len(points) == 0 or len(anchors) < 10:
        return out
    k = int(min(neighbours, len(anchors)))
    dist, idx = cKDTree(anchors).query(points, k=k, distance_upper_bound=reach)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    near = np.isfinite(dist)
    rows = np.flatnonzero(near[:, 0])
    if not len(rows):
        return out
    near = near[rows]
    normal = estimate_normals(anchors, 10, queries=anchors[idx[rows, 0]])
    nb = anchors[np.where(near, idx[rows], idx[rows, :1])]  # unused slots repeat the nearest
    offset = np.einsum("pki,pi->pk", nb - points[rows, None, :], normal)
    above = np.where(near, offset, -np.inf).max(axis=1) > tolerance
    below = np.where(near, offset, np.inf).min(axis=1) < -tolerance
    out[rows] = above & below
    return out


def membrane_sag(anchors: np.ndarray, region: HoleRegion, radius: float | None = None) -> float:
    """How far (coordinate units) a harmonic membrane across ``region`` departs from the quadric through its
    ``anchors`` (K, 3), K >= 6: |c3 + c5| r^2 / 2, with c3, c5 the u^2 and v^2 coefficients of
    `fit_height_field` of the anchors and r the region's bounding radius, or ``radius`` where it is smaller
    (the radius of the open part the membrane spans, `_open_radius`).

    Why: on a disc of radius r the quadric h has the constant Laplacian 2 (c3 + c5), and the harmonic
    function with h's boundary values differs from h by (c3 + c5) (rho^2 - r^2) / 2, the most at the centre
    (0 on a plane or a saddle; 1.53 for a hole of radius 7 on a cylinder of radius 8, where 1 / (2 * 8) =
    c3). It is the part of the membrane's error that the rim shows before the membrane is built."""
    _, _, coef, _, _ = fit_height_field(anchors)
    r = region.bounding_radius if radius is None else min(radius, region.bounding_radius)
    return float(abs(coef[3] + coef[5]) * r ** 2 / 2)


def _open_radius(seeds: np.ndarray, anchors: np.ndarray) -> float:
    """The radius of the widest open disc among ``anchors`` (K, 3) that holds a seed of ``seeds`` (S, 3): the
    largest distance, on the anchors' PCA plane, from a seed to its nearest anchor (inf with no seeds). A box
    that keeps captured points inside opens gaps far narrower than the box: the membrane, pinned at every
    anchor, departs from the surface by the width of the gap it spans, not of the box."""
    if len(seeds) == 0:
        return float("inf")
    centre = anchors.mean(axis=0)
    tangent = np.linalg.svd(anchors - centre, full_matrices=False)[2][:2]
    return float(cKDTree((anchors - centre) @ tangent.T).query((seeds - centre) @ tangent.T)[0].max())


def _within_hull_of(points: np.ndarray, inside: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Mask (P,) of ``points`` whose projection on the PCA plane of ``anchors`` lies in the convex hull of
    the projected ``inside`` points (all False with fewer than 3 of them, or when they are collinear)."""
    if len(points) == 0 or len(inside) < 3:
        return np.zeros(len(points), dtype=bool)
    from scipy.spatial import ConvexHull, QhullError

    centre = anchors.mean(axis=0)
    tangent = np.linalg.svd(anchors - centre, full_matrices=False)[2][:2]
    try:
        edges = ConvexHull((inside - centre) @ tangent.T).equations  # a u + b v + c <= 0 inside
    except QhullError:
        return np.zeros(len(points), dtype=bool)
    return ((points - centre) @ tangent.T @ edges[:, :2].T + edges[:, 2] <= 1e-9).all(axis=1)
