"""Conformance of every built-in inpainting method to the interface in `methods/base.py`, by the
public check `dpcbench.testing.check_method` (what a plug-in's author runs on their own method),
and that check's refusals of methods that break the contract, each with the message it gives.

Parametrized over every built-in name in `methods.registry.METHODS`, so a new method is checked as
soon as it is registered. A registered name whose module or class cannot be imported fails (never
skips). The data is `dpcbench.testing.sample_sequence` (3 frames, ~2k points each, two ball holes
per frame): each method runs in full four times (output, read-only input, blind, one frame).
"""

from __future__ import annotations

import numpy as np
import pytest

from dpcbench.methods.base import InpaintingMethod, PerFrameMethod
from dpcbench.methods.registry import METHODS, method_class
from dpcbench.testing import CHECKS, ConformanceError, check_method, sample_sequence

BUILTIN = METHODS.builtin_names()
#: parameters under which a method fills `sample_sequence` (a sparse float sphere, ~4 units between points). At
#: their defaults the cube methods take a float frame's unit as 1/1024 of its extent (the paper's rule for a 10-bit
#: body), no cube then holds enough points, and every check would see the frames come back unchanged (in 5 s an
#: inpaint: the cube grid of that unit is large). The unit is the median point spacing, not a length in coordinates,
#: so that the unit-of-length check sees the same parameters at every scale
FILLING = {"temporal-graph": {"spacing": "points", "cube_size": 10.0},
           "fu-nonlocal": {"spacing": "points", "cube_size": 10.0}}


@pytest.mark.parametrize("name", BUILTIN)
def test_every_builtin_method_passes_check_method(name):
    timings = check_method(method_class(name), FILLING.get(name), name=name)
    assert list(timings) == list(CHECKS)


@pytest.mark.parametrize("name", sorted(FILLING))
def test_the_cube_methods_fill_the_sample_sequence_under_their_check_parameters(name):
    frames, regions = sample_sequence()
    out = method_class(name)(**FILLING[name]).inpaint([f.copy() for f in frames], regions)
    assert all(len(o) > len(f) for o, f in zip(out, frames))


def test_the_example_plugin_passes_check_method(monkeypatch):
    from pathlib import Path

    src = Path(__file__).resolve().parents[1] / "examples" / "dpcbench-example-plugin" / "src"
    monkeypatch.syspath_prepend(str(src))
    assert list(check_method("dpcbench_example_plugin.fills:QuadricFill")) == list(CHECKS)
    assert list(check_method("dpcbench_example_plugin.fills:QuadricFill", {"rim_spacings": 2.0})) == list(CHECKS)


# -- methods that break the contract, one way each ------------------------------------------------
class GoodFill(PerFrameMethod):
    """Adds each region's centre (a correct, minimal method: the baseline the broken ones vary)."""

    name = "good-fill"
    summary = "adds each hole region's centre"
    version = "1"
    needs_regions = True

    def __init__(self, copies: int = 1):
        self.copies = copies

    def inpaint_frame(self, points, regions):
        centres = [np.asarray(r.center, dtype=float)[None] for r in regions for _ in range(self.copies)]
        return np.vstack([points, *centres])


class MutatingFill(GoodFill):
    name = "mutating-fill"

    def inpaint(self, frames, regions=None):
        for frame in frames:
            frame += 0.0  # in place: harmless on a writable frame... and still a write
            frame[0] = frame[-1]
        return super().inpaint(frames, regions)


class WrongShapeFill(GoodFill):
    name = "wrong-shape-fill"

    def inpaint_frame(self, points, regions):
        return super().inpaint_frame(points, regions)[:, :2]


class WorkingInitFill(GoodFill):
    name = "working-init-fill"

    def __init__(self, copies: int = 1):
        self.copies = copies
        self.offsets = np.linspace(0.0, 1.0, 64)  # work (and state) that belongs in inpaint


class ConvertingInitFill(GoodFill):
    name = "converting-init-fill"

    def __init__(self, copies: int = 1):
        self.copies = int(copies) + 1


class RandomFill(GoodFill):
    name = "random-fill"

    def inpaint_frame(self, points, regions):
        jitter = np.random.default_rng().normal(size=(len(regions), 3))  # no seed parameter
        return np.vstack([points, np.array([r.center for r in regions]) + jitter])


class AcceptsBlindFill(GoodFill):
    name = "accepts-blind-fill"

    def inpaint(self, frames, regions=None):
        if regions is None:
            return [np.array(f, dtype=np.float64) for f in frames]
        return super().inpaint(frames, regions)


class AbsoluteGridFill(GoodFill):
    """Fills each ball region with the points of a grid of step 4 coordinate units: a rule in absolute units."""

    name = "absolute-grid-fill"

    def inpaint_frame(self, points, regions):
        axis = np.arange(-20.0, 21.0, 4.0)
        grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
        fills = [r.center + grid[np.linalg.norm(grid, axis=1) <= r.radius] for r in regions]
        return np.vstack([points, *fills])


class AliasingFill(GoodFill):
    name = "aliasing-fill"

    def inpaint(self, frames, regions=None):
        checked, _ = self._check_inputs(frames, regions)
        return checked  # float64 input comes back as the very same arrays


def test_check_method_passes_a_correct_method_and_runs_a_subset():
    assert list(check_method(GoodFill)) == list(CHECKS)
    assert list(check_method(GoodFill, {"copies": 2}, checks=("output", "deterministic"))) == ["output", "deterministic"]
    with pytest.raises(ValueError, match="unknown check"):
        check_method(GoodFill, checks=("nope",))


@pytest.mark.parametrize("cls, check, message", [
    (MutatingFill, "inputs-untouched", r"inpaint changed input frame 0 in place; work on a copy"),
    (WrongShapeFill, "output", r"frame 0 of the output has shape \(\d+, 2\); expected \(N, 3\)"),
    (WorkingInitFill, "init-stores-parameters", r"__init__ set attribute\(s\) offsets that are not parameters"),
    (ConvertingInitFill, "init-stores-parameters", r"__init__ stored copies=2 for the value 1; store parameters unchanged"),
    (RandomFill, "deterministic", r"two runs with the same parameters differ in frame 0"),
    (AcceptsBlindFill, "blind", r"regions=None was accepted although detects_holes is False"),
    (AliasingFill, "output", r"frame 0 of the output shares memory with an input frame"),
    (AbsoluteGridFill, "unit-of-length", r"scaled by 0.000976562 \(the same capture in other units\), frame 0 came "
                                         r"back with \d+ points instead of \d+"),
])
def test_check_method_rejects_a_method_that_breaks_the_contract(cls, check, message):
    with pytest.raises(ConformanceError, match=message) as info:
        check_method(cls)
    assert info.value.check == check and info.value.method == cls.name
    assert str(info.value).startswith(f"{cls.name}: check {check!r} failed: ")


def test_check_method_names_the_class_fact_that_is_wrong():
    class Unnamed(GoodFill):
        name = ""

    with pytest.raises(ConformanceError, match=r"class attribute `name` must be a non-empty string"):
        check_method(Unnamed)
    with pytest.raises(ConformanceError, match=r"`name` is 'good-fill' but it is registered as 'other'"):
        check_method(GoodFill, name="other")
    with pytest.raises(ConformanceError, match=r"not a subclass of dpcbench.methods.base.InpaintingMethod"):
        check_method(dict)  # type: ignore[arg-type]

    class GroundTruthFill(InpaintingMethod):
        name, summary = "gt-fill", "takes the ground truth"

        def inpaint(self, frames, regions=None, truth=None):
            return frames

    with pytest.raises(ConformanceError, match=r"expected inpaint\(self, frames, regions=None\)"):
        check_method(GroundTruthFill)


# -- the command ---------------------------------------------------------------------------------
def test_check_method_command_reports_each_check_and_the_failure(capsys):
    from dpcbench.bench.cli import main

    assert main(["check-method", "none"]) == 0
    out = capsys.readouterr().out
    assert [line.split()[1] for line in out.splitlines() if line.startswith("ok")] == list(CHECKS)
    assert f"none: {len(CHECKS)} check(s) passed" in out
    assert main(["check-method", "tests.test_conformance:GoodFill", "--param", "copies=3", "--check", "output"]) == 0
    assert "1 check(s) passed" in capsys.readouterr().out
    assert main(["check-method", "tests.test_conformance:MutatingFill"]) == 1
    captured = capsys.readouterr()
    assert "FAILED  check 'inputs-untouched': inpaint changed input frame 0 in place" in captured.out
    assert "does not conform (check 'inputs-untouched')" in captured.err
    assert main(["check-method", "no-such-method"]) == 2
    assert "unknown method 'no-such-method'" in capsys.readouterr().err
    assert main(["check-method", "none", "--param", "k=1"]) == 2
    assert "unknown parameter" in capsys.readouterr().err
