"""temporal-fusion's colours (methods/temporal_fusion/colours.py): each new point coloured the way its position was
decided. The pooling helpers against brute force; the method on sequences whose frames carry one colour each, so
where a new point's colour came from can be read off it (a copy from the red frame is red, a harmonic fill from the
green frame's rim is green)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.base import colours_itself
from dpcbench.methods.registry import get_method
from dpcbench.methods.temporal_fusion import TemporalFusion
from dpcbench.methods.temporal_fusion.colours import as_sources, pooled, rounded

RED, GREEN, BLUE = (255, 0, 0), (0, 255, 0), (0, 0, 255)


def one_colour(points: np.ndarray, rgb) -> np.ndarray:
    return np.tile(np.array(rgb, dtype=np.uint8), (len(points), 1))


def bumpy_sphere(n: int = 6000, radius: float = 30.0) -> np.ndarray:
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * i / n), np.pi * (1.0 + 5.0 ** 0.5) * i
    u = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    return u * (radius * (1.0 + 0.06 * np.sin(3 * u[:, 0]) * np.cos(2 * u[:, 1])))[:, None]


# -- the helpers ------------------------------------------------------------------------------------------------
def test_pooled_is_the_mean_of_the_coloured_points_within_reach_else_the_nearest():
    rng = np.random.default_rng(3)
    points = rng.integers(0, 6, (80, 3)).astype(float)  # integer points: many exact ties at the reach
    colours = rng.integers(0, 256, (80, 3)).astype(float)
    colours[::7] = np.nan  # points without a carried colour never count
    targets = np.vstack([rng.integers(0, 6, (30, 3)).astype(float), [[20.0, 20.0, 20.0]]])
    got = pooled(points, colours, targets, 1.0)
    known = np.isfinite(colours).all(axis=1)
    for t, row in zip(targets, got):
        d = np.linalg.norm(points - t, axis=1)
        near = known & (d <= 1.0)
        if near.any():
            np.testing.assert_allclose(row, colours[near].mean(axis=0))
        else:
            nearest = known & (d == d[known].min())  # (equally near points: any one of them)
            assert any(np.array_equal(row, c) for c in colours[nearest])
    assert pooled(points, None, targets, 1.0) is None


def test_rounded_is_the_mean_of_the_coloured_points_in_each_voxel():
    rng = np.random.default_rng(4)
    points = rng.random((200, 3)) * 5
    colours = rng.integers(0, 256, (200, 3)).astype(float)
    colours[::5] = np.nan
    voxels = np.unique(np.floor(points + 0.5), axis=0)
    voxels = np.vstack([voxels, [[40.0, 40.0, 40.0]]])  # no point rounds to it
    got = rounded(points, colours, voxels)
    grid = np.floor(points + 0.5)
    known = np.isfinite(colours).all(axis=1)
    for v, row in zip(voxels, got):
        inside = known & (grid == v).all(axis=1)
        if inside.any():
            np.testing.assert_allclose(row, colours[inside].mean(axis=0))
        else:
            assert np.isnan(row).all()


def test_as_sources_marks_kept_and_uncoloured_rows():
    got = as_sources(2, np.array([[10.4, 300.0, -2.0], [np.nan, np.nan, np.nan]]))
    assert got.dtype == np.int16
    assert got.tolist() == [[-1, -1, -1], [-1, -1, -1], [10, 255, 0], [-1, -1, -1]]


# -- the method ---------------------------------------------------------------------------------------------------
def _fusion(frames, colours, regions, fill="auto", **params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        points, cols = TemporalFusion(**params).inpaint_with_colours(frames, colours, regions, fill=fill)
        geometry = TemporalFusion(**params).inpaint(frames, regions)
    assert all(np.array_equal(p, g) for p, g in zip(points, geometry))  # colour never changes the geometry
    assert all(c.shape == (len(p), 3) and c.dtype == np.uint8 for p, c in zip(points, cols))
    return points, cols


def test_copied_points_carry_their_source_frame_s_colour_on_float_data():
    """Frame 1's hole is copied from frame 0 (the same surface, shifted): every new point is red, frame 0's colour,
    where the harmonic fill colours it from frame 1's green rim; kept points keep their colour."""
    base = bumpy_sphere()
    region = HoleRegion.ball(base[100], 5.0)
    frames = [base + [0.3, 0.0, 0.0], base[~region.contains(base)]]
    colours = [one_colour(frames[0], RED), one_colour(frames[1], GREEN)]
    points, cols = _fusion(frames, colours, [[], [region]], window=1)
    n1 = len(frames[1])
    assert len(points[1]) > n1
    assert (cols[1][n1:] == RED).all() and (cols[1][:n1] == GREEN).all() and (cols[0] == RED).all()
    _, harmonic = _fusion(frames, colours, [[], [region]], fill="harmonic", window=1)
    assert (harmonic[1][n1:] == GREEN).all()


def test_a_reused_fill_carries_its_previous_frame_colour():
    """Both frames have the hole and no frame saw it: frame 0 fills it spatially (harmonic from its red rim), and
    frame 1 reuses that fill moved by the motion, red as in frame 0, where the generic fill makes it green."""
    base = bumpy_sphere()
    region = HoleRegion.ball(base[100], 5.0)
    kept = base[~region.contains(base)]
    frames = [kept, kept + [0.3, 0.0, 0.0]]
    colours = [one_colour(frames[0], RED), one_colour(frames[1], GREEN)]
    points, cols = _fusion(frames, colours, [[region], [region]], window=1)
    n = len(kept)
    assert len(points[0]) > n and len(points[1]) > n
    assert (cols[0][n:] == RED).all() and (cols[1][n:] == RED).all()
    _, off = _fusion(frames, colours, [[region], [region]], window=1, reuse_previous=False)
    assert (off[1][n:] == GREEN).all()  # without reuse frame 1 fills it itself, from its green rim


def test_voxel_copies_pool_the_previous_and_next_frame_s_colours():
    """The tiny human (voxelized) with medium holes in frame 1 only, frames 0 (red) and 2 (blue) whole: every new
    voxel is a re-voxelized copy pooling both, so it has no green and red + blue = 255 (+-1 rounding), and both
    frames contribute; with ``pool_adjacent`` off each voxel takes the copy fused first (one frame's colour) where
    the second left no gap."""
    from dpcbench.bench.data.standins import human
    from dpcbench.holes.registry import get_generator

    truth = [human.generate_frame(i, size="tiny")[0] for i in range(3)]
    damage = get_generator("region", preset="medium").damage(truth, 0)
    frames = [truth[0], damage.frames[1], truth[2]]
    colours = [one_colour(frames[0], RED), one_colour(frames[1], GREEN), one_colour(frames[2], BLUE)]
    regions = [[], damage.regions[1], []]
    _, cols = _fusion(frames, colours, regions)
    new = cols[1][len(frames[1]):].astype(int)
    assert len(new) > 100
    assert (new[:, 1] == 0).all() and np.isin(new[:, 0] + new[:, 2], [254, 255, 256]).all()
    mixed = (new[:, 0] > 5) & (new[:, 2] > 5)
    assert mixed.mean() > 0.5  # pooled: most voxels see both copies
    _, single = _fusion(frames, colours, regions, pool_adjacent=False)
    new = single[1][len(frames[1]):].astype(int)
    assert (new[:, 1] == 0).all() and ((new[:, 0] > 5) & (new[:, 2] > 5)).mean() < 0.1


def test_the_back_fill_carries_the_next_frame_s_colour():
    """Frame 0's hole, which no frame within the window saw and no spatial fill may fill (``fallback`` off), is
    filled by the back-fill from frame 1's copy of frame 2 (blue): frame 0's new points are blue, not its red."""
    base = bumpy_sphere()
    region = HoleRegion.ball(base[100], 5.0)
    kept = base[~region.contains(base)]
    frames = [kept, kept + [0.2, 0.0, 0.0], base + [0.4, 0.0, 0.0]]
    colours = [one_colour(frames[0], RED), one_colour(frames[1], GREEN), one_colour(frames[2], BLUE)]
    points, cols = _fusion(frames, colours, [[region], [region], []], window=1, fallback=False)
    n = len(kept)
    assert len(points[1]) > n and (cols[1][n:] == BLUE).all()  # frame 1 copies frame 2
    assert len(points[0]) > n and (cols[0][n:] == BLUE).all()  # frame 0 gets frame 1's fill back


def test_runs_and_the_generic_fills_use_the_method_s_colours():
    assert colours_itself(TemporalFusion()) and not colours_itself(get_method("lozes-pde"))
    base = bumpy_sphere(2000)
    region = HoleRegion.ball(base[10], 6.0)
    frames = [base, base[~region.contains(base)]]
    colours = [one_colour(frames[0], RED), one_colour(frames[1], GREEN)]
    for fill in ("nearest", "harmonic"):  # the generic fills ignore what the method carries
        points, cols = TemporalFusion(window=1).inpaint_with_colours(frames, colours, [[], [region]], fill=fill)
        assert (cols[1][len(frames[1]):] == GREEN).all()
    with pytest.raises(Exception, match="unknown colour fill"):
        TemporalFusion().inpaint_with_colours(frames, colours, [[], [region]], fill="magic")


def test_a_run_stores_the_method_s_own_colours(tmp_path):
    """`bench.execution.worker._inpaint_timed` asks a method that colours itself for its colours."""
    from dpcbench.bench.execution.worker import _inpaint_timed

    base = bumpy_sphere(3000)
    region = HoleRegion.ball(base[10], 6.0)
    frames = [base + [0.3, 0.0, 0.0], base[~region.contains(base)]]
    colours = [one_colour(frames[0], RED), one_colour(frames[1], GREEN)]
    out, sources, _, _, cols = _inpaint_timed(TemporalFusion(window=1), frames, [[], [region]], colours, "auto")
    assert sources is None and cols is not None
    want = TemporalFusion(window=1).inpaint_with_colours(frames, colours, [[], [region]])
    assert all(np.array_equal(a, b) for a, b in zip(cols, want[1]))
    assert (cols[1][len(frames[1]):] == RED).all()
    _, _, _, _, none = _inpaint_timed(get_method("lozes-pde"), frames, [[], [region]], colours, "auto")
    assert none is None  # the generic fill colours it afterwards
    assert cKDTree(out[1]).n == len(out[1])
