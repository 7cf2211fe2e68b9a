"""What step 6c's screened Poisson reconstructions would cost with a coarser octree or a smaller support, on the
supports a real run hands it (one of temporal-fusion's paper-scale benchmark inputs).

    .venv/bin/python experiments/poisson_options.py longdress-occlusion
    .venv/bin/python experiments/poisson_options.py coherent-800k

Runs temporal-fusion on the case (`tests/benchmarks/fusion_cases.py`), keeps every support step 6c gets, then
reconstructs each of its bodies (`_bodies`, those `poisson_surface_fill` reconstructs) once per option and prints
the CPU time (process time) of open3d's reconstruction alone, per body and in all. Options:

  cell 1, crop    the octree of versions 12-42 (finest cell one grid step g) on the body as step 6c gets it
  cell 2, crop    finest cell 2 g (`POISSON_CELL_STEPS` = 2, version 43)
  cell 1, rim     the body's points within the shell of R only (R grown by twice the hold-out ring), finest cell g
  cell 2, rim     both

Only the times are measured here: what the last two would do to the fill is not (see docs/temporal-fusion.md).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "benchmarks"))
from fusion_cases import CASES  # noqa: E402  (tests/benchmarks is no package)

from dpcbench.methods._spatial_fill.poisson import _bodies, poisson_input, poisson_mesh  # noqa: E402
from dpcbench.methods.registry import get_method  # noqa: E402
from dpcbench.methods.temporal_fusion import spatial  # noqa: E402

OPTIONS = {"cell 1, crop": (1, False), "cell 2, crop": (2, False), "cell 1, rim": (1, True), "cell 2, rim": (2, True)}


def reconstruction_cpu(points: np.ndarray, grid: float, cell_steps: int) -> tuple[int, float]:
    """(octree depth, CPU seconds of open3d's screened Poisson) of ``points`` (K, 3) with normals as step 6c's."""
    cloud, depth = poisson_input(points, grid, cell_steps)
    start = time.process_time()
    poisson_mesh(cloud, depth)
    return depth, time.process_time() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=sorted(CASES))
    args = parser.parse_args(argv)
    _, frames, regions = CASES[args.case]()
    supports: list = []
    fill = spatial.poisson_surface_fill

    def kept(support, region, covered, spacing, **kwargs):
        supports.append((np.array(support), region, spacing, kwargs))
        return fill(support, region, covered, spacing, **kwargs)

    spatial.poisson_surface_fill = kept
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        get_method("temporal-fusion").inpaint(frames, regions)
    totals = dict.fromkeys(OPTIONS, 0.0)
    for support, region, spacing, kwargs in supports:
        grid = spacing if kwargs["voxelized"] else (kwargs.get("step") or spacing)
        for body in _bodies(support, 3 * spacing):
            if len(body) < 32 or not region.contains(body, margin=3 * spacing).any():
                continue
            rim = body[region.contains(body, margin=2 * kwargs["ring"])]
            cells = []
            for name, (cell_steps, near) in OPTIONS.items():
                points = rim if near else body
                if len(points) < 32:
                    cells.append(f"{name}: -")
                    continue
                depth, cpu = reconstruction_cpu(points, grid, cell_steps)
                totals[name] += cpu
                cells.append(f"{name}: {len(points):,d} pts depth {depth} {cpu:.2f} s")
            print(f"{region.shape} r={region.bounding_radius:.0f}  " + "; ".join(cells), flush=True)
    print("in all (CPU s): " + ", ".join(f"{name} {cpu:.1f}" for name, cpu in totals.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
