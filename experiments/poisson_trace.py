"""Where step 6c's (`ClosedSurface`) time goes on one of temporal-fusion's paper-scale benchmark inputs: every
screened Poisson reconstruction (`poisson.poisson_mesh`: the solver, without the normals and the sampling) with its
support size, octree depth, mesh size and CPU time, every hold-out test with its decision and CPU, and the totals.

    .venv/bin/python experiments/poisson_trace.py longdress-occlusion [--param poisson_in_boxes=false]
    .venv/bin/python experiments/poisson_trace.py coherent-800k

Cases: `tests/benchmarks/fusion_cases.py` (coherent-800k, longdress-region, longdress-occlusion). Prints one line
per reconstruction ("fill" for a body's surface, "holdout" for the surface without its inner ring, at the
hold-out's depth or, for its first look, one level coarser), one per
hold-out decision, then the run's CPU time (process time) and the sha256 of its output (the golden hashes'
digest), so two revisions can be shown to give the same points.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "benchmarks"))
from fusion_cases import CASES, digest  # noqa: E402  (tests/benchmarks is no package)

from dpcbench.methods._spatial_fill import poisson  # noqa: E402
from dpcbench.methods.registry import get_method  # noqa: E402


def _param(text: str) -> tuple[str, object]:
    key, _, value = text.partition("=")
    return key, {"true": True, "false": False}.get(value.lower(), value)


def _trace(log: list) -> None:
    mesh_of, holds_out = poisson.poisson_mesh, poisson._holds_out
    state = {"role": "fill"}

    def traced_mesh(cloud, depth):
        start = time.process_time()
        mesh = mesh_of(cloud, depth)
        points = np.asarray(cloud.points)
        log.append(("surface", state["role"], len(points), float(np.ptp(points, axis=0).max()), depth,
                    len(mesh.triangles), time.process_time() - start))
        return mesh

    def traced_holds_out(support, region, ring, *args, **kwargs):
        state["role"] = "holdout"
        start = time.process_time()
        try:
            passed = holds_out(support, region, ring, *args, **kwargs)
        finally:
            state["role"] = "fill"
        log.append(("decision", region.shape, len(support), passed, time.process_time() - start))
        return passed

    poisson.poisson_mesh, poisson._holds_out = traced_mesh, traced_holds_out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=sorted(CASES))
    parser.add_argument("--param", action="append", default=[], type=_param, help="method parameter key=value")
    args = parser.parse_args(argv)
    _, frames, regions = CASES[args.case]()
    log: list = []
    _trace(log)
    start = time.process_time()
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = get_method("temporal-fusion", **dict(args.param)).inpaint(frames, regions)
    total = time.process_time() - start
    surface_cpu = 0.0
    for entry in log:
        if entry[0] == "surface":
            _, role, points, extent, depth, triangles, cpu = entry
            surface_cpu += cpu
            print(f"surface {role:8s} {points:8,d} points, extent {extent:7.1f}, depth {depth:2d}, "
                  f"{triangles:9,d} triangles, {cpu:6.2f} s CPU")
        else:
            _, shape, points, passed, cpu = entry
            print(f"hold-out {shape} body of {points:,d} points: {'passed' if passed else 'refused'} ({cpu:.2f} s CPU)")
    print(f"{sum(e[0] == 'surface' for e in log)} reconstructions {surface_cpu:.1f} s CPU (the solver alone) "
          f"of {total:.1f} s CPU; added {sum(len(o) - len(f) for o, f in zip(out, frames)):,d} points; "
          f"output sha256 {digest(out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
