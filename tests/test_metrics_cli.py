"""`dpcbench score` on small sequences written to a temporary folder."""

from __future__ import annotations

import json

import numpy as np
import pytest

import dpcbench.metrics as metrics
from dpcbench.bench.cli import main
from dpcbench.bench.data.plyio import PointCloud, write_ply
from dpcbench.bench.data.sequences import load_sequence, save_sequence
from dpcbench.holes.regions import HoleRegion, regions_to_json


def _grid(n=20):
    g = np.arange(n, dtype=float)
    return np.stack(np.meshgrid(g, g, [3.0]), -1).reshape(-1, 3)


@pytest.fixture()
def sequences(tmp_path):
    rng = np.random.default_rng(0)
    refs = [_grid() + [f, 0, 0] for f in range(3)]
    hole = [HoleRegion.ball(r[0] + [10, 10, 0], 3.0) for r in refs]
    results = [r[~h.contains(r)] for r, h in zip(refs, hole)]
    results[1] = np.concatenate([results[1], hole[1].center + rng.normal(0, 0.5, (15, 3))])
    save_sequence(refs, tmp_path / "ref", prefix="ref")
    save_sequence(results, tmp_path / "res", prefix="res")
    results = load_sequence(tmp_path / "res").points  # as stored: float32 coordinates
    holes_json = tmp_path / "holes.json"
    holes_json.write_text(json.dumps(regions_to_json([[h] for h in hole])))
    return tmp_path, refs, results, [[h] for h in hole]


def _run_json(capsys, *argv):
    code = main(["score", *map(str, argv), "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


def test_json_matches_the_library(sequences, capsys):
    folder, refs, results, _ = sequences
    out = _run_json(capsys, folder / "ref", folder / "res")
    want = metrics.score_sequence(refs, results)
    assert [f["frame"] for f in out["frames"]] == [0, 1, 2]
    for got_frame, want_frame in zip(out["frames"], want["frames"]):
        assert set(got_frame) == {"frame", *metrics.DEFAULT_METRICS}
        for name in metrics.DEFAULT_METRICS:
            assert got_frame[name] == pytest.approx(want_frame[name], rel=1e-9)
    assert out["mean"]["gpsnr_d1"] == pytest.approx(want["mean"]["gpsnr_d1"], rel=1e-9)
    assert out["settings"]["peak"] == "intrinsic" and out["settings"]["scope"] == "frame"
    assert out["settings"]["reference_normals"] == "estimated"


def test_regions_peak_and_metric_selection(sequences, capsys):
    folder, refs, results, regions = sequences
    out = _run_json(capsys, folder / "ref", folder / "res", "--region", folder / "holes.json", "--region-margin", "0.5",
                    "--peak", "bitdepth", "--metric", "d1_mse", "--metric", "gpsnr_d1",
                    "--metric", "temporal_consistency")
    # the frames are voxelized with coordinates < 32: bit depth 5, peak 31
    assert out["settings"]["peak"] == "bitdepth:5" and out["settings"]["scope"] == "holes"
    want = metrics.score_sequence(refs, results, ["d1_mse", "gpsnr_d1", "temporal_consistency"], peak=31,
                                  regions=regions, region_margin=0.5)
    for got_frame, want_frame in zip(out["frames"], want["frames"]):
        assert got_frame["d1_mse"] == pytest.approx(want_frame["d1_mse"], rel=1e-9)
        assert got_frame["gpsnr_d1"] == pytest.approx(want_frame["gpsnr_d1"], rel=1e-9)
    assert out["sequence"]["temporal_consistency"] == pytest.approx(want["sequence"]["temporal_consistency"])
    whole = _run_json(capsys, folder / "ref", folder / "res", "--metric", "d1_mse")
    assert out["frames"][0]["d1_mse"] > 10 * whole["frames"][0]["d1_mse"]


def test_single_files_and_table(sequences, capsys):
    folder, refs, results, _ = sequences
    code = main(["score", str(folder / "ref" / "ref_0000.ply"), str(folder / "ref" / "ref_0000.ply"), "--peak", "1023"])
    out = capsys.readouterr().out
    assert code == 0
    assert "gpsnr_d1" in out and "fscore" in out and "peak: 1023" in out and "capped" in out
    code = main(["score", str(folder / "ref"), str(folder / "res")])
    out = capsys.readouterr().out
    assert code == 0 and "mean" in out


def test_errors(sequences, capsys, tmp_path):
    folder, refs, results, _ = sequences
    (folder / "res" / "res_0002.ply").unlink()
    assert main(["score", str(folder / "ref"), str(folder / "res")]) == 2
    assert "mismatched frame counts" in capsys.readouterr().err
    assert main(["score", str(folder / "ref" / "ref_0000.ply"), str(folder / "ref" / "ref_0001.ply"),
                 "--region", str(folder / "holes.json")]) == 2
    assert "describes 3 frame(s)" in capsys.readouterr().err
    bad = tmp_path / "nan.ply"
    pts = _grid()
    pts[5, 2] = np.nan
    write_ply(bad, PointCloud(pts))
    assert main(["score", str(folder / "ref" / "ref_0000.ply"), str(bad)]) == 2
    assert "NaN" in capsys.readouterr().err
    not_holes = tmp_path / "x.json"
    not_holes.write_text("{}")
    assert main(["score", str(folder / "ref" / "ref_0000.ply"), str(folder / "ref" / "ref_0000.ply"),
                 "--region", str(not_holes)]) == 2
    assert "not a holes file" in capsys.readouterr().err
    assert main(["score", str(folder / "ref" / "ref_0000.ply"), str(folder / "ref" / "ref_0000.ply"),
                 "--peak", "loud"]) == 2
    assert "unknown peak" in capsys.readouterr().err
