"""Figures for print: size, text, colours by method, the floor dashed, PDF beside PNG."""

import matplotlib.image
import numpy as np
import pandas as pd
import pytest

from dpcbench.bench import figures, palette


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
    from dpcbench.bench.tables import comparison_table

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
    from dpcbench.bench.tables import comparison_table

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
