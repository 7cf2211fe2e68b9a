"""temporal-fusion's stages one by one (methods/temporal_fusion/): each stage's contract on constructed cases with
known answers, the config's declared constraints against the constructor, and the ablation table."""

from __future__ import annotations

import inspect
from dataclasses import fields

import numpy as np
import pytest
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.temporal_fusion import ABLATIONS, FusionConfig, TemporalFusion, constraints
from dpcbench.methods.temporal_fusion.align import align_sources
from dpcbench.methods.temporal_fusion.crop import crop_region
from dpcbench.methods.temporal_fusion.method import fill_region
from dpcbench.methods.temporal_fusion.records import SequenceData
from dpcbench.methods.temporal_fusion.rim_fill import copy_beats_growth, growth_holdout_miss, rim_fill
from dpcbench.methods.temporal_fusion.spatial import CASCADE, spatial_fill


def voxel_plane(half: int = 20) -> np.ndarray:
    g = np.arange(-half, half + 1, dtype=float)
    u, v = np.meshgrid(g, g, indexing="ij")
    return np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])


def bumpy_sphere(n: int = 6000, radius: float = 30.0) -> np.ndarray:
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * i / n), np.pi * (1.0 + 5.0 ** 0.5) * i
    u = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    return u * (radius * (1.0 + 0.06 * np.sin(3 * u[:, 0]) * np.cos(2 * u[:, 1])))[:, None]


def sequence(frames, regions, cfg: FusionConfig, voxelized: bool, spacing: float) -> SequenceData:
    trees = {}

    def tree_of(g):
        if g not in trees:
            trees[g] = cKDTree(frames[g])
        return trees[g]

    return SequenceData(frames, regions, tree_of, spacing, spacing, voxelized, cfg.fit_neighbours(voxelized),
                        cfg.fit_neighbours(False))


def strategy(fill):
    """A cascade strategy (`methods.temporal_fusion.spatial.CASCADE`) that always applies and fills with ``fill``."""
    return type("Strategy", (), {"trust": "a test's", "applies": staticmethod(lambda cfg, hole, state: True),
                                 "fill": staticmethod(fill)})


# -- config -------------------------------------------------------------------------------------------------------
def test_the_config_declares_exactly_the_constructor_s_parameters_and_defaults():
    """`FusionConfig`'s fields are `TemporalFusion.__init__`'s keyword parameters, in order, with the same
    defaults: get_params (and so every stored run id) reads the signature, the stages read the config."""
    signature = inspect.signature(TemporalFusion.__init__).parameters
    params = {name: p.default for name, p in signature.items() if name != "self"}
    assert {f.name: f.default for f in fields(FusionConfig)} == params
    assert list(constraints()) == list(params)
    assert FusionConfig.of(TemporalFusion().get_params()) == FusionConfig()
    assert all(c.rationale for c in constraints().values())


@pytest.mark.parametrize("name, bad", [("window", -1), ("window", 1.5), ("icp_iterations", True),
                                       ("deform_neighbours", 0), ("shell_spacings", 0.0), ("shell_factor", -0.1),
                                       ("accept_spacings", "1"), ("gap_spacings", -1), ("refine", 1),
                                       ("mls_neighbours", "many"), ("mls_neighbours", -2), ("snap", "yes")])
def test_each_constraint_refuses_a_value_out_of_its_range_naming_the_parameter(name, bad):
    with pytest.raises(ValueError, match=f"temporal-fusion: {name} must be"):
        FusionConfig.of({**TemporalFusion().get_params(), name: bad})
    with pytest.raises(ValueError, match=name):
        TemporalFusion(**{name: bad}).inpaint([np.zeros((10, 3))] * 2, None)


def test_the_boundary_values_of_each_range_are_allowed():
    params = {**TemporalFusion().get_params(), "window": 0, "shell_factor": 0.0, "gap_spacings": 0,
              "mls_neighbours": 0, "snap": True, "deform_neighbours": 1, "icp_iterations": np.int64(0)}
    assert FusionConfig.of(params).window == 0


def test_the_ablation_table_names_switches_that_are_on_by_default():
    """Each ablation switch is a boolean parameter, True by default (False restores an older behaviour); the
    user's knobs (window, accept_spacings, poisson_in_boxes, snap, front, ...) are not in it."""
    defaults = {f.name: f.default for f in fields(FusionConfig)}
    assert ABLATIONS and all(defaults[name] is True and constraints()[name].kind == "bool" for name in ABLATIONS)
    assert not {"window", "accept_spacings", "poisson_in_boxes", "snap", "front", "fallback"} & set(ABLATIONS)
    assert all(len(text) > 10 for text in ABLATIONS.values())


# -- crop -------------------------------------------------------------------------------------------------------
def test_the_crop_is_the_frame_s_points_within_reach_in_frame_order_and_the_rim_within_the_shell():
    plane = voxel_plane()
    order = np.random.default_rng(0).permutation(len(plane))
    frame = plane[order]
    region = HoleRegion.ball([0.0, 0.0, 0.0], 3.0)
    cfg = FusionConfig()
    seq = sequence([frame], [[region]], cfg, True, 1.0)
    crop = crop_region(cfg, seq, 0, region)
    shell = max(0.5 * 3.0, 4.0)
    assert crop.shell == shell and crop.reach == 3.0 + 2 * shell
    distance = np.linalg.norm(frame, axis=1)
    np.testing.assert_array_equal(crop.local, frame[distance <= crop.reach])  # brute force, same order
    np.testing.assert_array_equal(crop.rim, crop.local[np.linalg.norm(crop.local, axis=1) <= 3.0 + shell])


# -- rim fill ------------------------------------------------------------------------------------------------------
def test_rim_fill_closes_a_thin_gap_in_a_voxelized_plane_with_exactly_the_missing_voxels():
    plane = voxel_plane()
    region = HoleRegion.ball([0.0, 0.0, 0.0], 2.5)
    kept, missing = plane[~region.contains(plane)], plane[region.contains(plane)]
    cfg = FusionConfig()
    seq = sequence([kept], [[region]], cfg, True, 1.0)
    crop = crop_region(cfg, seq, 0, region)
    fill = rim_fill(cfg, seq, region, crop)
    np.testing.assert_array_equal(np.unique(fill, axis=0), np.unique(missing, axis=0))
    assert rim_fill(FusionConfig(rim_fill=False), seq, region, crop) is None
    assert rim_fill(cfg, sequence([kept], [[region]], cfg, False, 1.0), region, crop) is None  # float input


def test_a_thin_gap_takes_the_copy_only_where_it_predicts_the_captured_surface_better_than_the_growth():
    """Stage rim fill against the copies, on a thin hole (radius 2.5) closed by the growth. A rough voxelized plane
    (a fifth of its voxels one up, as a noisy capture): the growth, held out on the ring within one fit radius of the
    hole, misses those voxels; frame 1 is the same surface unmoved (rim residual 0), so the hole goes to the copies:
    the fill is the method's fill without the rim fill. A flat plane: the growth's hold-out miss is 0 and frame 1
    jittered by up to 0.3 voxels has a residual above it, so the growth is the fill."""
    region = HoleRegion.ball([0.0, 0.0, 0.0], 2.5)
    cfg = FusionConfig()
    rough = voxel_plane()
    rough[np.random.default_rng(0).random(len(rough)) < 0.2, 2] = 1.0
    unmoved = sequence([rough[~region.contains(rough)], rough], [[region], []], cfg, True, 1.0)
    crop = crop_region(cfg, unmoved, 0, region)
    grown = rim_fill(cfg, unmoved, region, crop)
    assert grown is not None and growth_holdout_miss(unmoved, region, crop) > 0
    assert copy_beats_growth(unmoved, region, crop, align_sources(cfg, unmoved, 0, region, crop))
    fill = fill_region(cfg, unmoved, 0, region, np.zeros((0, 3))).points
    without = fill_region(FusionConfig(rim_fill=False), unmoved, 0, region, np.zeros((0, 3))).points
    np.testing.assert_array_equal(fill, without)
    assert not np.array_equal(np.unique(fill, axis=0), np.unique(grown, axis=0))

    flat = voxel_plane()
    jittered = flat + np.random.default_rng(0).uniform(-0.3, 0.3, flat.shape)
    moved = sequence([flat[~region.contains(flat)], jittered], [[region], []], cfg, True, 1.0)
    crop = crop_region(cfg, moved, 0, region)
    assert growth_holdout_miss(moved, region, crop) == 0.0  # the flat ring grown back exactly
    assert not copy_beats_growth(moved, region, crop, align_sources(cfg, moved, 0, region, crop))
    np.testing.assert_array_equal(fill_region(cfg, moved, 0, region, np.zeros((0, 3))).points,
                                  rim_fill(cfg, moved, region, crop))


# -- align --------------------------------------------------------------------------------------------------------
def test_align_finds_the_known_motion_of_the_next_frame_and_its_copy_covers_the_hole():
    """Frame 1 is frame 0 moved by a known translation, frame 0 has a ball hole: the alignment of frame 1 is
    accepted, its motion is the inverse translation, its copy is the hidden patch, and it is next_motion."""
    base = bumpy_sphere()
    shift = np.array([0.6, -0.3, 0.2])
    region = HoleRegion.ball(base[100], 5.0)
    hidden = base[region.contains(base)]
    frames = [base[~region.contains(base)], base + shift]
    cfg = FusionConfig(window=1)
    spacing = float(np.median(cKDTree(base).query(base, k=2)[0][:, 1]))
    seq = sequence(frames, [[region], []], cfg, False, spacing)
    crop = crop_region(cfg, seq, 0, region)
    found = align_sources(cfg, seq, 0, region, crop)
    assert [c.frame for c in found.candidates] == [1] and found.partial == () and found.carried is None
    motion = found.motions[1]
    np.testing.assert_allclose(motion.rotation, np.eye(3), atol=1e-3)
    np.testing.assert_allclose(motion.translation, -shift, atol=0.05 * spacing)
    assert found.next_motion is motion
    assert found.candidates[0].residual <= cfg.accept_spacings * spacing
    copy = found.candidates[0].points
    assert len(copy) >= 0.9 * len(hidden) and cKDTree(hidden).query(copy)[0].max() < 0.2 * spacing


def test_a_frame_with_its_own_hole_near_the_region_gives_a_partial_copy_only():
    base = bumpy_sphere()
    region = HoleRegion.ball(base[100], 5.0)
    own = HoleRegion.ball(base[100] + np.array([1.0, 0.0, 0.0]), 3.0)
    frames = [base[~region.contains(base)], base[~own.contains(base)]]
    cfg = FusionConfig(window=1)
    spacing = float(np.median(cKDTree(base).query(base, k=2)[0][:, 1]))
    seq = sequence(frames, [[region], [own]], cfg, False, spacing)
    found = align_sources(cfg, seq, 0, region, crop_region(cfg, seq, 0, region))
    assert found.candidates == () and [c.frame for c in found.partial] == [1]
    none = align_sources(FusionConfig(window=1, partial_sources=False), seq, 0, region,
                         crop_region(cfg, seq, 0, region))
    assert none.candidates == () and none.partial == ()


# -- spatial cascade and the region's record ---------------------------------------------------------------------------
def test_the_cascade_runs_in_order_and_stops_at_the_first_fill_it_trusts():
    """On a flat float plane the spline (first in the cascade) fills the hole on the plane; no later strategy
    applies once it did; nothing runs where a copy saw the whole region or with ``fallback`` off."""
    assert [s.__name__ for s in CASCADE] == ["SurfaceSpline", "SheetSpline", "WalledCap", "ClosedSurface", "Cap",
                                             "Membrane", "Front", "BestSurface"]
    assert all(s.trust for s in CASCADE)
    plane = voxel_plane() + np.array([0.25, 0.25, 0.0])
    region = HoleRegion.ball([0.0, 0.0, 0.0], 4.0)
    kept = plane[~region.contains(plane)]
    cfg = FusionConfig()
    seq = sequence([kept], [[region]], cfg, False, 1.0)
    crop = crop_region(cfg, seq, 0, region)
    empty = np.zeros((0, 3))
    fill, not_reused = spatial_fill(cfg, seq, 0, region, crop, empty, 0, empty, False)
    hidden = plane[region.contains(plane)]
    assert len(fill) and np.abs(fill[:, 2]).max() < 0.05 and not_reused == ()  # on the plane
    assert cKDTree(np.vstack([kept, fill])).query(hidden)[0].max() < 1.0  # and the hole closed at the data's density
    assert len(spatial_fill(cfg, seq, 0, region, crop, empty, 0, empty, True)[0]) == 0
    assert len(spatial_fill(FusionConfig(fallback=False), seq, 0, region, crop, empty, 0, empty, False)[0]) == 0


def test_the_spatial_surfaces_see_the_rim_within_the_surface_shell(monkeypatch):
    """Stage spatial fits its surfaces to the rim within max(shell_factor r, surface_shell_spacings s) of R (at most the
    crop's own rim) and holds out half that width; the crop, and so the alignments, keep the rim of `shell`."""
    import dpcbench.methods.temporal_fusion.spatial as spatial

    plane = voxel_plane() + np.array([0.25, 0.25, 0.0])
    region = HoleRegion.ball([0.0, 0.0, 0.0], 3.0)
    kept = plane[~region.contains(plane)]
    seen = []

    def record(cfg, hole, state):  # what the cascade's strategies are given
        seen.append((hole.support, hole.ring))
        return state

    monkeypatch.setattr(spatial, "CASCADE", (strategy(record),))
    empty = np.zeros((0, 3))
    for surface_spacings, width in ((4.0, 4.0), (2.0, 2.0), (1.0, 1.5), (9.0, 4.0)):
        cfg = FusionConfig(surface_shell_spacings=surface_spacings)
        assert cfg.surface_shell(region, 1.0) == width
        seq = sequence([kept], [[region]], cfg, False, 1.0)
        crop = crop_region(cfg, seq, 0, region)
        assert crop.shell == 4.0  # max(0.5 r, shell_spacings s): the crop does not follow the surface shell
        spatial.spatial_fill(cfg, seq, 0, region, crop, empty, 0, empty, False)
        support, ring = seen.pop()
        distance = np.linalg.norm(crop.local, axis=1)
        np.testing.assert_array_equal(support, crop.local[distance <= 3.0 + width])  # brute force, same order
        assert ring == width / 2


def test_the_last_resort_fills_what_a_lone_membrane_left_open_and_keeps_the_membrane(monkeypatch):
    """Where every surface refused and the membrane, the first fill, spanned only part of R, the last resort still
    runs: the membrane's points stay and the best candidate fills the rest of R, keeping its gap from them. Where
    anything was filled before the membrane, it does not run (as before), nor with ``best_surface`` off."""
    import dpcbench.methods.temporal_fusion.spatial as spatial

    plane = voxel_plane() + np.array([0.25, 0.25, 0.0])
    region = HoleRegion.ball([0.0, 0.0, 0.0], 5.0)
    kept = plane[~region.contains(plane)]
    membrane = np.array([[4.0, 0.0, 0.0], [4.0, 1.0, 0.0], [3.0, 0.0, 0.0]])  # a few points at R's edge

    def lone_membrane(cfg, hole, state):  # the surfaces all refused; the membrane spans three points, recorded as
        alone = membrane if not len(state.spatial) else state.membrane_alone  # `Membrane.fill` records them
        return spatial.replace(state, spatial=np.vstack([state.spatial, membrane]), membrane_alone=alone)

    LoneMembrane = strategy(lone_membrane)
    OnePoint = strategy(lambda cfg, hole, state: spatial.replace(state, spatial=np.array([[-4.0, 0.0, 0.0]])))

    cfg = FusionConfig()
    seq = sequence([kept], [[region]], cfg, False, 1.0)
    crop = crop_region(cfg, seq, 0, region)
    empty = np.zeros((0, 3))
    monkeypatch.setattr(spatial, "CASCADE", (LoneMembrane, spatial.BestSurface))
    fill, _ = spatial.spatial_fill(cfg, seq, 0, region, crop, empty, 0, empty, False)
    np.testing.assert_array_equal(fill[:3], membrane)
    added = fill[3:]
    hidden = plane[region.contains(plane)]
    assert len(added) and np.abs(added[:, 2]).max() < 0.05  # the plane, where the spline of the rim puts it
    assert cKDTree(membrane).query(added)[0].min() >= cfg.fill_gap_spacings  # its gap from the membrane's points
    assert cKDTree(np.vstack([kept, fill])).query(hidden)[0].max() < 1.5  # R closed
    # a first fill that is not the membrane's alone: the last resort does not run
    monkeypatch.setattr(spatial, "CASCADE", (OnePoint, LoneMembrane, spatial.BestSurface))
    assert len(spatial.spatial_fill(cfg, seq, 0, region, crop, empty, 0, empty, False)[0]) == 4
    monkeypatch.setattr(spatial, "CASCADE", (LoneMembrane, spatial.BestSurface))
    assert len(spatial.spatial_fill(FusionConfig(best_surface=False), seq, 0, region, crop, empty, 0, empty,
                                    False)[0]) == 3


def test_fill_region_returns_the_next_frame_s_motion_only_where_the_region_stayed_open():
    """A hole every spatial strategy is off for, in a frame whose next frame has the same hole (no source): the
    region stays open and its record carries f+1's motion for the back-fill; filled, it carries none."""
    base = bumpy_sphere()
    region = HoleRegion.ball(base[100], 5.0)
    frames = [base[~region.contains(base)], base[~region.contains(base)]]
    spacing = float(np.median(cKDTree(base).query(base, k=2)[0][:, 1]))
    off = FusionConfig(window=1, fallback=False)
    seq = sequence(frames, [[region], [region]], off, False, spacing)
    record = fill_region(off, seq, 0, region, np.zeros((0, 3)))
    assert len(record.points) == 0 and record.next_motion is not None
    np.testing.assert_allclose(record.next_motion.translation, 0.0, atol=0.05 * spacing)
    on = FusionConfig(window=1)
    record = fill_region(on, sequence(frames, [[region], [region]], on, False, spacing), 0, region, np.zeros((0, 3)))
    assert len(record.points) and record.next_motion is None


def test_with_every_ablation_switch_off_the_oldest_pipeline_still_fills_a_hole_a_neighbour_saw():
    """All of `ABLATIONS` False (the pipeline before any of those steps): a hole that frame 0 and 2 saw is still
    copied onto the hidden surface, as by the defaults."""
    base = bumpy_sphere()
    region = HoleRegion.ball(base[100], 5.0)
    hidden = base[region.contains(base)]
    frames = [base.copy(), base[~region.contains(base)], base.copy()]
    spacing = float(np.median(cKDTree(base).query(base, k=2)[0][:, 1]))
    for params in ({}, {name: False for name in ABLATIONS}):
        out = TemporalFusion(window=1, **params).inpaint(frames, [[], [region], []])
        fill = out[1][len(frames[1]):]
        assert len(fill) >= 0.8 * len(hidden), params
        assert np.median(cKDTree(hidden).query(fill)[0]) < 0.2 * spacing, params


@pytest.mark.parametrize("voxelized", [False, True])
def test_the_membrane_adds_at_most_one_point_a_grid_cell_on_float_data(monkeypatch, voxelized):
    """`spatial.Membrane` where the output is not snapped to voxels keeps what `membrane_fill` returns at the capture's
    density, one point a cubic cell of the grid step (the first in each, as the closed surface's fill): a membrane whose
    points gathered two to a cell is thinned to one a cell, and what it records (the spatial fill, the parts frame f+1 must
    not reuse, the membrane alone) is the thinned set. Where the output is snapped (voxelized data) the snapping keeps
    one point a voxel, and the membrane's points are kept as returned."""
    import dpcbench.methods.temporal_fusion.spatial as spatial

    plane = voxel_plane() + np.array([0.25, 0.25, 0.0])
    region = HoleRegion.ball([0.0, 0.0, 0.0], 5.0)
    kept = plane[~region.contains(plane)]
    cells = plane[region.contains(plane)]
    gathered = np.vstack([cells, cells + [0.3, 0.2, 0.0]])  # two points in every cubic cell of edge 1
    monkeypatch.setattr(spatial, "membrane_fill", lambda *args, **kwargs: gathered)
    monkeypatch.setattr(spatial, "CASCADE", (spatial.Membrane,))
    cfg = FusionConfig()
    seq = sequence([kept], [[region]], cfg, voxelized, 1.0)
    crop = crop_region(cfg, seq, 0, region)
    empty = np.zeros((0, 3))
    fill, not_reused = spatial_fill(cfg, seq, 0, region, crop, empty, 0, empty, False)
    if voxelized:
        np.testing.assert_array_equal(fill, gathered)
        return
    occupied = np.floor(fill / seq.step)
    assert len(fill) == len(cells) == len(np.unique(occupied, axis=0))  # one a cell, every cell kept
    np.testing.assert_array_equal(fill, cells)  # the first in each cell, in order
    assert len(not_reused) == 1
    np.testing.assert_array_equal(not_reused[0], fill)
