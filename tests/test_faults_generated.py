"""Generated hostile input, from a seeded generator (each case is reproducible from its seed):

- paths with ``#``, ``?``, ``%``, spaces, quotes, glob characters and non-ASCII letters, through
  damage -> inpaint -> score and as results stores;
- symbolic links planted in and around ``--out`` (to the input, inside the output, dangling);
- hole region values (finite or not, in range or not, rotations orthonormal or not), checked against
  an independent rule and, for the accepted boxes, against a brute-force containment (Delaunay);
- corrupt PLY headers and bodies (counts, types, truncations, garbage);
- kills (SIGKILL, SIGTERM, SIGINT) of ``damage --overwrite`` and ``inpaint`` at random moments.

The rule every case must keep: a defined result, or a one-line error with exit 2; nothing written
outside the output folder; an output that is either the old one or the new one, whole."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import test_errors
from test_errors import assert_refused, run_cli, sphere, tree_hashes

from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.plyio import PointCloud, write_ply

REPO = Path(__file__).resolve().parents[1]
work = test_errors.work  # the workspace fixture: seq/ (3 frames of 800 points), holes.json

FRAGMENTS = ["#", "?", "%41", "%", " ", "é", "日本", "'", '"', "[x]", "*", "&", ";", "$HOME", "~", "-", "..x", "ß😀"]


def hostile_name(rng: np.random.Generator, stem: str) -> str:
    """A file or folder name made of 1-3 hostile fragments around ``stem`` (never '/', '.', '..')."""
    parts = [stem] + [FRAGMENTS[i] for i in rng.choice(len(FRAGMENTS), size=rng.integers(1, 4))]
    rng.shuffle(parts)
    name = "".join(parts).lstrip("-")
    return name if name not in (".", "..") else stem + name


def files_outside(root: Path, out: Path) -> dict[str, str]:
    return tree_hashes(root, skip=out)


# -- paths -------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(4))
def test_hostile_paths_go_through_damage_inpaint_score(work, capsys, seed):
    rng = np.random.default_rng(seed)
    src, dmg, filled = (hostile_name(rng, s) for s in ("in", "dmg", "fill"))
    shutil.copytree(work / "seq", work / src)
    code, _, err = run_cli(["damage", src, "--holes", "region", "--seed", seed, "--out", dmg], capsys)
    assert code == 0, (src, dmg, err)
    code, _, err = run_cli(["inpaint", dmg, "--method", "temporal-copy", "--regions", f"{dmg}/holes.json",
                            "--out", filled], capsys)
    assert code == 0, (dmg, filled, err)
    code, out, err = run_cli(["score", src, filled, "--region", f"{dmg}/holes.json", "--json"], capsys)
    assert code == 0, err
    assert len(json.loads(out)["frames"]) == 3
    record = json.loads((work / dmg / "holes.json").read_text())
    assert record["input_files"] == [f"s_{f:04d}.ply" for f in range(3)]
    assert sorted(p.name for p in (work / filled).iterdir()) == sorted(
        [f"{dmg}_{f:04d}.ply" for f in range(3)] + ["inpaint.json"])
    assert not [p for p in work.iterdir() if p.name.startswith(".")]  # no stage, lock or temporary file left


@pytest.mark.parametrize("seed", range(3))
def test_hostile_store_paths_open_their_own_file(tmp_path, seed):
    from dpcbench.bench.results.store import ResultsStore

    rng = np.random.default_rng(100 + seed)
    names = [hostile_name(rng, f"s{i}") + ".sqlite" for i in range(3)]
    for i, name in enumerate(names):
        ResultsStore(tmp_path / name).add_to_experiment(f"e{i}", ["r"])
    for i, name in enumerate(names):
        assert ResultsStore(tmp_path / name, readonly=True, verify=True).experiments() == [f"e{i}"]
    allowed = {n + side for n in names for side in ("", "-wal", "-shm")}
    assert {p.name for p in tmp_path.iterdir()} <= allowed


# -- links ---------------------------------------------------------------------------------------
LINK_KINDS = ("input", "inside", "dangling", "outside-folder")


@pytest.mark.parametrize("seed", range(6))
def test_links_planted_in_out_never_lead_a_write_outside(work, capsys, seed):
    rng = np.random.default_rng(200 + seed)
    out = work / "out"
    (out / "keep").mkdir(parents=True)
    (out / "keep" / "mine.txt").write_text("mine")
    (work / "elsewhere").mkdir()
    targets = ["seq_0000.ply", "seq_0002.ply", "masks.npz", "holes.json"]
    planted = {}
    for name in rng.choice(targets, size=rng.integers(1, 3), replace=False):
        kind = LINK_KINDS[rng.integers(len(LINK_KINDS))]
        to = {"input": work / "seq" / "s_0001.ply", "inside": out / "keep" / "mine.txt",
              "dangling": work / "elsewhere" / "nothing", "outside-folder": work / "elsewhere"}[kind]
        (out / name).symlink_to(to)
        planted[name] = kind
    before = files_outside(work, out)
    inside_before = (out / "keep" / "mine.txt").read_text()
    code, _, err = run_cli(["damage", "seq", "--holes", "region", "--seed", seed, "--out", "out", "--overwrite"],
                           capsys)
    assert files_outside(work, out) == before, planted  # the input and everything else unchanged
    assert (out / "keep" / "mine.txt").read_text() == inside_before
    assert list((work / "elsewhere").iterdir()) == []
    if all(kind == "inside" for kind in planted.values()):
        assert code == 0, (planted, err)
        assert not any((out / n).is_symlink() for n in planted)  # replaced by the files, not written through
    else:
        assert_refused(code, err, "damage", "symbolic link")


# -- region values -----------------------------------------------------------------------------
def _random_region(rng):
    """(region dict, valid?) with the validity rule written out independently of holes.regions."""
    limit = 1e15
    pick = rng.integers(6)
    center = rng.uniform(-100, 100, 3)
    bad_center = pick == 0
    if bad_center:
        center[rng.integers(3)] = [np.inf, -np.inf, 1e30, -2e15][rng.integers(4)]
    if rng.random() < 0.5:
        radius = [1.0, 12.5, np.inf, 0.0, -3.0, 1e16, 1e15][rng.integers(7)]
        ok = np.isfinite(center).all() and np.abs(center).max() <= limit and np.isfinite(radius) and 0 < radius <= limit
        return {"shape": "ball", "center": center.tolist(), "radius": radius}, bool(ok)
    half = rng.uniform(0.5, 20, 3)
    if rng.random() < 0.3:
        half[rng.integers(3)] = [np.inf, 0.0, -1.0, 2e15][rng.integers(4)]
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    kind = rng.integers(4)
    rot = [q, q + rng.normal(0, 1e-3, (3, 3)), np.zeros((3, 3)), 2 * q][kind]
    ok = (np.isfinite(center).all() and np.abs(center).max() <= limit and np.isfinite(half).all()
          and (half > 0).all() and (half <= limit).all() and kind == 0)
    return {"shape": "box", "center": center.tolist(), "half_extents": half.tolist(), "rotation": rot.tolist()}, bool(ok)


@pytest.mark.parametrize("seed", range(3))
def test_generated_region_values_are_refused_exactly_when_invalid(seed):
    from scipy.spatial import Delaunay

    from dpcbench.holes.regions import HoleRegion

    rng = np.random.default_rng(300 + seed)
    accepted = 0
    for _ in range(60):
        data, valid = _random_region(rng)
        data = json.loads(json.dumps(data))  # through JSON, as a holes.json delivers it (Infinity kept)
        if not valid:
            with pytest.raises(UserError):
                HoleRegion.from_dict(data)
            continue
        region = HoleRegion.from_dict(data)
        accepted += 1
        if region.shape != "box":
            continue
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        corners = region.center + (corners * region.half_extents) @ region.rotation.T
        pts = region.center + rng.uniform(-1.5, 1.5, (400, 3)) * region.half_extents.max()
        local = np.abs((pts - region.center) @ region.rotation) / region.half_extents
        clear = np.abs(local.max(axis=1) - 1) > 1e-6  # not on the boundary, where rounding decides
        brute = Delaunay(corners).find_simplex(pts) >= 0
        np.testing.assert_array_equal(region.contains(pts)[clear], brute[clear])
    assert accepted > 5


# -- corrupt PLY files ---------------------------------------------------------------------------
def _mutations(rng, data: bytes) -> list[bytes]:
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header, body = data[:end].decode(), data[end:]
    out = []
    for _ in range(40):
        kind = rng.integers(8)
        h, b = header, body
        if kind == 0:
            h = h.replace("element vertex 50", f"element vertex {[0, 49, 51, -1, 10**12, 'x'][rng.integers(6)]}")
        elif kind == 1:
            old = ["float x", "float y", "float z", "uchar red"][rng.integers(4)]
            new = ["double", "char", "int", "short", "list uchar int", "float128", ""][rng.integers(7)]
            h = h.replace(old, f"{new} {old.split()[1]}".strip())
        elif kind == 2:
            b = b[: rng.integers(0, len(b))]
        elif kind == 3:
            h = h.replace("end_header\n", "")
        elif kind == 4:
            pos = int(rng.integers(0, len(b) + 1))
            b = b[:pos] + rng.bytes(int(rng.integers(1, 64))) + b[pos:]
        elif kind == 5:
            h = h.replace("binary_little_endian", ["ascii", "binary_big_endian", "binary_middle_endian"][rng.integers(3)])
        elif kind == 6:
            h = h.replace("property float x\n", "property float x\nproperty float x\n")
        else:
            h = h.replace("ply\n", ["", "PLY\n", "ply \n"][rng.integers(3)], 1)
        out.append(h.encode() + b)
    return out


@pytest.mark.parametrize("seed", range(3))
def test_corrupt_ply_files_are_read_or_refused_never_crash(tmp_path, seed):
    from dpcbench.bench.data.plyio import read_ply

    rng = np.random.default_rng(400 + seed)
    pts = sphere(50, seed)
    write_ply(tmp_path / "good.ply", PointCloud(pts, np.full((50, 3), 7, dtype=np.uint8)))
    outcomes = {"read": 0, "refused": 0}
    for i, blob in enumerate(_mutations(rng, (tmp_path / "good.ply").read_bytes())):
        path = tmp_path / f"m{i}.ply"
        path.write_bytes(blob)
        for compact in (False, True):
            try:
                cloud = read_ply(path, compact=compact)
            except UserError as err:
                assert "\n" not in str(err).strip() or str(path) in str(err)
                outcomes["refused"] += 1
                continue
            assert cloud.points.ndim == 2 and cloud.points.shape[1] == 3 and len(cloud.points) > 0
            assert np.isfinite(np.asarray(cloud.points, dtype=np.float64)).all()
            outcomes["read"] += 1
    assert outcomes["refused"] > 0 and sum(outcomes.values()) == 80
    np.testing.assert_array_equal(read_ply(tmp_path / "good.ply").points, pts.astype(np.float32))


# -- kills mid-write -------------------------------------------------------------------------------
def _big_input(folder: Path, frames: int = 6, points: int = 60_000) -> None:
    for f in range(frames):
        write_ply(folder / f"b_{f:04d}.ply", PointCloud(sphere(points, f, shift=0.3 * f),
                                                       np.full((points, 3), 90, dtype=np.uint8)))


def _damage_is_whole(out: Path) -> int:
    """The seed of the damage output in ``out``, after checking that frames, masks and record agree."""
    from dpcbench.bench.data.plyio import read_ply

    record = json.loads((out / "holes.json").read_text())
    masks = np.load(out / "masks.npz")
    frames = sorted(p for p in out.iterdir() if p.suffix == ".ply")
    assert [p.name for p in frames] == [e["file"] for e in record["frames"]]
    for entry, path in zip(record["frames"], frames):
        mask = masks[f"frame_{entry['frame']:04d}"]
        assert int(mask.sum()) == entry["removed"] and len(mask) == entry["points"]
        assert len(read_ply(path).points) == entry["points"] - entry["removed"]
    assert not [p for p in out.iterdir() if p.name.startswith(".") or ".tmp" in p.name]
    return record["seed"]


def _cli(*argv) -> list[str]:
    return [sys.executable, "-m", "dpcbench.bench.cli", *map(str, argv)]


@pytest.mark.parametrize("seed", range(2))
def test_a_killed_damage_overwrite_leaves_the_old_output_or_the_new_one(tmp_path, seed):
    rng = np.random.default_rng(500 + seed)
    env = {**os.environ, "DPCBENCH_QUIET": "1",
           "DPCBENCH_CACHE": str(tmp_path / "cache")}
    _big_input(tmp_path / "big")
    out = tmp_path / "d"
    subprocess.run(_cli("damage", tmp_path / "big", "--holes", "region", "--seed", 0, "--out", out),
                   env=env, check=True, capture_output=True)
    assert _damage_is_whole(out) == 0
    previous = 0
    for attempt in range(3):
        new_seed = 10 + attempt
        sig = [signal.SIGKILL, signal.SIGTERM, signal.SIGINT][rng.integers(3)]
        proc = subprocess.Popen(_cli("damage", tmp_path / "big", "--holes", "region", "--seed", new_seed,
                                     "--out", out, "--overwrite"), env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        time.sleep(float(rng.uniform(0.5, 5.0)))
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
        assert b"Traceback" not in err or sig != signal.SIGINT
        assert _damage_is_whole(out) in (previous, new_seed)  # the old output or the new one, whole
        done = subprocess.run(_cli("damage", tmp_path / "big", "--holes", "region", "--seed", new_seed, "--out", out,
                                   "--overwrite"), env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr  # no stale lock or staging folder in the way
        assert _damage_is_whole(out) == new_seed
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == [], "stage or lock left"
        previous = new_seed


def test_a_killed_inpaint_never_leaves_a_mixed_output(tmp_path):
    from dpcbench.bench.data.plyio import read_ply

    rng = np.random.default_rng(600)
    env = {**os.environ, "DPCBENCH_QUIET": "1",
           "DPCBENCH_CACHE": str(tmp_path / "cache")}
    _big_input(tmp_path / "big")
    subprocess.run(_cli("damage", tmp_path / "big", "--holes", "region", "--out", tmp_path / "d"), env=env, check=True,
                   capture_output=True)
    out = tmp_path / "f"
    for method in ("none", "temporal-copy", "none"):
        proc = subprocess.Popen(_cli("inpaint", tmp_path / "d", "--method", method, "--regions",
                                     tmp_path / "d" / "holes.json", "--out", out), env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(float(rng.uniform(1.0, 6.0)))
        proc.kill()
        proc.wait(timeout=60)
        if out.exists():  # whichever run it is, its record and frames agree
            record = json.loads((out / "inpaint.json").read_text())
            frames = sorted(p.name for p in out.iterdir() if p.suffix == ".ply")
            assert frames == record["files"]
            assert [len(read_ply(out / n).points) for n in frames] == record["points"]
            assert not [p for p in out.iterdir() if p.name.startswith(".")]


# -- labels ----------------------------------------------------------------------------------------
LABEL_FRAGMENTS = ["../", "/", "..", "|", "\\n", "<b>", "$x^2$", "%", "\\\\input{a}", "=HYPERLINK(1)", "#", "é", "'", "`"]


def test_hostile_labels_never_lead_a_write_outside_the_store_and_report(tmp_path, capsys, monkeypatch):
    """Labels (experiment name, sequence and hole labels) from a seeded generator go through `run` and
    `report`; every file written lies under the store's folder or the report's --out. (How they are
    escaped inside the tables is the tables' own concern.)"""
    rng = np.random.default_rng(700)

    def label() -> str:
        return "".join(LABEL_FRAGMENTS[i] for i in rng.choice(len(LABEL_FRAGMENTS), size=4))

    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    work_dir = tmp_path / "w"
    work_dir.mkdir()
    monkeypatch.chdir(work_dir)
    (work_dir / "l.toml").write_text(
        f'[experiment]\nname = "{label()}"\n[[sequences]]\nname = "human"\nlabel = "{label()}"\nframes = 2\n'
        f'params = {{ size = "tiny" }}\n[[holes]]\ngenerator = "region"\nlabel = "{label()}"\n[[methods]]\n'
        'name = "none"\n')
    before = {p for p in tmp_path.rglob("*")}
    code, _, err = run_cli(["run", "l.toml", "--store", "s/s.sqlite", "--executor", "serial"], capsys)
    assert code == 0, err
    code, _, err = run_cli(["report", "s/s.sqlite", "--out", "rep"], capsys)
    assert code == 0, err
    new = {p for p in tmp_path.rglob("*")} - before
    allowed = (work_dir / "s", work_dir / "rep", tmp_path / "cache")
    assert all(any(p == a or a in p.parents for a in allowed) for p in new), sorted(map(str, new))
    assert (work_dir / "rep" / "REPORT.md").is_file()
