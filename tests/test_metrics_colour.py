"""Colour PSNR (`metrics.colour`): pc_error 0.14.2's own figures on the synthetic golden pairs, a
brute-force reference on small random clouds (ties and duplicates included), closed forms, and the
real Longdress frame against recoloured copies (skipped without ../shared)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import dpcbench.metrics as metrics
from dpcbench.bench.data.plyio import read_ply
from dpcbench.metrics import pairs
from dpcbench.metrics.colour import merged_colours, pc_error_colour, to_ycbcr
from dpcbench.metrics.errors import UserError

GOLDEN = Path(__file__).resolve().parent / "data" / "golden_colour"
RELATIVE = 1e-4


def _same(got: float, want: float, rel: float) -> bool:
    if math.isinf(want) or math.isinf(got):
        return got == want
    return got == pytest.approx(want, rel=rel, abs=1e-15)


@pytest.mark.parametrize("grid_path", [True, False], ids=["grid", "kdtree"])
def test_golden_pc_error_colour_figures(monkeypatch, grid_path):
    """Every colour figure pc_error printed (3 channels x A->B, B->A, symmetric x MSE, PSNR) for 5 pairs,
    both colour spaces and both peaks (colour does not depend on the peak), to 1e-4 relative."""
    monkeypatch.setattr(pairs, "GRID_PATH", grid_path)
    cases = json.loads((GOLDEN / "pc_error.json").read_text())
    assert {c["name"] for c in cases} == {c["name"] for c in json.loads((GOLDEN / "cases.json").read_text())}
    checked = 0
    for case in cases:
        a, b = read_ply(GOLDEN / case["a"]), read_ply(GOLDEN / case["b"])
        for space in (0, 1):
            ours = pc_error_colour(a.points, b.points, a.colors, b.colors, mse_space=space)
            for peak in ("r0", "r1023"):
                gold = case[f"{peak}_space{space}"]
                assert gold["mseSpace"] == space
                names = [k for k in gold if k.startswith("c[")]
                assert len(names) == 18
                for name in names:
                    assert _same(ours[name], gold[name], RELATIVE), (case["name"], space, name, ours[name], gold[name])
                    checked += 1
    assert checked == 5 * 2 * 2 * 18


def test_golden_through_score_frame_and_registry():
    """The registered metrics give the golden symmetric PSNRs (cpsnr_y/u/v = space 1, cpsnr_r/g/b = space 0)."""
    case = next(c for c in json.loads((GOLDEN / "pc_error.json").read_text()) if c["name"] == "colour_noise")
    a, b = read_ply(GOLDEN / case["a"]), read_ply(GOLDEN / case["b"])
    values = metrics.score_frame(a.points, b.points, ["cpsnr_y", "cpsnr_u", "cpsnr_v", "cpsnr_r", "cpsnr_g",
                                                      "cpsnr_b", "cpsnr_rgb"],
                                 reference_colours=a.colors, result_colours=b.colors)
    for k, name in enumerate(("cpsnr_y", "cpsnr_u", "cpsnr_v")):
        assert values[name] == pytest.approx(case["r0_space1"][f"c[{k}],PSNRF"], rel=RELATIVE)
    for k, name in enumerate(("cpsnr_r", "cpsnr_g", "cpsnr_b")):
        assert values[name] == pytest.approx(case["r0_space0"][f"c[{k}],PSNRF"], rel=RELATIVE)
    gold = case["r0_space0"]
    mean = max(np.mean([gold[f"c[{k}], 1"] for k in range(3)]), np.mean([gold[f"c[{k}], 2"] for k in range(3)]))
    assert values["cpsnr_rgb"] == pytest.approx(10 * math.log10(255**2 / mean), rel=RELATIVE)


# -- brute force ------------------------------------------------------------------------------------

def _naive_dedup(points, colours):
    groups: dict[tuple, list[int]] = {}
    for i, p in enumerate(map(tuple, points)):
        groups.setdefault(p, []).append(i)
    keys = list(groups)  # insertion order = order of first occurrence
    pts = np.array(keys, dtype=np.float64)
    cols = np.array([[sum(int(colours[i][c]) for i in groups[k]) // len(groups[k]) for c in range(3)] for k in keys])
    return pts, cols


def _naive_yuv(rgb):
    r, g, b = (float(x) for x in rgb)
    return [np.float32((0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0),
            np.float32((-0.1146 * r - 0.3854 * g + 0.5 * b) / 255.0 + 0.5),
            np.float32((0.5 * r - 0.4542 * g - 0.0458 * b) / 255.0 + 0.5)]


def _naive_direction(q, cq, t, ct, space, mask=None):
    """Per-channel MSE over the (selected) queries: for each, every target's squared distance, the
    run of sorted distances within 1e-8 of each other (at most 30), their colours averaged."""
    total, count = np.zeros(3), 0
    for i in range(len(q)):
        if mask is not None and not mask[i]:
            continue
        d = q[i] - t
        sq = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]
        order = np.argsort(sq, kind="stable")
        run = [order[0]]
        for n in range(1, min(30, len(order))):
            if abs(sq[order[n]] - sq[order[n - 1]]) < 1e-8:
                run.append(order[n])
            else:
                break
        assert len(run) < 30, "the test clouds keep tie sets below pc_error's cap"
        mean = [math.floor(sum(int(ct[j][c]) for j in run) / len(run) + 0.5) for c in range(3)]
        if space == 1:
            x, y = _naive_yuv(cq[i]), _naive_yuv(mean)
            err = [float((x[c] - y[c]) * (x[c] - y[c])) for c in range(3)]
        else:
            err = [float((int(cq[i][c]) - mean[c]) ** 2) for c in range(3)]
        total += err
        count += 1
    return total / count if count else None


def _clouds(seed: int, integer: bool):
    rng = np.random.default_rng(seed)
    if integer:
        a = rng.integers(0, 9, (300, 3)).astype(np.float64)  # dense: duplicates and many ties
        b = np.concatenate([a[rng.random(300) < 0.6], rng.integers(0, 9, (60, 3))]).astype(np.float64)
    else:
        a = rng.integers(0, 12, (250, 3)) * 0.5 + rng.choice([0.0, 0.25], (250, 3))  # ties, not on the grid
        b = np.concatenate([a[:150] + rng.choice([0.0, 0.5, -0.5], (150, 3)), rng.random((40, 3)) * 6])
        a, b = np.concatenate([a, a[:30]]), np.concatenate([b, b[:10]])  # duplicates
    ca = rng.integers(0, 256, (len(a), 3)).astype(np.uint8)
    cb = rng.integers(0, 256, (len(b), 3)).astype(np.uint8)
    return a, b, ca, cb


@pytest.mark.parametrize("integer", [True, False], ids=["grid", "float"])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("space", [0, 1])
def test_matches_brute_force(integer, seed, space):
    a, b, ca, cb = _clouds(seed, integer)
    ours = pc_error_colour(a, b, ca, cb, mse_space=space)
    pa, pca = _naive_dedup(a, ca)
    pb, pcb = _naive_dedup(b, cb)
    assert len(pa) < len(a), "the test must exercise duplicate merging"
    fwd = _naive_direction(pa, pca, pb, pcb, space)
    bwd = _naive_direction(pb, pcb, pa, pca, space)
    for k in range(3):
        assert ours[f"c[{k}], 1"] == pytest.approx(fwd[k], rel=1e-12)
        assert ours[f"c[{k}], 2"] == pytest.approx(bwd[k], rel=1e-12)
        assert ours[f"c[{k}], F"] == pytest.approx(max(fwd[k], bwd[k]), rel=1e-12)


def test_hole_region_scope_matches_brute_force():
    a, b, ca, cb = _clouds(3, True)

    class Box:
        def contains(self, points, margin=0.0):
            return np.all(np.abs(np.asarray(points) - 4.0) <= 2.0 + margin, axis=1)

    region = [Box()]
    got = metrics.score_frame(a, b, ["cpsnr_y", "cpsnr_r"], regions=region, reference_colours=ca, result_colours=cb)
    pa, pca = _naive_dedup(a, ca)
    pb, pcb = _naive_dedup(b, cb)
    for name, space, ch in (("cpsnr_y", 1, 0), ("cpsnr_r", 0, 0)):
        fwd = _naive_direction(pa, pca, pb, pcb, space, Box().contains(pa))
        bwd = _naive_direction(pb, pcb, pa, pca, space, Box().contains(pb))
        peak = 1.0 if space == 1 else 255.0
        assert got[name] == pytest.approx(10 * math.log10(peak**2 / max(fwd[ch], bwd[ch])), rel=1e-12)


# -- conventions, closed forms -----------------------------------------------------------------------

def test_duplicates_floor_and_ties_round_half_up():
    """Merged duplicates take the floor of the mean colour; equally distant neighbours the rounded mean."""
    pts = np.array([[0, 0, 0], [0, 0, 0], [5, 5, 5]], dtype=float)
    cols = np.array([[10, 10, 10], [13, 14, 11], [0, 0, 0]], dtype=np.uint8)
    kept = np.array([0, 2])
    assert merged_colours(pts, cols, kept).tolist() == [[11, 12, 10], [0, 0, 0]]
    # one query exactly between two targets of red 10 and 13: compared with round(11.5) = 12
    query = np.array([[1.0, 0, 0]])
    targets = np.array([[0.0, 0, 0], [2.0, 0, 0]])
    out = pc_error_colour(query, targets, np.array([[12, 0, 0]], np.uint8),
                          np.array([[10, 0, 0], [13, 0, 0]], np.uint8), mse_space=0)
    assert out["c[0], 1"] == 0.0
    assert out["c[0], 2"] == pytest.approx((4 + 1) / 2)


def test_identical_clouds_are_infinite_and_capped():
    a, _, ca, _ = _clouds(4, True)
    out = pc_error_colour(a, a, ca, ca)
    assert all(math.isinf(out[f"c[{k}],PSNRF"]) for k in range(3))
    assert metrics.score_frame(a, a, ["cpsnr_y"], reference_colours=ca, result_colours=ca)["cpsnr_y"] == 200.0


def test_uniform_offset_closed_form():
    """Same geometry, every channel shifted by delta: RGB MSE = delta^2 exactly, Y MSE = (delta/255)^2
    up to float32 rounding, and Cb, Cr almost unchanged (their coefficients sum to 0)."""
    rng = np.random.default_rng(5)
    a = rng.random((400, 3)) * 100
    ca = rng.integers(20, 200, (400, 3)).astype(np.uint8)
    delta = 7
    out0 = pc_error_colour(a, a, ca, ca + delta, mse_space=0)
    out1 = pc_error_colour(a, a, ca, ca + delta, mse_space=1)
    for k in range(3):
        assert out0[f"c[{k}], F"] == delta**2
        assert out0[f"c[{k}],PSNRF"] == pytest.approx(20 * math.log10(255 / delta), rel=1e-12)
    assert out1["c[0],PSNRF"] == pytest.approx(20 * math.log10(255 / delta), rel=1e-5)
    assert out1["c[1],PSNRF"] > 100 and out1["c[2],PSNRF"] > 100


def test_ycbcr_conversion_values():
    yuv = to_ycbcr(np.array([[255, 255, 255], [0, 0, 0], [255, 0, 0]], np.uint8))
    assert yuv.dtype == np.float32
    assert yuv[0].tolist() == pytest.approx([1.0, 0.5, 0.5], abs=1e-6)
    assert yuv[1].tolist() == pytest.approx([0.0, 0.5, 0.5], abs=1e-7)
    assert yuv[2].tolist() == pytest.approx([0.2126, 0.5 - 0.1146, 1.0], abs=1e-6)


def test_colour_metrics_without_colours_are_refused():
    a, b, ca, _ = _clouds(6, True)
    with pytest.raises(UserError, match="colours on both clouds"):
        metrics.score_frame(a, b, ["cpsnr_y"])
    with pytest.raises(UserError, match=r"\(300, 3\)"):
        metrics.score_frame(a, b, ["cpsnr_y"], reference_colours=ca[:10], result_colours=ca[:len(b)])


def test_longdress_recoloured(shared_dir):
    """The real 858k-point frame against itself (+inf) and against recoloured copies (uniform offset,
    clipped at 255), whose MSEs have the closed form mean((clip(c + delta) - c)^2): same geometry, so
    every point is compared with its own colour."""
    files = sorted((shared_dir / "data" / "8i_longdress_1300").glob("*.ply"))
    if not files:
        pytest.skip("Longdress frame not present")
    cloud = read_ply(files[0])
    pts, cols = cloud.points, cloud.colors
    pair = metrics.make_pair(pts, pts, None, cols, cols)
    kept = pair.reference_index
    base = pair.reference_colours  # deduplicated colours
    assert len(base) == len(pts) if kept is None else len(kept)
    values, _ = metrics.score_pair(pair, ["cpsnr_y", "cpsnr_r"], max_psnr=None)
    assert math.isinf(values["cpsnr_y"]) and math.isinf(values["cpsnr_r"])
    delta = 9
    shifted = np.clip(cols.astype(int) + delta, 0, 255).astype(np.uint8)
    out = pc_error_colour(pts, pts, cols, shifted, mse_space=0)
    expected = ((merged_colours(pts, shifted, kept).astype(float) - base.astype(float)) ** 2).mean(axis=0)
    for k in range(3):
        assert out[f"c[{k}], 1"] == pytest.approx(expected[k], rel=1e-12)
        assert out[f"c[{k}], 2"] == pytest.approx(expected[k], rel=1e-12)
    yuv = pc_error_colour(pts, pts, cols, shifted, mse_space=1)
    d = to_ycbcr(base) - to_ycbcr(merged_colours(pts, shifted, kept))
    assert yuv["c[0], F"] == pytest.approx(float(np.mean((d[:, 0] * d[:, 0]).astype(np.float64))), rel=1e-9)


#: pc_error 0.14.2's symmetric colour PSNRs (c[0..2],PSNRF, ``--color=1 --mseSpace=S``) on real frames against
#: the processed copies of `tests.colour_pairs` (printed by tests/benchmarks/pc_error_compare.py with a pc_error
#: built from mpeg-pcc-dmetric release-v0.14.2)
PC_ERROR_REAL = {
    "longdress/damaged/space1": (36.4087351, 44.8267665, 44.734357),
    "longdress/damaged/space0": (34.7390198, 36.2513794, 36.3597534),
    "longdress/filled/space1": (36.5186056, 44.9249674, 44.78363),
    "longdress/filled/space0": (34.8560842, 36.352728, 36.4437931),
    "longdress/recoloured/space1": (35.0694354, 36.4168212, 35.9555665),
    "longdress/recoloured/space0": (32.5746729, 32.5613556, 32.5804896),
    "ricardo9/damaged/space1": (59.667805, 68.8389485, 68.2934304),
    "ricardo9/damaged/space0": (60.0983887, 59.0456328, 57.9303471),
    "ricardo9/filled/space1": (59.9286895, 68.8317035, 68.3352082),
    "ricardo9/filled/space0": (60.3157045, 59.2896667, 58.1266471),
    "ricardo9/recoloured/space1": (35.3797447, 36.8800579, 36.6175307),
    "ricardo9/recoloured/space0": (33.4383815, 32.8658917, 33.0522311),
}


@pytest.mark.parametrize("frame", ["longdress", "ricardo9"])
def test_real_frames_match_pc_error(shared_dir, frame):
    """cpsnr_y/u/v (and R/G/B) of a real 8i / MVUB frame against a damaged, a filled (duplicates included) and a
    recoloured copy, within 1e-4 relative of the figures pc_error printed (printed to 7 digits: 1e-6 here)."""
    from tests.colour_pairs import FRAMES, processed_copies

    path = shared_dir / "data" / FRAMES[frame]
    if not path.is_file():
        pytest.skip(f"{path} not present")
    cloud = read_ply(path)
    for kind, (points, colours) in processed_copies(cloud.points, cloud.colors).items():
        for space in (1, 0):
            ours = pc_error_colour(cloud.points, points, cloud.colors, colours, mse_space=space)
            for k, want in enumerate(PC_ERROR_REAL[f"{frame}/{kind}/space{space}"]):
                assert ours[f"c[{k}],PSNRF"] == pytest.approx(want, rel=1e-6), (frame, kind, space, k)
    names = ["cpsnr_y", "cpsnr_u", "cpsnr_v"]
    points, colours = processed_copies(cloud.points, cloud.colors)["filled"]
    values, _ = metrics.score_pair(metrics.make_pair(cloud.points, points, None, cloud.colors, colours), names)
    want = PC_ERROR_REAL[f"{frame}/filled/space1"]
    assert [values[n] for n in names] == pytest.approx(list(want), rel=1e-6)


# -- dpcbench score ----------------------------------------------------------------------------------

def test_score_command_adds_colour_psnr(capsys):
    import dpcbench.bench.cli as cli

    ref, res = GOLDEN / "colour_ref.ply", GOLDEN / "colour_holes.ply"
    assert cli.main(["score", str(ref), str(res), "--json", "--max-psnr", "inf"]) == 0
    out = json.loads(capsys.readouterr().out)
    gold = next(c for c in json.loads((GOLDEN / "pc_error.json").read_text()) if c["name"] == "colour_holes")
    for k, name in enumerate(("cpsnr_y", "cpsnr_u", "cpsnr_v")):
        assert out["mean"][name] == pytest.approx(gold["r0_space1"][f"c[{k}],PSNRF"], rel=RELATIVE)
    assert out["mean"]["gpsnr_d1"] == pytest.approx(gold["r0_space1"]["mseF,PSNR (p2point)"], rel=RELATIVE)
    assert out["settings"]["colour"] == "both clouds have colours"
    assert cli.main(["score", str(ref), str(res)]) == 0
    table = capsys.readouterr().out
    assert "cpsnr_y" in table.splitlines()[0]


def test_score_command_says_when_colours_are_missing(tmp_path, capsys):
    import dpcbench.bench.cli as cli
    from dpcbench.bench.data.plyio import PointCloud, write_ply

    ref = GOLDEN / "colour_ref.ply"
    bare = write_ply(tmp_path / "bare.ply", PointCloud(read_ply(GOLDEN / "colour_noise.ply").points))
    assert cli.main(["score", str(ref), str(bare), "--json"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert not any(k.startswith("cpsnr_") for k in out["mean"])
    assert out["settings"]["colour"] == "no colour PSNR: the result has no colours"
    assert "no colour PSNR" in captured.err
    assert cli.main(["score", str(ref), str(bare), "--metric", "cpsnr_y"]) == 2
    assert "has no colours" in capsys.readouterr().err
