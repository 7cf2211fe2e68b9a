"""The per-frame diagnostics of Proposed's temporal terms (issue 50): `bench.reporting.temporal_diagnostics`."""

from __future__ import annotations

import numpy as np

from dpcbench.bench.reporting.temporal_diagnostics import run
from dpcbench.holes.registry import get_generator
from dpcbench.methods import temporal_graph as tg
from dpcbench.methods.registry import get_method
from dpcbench.metrics import score_frame


def _sphere(radius: float = 30.0) -> np.ndarray:
    """The voxels (integer points) within half a voxel of a sphere's surface."""
    r = int(radius) + 2
    grid = np.stack(np.meshgrid(*[np.arange(-r, r + 1)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    return grid[np.abs(np.linalg.norm(grid, axis=1) - radius) <= 0.5]


def test_identical_frames_align_exactly_and_the_scores_are_the_methods_own():
    frame = _sphere()
    frames = [frame.copy() for _ in range(3)]
    holes = {"preset": "small", "coherent": False}
    records = run(frames, holes, seed=0)
    assert [r["frame"] for r in records] == [0, 1, 2]
    # an identical neighbour: the inter-source cube is the target's own surface, ICP residual ~0
    assert sum(r["links"] for r in records) > 0
    for r in records:
        assert r["icp_residual"] < 1e-6
        assert np.isfinite(r["dist"]).all() and (r["dist"] >= 0).all()
    # the D1 figures are those of the methods run on their own (the wrapping changes nothing)
    damage = get_generator("region", **holes).damage(frames, 0)
    proposed = get_method("temporal-graph", variant="paper").inpaint([f.copy() for f in damage.frames],
                                                                     damage.regions)
    for f, r in enumerate(records):
        d1 = score_frame(frames[f], proposed[f], ["gpsnr_d1"], peak="intrinsic")["gpsnr_d1"]
        assert np.isclose(r["proposed"], d1)
        assert np.isclose(r["gain"], r["proposed"] - r["hu"])
    # the module's functions are restored
    assert tg.inter_source.__name__ == "inter_source" and tg.temporal_links.__name__ == "temporal_links"
    assert tg.select_new_points.__name__ == "select_new_points"
