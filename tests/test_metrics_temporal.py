"""Temporal consistency separates steady fills from jittery or frozen ones on a constructed sequence."""

from __future__ import annotations

import math

import numpy as np
import pytest

import dpcbench.metrics as metrics
from dpcbench.holes.regions import HoleRegion

RADIUS = 10.0
MOTION = np.array([0.6, 0.0, 0.0])  # per frame, along the normal at the hole centre
N_FRAMES = 5


def _sample_sphere(rng, n, centre, radius=RADIUS):
    v = rng.normal(size=(n, 3))
    return centre + radius * v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def scene():
    """A sphere moving along +x, sampled afresh each frame (no point correspondence, like a capture),
    with a hole at its +x pole that moves with it."""
    rng = np.random.default_rng(0)
    centres = [MOTION * f for f in range(N_FRAMES)]
    truth = [_sample_sphere(rng, 5000, c) for c in centres]
    regions = [[HoleRegion.ball(c + [RADIUS, 0, 0], 3.0)] for c in centres]
    known = [t[~r[0].contains(t)] for t, r in zip(truth, regions)]

    def fill(offsets, centres_used=centres):
        """Known points plus a fresh sample of the sphere inside each hole, pushed out radially by offsets[f]."""
        out = []
        for f in range(N_FRAMES):
            c = centres_used[f]
            patch = _sample_sphere(rng, 4000, c)
            patch = patch[HoleRegion.ball(c + [RADIUS, 0, 0], 3.0).contains(patch)]  # the hole, where c puts it
            unit = (patch - c) / RADIUS
            out.append(np.concatenate([known[f], patch + offsets[f] * unit]))
        return out

    return {"truth": truth, "regions": regions, "fill": fill, "rng": rng}


def test_steady_jittery_and_frozen_fills(scene):
    truth, regions, fill = scene["truth"], scene["regions"], scene["fill"]

    def tc(results):
        return metrics.temporal_consistency(truth, results, regions)

    assert tc(truth) == 0.0
    steady = tc(fill([0.0] * N_FRAMES))
    steady_wrong = tc(fill([0.5] * N_FRAMES))  # wrong, but wrong the same way every frame
    jitter = tc(fill([0.5, -0.5, 0.5, -0.5, 0.5]))
    frozen = tc(fill([0.0] * N_FRAMES, centres_used=[np.zeros(3)] * N_FRAMES))  # fill stuck at frame 0's place
    # measured: steady 0.009, steady-but-wrong 0.084 (the hole border, where the nearest result point
    # switches between pushed fill and untouched points), jitter 0.83, frozen 0.39
    assert steady < 0.03 and steady_wrong < 0.15
    assert jitter > 0.5 and jitter > 5 * steady_wrong
    assert frozen > 0.25 and frozen > 3 * steady_wrong
    # GPSNR alone cannot tell the jittery fill from the steady-but-wrong one: same error every frame
    gpsnr_wrong = metrics.score_sequence(truth, fill([0.5] * N_FRAMES), ["gpsnr_d1"], peak=1, regions=regions)
    gpsnr_jitter = metrics.score_sequence(truth, fill([0.5, -0.5, 0.5, -0.5, 0.5]), ["gpsnr_d1"], peak=1,
                                          regions=regions)
    assert gpsnr_jitter["mean"]["gpsnr_d1"] == pytest.approx(gpsnr_wrong["mean"]["gpsnr_d1"], abs=1.5)


def test_per_pair_values_and_sequence_entry(scene):
    truth, regions, fill = scene["truth"], scene["regions"], scene["fill"]
    results = fill([0.0, 0.0, 0.8, 0.0, 0.0])  # one bad frame spoils the two pairs it belongs to
    pairs = metrics.temporal_consistency_per_pair(truth, results, regions)
    assert pairs.shape == (N_FRAMES - 1,)
    assert pairs[1] > 0.3 and pairs[2] > 0.3 and pairs[0] < 0.05 and pairs[3] < 0.05
    out = metrics.score_sequence(truth, results, ["chamfer", "temporal_consistency"], regions=regions)
    assert out["sequence"]["temporal_consistency"] == pytest.approx(pairs.mean())
    # without regions the whole frames are compared (the untouched points dilute the value)
    assert metrics.temporal_consistency(truth, results) < pairs.mean()


def test_bad_inputs(scene):
    truth = scene["truth"]
    with pytest.raises(ValueError, match="at least two frames"):
        metrics.temporal_consistency(truth[:1], truth[:1])
    with pytest.raises(ValueError, match="as many result frames"):
        metrics.temporal_consistency(truth, truth[:3])
    with pytest.raises(ValueError, match="regions"):
        metrics.temporal_consistency(truth, truth, [[]])
    with pytest.raises(ValueError, match="zero points"):
        metrics.temporal_consistency(truth[:2], [truth[0], np.empty((0, 3))])
    far = [[HoleRegion.ball([100, 100, 100], 1.0)] for _ in truth]
    assert math.isnan(metrics.temporal_consistency(truth, truth, far))
