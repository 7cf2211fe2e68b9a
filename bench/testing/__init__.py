"""`dpcbench.testing`: the conformance check of an inpainting method, for your own method as for the
built-ins (after scikit-learn's ``check_estimator``)::

    from dpcbench.testing import check_method
    check_method(MyFill)                 # raises ConformanceError naming the failed check
    check_method(MyFill, {"k": 8})       # with parameters

`check_method` runs the method on a tiny synthetic sequence (`sample_sequence`: 3 frames of a
bumpy sphere of radius 50, ~2 000 points each, spacing ~4 units, two ball holes per frame) and
checks, in this order (`CHECKS`):

- ``class-facts``: a subclass of `InpaintingMethod` with a non-empty ``name``, ``summary`` and
  ``version`` (strings), boolean ``uses_neighbour_frames`` / ``needs_regions`` / ``detects_holes``,
  not both ``needs_regions`` and ``detects_holes``;
- ``signature``: ``inpaint(self, frames, regions=None)``: no way to receive the ground truth;
- ``init-stores-parameters``: every ``__init__`` parameter has a default, and ``__init__`` stores
  each parameter under its own name, unchanged, and nothing else (the work belongs in ``inpaint``);
- ``params-round-trip``: ``cls(**m.get_params())`` has the same parameters and repr; an unknown
  parameter in ``set_params`` is a ValueError;
- ``output``: a list of one array per input frame, float64, shape (N > 0, 3), finite, sharing no
  memory with the input;
- ``inputs-untouched``: the frames and regions passed in are unchanged afterwards;
- ``read-only-input``: read-only frames (memory maps, shared caches) are accepted;
- ``deterministic``: a second instance with the same parameters gives the same output, bit for bit;
- ``no-hole-identity``: empty region lists give back the input frames unchanged;
- ``unit-of-length``: the same sequence in other units (every coordinate and region scaled by 2^-10, a capture in
  metres instead of millimetres, and by 2^10; powers of two, exact in floating point) gives the same output, scaled:
  per frame the same point count within 1 % and at most 1 % of the points farther than 1e-6 spacings from the
  unscaled output's. The 1 % leaves room for decision noise (a threshold decision flipped by the last bits of a
  routine that is not exactly scaled; temporal-fusion 50 moves at most 0.02 % of a D-FAUST frame, `experiments/
  scale_check.py`), not for a rule in absolute units (temporal-fusion 49's quadric ridge moved 1.7-3.3 % of this
  sequence's points). Check a method whose parameters hold lengths in coordinates with those unset or relative;
- ``blind``: ``regions=None`` gives finite frames when the method ``detects_holes``, else a
  ValueError that mentions "regions";
- ``one-frame``: a one-frame sequence works, or is refused with a ValueError that mentions "frame";
- ``bad-input``: a NaN coordinate, an empty frame, an (N, 2) frame and a wrong number of region
  lists are each refused with a ValueError that mentions "frame" or "region".

It lives in ``bench/testing/`` and is installed as ``dpcbench.testing`` (pyproject's package-dir):
a public module with its own short name, while the repository's top-level layout stays as it is.
"""

from __future__ import annotations

import inspect
import time
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.base import InpaintingMethod

__all__ = ["CHECKS", "ConformanceError", "check_method", "sample_sequence"]

CHECKS: tuple[str, ...] = (
    "class-facts", "signature", "init-stores-parameters", "params-round-trip", "output", "inputs-untouched",
    "read-only-input", "deterministic", "no-hole-identity", "unit-of-length", "blind", "one-frame", "bad-input",
)
#: `unit-of-length`'s scales (exact in floating point) and the share of a frame's points (and of its count) that may
#: differ: decision noise, not a rule in absolute units (module docstring)
UNIT_SCALES = (2.0 ** -10, 2.0 ** 10)
UNIT_MOVED_SHARE = 0.01


class ConformanceError(AssertionError):
    """A method failed one conformance check: ``check`` (one of `CHECKS`) and what was wrong."""

    def __init__(self, method: str, check: str, message: str):
        super().__init__(f"{method}: check {check!r} failed: {message}")
        self.method = method
        self.check = check
        self.detail = message


def bumpy_sphere(n_points: int, frame: int) -> np.ndarray:
    """Fibonacci-sampled sphere of radius 50 with a smooth bump field that moves with ``frame``:
    r(u) = 50 (1 + 0.08 sin(3 u_x + 0.2 f) cos(2 u_y) + 0.05 u_z^2), u the unit direction."""
    i = np.arange(n_points) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n_points)
    azimuth = np.pi * (1.0 + 5.0 ** 0.5) * i
    u = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    radius = 50.0 * (1.0 + 0.08 * np.sin(3 * u[:, 0] + 0.2 * frame) * np.cos(2 * u[:, 1]) + 0.05 * u[:, 2] ** 2)
    return u * radius[:, None] + np.array([1.5, -0.5, 0.8]) * frame


def sample_sequence(n_frames: int = 3) -> tuple[list[np.ndarray], list[list[HoleRegion]]]:
    """(damaged frames, hole regions per frame): `bumpy_sphere` frames of 2000 + 40 f points with two
    ball holes each (radius 16 at the top, fixed over time; radius 14 at a direction that wanders),
    together removing 2-15% of a frame. Deterministic (no randomness)."""
    frames, regions = [], []
    for f in range(n_frames):
        intact = bumpy_sphere(2000 + 40 * f, f)
        frame_regions = [HoleRegion.ball(intact[np.argmax(intact[:, 2])], 16.0),
                         HoleRegion.ball(intact[np.argmax(intact @ np.array([1.0, 0.3 * f, 0.2]))], 14.0)]
        removed = np.zeros(len(intact), dtype=bool)
        for region in frame_regions:
            removed |= region.contains(intact)
        frames.append(intact[~removed])
        regions.append(frame_regions)
    return frames, regions


def _quiet(fn: Callable[[], Any]) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn()


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a is b or a == b)
    except Exception:  # an array-valued parameter: compare element-wise
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))


class _Context:
    """What the checks of one `check_method` call share: the class, the name it is registered under,
    its parameters, the sample sequence, the state one check leaves for the next, and the helpers
    that fail a check."""

    def __init__(self, cls, name: str | None, label: str, params: dict[str, Any]):
        self.cls, self.name, self.label, self.params = cls, name, label, params
        self.frames, self.regions = sample_sequence()
        self.state: dict[str, Any] = {}

    def fail(self, check: str, message: str):
        raise ConformanceError(self.label, check, message)

    def run(self, check: str, fn: Callable[[], Any]) -> Any:
        """``fn()`` quietly; an exception it raises fails ``check`` with the exception named."""
        try:
            return _quiet(fn)
        except ConformanceError:
            raise
        except Exception as err:
            self.fail(check, f"raised {type(err).__name__}: {err}")

    def check_frames(self, check: str, out: Any, n: int, inputs: list[np.ndarray]) -> list[np.ndarray]:
        """``out`` if it is a list of ``n`` new, finite (N, 3) float64 arrays; else ``check`` fails."""
        fail = self.fail
        if not isinstance(out, list) or len(out) != n:
            fail(check, f"inpaint must return a list of {n} frames, got {type(out).__name__}"
                        f"{f' of {len(out)}' if hasattr(out, '__len__') else ''}")
        for f, arr in enumerate(out):
            if not isinstance(arr, np.ndarray) or arr.dtype != np.float64:
                fail(check, f"frame {f} of the output is {type(arr).__name__} of dtype {getattr(arr, 'dtype', None)}; "
                            "return float64 numpy arrays")
            if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
                fail(check, f"frame {f} of the output has shape {arr.shape}; expected (N, 3) with N > 0")
            if not np.isfinite(arr).all():
                fail(check, f"frame {f} of the output has NaN or infinite coordinates")
            if any(np.shares_memory(arr, frame) for frame in inputs):
                fail(check, f"frame {f} of the output shares memory with an input frame; return new arrays")
        return out


def _interface_checks(ctx: _Context) -> dict[str, Callable[[], None]]:
    """The checks of the class and its parameters: class facts, inpaint's signature, __init__ storing
    its parameters, get_params/set_params."""
    cls, name, params, state, fail, run = ctx.cls, ctx.name, ctx.params, ctx.state, ctx.fail, ctx.run

    def class_facts():
        if not (isinstance(cls, type) and issubclass(cls, InpaintingMethod)):
            fail("class-facts", f"{cls!r} is not a subclass of dpcbench.methods.base.InpaintingMethod")
        for fact in ("name", "summary", "version"):
            value = getattr(cls, fact, None)
            if not (isinstance(value, str) and value.strip()):
                fail("class-facts", f"class attribute `{fact}` must be a non-empty string, got {value!r}")
        if name is not None and cls.name != name:
            fail("class-facts", f"class attribute `name` is {cls.name!r} but it is registered as {name!r}")
        for fact in ("uses_neighbour_frames", "needs_regions", "detects_holes"):
            if not isinstance(getattr(cls, fact), bool):
                fail("class-facts", f"class attribute `{fact}` must be True or False, got {getattr(cls, fact)!r}")
        if cls.needs_regions and cls.detects_holes:
            fail("class-facts", "needs_regions and detects_holes are both True; a method that needs the regions "
                                "cannot detect holes")

    def signature():
        parameters = inspect.signature(cls.inpaint).parameters
        if list(parameters) != ["self", "frames", "regions"] or parameters["regions"].default is not None:
            fail("signature", f"inpaint{inspect.signature(cls.inpaint)}: expected inpaint(self, frames, regions=None) "
                              "(a method never receives the ground truth)")

    def init_stores_parameters():
        signature_params = {n: p for n, p in inspect.signature(cls.__init__).parameters.items() if n != "self"}
        for n, p in signature_params.items():
            if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
                fail("init-stores-parameters", f"__init__ takes *{n}; list every parameter by name")
            if p.default is p.empty and n not in params:
                fail("init-stores-parameters", f"__init__ parameter {n!r} has no default; give every parameter one")
        given = {n: p.default for n, p in signature_params.items()}
        given.update(params)
        instance = run("init-stores-parameters", lambda: cls(**params))
        stored = vars(instance)
        extra = sorted(set(stored) - set(signature_params))
        if extra:
            fail("init-stores-parameters", f"__init__ set attribute(s) {', '.join(extra)} that are not parameters; "
                                           "__init__ must only store its parameters (do the work in inpaint)")
        missing = sorted(set(signature_params) - set(stored))
        if missing:
            fail("init-stores-parameters", f"__init__ did not store parameter(s) {', '.join(missing)} under their "
                                           "own names")
        changed = [n for n in signature_params if not _same(stored[n], given[n])]
        if changed:
            n = changed[0]
            fail("init-stores-parameters", f"__init__ stored {n}={stored[n]!r} for the value {given[n]!r}; store "
                                           "parameters unchanged (convert or check them in inpaint / _validate)")
        state["instance"] = instance

    def params_round_trip():
        instance = state["instance"]
        got = run("params-round-trip", instance.get_params)
        clone = run("params-round-trip", lambda: cls(**got))
        if clone.get_params() != got or repr(clone) != repr(instance):
            fail("params-round-trip", f"cls(**get_params()) gives {clone.get_params()!r}, not {got!r}")
        try:
            instance.set_params(no_such_parameter=1)
        except ValueError:
            pass
        else:
            fail("params-round-trip", "set_params(no_such_parameter=1) did not raise ValueError")
        state["params"] = got

    return {"class-facts": class_facts, "signature": signature, "init-stores-parameters": init_stores_parameters, "params-round-trip": params_round_trip}


def _output_checks(ctx: _Context) -> dict[str, Callable[[], None]]:
    """The checks of inpaint's output on the sample sequence: new float64 frames, inputs untouched,
    read-only input, the same output twice, no change without holes."""
    cls, frames, regions, state = ctx.cls, ctx.frames, ctx.regions, ctx.state
    fail, run, check_frames = ctx.fail, ctx.run, ctx.check_frames

    def output():
        given = [frame.copy() for frame in frames]
        state["given"] = given
        state["region_dicts"] = [[r.to_dict() for r in frame_regions] for frame_regions in regions]
        out = run("output", lambda: cls(**state["params"]).inpaint(given, regions))
        state["out"] = check_frames("output", out, len(frames), given)

    def inputs_untouched():
        for f, (arr, frame) in enumerate(zip(state["given"], frames)):
            if arr.shape != frame.shape or not np.array_equal(arr, frame):
                fail("inputs-untouched", f"inpaint changed input frame {f} in place; work on a copy "
                                         "(np.array(frame, copy=True)) and never write to the frames given")
        if [[r.to_dict() for r in frame_regions] for frame_regions in regions] != state["region_dicts"]:
            fail("inputs-untouched", "inpaint changed the hole regions given; never write to them")

    def read_only_input():
        readonly = []
        for frame in frames:
            arr = frame.copy()
            arr.flags.writeable = False
            readonly.append(arr)
        out = run("read-only-input", lambda: cls(**state["params"]).inpaint(readonly, regions))
        state["again"] = check_frames("read-only-input", out, len(frames), readonly)

    def deterministic():
        for f, (a, b) in enumerate(zip(state["out"], state["again"])):
            if a.shape != b.shape or not np.array_equal(a, b):
                fail("deterministic", f"two runs with the same parameters differ in frame {f} ({a.shape} vs {b.shape}); "
                                      "take randomness only from a seed parameter")

    def no_hole_identity():
        given = [frame.copy() for frame in frames]
        out = run("no-hole-identity", lambda: cls(**state["params"]).inpaint(given, [[] for _ in frames]))
        out = check_frames("no-hole-identity", out, len(frames), given)
        for f, (a, b) in enumerate(zip(out, frames)):
            if not np.array_equal(a, b):
                fail("no-hole-identity", f"with no hole region, frame {f} came back changed ({len(b)} -> {len(a)} "
                                         "points); return the input as it is")

    def unit_of_length():
        from scipy.spatial import cKDTree

        from dpcbench.metrics.neighbours import point_spacing

        spacings = [point_spacing(frame) for frame in frames]
        for scale in UNIT_SCALES:
            scaled_frames = [f * scale for f in frames]
            scaled_regions = [[r.scaled(scale) for r in frame_regions] for frame_regions in regions]
            out = run("unit-of-length", lambda s=scaled_frames, r=scaled_regions: cls(**state["params"]).inpaint(s, r))
            out = check_frames("unit-of-length", out, len(frames), frames)
            for f, (want, got) in enumerate(zip(state["out"], out)):
                got = got / scale
                moved = cKDTree(want).query(got)[0] > 1e-6 * spacings[f]
                if abs(len(got) - len(want)) > UNIT_MOVED_SHARE * len(want) or moved.mean() > UNIT_MOVED_SHARE:
                    fail("unit-of-length", f"with every coordinate scaled by {scale:g} (the same capture in other "
                                           f"units), frame {f} came back with {len(got)} points instead of "
                                           f"{len(want)}, {moved.mean():.1%} of them moved; state every length "
                                           "in the data's own point spacing, not in absolute units")

    return {"output": output, "inputs-untouched": inputs_untouched, "read-only-input": read_only_input,
            "deterministic": deterministic, "no-hole-identity": no_hole_identity, "unit-of-length": unit_of_length}


def _robustness_checks(ctx: _Context) -> dict[str, Callable[[], None]]:
    """The checks of what inpaint refuses or survives: no regions (blind), one frame, defective input."""
    cls, frames, regions, state = ctx.cls, ctx.frames, ctx.regions, ctx.state
    fail, run, check_frames = ctx.fail, ctx.run, ctx.check_frames

    def blind():
        if cls.detects_holes and not cls.needs_regions:
            out = run("blind", lambda: cls(**state["params"]).inpaint([f.copy() for f in frames], None))
            check_frames("blind", out, len(frames), frames)
            return
        try:
            _quiet(lambda: cls(**state["params"]).inpaint([f.copy() for f in frames], None))
        except ValueError as err:
            if "region" not in str(err):
                fail("blind", f"regions=None was refused, but the message does not mention the regions: {err}")
        except Exception as err:
            fail("blind", f"regions=None raised {type(err).__name__}: {err}; raise a ValueError that says the method "
                          "needs the hole regions (or set detects_holes = True)")
        else:
            fail("blind", "regions=None was accepted although detects_holes is False; refuse it with a ValueError "
                          "(self._check_inputs does) or set detects_holes = True")

    def one_frame():
        try:
            out = _quiet(lambda: cls(**state["params"]).inpaint([frames[0].copy()], [regions[0]]))
        except ValueError as err:
            if "frame" not in str(err):
                fail("one-frame", f"a one-frame sequence was refused with a message that does not mention frames: {err}")
            return
        except Exception as err:
            fail("one-frame", f"a one-frame sequence raised {type(err).__name__}: {err}; work, or raise a ValueError "
                              "that says how many frames are needed")
        check_frames("one-frame", out, 1, frames[:1])

    def bad_input():
        for defect in ("nan", "empty", "wrong-shape", "region-count"):
            bad, bad_regions = [f.copy() for f in frames], list(regions)
            if defect == "nan":
                bad[1][5, 2] = np.nan
            elif defect == "empty":
                bad[1] = np.zeros((0, 3))
            elif defect == "wrong-shape":
                bad[1] = bad[1][:, :2]
            else:
                bad_regions = bad_regions[:-1]
            try:
                _quiet(lambda b=bad, r=bad_regions: cls(**state["params"]).inpaint(b, r))
            except ValueError as err:
                if "frame" not in str(err) and "region" not in str(err):
                    fail("bad-input", f"input with a {defect} defect was refused, but the message names neither the "
                                      f"frame nor the regions: {err}")
            except Exception as err:
                fail("bad-input", f"input with a {defect} defect raised {type(err).__name__}: {err}; check the input "
                                  "first (self._check_inputs) and raise a ValueError")
            else:
                fail("bad-input", f"input with a {defect} defect was accepted; check it (self._check_inputs)")

    return {"blind": blind, "one-frame": one_frame, "bad-input": bad_input}


def check_method(method: type[InpaintingMethod] | str, params: dict[str, Any] | None = None, *,
                 name: str | None = None, checks: tuple[str, ...] = CHECKS,
                 progress: Callable[[str, float], None] | None = None) -> dict[str, float]:
    """Run the conformance checks (`CHECKS`, see the module docstring) on a method class (or a name
    the registry knows: a built-in, a plug-in, or an import path ``"pkg.mod:Class"``), constructed
    with ``params`` (default: its defaults). ``name``: the name it is registered under, which the
    class's ``name`` must equal. ``checks``: the subset to run (the others are skipped).
    ``progress(check, seconds)`` is called after each check passes.

    Returns {check: seconds} of the checks run; raises `ConformanceError` at the first failure.
    """
    if isinstance(method, str):
        from dpcbench.holes.lazy import is_import_path
        from dpcbench.methods.registry import METHODS, method_class

        if name is None and (method in METHODS.plugins or not is_import_path(method)):
            name = method  # a registered name must be the class's `name`; an import path names none
        method = method_class(method)
    cls = method
    label = str(name or getattr(cls, "name", "") or getattr(cls, "__name__", repr(cls)))
    unknown = [c for c in checks if c not in CHECKS]
    if unknown:
        raise ValueError(f"unknown check(s) {unknown}; known: {', '.join(CHECKS)}")
    params = dict(params or {})
    ctx = _Context(cls, name, label, params)
    timings: dict[str, float] = {}
    steps = {**_interface_checks(ctx), **_output_checks(ctx), **_robustness_checks(ctx)}
    # a check that needs an earlier one's state runs it first (its time is counted there)
    needs = {"params-round-trip": ("init-stores-parameters",), "output": ("params-round-trip",),
             "inputs-untouched": ("output",), "read-only-input": ("params-round-trip",),
             "deterministic": ("output", "read-only-input")}
    for other in ("no-hole-identity", "blind", "one-frame", "bad-input"):
        needs[other] = ("params-round-trip",)
    needs["unit-of-length"] = ("output",)
    done: set[str] = set()

    def do(check: str):
        if check in done:
            return
        for required in needs.get(check, ()):
            do(required)
        if check in ("init-stores-parameters",) and "class-facts" not in done:
            do("class-facts")
        start = time.perf_counter()
        steps[check]()
        done.add(check)
        if check in checks:
            timings[check] = time.perf_counter() - start
            if progress is not None:
                progress(check, timings[check])

    for check in CHECKS:
        if check in checks:
            do(check)
    return timings
