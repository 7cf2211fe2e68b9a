"""The method palette: fixed by name, colour-blind safe (checked by simulating colour-vision deficiency)."""

import itertools

import numpy as np
import pytest

from dpcbench.bench.reporting import palette

# Machado, Oliveira & Fernandes (2009), severity 1.0, applied to linear sRGB
DEUTERANOPIA = np.array([[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                         [-0.011820, 0.042940, 0.968881]])
PROTANOPIA = np.array([[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                       [-0.003882, -0.048116, 1.051998]])
#: the smallest sRGB distance two colours keep under simulation; matplotlib's red against green (tab10
#: C3/C2) keeps 0.12 under deuteranopia, the Okabe-Ito set at least 0.20
MIN_DISTANCE = 0.15


def _seen(colour: str, matrix: np.ndarray) -> np.ndarray:
    c = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    out = np.clip(matrix @ linear, 0.0, 1.0)
    return np.where(out <= 0.0031308, 12.92 * out, 1.055 * out ** (1 / 2.4) - 0.055)


def _min_distance(colours, matrix) -> float:
    return min(float(np.linalg.norm(_seen(a, matrix) - _seen(b, matrix)))
               for a, b in itertools.combinations(colours, 2))


@pytest.mark.parametrize("matrix", [DEUTERANOPIA, PROTANOPIA], ids=["deuteranopia", "protanopia"])
def test_builtin_colours_stay_apart_under_colour_vision_deficiency(matrix):
    assert _min_distance(palette.METHOD_COLOURS.values(), matrix) > MIN_DISTANCE


def test_the_check_rejects_red_against_green():
    assert _min_distance(["#d62728", "#2ca02c"], DEUTERANOPIA) < MIN_DISTANCE


def test_proposed_and_hu_are_not_red_and_green():
    proposed, hu = palette.method_colour("temporal-graph"), palette.method_colour("fu-nonlocal")
    for colour in (proposed, hu):
        r, g, b = (int(colour[i:i + 2], 16) for i in (1, 3, 5))
        assert not (r > 150 and g < 80 and b < 80), colour  # not a red
        assert not (g > 120 and r < 80 and b < 80), colour  # not a green


def test_colour_follows_the_name_not_the_position():
    a = palette.configuration_colours([("A", "temporal-fusion"), ("B", "lozes-pde")])
    b = palette.configuration_colours([("B", "lozes-pde"), ("X", "meshlab"), ("A", "temporal-fusion")])
    assert a["A"] == b["A"] == palette.METHOD_COLOURS["temporal-fusion"]
    assert a["B"] == b["B"]
    assert palette.method_colour("mypkg.fills:MyFill") == palette.method_colour("mypkg.fills:MyFill")
    assert palette.method_colour("mypkg.fills:MyFill") in palette.EXTRA_COLOURS


def test_configurations_of_one_method_share_its_hue_in_shades():
    colours = palette.configuration_colours([("Proposed", "temporal-graph"), ("tuned", "temporal-graph")])
    assert colours["Proposed"] == "#0072B2"
    assert colours["tuned"] == palette.shade("#0072B2", 0.35) == "#004A74"
    with pytest.raises(ValueError, match="outside"):
        palette.shade("#0072B2", 1.0)
