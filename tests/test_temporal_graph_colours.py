"""temporal-graph and fu-nonlocal carry colour as a further signal on each target cube's graph (`cube_colours`):
the closed forms of the colour solve, and the methods on sequences whose frames carry one colour each, so where a
new point's colour came from can be read off it."""

from __future__ import annotations

import numpy as np
import pytest

from dpcbench.methods._graph import knn_laplacian, temporal_links
from dpcbench.methods.temporal_graph import INTRA_COLOUR_WEIGHT, FuNonlocal, InterSource, TemporalGraph, cube_colours
from tests.test_temporal_graph import FAST, switch_case

RED, GREEN, BLUE = (255, 0, 0), (0, 255, 0), (0, 0, 255)


def one_colour(points: np.ndarray, rgb) -> np.ndarray:
    return np.tile(np.array(rgb, dtype=np.uint8), (len(points), 1))


# -- the solve ------------------------------------------------------------------------------------------------------
def _cube(rng):
    """A cube's rows (8 known, 6 new) on a plane, its source, one inter-source cube (the rows shifted a little)."""
    known = np.column_stack([rng.random((8, 2)) * 4, np.zeros(8)])
    new = np.column_stack([rng.random((6, 2)) * 4, np.zeros(6)])
    source = np.vstack([new, np.column_stack([rng.random((10, 2)) * 4, np.zeros(10)])])
    rows = np.vstack([known, new])
    inter = InterSource(rows + 0.01, np.eye(3), np.zeros(3), 0.0, True, [], rng.random((14, 3)) * 255)
    link = temporal_links(rows, inter.aligned, np.eye(3), np.zeros(3), [], 1.0, link_cutoff=True,
                          skip_hole_links=False, off_surface=None)
    return rows, source, inter, link, knn_laplacian(rows, 4, 1.0)


def test_without_graph_and_temporal_terms_a_new_row_takes_its_source_colour():
    rng = np.random.default_rng(0)
    rows, source, inter, link, laplacian = _cube(rng)
    source_colours = rng.random((len(source), 3)) * 255
    got = cube_colours(rows, 8, rng.random((8, 3)) * 255, source, source_colours, [inter], [link], laplacian,
                       alpha=1.0, gamma=0.0, beta=0.0)
    np.testing.assert_allclose(got, source_colours[:6])  # the new rows are the first six source points


def test_a_constant_colour_stays_constant_and_strong_temporal_terms_give_the_counterparts():
    rng = np.random.default_rng(1)
    rows, source, inter, link, laplacian = _cube(rng)
    grey = np.full((len(source), 3), 90.0)
    flat = InterSource(inter.aligned, inter.rotation, inter.translation, 0.0, True, [], np.full((14, 3), 90.0))
    got = cube_colours(rows, 8, np.full((8, 3), 90.0), source, grey, [flat], [link], laplacian,
                       alpha=1.0, gamma=3.0, beta=1.0)
    np.testing.assert_allclose(got, 90.0)
    assert link.linked.all()
    got = cube_colours(rows, 8, np.full((8, 3), 90.0), source, grey, [inter], [link], laplacian,
                       alpha=1e-6, gamma=1e-6, beta=1e6)
    np.testing.assert_allclose(got, inter.colours[8:], atol=1e-3)  # each row's counterpart is its shifted self


@pytest.mark.parametrize("source_kind", ["inter", "intra"])
def test_the_solve_is_eq6_with_the_known_colours_fixed(source_kind):
    """Against a dense solve of (w Omega + beta D + gamma L) x = w c_s + beta D W c_g on the new rows, the known
    rows' colours fixed (moved to the right-hand side): from an inter-source cube c_s is its colours and w = alpha;
    from an intra-source cube c_s is the nearest known row's colour and w = alpha * INTRA_COLOUR_WEIGHT."""
    rng = np.random.default_rng(2)
    rows, source, inter, link, laplacian = _cube(rng)
    known_colours = rng.random((8, 3)) * 255
    alpha, gamma, beta = 0.7, 2.0, 0.5
    if source_kind == "inter":
        source_colours = rng.random((len(source), 3)) * 255
        prior, w = source_colours[:6], alpha  # the new rows are the first six source points
    else:
        source_colours = None
        nearest = np.argmin(np.linalg.norm(rows[8:, None] - rows[None, :8], axis=2), axis=1)
        prior, w = known_colours[nearest], alpha * INTRA_COLOUR_WEIGHT
    got = cube_colours(rows, 8, known_colours, source, source_colours, [inter], [link], laplacian,
                       alpha=alpha, gamma=gamma, beta=beta)
    dense = np.asarray(laplacian.todense())
    a = w * np.eye(6) + beta * np.diag(link.linked[8:].astype(float)) + gamma * dense[8:, 8:]
    counterpart = inter.colours[np.argmin(np.linalg.norm(rows[:, None] - inter.aligned[None], axis=2), axis=1)]
    b = w * prior + beta * counterpart[8:] - gamma * dense[8:, :8] @ known_colours
    np.testing.assert_allclose(got, np.linalg.solve(a, b), rtol=1e-7, atol=1e-7)


def test_from_an_intra_source_cube_the_colour_is_the_graph_s_harmonic_extension():
    """Without temporal terms a new row from an intra-source cube takes no colour from that cube: its colour is
    (up to the weak anchor) the harmonic extension of the known colours, L_uu x = -L_uk c_k; a colour linear along
    the plane is reproduced inside the range of the known colours."""
    rng = np.random.default_rng(5)
    rows, source, inter, link, laplacian = _cube(rng)
    known_colours = rng.random((8, 3)) * 255
    got = cube_colours(rows, 8, known_colours, source, None, [], [], laplacian, alpha=1.0, gamma=0.5, beta=0.0)
    dense = np.asarray(laplacian.todense())
    harmonic = np.linalg.solve(dense[8:, 8:], -dense[8:, :8] @ known_colours)
    np.testing.assert_allclose(got, harmonic, atol=0.5)
    assert (got >= known_colours.min(axis=0) - 1e-6).all() and (got <= known_colours.max(axis=0) + 1e-6).all()


# -- the methods ----------------------------------------------------------------------------------------------------
def _coloured(cls, damaged, colours, regions, **params):
    points, cols = cls(**FAST, **params).inpaint_with_colours(damaged, colours, regions)
    geometry = cls(**FAST, **params).inpaint(damaged, regions)
    assert all(np.array_equal(p, g) for p, g in zip(points, geometry))  # colour never changes the geometry
    assert all(c.shape == (len(p), 3) and c.dtype == np.uint8 for p, c in zip(points, cols))
    return points, cols


@pytest.mark.parametrize("variant", ["tuned", "paper", "literal"])
def test_known_points_keep_their_colour_and_fu_nonlocal_spreads_the_frame_s_own(variant):
    """fu-nonlocal has only frame 1's own signals (its known colours and its intra-source cubes, all green): every
    new point is green. Known points keep their colour in every variant, also where the literal one moves them."""
    damaged, regions = switch_case()
    colours = [one_colour(damaged[0], RED), one_colour(damaged[1], GREEN), one_colour(damaged[2], BLUE)]
    points, cols = _coloured(FuNonlocal, damaged, colours, regions, variant=variant)
    n = len(damaged[1])
    assert len(points[1]) > n + 20
    assert (cols[1] == GREEN).all()
    assert all((c[:len(d)] == col).all() for c, d, col in zip(cols, damaged, colours))


def test_temporal_graph_takes_colour_from_the_neighbouring_frames():
    """temporal-graph's temporal terms (and its inter-source cubes) link frame 1's new points to frame 0 (red) and
    frame 2 (blue): they carry red and blue; with beta = 0 it is fu-nonlocal, colours included."""
    damaged, regions = switch_case()
    colours = [one_colour(damaged[0], RED), one_colour(damaged[1], GREEN), one_colour(damaged[2], BLUE)]
    n = len(damaged[1])
    _, cols = _coloured(TemporalGraph, damaged, colours, regions, variant="paper")
    new = cols[1][n:].astype(int)
    assert (cols[1][:n] == GREEN).all()
    assert new[:, 0].mean() > 20 and new[:, 2].mean() > 20 and new[:, 1].mean() < 230
    _, off = _coloured(TemporalGraph, damaged, colours, regions, variant="paper", beta=0.0)
    _, fu = _coloured(FuNonlocal, damaged, colours, regions, variant="paper")
    assert all(np.array_equal(a, b) for a, b in zip(off, fu))


def test_a_frame_whose_new_points_all_fall_on_occupied_voxels_keeps_one_colour_a_point():
    """Bunny tiny, coherent "paper" holes, seed 1: every point frame 0's cubes add lands on a voxel already held, so
    step 10 leaves none; the colours must then be the frame's own (the quick preset's run failed on a misaligned
    colour array here)."""
    from dpcbench.bench.data.datasets import load_dataset
    from dpcbench.holes.registry import get_generator

    seq = load_dataset("bunny", frames=3, progress=False, size="tiny")
    damage = get_generator("region", preset="paper", coherent=True).damage(seq.points, seed=1, colors=seq.colors)
    method = TemporalGraph()
    outputs, colours = method.inpaint_with_colours(damage.frames, damage.colors, damage.regions)
    assert len(outputs[0]) == len(damage.frames[0])  # the case: nothing added to frame 0
    for frame, frame_colours, points, coloured in zip(damage.frames, damage.colors, outputs, colours):
        assert coloured.shape == (len(points), 3) and coloured.dtype == np.uint8
        np.testing.assert_array_equal(points[:len(frame)], frame)  # known points fixed, first
        np.testing.assert_array_equal(coloured[:len(frame)], frame_colours)
    for got, expected in zip(outputs, method.inpaint(damage.frames, damage.regions)):
        np.testing.assert_array_equal(got, expected)
