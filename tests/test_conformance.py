"""Conformance of every registered inpainting method to the interface in `methods/base.py`.

Parametrized over every name in `methods.registry.METHODS`, so a new method is checked as soon as it
is registered. A registered name whose module or class cannot be imported fails (never skips).

The data is a tiny synthetic sequence (3 frames of a bumpy sphere, ~2k points each, radius 50, so
the spacing is ~4 units) with two ball holes per frame, small enough for the slow methods. Each
method runs in full three times (reference output, mutation + determinism, read-only input on two
frames) plus a one-frame run, to keep the suite well under a minute.
"""

from __future__ import annotations

import inspect
import warnings

import numpy as np
import pytest

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.base import InpaintingMethod
from dpcbench.methods.registry import METHODS, method_class

N_FRAMES = 3


def bumpy_sphere(n_points: int, frame: int) -> np.ndarray:
    """Fibonacci-sampled sphere of radius 50 with a smooth bump field that moves with ``frame``:
    r(u) = 50 (1 + 0.08 sin(3 u_x + 0.2 f) cos(2 u_y) + 0.05 u_z^2), u the unit direction."""
    i = np.arange(n_points) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n_points)
    azimuth = np.pi * (1.0 + 5.0 ** 0.5) * i
    u = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    radius = 50.0 * (1.0 + 0.08 * np.sin(3 * u[:, 0] + 0.2 * frame) * np.cos(2 * u[:, 1]) + 0.05 * u[:, 2] ** 2)
    return u * radius[:, None] + np.array([1.5, -0.5, 0.8]) * frame


@pytest.fixture(scope="module")
def damaged_sequence():
    """(damaged frames, regions per frame): two ball holes per frame, each removing ~2-4% of it."""
    frames, regions = [], []
    for f in range(N_FRAMES):
        intact = bumpy_sphere(2000 + 40 * f, f)
        # a hole at a fixed direction (coherent over time) and one that wanders
        frame_regions = [HoleRegion.ball(intact[np.argmax(intact[:, 2])], 16.0),
                         HoleRegion.ball(intact[np.argmax(intact @ np.array([1.0, 0.3 * f, 0.2]))], 14.0)]
        removed = np.zeros(len(intact), dtype=bool)
        for region in frame_regions:
            removed |= region.contains(intact)
        assert 0.02 < removed.mean() < 0.15
        frames.append(intact[~removed])
        regions.append(frame_regions)
    return frames, regions


def run_quietly(method, frames, regions):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return method.inpaint(frames, regions)


@pytest.fixture(scope="module")
def outputs(damaged_sequence):
    """name -> output of the default-configured method on the shared sequence (computed once)."""
    frames, regions = damaged_sequence
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = run_quietly(method_class(name)(), frames, regions)
        return cache[name]

    return get


NAMES = sorted(METHODS)


@pytest.mark.parametrize("name", NAMES)
def test_class_facts(name):
    cls = method_class(name)
    assert issubclass(cls, InpaintingMethod)
    assert cls.name == name, f"class fact `name` is {cls.name!r}, registry key is {name!r}"
    assert isinstance(cls.summary, str) and cls.summary.strip()
    assert isinstance(cls.version, str) and cls.version.strip()
    for fact in ("uses_neighbour_frames", "needs_regions", "detects_holes"):
        assert isinstance(getattr(cls, fact), bool), fact
    assert not (cls.needs_regions and cls.detects_holes), "a method that needs regions cannot detect holes"


@pytest.mark.parametrize("name", NAMES)
def test_inpaint_takes_only_frames_and_regions(name):
    """The interface gives a method no way to receive the ground truth."""
    cls = method_class(name)
    params = list(inspect.signature(cls.inpaint).parameters)
    assert params == ["self", "frames", "regions"], params
    assert inspect.signature(cls.inpaint).parameters["regions"].default is None


@pytest.mark.parametrize("name", NAMES)
def test_init_only_stores_parameters(name):
    cls = method_class(name)
    method = cls()
    params = method.get_params()
    assert set(vars(method)) == set(params), "__init__ must store its parameters and nothing else"
    clone = cls(**params)
    assert clone.get_params() == params
    assert repr(clone) == repr(method)
    with pytest.raises(ValueError, match="unknown parameter"):
        method.set_params(no_such_parameter=1)


@pytest.mark.parametrize("name", NAMES)
def test_output_is_a_list_of_finite_float_frames(name, outputs, damaged_sequence):
    frames, _ = damaged_sequence
    out = outputs(name)
    assert isinstance(out, list) and len(out) == len(frames)
    for f, arr in enumerate(out):
        assert isinstance(arr, np.ndarray) and arr.dtype == np.float64, (f, type(arr), getattr(arr, "dtype", None))
        assert arr.ndim == 2 and arr.shape[1] == 3 and len(arr) > 0, (f, arr.shape)
        assert np.isfinite(arr).all(), f
        assert not any(np.shares_memory(arr, frame) for frame in frames), "output must not alias the input"


@pytest.mark.parametrize("name", NAMES)
def test_inputs_are_not_mutated_and_same_parameters_give_the_same_output(name, outputs, damaged_sequence):
    frames, regions = damaged_sequence
    cls = method_class(name)
    given = [frame.copy() for frame in frames]
    region_dicts = [[r.to_dict() for r in frame_regions] for frame_regions in regions]
    again = run_quietly(cls(**cls().get_params()), given, regions)
    for arr, frame in zip(given, frames):
        np.testing.assert_array_equal(arr, frame)
    assert [[r.to_dict() for r in frame_regions] for frame_regions in regions] == region_dicts
    for a, b in zip(outputs(name), again):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", NAMES)
def test_read_only_frames_are_accepted(name, damaged_sequence):
    """Frames may be read-only (memory-mapped files, shared caches); a method that only reads its
    input works on them. (open3d's Vector3dVector refuses read-only arrays: copy before it.)"""
    frames, regions = damaged_sequence
    readonly = []
    for frame in frames[:2]:
        arr = frame.copy()
        arr.flags.writeable = False
        readonly.append(arr)
    out = run_quietly(method_class(name)(), readonly, regions[:2])
    assert len(out) == 2


@pytest.mark.parametrize("name", NAMES)
def test_empty_hole_lists_return_the_input_unchanged(name, damaged_sequence):
    frames, _ = damaged_sequence
    out = run_quietly(method_class(name)(), frames, [[] for _ in frames])
    assert len(out) == len(frames)
    for a, b in zip(out, frames):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", NAMES)
def test_blind_protocol_works_or_is_refused(name, damaged_sequence):
    """regions=None: a method that detects holes itself returns finite frames of the right count
    (whether it finds the holes is each method's own test); one that cannot refuses clearly."""
    frames, _ = damaged_sequence
    cls = method_class(name)
    if not (cls.detects_holes and not cls.needs_regions):
        with pytest.raises(ValueError, match="regions"):
            cls().inpaint(frames, None)
        return
    out = run_quietly(cls(), frames, None)
    assert len(out) == len(frames)
    for result in out:
        assert result.ndim == 2 and result.shape[1] == 3 and np.isfinite(result).all()


@pytest.mark.parametrize("name", NAMES)
def test_one_frame_sequence_works_or_says_why(name, damaged_sequence):
    frames, regions = damaged_sequence
    cls = method_class(name)
    try:
        out = run_quietly(cls(), frames[:1], regions[:1])
    except ValueError as err:
        assert "frame" in str(err)
    else:
        assert len(out) == 1 and out[0].shape[1] == 3 and np.isfinite(out[0]).all()


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("defect", ["nan", "empty", "wrong-shape", "region-count"])
def test_bad_input_raises_a_clear_value_error(name, defect, damaged_sequence):
    frames, regions = damaged_sequence
    frames, regions = [f.copy() for f in frames], list(regions)
    if defect == "nan":
        frames[1][5, 2] = np.nan
    elif defect == "empty":
        frames[1] = np.zeros((0, 3))
    elif defect == "wrong-shape":
        frames[1] = frames[1][:, :2]
    else:
        regions = regions[:-1]
    with pytest.raises(ValueError, match="frame|region"):
        run_quietly(method_class(name)(), frames, regions)
