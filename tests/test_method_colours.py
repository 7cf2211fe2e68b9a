"""Colour through the methods (`methods._colour`, `InpaintingMethod.inpaint_with_colours`)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._colour import colour_frame, harmonic_colours, kept_index
from dpcbench.methods.registry import get_method
from dpcbench.metrics.errors import UserError


def _plane(n=40, z=0.0):
    g = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2).astype(float)
    return np.column_stack([g, np.full(len(g), z)])


def _ramp(points):
    """A colour that is linear in x (a harmonic function: the graph fill should come close to it)."""
    red = 40 + 4 * points[:, 0]
    return np.column_stack([red, np.full(len(points), 100), 255 - red]).astype(np.uint8)


def test_kept_index_is_exact_matching():
    rng = np.random.default_rng(0)
    inputs = rng.integers(0, 5, (200, 3)).astype(float)  # many repeated points
    outputs = np.concatenate([inputs[::3], rng.random((30, 3)) + 10.0])
    idx = kept_index(inputs, outputs)
    for i, p in enumerate(outputs):
        same = np.flatnonzero((inputs == p).all(axis=1))
        assert idx[i] == (same[0] if same.size else -1)


def test_harmonic_colours_keep_a_constant_colour_where_a_part_hangs_on_by_a_negligible_edge():
    """A harmonic fill of a constant colour is that colour (the maximum principle). Five unknown points beside the
    known ones, five more 8 units off them, joined to the first five by edges of weight exp(-64 / s^2) ~ 1e-28: that
    part is anchored to its nearest input colour like one with no edge at all, not left free in all but name (the
    LU solve then returned 229 for 255)."""
    g = np.arange(5, dtype=float)
    known = np.column_stack([g, np.zeros(5), np.zeros(5)])
    near = known + [0.0, 1.0, 0.0]
    far = near + [0.0, 8.0, 0.0]
    green = np.tile([0.0, 255.0, 0.0], (5, 1))
    got = harmonic_colours(known, green, np.vstack([near, far]), np.tile([0.0, 255.0, 0.0], (10, 1)), k=8)
    np.testing.assert_allclose(got, np.tile([0.0, 255.0, 0.0], (10, 1)), atol=1e-6)


@pytest.mark.parametrize("direct", [True, False], ids=["lu", "cg"])
def test_harmonic_matches_a_dense_solve(monkeypatch, direct):
    from dpcbench.methods import _colour

    if not direct:
        monkeypatch.setattr(_colour, "_DIRECT_MAX", 0)
    rng = np.random.default_rng(1)
    known = rng.random((60, 3)) * 10
    unknown = rng.random((25, 3)) * 10
    kc = rng.integers(0, 256, (60, 3)).astype(float)
    got = harmonic_colours(known, kc, unknown, np.zeros((25, 3)), k=6)
    # the same system, dense: u's k nearest nodes (itself excluded), Gaussian weights, symmetrised U-U
    nodes = np.concatenate([unknown, known])
    d, j = cKDTree(nodes).query(unknown, k=7)
    d, j = d[:, 1:], j[:, 1:]
    s2 = np.median(d[d > 0] ** 2)
    w = np.zeros((25, 85))
    for u in range(25):
        w[u, j[u]] = np.exp(-d[u] ** 2 / s2)
    wuu = (w[:, :25] + w[:, :25].T) / 2
    wuk = w[:, 25:]
    deg = wuu.sum(1) + wuk.sum(1)
    reaches = wuk.sum(1) > 0
    assert reaches.any()
    a = np.diag(deg) - wuu
    # groups without a known neighbour would be anchored; with this density every group reaches one
    from scipy.sparse.csgraph import connected_components

    n, lab = connected_components(wuu > 0)
    assert all(reaches[lab == g].any() for g in range(n))
    want = np.linalg.solve(a, wuk @ kc)
    assert np.allclose(got, want, rtol=1e-6, atol=1e-5)
    assert got.min() >= kc.min() - 1e-6 and got.max() <= kc.max() + 1e-6  # maximum principle


def test_fills_on_a_hole_in_a_plane():
    full = _plane()
    colours_full = _ramp(full)
    hole = np.linalg.norm(full[:, :2] - 20, axis=1) < 8
    inputs, colours = full[~hole], colours_full[~hole]
    outputs = np.concatenate([inputs, full[hole]])  # a perfect geometric fill
    for fill in ("nearest", "harmonic"):
        got = colour_frame(inputs, colours, outputs, fill)
        assert np.array_equal(got[: len(inputs)], colours)  # kept points keep their colour
        new = got[len(inputs):]
        if fill == "nearest":
            _, idx = cKDTree(inputs).query(full[hole])
            assert np.array_equal(new, colours[idx])
        err = np.abs(new.astype(int) - colours_full[hole].astype(int))[:, 0].mean()
        if fill == "harmonic":
            harmonic_err = err
        else:
            nearest_err = err
    assert harmonic_err < 0.5 * nearest_err  # a linear ramp is harmonic: interpolation recovers it


def test_every_method_output_carries_colour():
    frames = [_plane(24, 0.0), _plane(24, 0.0)]
    colours = [_ramp(f) for f in frames]
    region = HoleRegion.ball([12.0, 12.0, 0.0], 4.0)
    keep = [~region.contains(f) for f in frames]
    damaged = [f[k] for f, k in zip(frames, keep)]
    dcol = [c[k] for c, k in zip(colours, keep)]
    regions = [[region], [region]]
    for name in ("none", "temporal-copy", "lozes-pde"):
        method = get_method(name)
        points, cols = method.inpaint_with_colours(damaged, dcol, regions)
        geometry = get_method(name).inpaint(damaged, regions)
        for p, c, g in zip(points, cols, geometry):
            assert np.array_equal(p, g)  # colour never changes the geometry
            assert c.shape == (len(p), 3) and c.dtype == np.uint8
    with pytest.raises(UserError, match="colours"):
        get_method("none").inpaint_with_colours(damaged, dcol[:1], regions)
    with pytest.raises(UserError, match="unknown colour fill"):
        get_method("none").inpaint_with_colours(damaged, dcol, regions, fill="magic")


BUILT_INS = ("none", "temporal-copy", "lozes-pde", "meshlab", "fu-nonlocal", "temporal-graph", "temporal-fusion")


@pytest.mark.parametrize("name", BUILT_INS)
def test_every_built_in_method_carries_colour_with_its_own_geometry(name):
    """Every built-in method, by each fill: one (N', 3) uint8 colour per output point, the geometry exactly
    ``inpaint``'s, kept points (when the method keeps them) with their own colour."""
    import warnings

    from dpcbench.methods.registry import METHODS

    assert set(BUILT_INS) <= set(METHODS)
    frames = [_plane(30, 0.0) + [s, 0.0, 0.0] for s in (0.0, 1.0, 2.0)]  # a plane moving along x
    regions = [[], [HoleRegion.ball([16.0, 15.0, 0.0], 4.5)], []]  # a hole in the middle frame
    keep = [~r[0].contains(f) if r else np.ones(len(f), dtype=bool) for f, r in zip(frames, regions)]
    damaged = [f[k] for f, k in zip(frames, keep)]
    dcol = [_ramp(f)[k] for f, k in zip(frames, keep)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        geometry = get_method(name).inpaint(damaged, regions)
        for fill in ("auto", "nearest"):
            points, cols = get_method(name).inpaint_with_colours(damaged, dcol, regions, fill=fill)
            for p, c, g, d, dc in zip(points, cols, geometry, damaged, dcol):
                assert np.array_equal(p, g)
                assert c.shape == (len(p), 3) and c.dtype == np.uint8
                kept = kept_index(d, p)
                assert np.array_equal(c[kept >= 0], dc[kept[kept >= 0]])


def test_temporal_copy_reports_its_sources_and_carries_their_colours():
    """Frame 1's hole is copied from frame 0, which is the same plane shifted by (0.5, 0, 0): every
    copied point is a frame-0 point moved by the alignment, and takes that point's colour."""
    base = _plane(30)
    frames = [base + [0.5, 0.0, 0.0], base.copy()]
    colours = [np.random.default_rng(2).integers(0, 256, (len(base), 3)).astype(np.uint8) for _ in frames]
    region = HoleRegion.ball([15.0, 15.0, 0.0], 5.0)
    keep1 = ~region.contains(frames[1])
    damaged = [frames[0], frames[1][keep1]]
    dcol = [colours[0], colours[1][keep1]]
    regions = [[], [region]]
    method = get_method("temporal-copy")
    points, sources = method.inpaint_with_sources(damaged, regions)
    assert all(np.array_equal(p, g) for p, g in zip(points, get_method("temporal-copy").inpaint(damaged, regions)))
    frame_of, row_of = sources[1]
    n1 = len(damaged[1])
    assert np.array_equal(frame_of[:n1], np.ones(n1)) and np.array_equal(row_of[:n1], np.arange(n1))
    added = slice(n1, None)
    assert len(points[1]) > n1 and (frame_of[added] == 0).all()
    # the copied point is the source point rigidly moved: the motion is one translation for all
    shift = points[1][added] - damaged[0][row_of[added]]
    assert np.allclose(shift, shift[0], atol=1e-6)
    _, cols = method.inpaint_with_colours(damaged, dcol, regions, fill="source")
    assert np.array_equal(cols[1][added], colours[0][row_of[added]])
    assert np.array_equal(cols[1][:n1], dcol[1])


def test_inpaint_command_uses_the_methods_colours(tmp_path):
    import json

    from dpcbench.bench.cli import main
    from dpcbench.bench.data.plyio import PointCloud, read_ply, write_ply
    from dpcbench.holes.regions import regions_to_json

    full = _plane(30)
    colours = _ramp(full)
    region = HoleRegion.ball([15.0, 15.0, 0.0], 5.0)
    keep = ~region.contains(full)
    (tmp_path / "in").mkdir()
    write_ply(tmp_path / "in" / "f_0000.ply", PointCloud(full[keep], colours[keep]))
    (tmp_path / "holes.json").write_text(json.dumps(regions_to_json([[region]])))
    outs = {}
    for fill in ("nearest", "auto"):
        out = tmp_path / fill
        assert main(["inpaint", str(tmp_path / "in"), "--method", "lozes-pde", "--regions", str(tmp_path / "holes.json"),
                     "--out", str(out), "--colour", fill]) == 0
        cloud = read_ply(next(out.glob("*.ply")))
        assert json.loads((out / "inpaint.json").read_text())["colour"] == fill
        idx = kept_index(full[keep], cloud.points)
        assert np.array_equal(cloud.colors[idx >= 0], colours[keep][idx[idx >= 0]])
        outs[fill] = cloud
    new = kept_index(full[keep], outs["auto"].points) < 0
    assert new.any()
    _, nearest = cKDTree(full[keep]).query(outs["nearest"].points[new])
    assert np.array_equal(outs["nearest"].colors[new], colours[keep][nearest])
    assert not np.array_equal(outs["auto"].colors[new], outs["nearest"].colors[new])  # harmonic, not nearest
