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


def _psnr_frames(capped_method="temporal-fusion"):
    """gpsnr_d1 per frame: two methods near 30-40 dB, one at the 200 dB cap on frame 1 (equal to the reference)."""
    rows = []
    for seq in ("Samba (real captured motion, not one of the paper's sequences) · independent holes", "b"):
        for m, method in enumerate(("none", "lozes-pde", capped_method)):
            for frame in range(3):
                value = 200.0 if (method == capped_method and frame == 1) else 30.0 + 3 * m + 0.5 * frame
                rows.append({"sequence": seq, "method": method, "frame": frame, "metric": "gpsnr_d1", "scope": "frame",
                             "peak": "intrinsic", "value": value, "seed": 0})
    return pd.DataFrame(rows)


def test_capped_psnr_stays_off_the_scale_and_is_marked(tmp_path, monkeypatch):
    """A frame equal to the reference (200 dB, the cap) would squash the other values into the bottom tenth of the
    axis: the y range is set by the values below the cap, the capped ones marked at the top."""
    from dpcbench.bench.reporting.tables import comparison_table

    assert figures.psnr_cap("gpsnr_d1") == 200.0 and figures.psnr_cap("nshd") is None
    assert figures.capped_limits([30.0, 36.0], 200.0, from_zero=True) is None
    bottom, top = figures.capped_limits([30.0, 36.0, 200.0], 200.0, from_zero=False)
    assert 36.0 < top < 40.0 and 25.0 < bottom < 30.0

    limits, notes = [], []
    set_ylim, text = figures.plt.Axes.set_ylim, figures.plt.Figure.text

    def record_ylim(self, *args, **kwargs):
        result = set_ylim(self, *args, **kwargs)
        limits.append(self.get_ylim())
        return result

    def record_text(self, x, y, s, *args, **kwargs):
        notes.append(s)
        return text(self, x, y, s, *args, **kwargs)

    monkeypatch.setattr(figures.plt.Axes, "set_ylim", record_ylim)
    monkeypatch.setattr(figures.plt.Figure, "text", record_text)
    df = _psnr_frames()
    table = comparison_table(df, "gpsnr_d1", peak="intrinsic", column_of=lambda sel: sel["method"])
    figures.bar_chart(table, tmp_path / "bars.png")
    # the mean over frames of which one is capped (~87 dB) sets the scale, its interval (hundreds of dB) is cut
    bottom, top = limits[-1]
    assert -0.3 * top <= bottom <= 0.0 and 87 < top < 120, limits
    assert any("cut at its edge" in note for note in notes)
    # a cell at the cap in every frame: off the scale, marked at the top
    limits.clear()
    notes.clear()
    always = df.assign(value=np.where(df["method"] == "temporal-fusion", 200.0, df["value"]))
    figures.bar_chart(comparison_table(always, "gpsnr_d1", peak="intrinsic", column_of=lambda sel: sel["method"]),
                      tmp_path / "bars2.png")
    bottom, top = limits[-1]
    assert top < 45, limits
    assert any(figures.CAP_MARK in note and "200 dB" in note for note in notes)
    assert figures.bar_limits([30.0, 36.0], [29.0, 35.0], [31.0, 37.0], 200.0) is None  # nothing to cut: matplotlib's
    limits.clear()
    notes.clear()
    figures.per_frame_curves(df, "gpsnr_d1", "frame", "intrinsic", tmp_path / "curves.png",
                             column_of=lambda sel: sel["method"])
    assert [top < 45 for _, top in limits].count(True) == 2, limits  # one per panel (matplotlib's own calls besides)
    assert any("200 dB" in note for note in notes)


def test_long_panel_titles_wrap_within_their_panel(tmp_path, monkeypatch):
    titles = []
    set_title = figures.plt.Axes.set_title

    def record(self, label, *args, **kwargs):
        titles.append(label)
        return set_title(self, label, *args, **kwargs)

    monkeypatch.setattr(figures.plt.Axes, "set_title", record)
    figures.per_frame_curves(_psnr_frames(), "gpsnr_d1", "frame", "intrinsic", tmp_path / "curves.png",
                             column_of=lambda sel: sel["method"])
    longest = max(len(line) for t in titles for line in t.split("\n"))
    assert longest <= 16 * figures.DOUBLE_COLUMN_IN / 2 and any("\n" in t for t in titles)
