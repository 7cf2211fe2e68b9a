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
- the candidates are tried in order of m, least first, and the first with m < o fills what it reaches; the others
  fill nothing, not even what it left open; a hole no candidate passes stays open.

This rule fills where D1 gains. Where the surface is flat round the hole, an open hole's point-to-plane error (D2)
is small, so a fill more than about a spacing off the surface can score less D2 than the open hole
(`bench.results.oracle.d2_break_even` measures that bound on a damaged frame with its truth).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill.poisson import poisson_surface_fill
from dpcbench.methods._spatial_fill.spline import rim_sheet, rim_surface_fill

#: a candidate surface: (support (K, 3), fill function (support, region, covered tree or None) -> points (P, 3))
Candidate = tuple[np.ndarray, Callable[[np.ndarray, object, "cKDTree | None"], np.ndarray]]


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
    surface = fill(support[~inner], region.grown(ring), None)
    if not len(surface):
        return float("inf")
    distance, _ = cKDTree(surface).query(support[inner])
    return float(np.sqrt(np.mean(distance ** 2)))


def best_surface_fill(covered: cKDTree, region: HoleRegion, surfaces: dict[str, Candidate], ring: float
                      ) -> tuple[str | None, np.ndarray]:
    """(the name of the candidate that filled, None when none did; its fill (P, 3)) for ``region``. ``covered``: what
    the output holds round the hole already (the frame's points and the fill so far): the open part's error is
    measured from it, and a new point keeps its gap from it.

    The candidates of ``surfaces`` are ranked by `holdout_miss`, least first (those that make nothing in the region
    are dropped); the first whose miss is below the open part's predicted error, the RMS distance of its new points
    to ``covered``, fills what it reaches (farther than its gap from ``covered``), and the rest of the hole stays
    open. A worse-ranked candidate does not fill what the better one left open: measured on one-frame Longdress
    damages, such a continuation lay off the surface by more than the open hole's own error (docs/temporal-fusion.md,
    "Version 56")."""
    # each candidate's own fill is made only when its turn comes: once one fills, the rest are not needed (a closed
    # surface's fill is a Poisson solve)
    for miss, name in sorted((holdout_miss(candidate, region, ring), name) for name, candidate in surfaces.items()):
        support, fill = surfaces[name]
        points = fill(support, region, covered)
        if len(points) and miss < float(np.sqrt(np.mean(covered.query(points)[0] ** 2))):
            return name, points
    return None, np.zeros((0, 3))
