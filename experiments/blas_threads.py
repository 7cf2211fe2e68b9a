"""What numpy's and scipy's BLAS threads cost temporal-fusion on a benchmark case: the case inpainted in a fresh
process with the BLAS thread pools as they come (one thread a core) and with ``OPENBLAS_NUM_THREADS=1``, and with
``--against REV`` by the package of git revision REV too (`_revision.package_of`), in alternating rounds (this
machine's load drifts between minutes, so only runs within one round compare).

    .venv/bin/python experiments/blas_threads.py longdress-occlusion coherent-800k [--rounds 2] [--against REV]

Cases: tests/benchmarks/fusion_cases.py. Prints per run the CPU seconds of the inpaint call (time.process_time:
every thread of the process, a thread spinning while it waits for work included), the main thread's share of it
(time.thread_time), the other threads' (BLAS's and open3d's workers), its wall seconds and the first 16 hex digits
of the output's sha256 (the same digest in every setting: the thread count changes no output bit).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = {"default threads": {}, "OPENBLAS_NUM_THREADS=1": {"OPENBLAS_NUM_THREADS": "1"}}
REVISION = "default threads, revision "


def _child(case: str) -> dict:
    """One inpaint of ``case`` by temporal-fusion (registry defaults) in this process: CPU s, wall s, digest."""
    import numpy as np

    sys.path.insert(0, str(ROOT / "tests" / "benchmarks"))
    from fusion_cases import CASES

    from dpcbench.methods.registry import get_method

    _, frames, regions = CASES[case]()
    method = get_method("temporal-fusion")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cpu, main, wall = time.process_time(), time.thread_time(), time.perf_counter()
        out = method.inpaint([f.copy() for f in frames], regions)
        cpu, main, wall = time.process_time() - cpu, time.thread_time() - main, time.perf_counter() - wall
    digest = hashlib.sha256(b"".join(np.ascontiguousarray(o, dtype=np.float64).tobytes() for o in out)).hexdigest()
    return {"cpu": cpu, "main": main, "wall": wall, "sha256": digest[:16]}


def _default_threads(env) -> dict[str, str]:
    """``env`` without the variables that set OpenBLAS's thread count (OpenBLAS also reads OMP_NUM_THREADS)."""
    return {k: v for k, v in env.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", help="fusion_cases.py case names")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--against", metavar="REV", help="also run the package of git revision REV (default threads)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(_child(args.cases[0])))
        return 0
    arms = {setting: {**_default_threads(os.environ), **extra} for setting, extra in SETTINGS.items()}
    with contextlib.ExitStack() as stack:
        if args.against:
            from _revision import package_of

            arms[REVISION + args.against] = _default_threads(stack.enter_context(package_of(args.against)))
        for case in args.cases:
            for round_ in range(args.rounds):
                # the order alternates between rounds, so a drift of the machine's speed favours no arm
                for arm in (list(arms) if round_ % 2 == 0 else list(reversed(arms))):
                    done = subprocess.run([sys.executable, __file__, "--child", case], env=arms[arm],
                                          capture_output=True, text=True, check=True)
                    r = json.loads(done.stdout.strip().splitlines()[-1])
                    print(f"{case}, round {round_ + 1}, {arm}: CPU {r['cpu']:.2f} s (main thread {r['main']:.2f}, "
                          f"others {r['cpu'] - r['main']:.2f}), wall {r['wall']:.2f} s, sha256 {r['sha256']}",
                          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
