"""The instruction set a run computes with, and the pin that makes results the same across machines.

The last bits of ``np.exp`` (numpy's AVX-512 kernels or libm) and of OpenBLAS (per-CPU kernels)
differ from CPU to CPU, and the greedy fills of temporal-graph / fu-nonlocal turn a last-bit change
into a different fill (0.1-0.5 dB). `pin_environment` gives the environment variables that hold
numpy's SIMD dispatch to X86_V3 (AVX2, FMA), OpenBLAS to its Haswell kernels and BLAS/OpenMP to one
thread, as ``.ci/pinned-isa`` does: they act on a process whose numpy has not loaded yet, so the
runner's workers (fresh processes that inherit the driver's environment) compute pinned. An
experiment with ``pin_isa = true`` (the regression preset) is run that way by `dpcbench run`.
`describe` names what a process computes with (recorded in every run's ``env["isa"]``).
"""

from __future__ import annotations

import os
import platform
from contextlib import contextmanager

#: the variables `pin_environment` sets
PIN_VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")


def _dispatch():
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # pragma: no cover - numpy < 2 or a build without dispatch
        return None, None
    return list(__cpu_dispatch__), dict(__cpu_features__)


def pin_environment() -> dict[str, str]:
    """The variables of ``.ci/pinned-isa``: on an x86-64 machine with AVX2 (numpy's X86_V3), every
    dispatch target but X86_V3 disabled (``NPY_DISABLE_CPU_FEATURES``) and ``OPENBLAS_CORETYPE=Haswell``;
    elsewhere (ARM, an old x86) none of those; one BLAS/OpenMP thread everywhere."""
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    dispatch, features = _dispatch()
    if (platform.machine() in ("x86_64", "AMD64") and dispatch is not None and "X86_V3" in dispatch
            and features.get("X86_V3")):
        disabled = " ".join(f for f in dispatch if f != "X86_V3")
        if disabled:
            env["NPY_DISABLE_CPU_FEATURES"] = disabled
        env["OPENBLAS_CORETYPE"] = "Haswell"
    return env


def pin() -> dict[str, str]:
    """Put `pin_environment` into ``os.environ`` (for the worker processes started afterwards);
    returns what was set."""
    env = pin_environment()
    os.environ.update(env)
    return env


@contextmanager
def pinned():
    """`pin` for the block (yields what it set), then ``os.environ`` as it was: the pin is for the workers started
    inside, not for what the calling process runs next (a script or test that calls `dpcbench run`'s ``main``)."""
    before = {key: os.environ.get(key) for key in PIN_VARIABLES}
    try:
        yield pin()
    finally:
        for key, value in before.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def describe() -> str:
    """What this process computes with: the machine, numpy's enabled SIMD dispatch targets, and the
    pin variables that are set ("x86_64; numpy dispatch AVX512F AVX512_SKX ...; pinned: ..." or
    "unpinned")."""
    dispatch, features = _dispatch()
    disabled = set(os.environ.get("NPY_DISABLE_CPU_FEATURES", "").replace(",", " ").split())
    enabled = [f for f in dispatch or [] if features.get(f) and f not in disabled]
    pinned = {k: os.environ[k] for k in ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE") if os.environ.get(k)}
    highest = enabled[-1] if enabled else "baseline only"
    return (f"{platform.machine()}; numpy dispatch up to {highest}"
            + ("; pinned (" + ", ".join(f"{k}={v}" for k, v in pinned.items()) + ")" if pinned else "; unpinned"))
