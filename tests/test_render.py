"""dpcbench.bench.reporting.render: projection, z-buffer, shading, zoom box, highlight, figure layout."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib.image as mpimg
import numpy as np
import pytest

from dpcbench.bench.data.plyio import PointCloud
from dpcbench.bench.reporting.render import (
    HIGHLIGHT_COLOR,
    panel_colours,
    rasterize,
    render_clouds,
    shade_normals,
    view_rotation,
    zoom_box,
)

RED, BLUE = np.array([255, 0, 0], np.uint8), np.array([0, 0, 255], np.uint8)


def test_view_rotations():
    np.testing.assert_allclose(view_rotation("front"), np.eye(3), atol=1e-12)
    # "left" looks at the +x face: +x comes towards the viewer (+z); "top": +y comes towards the viewer
    np.testing.assert_allclose(view_rotation("left") @ [1, 0, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(view_rotation("top") @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(view_rotation((90, 0)), view_rotation("right"), atol=1e-12)
    with pytest.raises(ValueError, match="unknown view"):
        view_rotation("diagonal")


def test_rasterize_places_points_and_keeps_the_nearest():
    bounds = (np.array([0.0, 0.0]), np.array([10.0, 10.0]))
    # two points on the same pixel: the one with larger z (nearer the viewer) wins in either order
    pts = np.array([[5.0, 5.0, 0.0], [5.0, 5.0, 3.0]])
    cols = np.stack([RED, BLUE])
    for order in ([0, 1], [1, 0]):
        img = rasterize(pts[order], cols[order], np.eye(3), bounds, 11, 11, radius=0)
        np.testing.assert_array_equal(img[5, 5], BLUE)
    # x to the right, y up: (0, 10) is the top-left pixel, (10, 0) the bottom-right one
    img = rasterize(np.array([[0.0, 10.0, 0.0], [10.0, 0.0, 0.0]]), cols, np.eye(3), bounds, 11, 11, radius=0)
    np.testing.assert_array_equal(img[0, 0], RED)
    np.testing.assert_array_equal(img[10, 10], BLUE)
    assert (img == 255).all(axis=2).sum() == 11 * 11 - 2
    # a splat of radius 1 covers a 3x3 square; radius 2 a 5x5 square without its 4 corners
    img = rasterize(pts[:1], cols[:1], np.eye(3), bounds, 11, 11, radius=1)
    assert (img == RED).all(axis=2).sum() == 9
    img = rasterize(pts[:1], cols[:1], np.eye(3), bounds, 11, 11, radius=2)
    assert (img == RED).all(axis=2).sum() == 21


def test_shade_normals_facing_light_is_brighter():
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    shade = shade_normals(normals, np.eye(3)).astype(int)
    assert shade[0].sum() > shade[1].sum()
    np.testing.assert_array_equal(shade[0], shade[2])  # unoriented normals: n and -n shade alike


def test_panel_colours_by_shading_mode():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    normals = np.array([[0.0, 0, 1]] * 2 + [[1.0, 0, 0]] * 2)  # facing the viewer / edge-on
    own = np.full((4, 3), 100, np.uint8)
    rot = np.eye(3)
    np.testing.assert_array_equal(panel_colours(pts, own, normals, "auto", rot), own)
    np.testing.assert_array_equal(panel_colours(pts, own, normals, "color", rot), own)
    np.testing.assert_array_equal(panel_colours(pts, own, normals, "normal", rot), shade_normals(normals, rot))
    np.testing.assert_array_equal(panel_colours(pts, None, normals, "auto", rot), shade_normals(normals, rot))
    shaded = panel_colours(pts, own, normals, "shaded", rot).astype(int)
    assert np.all(shaded <= 100) and shaded[0, 0] > shaded[2, 0]  # lit faces brighter than edge-on ones
    # no normals given: estimated (a flat square in z = 0 has normals +-z, facing the viewer)
    flat = panel_colours(pts, None, None, "normal", rot)
    np.testing.assert_array_equal(flat, shade_normals(np.tile([0.0, 0, 1], (4, 1)), rot))
    with pytest.raises(ValueError, match="no colours"):
        panel_colours(pts, None, normals, "color", rot)


def test_zoom_box_forms():
    lo, hi = zoom_box([4, 5, 6, 1, 2, 3])
    np.testing.assert_array_equal(lo, [1, 2, 3])
    np.testing.assert_array_equal(hi, [4, 5, 6])
    lo, hi = zoom_box(SimpleNamespace(center=[10, 10, 10], radius=2.0))
    np.testing.assert_array_equal(hi - lo, [4, 4, 4])
    rot = view_rotation((90, 0))  # a box turned by 90 degrees about y swaps its x and z extents
    lo, hi = zoom_box(SimpleNamespace(center=[0, 0, 0], radius=None, half_extents=[1, 2, 3], rotation=rot))
    np.testing.assert_allclose(hi, [3, 2, 1], atol=1e-12)
    with pytest.raises(ValueError, match="6 numbers"):
        zoom_box([1, 2, 3])
    with pytest.raises(ValueError, match="zero size"):
        zoom_box([0, 0, 0, 1, 0, 1])


def sphere(n=3000, seed=0, centre=(0, 0, 0)):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    return 50 * u / np.linalg.norm(u, axis=1, keepdims=True) + np.asarray(centre, float)


def test_render_grid_with_zoom_and_highlight(tmp_path):
    a, b = sphere(seed=1), sphere(seed=2, centre=(30, 0, 0))
    coloured = PointCloud(a, np.full((len(a), 3), 90, np.uint8))
    mask = b[:, 0] > 60
    out = render_clouds([[coloured, b], [a, b]], tmp_path / "grid.png", titles=[["a", "b"], ["c", "d"]],
                        highlight=[[None, mask], [None, None]], zoom=[0, -20, -60, 40, 20, 60], panel_height=200)
    img = mpimg.imread(out)
    assert img.shape[0] > img.shape[1] * 0.9  # 2 rows of panels + 2 zoom rows, 2 columns
    red = (img[..., 0] > 0.85) & (img[..., 1] < 0.2) & (img[..., 2] < 0.2)
    assert red.sum() > 50  # the highlighted points
    # deterministic: the same call gives the same PNG
    again = render_clouds([[coloured, b], [a, b]], tmp_path / "again.png", titles=[["a", "b"], ["c", "d"]],
                          highlight=[[None, mask], [None, None]], zoom=[0, -20, -60, 40, 20, 60], panel_height=200)
    np.testing.assert_array_equal(mpimg.imread(again), img)


def test_render_refuses_bad_panels(tmp_path):
    with pytest.raises(ValueError, match="one entry per panel"):
        render_clouds([sphere(), sphere()], tmp_path / "x.png", titles=["only one"])
    with pytest.raises(ValueError, match="NaN"):
        render_clouds([np.array([[0.0, np.nan, 0.0]])], tmp_path / "x.png")
    with pytest.raises(ValueError, match="highlight mask"):
        render_clouds([sphere()], tmp_path / "x.png", highlight=[np.ones(3, bool)])
    with pytest.raises(ValueError, match="empty"):
        render_clouds([], tmp_path / "x.png")
    assert HIGHLIGHT_COLOR[0] > 200


def _record_rasterize(monkeypatch):
    """Capture every rasterize call of bench.reporting.render: (points, bounds, width, height, radius)."""
    from dpcbench.bench.reporting import render

    calls = []
    original = render.rasterize

    def recording(points, colors, rotation, bounds, width, height, radius=1, background=(255, 255, 255)):
        calls.append((np.array(points), (np.array(bounds[0]), np.array(bounds[1])), width, height, radius))
        return original(points, colors, rotation, bounds, width, height, radius, background)

    monkeypatch.setattr(render, "rasterize", recording)
    return calls


def test_splat_size_closes_gaps_within_limits():
    from dpcbench.bench.reporting.render import point_spacing, splat_size

    assert splat_size(1.0, 10.0) == 5  # half of 10 pixels between neighbours
    assert splat_size(1.0, 10.0, cover=0.7, limit=10) == 7 and splat_size(1.0, 10.0, cover=0.7) == 6  # capped
    assert splat_size(1.0, 0.1) == 1 and splat_size(1.0, 0.01, minimum=0) == 1  # rounded up: never a gap
    assert splat_size(0.0, 10.0) == 2 and splat_size(0.0, 10.0, limit=1) == 1  # one point: a visible dot
    grid = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0), [0.0]), -1).reshape(-1, 3) * 2.5
    assert point_spacing(grid) == pytest.approx(2.5)
    assert point_spacing(grid[:1]) == 0.0
    # more points than the probe: still the grid's spacing, not the probe's own (a random thinning's nearest
    # neighbours lie about half as far apart as a grid's: 0.48 voxel was measured so on a voxelized frame)
    big = np.stack(np.meshgrid(np.arange(60.0), np.arange(60.0), [0.0]), -1).reshape(-1, 3)
    assert point_spacing(big, sample=500) == pytest.approx(1.0)


def test_render_clouds_uses_one_splat_size_for_every_panel(monkeypatch, tmp_path):
    """A panel with a quarter of the points keeps the splat radius of the first panel (its own spacing
    would give it larger splats and make it look magnified)."""
    calls = _record_rasterize(monkeypatch)
    dense = sphere(n=4000, seed=1)
    render_clouds([dense, dense[::4]], tmp_path / "two.png", panel_height=120)
    radii = [radius for *_, radius in calls]
    assert len(radii) == 2 and radii[0] == radii[1] >= 1


def test_a_close_zoom_of_a_voxel_grid_has_no_gaps(monkeypatch, tmp_path):
    """A flat voxel grid facing the camera, 90,000 points (more than the spacing probe's 50,000), zoomed to about 3 pixels a voxel:
    every pixel inside the zoomed grid is covered (a spacing measured at half the voxel, or splats that close the
    rows but not the diagonals, left a grid of background pixels there)."""
    from dpcbench.bench.reporting import render

    calls = _record_rasterize(monkeypatch)
    g = np.arange(300.0)
    plane = np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)
    render_clouds([plane], tmp_path / "zoom.png", zoom=(100, 100, -1, 175, 175, 1), panel_height=480, view="front",
                  shading="normal")
    points, bounds, width, height, radius = calls[-1]  # the zoom panel
    image = render.rasterize(points, np.zeros((len(points), 3), np.uint8), render.view_rotation("front"), bounds,
                             width, height, radius)
    assert width / 75 > 2.5  # a close zoom: pixels per voxel
    assert not np.any(np.all(image[2:-2, 2:-2] == 255, axis=-1))


def _zoom_grid_scene():
    """Two frames of a sphere (the second with a quarter of the points), a hole on its front and one
    on its top in frame 0, one on the front in frame 1; the filled column tints the hole points."""
    full = sphere(n=600, seed=3)
    front = np.linalg.norm(full - [0.0, 0.0, 50.0], axis=1) < 12
    top = np.linalg.norm(full - [0.0, 50.0, 0.0], axis=1) < 12
    grid = [[full, full[~(front | top)], full], [full, full[~front][::4], full[::4]]]
    highlight = [[None, None, front | top], [None, None, front[::4]]]
    zooms = [[[0.0, 0.0, 50.0], [0.0, 50.0, 0.0]], [[0.0, 0.0, 50.0]]]
    return grid, highlight, zooms


def test_zoom_grid_columns_zoom_rows_and_one_splat_size(tmp_path, monkeypatch):
    """Columns are the configurations, each frame a body row and then one zoom row per zoom; every
    body panel is drawn with one splat radius and every zoom with one (a sparse panel does not get
    larger splats); exactly ``width_in`` x ``dpi`` pixels wide, PDF beside the PNG."""
    from dpcbench.bench.reporting.render import render_zoom_grid

    calls = _record_rasterize(monkeypatch)
    grid, highlight, zooms = _zoom_grid_scene()
    fig = render_zoom_grid(grid, tmp_path / "z.png", column_labels=["truth", "damaged", "filled"],
                           row_labels=["f=0", "f=1"], zooms=zooms, zoom_half=15.0, highlight=highlight, view="front",
                           width_in=3.5, dpi=150)
    assert fig.columns == ["truth", "damaged", "filled"]
    assert fig.zoom_rows == [(0, 0), (0, 1), (1, 0)]
    assert len(calls) == 3 * (2 + 3)  # 3 columns x (2 body rows + 3 zoom rows)
    body = [c for c in calls if c[1][1][0] - c[1][0][0] > 40]  # a body panel shows the whole sphere
    zoom = [c for c in calls if c[1][1][0] - c[1][0][0] == pytest.approx(30.0)]
    assert len(body) == 6 and len(zoom) == 9
    assert {c[4] for c in body} == {fig.body_splat} and {c[4] for c in zoom} == {fig.zoom_splat}
    assert fig.zoom_splat > fig.body_splat  # magnified: larger splats close the gaps
    # each zoom row is centred on its own zoom (front hole: screen centre (0, 0); top hole seen from front: (0, 50))
    centres = [((lo + hi) / 2).round(6).tolist() for _, (lo, hi), *_ in zoom]
    assert centres == [[0.0, 0.0]] * 3 + [[0.0, 50.0]] * 3 + [[0.0, 0.0]] * 3
    image = mpimg.imread(fig.png)
    assert image.shape[1] == 3.5 * 150 and image.shape[0] == round(fig.size_in[1] * 150)  # no tight bounding box
    assert fig.pdf.read_bytes()[:5] == b"%PDF-"


def test_zoom_grid_magnifies_tints_and_windows_depth(tmp_path):
    """The hole's tinted fill covers many times more pixels in its zoom than in the body panel; a blob
    far in front of the hole (an occluding limb) hides it on the body but not in the zoom (depth window)."""
    from dpcbench.bench.reporting.render import render_zoom_grid

    full = sphere(n=6000, seed=3)
    hole = np.linalg.norm(full - [0.0, 0.0, 50.0], axis=1) < 10
    blob = sphere(n=1000, seed=4) * 0.3 + [0.0, 0.0, 95.0]  # 45 units in front of the hole centre, wider
    grid = [[full[~hole], np.vstack([full, blob]), full]]
    highlight = [[None, np.r_[hole, np.zeros(len(blob), bool)], hole]]
    fig = render_zoom_grid(grid, tmp_path / "z.png", column_labels=["damaged", "blob", "filled"], row_labels=["f=0"],
                           zooms=[[[0.0, 0.0, 50.0]]], zoom_half=15.0, highlight=highlight, view="front", width_in=3.0,
                           dpi=200)
    img = mpimg.imread(fig.png)[..., :3]
    red = (img[..., 0] > 0.3) & (img[..., 0] > 2.5 * img[..., 1]) & (img[..., 0] > 2.5 * img[..., 2])
    dpi = 200
    label, pitch = round(0.36 * dpi), (3.0 - 0.36) / 3 * dpi
    columns = [red[:, int(label + c * pitch) + 2:int(label + (c + 1) * pitch) - 8] for c in range(3)]
    # rows: body panels end where the zoom row begins (square, the panel's width, above the key)
    key = round(0.3 * dpi)
    zoom_rows = slice(img.shape[0] - key - int(pitch) + 4, img.shape[0] - key - 4)
    body_rows = slice(0, img.shape[0] - key - int(pitch) - 4)
    assert not columns[0].any()  # the damaged column has nothing tinted
    filled_body, filled_zoom = columns[2][body_rows].sum(), columns[2][zoom_rows].sum()
    assert filled_body > 5 and filled_zoom > 5 * filled_body  # magnified
    assert columns[1][body_rows].sum() < 0.5 * filled_body  # the blob hides it on the body
    assert columns[1][zoom_rows].sum() > 0.5 * filled_zoom  # but not in the zoom: outside the depth window


def test_zoom_grid_key_and_text_size(tmp_path, monkeypatch):
    """The figure has a key for the red tint and the orange zoom box, and no text under 7 pt."""
    import matplotlib.figure

    from dpcbench.bench.reporting.render import ZOOM_COLOUR, render_zoom_grid

    sizes, keys = [], []
    text, legend = matplotlib.figure.Figure.text, matplotlib.figure.Figure.legend
    monkeypatch.setattr(matplotlib.figure.Figure, "text",
                        lambda self, *a, **k: sizes.append(k.get("fontsize")) or text(self, *a, **k))
    monkeypatch.setattr(matplotlib.figure.Figure, "legend",
                        lambda self, *a, **k: keys.append(k.get("handles")) or legend(self, *a, **k))
    grid, highlight, zooms = _zoom_grid_scene()
    render_zoom_grid(grid, tmp_path / "z.png", column_labels=["a long configuration name (ours)", "b", "c"],
                     row_labels=["f=0", "f=1"], zooms=zooms, highlight=highlight, title="t", dpi=100)
    assert sizes and min(sizes) >= 7
    (handles,) = keys
    tint, box = handles
    import matplotlib.colors

    assert tint.get_facecolor()[0] > 0.7 and tint.get_facecolor()[1] < 0.2  # red
    assert tint.get_label() and box.get_label() and not box.get_fill()
    assert matplotlib.colors.same_color(box.get_edgecolor(), ZOOM_COLOUR)


def test_zoom_grid_refuses_bad_input(tmp_path):
    from dpcbench.bench.reporting.render import render_zoom_grid

    grid, highlight, zooms = _zoom_grid_scene()
    with pytest.raises(ValueError, match="lists of zooms"):
        render_zoom_grid(grid, tmp_path / "x.png", column_labels=["a", "b", "c"], row_labels=["f=0", "f=1"],
                         zooms=zooms[:1])
    with pytest.raises(ValueError, match="column_colours"):
        render_zoom_grid(grid, tmp_path / "x.png", column_labels=["a", "b", "c"], row_labels=["f=0", "f=1"],
                         zooms=zooms, column_colours=["red"])
    with pytest.raises(ValueError, match="highlight mask"):
        render_zoom_grid(grid, tmp_path / "x.png", column_labels=["a", "b", "c"], row_labels=["f=0", "f=1"],
                         zooms=zooms, highlight=[[None, None, np.ones(3, bool)], [None, None, None]])
