"""`dpcbench damage` and `dpcbench detect-holes`: files written, round trip, clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dpcbench.bench.cli import main
from dpcbench.bench.data.plyio import read_ply
from dpcbench.holes.regions import regions_from_json
from dpcbench.holes.registry import get_generator


@pytest.fixture(scope="module")
def human():
    from dpcbench.bench.data.datasets import load_dataset

    return load_dataset("human", frames=2, size="tiny", progress=False)


TINY = ["--frames", "2", "--dataset-param", "size=tiny"]


def test_damage_round_trip(tmp_path, human, monkeypatch):
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    out = tmp_path / "dmg"
    rc = main(["damage", "human", *TINY, "--holes", "region", "--param", "preset=medium",
               "--param", "coherent=true", "--seed", "5", "--out", str(out)])
    assert rc == 0
    record = json.loads((out / "holes.json").read_text())
    assert record["generator"] == "region" and record["seed"] == 5
    assert record["params"]["coherent"] is True and record["params"]["preset"] == "medium"
    masks = np.load(out / "masks.npz")
    assert sorted(masks.files) == ["frame_0000", "frame_0001"]
    expected = get_generator("region", preset="medium", coherent=True).damage(human.points, 5)
    regions = regions_from_json(out / "holes.json")
    for f, frame in enumerate(human.frames):
        mask = masks[f"frame_{f:04d}"]
        np.testing.assert_array_equal(mask, expected.removed[f])
        entry = record["frames"][f]
        damaged = read_ply(out / entry["file"])
        np.testing.assert_array_equal(damaged.points, frame.points[~mask])  # integer coords: exact in float32
        np.testing.assert_array_equal(damaged.colors, frame.colors[~mask])
        assert entry["removed"] == mask.sum() and entry["points"] == len(mask)
        assert record["removed_fraction"][f] == pytest.approx(mask.mean())
        assert [r.to_dict() for r in regions[f]] == [r.to_dict() for r in expected.regions[f]]

    # detect-holes on the damaged folder finds regions in the same format
    det = tmp_path / "det" / "holes.json"
    assert main(["detect-holes", str(out), "--out", str(det)]) == 0
    detected = regions_from_json(det)
    assert len(detected) == 2 and all(len(r) >= 1 for r in detected)
    assert json.loads(det.read_text())["frames"][0]["points"] == len(human.points[0]) - masks["frame_0000"].sum()


def test_damage_refuses_to_overwrite(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    args = ["damage", "human", *TINY, "--holes", "dropout", "--out", str(tmp_path)]
    assert main(args) == 0
    assert main(args) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(args + ["--overwrite", "--seed", "1"]) == 0


@pytest.mark.parametrize(
    "extra,message",
    [
        (["--holes", "nope"], "unknown hole generator 'nope'"),
        (["--holes", "region", "--param", "bogus=1"], "valid parameters: preset"),
        (["--holes", "region", "--param", "count=0"], "positive integer"),
        (["--holes", "region", "--param", "oops"], "KEY=VALUE"),
    ],
)
def test_damage_errors(tmp_path, capsys, extra, message):
    rc = main(["damage", "human", *TINY, "--out", str(tmp_path / "x"), *extra])
    assert rc == 2
    assert message in capsys.readouterr().err


def test_missing_input_is_a_clear_error(tmp_path, capsys):
    assert main(["damage", str(tmp_path / "nothing"), "--holes", "region", "--out", str(tmp_path / "x")]) == 2
    assert "no such file or folder" in capsys.readouterr().err
    assert main(["detect-holes", str(tmp_path / "nothing"), "--out", str(tmp_path / "h.json")]) == 2


def test_detect_holes_bad_parameter(tmp_path, capsys):
    assert main(["detect-holes", "human", *TINY, "--param", "radius=3", "--out", str(tmp_path / "h.json")]) == 2
    assert "unknown parameter(s) radius" in capsys.readouterr().err


def _red_pixels(png) -> int:
    import matplotlib.image

    from dpcbench.bench.reporting.render import HIGHLIGHT_COLOR

    rgb = (matplotlib.image.imread(png)[..., :3] * 255).round().astype(int)
    return int((np.abs(rgb - np.asarray(HIGHLIGHT_COLOR)).sum(-1) <= 3).sum())


def test_render_paints_the_holes(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    truth, out = tmp_path / "truth", tmp_path / "dmg"
    assert main(["generate", "human", "--frames", "2", "--param", "size=tiny", "--out", str(truth)]) == 0
    assert main(["damage", str(truth), "--holes", "region", "--param", "preset=large",
                 "--seed", "0", "--out", str(out)]) == 0
    plain, painted, rims = tmp_path / "plain.png", tmp_path / "holes.png", tmp_path / "rims.png"
    assert main(["render", str(truth), "--frames", "0,1", "--out", str(plain)]) == 0
    assert main(["render", str(truth), "--frames", "0,1", "--holes", str(out), "--out", str(painted)]) == 0
    assert _red_pixels(plain) == 0 and _red_pixels(painted) > 100
    # a holes.json paints the points inside the regions: on the ground truth, the removed ones
    assert main(["render", str(truth), "--frames", "1", "--holes", str(out / "holes.json"), "--out", str(rims)]) == 0
    assert _red_pixels(rims) > 50
    # masks of the ground truth do not fit the damaged frames: a clear error, no picture
    capsys.readouterr()
    assert main(["render", str(out), "--holes", str(out), "--out", str(tmp_path / "bad.png")]) == 2
    assert "render the ground truth" in capsys.readouterr().err
    assert not (tmp_path / "bad.png").exists()
    assert main(["render", str(truth), "--holes", str(tmp_path / "none"), "--out", str(tmp_path / "bad.png")]) == 2
