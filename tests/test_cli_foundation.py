"""The foundation's CLI commands (list, generate, info, render) driven through bench.cli.main, the bad
inputs a user can give them, and one run of the installed `dpcbench` entry point."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dpcbench.bench.cli import main
from dpcbench.bench.data.plyio import PointCloud, read_ply, write_ply


@pytest.fixture(autouse=True)
def quiet_private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    monkeypatch.delenv("DPCBENCH_DATA_DIR", raising=False)


def cloud(n=300, seed=0, colors=True) -> PointCloud:
    rng = np.random.default_rng(seed)
    return PointCloud(rng.uniform(0, 100, size=(n, 3)),
                      rng.integers(0, 256, (n, 3)).astype(np.uint8) if colors else None)


def run_cli(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_list_shows_every_section(capsys):
    code, out, _ = run_cli(["list"], capsys)
    assert code == 0
    for section in ("sequences:", "hole generators:", "methods:", "metrics:"):
        assert section in out
    assert "human" in out and "bunny" in out and "longdress" in out and "unavailable: no data folder" in out
    code, out, _ = run_cli(["list", "--json"], capsys)
    data = json.loads(out)
    assert {r["name"] for r in data["sequences"]} >= {"human", "bunny", "soldier", "ulliwegner"}


def test_list_reports_a_broken_entry_instead_of_crashing(capsys, monkeypatch):
    from dpcbench.holes import registry as hole_registry
    from dpcbench.methods import registry as method_registry

    monkeypatch.setitem(hole_registry.GENERATORS, "broken-holes", "holes.no_such_module:Nothing")
    monkeypatch.setitem(method_registry.METHODS, "broken-method", "methods.no_such_module:Nothing")
    code, out, _ = run_cli(["list"], capsys)
    assert code == 0
    lines = {line.split()[0]: line for line in out.splitlines() if line.startswith("  ")}
    assert "unavailable: ModuleNotFoundError" in lines["broken-holes"]
    assert "unavailable: ModuleNotFoundError" in lines["broken-method"]


def test_generate_default_human_is_10_bit_and_large(tmp_path, capsys):
    code, out, _ = run_cli(["generate", "human", "--frames", "1", "--out", tmp_path / "h"], capsys)
    assert code == 0 and "wrote 1 frames" in out
    frame = read_ply(tmp_path / "h" / "human_0000.ply")
    assert len(frame) >= 300_000
    assert np.array_equal(frame.points, np.round(frame.points))
    assert frame.points.min() >= 0 and frame.points.max() <= 1023 and frame.colors is not None


def test_generate_writes_ply_frames_re_voxelized_on_a_coarser_grid(tmp_path, capsys):
    """`generate FOLDER --param voxel_size=2` writes the frames as `coarsen_voxels` makes them (the one thing to
    make from PLY frames: without it the folder is refused, as before)."""
    from dpcbench.bench.data.plyio import PointCloud, write_ply
    from dpcbench.bench.data.sequences import coarsen_voxels

    rng = np.random.default_rng(0)
    frames = [PointCloud(rng.integers(0, 1024, size=(500, 3)).astype(np.float64),
                         rng.integers(0, 256, size=(500, 3)).astype(np.uint8)) for _ in range(2)]
    for i, frame in enumerate(frames):
        write_ply(tmp_path / "vox10" / f"f_{i}.ply", frame)
    code, out, _ = run_cli(["generate", tmp_path / "vox10", "--param", "voxel_size=2", "--out", tmp_path / "vox9"],
                           capsys)
    assert code == 0 and "wrote 2 frames" in out and "9-bit integer coordinates" in out
    for frame, path in zip(frames, sorted((tmp_path / "vox9").glob("*.ply"))):
        expected, written = coarsen_voxels(frame, 2), read_ply(path)
        np.testing.assert_array_equal(written.points, expected.points)
        np.testing.assert_array_equal(written.colors, expected.colors)
    code, _, err = run_cli(["generate", tmp_path / "vox10", "--out", tmp_path / "copy"], capsys)
    assert code == 2 and "voxel_size=K" in err and not (tmp_path / "copy").exists()


def test_generate_info_render_round_trip(tmp_path, capsys):
    out_dir = tmp_path / "bunny"
    code, _, _ = run_cli(["generate", "bunny", "--frames", "3", "--out", out_dir, "--param", "size=tiny",
                          "--param", "bit_depth=9"], capsys)
    assert code == 0
    files = sorted(out_dir.glob("*.ply"))
    assert [f.name for f in files] == ["bunny_0000.ply", "bunny_0001.ply", "bunny_0002.ply"]
    code, out, _ = run_cli(["info", out_dir, "--json"], capsys)
    info = json.loads(out)
    assert code == 0 and info["frames"] == 3 and info["bit_depth"] == 9 and info["colors"] and info["normals"]
    assert info["points_per_frame"] == [len(read_ply(f)) for f in files]
    assert info["median_spacing_frame0"] == 1.0
    code, out, _ = run_cli(["info", "human", "--frames", "1", "--param", "size=tiny"], capsys)
    assert code == 0 and "10-bit integer coordinates (0..1023)" in out and "colours yes, normals yes" in out
    png = tmp_path / "fig.png"
    code, out, _ = run_cli(["render", out_dir, "--out", png, "--frames", "0,2", "--zoom", "200,100,200,300,200,300",
                            "--view", "left"], capsys)
    assert code == 0 and png.stat().st_size > 1000
    code, _, _ = run_cli(["render", "human", "--param", "size=tiny", "--frames", "1", "--out", tmp_path / "h.png",
                          "--view", "30,10", "--shading", "normal"], capsys)
    assert code == 0 and (tmp_path / "h.png").is_file()


def truncated(path: Path) -> Path:
    write_ply(path, cloud(500))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) - 2000])
    return path


def bad_inputs(root: Path) -> dict[str, tuple[list, list[str]]]:
    """case -> (argv, substrings the error message must contain)."""
    (root / "empty_folder").mkdir()
    (root / "empty_folder" / "notes.txt").write_text("no frames here")
    truncated(root / "trunc.ply")
    (root / "garbage.ply").write_bytes(b"this is not a ply file at all\n" * 10)
    write_ply(root / "zero.ply", PointCloud(np.empty((0, 3)), np.empty((0, 3), np.uint8)))
    nan = cloud(50)
    nan.points[7, 1] = np.nan
    write_ply(root / "nan.ply", nan)
    inf = cloud(50)
    inf.points[3, 0] = np.inf
    write_ply(root / "inf.ply", inf)
    write_ply(root / "mixed" / "f_0.ply", cloud(50, colors=True))
    write_ply(root / "mixed" / "f_1.ply", cloud(50, colors=False))
    return {
        "missing folder": (["info", root / "no_such_folder"], ["no_such_folder", "no such file or folder"]),
        "no ply": (["info", root / "empty_folder"], ["empty_folder", "no .ply file"]),
        "truncated": (["info", root / "trunc.ply"], ["trunc.ply", "cannot parse PLY"]),
        "corrupt": (["render", root / "garbage.ply", "--out", root / "x.png"], ["garbage.ply", "cannot parse PLY"]),
        "zero points": (["info", root / "zero.ply"], ["zero.ply", "zero points"]),
        "nan": (["info", root / "nan.ply"], ["nan.ply", "NaN or infinite", "index 7"]),
        "inf": (["render", root / "inf.ply", "--out", root / "x.png"], ["inf.ply", "NaN or infinite"]),
        "mismatched": (["info", root / "mixed"], ["f_1.ply", "mismatched attributes", "colors"]),
        "unknown name": (["info", "longdres"], ["longdres", "Known names"]),
        "render unknown name": (["render", "longdres", "--out", root / "x.png"], ["longdres", "Known names"]),
        "generate unknown": (["generate", "dragon", "--out", root / "g"], ["dragon", "human, bunny"]),
        "generate paper": (["generate", "soldier", "--out", root / "g"], ["soldier", "--data-dir"]),
        "paper no data": (["info", "soldier"], ["Soldier", "plenodb.jpeg.org", "soldier_vox10_0536.ply"]),
        "bad param": (["generate", "human", "--out", root / "g", "--param", "size"], ["KEY=VALUE"]),
        "unknown param": (["info", "human", "--param", "colour=red"], ["colour", "accepted"]),
        "bad value": (["generate", "human", "--out", root / "g", "--param", "motion=fly"], ["fly", "walk"]),
        "bad frames": (["render", "human", "--frames", "x", "--out", root / "x.png"], ["--frames"]),
        "bad zoom": (["render", "human", "--zoom", "1,2,3", "--out", root / "x.png"], ["--zoom", "6 numbers"]),
        "bad view": (["render", "human", "--view", "sideways", "--out", root / "x.png"], ["--view"]),
        "not png": (["render", "human", "--out", root / "x.jpg"], ["x.jpg", ".png"]),
        "frame out of range": (["info", root / "mixed", "--frames", "5"], ["has 2 frames"]),
    }


def test_every_bad_input_is_a_clear_error(tmp_path, capsys):
    for case, (argv, needles) in bad_inputs(tmp_path).items():
        code, out, err = run_cli(argv, capsys)
        assert code == 2, f"{case}: exit code {code}, stderr {err!r}"
        assert "Traceback" not in err and err.startswith(f"dpcbench {argv[0]}: error:"), f"{case}: {err!r}"
        for needle in needles:
            assert needle in err, f"{case}: {needle!r} not in {err!r}"


def test_installed_entry_point(tmp_path):
    exe = Path(sys.executable).parent / "dpcbench"
    assert exe.is_file(), "the dpcbench console script is not installed in this environment"
    write_ply(tmp_path / "seq" / "a_1.ply", cloud(40, seed=1))
    write_ply(tmp_path / "seq" / "a_2.ply", cloud(60, seed=2))
    env = {**os.environ, "DPCBENCH_QUIET": "1"}
    ok = subprocess.run([str(exe), "info", str(tmp_path / "seq")], capture_output=True, text=True, env=env)
    assert ok.returncode == 0 and "frames:      2" in ok.stdout and "40..60 per frame" in ok.stdout
    bad = subprocess.run([str(exe), "info", str(tmp_path / "nothing")], capture_output=True, text=True, env=env)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and "nothing" in bad.stderr
