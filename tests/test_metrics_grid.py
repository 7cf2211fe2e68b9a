"""metrics.grid: the numpy-only neighbours of integer-grid clouds give the KD-tree path's values.

Every check compares against brute force (all pairwise squared distances) or against the KD-tree
path of the same `CloudPair` (``pairs.GRID_PATH = False``), on small integer clouds built to have
many ties (coarse grids, scaled copies), duplicates, far queries and more than 30 tied neighbours.
"""

import subprocess
import sys

import numpy as np
import pytest

import dpcbench.metrics.grid as grid
import dpcbench.metrics.pairs as pairs
from dpcbench.metrics import score_frame


def _pair(ref, res, normals=None, *, use_grid: bool, monkeypatch):
    monkeypatch.setattr(pairs, "GRID_PATH", use_grid)
    pair = pairs.CloudPair(ref, res, normals)
    assert (pair._grid is not None) == use_grid
    return pair


def _ties(nb) -> set:
    return set(zip(nb.exact_rows.tolist(), nb.exact_cols.tolist()))


def _brute(queries, targets, exclude_self=False):
    """(nearest squared distance (Q,), set of (query, target) pairs at it) by all pairwise distances."""
    d = ((queries[:, None, :] - targets[None, :, :]) ** 2).sum(axis=2)
    if exclude_self:
        np.fill_diagonal(d, np.inf)
    best = d.min(axis=1)
    rows, cols = np.nonzero(d == best[:, None])
    return best, set(zip(rows.tolist(), cols.tolist()))


def _random_case(rng):
    side = int(rng.integers(3, 40))
    ref = rng.integers(0, side, (int(rng.integers(2, 250)), 3)).astype(float)
    extra = rng.integers(0, side, (int(rng.integers(1, 250)), 3))
    res = np.concatenate([ref[rng.random(len(ref)) < 0.5], extra * (2 if rng.random() < 0.3 else 1)])
    return ref, res


@pytest.mark.parametrize("seed", range(4))
def test_grid_path_equals_kdtree_path_and_brute_force(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        ref, res = _random_case(rng)
        normals = rng.normal(size=ref.shape)
        g = _pair(ref, res, normals, use_grid=True, monkeypatch=monkeypatch)
        k = _pair(ref, res, normals, use_grid=False, monkeypatch=monkeypatch)
        assert np.array_equal(g.reference, k.reference) and np.array_equal(g.result, k.result)
        for name in ("ref_to_res", "res_to_ref"):
            gn, kn = getattr(g, name), getattr(k, name)
            assert np.array_equal(gn.sq_dist, kn.sq_dist)
            assert np.array_equal(gn.index, kn.index)  # tied queries: the KD-tree's first, on both paths
            assert _ties(gn) == _ties(kn)
            assert set(zip(gn.same_rows.tolist(), gn.same_cols.tolist())) == set(
                zip(kn.same_rows.tolist(), kn.same_cols.tolist()))
        # brute force: distances and every tie (no point here has more than 30 tied neighbours... checked)
        best, ties = _brute(g.reference, g.result)
        if max(np.bincount([r for r, _ in ties])) <= 30:
            assert np.array_equal(g.ref_to_res.sq_dist, best) and _ties(g.ref_to_res) == ties
        if len(g.reference) > 1:
            spacing, _ = _brute(g.reference, g.reference, exclude_self=True)
            assert np.array_equal(g.reference_spacing, np.sqrt(spacing))
            assert g.intrinsic_resolution == k.intrinsic_resolution == np.sqrt(spacing.max())
        assert np.allclose(g.result_normals, k.result_normals, rtol=0, atol=1e-12)
        assert np.allclose(g.plane_ref_to_res, k.plane_ref_to_res, rtol=1e-12, atol=1e-12)
        assert np.allclose(g.plane_res_to_ref, k.plane_res_to_ref, rtol=1e-12, atol=1e-12)


def _norm17_shell():
    """The 48 grid offsets at squared distance 17 ((4,1,0) and (3,2,2) with all signs and orders)."""
    r = np.arange(-4, 5)
    o = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
    return o[(o ** 2).sum(axis=1) == 17]


def test_more_than_30_ties_and_far_queries_are_the_kdtree_s(monkeypatch):
    """pc_error keeps 30 of >30 tied neighbours (which 30 is the KD-tree's), and the ball search stops
    at MAX_SQ_RADIUS: both kinds of queries are answered by the KD-tree, with its values."""
    shell = _norm17_shell().astype(float)
    assert len(shell) == 48
    centres = np.array([[0, 0, 0], [100, 0, 0], [0, 200, 50]], dtype=float)
    res = np.concatenate([c + shell for c in centres])
    ref = np.concatenate([centres, [[500.0, 500.0, 500.0]]])  # the last: ~520 away from any result point
    found = grid.ball_search(*_grid_parts(ref, res))
    assert list(found.count[:3]) == [48, 48, 48] and found.sq[3] == -1
    g = _pair(ref, res, use_grid=True, monkeypatch=monkeypatch)
    k = _pair(ref, res, use_grid=False, monkeypatch=monkeypatch)
    assert np.array_equal(g.ref_to_res._kd_rows, [0, 1, 2, 3])
    assert np.array_equal(g.ref_to_res.sq_dist, k.ref_to_res.sq_dist)
    assert g.ref_to_res.sq_dist[3] == k.ref_to_res.sq_dist[3] > grid.MAX_SQ_RADIUS
    assert _ties(g.ref_to_res) == _ties(k.ref_to_res)
    assert np.bincount(g.ref_to_res.exact_rows).tolist() == [30, 30, 30, 1]  # truncated as pc_error
    assert np.array_equal(g.ref_to_res.index, k.ref_to_res.index)
    assert g.intrinsic_resolution == k.intrinsic_resolution  # the far reference point sets it


def _grid_parts(ref, res):
    frame = grid.GridFrame(ref, res)
    targets = grid.GridCloud(res, frame)
    return targets, frame, grid.GridCloud(ref, frame).keys


def test_lookup_budget_changes_no_value(monkeypatch):
    rng = np.random.default_rng(7)
    ref = rng.integers(0, 60, (300, 3)).astype(float)
    res = rng.integers(0, 60, (40, 3)).astype(float)  # sparse: queries far from their nearest
    normals = rng.normal(size=ref.shape)
    names = ["d1_mse", "gpsnr_d2", "hausdorff", "gpsnr_d1"]
    want = score_frame(ref, res, names, reference_normals=normals)
    monkeypatch.setattr(grid, "LOOKUP_BUDGET", 500)
    frame = grid.GridFrame(ref, res)
    assert (grid.ball_search(grid.GridCloud(res, frame), frame, grid.GridCloud(ref, frame).keys).sq < 0).sum() > 100
    pair = pairs.CloudPair(ref, res, normals)
    assert pair.ref_to_res._kd_rows.size == 0  # the queries the ball search left: answered by coarse_search
    assert score_frame(ref, res, names, reference_normals=normals) == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_coarse_search_is_exact_against_brute_force(seed):
    """Distances and every tie of far queries; beyond the reach: unsettled (-1), for the KD-tree."""
    rng = np.random.default_rng(seed)
    for _ in range(60):
        side = int(rng.integers(5, 150))
        ref = rng.integers(0, side, (int(rng.integers(2, 200)), 3))
        res = rng.integers(0, side, (int(rng.integers(1, 150)), 3)) * int(rng.integers(1, 6))
        frame = grid.GridFrame(ref, res)
        targets, queries = grid.GridCloud(res, frame), grid.GridCloud(ref, frame)
        out = grid.coarse_search(targets, frame, queries.keys)
        q = grid._relative(frame, queries.keys)
        t = grid._relative(frame, targets.keys)
        d2 = ((q[:, None, :] - t[None, :, :]) ** 2).sum(axis=2).astype(float)
        d2[d2 == 0] = np.inf  # a target at the query itself is not a neighbour
        best = d2.min(axis=1)
        within = best < (grid._CELL_REACH * grid._CELL + 1) ** 2
        assert np.array_equal(out.sq, np.where(within, best, -1).astype(np.int64))
        rows, cols = np.nonzero((d2 == best[:, None]) & within[:, None])
        assert set(zip(out.tie_query.tolist(), out.tie_target.tolist())) == set(
            zip(rows.tolist(), targets.rows[cols].tolist()))


def test_duplicates_keep_first_occurrence_and_dtypes_do_not_matter(monkeypatch):
    rng = np.random.default_rng(3)
    ref = rng.integers(-20, 20, (400, 3)).astype(float)
    ref = np.concatenate([ref, ref[::7]])  # duplicates
    res = np.concatenate([ref[::2], rng.integers(-25, 25, (100, 3))])
    normals = rng.normal(size=ref.shape)
    names = ["gpsnr_d1", "gpsnr_d2", "d1_mse", "d2_mse", "hausdorff_psnr", "chamfer", "fscore"]
    monkeypatch.setattr(pairs, "GRID_PATH", False)
    want = score_frame(ref, res, names, reference_normals=normals)
    k = pairs.CloudPair(ref, res, normals)
    monkeypatch.setattr(pairs, "GRID_PATH", True)
    g = pairs.CloudPair(ref, res, normals)
    assert np.array_equal(g.reference_index, k.reference_index) and np.array_equal(g.result_index, k.result_index)
    for dtype in (np.float64, np.float32, np.int16, np.int32):
        got = score_frame(ref.astype(dtype), res.astype(dtype), names, reference_normals=normals.astype(np.float32))
        want32 = score_frame(ref, res, names, reference_normals=normals.astype(np.float32).astype(np.float64))
        assert got == pytest.approx(want32, rel=1e-12)
    assert score_frame(ref, res, names, reference_normals=normals) == pytest.approx(want, rel=1e-12)


def test_float_clouds_take_the_kdtree_path_and_grid_clouds_never_import_scipy():
    a = np.random.default_rng(0).random((50, 3))
    assert pairs.CloudPair(a, a + 0.5)._grid is None
    assert pairs.CloudPair(np.round(a * 10), np.round(a * 10) + 1, drop_duplicates=False)._grid is None
    code = (
        "import sys, numpy as np\n"
        "from dpcbench.metrics import score_frame\n"
        "rng = np.random.default_rng(0)\n"
        "a = rng.integers(0, 50, (2000, 3)); b = np.concatenate([a[::2], rng.integers(0, 50, (300, 3))])\n"
        "print(score_frame(a, b, ['gpsnr_d1', 'gpsnr_d2'], reference_normals=rng.normal(size=a.shape)))\n"
        "assert not [m for m in sys.modules if m.startswith(('scipy', 'pandas', 'open3d'))], 'heavy import'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)


def test_bad_input_still_gets_the_clear_errors():
    from dpcbench.metrics.errors import UserError

    with pytest.raises(UserError, match="NaN or infinite"):
        pairs.CloudPair(np.array([[0, 0, 0], [np.inf, 0, 0]]), np.zeros((2, 3)))
    with pytest.raises(UserError, match="zero points"):
        pairs.CloudPair(np.zeros((0, 3)), np.zeros((2, 3)))
    with pytest.raises(UserError, match=r"\(N, 3\)"):
        pairs.CloudPair(np.zeros((4, 2), dtype=np.int32), np.zeros((2, 3)))
