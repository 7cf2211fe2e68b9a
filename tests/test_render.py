"""dpcbench.bench.render: projection, z-buffer, shading, zoom box, highlight, figure layout."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib.image as mpimg
import numpy as np
import pytest

from dpcbench.bench.plyio import PointCloud
from dpcbench.bench.render import (
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


def test_zoom_grid_layout_magnification_and_depth_window(tmp_path):
    """Rows x columns of (cloud, zoom beside it): the hole's tinted fill covers many times more pixels
    in the zoom than in the cloud panel, a blob far in front of the hole (an occluding limb) hides it
    in the cloud panel but not in the zoom, and a column without a hole gets a plain "no hole" zoom."""
    from dpcbench.bench.render import render_zoom_grid

    full = sphere(n=20000, seed=3)
    hole = np.linalg.norm(full - [0.0, 0.0, 50.0], axis=1) < 10
    blob = sphere(n=2000, seed=4) * 0.3 + [0.0, 0.0, 95.0]  # 45 units in front of the hole centre, wider
    with_blob = np.vstack([full, blob])
    grid = [[full[~hole], full[~hole]], [with_blob, full]]
    highlight = [[None, None], [np.r_[hole, np.zeros(len(blob), bool)], hole]]
    H = 200
    out = render_zoom_grid(grid, tmp_path / "z.png", row_labels=["damaged", "filled"], column_labels=["f=0", "f=1"],
                           zooms=[np.array([0.0, 0.0, 50.0]), None], zoom_half=15.0, highlight=highlight,
                           view="front", panel_height=H)
    img = mpimg.imread(out)[..., :3]
    assert img.shape[1] > 1.6 * img.shape[0]  # two cells of (cloud, zoom) side by side, two rows
    label_w, head_h, gap_in, gap_row = int(0.3 * H), int(0.2 * H), 3, 8
    width = img.shape[1]
    cell = (width - label_w - gap_in - max(6, H // 12)) // 2  # two cells and one gap between them
    W = cell - gap_in - H
    red = (img[..., 0] > 0.3) & (img[..., 0] > 2.5 * img[..., 1]) & (img[..., 0] > 2.5 * img[..., 2])
    row1 = slice(head_h + H + gap_row, head_h + 2 * H + gap_row)
    cloud_panel = red[row1, label_w:label_w + W]
    zoom_panel = red[row1, label_w + W + gap_in:label_w + W + gap_in + H]
    hidden = red[row1, label_w + cell + max(6, H // 12):label_w + cell + max(6, H // 12) + W]  # f=1: no blob
    assert hidden.sum() > 20  # the fill is visible in a cloud panel without the blob in front
    assert cloud_panel.sum() < 0.5 * hidden.sum()  # the blob hides (most of) it in the panel it is in
    assert zoom_panel.sum() > 5 * hidden.sum()  # magnified, and the blob is outside the depth window
    assert not red[head_h:head_h + H].any()  # the damaged row has nothing tinted
    no_hole = img[row1, width - gap_in - H + 10:width - gap_in - 10]
    assert np.mean(np.all(np.abs(no_hole - 238 / 255) < 0.02, axis=-1)) > 0.8
    with pytest.raises(ValueError, match="zoom centres"):
        render_zoom_grid(grid, tmp_path / "x.png", row_labels=["a", "b"], column_labels=["f=0", "f=1"], zooms=[None])
