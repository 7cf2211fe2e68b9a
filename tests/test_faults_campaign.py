"""Issue 51's classes of faults, one test each: writes that escape --out or mix two outputs, lost
precision, ground truth replaced, store paths in SQLite URIs, accepted values that give wrong numbers,
crashes on hostile files and configs, Dask without workers. Each asserts the defined result: a one-line
error (exit 2) with nothing changed outside --out, or the exact output."""

from __future__ import annotations

import json
import os
import sqlite3
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import plyfile
import pytest
import test_errors
from test_errors import assert_refused, run_cli, sphere, tree_hashes

from dpcbench.bench.core.errors import UserError

work = test_errors.work  # the workspace fixture: seq/ (3 frames of 800 points), holes.json


def _damage(out, capsys, *extra, seed=0):
    code, _, err = run_cli(["damage", "seq", "--holes", "region", "--seed", seed, "--out", out, *extra], capsys)
    return code, err


# -- 1. writes never escape the output folder -------------------------------------------------
def test_a_link_planted_in_out_is_never_written_through(work, capsys):
    before = tree_hashes(work / "seq")
    (work / "out").mkdir()
    (work / "out" / "masks.npz").symlink_to(work / "seq" / "s_0001.ply")
    code, err = _damage("out", capsys, "--overwrite")
    assert_refused(code, err, "damage", "symbolic link", "outside the output folder")
    assert tree_hashes(work / "seq") == before  # the input frame is still a PLY, not a zip
    # a link that stays inside the output folder is allowed
    (work / "out" / "masks.npz").unlink()
    (work / "out" / "keep").mkdir()
    (work / "out" / "inner").symlink_to(work / "out" / "keep")
    code, err = _damage("out", capsys)
    assert code == 0, err
    assert (work / "out" / "inner").is_symlink() and tree_hashes(work / "seq") == before


def test_a_staged_output_refuses_a_linked_subfolder_leading_out(tmp_path):
    from dpcbench.bench.data.outputs import Outputs

    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "R").mkdir()
    (tmp_path / "R" / "figures").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(UserError, match="figures is a symbolic link"):
        with Outputs().staged(tmp_path / "R") as stage:
            (stage / "figures").mkdir()
            (stage / "figures" / "f.png").write_bytes(b"png")
    assert list((tmp_path / "elsewhere").iterdir()) == []
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no stage, no lock left


def test_a_detect_holes_link_out_of_its_folder_is_refused(work, capsys):
    (work / "d").mkdir()
    (work / "d" / "h.json").symlink_to(work / "holes.json")
    before = tree_hashes(work, skip=work / "d")
    code, _, err = run_cli(["detect-holes", "seq", "--out", "d/h.json"], capsys)
    assert_refused(code, err, "detect-holes", "symbolic link")
    assert tree_hashes(work, skip=work / "d") == before


# -- 2. an output appears whole, once; one writer at a time; readers skip temporary files --------
def test_a_staged_output_appears_whole_and_keeps_the_old_until_complete(tmp_path):
    from dpcbench.bench.data.outputs import Outputs

    out = tmp_path / "o"
    with Outputs().staged(out) as stage:
        (stage / "a.txt").write_text("old a")
        (stage / "b.txt").write_text("old b")
    with pytest.raises(RuntimeError):
        with Outputs().staged(out) as stage:
            (stage / "a.txt").write_text("new a")
            assert (out / "a.txt").read_text() == "old a"  # untouched while the new one is written
            raise RuntimeError("killed half-way")
    assert (out / "a.txt").read_text() == "old a"
    with Outputs().staged(out) as stage:
        (stage / "a.txt").write_text("new a")
    assert (out / "a.txt").read_text() == "new a" and (out / "b.txt").read_text() == "old b"  # others kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


def test_a_second_writer_of_one_output_is_refused_and_stale_stages_are_removed(tmp_path):
    from dpcbench.bench.core.atomic import STAGE_TAG
    from dpcbench.bench.data.outputs import Outputs

    out = tmp_path / "o"
    stale = tmp_path / f".o{STAGE_TAG}999999-deadbeef"  # a killed writer's staging folder
    stale.mkdir(parents=True)
    (stale / "x.ply").write_text("half")
    with Outputs().staged(out) as stage:
        assert not stale.exists()
        with pytest.raises(UserError, match="another dpcbench command"):
            with Outputs().staged(out):
                pass
        (stage / "x.txt").write_text("one")
    assert (out / "x.txt").read_text() == "one"
    # a killed writer's stage of another output in the same folder is removed too; a live one is kept
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    other_dead = tmp_path / f".p{STAGE_TAG}{int(dead.stdout)}-cafe0000"
    other_live = tmp_path / f".q{STAGE_TAG}{os.getpid()}-cafe0001"
    other_dead.mkdir()
    other_live.mkdir()
    with Outputs().staged(out) as stage:
        (stage / "x.txt").write_text("two")
    assert not other_dead.exists() and other_live.exists()


def test_concurrent_damage_into_one_out_never_replaces_ground_truth(work, capsys):
    assert _damage("out", capsys)[0] == 0
    truth = tree_hashes(work / "out")
    code, err = _damage("out", capsys, seed=5)  # the second, finishing after the first
    assert_refused(code, err, "damage", "holes.json")
    assert tree_hashes(work / "out") == truth


def test_readers_skip_hidden_and_temporary_frames(work, capsys):
    from dpcbench.bench.data.sequences import list_frame_files

    (work / "seq" / ".s_0005.x1y2.tmp.ply").write_bytes((work / "seq" / "s_0000.ply").read_bytes())
    (work / "seq" / "s_0006.ply.tmp.ply").write_bytes(b"ply\nhalf")
    assert [p.name for p in list_frame_files(work / "seq")] == ["s_0000.ply", "s_0001.ply", "s_0002.ply"]
    (work / "out").mkdir()
    (work / "out" / ".seq_0007.k9.tmp.ply").write_bytes(b"ply\nhalf")  # a killed writer's leftover in --out
    code, err = _damage("out", capsys)
    assert code == 0, err
    assert [p.name for p in list_frame_files(work / "out")] == [f"seq_{f:04d}.ply" for f in range(3)]


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_files_get_the_mode_the_umask_gives(tmp_path, umask):
    from dpcbench.bench.core.atomic import atomic_write_text

    old = os.umask(umask)
    try:
        path = atomic_write_text(tmp_path / "f.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


# -- 3. precision ------------------------------------------------------------------------------
def _write_double(path: Path, pts: np.ndarray) -> None:
    table = np.empty(len(pts), dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8")])
    table["x"], table["y"], table["z"] = pts.T
    path.parent.mkdir(parents=True, exist_ok=True)
    plyfile.PlyData([plyfile.PlyElement.describe(table, "vertex")]).write(str(path))


def test_double_coordinates_stay_double_through_damage(work, capsys):
    from dpcbench.bench.data.plyio import read_ply

    frames = [sphere(800, f) * 0.01 + np.array([5e5, 4.5e6, 100.0]) for f in range(2)]  # georeferenced, 1 cm
    for f, pts in enumerate(frames):
        _write_double(work / "geo" / f"g_{f:04d}.ply", pts)
    code, _, err = run_cli(["damage", "geo", "--holes", "region", "--out", "gd"], capsys)
    assert code == 0, err
    masks = np.load(work / "gd" / "masks.npz")
    for f, pts in enumerate(frames):
        back = read_ply(work / "gd" / f"geo_{f:04d}.ply")
        assert back.precision == "float64"
        np.testing.assert_array_equal(back.points, pts[~masks[f"frame_{f:04d}"]])  # bit for bit
    # float32 input is written as float32, as before
    code, _, err = run_cli(["damage", "seq", "--holes", "region", "--out", "sd"], capsys)
    assert b"property float x" in (work / "sd" / "seq_0000.ply").read_bytes()[:200]


# -- 4. ground truth ---------------------------------------------------------------------------
def test_ground_truth_is_never_replaced_without_overwrite(work, capsys):
    assert _damage("d", capsys)[0] == 0
    truth = tree_hashes(work / "d")
    (work / "d2").mkdir()
    code, _, err = run_cli(["damage", "seq", "--holes", "region", "--out", "d2"], capsys)
    (work / "d2" / "seq_0001.ply").rename(work / "d2" / "other.ply")  # frames renamed: the generic rules pass
    truth2 = tree_hashes(work / "d2")
    for argv in (["detect-holes", "seq", "--out", "d/holes.json"],
                 ["compare", "--store", "missing.sqlite", "--save-current", "d/holes.json"],
                 ["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", "d"],
                 ["damage", "seq", "--holes", "region", "--out", "d2", "--frames", "1"]):
        code, _, err = run_cli(argv, capsys)
        assert code == 2, (argv, err)
        assert "damage output" in err or "holes.json" in err, (argv, err)
        assert tree_hashes(work / "d") == truth and tree_hashes(work / "d2") == truth2, argv
    code, _, err = run_cli(["detect-holes", "seq", "--out", "d/holes.json"], capsys)
    assert_refused(code, err, "detect-holes", "damage output")
    code, _, err = run_cli(["detect-holes", "seq", "--out", "d/holes.json", "--overwrite"], capsys)
    assert code == 0, err


# -- 5. store paths --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["r#1.sqlite", "a?b.sqlite", "p%41.sqlite", "sp ace é.sqlite"])
def test_store_paths_with_uri_characters_open_that_file(tmp_path, name):
    from dpcbench.bench.results.store import ResultsStore

    ResultsStore(tmp_path / name).add_to_experiment("e", ["r1"])
    store = ResultsStore(tmp_path / name, readonly=True, verify=True)
    assert store.experiments() == ["e"]
    # no other file (e.g. "r", the name cut at '#') created; SQLite's -wal/-shm beside the store only
    assert {p.name for p in tmp_path.iterdir()} <= {name, f"{name}-wal", f"{name}-shm"}


def test_a_store_without_experiment_runs_is_one_line(tmp_path):
    from dpcbench.bench.results.store import ResultsStore

    ResultsStore(tmp_path / "s.sqlite").add_to_experiment("e", ["r1"])
    with sqlite3.connect(tmp_path / "s.sqlite") as conn:
        conn.execute("DROP TABLE experiment_runs")
    with pytest.raises(UserError, match="experiment_runs"):
        ResultsStore(tmp_path / "s.sqlite", readonly=True)


def test_a_healthy_store_in_a_read_only_folder_is_read_immutable(tmp_path, monkeypatch):
    from dpcbench.bench.results import store as store_mod

    store_mod.ResultsStore(tmp_path / "s.sqlite").add_to_experiment("e", ["r1"])
    for side in ("-wal", "-shm"):
        Path(f"{tmp_path / 's.sqlite'}{side}").unlink(missing_ok=True)
    real = sqlite3.connect
    uris = []

    def connect(database, *args, **kwargs):  # what SQLite does where it cannot create the -shm file
        uris.append(database)
        if "immutable=1" not in str(database):
            raise sqlite3.OperationalError("unable to open database file")
        return real(database, *args, **kwargs)

    monkeypatch.setattr(store_mod.sqlite3, "connect", connect)
    monkeypatch.setattr(store_mod.os, "access", lambda path, mode: False)
    assert store_mod.ResultsStore(tmp_path / "s.sqlite", readonly=True, verify=True).experiments() == ["e"]
    assert any("immutable=1" in u for u in uris)


# -- 6. region values, frames, coordinates, peaks --------------------------------------------------
@pytest.mark.parametrize("region", [
    {"shape": "ball", "center": [50, 50, 50], "radius": float("inf")},
    {"shape": "ball", "center": [50, 50, 50], "radius": 1e300},
    {"shape": "ball", "center": [1e30, 0, 0], "radius": 1},
    {"shape": "box", "center": [50, 50, 50], "half_extents": [5, 5, 5], "rotation": [[0] * 3] * 3},
    {"shape": "box", "center": [50, 50, 50], "half_extents": [5, 5, 5], "rotation": [[2, 0, 0], [0, 1, 0], [0, 0, 1]]},
    {"shape": "box", "center": [50, 50, 50], "half_extents": [5, float("inf"), 5]},
])
def test_region_values_that_give_wrong_numbers_are_refused(work, capsys, region):
    record = json.loads((work / "holes.json").read_text())
    record["frames"][1]["regions"] = [region]
    (work / "bad.json").write_text(json.dumps(record))
    code, _, err = run_cli(["inpaint", "seq", "--method", "temporal-copy", "--regions", "bad.json", "--out", "o"],
                           capsys)
    assert_refused(code, err, "inpaint", "frames[1].regions[0]")
    assert not (work / "o").exists()


def test_holes_json_used_on_other_frames_is_refused(work, capsys):
    for f in range(3, 6):
        (work / "seq" / f"s_{f:04d}.ply").write_bytes((work / "seq" / f"s_{f - 3:04d}.ply").read_bytes())
    code, _, err = run_cli(["damage", "seq", "--frames", "0-2", "--holes", "region", "--out", "d"], capsys)
    assert code == 0, err
    assert json.loads((work / "d" / "holes.json").read_text())["input_files"] == [f"s_{f:04d}.ply" for f in range(3)]
    code, _, err = run_cli(["score", "seq", "seq", "--region", "d/holes.json"], capsys)
    assert code == 2  # 6 frames for 3
    code, _, err = run_cli(["inpaint", "seq", "--frames", "2,1,0", "--method", "none", "--regions", "d/holes.json",
                            "--out", "o"], capsys)
    assert_refused(code, err, "inpaint", "increasing order")
    code, _, err = run_cli(["inpaint", "seq", "--frames", "3-5", "--method", "none", "--regions", "d/holes.json",
                            "--out", "o"], capsys)
    assert_refused(code, err, "inpaint", "made for the frames s_0000.ply")


def test_frames_of_a_standin_are_bounded(work, capsys):
    code, _, err = run_cli(["damage", "human", "--frames", "99999999", "--holes", "region", "--out", "o"], capsys)
    assert_refused(code, err, "damage", "at most 1000")


def test_coordinates_beyond_the_limit_and_huge_peaks_are_refused(work, capsys):
    _write_double(work / "huge" / "h_0000.ply", sphere(300, 0) * 1e27 + 1e30)
    code, _, err = run_cli(["score", "huge", "huge"], capsys)
    assert_refused(code, err, "score", "beyond")
    code, _, err = run_cli(["score", "seq", "seq", "--peak", "1e200"], capsys)
    assert_refused(code, err, "score", "--peak")


# -- 8 and 11. values refused at config parse, crashes -------------------------------------------
CONFIG = """[experiment]
name = "e"
{experiment}
[[sequences]]
name = "human"
frames = 2
params = {{ size = "tiny" }}
[[holes]]
generator = "region"
seeds = {seeds}
[[methods]]
name = "{method}"
{method_params}
[metrics]
{metrics}
"""


@pytest.mark.parametrize("change,needle", [
    ({"seeds": "[-1]"}, "seeds"),
    ({"metrics": "peaks = [inf]"}, "peaks"),
    ({"metrics": "region_margin = nan"}, "region_margin"),
    ({"experiment": "timeout_s = nan"}, "timeout_s"),
    ({"method": "meshlab", "method_params": "params = { poisson_depth = 2.5 }"}, "poisson_depth"),
    ({"method": "temporal-graph", "method_params": "params = { k_neighbors = inf }"}, "k_neighbors"),
])
def test_values_that_used_to_pass_the_dry_run_are_refused(tmp_path, change, needle):
    import tomllib

    from dpcbench.bench.experiment.config import ConfigError, parse_config

    fields = {"experiment": "", "seeds": "[0]", "method": "none", "method_params": "", "metrics": "", **change}
    with pytest.raises(ConfigError, match=needle):
        parse_config(tomllib.loads(CONFIG.format(**fields)))


def test_a_symlink_loop_reached_through_a_config_is_one_line(work, capsys):
    (work / "loop").symlink_to(work / "loop")
    (work / "c.toml").write_text('[experiment]\nname = "e"\n[[sequences]]\npath = "loop"\n[[holes]]\n'
                                 'generator = "region"\n[[methods]]\nname = "none"\n')
    code, _, err = run_cli(["run", "c.toml", "--dry-run"], capsys)
    assert_refused(code, err, "run", "loop")
    code, _, err = run_cli(["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", "loop"], capsys)
    assert_refused(code, err, "inpaint", "loop")


def test_an_obj_face_past_the_vertex_list_is_refused_before_pymeshlab(tmp_path):
    from dpcbench.bench.data.meshseq import read_mesh

    good = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf -4/1/1 -2//2 -1\n"
    (tmp_path / "good.obj").write_text(good)
    assert read_mesh(tmp_path / "good.obj")[1].tolist() == [[0, 1, 2], [0, 2, 3]]
    for bad in ("f 1 2 99\n", "f 0 1 2\n", "f -9 1 2\n", "f a b c\n"):
        (tmp_path / "bad.obj").write_text(good + bad)
        with pytest.raises(UserError, match="line 7: face index"):
            read_mesh(tmp_path / "bad.obj")


def test_a_full_disk_without_a_file_name_names_the_output(work, capsys, monkeypatch):
    import errno

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")  # zlib's and numpy's writes carry no name

    monkeypatch.setattr(np, "savez_compressed", full)
    code, err = _damage("out", capsys)
    assert_refused(code, err, "damage", "No space left on device", "out")
    assert not (work / "out").exists() or not any((work / "out").iterdir())


@pytest.mark.parametrize("address", ["tcp://host:99999", "http://h:1", "tcp://a b:1", ";rm -rf /", "tcp://"])
def test_malformed_scheduler_addresses_are_refused(address):
    from dpcbench.bench.execution.executors import make_executor

    with pytest.raises(UserError, match="not a Dask scheduler address"):
        make_executor("dask", 1, address)


def test_a_dask_scheduler_without_workers_is_an_error_and_leaves_no_marker(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    from dpcbench.bench.execution.executors import SHARED_MARKER_PREFIX, DaskExecutor

    monkeypatch.setenv("DPCBENCH_DASK_WORKER_WAIT_S", "1")
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        executor = DaskExecutor(1, cluster.scheduler_address)
        with pytest.raises(UserError, match="has no worker"):
            list(executor.execute([object()], tmp_path))
    assert not list(tmp_path.glob(f"{SHARED_MARKER_PREFIX}*"))


def test_a_bad_runs_dir_is_one_line(work, capsys):
    (work / "afile").write_text("x")
    code, _, err = run_cli(["run", "paper-quick", "--runs-dir", "afile/x", "--store", "s.sqlite"], capsys)
    assert_refused(code, err, "run", "--runs-dir")
