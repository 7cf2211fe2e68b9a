"""Hole detection without ground truth: boundary points, rims, silhouette exclusion, recall/precision."""

from __future__ import annotations

import numpy as np
import pytest

from dpcbench.holes.detection import boundary_points, detect_holes, detection_scores
from dpcbench.holes.regions import HoleRegion
from dpcbench.holes.registry import get_generator


def sphere(n=8000, radius=50.0, seed=0):
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return radius * p / np.linalg.norm(p, axis=1, keepdims=True)


def test_boundary_points_of_a_flat_disk():
    """Unit grid disk of radius 30: the outermost ring is boundary, the inside (> 2 from the rim) is not."""
    xs, ys = np.meshgrid(np.arange(-30.0, 31), np.arange(-30.0, 31))
    disk = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    r = np.linalg.norm(disk, axis=1)
    disk, r = disk[r <= 30], r[r <= 30]
    on_rim, largest, direction = boundary_points(disk)
    assert not on_rim[r < 28].any()
    outer = r >= 29  # the digital circle's staircase leaves some rim points a gap near pi / 2 only
    assert on_rim[outer].mean() > 0.75
    assert np.median(largest[outer]) > 0.75 * np.pi
    # the empty side points outwards, radially
    flagged = outer & on_rim
    radial = disk[flagged] / r[flagged, None]
    assert np.einsum("ij,ij->i", direction[flagged], radial).mean() > 0.9


def test_closed_sphere_has_no_holes():
    assert detect_holes(sphere()) == []


def test_removed_cap_is_found_and_covered():
    pts = sphere()
    pole = np.array([0.0, 0.0, 50.0])
    cap = np.linalg.norm(pts - pole, axis=1) <= 15
    regions = detect_holes(pts[~cap])
    assert len(regions) == 1
    assert regions[0].contains(pts[cap]).all()
    assert regions[0].radius < 30  # about the cap (chord 15) plus the rim band, not the sphere
    assert regions[0].extra["inward"] > 0.5


def test_open_scan_silhouette_is_not_a_hole():
    """A hemisphere (a front-only scan): its rim is an outer silhouette, empty outside, so its gap
    directions do not point at the rim centroid (inward score about 0) and it is not reported."""
    pts = sphere()
    half = pts[pts[:, 2] > 0]
    assert detect_holes(half) == []
    everything = detect_holes(half, min_inward=-1.0, max_radius=10.0)
    assert len(everything) == 1 and everything[0].extra["inward"] < 0.1


def test_detection_scores_closed_form():
    truth = [HoleRegion.ball([0, 0, 0], 5.0), HoleRegion.ball([100, 0, 0], 5.0)]
    removed = np.array([[0, 0, 0], [1, 0, 0], [100, 0, 0], [101, 0, 0.0]])
    detected = [HoleRegion.ball([0.5, 0, 0], 2.0), HoleRegion.ball([50, 50, 50], 3.0)]
    scores = detection_scores(detected, truth, removed)
    assert scores["recall"] == 0.5 and scores["precision"] == 0.5
    assert detection_scores([], truth, removed)["recall"] == 0.0


@pytest.fixture(scope="module")
def human():
    from dpcbench.bench.datasets import load_dataset

    return load_dataset("human", frames=3, size="tiny", progress=False).points


def test_intact_human_has_no_detected_holes(human):
    """The embedded human is a closed voxelized surface: nothing to detect (measured: 0 regions on
    4 frames of tiny and of small)."""
    assert detect_holes(human[0]) == []


@pytest.mark.parametrize("preset", ["small", "medium"])
def test_detection_finds_synthetic_holes(human, preset):
    """Recall and precision of detection on region holes of the tiny embedded human, 3 frames.

    Measured (a one-off script, not kept; 4 frames x seeds 0-2, default parameters): tiny
    human, small preset recall 1.00 / precision 1.00, medium 0.98 / 1.00, large 0.87 / 0.97;
    small human: small and medium 1.00 / 1.00, large 0.77 / 1.00 (large holes that sever a limb
    leave two open rims that look like the end of an open scan and are not reported). Thresholds
    below leave room for other seeds: mean recall >= 0.9 and mean precision >= 0.9.
    """
    res = get_generator("region", preset=preset).damage(human, 0)
    recall, precision = [], []
    for f, original in enumerate(human):
        scores = detection_scores(detect_holes(res.frames[f]), res.regions[f], original[res.removed[f]])
        recall.append(scores["recall"])
        precision.append(scores["precision"])
    assert np.mean(recall) >= 0.9
    assert np.mean(precision) >= 0.9


def test_real_capture_holes(shared_dir):
    """ricardo9 (MVUB, 9-bit, front-only capture of an upper body): its largest rims are the open
    outline of the scan (inward score < 0) and are excluded; a few hole regions remain."""
    from dpcbench.bench.sequences import load_sequence

    points = load_sequence(shared_dir / "data" / "mvub_ricardo9").points[0]
    every_rim = detect_holes(points, min_inward=-1.0, max_radius=10.0)  # one run, filtered below
    diag = np.linalg.norm(np.ptp(points, axis=0))
    outline = every_rim[0]  # largest rim first
    assert outline.extra["inward"] < 0 and outline.radius > 0.25 * diag
    holes = [r for r in every_rim if r.extra["inward"] >= 0.1 and r.radius <= 0.25 * diag]  # the defaults
    assert all(r is not outline for r in holes)
    assert 1 <= len(holes) <= 20


@pytest.mark.parametrize(
    "points,params,match",
    [
        (np.zeros((0, 3)), {}, "no points"),
        (np.full((50, 3), np.nan), {}, "NaN"),
        (sphere(500), {"k": 2}, "k must be"),
        (sphere(500), {"gap": 7.0}, "gap must be"),
        (sphere(20), {}, "need more than k"),
        (sphere(500), {"link": 0}, "must be positive"),
    ],
)
def test_bad_input_refused(points, params, match):
    with pytest.raises(ValueError, match=match):
        detect_holes(points, **params)


@pytest.mark.parametrize("seed", [0, 1])
def test_octant_prefilter_changes_no_boundary_decision(seed):
    """detect_holes skips the angle sort where all 8 sectors hold a neighbour; the boundary mask and the
    gap directions of the boundary points must equal the full computation's."""
    pts = sphere(6000, seed=seed)
    rng = np.random.default_rng(seed)
    pts = pts[np.linalg.norm(pts - pts[rng.integers(len(pts))], axis=1) > 20]  # a hole
    full_mask, full_gap, full_dir = boundary_points(pts)
    fast_mask, fast_gap, fast_dir = boundary_points(pts, interior_values=False)
    assert np.array_equal(full_mask, fast_mask)
    assert 0 < full_mask.sum() < len(pts)
    computed = ~np.isnan(fast_gap)
    assert computed[full_mask].all() and computed.mean() < 0.5
    assert np.array_equal(fast_gap[computed], full_gap[computed])
    assert np.array_equal(fast_dir[computed], full_dir[computed])
    assert (full_gap[~computed] <= np.pi / 2).all()


def reference_boundary_points(points, k=32, gap=0.6 * np.pi):
    """The plain computation: one k-NN query of all points in input order, angles of every point."""
    from scipy.spatial import cKDTree

    from dpcbench.holes.geometry import estimate_normals, tangent_basis

    _, nbr = cKDTree(points).query(points, k=k)
    tangent = tangent_basis(estimate_normals(points, k))
    offsets = points[nbr[:, 1:]] - points[:, None, :]
    u = np.einsum("nkd,nd->nk", offsets, tangent[:, :, 0])
    v = np.einsum("nkd,nd->nk", offsets, tangent[:, :, 1])
    angles = np.sort(np.arctan2(v, u), axis=1)
    gaps = np.diff(angles, axis=1, append=angles[:, :1] + 2 * np.pi)
    widest = gaps.argmax(axis=1)
    rows = np.arange(len(points))
    largest = gaps[rows, widest]
    middle = angles[rows, widest] + largest / 2
    direction = np.cos(middle)[:, None] * tangent[:, :, 0] + np.sin(middle)[:, None] * tangent[:, :, 1]
    return largest > gap, largest, direction


@pytest.mark.parametrize("block", [997, 1 << 16])
def test_blocked_leaf_order_query_matches_plain_computation(human, monkeypatch, block):
    """boundary_points queries the neighbours block by block in KD-tree leaf order and tests the sectors
    of the nearest neighbours first; on a voxelized frame with holes (ties among neighbour distances,
    offsets exactly on sector borders) and with many small blocks, its mask, gaps and directions are
    exactly those of the plain computation (all gaps) and of the prefiltered one (boundary points)."""
    import dpcbench.holes.detection as detection

    monkeypatch.setattr(detection, "_BLOCK", block)
    frame = get_generator("region", preset="large").damage([human[0]], 0).frames[0]
    ref_mask, ref_gap, ref_dir = reference_boundary_points(frame)
    mask, gaps, direction = boundary_points(frame)
    assert 0 < ref_mask.sum() < len(frame) * 0.2
    assert np.array_equal(mask, ref_mask) and np.array_equal(gaps, ref_gap) and np.array_equal(direction, ref_dir)
    fast_mask, fast_gap, fast_dir = boundary_points(frame, interior_values=False)
    computed = ~np.isnan(fast_gap)
    assert np.array_equal(fast_mask, ref_mask) and computed[ref_mask].all() and computed.mean() < 0.2
    assert np.array_equal(fast_gap[computed], ref_gap[computed])
    assert np.array_equal(fast_dir[computed], ref_dir[computed])
