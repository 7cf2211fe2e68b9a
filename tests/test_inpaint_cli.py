"""`dpcbench inpaint`: outputs, parameter parsing, and refusals with clear messages."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dpcbench.bench.cli import main
from dpcbench.bench.data.plyio import PointCloud, read_ply
from dpcbench.bench.data.sequences import load_sequence, save_sequence
from dpcbench.holes.regions import HoleRegion, regions_to_json
from tests.runner_fixtures import voxel_plane


@pytest.fixture
def damaged_dir(tmp_path):
    """Three voxel-plane frames on disk (with colours), a hole in the middle one, and its holes.json."""
    region = HoleRegion.ball([20.0, 20.0, 20.0], 6.0)
    frames = [voxel_plane(s) for s in (0, 1, 2)]
    frames[1] = frames[1][~region.contains(frames[1])]
    clouds = [PointCloud(f, np.full((len(f), 3), 7 * k, dtype=np.uint8)) for k, f in enumerate(frames)]
    folder = tmp_path / "damaged"
    save_sequence(clouds, folder, prefix="plane")
    holes = tmp_path / "holes.json"
    holes.write_text(json.dumps(regions_to_json([[], [region], []])))
    return folder, holes, frames, region


FAST = ["--param", "cube_size=12", "--param", "min_known_points=12"]


def test_inpaint_writes_filled_frames_and_a_record(damaged_dir, tmp_path):
    folder, holes, frames, region = damaged_dir
    out = tmp_path / "out"
    code = main(["inpaint", str(folder), "--method", "fu-nonlocal", *FAST, "--param", "known_points=fixed",
                 "--regions", str(holes), "--out", str(out)])
    assert code == 0
    result = load_sequence(out)
    assert len(result) == 3
    np.testing.assert_array_equal(result.points[0], frames[0])
    filled = result.points[1]
    assert len(filled) > len(frames[1])
    new = filled[len(frames[1]):]
    assert region.contains(new).all() and np.all(new[:, 2] == 20)
    # colours carried from the nearest input point
    assert read_ply(sorted(out.glob("*.ply"))[1]).colors is not None
    record = json.loads((out / "inpaint.json").read_text())
    assert record["method"] == "fu-nonlocal" and record["protocol"] == "regions"
    # values parsed as JSON when they parse (numbers), else kept as text
    assert record["params"]["cube_size"] == 12 and record["params"]["known_points"] == "fixed"
    assert record["points"][1] == len(filled)
    # the input folder is untouched
    np.testing.assert_array_equal(load_sequence(folder).points[1], frames[1])


def test_inpaint_temporal_graph_and_blind_none(damaged_dir, tmp_path):
    folder, holes, frames, _ = damaged_dir
    assert main(["inpaint", str(folder), "--method", "temporal-graph", *FAST, "--param", "beta=0.5",
                 "--regions", str(holes), "--out", str(tmp_path / "tg")]) == 0
    assert len(load_sequence(tmp_path / "tg").points[1]) > len(frames[1])
    assert main(["inpaint", str(folder), "--method", "none", "--out", str(tmp_path / "blind")]) == 0
    record = json.loads((tmp_path / "blind" / "inpaint.json").read_text())
    assert record["protocol"] == "blind"


@pytest.mark.parametrize("extra, message", [
    (["--method", "no-such-method"], "unknown method 'no-such-method'"),
    (["--method", "fu-nonlocal", "--param", "gamma_ray=3"], "unknown parameter(s) gamma_ray"),
    (["--method", "fu-nonlocal", "--param", "cube_size=-1"], "cube_size must be a positive number"),
    (["--method", "fu-nonlocal", "--param", "novalue"], "expected KEY=VALUE"),
])
def test_bad_method_or_parameter_is_a_clear_error(damaged_dir, tmp_path, capsys, extra, message):
    folder, holes, _, _ = damaged_dir
    code = main(["inpaint", str(folder), *extra, "--regions", str(holes), "--out", str(tmp_path / "o")])
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_refuses_to_write_into_the_input(damaged_dir, capsys):
    folder, holes, _, _ = damaged_dir
    for out in (folder, folder / "sub"):
        code = main(["inpaint", str(folder), "--method", "none", "--regions", str(holes), "--out", str(out)])
        assert code == 2
        assert "never overwritten" in capsys.readouterr().err
    assert not (folder / "sub").exists()
    assert not (folder / "inpaint.json").exists()


def test_regions_that_do_not_match_the_input_are_refused(damaged_dir, tmp_path, capsys):
    folder, _, _, _ = damaged_dir
    short = tmp_path / "short.json"
    short.write_text(json.dumps(regions_to_json([[], []])))
    code = main(["inpaint", str(folder), "--method", "none", "--regions", str(short), "--out", str(tmp_path / "o")])
    assert code == 2 and "describes 2 frame(s)" in capsys.readouterr().err
    far = tmp_path / "far.json"
    far.write_text(json.dumps(regions_to_json([[], [HoleRegion.ball([900.0, 900.0, 900.0], 3.0)], []])))
    code = main(["inpaint", str(folder), "--method", "fu-nonlocal", *FAST, "--regions", str(far),
                 "--out", str(tmp_path / "o2")])
    assert code == 2 and "do not belong to this cloud" in capsys.readouterr().err
    code = main(["inpaint", str(folder), "--method", "none", "--regions", str(tmp_path / "missing.json"),
                 "--out", str(tmp_path / "o3")])
    assert code == 2 and "no such holes file" in capsys.readouterr().err


def test_embedded_dataset_name_as_input(tmp_path):
    code = main(["inpaint", "human", "--dataset-param", "size=tiny", "--frames", "2", "--method", "none",
                 "--out", str(tmp_path / "human")])
    assert code == 0
    assert len(load_sequence(tmp_path / "human")) == 2
