"""The steps of temporal-graph / fu-nonlocal one by one, each on a closed-form or tiny case.

Order of the pipeline (methods/temporal_graph.py): cubes (hole cells, groups, target order), sources
(features, candidates, inter-source window), alignment, new points, graph, solve, post-processing.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._cubes import (
    CellGrid,
    TargetCubeOrder,
    block_sums,
    hole_cells,
    region_groups,
)
from dpcbench.methods._graph import knn_laplacian, solve_cube, spatial_laplacian, temporal_links
from dpcbench.methods._registration import align_best
from dpcbench.methods.temporal_graph import (
    CandidateCubes,
    CubeFill,
    FrameContext,
    LocalPoints,
    NeighbourFrame,
    cube_unit,
    drop_contradicted_rows,
    finish_frame,
    inter_source,
    intra_source,
    normal_features,
    select_new_points,
    voxelize_fill,
)


def fibonacci_sphere(radius=20.0, n=4000, center=(0.0, 0.0, 0.0)):
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    theta = np.pi * (1 + 5 ** 0.5) * k
    pts = np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])
    return radius * pts + np.asarray(center)


def rotation_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# -- cubes: hole cells, groups of holes, the order of the target cubes ------------------------------

def test_hole_cells_are_the_cells_whose_centre_is_within_the_region_plus_half_a_diagonal():
    grid = CellGrid(np.zeros(3), np.full(3, 20.0), cell=2.0, cells_per_cube=4)
    region = HoleRegion.ball([9.3, 10.1, 8.7], 3.5)
    got = hole_cells(grid, [region])
    want = np.zeros(tuple(grid.shape), dtype=bool)
    for idx in itertools.product(*[range(n) for n in grid.shape]):
        centre = grid.origin + (np.array(idx) + 0.5) * grid.cell
        want[idx] = np.linalg.norm(centre - region.center) <= 3.5 + np.sqrt(3.0)
    np.testing.assert_array_equal(got, want)
    assert got.sum() > 0


def test_region_groups_join_regions_closer_than_twice_the_reach():
    a, b = HoleRegion.ball([0.0, 0, 0], 2.0), HoleRegion.ball([10.0, 0, 0], 2.0)  # gap 10 - 4 = 6
    c = HoleRegion.ball([100.0, 0, 0], 2.0)
    assert region_groups([a, c, b], reach=3.0) == [[a, b], [c]]  # 6 <= 2 * 3: joined
    assert region_groups([a, c, b], reach=2.9) == [[a], [c], [b]]


def rim_case():
    """Cells per cube 4 on a (7, 4, 4) window (anchors x = 0..3): known points in the slabs x = 0, 1, 2
    (1, 2 and 3 points a cell), the slab x = 3 missing (pending)."""
    known = np.zeros((7, 4, 4), dtype=np.int64)
    known[0], known[1], known[2] = 1, 2, 3
    pending = np.zeros((7, 4, 4), dtype=bool)
    pending[3] = True
    return pending, known


def test_target_order_takes_the_cube_centred_on_the_rim_with_the_most_known_points():
    # known points per cube: a = 0: 16 * 6 = 96, a = 1: 80, a = 2: 48, a = 3: 0; the missing slab
    # x = 3 lies in the central cells (a + 1, a + 2) of the cubes a = 1 and a = 2 only
    pending, known = rim_case()
    order = TargetCubeOrder(pending.copy(), known.copy(), 4, min_known_points=10, rim_centred=True)
    np.testing.assert_array_equal(order.known_sums[:, 0, 0], [96, 80, 48, 0])
    first = order.next()
    np.testing.assert_array_equal(first, [1, 0, 0])
    order.filled(first, np.empty((0, 3), dtype=np.int64))
    assert order.next() is None  # its cells covered the whole missing slab
    # without rim-centring: the cube with the most known points and any missing cell
    plain = TargetCubeOrder(pending.copy(), known.copy(), 4, min_known_points=10, rim_centred=False)
    np.testing.assert_array_equal(plain.next(), [0, 0, 0])
    # too few known points anywhere: no target cube
    assert TargetCubeOrder(pending.copy(), known.copy(), 4, min_known_points=97, rim_centred=False).next() is None


def test_target_order_counts_new_points_and_keeps_its_sums_equal_to_a_full_recount():
    rng = np.random.default_rng(0)
    pending = rng.random((9, 8, 7)) < 0.2
    known = rng.integers(0, 4, size=(9, 8, 7))
    order = TargetCubeOrder(pending.copy(), known.copy(), 4, min_known_points=5, rim_centred=True)
    picks = []
    while (pick := order.next()) is not None and len(picks) < 6:
        picks.append(tuple(pick))
        new_cells = pick + rng.integers(0, 4, size=(20, 3))  # new points lie in the target cube
        order.filled(pick, new_cells)
        np.testing.assert_array_equal(order.known_sums, block_sums(order.known, 4))
        np.testing.assert_array_equal(order.pending_sums, block_sums(order.pending.astype(np.int64), 4))
        np.testing.assert_array_equal(order.central_sums, block_sums(order.pending[1:-1, 1:-1, 1:-1].astype(np.int64), 2))
        assert not order.pending[order.block(pick)].any()
    assert len(set(picks)) == len(picks) >= 2  # each cube is a target at most once
    assert order.known.sum() > known.sum()


def test_a_deferred_cube_returns_once_it_holds_more_known_points():
    known = np.zeros((7, 8, 4), dtype=np.int64)
    known[0, 0, 0] = 20  # the only points of cube (0, 0, 0): two cells away from the missing slab
    pending = np.zeros((7, 8, 4), dtype=bool)
    pending[3] = True
    order = TargetCubeOrder(pending, known, 4, min_known_points=10, rim_centred=False)
    pick = order.next()
    np.testing.assert_array_equal(pick, [0, 0, 0])
    assert not order.reaches_pending(pick)
    order.defer(pick)
    assert order.next() is None  # put off: nothing else has enough points
    # a fill of the cube (3, 3, 0) brings a point next to the slab, inside cube (0, 0, 0)
    order.filled(np.array([3, 3, 0]), np.array([[2, 3, 0]]))
    again = order.next()
    np.testing.assert_array_equal(again, [0, 0, 0])
    assert order.reaches_pending(again)


# -- sources: features, candidates, the inter-source window -----------------------------------------

def test_normal_features_on_a_plane_and_a_sphere():
    i, j = np.meshgrid(np.arange(30.0), np.arange(30.0), indexing="ij")
    plane = np.column_stack([i.ravel(), j.ravel(), np.full(i.size, 5.0)])
    normals, agtv = normal_features(plane, cKDTree(plane), sigma=1.0, feature_fraction=1.0)
    np.testing.assert_allclose(np.abs(normals[:, 2]), 1.0, atol=1e-9)
    np.testing.assert_allclose(agtv, 0.0, atol=1e-9)  # no variation of the normal on a plane
    sphere = fibonacci_sphere()
    normals, agtv = normal_features(sphere, cKDTree(sphere), sigma=1.0, feature_fraction=0.25)
    sampled = ~np.isnan(agtv)
    assert sampled.sum() == round(0.25 * len(sphere)) and np.isnan(normals[~sampled]).all()
    radial = sphere[sampled] / 20.0
    assert np.einsum("ij,ij->i", normals[sampled], radial).min() > 0.99  # outward, radial
    assert (agtv[sampled] > 0).all()  # a curved surface varies


def plane_candidates():
    """Points on a grid of the box [0, 32)^3 with the normal +z for x < 16 and +x for x >= 16."""
    axes = [np.arange(0.5, 32.0, 2.0)] * 3
    points = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    normals = np.where(points[:, :1] < 16, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    agtv = np.zeros(len(points))
    grid = CellGrid(points.min(axis=0), points.max(axis=0), cell=2.0, cells_per_cube=4)
    return grid, points, normals, agtv


def test_candidate_features_are_the_means_over_each_cube_and_rank_by_feature_distance():
    grid, points, normals, agtv = plane_candidates()
    cand = CandidateCubes.build(grid, points, normals, agtv, [], min_known_points=64, hole_free=True, agtv_weight=1.0)
    assert len(cand.count) > 0 and (cand.count == 64).all()  # full cubes only: 4^3 cells of one point
    k = 5
    inside = ((points >= cand.lower[k]) & (points < cand.lower[k] + 8.0)).all(axis=1)
    np.testing.assert_allclose(cand.dc[k], normals[inside].mean(axis=0))
    query = np.array([1.0, 0.0, 0.0, 0.0])
    best = cand.ranked(query, 10, np.zeros(3), cube=8.0, cell=2.0, cells_per_cube=4, hole_free=True,
                       agtv_weight=1.0, want=3)
    assert len(best) == 3
    assert (cand.lower[best][:, 0] >= 16).all()  # cubes wholly in the +x half
    assert len(cand.ranked(query, 65, np.zeros(3), cube=8.0, cell=2.0, cells_per_cube=4, hole_free=True,
                           agtv_weight=1.0, want=3)) == 0  # none holds 65 points
    # holes allowed: the cubes overlapping the target cube are never candidates
    target_lower = cand.lower[best[0]]
    near = cand.ranked(query, 10, target_lower, cube=8.0, cell=2.0, cells_per_cube=4, hole_free=False,
                       agtv_weight=1.0, want=50)
    assert (np.abs(cand.lower[near] - target_lower) >= 8.0 - 1.0).any(axis=1).all()


def test_hole_free_candidates_touch_no_hole():
    grid, points, normals, agtv = plane_candidates()
    region = HoleRegion.ball([16.0, 16.0, 16.0], 4.0)
    free = CandidateCubes.build(grid, points, normals, agtv, [region], min_known_points=64, hole_free=True,
                                agtv_weight=1.0)
    every = CandidateCubes.build(grid, points, normals, agtv, [region], min_known_points=64, hole_free=False,
                                 agtv_weight=1.0)
    assert 0 < len(free.count) < len(every.count)
    centre_in = ((free.lower <= region.center) & (region.center < free.lower + 8.0)).all(axis=1)
    assert not centre_in.any()


def test_intra_source_finds_and_aligns_the_patch_that_matches_the_target():
    # two separated patches of one paraboloid: the target is a cube of one, with a hole; the
    # source is the other, which has the same shape
    xy = np.stack(np.meshgrid(np.arange(-4.0, 4.0, 0.25), np.arange(-4.0, 4.0, 0.25), indexing="ij"), -1).reshape(-1, 2)
    bowl = np.column_stack([xy, 0.05 * (xy ** 2).sum(axis=1)])
    source_patch, target_patch = bowl + [40.0, 4.0, 4.0], bowl + [4.0, 4.0, 4.0]
    frame = np.vstack([source_patch, target_patch[np.linalg.norm(xy, axis=1) > 1.5]])
    tree = cKDTree(frame)
    normals, agtv = normal_features(frame, tree, 0.25, 1.0)
    grid = CellGrid(frame.min(axis=0), frame.max(axis=0), 2.0, 4, pad=4)
    hole = HoleRegion.ball([4.0, 4.0, 4.0], 1.6)
    cand = CandidateCubes.build(grid, frame, normals, agtv, [hole], min_known_points=16, hole_free=True,
                                agtv_weight=1.0)
    lower = np.array([0.0, 0.0, 2.0])
    target = frame[((frame >= lower) & (frame < lower + 8.0)).all(axis=1)]
    in_target = ((frame >= lower) & (frame < lower + 8.0)).all(axis=1)
    query = np.concatenate([normals[in_target].mean(axis=0), [agtv[in_target].mean()]])
    ctx = FrameContext(frame, tree, grid, 8.0, 2.0, 0.25, 0.25, cand, (), None, None)
    fit = intra_source(target, lower, query, ctx, intra_candidates=4, hole_free=True, grow_source=True,
                       cells_per_cube=4, agtv_weight=1.0, icp_iterations=20, residual=True)
    assert fit is not None and fit.residual < 0.05
    # the source came from the other patch, translated into the target cube, and covers its hole
    aligned = fit.aligned
    hole = (np.linalg.norm(aligned[:, :2] - 4.0, axis=1) < 1.0)
    assert hole.sum() > 10
    np.testing.assert_allclose(aligned[hole, 2], 4.0 + 0.05 * ((aligned[hole, :2] - 4.0) ** 2).sum(axis=1), atol=0.05)


def test_inter_source_aligns_the_moved_neighbour_onto_the_target_surface():
    # the neighbour is the sphere moved by (1.5, -1, 0.5): its points near the target cube lie up to a
    # unit off the frame's sphere; aligned onto the target's known points they lie on it. (A sphere
    # turns freely about its centre, so the surface, not the motion, is what is determined here; the
    # motion itself: test_align_best_picks_the_matching_candidate_and_recovers_its_motion.)
    sphere = fibonacci_sphere(radius=20.0, n=20000)
    neighbour = sphere + [1.5, -1.0, 0.5]
    lower = np.array([-6.0, -6.0, 14.0])
    target = sphere[((sphere >= lower) & (sphere < lower + 12.0)).all(axis=1)]
    frame = NeighbourFrame(neighbour, cKDTree(neighbour), [], [])
    got = inter_source(target, lower, frame, cube=12.0, cell=3.0, unit=1.0, search_box=2.5, grow_source=True,
                       icp_iterations=30)
    assert got is not None and got.raw
    unmoved = neighbour[((neighbour >= lower) & (neighbour < lower + 12.0)).all(axis=1)]
    assert np.abs(np.linalg.norm(unmoved, axis=1) - 20.0).mean() > 0.3
    in_cube = got.aligned[((got.aligned >= lower) & (got.aligned < lower + 12.0)).all(axis=1)]
    assert len(in_cube) >= 0.9 * len(target)
    assert np.abs(np.linalg.norm(in_cube, axis=1) - 20.0).max() < 0.02
    np.testing.assert_allclose(np.linalg.det(got.rotation), 1.0)
    # a hole of that frame's input near the target: not captured data
    holed = NeighbourFrame(neighbour, frame.tree, [], [HoleRegion.ball(lower + 6.0, 3.0)])
    assert not inter_source(target, lower, holed, cube=12.0, cell=3.0, unit=1.0, search_box=2.5,
                            grow_source=True, icp_iterations=5).raw
    far = NeighbourFrame(neighbour + 500.0, cKDTree(neighbour + 500.0), [], [])
    assert inter_source(target, lower, far, cube=12.0, cell=3.0, unit=1.0, search_box=2.5, grow_source=True,
                        icp_iterations=5) is None  # nothing in the search box


# -- alignment --------------------------------------------------------------------------------------

def test_align_best_picks_the_matching_candidate_and_recovers_its_motion():
    rng = np.random.default_rng(3)
    xy = rng.uniform(-5, 5, size=(600, 2))
    patch = np.column_stack([xy, 0.1 * xy[:, 0] ** 2 - 0.06 * xy[:, 1] ** 2 + 0.02 * xy[:, 0] * xy[:, 1]])
    rot, t = rotation_z(0.06), np.array([0.3, -0.2, 0.1])
    partial = patch[np.linalg.norm(xy, axis=1) > 2.0]
    moved_source = (patch - t) @ rot  # source = R^T (p - t): the fit must return (rot, t)
    flat = np.column_stack([xy, np.zeros(len(xy))])
    fit = align_best([flat, moved_source, None], partial, iterations=30)
    assert fit is not None and fit.source is moved_source
    np.testing.assert_allclose(fit.rotation, rot, atol=1e-3)
    np.testing.assert_allclose(fit.translation, t, atol=1e-3)
    assert fit.residual < 1e-3
    np.testing.assert_allclose(fit.aligned, moved_source @ fit.rotation.T + fit.translation)
    one = align_best([moved_source], partial, iterations=30, residual=False)
    assert one is not None and one.residual == 0.0
    assert align_best([None, patch[:2]], partial, iterations=5) is None


# -- new points -------------------------------------------------------------------------------------

def test_new_points_are_the_source_points_in_the_cube_in_a_hole_and_in_a_pending_cell():
    region = HoleRegion.ball([4.0, 4.0, 4.0], 3.0)
    source = np.array([[4.0, 4.0, 4.0],    # in the cube, the hole, a pending cell: new
                       [4.4, 4.0, 4.0],    # the same
                       [4.0, 4.0, 6.5],    # in the hole, but its cell is not pending
                       [0.5, 0.5, 0.5],    # in the cube and a pending cell, outside the hole
                       [4.0, 4.0, 8.5]])   # outside the cube
    cells = np.floor(source / 2.0).astype(np.int64)  # local cells of side 2 from the origin
    pending = np.zeros((5, 5, 5), dtype=bool)
    pending[2, 2, 2] = pending[0, 0, 0] = pending[2, 2, 4] = True
    got = select_new_points(source, np.empty((0, 3)), np.zeros(3), [region], pending, cells, cube=8.0,
                            mode="pending-cells", slot=None)
    np.testing.assert_array_equal(got, source[:2])
    # empty slots: one point per free voxel of side 1 in the hole, pending or not
    target = np.array([[4.0, 4.0, 6.6]])  # holds the slot of the third point
    got = select_new_points(source, target, np.zeros(3), [region], pending, cells, cube=8.0, mode="empty-slots",
                            slot=1.0)
    np.testing.assert_array_equal(got, source[:1])  # the second shares the first one's slot (4.4 rounds to 4)


# -- graph ------------------------------------------------------------------------------------------

def test_spatial_graph_on_the_source_places_known_rows_at_their_nearest_source_point():
    rng = np.random.default_rng(4)
    source = rng.uniform(0, 6, size=(40, 3))
    known_rows = source[:10] + rng.normal(0, 0.05, size=(10, 3))
    rows = np.vstack([known_rows, source[30:]])
    got = spatial_laplacian(rows, source, 10, 4, 1.0, "source")
    want = knn_laplacian(np.vstack([source[:10], source[30:]]), 4, 1.0)
    np.testing.assert_allclose(got.toarray(), want.toarray())
    np.testing.assert_allclose(spatial_laplacian(rows, source, 10, 4, 1.0, "estimate").toarray(),
                               knn_laplacian(rows, 4, 1.0).toarray())
    with pytest.raises(ValueError, match="graph_on"):
        spatial_laplacian(rows, source, 10, 4, 1.0, "both")


def test_a_row_that_maps_into_a_hole_of_the_neighbour_is_neither_linked_nor_judged():
    grid = np.stack(np.meshgrid(np.arange(-10, 11.0), np.arange(-10, 11.0), indexing="ij"), -1).reshape(-1, 2)
    source = np.column_stack([grid, np.zeros(len(grid))])
    rot, t = rotation_z(0.1), np.array([5.0, 0.0, 0.0])
    aligned = source @ rot.T + t
    hole = HoleRegion.ball([0.0, 0.0, 3.0], 1.5)  # in the neighbour's own coordinates
    rows = np.array([[5.0, 0.0, 3.0],   # maps back to (0, 0, 3): in the hole
                     [5.0, 0.0, 5.0]])  # maps back to (0, 0, 5): no hole, 5 off the plane
    links = temporal_links(rows, aligned, rot, t, [hole], 2.5, link_cutoff=False, skip_hole_links=True,
                           off_surface=0.4)
    assert links.linked.tolist() == [False, True]
    assert links.contradicted.tolist() == [False, True] and links.supported.tolist() == [False, False]
    np.testing.assert_allclose(links.counterpart[0], aligned[np.argmin(np.linalg.norm(aligned - rows[0], axis=1))])


# -- solve ------------------------------------------------------------------------------------------

def test_solve_reproduces_closed_form_minimisers():
    # no graph (gamma = 0): rows decouple. A missing row minimises alpha |x - s|^2 + beta sum_g |x - T_g|^2
    # -> x = (alpha s + beta sum T_g) / (alpha + beta G); a known row (free) |x - c|^2 + beta |x - T|^2.
    target = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    source = np.array([[9.0, 9.0, 9.0], [2.0, 4.0, 6.0]])
    known = np.array([True, False])
    t1, t2 = np.array([[3.0, 2.0, 1.0], [4.0, 0.0, 2.0]]), np.array([[0.0, 0.0, 0.0], [6.0, 2.0, 0.0]])
    lap = knn_laplacian(target, 1, 1.0)
    alpha, beta = 2.0, 0.5
    got = solve_cube(target, source, known, lap, alpha=alpha, gamma=0.0, beta=beta,
                     temporal=[(t1, np.array([True, True])), (t2, np.array([False, True]))])
    np.testing.assert_allclose(got[0], (target[0] + beta * t1[0]) / (1 + beta))
    np.testing.assert_allclose(got[1], (alpha * source[1] + beta * (t1[1] + t2[1])) / (alpha + 2 * beta))
    # one known row k fixed, one missing row x, an edge of weight w: alpha |x - s|^2 + gamma w |x - k|^2
    # -> x = (alpha s + gamma w k) / (alpha + gamma w)
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    w = np.exp(-1.0 / 2.0)
    lap = knn_laplacian(pts, 1, 1.0)
    k_row, s_row = np.array([1.0, 1.0, 1.0]), np.array([3.0, -1.0, 5.0])
    got = solve_cube(np.array([k_row, [0, 0, 0]]), np.array([[0, 0, 0], s_row]), known, lap, alpha=1.0, gamma=0.5,
                     fix_known=True)
    np.testing.assert_array_equal(got[0], k_row)
    np.testing.assert_allclose(got[1], (s_row + 0.5 * w * k_row) / (1.0 + 0.5 * w))


# -- post-processing --------------------------------------------------------------------------------

def test_drop_contradicted_keeps_rows_supported_somewhere_or_contradicted_nowhere():
    from dpcbench.methods._graph import TemporalLinks

    def links(contradicted, supported):
        n = len(contradicted) + 1  # one known row first
        return TemporalLinks(np.zeros((n, 3)), np.ones(n, bool), np.array([False, *contradicted]),
                             np.array([True, *supported]))

    new = np.arange(12.0).reshape(4, 3)
    # rows: supported in g1 / contradicted in g2 / contradicted in both / neither
    got = drop_contradicted_rows(new, [links([False, True, True, False], [True, False, False, False]),
                                       links([True, False, True, False], [False, False, False, False])], 1)
    np.testing.assert_array_equal(got, new[[0, 3]])


def test_voxelize_fill_gives_the_voxels_of_the_sampled_plane_inside_the_hole():
    rng = np.random.default_rng(5)
    xy = rng.uniform(-6, 6, size=(3000, 2))
    normal = np.array([-0.3, -0.2, 1.0]) / np.linalg.norm([-0.3, -0.2, 1.0])
    added = np.column_stack([xy, 0.3 * xy[:, 0] + 0.2 * xy[:, 1] + 10.25])
    region = HoleRegion.ball([0.0, 0.0, 10.25], 5.0)
    voxels = voxelize_fill(added, [region])
    assert np.array_equal(voxels, np.round(voxels)) and len(np.unique(voxels, axis=0)) == len(voxels)
    assert region.contains(voxels).all()
    off = np.abs((voxels - [0.0, 0.0, 10.25]) @ normal)
    assert off.max() <= 0.5 + 0.05  # within half a voxel of the plane (its PCA estimate)
    # no gap: every grid column well inside the hole holds a voxel
    columns = {tuple(v[:2]) for v in voxels.astype(int)}
    inner = [(i, j) for i in range(-3, 4) for j in range(-3, 4) if i * i + j * j <= 9]
    assert all(c in columns for c in inner)


def test_finish_frame_appends_only_unoccupied_voxels_and_rounds_moved_known_points():
    out = np.array([[0.0, 0.0, 0.0], [1.2, 0.0, 0.0], [2.0, 0.0, 0.0]])
    added = np.array([[1.0, 1.0, 0.0], [1.9, 0.1, 0.0], [3.0, 0.2, 0.0]])  # 3 points: rounded, not fitted
    region = HoleRegion.ball([1.5, 0.0, 0.0], 5.0)
    got = finish_frame(out, added, [region], voxelized=True, round_known=True)
    np.testing.assert_array_equal(got, [[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0], [3, 0, 0]])
    got = finish_frame(out, added, [region], voxelized=False, round_known=True)
    np.testing.assert_array_equal(got, np.vstack([out, added]))  # unvoxelized: as solved


# -- state and units --------------------------------------------------------------------------------

def test_local_points_apply_moves_rows_and_appends_new_points_without_touching_the_old_state():
    local = LocalPoints(np.zeros((3, 3)), np.ones((3, 3)), np.ones(3), np.array([7, 8, 9]))
    after = local.apply(CubeFill(np.full((2, 3), 5.0), np.array([1]), np.array([[1.0, 2.0, 3.0]])))
    np.testing.assert_array_equal(local.points, np.zeros((3, 3)))
    np.testing.assert_array_equal(after.points, [[0, 0, 0], [1, 2, 3], [0, 0, 0], [5, 5, 5], [5, 5, 5]])
    np.testing.assert_array_equal(after.index, [7, 8, 9, -1, -1])
    assert np.isnan(after.agtv[3:]).all() and np.isnan(after.normals[3:]).all()
    with pytest.raises(AttributeError):
        after.points = local.points  # frozen


def test_cube_unit():
    i, j = np.meshgrid(np.arange(0, 2047.0, 2.0), np.arange(0, 100.0, 2.0), indexing="ij")
    plane = np.column_stack([i.ravel(), j.ravel(), np.zeros(i.size)])
    tree = cKDTree(plane)
    assert cube_unit(plane, tree, None, True, "m") == 1.0
    assert cube_unit(plane, tree, None, False, "m") == pytest.approx(2046.0 / 1024.0)
    assert cube_unit(plane, tree, 3.5, False, "m") == 3.5
    assert cube_unit(plane, tree, "points", False, "m") == pytest.approx(2.0, rel=0.05)
    with pytest.raises(ValueError, match="zero extent"):
        cube_unit(np.zeros((10, 3)), None, None, False, "m")
