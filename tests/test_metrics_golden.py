"""pc_error 0.14.2's own figures reproduced by the library and by `dpcbench score`.

Two sets of golden pairs: the synthetic ones shipped in ``tests/data/golden_synthetic`` (a voxelized
ellipsoid with exact normals against holes, jitter, duplicate points with an off-surface fill, and
the same reference with unoriented normals), which always run, and the real-data ones in
``../shared/golden`` (skipped without ../shared).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import dpcbench.metrics as metrics
from dpcbench.bench.cli import main
from dpcbench.bench.data.plyio import read_ply

RELATIVE = 1e-4
PEAKS = {"r0": "intrinsic", "r1023": 1023}
SYNTHETIC = Path(__file__).resolve().parent / "data" / "golden_synthetic"
SYNTHETIC_CASES = [c["name"] for c in json.loads((SYNTHETIC / "cases.json").read_text())]


def _golden(folder: Path):
    """(folder, pc_error's figures): the committed synthetic set must be there (a missing file fails);
    the real-data set in ../shared may be absent (skipped)."""
    if not (folder / "pc_error.json").is_file():
        assert folder != SYNTHETIC, f"{folder / 'pc_error.json'} is missing: it is committed with the tests"
        pytest.skip(f"{folder / 'pc_error.json'} not present")
    return folder, json.loads((folder / "pc_error.json").read_text())


def _library_figures(folder: Path, case: dict, key: str) -> dict:
    a = read_ply(folder / case["a"])
    b = read_ply(folder / case["b"])
    assert a.normals is not None, "the golden reference files carry normals"
    pair = metrics.make_pair(a.points, b.points, a.normals)
    values, _ = metrics.score_pair(
        pair, ["d1_mse", "gpsnr_d1", "d2_mse", "gpsnr_d2", "hausdorff", "hausdorff_psnr"], peak=PEAKS[key])
    return {
        "d1_mse": values["d1_mse"], "d1_psnr": values["gpsnr_d1"],
        "d2_mse": values["d2_mse"], "d2_psnr": values["gpsnr_d2"],
        "d1_hausdorff_sq": values["hausdorff"] ** 2, "d1_hausdorff_psnr": values["hausdorff_psnr"],
        "peak": metrics.resolve_peak(PEAKS[key], pair),
    }


def _check_library(folder: Path, cases: list[dict]) -> None:
    cases_listed = {c["name"] for c in json.loads((folder / "cases.json").read_text())}
    assert cases_listed == {c["name"] for c in cases}
    for case in cases:
        for key in PEAKS:
            got = _library_figures(folder, case, key)
            for name, value in case[key].items():
                assert got[name] == pytest.approx(value, rel=RELATIVE, abs=1e-12), f"{case['name']} {key} {name}"


def test_synthetic_golden_cases_are_shipped():
    """The shipped set covers what it is for: duplicate points in a result and unoriented normals."""
    _, cases = _golden(SYNTHETIC)
    assert {"ellipsoid_holes", "ellipsoid_jitter", "ellipsoid_filled_dups", "ellipsoid_holes_unoriented",
            "ellipsoid_filled_dups_unoriented"} == {c["name"] for c in cases}
    dups = read_ply(SYNTHETIC / "ellipsoid_filled_dups.ply").points
    assert len(metrics.pairs.first_occurrences(dups)) < len(dups)
    oriented = read_ply(SYNTHETIC / "ellipsoid_ref.ply")
    unoriented = read_ply(SYNTHETIC / "ellipsoid_ref_unoriented.ply")
    dots = (oriented.normals * unoriented.normals).sum(axis=1)
    assert 0.3 < (dots < 0).mean() < 0.7  # about half flipped, the same directions otherwise
    assert abs(abs(dots) - 1).max() < 1e-6
    # pc_error averages the normals it carries onto the result, so flipped ones change D2
    by_name = {c["name"]: c for c in cases}
    assert by_name["ellipsoid_holes"]["r0"]["d2_mse"] != by_name["ellipsoid_holes_unoriented"]["r0"]["d2_mse"]


def test_library_reproduces_pc_error_on_synthetic_cases():
    _check_library(*_golden(SYNTHETIC))


def test_library_reproduces_pc_error(shared_dir):
    _check_library(*_golden(shared_dir / "golden"))


def _check_cli(folder: Path, case: dict, capsys) -> None:
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
        assert frame["hausdorff_psnr"] == pytest.approx(want["d1_hausdorff_psnr"], rel=RELATIVE, abs=1e-9)
        assert out["mean"]["gpsnr_d1"] == frame["gpsnr_d1"]
        assert out["settings"]["reference_normals"] == "given"


@pytest.mark.parametrize("case_name", ["ellipsoid_filled_dups", "ellipsoid_holes_unoriented"])
def test_cli_json_reproduces_pc_error_on_synthetic_cases(capsys, case_name):
    folder, cases = _golden(SYNTHETIC)
    _check_cli(folder, next(c for c in cases if c["name"] == case_name), capsys)


@pytest.mark.parametrize("case_name", ["punching_holes", "punching_vox_holes"])
def test_cli_json_reproduces_pc_error(shared_dir, capsys, case_name):
    folder, cases = _golden(shared_dir / "golden")
    _check_cli(folder, next(c for c in cases if c["name"] == case_name), capsys)
