"""Oracle fills: what a fill that knows the ground truth's surface scores (`dpcbench oracle`).

A method never sees the ground truth; these fills do, so a row's best achievable D1 / D2 is a
measurement, not an argument. Each fills the hole of a damaged frame (the truth's points absent
from it: ``truth[mask]`` with the damage's removal mask, else the truth points farther than 1% of
the damaged frame's spacing from every damaged point) and returns ``damaged ∪ fill``:

- ``none``:    no fill (the damaged frame itself): the floor;
- ``surface``: one sample per missing truth point q, moved within the truth's tangent plane at q
               (PCA of its ``k`` nearest truth points, `metrics.neighbours.estimate_normals`) by
               ``u t1 + v t2``, ``u, v ~ U(-s/2, s/2)`` (seeded), s the damaged frame's median
               nearest-neighbour spacing: points at the truth's density, not at its sample positions,
               but each keeping its sample's own offset from the surface along the normal (a voxel's
               rounding, a scan's noise); on a plane every sample lies on it, so its D2 is the ceiling;
- ``smooth``:  the ``surface`` samples moved onto the truth's smooth surface, each to the foot of its moving-
               least-squares quadric of the ``SMOOTH_NEIGHBOURS`` nearest truth points (`methods._front_fill.
               local_quadric`): a fill that knows the surface but neither where the truth's samples lie on it
               nor their own offsets from it (a voxelized capture's rounding, a scan's noise), which no fill
               from the data can know. ``surface`` keeps each sample's offset along the normal, so on voxelized
               data its D2 is far above what a fill can reach; this one is the stricter ceiling;
- ``jitter``:  the missing truth points moved along their truth normal by ``N(0, sigma^2)``
               (seeded), sigma a method's measured off-surface error (`off_surface_rms`): what the
               method would score if its only error were that;
- ``truth``:   the missing truth points themselves: the ceiling (the result equals the truth).

`d2_break_even` finds the jitter oracle's sigma at which its D2 equals no fill's: the off-surface error
(RMS along the truth's normal) below which a complete fill scores at least no fill's D2 and above
which even a complete fill scores less. An open hole's point-to-plane error is small where the
surface round it is flat (each hidden point's nearest rim point lies in its tangent plane), so this
bound is often well under a spacing: a D2 target above no fill asks that much of a fill.

`score_colour_oracles` scores colour the same way: the ``truth`` fill's positions (the damaged frame plus every
missing truth point), the missing points coloured from the damaged frame alone by one of the methods' colour
fills (`methods._colour.colour_frame`: ``harmonic`` from the hole's rim, ``nearest`` input colour), against the
truth's colours. The geometry is perfect, so the figure is the colour fill's own error: a method that colours its
new points with that fill reaches about it by placing them well, and a colour target above it asks for a better
colour estimate, not better geometry.

`off_surface_rms` measures a method's off-surface error: the RMS over its fill points (result
points farther than 1% of the spacing from every damaged point) of ``|(p - q) . n_q|``, q the
nearest truth point and n_q the truth's PCA normal there (D2's point-to-plane distance).
`off_surface_by_depth` splits it by depth, each fill point's distance to the damaged frame: a fill that sits on the
surface at the rim may drift off it farther in.

`refused_fill` and `score_refusals` are the refusal oracle: a method's result without its fill points whose
``|(p - q) . n_q|`` is at least a limit (in spacings of the damaged frame, `metrics.neighbours.point_spacing`, the
unit of `d2_break_even`). That is what a refusal rule that knew every fill point's true error would keep, point by point
(a hole refused whole is a special case), so where no limit brings D2 up to no fill's at the D1 a target asks, no
refusal rule does, and the target takes fill points nearer the truth.
Scores are those of `metrics.score_sequence` (whole frame, and in the hole regions when given).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.bench.core.errors import UserError

VARIANTS = ("none", "surface", "smooth", "jitter", "truth")
#: the ``smooth`` oracle's quadric fit: 20 neighbours, as temporal-fusion's own surface fits (`local_quadric`)
SMOOTH_NEIGHBOURS = 20
#: the colour fills scored on the truth's positions by `score_colour_oracles` (those of `methods._colour` that use
#: the damaged frame alone)
COLOUR_FILLS = ("harmonic", "nearest")
#: a truth point closer than this share of the damaged frame's spacing to a damaged point is kept
MATCH_SHARE = 0.01
DEFAULT_NEIGHBOURS = 12
#: the depth bins of `off_surface_by_depth`, spacings from the damaged frame's nearest point: doubling, since a fill's
#: error grows with how far it reaches from what it was fitted to
DEPTH_EDGES = (0.0, 2.0, 4.0, 8.0, 16.0, 32.0, np.inf)


def spacing(points: np.ndarray) -> float:
    """Median distance from each point to its nearest other point."""
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        raise UserError(f"a frame of {len(points)} point(s) has no spacing; give frames of at least 2 points")
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


def missing_points(truth: np.ndarray, damaged: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """The truth's points absent from the damaged frame: ``truth[mask]`` (mask: True = removed),
    else those farther than MATCH_SHARE x spacing(damaged) from every damaged point."""
    truth = np.asarray(truth, dtype=float)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (len(truth),):
            raise UserError(f"a removal mask of {mask.shape[0]} entries for a truth frame of {len(truth)} points; "
                            "use the masks.npz written with these damaged frames")
        return truth[mask]
    d, _ = cKDTree(np.asarray(damaged, dtype=float)).query(truth, k=1)
    return truth[d > MATCH_SHARE * spacing(damaged)]


def _tangents(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane orthogonal to each (unit) normal."""
    axis = np.eye(3)[np.argmin(np.abs(normals), axis=1)]  # the axis least aligned with n
    t1 = np.cross(normals, axis)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(normals, t1)


def oracle_fill(truth: np.ndarray, damaged: np.ndarray, variant: str, *, mask: np.ndarray | None = None,
                sigma: float = 0.0, seed: int = 0, k: int = DEFAULT_NEIGHBOURS) -> np.ndarray:
    """``damaged`` with the hole filled by the oracle ``variant`` (module docstring): (N, 3)."""
    from dpcbench.metrics.neighbours import estimate_normals

    if variant not in VARIANTS:
        raise UserError(f"oracle variant {variant!r}: expected one of {', '.join(VARIANTS)}")
    damaged = np.asarray(damaged, dtype=float)
    if variant == "none":
        return damaged
    truth = np.asarray(truth, dtype=float)
    hole = missing_points(truth, damaged, mask)
    if variant == "truth" or not len(hole):
        return np.vstack([damaged, hole])
    rng = np.random.default_rng(seed)
    tree = cKDTree(truth)
    normals = estimate_normals(truth, k, queries=hole, tree=tree)
    if variant in ("surface", "smooth"):
        s = spacing(damaged)
        t1, t2 = _tangents(normals)
        u, v = rng.uniform(-s / 2, s / 2, (2, len(hole), 1))
        fill = hole + u * t1 + v * t2
        if variant == "smooth":
            from dpcbench.methods._front_fill import local_quadric

            fill, _, _ = local_quadric(fill, truth, neighbours=SMOOTH_NEIGHBOURS, support_tree=tree)
    else:  # jitter
        if not (np.isfinite(sigma) and sigma >= 0):
            raise UserError(f"oracle jitter: sigma must be a distance >= 0, got {sigma!r}")
        fill = hole + rng.normal(0.0, sigma, (len(hole), 1)) * normals
    return np.vstack([damaged, fill])


def fill_offsets(truth: np.ndarray, damaged: np.ndarray, result: np.ndarray,
                 k: int = DEFAULT_NEIGHBOURS) -> tuple[np.ndarray, np.ndarray]:
    """(mask (R,) of the ``result``'s fill points: those farther than MATCH_SHARE x spacing(damaged) from every
    damaged point; their point-to-plane distances (F,) to the truth, ``|(p - q) . n_q|``, q the nearest truth point
    and n_q the truth's PCA normal of its ``k`` nearest points there)."""
    is_fill, distance, _ = _fill_offsets_and_depths(truth, damaged, result, k)
    return is_fill, distance


def _fill_offsets_and_depths(truth, damaged, result, k):
    """`fill_offsets`, and each fill point's depth (F,): its distance to the nearest damaged point."""
    from dpcbench.metrics.neighbours import estimate_normals

    truth, result = np.asarray(truth, dtype=float), np.asarray(result, dtype=float)
    d, _ = cKDTree(np.asarray(damaged, dtype=float)).query(result, k=1)
    is_fill = d > MATCH_SHARE * spacing(damaged)
    fill = result[is_fill]
    if not len(fill):
        return is_fill, np.zeros(0), np.zeros(0)
    tree = cKDTree(truth)
    _, nearest = tree.query(fill, k=1)
    normals = estimate_normals(truth, k, queries=truth[nearest], tree=tree)
    return is_fill, np.abs(np.einsum("ij,ij->i", fill - truth[nearest], normals)), d[is_fill]


def off_surface_by_depth(truth: list[np.ndarray], damaged: list[np.ndarray], results: list[np.ndarray],
                         edges=DEPTH_EDGES, k: int = DEFAULT_NEIGHBOURS) -> list[dict]:
    """How far a method's fill lies off the truth, by how deep into the hole it lies. Over all frames, each of the
    ``results``' fill points (`fill_offsets`) with its off-surface distance o = ``|(p - q) . n_q|`` and its depth
    d = the distance to the nearest point of its damaged frame, both in spacings of that frame
    (`metrics.neighbours.point_spacing`), pooled into the bins [edges[i], edges[i + 1]) of d. Returns one dict per
    bin that holds a point: ``low``, ``high`` (spacings), ``points``, ``off_rms`` = sqrt(mean o^2) and ``off_p90``
    (the 90th percentile of o), in spacings.

    A fill is judged by its hold-out at the rim, a few spacings deep; this shows what it does deeper in, where
    nothing it was tested on lies."""
    from dpcbench.metrics.neighbours import point_spacing

    if not len(truth) == len(damaged) == len(results):
        raise UserError(f"{len(truth)} truth frame(s), {len(damaged)} damaged and {len(results)} result frame(s); "
                        "give the truth, the damage and a method's result of the same sequence")
    offs, depths = [], []
    for t, d, r in zip(truth, damaged, results):
        unit = point_spacing(np.asarray(d, dtype=float))
        _, off, depth = _fill_offsets_and_depths(t, d, r, k)
        offs.append(off / unit)
        depths.append(depth / unit)
    off, depth = np.concatenate(offs), np.concatenate(depths)
    rows = []
    for low, high in zip(edges[:-1], edges[1:]):
        at = (depth >= low) & (depth < high)
        if at.any():
            rows.append({"low": float(low), "high": float(high), "points": int(at.sum()),
                         "off_rms": float(np.sqrt(np.mean(off[at] ** 2))), "off_p90": float(np.quantile(off[at], 0.9))})
    return rows


def off_surface_rms(truth: np.ndarray, damaged: np.ndarray, result: np.ndarray,
                    k: int = DEFAULT_NEIGHBOURS) -> tuple[float, int]:
    """(RMS point-to-plane distance of the result's fill points to the truth (`fill_offsets`), their count);
    (nan, 0) when the result adds no point."""
    _, distance = fill_offsets(truth, damaged, result, k)
    if not len(distance):
        return float("nan"), 0
    return float(np.sqrt(np.mean(distance ** 2))), len(distance)


def refused_fill(truth: np.ndarray, damaged: np.ndarray, result: np.ndarray, limit: float,
                 k: int = DEFAULT_NEIGHBOURS) -> np.ndarray:
    """The method's ``result`` (R, 3) without the fill points whose point-to-plane distance to the truth
    (`fill_offsets`) is ``limit`` (coordinate units) or more, in the result's row order: (M, 3) (module docstring,
    the refusal oracle)."""
    return refused_fills(truth, damaged, result, [limit], k)[0]


def refused_fills(truth: np.ndarray, damaged: np.ndarray, result: np.ndarray, limits,
                  k: int = DEFAULT_NEIGHBOURS) -> list[np.ndarray]:
    """`refused_fill` at each of ``limits`` (coordinate units), the fill points' offsets measured once."""
    limits = [float(x) for x in limits]
    for limit in limits:
        if not (np.isfinite(limit) and limit > 0):
            raise UserError(f"refusal oracle: the limit must be a distance > 0, got {limit!r}")
    is_fill, distance = fill_offsets(truth, damaged, result, k)
    rows, result = np.flatnonzero(is_fill), np.asarray(result, dtype=float)
    kept = []
    for limit in limits:
        keep = np.ones(len(result), dtype=bool)
        keep[rows[distance >= limit]] = False
        kept.append(result[keep])
    return kept


def d2_break_even(truth: list[np.ndarray], damaged: list[np.ndarray], *, masks: list | None = None,
                  seed: int = 0, peak="intrinsic", reference_normals=None, iterations: int = 12) -> dict:
    """The jitter oracle's sigma (coordinate units) at which the mean whole-frame D2 over the frames equals no
    fill's (module docstring), found by bisection on log sigma (the jitter of frame f uses seed ``seed + f``, as
    `score_oracles`; with its noise directions fixed its D2 falls as sigma grows). Returns {"sigma", "spacing"
    (the damaged frames' mean `metrics.neighbours.point_spacing`: median 8th-neighbour distance / sqrt 2, one voxel
    on voxelized data, the unit of temporal-fusion's bounds), "none_d2", "jitter_d2" (at sigma)}; sigma is 0 when no
    fill already scores infinite D2 (nothing missing, or a flat hole whose hidden points all lie in their rim
    neighbours' tangent planes) and inf when even 100 spacings keep the jitter at or above it."""
    from dpcbench import metrics as metrics_pkg
    from dpcbench.metrics.neighbours import point_spacing

    if len(truth) != len(damaged):
        raise UserError(f"{len(truth)} truth frame(s) and {len(damaged)} damaged frame(s); give sequences of the "
                        "same length")
    normals = reference_normals or [None] * len(truth)

    def mean_d2(sigma: float | None) -> float:
        values = []
        for f, (t, d) in enumerate(zip(truth, damaged)):
            filled = d if sigma is None else oracle_fill(t, d, "jitter", mask=None if masks is None else masks[f],
                                                         sigma=sigma, seed=seed + f)
            values.append(metrics_pkg.score_frame(t, filled, ["gpsnr_d2"], peak=peak,
                                                  reference_normals=normals[f])["gpsnr_d2"])
        return float(np.mean(values))

    step = float(np.mean([point_spacing(np.asarray(d, dtype=float)) for d in damaged]))
    floor = mean_d2(None)
    result = {"spacing": step, "none_d2": floor}
    if not np.isfinite(floor):
        return {**result, "sigma": 0.0, "jitter_d2": floor}
    low, high = 1e-4 * step, 100.0 * step
    if mean_d2(high) >= floor:
        return {**result, "sigma": float("inf"), "jitter_d2": float("nan")}
    low_d2 = mean_d2(low)
    if low_d2 < floor:
        return {**result, "sigma": 0.0, "jitter_d2": float("nan")}
    for _ in range(iterations):
        middle = float(np.sqrt(low * high))
        middle_d2 = mean_d2(middle)
        if middle_d2 >= floor:
            low, low_d2 = middle, middle_d2
        else:
            high = middle
    return {**result, "sigma": low, "jitter_d2": low_d2}


def score_oracles(truth: list[np.ndarray], damaged: list[np.ndarray], variants=VARIANTS, *,
                  masks: list | None = None, regions: list | None = None, sigma: float = 0.0, seed: int = 0,
                  metrics=("gpsnr_d1", "gpsnr_d2", "nshd"), peak="intrinsic", reference_normals=None) -> dict:
    """variant -> {"frame": `metrics.score_sequence` of the filled frames against the truth, whole
    frames, and "holes": the same in ``regions`` (when given)}. Frame f of variant v is filled with
    seed ``seed + f``."""
    if len(truth) != len(damaged):
        raise UserError(f"{len(truth)} truth frame(s) and {len(damaged)} damaged frame(s); give sequences of the "
                        "same length")
    out = {}
    for variant in variants:
        filled = [oracle_fill(t, d, variant, mask=None if masks is None else masks[f], sigma=sigma, seed=seed + f)
                  for f, (t, d) in enumerate(zip(truth, damaged))]
        out[variant] = _scores(truth, filled, metrics, peak, regions, reference_normals)
    return out


def _scores(truth: list[np.ndarray], frames: list[np.ndarray], metrics, peak, regions, reference_normals) -> dict:
    """{"frame": `metrics.score_sequence` of ``frames`` against ``truth``, whole frames, and with ``regions`` "holes":
    the same in them}."""
    from dpcbench import metrics as metrics_pkg

    scores = {"frame": metrics_pkg.score_sequence(truth, frames, list(metrics), peak=peak,
                                                  reference_normals=reference_normals)}
    if regions is not None:
        scores["holes"] = metrics_pkg.score_sequence(truth, frames, list(metrics), peak=peak, regions=regions,
                                                     reference_normals=reference_normals)
    return scores


def score_refusals(truth: list[np.ndarray], damaged: list[np.ndarray], results: list[np.ndarray], limits, *,
                   regions: list | None = None, metrics=("gpsnr_d1", "gpsnr_d2", "nshd"), peak="intrinsic",
                   reference_normals=None) -> dict:
    """label -> {"frame", and with ``regions`` "holes": `metrics.score_sequence` against the truth} for the method's
    ``results`` as they are ("method") and, for each of ``limits`` (spacings of each damaged frame,
    `metrics.neighbours.point_spacing`), the refusal oracle at it ("refusal < L s", `refused_fill`)."""
    from dpcbench.metrics.neighbours import point_spacing

    if not len(truth) == len(damaged) == len(results):
        raise UserError(f"{len(truth)} truth frame(s), {len(damaged)} damaged and {len(results)} result frame(s); "
                        "give the truth, the damage and a method's result of the same sequence")
    limits = [float(x) for x in limits]
    bad = [x for x in limits if not (np.isfinite(x) and x > 0)]
    if bad:
        raise UserError(f"refusal limit {bad[0]!r}: give distances > 0, in spacings")
    # per frame, the result at every limit (in that frame's spacings), its fill points' offsets measured once
    refused = [refused_fills(t, d, r, [limit * point_spacing(np.asarray(d, dtype=float)) for limit in limits])
               for t, d, r in zip(truth, damaged, results)]
    sets = {"method": [np.asarray(r, dtype=float) for r in results]}
    for i, limit in enumerate(limits):
        sets[f"refusal < {limit:g} s"] = [frame[i] for frame in refused]
    return {label: _scores(truth, frames, metrics, peak, regions, reference_normals) for label, frames in sets.items()}


def score_colour_oracles(truth: list[np.ndarray], truth_colours: list[np.ndarray], damaged: list[np.ndarray],
                         damaged_colours: list[np.ndarray], fills=COLOUR_FILLS, *, masks: list | None = None,
                         regions: list | None = None, metrics=("cpsnr_y", "cpsnr_u", "cpsnr_v")) -> dict:
    """fill -> {"frame": `metrics.score_sequence` of the coloured truth oracle against the truth, whole frames, and
    "holes": the same in ``regions`` (when given)} (module docstring). truth (N_f, 3) and truth_colours (N_f, 3)
    uint8 per frame; damaged (M_f, 3) and damaged_colours (M_f, 3) uint8 per frame: the damaged points keep their
    colours, the missing truth points take ``fill``'s colours from the damaged frame."""
    from dpcbench import metrics as metrics_pkg
    from dpcbench.methods._colour import colour_frame

    unknown = [f for f in fills if f not in COLOUR_FILLS]
    if unknown:
        raise UserError(f"colour oracle fill {unknown[0]!r}: expected one of {', '.join(COLOUR_FILLS)}")
    if not len(truth) == len(truth_colours) == len(damaged) == len(damaged_colours):
        raise UserError(f"{len(truth)} truth frame(s) and {len(damaged)} damaged frame(s), {len(truth_colours)} and "
                        f"{len(damaged_colours)} with colours; give sequences of the same length, coloured")
    filled = [oracle_fill(t, d, "truth", mask=None if masks is None else masks[f])
              for f, (t, d) in enumerate(zip(truth, damaged))]
    out = {}
    for fill in fills:
        colours = [colour_frame(np.asarray(d, dtype=float), np.asarray(c), p, fill=fill)
                   for d, c, p in zip(damaged, damaged_colours, filled)]
        scores = {"frame": metrics_pkg.score_sequence(truth, filled, list(metrics), reference_colours=truth_colours,
                                                      result_colours=colours)}
        if regions is not None:
            scores["holes"] = metrics_pkg.score_sequence(truth, filled, list(metrics), regions=regions,
                                                         reference_colours=truth_colours, result_colours=colours)
        out[fill] = scores
    return out
