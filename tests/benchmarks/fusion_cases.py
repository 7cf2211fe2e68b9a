"""The inputs of temporal-fusion's paper-scale benchmarks (`test_bench_temporal_fusion.py`), importable so that
`profile_method.py --case NAME` profiles exactly what a benchmark times.

Each case is a function returning ``(truth, damaged frames, regions)``: lists of (N_f, 3) float64 arrays and of
`holes.regions.HoleRegion` lists, one per frame, deterministic (fixed seeds).

  coherent-800k          3 frames of the 800k-point human (11-bit grid, height 1040), 5 medium coherent region
                         holes a frame (seed 0): no frame sees another's holes, every hole goes to the spatial fills
  longdress-region       the real 858k-point Longdress frame of ../shared ($DPCBENCH_SHARED; 10-bit), 4 medium
                         region holes (seed 0)
  longdress-occlusion    the same frame with the occlusion rig's boxes (seed 0)

``digest(outputs)``: experiments/fusion_golden.py's sha256 of a run's output points, so that a benchmark or a
trace shows that two revisions give the same points.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))
from fusion_golden import digest  # noqa: E402,F401  (the golden hashes' sha256 of a run's output points)

SIZES = {
    "100k": dict(size="small"),
    "290k": dict(size="default", height=620),
    "800k": dict(size="default", bit_depth=11, height=1040),
}
SHARED = Path(os.environ.get("DPCBENCH_SHARED", Path(__file__).resolve().parents[2].parent / "shared"))
LONGDRESS = SHARED / "data" / "8i_longdress_1300"
LONGDRESS_FILE = LONGDRESS / "longdress_vox10_1300.ply"


def coherent_800k():
    """3 frames of the 800k-point human, 5 medium coherent region holes in each (seed 0)."""
    from dpcbench.bench.data.datasets import load_dataset
    from dpcbench.holes.registry import get_generator

    truth = load_dataset("human", frames=3, progress=False, **SIZES["800k"]).points
    damage = get_generator("region", preset="medium", count=5, coherent=True).damage(truth, seed=0)
    return list(truth), damage.frames, damage.regions


def longdress(holes: str):
    """The Longdress frame with ``holes`` ("region": 4 medium balls; "occlusion": the rig's boxes), seed 0."""
    from dpcbench.bench.data.sequences import load_sequence
    from dpcbench.holes.registry import get_generator

    truth = [load_sequence(LONGDRESS).points[0]]
    params = dict(preset="medium") if holes == "region" else {}
    damage = get_generator(holes, **params).damage(truth, seed=0)
    return truth, damage.frames, damage.regions


CASES = {
    "coherent-800k": coherent_800k,
    "longdress-region": lambda: longdress("region"),
    "longdress-occlusion": lambda: longdress("occlusion"),
}
