"""BLAS held to one thread: a context manager (`OneBlasThread`) and the tall product of a few columns on it
(`rows_times`). numpy and scipy each bundle an OpenBLAS whose threads, on the small or thin products of point
geometry, cost more than the arithmetic; the results are the same bits on one thread or many (OpenBLAS splits a
product by rows and columns, never a row's sums)."""

from __future__ import annotations

import numpy as np


class OneBlasThread:
    """Context manager: BLAS limited to one thread inside, restored on exit.

    Every OpenBLAS library loaded in the process when first entered (numpy's and scipy's bundle one each) gets its
    own ``openblas_set_num_threads`` through ctypes: a few microseconds, so a per-call limit costs nothing. Where
    none can be found that way (another BLAS, another OS), threadpoolctl does it when installed (not a dependency:
    it rescans the libraries on every call), and else this does nothing. The limit is process-wide while inside:
    BLAS calls of other threads run on one thread meanwhile.

    Why: the batched products of hole detection ((m, 3) @ (3, n) projections, (10, m) @ (m, n) moments, eigh of a
    few 3 x 3 stacks) are many small calls, for which OpenBLAS's thread start-up costs more than the arithmetic
    (a (16384, 3) @ (3, 57) product: 8 ms with 2 threads, 0.26 ms with one); and a tall product of three columns
    (`rows_times`) is memory-bound, which a second thread does not speed up.
    """

    _apis: list | None = None  # per OpenBLAS library found: (get_num_threads, set_num_threads)

    @classmethod
    def _lookup(cls) -> list:
        if cls._apis is None:
            cls._apis = []
            try:
                import ctypes

                with open("/proc/self/maps") as maps:
                    paths = sorted({line.split()[-1] for line in maps if "openblas" in line.lower()})
                for path in paths:
                    lib = ctypes.CDLL(path)
                    found = [(getattr(lib, f"{p}_get_num_threads{s}", None), getattr(lib, f"{p}_set_num_threads{s}", None))
                             for p in ("scipy_openblas", "openblas") for s in ("64_", "")]
                    for get, put in found:
                        if get is not None and put is not None:
                            get.restype = ctypes.c_int
                            cls._apis.append((get, put))
                            break
            except OSError:  # no /proc (not Linux) or a library that cannot be opened: leave BLAS as it is
                pass
        return cls._apis

    def __enter__(self):
        self._limits = None
        self._saved = [(put, get()) for get, put in self._lookup()]
        for put, _ in self._saved:
            put(1)
        if not self._saved:
            try:
                from threadpoolctl import threadpool_limits  # type: ignore[import-not-found]
            except ImportError:
                pass
            else:
                self._limits = threadpool_limits(limits=1, user_api="blas")
        return self

    def __exit__(self, *exc):
        if self._limits is not None:
            self._limits.restore_original_limits()
        for put, threads in self._saved:
            put(threads)
        return False


def rows_times(rows: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``rows`` (N, K) @ ``matrix`` (K, M) for a small K and M (a box's rotation, a frame's axes), on one BLAS
    thread (`OneBlasThread`): OpenBLAS splits such a product by rows over all its threads, which then wait for one
    another longer than the product takes and spin after it (843k rows times a 3 x 3 rotation on a 2-core machine:
    10 ms of CPU on one thread, 25-100 ms on two: `tests/benchmarks/test_bench_holes.py -k box_contains`)."""
    with OneBlasThread():
        return rows @ matrix
