"""Metrics against brute-force all-pairs references and closed-form cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

import dpcbench.metrics as metrics
from dpcbench.holes.regions import HoleRegion
from dpcbench.metrics.pairs import SIMILAR_SQ_DISTANCE, CloudPair

# -- a brute-force pc_error, written from its description (all pairs, python loops) --------------------

def _dedup(points, normals=None):
    _, first = np.unique(points, axis=0, return_index=True)
    keep = np.sort(first)
    return points[keep], None if normals is None else normals[keep]


def _sq_matrix(a, b):
    d = a[:, None, :] - b[None, :, :]
    return (d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]) + d[..., 2] * d[..., 2]


def _same_distance_sets(sq_row):
    """pc_error's sets for one query: exact ties of the nearest, and the 1e-8 chain (both capped at 30)."""
    order = np.argsort(sq_row, kind="stable")
    s = sq_row[order]
    exact = [int(j) for j, v in zip(order, s) if v == s[0]][:30]
    chain = [int(order[0])]
    for n in range(1, min(len(s), 30)):
        if abs(s[n] - s[n - 1]) < SIMILAR_SQ_DISTANCE:
            chain.append(int(order[n]))
        else:
            break
    return exact, chain


def brute_pc_error(a, b, normals_a, peak=None):
    a, normals_a = _dedup(a, normals_a)
    b, _ = _dedup(b)
    ab = _sq_matrix(a, b)
    ba = ab.T
    # normals carried onto b (scaleNormals)
    nb_sum = np.zeros((len(b), 3))
    count = np.zeros(len(b), int)
    for i in range(len(a)):
        exact, _ = _same_distance_sets(ab[i])
        for j in exact:
            nb_sum[j] += normals_a[i]
            count[j] += 1
    normals_b = np.zeros((len(b), 3))
    for j in range(len(b)):
        if count[j]:
            normals_b[j] = nb_sum[j] / count[j]
        else:
            exact, _ = _same_distance_sets(ba[j])
            normals_b[j] = np.mean([normals_a[i] for i in exact], axis=0)

    def plane(q, t, nt, sq):
        errs = []
        for i in range(len(q)):
            _, chain = _same_distance_sets(sq[i])
            errs.append(np.mean([((q[i] - t[j]) @ nt[j]) ** 2 for j in chain]))
        return np.array(errs)

    d1 = max(ab.min(axis=1).mean(), ba.min(axis=1).mean())
    d2 = max(plane(a, b, normals_b, ab).mean(), plane(b, a, normals_a, ba).mean())
    h2 = max(ab.min(axis=1).max(), ba.min(axis=1).max())
    self_sq = _sq_matrix(a, a)
    np.fill_diagonal(self_sq, np.inf)
    spacing = np.sqrt(self_sq.min(axis=1))
    p = spacing[spacing**2 > 1e-10].max() if peak is None else peak
    return {
        "d1_mse": d1, "d2_mse": d2, "d1_hausdorff_sq": h2, "peak": p,
        "d1_psnr": 10 * math.log10(3 * p * p / d1), "d2_psnr": 10 * math.log10(3 * p * p / d2),
        "d1_hausdorff_psnr": 10 * math.log10(3 * p * p / h2),
    }


def _voxel_cloud(rng, n, size):
    """n random points of an integer grid 0..size-1 (ties and duplicates guaranteed)."""
    return rng.integers(0, size, size=(n, 3)).astype(np.float64)


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("kind", ["float", "voxel"])
def test_pc_error_matches_brute_force(seed, kind):
    rng = np.random.default_rng(seed)
    if kind == "float":
        a = rng.random((300, 3)) * 10
        b = np.concatenate([a[:200] + rng.normal(0, 0.2, (200, 3)), rng.random((60, 3)) * 10])
        b = np.concatenate([b, b[:5]])  # duplicates in the result
    else:
        a = _voxel_cloud(rng, 350, 14)  # has duplicates and many equal-distance neighbours
        b = np.concatenate([_voxel_cloud(rng, 250, 14), a[:100]])
    normals = _unit(rng.normal(size=a.shape))  # random signs on purpose: averaging must use them as given
    want = brute_pc_error(a, b, normals)
    got = metrics.pc_error(a, b, normals)
    for key, value in want.items():
        assert got[key] == pytest.approx(value, rel=1e-12), key
    got_1023 = metrics.pc_error(a, b, normals, peak=1023)
    want_1023 = brute_pc_error(a, b, normals, peak=1023.0)
    for key, value in want_1023.items():
        assert got_1023[key] == pytest.approx(value, rel=1e-12), key


def _brute_companions(a, b, tau, ref_mask=None, res_mask=None):
    a, _ = _dedup(a)
    b, _ = _dedup(b)
    d_ab = np.sqrt(_sq_matrix(a, b).min(axis=1))
    d_ba = np.sqrt(_sq_matrix(b, a).min(axis=1))
    if ref_mask is not None:
        d_ab, d_ba = d_ab[ref_mask(a)], d_ba[res_mask(b)]
    h = max(d_ab.max(), d_ba.max())
    diag = np.linalg.norm(a.max(0) - a.min(0))
    p, r = np.mean(d_ba <= tau), np.mean(d_ab <= tau)
    return {
        "hausdorff": h,
        "nshd": h * h / (diag * diag * len(a)),
        "chamfer": np.mean(d_ab**2) + np.mean(d_ba**2),
        "fscore": 0.0 if p + r == 0 else 2 * p * r / (p + r),
        "d1_mse": max(np.mean(d_ab**2), np.mean(d_ba**2)),
    }


@pytest.mark.parametrize("seed", [0, 1])
def test_companions_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    a = rng.random((400, 3)) * 5
    b = np.concatenate([a[:300] + rng.normal(0, 0.05, (300, 3)), rng.random((50, 3)) * 5])
    names = ["hausdorff", "nshd", "chamfer", "fscore", "d1_mse"]
    got = metrics.score_frame(a, b, names, fscore_threshold=0.1)
    want = _brute_companions(a, b, 0.1)
    for name in names:
        assert got[name] == pytest.approx(want[name], rel=1e-12), name
    # default threshold: 2 x the median nearest-neighbour spacing of the reference
    sq = _sq_matrix(a, a)
    np.fill_diagonal(sq, np.inf)
    tau = 2 * np.median(np.sqrt(sq.min(axis=1)))
    assert metrics.fscore(a, b) == pytest.approx(_brute_companions(a, b, tau)["fscore"], rel=1e-12)


def test_region_variant_matches_brute_force():
    rng = np.random.default_rng(3)
    a = rng.random((500, 3)) * 4
    hole = HoleRegion.ball([2, 2, 2], 0.8)
    b = a[~hole.contains(a)]
    b = np.concatenate([b, hole.center + rng.normal(0, 0.3, (20, 3))])  # a rough fill
    names = ["hausdorff", "nshd", "chamfer", "fscore", "d1_mse"]
    got = metrics.score_frame(a, b, names, regions=[hole], region_margin=0.1, fscore_threshold=0.2)

    def inside(pts):
        return hole.contains(pts, 0.1)

    want = _brute_companions(a, b, 0.2, inside, inside)
    for name in ("hausdorff", "chamfer", "fscore", "d1_mse"):
        assert got[name] == pytest.approx(want[name], rel=1e-12), name
    # NSHD normalises by the whole reference frame, in the region variant too
    diag = np.linalg.norm(a.max(0) - a.min(0))
    assert got["nshd"] == pytest.approx(want["hausdorff"] ** 2 / (diag**2 * len(a)), rel=1e-12)
    whole = metrics.score_frame(a, b, ["d1_mse"])
    assert got["d1_mse"] > 5 * whole["d1_mse"]  # not diluted by the untouched points


def test_region_left_empty_is_scored_against_the_hole_border():
    grid = np.stack(np.meshgrid(np.arange(21.0), np.arange(21.0), [0.0]), -1).reshape(-1, 3)
    hole = HoleRegion.ball([10, 10, 0], 3.5)
    result = grid[~hole.contains(grid)]
    got = metrics.score_frame(grid, result, ["d1_mse", "hausdorff", "fscore", "gpsnr_d1"], regions=[hole], peak=1)
    gt_in_hole = grid[hole.contains(grid)]
    nearest_sq = _sq_matrix(gt_in_hole, result).min(axis=1)
    assert got["d1_mse"] == pytest.approx(nearest_sq.mean())  # only the ground-truth side is evaluated
    assert got["hausdorff"] == pytest.approx(np.sqrt(nearest_sq.max()))
    assert got["fscore"] == 0.0
    assert math.isfinite(got["gpsnr_d1"])
    # a region holding no point on either side: nothing to score
    empty = metrics.score_frame(grid, result, ["d1_mse", "gpsnr_d1", "fscore"],
                                regions=[HoleRegion.ball([0, 0, 50], 1)])
    assert all(math.isnan(v) for v in empty.values())


def _plane(n=25, spacing=1.0):
    g = np.arange(n) * spacing
    return np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)


def test_cloud_against_itself():
    a = _plane()
    got = metrics.score_frame(a, a.copy(), list(metrics.DEFAULT_METRICS) + ["d1_mse", "d2_mse"], peak=1023)
    assert got["d1_mse"] == 0 and got["d2_mse"] == 0 and got["hausdorff"] == 0 and got["chamfer"] == 0
    assert got["gpsnr_d1"] == metrics.DEFAULT_MAX_PSNR and got["gpsnr_d2"] == metrics.DEFAULT_MAX_PSNR
    assert got["fscore"] == 1.0 and got["nshd"] == 0.0
    raw = metrics.pc_error(a, a, np.tile([0.0, 0.0, 1.0], (len(a), 1)))
    assert raw["d1_psnr"] == math.inf  # pc_error's own output is not capped
    assert metrics.gpsnr_d1(a, a, max_psnr=None) == math.inf


def test_shifted_copy_closed_form():
    a = _plane()
    shift = np.array([0.1, 0.2, 0.05])  # shorter than half the spacing: each point's nearest is its copy
    got = metrics.score_frame(a, a + shift, ["d1_mse", "gpsnr_d1", "hausdorff", "nshd", "chamfer", "fscore"], peak=1023)
    s2 = float(shift @ shift)
    assert got["d1_mse"] == pytest.approx(s2, rel=1e-12)
    assert got["gpsnr_d1"] == pytest.approx(10 * math.log10(3 * 1023**2 / s2), rel=1e-12)
    assert got["hausdorff"] == pytest.approx(math.sqrt(s2), rel=1e-12)
    assert got["chamfer"] == pytest.approx(2 * s2, rel=1e-12)
    diag = np.linalg.norm(a.max(0) - a.min(0))
    assert got["nshd"] == pytest.approx(s2 / (diag**2 * len(a)), rel=1e-12)
    assert got["fscore"] == 1.0
    assert metrics.resolve_peak("intrinsic", CloudPair(a, a)) == 1.0  # unit grid spacing


@pytest.mark.parametrize("estimate", [False, True])
def test_plane_against_displaced_plane_d2(estimate):
    a = _plane()
    normals = None if estimate else np.tile([0.0, 0.0, 1.0], (len(a), 1))
    delta = 0.3
    got = metrics.score_frame(a, a + [0, 0, delta], ["d1_mse", "d2_mse", "gpsnr_d2"], reference_normals=normals, peak=2)
    assert got["d2_mse"] == pytest.approx(delta**2, rel=1e-9)
    assert got["gpsnr_d2"] == pytest.approx(10 * math.log10(12 / delta**2), rel=1e-9)
    # sliding within the plane: point-to-point sees it, point-to-plane does not
    slid = metrics.score_frame(a, a + [0.3, 0, 0], ["d1_mse", "d2_mse"], reference_normals=normals)
    assert slid["d1_mse"] == pytest.approx(0.09, rel=1e-9)
    assert slid["d2_mse"] == pytest.approx(0.0, abs=1e-12)


def _sphere(n=3000, radius=10.0):
    """Fibonacci points on a sphere, and their outward normals."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    unit = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    return radius * unit, unit


def test_estimated_normals_do_not_depend_on_their_signs():
    """A hole in a sphere: hole points average their normals onto the border points of the result.

    Estimated normals (open3d, arbitrary signs) are aligned locally before averaging, so D2 equals D2
    with the same normals consistently oriented outwards and given explicitly."""
    a, _ = _sphere()
    hole = HoleRegion.ball(a[0], 4.0)
    b = a[~hole.contains(a)]
    estimated = metrics.estimate_normals(a)
    assert 0.2 < np.mean(np.einsum("ij,ij->i", estimated, a) > 0) < 0.8  # open3d's signs are mixed here
    oriented = estimated * np.sign(np.einsum("ij,ij->i", estimated, a))[:, None]
    assert metrics.d2_mse(a, b) == pytest.approx(metrics.d2_mse(a, b, reference_normals=oriented), rel=1e-12)
    assert metrics.d2_mse(a, b, reference_normals=estimated) != pytest.approx(metrics.d2_mse(a, b), rel=1e-3)


def test_duplicates_are_merged_like_pc_error():
    rng = np.random.default_rng(1)
    a = rng.random((200, 3))
    b = a + rng.normal(0, 0.01, a.shape)
    base = metrics.score_frame(a, b, ["d1_mse", "d2_mse", "chamfer"], peak=1)
    doubled = metrics.score_frame(np.concatenate([a, a[:50]]), np.concatenate([b, b[:80]]),
                                  ["d1_mse", "d2_mse", "chamfer"], peak=1)
    for name in base:
        assert doubled[name] == pytest.approx(base[name], rel=1e-12)
    kept = metrics.score_frame(
        np.concatenate([a, a[:50]]), np.concatenate([b, b[:80]]), ["d1_mse"], peak=1, drop_duplicates=False
    )
    assert kept["d1_mse"] != pytest.approx(base["d1_mse"], rel=1e-6)


def test_peaks():
    a = _plane(spacing=2.0)
    pair = CloudPair(a, a + 0.1)
    assert metrics.resolve_peak("intrinsic", pair) == 2.0
    assert metrics.resolve_peak("bitdepth:10") == 1023
    assert metrics.resolve_peak("bitdepth", bit_depth=9) == 511
    assert metrics.resolve_peak("1023") == 1023 and metrics.resolve_peak(12.5) == 12.5
    for bad in ("foo", "bitdepth", "bitdepth:x", -1, 0, float("nan"), None):
        with pytest.raises(ValueError):
            metrics.resolve_peak(bad, pair)
    d1 = metrics.d1_mse(a, a + 0.1)
    assert metrics.gpsnr_d1(a, a + 0.1, peak="bitdepth:10") == pytest.approx(10 * math.log10(3 * 1023**2 / d1))
    with pytest.raises(ValueError, match="two distinct"):
        metrics.gpsnr_d1(np.zeros((3, 3)), np.ones((2, 3)))


def test_bad_inputs_raise_clear_errors():
    good = np.random.default_rng(0).random((10, 3))
    with pytest.raises(ValueError, match="zero points"):
        metrics.score_frame(np.empty((0, 3)), good)
    with pytest.raises(ValueError, match="zero points"):
        metrics.score_frame(good, np.empty((0, 3)))
    nan = good.copy()
    nan[3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        metrics.score_frame(good, nan)
    with pytest.raises(ValueError, match="shape"):
        metrics.score_frame(good[:, :2], good)
    with pytest.raises(ValueError, match="normals"):
        metrics.score_frame(good, good, reference_normals=np.ones((3, 3)))
    with pytest.raises(KeyError, match="unknown metric"):
        metrics.score_frame(good, good, ["psnr"])
    with pytest.raises(ValueError, match="unknown scoring option"):
        metrics.score_frame(good, good, fscore_tau=1.0)
    with pytest.raises(ValueError, match="sequence-level"):
        metrics.score_frame(good, good, ["temporal_consistency"])
    with pytest.raises(ValueError, match="mismatched frame counts"):
        metrics.score_sequence([good, good], [good])
    with pytest.raises(ValueError, match="frame 1: result"):
        metrics.score_sequence([good, good], [good, np.empty((0, 3))])
    with pytest.raises(ValueError, match="positive distance"):
        metrics.fscore(good, good, fscore_threshold=-1)


def test_score_sequence_aggregates_per_frame_values():
    rng = np.random.default_rng(2)
    refs = [rng.random((300, 3)) for _ in range(3)]
    results = [refs[0].copy(), refs[1] + 0.01, refs[2] + rng.normal(0, 0.02, (300, 3))]
    out = metrics.score_sequence(refs, results, ["gpsnr_d1", "chamfer"], peak=1)
    assert [f["frame"] for f in out["frames"]] == [0, 1, 2]
    for i in range(3):
        single = metrics.score_frame(refs[i], results[i], ["gpsnr_d1", "chamfer"], peak=1)
        assert out["frames"][i]["chamfer"] == pytest.approx(single["chamfer"])
    assert out["mean"]["gpsnr_d1"] == pytest.approx(np.mean([f["gpsnr_d1"] for f in out["frames"]]))
    assert out["frames"][0]["gpsnr_d1"] == metrics.DEFAULT_MAX_PSNR
    assert out["capped"] == [{"frame": 0, "metric": "gpsnr_d1"}]
    # a frame where the hole-region metric is undefined is left out of the mean
    far = HoleRegion.ball([9, 9, 9], 0.5)
    everywhere = HoleRegion.ball([0.5, 0.5, 0.5], 2)
    out = metrics.score_sequence(refs, results, ["chamfer"], regions=[[far], [everywhere], [everywhere]])
    assert math.isnan(out["frames"][0]["chamfer"])
    assert out["mean"]["chamfer"] == pytest.approx((out["frames"][1]["chamfer"] + out["frames"][2]["chamfer"]) / 2)


def test_registry_facts():
    for name in ("gpsnr_d1", "gpsnr_d2", "nshd", "hausdorff", "chamfer", "fscore", "temporal_consistency"):
        metric = metrics.METRICS[name]
        assert metric.name == name and metric.unit and metric.version and metric.description
    assert metrics.METRICS["gpsnr_d1"].higher_is_better and metrics.METRICS["fscore"].higher_is_better
    assert not metrics.METRICS["nshd"].higher_is_better and not metrics.METRICS["chamfer"].higher_is_better
    assert metrics.METRICS["temporal_consistency"].level == "sequence"
    assert set(metrics.DEFAULT_METRICS) == {"gpsnr_d1", "gpsnr_d2", "nshd", "hausdorff", "chamfer", "fscore"}


def test_one_pair_serves_all_metrics_and_scopes(monkeypatch):
    """score_frame builds each KD-tree once and queries each direction once, whatever the metrics."""
    import scipy.spatial  # metrics.pairs imports cKDTree from here when it builds a tree

    built = []
    original = scipy.spatial.cKDTree

    def counting_tree(points, *args, **kwargs):
        built.append(len(points))
        return original(points, *args, **kwargs)

    monkeypatch.setattr(scipy.spatial, "cKDTree", counting_tree)
    rng = np.random.default_rng(0)
    a = rng.random((500, 3))
    b = a + rng.normal(0, 0.01, a.shape)
    names = list(metrics.DEFAULT_METRICS) + ["d1_mse", "d2_mse", "hausdorff_psnr"]
    region = [HoleRegion.ball([0.5, 0.5, 0.5], 0.3)]
    both = metrics.score_frame_scopes(a, b, names, regions=region)
    assert sorted(built) == [500, 500]  # one tree per cloud (normal estimation uses open3d's own)
    assert both["frame"] == metrics.score_frame(a, b, names)
    assert both["holes"] == metrics.score_frame(a, b, names, regions=region)


# -- the exact shortcuts of metrics.pairs (hash matching, face neighbours) change no value ---------------

def _matched_pairs(rng):
    """Float pairs where most result points are exact copies of reference points, some have a second
    point within pc_error's 1e-8 squared tolerance (so the shortcut must still find their tie runs),
    -0.0 coordinates and duplicates on both sides."""
    a = rng.random((400, 3)) * 10
    a[:20, 0] = 0.0
    companions = a[20:40] + 5e-5  # squared distance 7.5e-9 < 1e-8 from their originals
    a = np.concatenate([a, companions, a[:10]])  # duplicates in the reference
    b = np.concatenate([a[:300], rng.random((80, 3)) * 10, a[40:45]])
    b[:20, 0] = -0.0
    return a, b


@pytest.mark.parametrize("seed", [0, 1])
def test_exact_match_shortcut_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    a, b = _matched_pairs(rng)
    normals = _unit(rng.normal(size=a.shape))
    want = brute_pc_error(a, b, normals)
    got = metrics.pc_error(a, b, normals)
    for key, value in want.items():
        assert got[key] == pytest.approx(value, rel=1e-12), key


@pytest.mark.parametrize("kind", ["float", "voxel"])
def test_hash_collisions_change_no_value(monkeypatch, kind):
    """With a hash that collides everywhere (2 bits), deduplication and exact matching must fall back
    on coordinates and KD-tree queries and give the same figures."""
    import dpcbench.metrics.pairs as pairs_module

    rng = np.random.default_rng(3)
    if kind == "float":
        a, b = _matched_pairs(rng)
    else:
        a = _voxel_cloud(rng, 350, 14)
        b = np.concatenate([_voxel_cloud(rng, 250, 14), a[:100]])
    normals = _unit(rng.normal(size=a.shape))
    want = metrics.pc_error(a, b, normals)
    original = pairs_module.point_keys
    monkeypatch.setattr(pairs_module, "point_keys", lambda p: original(p) & np.uint64(3))
    got = metrics.pc_error(a, b, normals)
    assert got == want
    assert got == pytest.approx(brute_pc_error(a, b, normals), rel=1e-12)


def test_first_occurrences_against_numpy_unique():
    from dpcbench.metrics.pairs import first_occurrences

    rng = np.random.default_rng(4)
    points = _voxel_cloud(rng, 2000, 9)  # many duplicates
    points[rng.random(len(points)) < 0.2, 1] *= -1  # -0.0 and 0.0 must be equal
    _, first = np.unique(points + 0.0, axis=0, return_index=True)
    assert np.array_equal(first_occurrences(points), np.sort(first))
    assert first_occurrences(rng.random((100, 3))) is None


def test_face_neighbour_mask_against_brute_force():
    from dpcbench.metrics.pairs import face_neighbour_mask

    rng = np.random.default_rng(5)
    points = np.unique(_voxel_cloud(rng, 600, 12), axis=0) - 3  # distinct, negative coordinates too
    got = face_neighbour_mask(points)
    sq = _sq_matrix(points, points)
    want = (sq == 1.0).any(axis=1)
    assert np.array_equal(got, want)
    assert 0 < want.sum() < len(points)


def test_values_do_not_depend_on_threads():
    rng = np.random.default_rng(6)
    a = _voxel_cloud(rng, 3000, 30)
    b = np.concatenate([a[:2000], _voxel_cloud(rng, 500, 30) + 0.5])
    assert metrics.score_frame(a, b, workers=1) == metrics.score_frame(a, b, workers=2)
    with pytest.raises(ValueError, match="workers"):
        metrics.score_frame(a, b, workers=0)
