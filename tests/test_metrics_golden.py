"""pc_error 0.14.2's own figures (../shared/golden) reproduced by the library and by `dpcbench score`."""

from __future__ import annotations

import json

import pytest

import metrics
from bench.cli import main
from bench.plyio import read_ply

RELATIVE = 1e-4
PEAKS = {"r0": "intrinsic", "r1023": 1023}


def _golden(shared_dir):
    folder = shared_dir / "golden"
    if not (folder / "pc_error.json").is_file():
        pytest.skip(f"{folder / 'pc_error.json'} not present")
    return folder, json.loads((folder / "pc_error.json").read_text())


def test_library_reproduces_pc_error(shared_dir):
    folder, cases = _golden(shared_dir)
    cases_listed = {c["name"] for c in json.loads((folder / "cases.json").read_text())}
    assert cases_listed == {c["name"] for c in cases}
    for case in cases:
        a = read_ply(folder / case["a"])
        b = read_ply(folder / case["b"])
        assert a.normals is not None, "the golden reference files carry normals"
        pair = metrics.make_pair(a.points, b.points, a.normals)
        for key, peak in PEAKS.items():
            values, _ = metrics.score_pair(
                pair, ["d1_mse", "gpsnr_d1", "d2_mse", "gpsnr_d2", "hausdorff", "hausdorff_psnr"], peak=peak
            )
            want = case[key]
            got = {
                "d1_mse": values["d1_mse"], "d1_psnr": values["gpsnr_d1"],
                "d2_mse": values["d2_mse"], "d2_psnr": values["gpsnr_d2"],
                "d1_hausdorff_sq": values["hausdorff"] ** 2, "d1_hausdorff_psnr": values["hausdorff_psnr"],
                "peak": metrics.resolve_peak(peak, pair),
            }
            for name, value in want.items():
                assert got[name] == pytest.approx(value, rel=RELATIVE), f"{case['name']} {key} {name}"


@pytest.mark.parametrize("case_name", ["punching_holes", "punching_vox_holes"])
def test_cli_json_reproduces_pc_error(shared_dir, capsys, case_name):
    folder, cases = _golden(shared_dir)
    case = next(c for c in cases if c["name"] == case_name)
    for key, peak in (("r0", "intrinsic"), ("r1023", "1023")):
        code = main(["score", str(folder / case["a"]), str(folder / case["b"]), "--json", "--peak", peak,
                     "--metric", "gpsnr_d1", "--metric", "gpsnr_d2", "--metric", "d1_mse", "--metric", "d2_mse",
                     "--metric", "hausdorff_psnr"])
        assert code == 0
        out = json.loads(capsys.readouterr().out)
        frame = out["frames"][0]
        want = case[key]
        assert frame["d1_mse"] == pytest.approx(want["d1_mse"], rel=RELATIVE)
        assert frame["gpsnr_d1"] == pytest.approx(want["d1_psnr"], rel=RELATIVE)
        assert frame["d2_mse"] == pytest.approx(want["d2_mse"], rel=RELATIVE)
        assert frame["gpsnr_d2"] == pytest.approx(want["d2_psnr"], rel=RELATIVE)
        assert frame["hausdorff_psnr"] == pytest.approx(want["d1_hausdorff_psnr"], rel=RELATIVE)
        assert out["mean"]["gpsnr_d1"] == frame["gpsnr_d1"]
        assert out["settings"]["reference_normals"] == "given"
