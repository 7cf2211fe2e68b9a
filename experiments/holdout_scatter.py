"""The closed surface's hold-out test (step 6c, `methods._spatial_fill.poisson._holds_out`) with the ring's scatter e
measured three ways, on every decision a run makes: the decision with each e, and which differ from the method's.

    .venv/bin/python experiments/holdout_scatter.py                      # the golden inputs, defaults
    .venv/bin/python experiments/holdout_scatter.py --case longdress-occlusion --case coherent-800k --cut 4 --cut 3

The test passes a body when sqrt(m^2 - e^2) <= 1 spacing: m the inner ring's RMS distance to the surface built
without it (finest octree cell 2 g), e the ring's own scatter. The three e:

- ``fine``: the ring's RMS distance to the screened Poisson surface of the whole body at the fill's finest cell g
  (temporal-fusion up to version 45: a fine reconstruction per body, made before the test);
- ``coarse``: the same at the hold-out's cell 2 g (the two surfaces of the test at one resolution);
- ``local``: the RMS of `local_quadric`'s residual at the ring's points, each fitted to its 20 nearest body points
  (the capture's scatter about a local quadric; no reconstruction; the method's since version 46).

Prints one line per decision (body size, m, each e in spacings; a star where that e decides otherwise than the
method; the held-out support's size and its reconstruction's CPU) and in all how many decisions each other e changes.
With ``--cut K`` (repeatable) also the hold-out with its support cut to R grown by K rings (the ring is half the
crop's shell): its miss, CPU and decision (with the local e). With ``--coarse STEPS`` (repeatable) also the held-out
surface on an octree whose finest cell is STEPS g (the method's is 2 g): its miss and CPU.

Cases: experiments/fusion_golden.py's inputs (defaults), or with ``--case`` the paper-scale benchmark inputs of
tests/benchmarks/fusion_cases.py.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "benchmarks"))

from dpcbench.methods._front_fill import local_quadric  # noqa: E402
from dpcbench.methods._spatial_fill import poisson  # noqa: E402
from dpcbench.methods.registry import get_method  # noqa: E402


def _rms_to(samples: np.ndarray, region, ring: float, points: np.ndarray) -> float:
    samples = samples[region.contains(samples, margin=ring)]
    return float(np.sqrt(np.mean(cKDTree(samples).query(points)[0] ** 2))) if len(samples) else 0.0


def _miss(outer, ring_points, region, ring, grid, cell_steps=poisson.POISSON_HOLDOUT_CELL_STEPS) -> tuple[float, float]:
    """(the ring's RMS distance m to the surface of ``outer`` at the hold-out's cell (or ``cell_steps`` g), that
    reconstruction's CPU s)."""
    start = time.process_time()
    held = poisson._poisson_samples(outer, grid, (region, ring), cell_steps)
    held = held[region.contains(held, margin=ring)]
    cpu = time.process_time() - start
    return (float(np.sqrt(np.mean(cKDTree(held).query(ring_points)[0] ** 2))) if len(held) else np.inf), cpu


def _trace(log: list, cuts: list[float], coarse: list[int]) -> None:
    """Wrap `poisson._holds_out` once; each decision appends a record to ``log`` (the caller empties it per case)."""
    holds_out = poisson._holds_out

    def traced(support, region, ring, spacing, grid, max_holdout_spacings):
        passed = holds_out(support, region, ring, spacing, grid, max_holdout_spacings)
        inner = region.contains(support, margin=ring)
        if inner.sum() < 6 or (~inner).sum() < 32:
            return passed
        outer, ring_points = support[~inner], support[inner]
        m, cpu = _miss(outer, ring_points, region, ring, grid)
        e = {
            "fine": _rms_to(poisson._poisson_samples(support, grid, near=(region, ring)), region, ring, ring_points),
            "coarse": _rms_to(poisson._poisson_samples(support, grid, near=(region, ring),
                                                       cell_steps=poisson.POISSON_HOLDOUT_CELL_STEPS),
                              region, ring, ring_points),
            "local": float(np.sqrt(np.mean(local_quadric(ring_points, support, 20)[2] ** 2))),
        }
        bound = max_holdout_spacings * spacing
        verdict = {k: bool(m * m - v * v <= bound * bound) for k, v in e.items()}
        cut = []
        for k in cuts:  # the held-out support cut to R grown by k rings: its miss, CPU and decision (local e)
            kept = outer[region.contains(outer, margin=k * ring)]
            mk, cpu_k = (_miss(kept, ring_points, region, ring, grid) if len(kept) >= 32
                         else (np.inf, 0.0))
            cut.append((k, len(kept), mk / spacing, cpu_k, bool(mk * mk - e["local"] ** 2 <= bound * bound)))
        coarser = []
        for steps in coarse:  # the held-out support's surface on a coarser octree: its miss, CPU and depths
            mc, cpu_c = _miss(outer, ring_points, region, ring, grid, steps)
            depth = poisson.octree_depth(outer, grid, poisson.POISSON_HOLDOUT_CELL_STEPS)
            coarser.append((steps, mc / spacing, cpu_c, depth, poisson.octree_depth(outer, grid, steps)))
        log.append((len(support), m / spacing, {k: v / spacing for k, v in e.items()}, verdict, passed, len(outer),
                    cpu, cut, coarser))
        return passed

    poisson._holds_out = traced


def _cases(names: list[str]) -> dict:
    if names:
        from fusion_cases import CASES

        return {name: CASES[name]()[1:] for name in names}
    from fusion_golden import inputs

    return {name: (frames, regions) for name, (frames, regions, _) in inputs().items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", action="append", default=[], help="a fusion_cases.py case (repeatable)")
    parser.add_argument("--cut", action="append", default=[], type=float,
                        help="also the hold-out with its support cut to R grown by this many rings (repeatable)")
    parser.add_argument("--coarse", action="append", default=[], type=int,
                        help="also the held-out surface with its finest cell this many g (repeatable): its miss, CPU")
    args = parser.parse_args(argv)
    totals = {"fine": 0, "coarse": 0, "decisions": 0}
    cut_changed = dict.fromkeys(args.cut, 0)
    log: list = []
    _trace(log, args.cut, args.coarse)
    for name, (frames, regions) in _cases(args.case).items():
        log.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            get_method("temporal-fusion").inpaint([f.copy() for f in frames], regions)
        print(f"== {name}: {len(log)} decisions")
        for size, m, e, verdict, passed, outer, cpu, cut, coarser in log:
            marks = " ".join(f"{k} {v:.2f}{'' if verdict[k] == passed else '*'}" for k, v in e.items())
            print(f"   body {size:8,d}  m {m:6.2f}  e: {marks}  {'passed' if passed else 'refused'}"
                  f"  (held-out support {outer:,d}, {cpu:.2f} s CPU)")
            for k, kept, mk, cpu_k, ok in cut:
                print(f"      cut to {k:g} rings: support {kept:,d}, m {mk:6.2f}, {cpu_k:.2f} s CPU, "
                      f"{'passed' if ok else 'refused'}{'' if ok == passed else '*'}")
                cut_changed[k] += ok != passed
            for steps, mc, cpu_c, depth, depth_c in coarser:
                print(f"      finest cell {steps} g: m {mc:6.2f}, {cpu_c:.2f} s CPU, octree depth {depth_c} "
                      f"(the hold-out's {depth})")
        for key in ("fine", "coarse"):
            totals[key] += sum(v[key] != p for _, _, _, v, p, *_ in log)
        totals["decisions"] += len(log)
    print(f"decisions {totals['decisions']}; changed with e fine (version 45) {totals['fine']}, "
          f"with e coarse {totals['coarse']}"
          + "".join(f", cut to {k:g} rings {n}" for k, n in cut_changed.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
