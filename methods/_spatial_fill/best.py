"""The last resort of `temporal-fusion`'s spatial cascade (`BestSurface` in `methods.temporal_fusion.spatial`): where
every strategy refused a hole, the surface that predicts the hole's edge best, unless leaving the hole open is
predicted to cost less.

The cascade's strategies refuse a surface they cannot trust (its hold-out miss over a bound of one spacing, a rim
that is no height field, ...): the refused hole stays open. An open hole costs its hidden points their squared
distance to the nearest captured point (D1's point-to-point error), which on a hole of radius r is of order r^2 / 2;
an imperfect surface costs them about its own squared error. So a refusal is decided here by comparing the two
predicted costs, each measured on the data round the hole, not by a fixed bound:

- candidates: the thin-plate-spline height field of the rim (`rim_surface_fill`), the same on the hole's own sheet
  (`rim_sheet`), and the screened Poisson surface of the crop (`poisson_surface_fill`), each without its refusal
  tests;
- the fill's predicted error m: a candidate's hold-out miss, the RMS distance of the inner ring (the support points
  within ``ring`` of the region) to the same candidate built without them (`holdout_miss`): the error of the surface
  where it had to bridge a gap, measured on points it did not see;
- the open hole's predicted error o: the RMS distance of the candidate's own fill points (a sample of the hidden
  surface as far as the candidate knows it) to the nearest captured point;
- the candidate with the least m fills what it reaches when m < o; the next ones, in order of m and built on what
  the ones before filled, fill only what is still open, each under the same rule; a hole no candidate passes stays
  open.

This rule fills where D1 gains. Where the surface is flat round the hole, an open hole's point-to-plane error (D2)
is small, so a fill more than about a spacing off the surface can score less D2 than the open hole
(`bench.results.oracle.d2_break_even` measures that bound on a damaged frame with its truth).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill.common import grown_agreeing
from dpcbench.methods._spatial_fill.poisson import poisson_surface_fill
from dpcbench.methods._spatial_fill.spline import rim_sheet, rim_surface_fill

#: a candidate surface: (support (K, 3), fill function (support, region, covered tree or None) -> points (P, 3))
Candidate = tuple[np.ndarray, Callable[[np.ndarray, object, "cKDTree | None"], np.ndarray]]


class GrownRegion:
    """``region`` grown by ``margin``: what `HoleRegion.contains` with that margin holds, with the centre, a bounding
    radius and the shape's size grown as much (what the fills read of a region: the ball's radius or the box's half
    extents, for a superset test such as `poisson._triangles_near`; the exact test is ``contains``)."""

    def __init__(self, region: HoleRegion, margin: float) -> None:
        self.region, self.margin = region, float(margin)
        self.shape, self.center, self.rotation = region.shape, region.center, region.rotation
        self.bounding_radius = region.bounding_radius + self.margin
        self.radius = region.radius + self.margin
        self.half_extents = None if region.half_extents is None else region.half_extents + self.margin

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        return self.region.contains(points, margin=self.margin + margin)


def candidates(rim: np.ndarray, crop: np.ndarray, region: HoleRegion, spacing: float, *, voxelized: bool, step: float,
               gap_spacings: float, ring: float, sheet: bool = True, closed: bool = True) -> dict[str, Candidate]:
    """The candidate surfaces by name, without their refusal tests (no hold-out, no height-field bound): the spline
    on ``rim`` (the rim and the copies, as step 6), with ``sheet`` the same on the hole's own sheet of it where
    ``region``'s edge is one sheet (`rim_sheet`, as step 6f), with ``closed`` the closed surface on ``crop`` (the crop
    and the accepted points, as step 6c)."""

    def spline(support, region, covered):
        return rim_surface_fill(support, region, covered, spacing, voxelized=voxelized, step=step, max_steep=1.0,
                                gap_spacings=gap_spacings, ring=0.0)

    def poisson(support, region, covered):
        return poisson_surface_fill(support, region, covered, spacing, voxelized=voxelized, step=step,
                                    gap_spacings=gap_spacings, ring=0.0)

    surfaces: dict[str, Candidate] = {"spline": (rim, spline)}
    narrowed = rim_sheet(rim, region, ring, spacing) if sheet else None
    if narrowed is not None:
        surfaces["sheet"] = (narrowed, spline)
    if closed:
        surfaces["closed"] = (crop, poisson)
    return surfaces


def holdout_miss(candidate: Candidate, region: HoleRegion, ring: float) -> float:
    """RMS distance of the inner ring (the points of the candidate's support within ``ring`` of ``region``) to the
    fill the candidate makes of ``region`` grown by ``ring`` from the rest of its support; inf when the ring or the
    rest is too small to judge (fewer than 6 / 12 points) or the candidate makes nothing there."""
    support, fill = candidate
    inner = region.contains(support, margin=ring)
    if inner.sum() < 6 or (~inner).sum() < 12:
        return float("inf")
    surface = fill(support[~inner], GrownRegion(region, ring), None)
    if not len(surface):
        return float("inf")
    distance, _ = cKDTree(surface).query(support[inner])
    return float(np.sqrt(np.mean(distance ** 2)))


def best_surface_fill(captured: cKDTree, region: HoleRegion, covered: cKDTree, surfaces: dict[str, Candidate],
                      ring: float, spacing: float) -> tuple[list[str], np.ndarray]:
    """(names of the candidates that filled, in order; their fill (P, 3)) for ``region``. ``captured``: what the
    output holds round the hole already (the frame's points and the fill so far), from which the open part's error
    is measured; ``covered``: what a new point must keep its gap from.

    The candidates of ``surfaces`` are ranked by `holdout_miss`, least first (those that make nothing in the region
    are dropped). Each in turn, built on its support plus what the ones before it filled, fills what is still open
    (farther than its gap from ``covered`` and from those fills) when its miss is below the open part's predicted
    error, the RMS distance of its new points to ``captured`` and those fills: the best surface fills what it reaches, and the next
    ones only the parts it left open (a Poisson surface that closes one side of a fold, a spline across the rest),
    and only where they continue it (`grown_agreeing` from the fills so far, reach 3 spacings as step 4, tolerance
    the surface's own miss, at least a spacing). Nothing when no candidate passes."""
    ranked = []
    alone = {}  # each candidate's fill on its own support: the first to fill reuses it (a Poisson solve is costly)
    for name, (support, fill) in surfaces.items():
        alone[name] = fill(support, region, covered)
        if len(alone[name]):
            ranked.append((holdout_miss(surfaces[name], region, ring), name))
    names: list[str] = []
    filled = np.zeros((0, 3))
    for miss, name in sorted(ranked):
        support, fill = surfaces[name]
        if not len(filled):
            points = alone[name]
        else:
            points = fill(np.vstack([support, filled]), region, cKDTree(np.vstack([covered.data, filled])))
        if len(filled) and len(points):
            # a later surface only continues what the better ones filled: grown from their fill, each point within the
            # surface's own predicted error of its local plane (grown from the data too, a closed surface's rounding
            # of a corner between the hole's floor and a wall beside it passed as a continuation of the wall)
            points = points[grown_agreeing(points, filled, 3 * spacing, max(miss, spacing))]
        if not len(points):
            continue
        held = captured if not len(filled) else cKDTree(np.vstack([captured.data, filled]))
        if not miss < float(np.sqrt(np.mean(held.query(points)[0] ** 2))):
            continue
        names.append(name)
        filled = np.vstack([filled, points])
    return names, filled
