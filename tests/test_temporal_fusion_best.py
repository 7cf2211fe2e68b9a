"""temporal-fusion's last resort (`methods/_spatial_fill/best.py`, strategy `BestSurface`): the hold-out miss on
closed-form surfaces, the rule that ranks candidates and leaves a hole open only where that is predicted cheaper,
only the best passing candidate fills, and its place in the method (a hole every other strategy refuses)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._spatial_fill.best import best_surface_fill, candidates, holdout_miss
from dpcbench.methods.temporal_fusion import TemporalFusion


def plane(half: int = 20, height=lambda u, v: 0.0 * u) -> np.ndarray:
    g = np.arange(-half, half + 1, dtype=float)
    u, v = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    return np.column_stack([u, v, height(u, v)])


def holed(points: np.ndarray, region: HoleRegion) -> np.ndarray:
    return points[~region.contains(points)]


HOLE = HoleRegion(shape="ball", center=np.zeros(3), radius=6.0)
RING = 2.0


def holding_out(region):
    """Whether a stub surface is called for the hold-out (`holdout_miss` builds it on the region grown by the ring)."""
    return region.radius == HOLE.radius + RING


def rim_and_crop(points):
    crop = points[np.linalg.norm(points - HOLE.center, axis=1) <= HOLE.radius + 2 * 4.0]
    return crop[HOLE.contains(crop, margin=4.0)], crop


def test_the_spline_predicts_a_plane_s_inner_ring_exactly_and_a_wrong_surface_misses_it_by_its_offset():
    """On a plane every candidate surface built without the inner ring passes through it (miss ~ 0); a surface
    lying 5 units off the plane misses the ring by 5."""
    rim, crop = rim_and_crop(holed(plane(), HOLE))
    surfaces = candidates(rim, crop, HOLE, 1.0, voxelized=True, step=1.0, gap_spacings=1.0, ring=RING)
    assert holdout_miss(surfaces["spline"], HOLE, RING) < 0.1

    def lifted(support, region, covered):
        return plane(12)[region.contains(plane(12))] + [0.0, 0.0, 5.0]

    assert abs(holdout_miss((rim, lifted), HOLE, RING) - 5.0) < 1e-9
    # too little support to judge: inf
    assert holdout_miss((rim[:5], lifted), HOLE, RING) == float("inf")


def test_the_hold_out_of_a_flat_box_reaches_the_grown_box_s_corners():
    """A flat box hole (half extents 6, 6, 1) in a plane: the spline built without the inner ring covers the whole
    grown box, its corners included (they lie 11.3 from the centre, beyond |h| + ring = 10.5), so it passes through
    every ring point (miss ~ 0)."""
    box = HoleRegion.box([0.0, 0.0, 0.0], [6.0, 6.0, 1.0])
    crop = holed(plane(), box)
    rim = crop[box.contains(crop, margin=4.0)]
    surfaces = candidates(rim, crop, box, 1.0, voxelized=True, step=1.0, gap_spacings=1.0, ring=RING)
    assert holdout_miss(surfaces["spline"], box, RING) < 0.1


def test_the_last_resort_fills_a_curved_hole_on_its_surface():
    """A paraboloid z = (u^2 + v^2) / 40 with a ball hole: the fill covers every hidden voxel within 1.5 and lies
    within a voxel of the surface."""
    truth = plane(height=lambda u, v: np.round((u ** 2 + v ** 2) / 40.0))
    rim, crop = rim_and_crop(holed(truth, HOLE))
    surfaces = candidates(rim, crop, HOLE, 1.0, voxelized=True, step=1.0, gap_spacings=1.0, ring=RING)
    name, fill = best_surface_fill(cKDTree(crop), HOLE, surfaces, RING)
    hidden = truth[HOLE.contains(truth)]
    assert name is not None and len(fill)
    # every candidate is judged, the closed surface's hold-out (built on the grown region) included
    assert all(holdout_miss(surfaces[name], HOLE, RING) <= 1.0 for name in ("spline", "closed"))
    assert (cKDTree(fill).query(hidden)[0] <= 1.5).all()
    assert cKDTree(truth).query(fill)[0].max() <= 1.0


def test_a_surface_that_misses_its_ring_by_more_than_the_open_hole_s_error_leaves_the_hole_open():
    """The rule: a candidate fills only when its hold-out miss is below the RMS distance of its points to the data.
    A surface whose hold-out lies 50 units off but whose fill hugs the data (open error < 1) is refused; the same
    surface with a hold-out of 0.2 fills."""
    rim, crop = rim_and_crop(holed(plane(), HOLE))
    near_data = np.array([[6.4, 0.0, 0.5], [-6.4, 0.0, 0.5]])  # inside the region, half a unit off the rim

    def surface(miss):
        def fill(support, region, covered):
            if holding_out(region):  # the hold-out: a surface `miss` above the inner ring
                return support[:0] if not len(support) else np.vstack([crop[HOLE.contains(crop, margin=RING)]
                                                                       + [0.0, 0.0, miss]])
            return near_data
        return fill

    for miss, expected in ((50.0, None), (0.2, "wrong")):
        name, fill = best_surface_fill(cKDTree(crop), HOLE, {"wrong": (rim, surface(miss))}, RING)
        assert name == expected and len(fill) == (0 if expected is None else 2)


def test_only_the_best_surface_that_passes_fills_and_a_worse_one_does_not_fill_what_it_left_open():
    """The better candidate (hold-out miss 0) fills the half x < 0 of a flat hole; the worse one (miss 0.5) would
    fill all of it and is not used, so the other half stays open. When the better one does not pass (its points hug
    the data: open error below its miss), the worse one fills."""
    rim, crop = rim_and_crop(holed(plane(), HOLE))
    hidden = plane()[HOLE.contains(plane())]

    def half(support, region, covered):
        points = plane(12)[region.contains(plane(12))]
        return points if holding_out(region) else points[points[:, 0] < 0]

    def whole(support, region, covered):
        points = plane(12)[region.contains(plane(12))]
        return points + [0.0, 0.0, 0.5] if holding_out(region) else points

    name, fill = best_surface_fill(cKDTree(crop), HOLE, {"whole": (rim, whole), "half": (rim, half)}, RING)
    assert name == "half"
    assert np.array_equal(fill, half(rim, HOLE, None))
    assert (hidden[:, 0] >= 0).any() and cKDTree(fill).query(hidden[hidden[:, 0] > 1])[0].min() > 1.0  # left open

    def hugging(support, region, covered):  # miss 0.3, but its one point is 0.1 from the data: open error 0.1
        return plane(12)[region.contains(plane(12))] + [0.0, 0.0, 0.3] if holding_out(region) else \
            np.array([[6.9, 0.0, 0.0]])

    name, fill = best_surface_fill(cKDTree(crop), HOLE, {"whole": (rim, whole), "hugging": (rim, hugging)}, RING)
    assert name == "whole" and np.array_equal(fill, whole(rim, HOLE, None))


def test_temporal_fusion_fills_a_hole_its_strategies_refuse_only_with_the_last_resort():
    """With every strategy's hold-out bound at 1e-9 spacings (each refuses; the cap and membrane off), the one-frame hole stays open without
    the last resort and is filled with it."""
    truth = plane(height=lambda u, v: np.round((u ** 2 + v ** 2) / 40.0))
    frame = holed(truth, HOLE)
    strict = dict(surface_holdout_spacings=1e-9, rim_fill=False, cap=False, membrane=False)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a one-frame sequence: the spatial fill only
        off = TemporalFusion(best_surface=False, **strict).inpaint([frame], [[HOLE]])[0]
        on = TemporalFusion(**strict).inpaint([frame], [[HOLE]])[0]
    assert len(off) == len(frame)
    hidden = truth[HOLE.contains(truth)]
    assert (cKDTree(on).query(hidden)[0] <= 1.5).all()
