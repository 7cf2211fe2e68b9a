"""The Python API on what researchers hold: open3d point clouds, (N, 3) arrays of any float dtype
and lists of them, wherever a frame is accepted; results as numpy, and `to_open3d` back. Also runs
the Python examples of docs/adding-a-method.md, so the page stays true."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.registry import get_method
from dpcbench.metrics import score_frame, score_sequence
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.points import as_points, to_open3d
from dpcbench.testing import sample_sequence

REPO = Path(__file__).resolve().parents[1]


def test_a_method_takes_open3d_clouds_and_float32_arrays_and_returns_the_same_numpy_frames():
    frames, regions = sample_sequence()
    expected = get_method("temporal-copy").inpaint(frames, regions)
    clouds = [o3d.geometry.PointCloud(o3d.utility.Vector3dVector(f)) for f in frames]
    from_clouds = get_method("temporal-copy").inpaint(clouds, regions)
    for a, b in zip(expected, from_clouds):
        assert isinstance(b, np.ndarray) and b.dtype == np.float64
        np.testing.assert_array_equal(a, b)
    # float32 frames: the method sees their float64 values
    as32 = [f.astype(np.float32) for f in frames]
    from32 = get_method("temporal-copy").inpaint(as32, regions)
    again = get_method("temporal-copy").inpaint([f.astype(np.float64) for f in as32], regions)
    for a, b in zip(from32, again):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(UserError, match=r"got one array; wrap it: \[frame\]"):
        get_method("none").inpaint(clouds[0], None)


def test_scores_of_open3d_clouds_and_float32_arrays_equal_those_of_float64_arrays():
    rng = np.random.default_rng(4)
    reference = rng.random((400, 3)) * 100
    result = (reference[:350] + rng.normal(scale=0.2, size=(350, 3))).astype(np.float32)
    expected = score_frame(reference, result.astype(np.float64))
    assert score_frame(to_open3d(reference), to_open3d(result)) == expected
    assert score_frame(reference.tolist(), result) == expected
    region = [HoleRegion.ball(reference[0], 20.0)]
    seq = score_sequence([to_open3d(reference)] * 2, [result, to_open3d(result)], ["gpsnr_d1", "temporal_consistency"],
                         regions=[region, region])
    ref = score_sequence([reference] * 2, [result.astype(np.float64)] * 2, ["gpsnr_d1", "temporal_consistency"],
                         regions=[region, region])
    assert seq == ref


def test_to_open3d_round_trips_a_frame_and_a_list():
    frame = np.arange(12, dtype=np.float64).reshape(4, 3)
    cloud = to_open3d(frame)
    assert isinstance(cloud, o3d.geometry.PointCloud)
    np.testing.assert_array_equal(np.asarray(cloud.points), frame)
    clouds = to_open3d([frame, frame[:2]])
    assert [len(c.points) for c in clouds] == [4, 2]
    np.testing.assert_array_equal(as_points(clouds[1]), frame[:2])
    with pytest.raises(ValueError, match=r"must be an \(N, 3\) array, got shape \(4, 2\)"):
        to_open3d(frame[:, :2])


def _python_blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), flags=re.S)


def test_the_python_examples_of_adding_a_method_run(tmp_path, monkeypatch):
    """Every ```python block of docs/adding-a-method.md, in order, in one namespace, from a scratch
    folder with the example plug-in importable (as when it is installed)."""
    blocks = _python_blocks(REPO / "docs" / "adding-a-method.md")
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(REPO / "examples" / "dpcbench-example-plugin" / "src"))
    namespace: dict = {"__name__": "docs_example"}
    for block in blocks:
        exec(compile(block, "docs/adding-a-method.md", "exec"), namespace)


# -- housekeeping a release needs ------------------------------------------------------------------
def test_one_version_for_the_package_the_cli_and_the_citation(capsys):
    import sys

    from dpcbench.bench import __version__
    from dpcbench.bench.cli import main
    from dpcbench.bench.execution.provenance import package_versions

    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    declared = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.strip() == f"dpcbench {declared}"
    assert __version__ == declared and package_versions(["dpcbench"])["dpcbench"] == declared  # run records' env
    citation = (REPO / "CITATION.cff").read_text()
    assert re.search(rf'^version: "{re.escape(declared)}"$', citation, flags=re.M)
    assert "arXiv:1904.10795" in citation and "3D Dynamic Point Cloud Inpainting via Temporal Consistency" in citation


def test_license_and_type_markers_ship():
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert project["project"]["license"] == "MIT"
    assert (REPO / "LICENSE").read_text().startswith("MIT License")
    package_data = project["tool"]["setuptools"]["package-data"]
    for package, folder in project["tool"]["setuptools"]["package-dir"].items():
        assert (REPO / folder / "py.typed").is_file(), folder
        assert "py.typed" in package_data.get(package, []), package
    assert (REPO / "CHANGELOG.md").read_text().startswith("# Changelog")
