"""Figures for print: size, text, colours by method, the floor dashed, PDF beside PNG."""

import matplotlib.image
import numpy as np
import pandas as pd
import pytest

from dpcbench.bench.reporting import figures, palette


def _frames(sequences=("human", "bunny", "samba"), methods=("none", "temporal-graph", "fu-nonlocal")):
    rows = []
    for s, seq in enumerate(sequences):
        for m, method in enumerate(methods):
            for frame in range(4):
                rows.append({"sequence": seq, "method": method, "frame": frame, "metric": "nshd", "scope": "frame",
                             "peak": "", "value": 1e-8 * (1 + m + s) + 1e-10 * frame})
    return pd.DataFrame(rows)


def _lines(monkeypatch):
    """Capture every Line2D drawn by per_frame_curves (label -> (colour, linestyle, y data))."""
    drawn = {}
    original = figures.plt.Axes.plot

    def plot(self, *args, **kwargs):
        lines = original(self, *args, **kwargs)
        for line in lines:
            drawn.setdefault(line.get_label(), []).append((line.get_color(), line.get_linestyle(), line.get_ydata()))
        return lines

    monkeypatch.setattr(figures.plt.Axes, "plot", plot)
    return drawn


def test_per_frame_curves_for_print(tmp_path, monkeypatch):
    drawn = _lines(monkeypatch)
    out = figures.per_frame_curves(_frames(), "nshd", "frame", "", tmp_path / "f.png",
                                   column_of=lambda sel: sel["method"])
    assert out.exists() and out.with_suffix(".pdf").exists()
    height, width = matplotlib.image.imread(out).shape[:2]
    assert width / height < 3.0  # a grid, not a strip
    assert width == pytest.approx(figures.DOUBLE_COLUMN_IN * figures.PRINT_DPI, rel=0.1)
    colour, style, ys = drawn["temporal-graph"][0]
    assert colour.lower() == palette.METHOD_COLOURS["temporal-graph"].lower()
    assert drawn["none"][0][1] == "--"  # the floor dashed
    assert np.allclose(ys, 1e-8 * 2 * 1e7 + 1e-10 * np.arange(4) * 1e7)  # in units of 1e-7, as the tables


def test_single_column_width_gives_one_panel_per_row(tmp_path):
    out = figures.per_frame_curves(_frames(), "nshd", "frame", "", tmp_path / "f.png", width_in=figures.SINGLE_COLUMN_IN,
                                   column_of=lambda sel: sel["method"])
    height, width = matplotlib.image.imread(out).shape[:2]
    assert width == pytest.approx(figures.SINGLE_COLUMN_IN * figures.PRINT_DPI, rel=0.15)
    assert height > width  # three sequences stacked


def test_print_style_keeps_text_readable():
    style = figures.print_style()
    assert min(v for k, v in style.items() if k.endswith("size")) >= figures.MIN_TEXT_PT



def test_bar_chart_intervals_floor_and_colours(tmp_path, monkeypatch):
    from dpcbench.bench.reporting.tables import comparison_table

    df = _frames(sequences=("human", "bunny"))
    df["seed"] = 0
    table = comparison_table(df, "nshd", column_of=lambda sel: sel["method"], scale=1e7, decimals=None)
    drawn = {}
    original = figures.plt.Axes.bar

    def bar(self, x, height, *args, **kwargs):
        drawn[kwargs.get("label")] = (kwargs.get("color"), kwargs.get("yerr"))
        return original(self, x, height, *args, **kwargs)

    monkeypatch.setattr(figures.plt.Axes, "bar", bar)
    out = figures.bar_chart(table, tmp_path / "t.png")
    assert out.exists() and out.with_suffix(".pdf").exists()
    assert "none" not in drawn  # the floor is a line, not a bar
    colour, (low, high) = drawn["fu-nonlocal"]
    assert colour == palette.METHOD_COLOURS["fu-nonlocal"]
    lo, hi = table.interval("human", "fu-nonlocal")
    assert high[0] == pytest.approx(hi * 1e7 - table.mean[("human", "fu-nonlocal")] * 1e7)
    assert low[0] == pytest.approx(table.mean[("human", "fu-nonlocal")] * 1e7 - max(lo * 1e7, 0.0))
    height, width = matplotlib.image.imread(out).shape[:2]
    assert width / height < 3.0


def test_a_label_with_dollar_signs_prints_as_written(tmp_path):
    from dpcbench.bench.reporting.tables import comparison_table

    df = _frames(sequences=(r"$\frac{broken$", "a $5 and $6 bill"))
    df["seed"] = 0
    table = comparison_table(df, "nshd", column_of=lambda sel: sel["method"] + r" $x^$", scale=1e7)
    assert figures.bar_chart(table, tmp_path / "t.png").exists()
    assert figures.per_frame_curves(df, "nshd", "frame", "", tmp_path / "f.png",
                                    column_of=lambda sel: sel["method"] + r" $\sqrt{$").exists()


def test_long_row_names_become_letters_with_a_key():
    assert figures.tick_labels(["human", "bunny"]) == (["human", "bunny"], [])
    ticks, key = figures.tick_labels(["Bunny (stand-in) · coherent holes", "human"])
    assert ticks == ["A", "B"] and key == ["A: Bunny (stand-in) · coherent holes", "B: human"]


def test_bar_chart_draws_without_warnings(tmp_path):
    """Every warning an error: a legend only of labelled artists (an unlabelled one warned "No artists
    with labels found"), for a table with methods and for one with only the floor column."""
    import warnings

    from dpcbench.bench.reporting.tables import comparison_table

    for methods in (("none", "temporal-graph", "fu-nonlocal"), ("none",)):
        df = _frames(sequences=("human",), methods=methods)
        df["seed"] = 0
        table = comparison_table(df, "nshd", column_of=lambda sel: sel["method"], scale=1e7, decimals=None)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert figures.bar_chart(table, tmp_path / f"{len(methods)}.png").exists()


def _sphere_with_holes(n=1500):
    """A unit sphere of ``n`` points; frame 0 has a hole on the front and one on top, frame 1 one on the front."""
    from dpcbench.holes.regions import HoleRegion

    rng = np.random.default_rng(0)
    base = rng.normal(size=(n, 3))
    base /= np.linalg.norm(base, axis=1, keepdims=True)
    front, top = HoleRegion.ball([0.0, 0.0, 1.0], 0.3), HoleRegion.ball([0.0, 1.0, 0.0], 0.25)
    regions = [[front, top], [front]]
    damaged = [base[~(front.contains(base) | top.contains(base))], base[~front.contains(base)]]
    return base, damaged, regions


def test_subjective_grid_columns_zooms_size_and_colours(tmp_path, monkeypatch):
    """k methods give k + 2 columns (ground truth, damaged, the methods, in that order, titled in the
    palette's colours); every hole region of every frame gets a zoom row, centred on that hole as seen
    from outside the body; 7.2 in wide at 300 dpi exactly, PDF beside it."""
    import matplotlib.figure

    from dpcbench.bench.reporting import render

    base, damaged, regions = _sphere_with_holes()
    methods = ["Meshlab", "Proposed", "temporal-fusion (ours)"]
    colours = [palette.METHOD_COLOURS[name] for name in ("meshlab", "temporal-graph", "temporal-fusion")]
    columns = [("Ground truth", [base, base]), ("With holes", damaged)] + [(m, [base, base]) for m in methods]
    drawn, texts = [], {}
    original, text = render.rasterize, matplotlib.figure.Figure.text

    def rasterize(points, colors, rotation, bounds, *args, **kwargs):
        drawn.append((np.array(rotation), (bounds[0] + bounds[1]) / 2, len(points)))
        return original(points, colors, rotation, bounds, *args, **kwargs)

    def record_text(self, x, y, s, *args, **kwargs):
        texts[s] = kwargs.get("color")
        return text(self, x, y, s, *args, **kwargs)

    monkeypatch.setattr(render, "rasterize", rasterize)
    monkeypatch.setattr(matplotlib.figure.Figure, "text", record_text)
    fig = figures.subjective_grid(columns, ["f=0", "f=1"], tmp_path / "fig.png", hole_regions=regions,
                                  column_colours=[None, None] + colours, title="test")
    assert fig.columns == ["Ground truth", "With holes"] + methods  # k + 2 columns, in order
    assert fig.zoom_rows == [(0, 0), (0, 1), (1, 0)]  # every hole of every frame
    assert len(drawn) == len(columns) * (2 + 3)
    # drawn row by row (body f=0, its 2 zooms, body f=1, its zoom), 5 panels a row; each zoom row's
    # panels centred on its hole, seen straight on from the hole's outside (`hole_view`)
    for (f, r), position in zip(fig.zoom_rows, (1, 2, 4)):
        rotation = render.view_rotation(figures.hole_view(base, regions[f][r]))
        for d_rotation, centre, _ in drawn[5 * position:5 * position + 5]:
            np.testing.assert_allclose(d_rotation, rotation, atol=1e-12)
            np.testing.assert_allclose(centre, (rotation @ regions[f][r].center)[:2], atol=1e-9)
    assert texts["Meshlab"].lower() == colours[0].lower() and texts["Ground truth"] == "black"
    image = matplotlib.image.imread(fig.png)
    assert image.shape[1] == 7.2 * 300 and image.shape[0] == round(fig.size_in[1] * 300)
    assert fig.pdf.exists() and fig.pdf.read_bytes()[:5] == b"%PDF-"
    with pytest.raises(ValueError, match="one list of regions per frame"):
        figures.subjective_grid(columns, ["f=0", "f=1"], tmp_path / "x.png", hole_regions=regions[:1])


def test_figure_columns_follow_the_table_in_palette_colours():
    """Every non-floor column of the tables that ran, in TABLE_COLUMNS' order, in its palette colour
    (the tuned temporal-graph a darker shade of Proposed's); the missing ones named."""
    from dpcbench.bench.reporting import paper

    labels = [label for _, label, _, role in paper.TABLE_COLUMNS if role != "floor"]
    done = {label: (None, f"folder of {label}") for label in reversed(labels) if label != "Lozes"}
    columns, colours, missing = paper.figure_columns(done, lambda folder: [folder])
    assert [label for label, _ in columns] == [label for label in labels if label != "Lozes"]
    assert columns[0][1] == ["folder of Meshlab"] and missing == ["Lozes"]
    assert colours[0] == palette.METHOD_COLOURS["meshlab"]
    proposed, tuned = colours[2], colours[3]
    assert proposed == palette.METHOD_COLOURS["temporal-graph"] and tuned == palette.shade(proposed, 0.35)


def test_shown_frames_keep_the_zoom_rows_within_a_page():
    from dpcbench.bench.reporting import paper

    assert paper.shown_frames([0, 9], [3, 3]) == [0, 9]
    assert paper.shown_frames([0, 9], [6, 6]) == [0]  # 12 zoom rows: only the first frame
    assert paper.shown_frames([0, 9], [paper.MAX_ZOOM_ROWS + 4, 0]) == [0]  # the first is always shown
    assert paper.shown_frames([0, 1], [0, paper.MAX_ZOOM_ROWS]) == [0, 1]


def test_hole_view_looks_into_a_hole_on_the_side_of_a_limb():
    """A limb (a cylinder along y) beside a large torso (a plane far in +x): a hole on the limb's -z side
    is seen edge-on from the centroid's direction (`facing_view`), straight on along its normal by `hole_view`."""
    from dpcbench.bench.reporting.render import view_rotation
    from dpcbench.holes.regions import HoleRegion

    rng = np.random.default_rng(2)
    angle, height = rng.uniform(0, 2 * np.pi, 3000), rng.uniform(0, 40, 3000)
    limb = np.c_[3 * np.cos(angle), height, 3 * np.sin(angle)]
    torso = np.c_[np.full(6000, 50.0), rng.uniform(0, 40, 6000), rng.uniform(-20, 20, 6000)]
    body = np.vstack([limb, torso])
    hole = HoleRegion.ball([0.0, 20.0, -3.0], 1.5)
    towards_viewer = view_rotation(figures.hole_view(body, hole)) @ [0.0, 0.0, -1.0]
    assert towards_viewer[2] > 0.95  # the hole's outward normal (-z) points at the viewer
    edge_on = view_rotation(figures.facing_view(body, hole.center)) @ [0.0, 0.0, -1.0]
    assert edge_on[2] < 0.5
    sparse = HoleRegion.ball([0.0, 100.0, 0.0], 1.0)  # no point near: the centroid's direction
    assert figures.hole_view(body, sparse) == figures.facing_view(body, sparse.center)
