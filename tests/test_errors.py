"""The CLI's one error path (`bench.core.errors`): bad input -> one line on stderr and exit 2, never a
traceback, never a file changed outside --out, never a silent wrong number; bugs keep their
traceback. One test per kind of fault, then a generated family of bad inputs for every command."""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dpcbench.bench.cli import main
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.data.plyio import PointCloud, write_ply
from dpcbench.holes.regions import HoleRegion, regions_to_json

REPO = Path(__file__).resolve().parents[1]


# -- tiny data ---------------------------------------------------------------------------------
def sphere(n: int, seed: int, shift: float = 0.0) -> np.ndarray:
    """n points on a sphere of radius 40 around (50 + shift, 50, 50) (Fibonacci lattice + jitter)."""
    rng = np.random.default_rng(seed)
    i = np.arange(n) + 0.5
    phi, theta = np.arccos(1 - 2 * i / n), np.pi * (1 + 5 ** 0.5) * i
    unit = np.column_stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)])
    return 40 * unit + np.array([50.0 + shift, 50.0, 50.0]) + rng.normal(0, 0.05, (n, 3))


@pytest.fixture
def work(tmp_path, monkeypatch):
    """A workspace: seq/ (3 frames, 800 points, colours), holes.json for it, and the environment
    (quiet, private cache, private store)."""
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "_cache"))
    monkeypatch.setenv("DPCBENCH_STORE", str(tmp_path / "_store" / "results.sqlite"))
    ws = tmp_path / "ws"
    seq = ws / "seq"
    frames = [sphere(800, f, shift=0.5 * f) for f in range(3)]
    for f, pts in enumerate(frames):
        colors = np.full((len(pts), 3), 100 + 20 * f, dtype=np.uint8)
        write_ply(seq / f"s_{f:04d}.ply", PointCloud(pts, colors))
    regions = [[HoleRegion.ball(pts[0], 6.0)] for pts in frames]
    (ws / "holes.json").write_text(json.dumps(regions_to_json(regions)))
    monkeypatch.chdir(ws)
    return ws


def run_cli(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_refused(code, err, command, *needles):
    lines = err.strip().splitlines()
    assert code == 2, f"exit {code}, stderr {err!r}"
    assert len(lines) == 1 and lines[0].startswith(f"dpcbench {command}: error:"), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, f"{needle!r} not in {err!r}"


def tree_hashes(root: Path, skip: Path | None = None) -> dict[str, str]:
    """Path -> SHA-256 of every file under root (outside ``skip``). SQLite's own sidecar files
    (-wal, -shm), which even a read-only reader of a WAL database creates, are not user files."""
    out = {}
    for p in sorted(root.rglob("*")):
        if skip is not None and (p == skip or skip in p.parents):
            continue
        if p.name.endswith(("-wal", "-shm")):
            continue
        out[str(p.relative_to(root))] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
    return out


# -- data loss ----------------------------------------------------------------------------------
def test_detect_holes_never_writes_json_over_a_ply_or_into_the_input(work, capsys):
    frame = work / "seq" / "s_0001.ply"
    before = frame.read_bytes()
    for out in (frame, work / "seq" / "holes.json"):
        for extra in ([], ["--overwrite"]):
            code, _, err = run_cli(["detect-holes", "seq", "--out", out, *extra], capsys)
            assert_refused(code, err, "detect-holes")
    assert frame.read_bytes() == before and not (work / "seq" / "holes.json").exists()


def test_a_file_dpcbench_did_not_write_is_replaced_only_with_overwrite(work, capsys):
    mine = work / "notes.json"
    mine.write_text('{"mine": true}')
    code, _, err = run_cli(["detect-holes", "seq", "--out", mine, "--param", "k=8"], capsys)
    assert_refused(code, err, "detect-holes", "did not write", "--overwrite")
    assert mine.read_text() == '{"mine": true}'
    assert run_cli(["detect-holes", "seq", "--out", mine, "--param", "k=8", "--overwrite"], capsys)[0] == 0
    assert json.loads(mine.read_text())["format"] == "dpcbench-holes"
    # its own output is rewritten freely; once the user edits it, it is theirs again
    assert run_cli(["detect-holes", "seq", "--out", mine, "--param", "k=8"], capsys)[0] == 0
    mine.write_text('{"edited": 1}')
    code, _, err = run_cli(["detect-holes", "seq", "--out", mine, "--param", "k=8"], capsys)
    assert_refused(code, err, "detect-holes", "did not write")


def test_a_sequence_never_mixes_with_other_frames_or_replaces_user_files(work, capsys):
    out = work / "filled"
    out.mkdir()
    (out / "other_0000.ply").write_bytes((work / "seq" / "s_0000.ply").read_bytes())
    code, _, err = run_cli(["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", out], capsys)
    assert_refused(code, err, "inpaint", "other .ply frame", "other_0000.ply")
    (out / "other_0000.ply").unlink()
    (out / "inpaint.json").write_text("my notes")
    code, _, err = run_cli(["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", out], capsys)
    assert_refused(code, err, "inpaint", "inpaint.json", "--overwrite")
    assert (out / "inpaint.json").read_text() == "my notes"
    # one frame given as input: its folder is not written into either, not even with --overwrite
    code, _, err = run_cli(["damage", "seq/s_0000.ply", "--holes", "dropout", "--out", "seq", "--overwrite"], capsys)
    assert_refused(code, err, "damage", "holds the input file s_0000.ply")


# -- output paths that cannot be written --------------------------------------------------------
def test_output_paths_that_are_files_under_files_or_unwritable(work, capsys, monkeypatch):
    a_file = work / "a_file"
    a_file.write_text("x")
    cases = [
        ["damage", "seq", "--holes", "dropout", "--out", a_file],
        ["damage", "seq", "--holes", "dropout", "--out", a_file / "sub"],
        ["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", a_file],
        ["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", a_file / "sub"],
        ["detect-holes", "seq", "--out", a_file / "h.json"],
        ["detect-holes", "seq", "--out", work / "seq2"],  # a folder path given for a file
        ["render", "seq", "--out", a_file / "x.png"],
        ["report", "_nowhere.sqlite", "--out", a_file],
        ["run", "paper-quick", "--dry-run", "--store", a_file / "r.sqlite"],
        ["compare", "x.csv", "y.csv", "--out", a_file / "c.csv"],
        ["dashboard", "--out", a_file / "d.html"],
    ]
    (work / "seq2").mkdir()
    for argv in cases:
        code, _, err = run_cli(argv, capsys)
        assert_refused(code, err, argv[0])
    assert a_file.read_text() == "x"

    # a folder that cannot be written (simulated: root ignores permission bits)
    from dpcbench.bench.data import outputs

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(outputs.tempfile, "mkstemp", refuse)
    for argv in (["damage", "seq", "--holes", "dropout", "--out", work / "ro"],
                 ["detect-holes", "seq", "--out", work / "ro.json"],
                 ["run", "paper-quick", "--dry-run", "--store", work / "ro" / "r.sqlite"]):
        code, _, err = run_cli(argv, capsys)
        assert_refused(code, err, argv[0], "Permission denied")
        assert not (work / "ro").exists()


def test_an_oserror_writing_a_claimed_output_is_one_line(work, capsys, monkeypatch):
    from dpcbench.bench.data import sequences

    def disk_full(path, cloud, **kwargs):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(sequences, "write_ply", disk_full)
    code, _, err = run_cli(["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", "o"], capsys)
    assert_refused(code, err, "inpaint", "No space left on device")


def test_a_bug_keeps_its_traceback(work, monkeypatch):
    from dpcbench.methods import reference

    def broken(self, frames, regions=None):
        raise ValueError("operands could not be broadcast together")  # what a numpy bug looks like

    monkeypatch.setattr(reference.NoFill, "inpaint", broken)
    with pytest.raises(ValueError, match="broadcast"):
        main(["inpaint", "seq", "--method", "none", "--regions", "holes.json", "--out", "o"])


# -- holes.json ---------------------------------------------------------------------------------
@pytest.mark.parametrize("content,needle", [
    ("[1, 2, 3]", "holds a JSON list"),
    ('"text"', "holds a JSON str"),
    ('{"format": "dpcbench-holes", "frames": 3}', "'frames' must be a list"),
    ('{"format": "dpcbench-holes", "frames": [{"frame": 0, "regions": [{"shape": "box", "center": [0, 0, 0]}]}]}',
     "half_extents"),
    ('{"format": "dpcbench-holes", "frames": [{"frame": 0, "regions": [{"shape": "ball", "center": [1, 2]}]}]}',
     "center: expected 3 numbers"),
    ("\x00\x01garbage", "not valid JSON"),
])
def test_holes_json_that_is_not_a_holes_object(work, capsys, content, needle):
    bad = work / "bad.json"
    bad.write_text(content)
    for argv in (["score", "seq", "seq", "--region", bad],
                 ["inpaint", "seq", "--method", "none", "--regions", bad, "--out", "o"],
                 ["render", "seq", "--holes", bad, "--out", "r.png"]):
        code, _, err = run_cli(argv, capsys)
        assert_refused(code, err, argv[0], needle)
    assert not (work / "o").exists() and not (work / "r.png").exists()


def test_holes_json_frame_indices_must_be_the_sequence_frames(work, capsys):
    record = json.loads((work / "holes.json").read_text())
    record["frames"][2]["frame"] = 7
    (work / "shifted.json").write_text(json.dumps(record))
    for argv in (["score", "seq", "seq", "--region", "shifted.json"],
                 ["inpaint", "seq", "--method", "none", "--regions", "shifted.json", "--out", "o"]):
        code, _, err = run_cli(argv, capsys)
        assert_refused(code, err, argv[0], "frame(s) 7 do not exist", "frames 0..2")


# -- parameters ---------------------------------------------------------------------------------
def test_param_of_the_wrong_type_is_named(work, capsys):
    code, _, err = run_cli(["damage", "seq", "--holes", "region", "--param", "cube_size=abc", "--out", "d"], capsys)
    assert_refused(code, err, "damage", "cube_size must be a number or none, got 'abc'")
    code, _, err = run_cli(["inpaint", "seq", "--method", "temporal-graph", "--param", "cube_size=abc",
                            "--regions", "holes.json", "--out", "o"], capsys)
    assert_refused(code, err, "inpaint", "cube_size", "'abc'")
    code, _, err = run_cli(["info", "human", "--param", "bit_depth=abc"], capsys)
    assert_refused(code, err, "info", "bit_depth must be a whole number, got 'abc'")
    assert "invalid literal" not in err
    assert not Path("d").exists() and not Path("o").exists()


def test_one_param_parser_for_every_command():
    from dpcbench.bench.core.params import parse_params
    from dpcbench.bench.data.datasets import parse_params as dataset_params

    assert dataset_params is parse_params  # generate/info/render use the same function as damage/inpaint
    parsed = parse_params(["a=yes", "b=No", "c=none", "d=20", "e=0.5", "f=1e-3", "g=[1, 2]", 'h="20"', "i=large",
                           "j=null", "k=true"])
    assert parsed == {"a": True, "b": False, "c": None, "d": 20, "e": 0.5, "f": 0.001, "g": [1, 2], "h": "20",
                      "i": "large", "j": None, "k": True}
    assert isinstance(parsed["d"], int)
    for bad, needle in ((["x"], "KEY=VALUE"), (["=1"], "KEY=VALUE"), (["g=[1,"], "not valid JSON"),
                        (["a=1", "a=2"], "given twice"), (["n=nan"], "NaN")):
        with pytest.raises(UserError, match=needle):
            parse_params(bad)


def test_every_param_option_of_every_command_goes_through_the_one_parser():
    """Every ``--param``-like option (``--param``, ``--dataset-param``) of every command is read by
    bench.core.params.parse_params and by nothing else, so ``x=none`` is None everywhere."""
    import ast
    from pathlib import Path

    import dpcbench.bench.cli.commands as commands_pkg
    from dpcbench.bench.core.params import parse_params

    folder = Path(commands_pkg.__file__).parent
    checked = {}
    for path in sorted(folder.glob("*.py")):
        tree = ast.parse(path.read_text())
        dests = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
                for arg in node.args:
                    if isinstance(arg, ast.Constant) and str(arg.value).startswith("--") and \
                            str(arg.value).endswith("param"):
                        dests.add(str(arg.value)[2:].replace("-", "_"))
        if not dests:
            continue
        # each args.<dest> is used only as the first argument of a parse_params(...) call
        parsed_by = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) == "parse_params":
                first = node.args[0] if node.args else None
                if isinstance(first, ast.Attribute) and first.attr in dests:
                    parsed_by[first.attr] = parsed_by.get(first.attr, 0) + 1
        uses = [n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr in dests
                and isinstance(n.value, ast.Name) and n.value.id == "args"]
        for dest in dests:
            assert parsed_by.get(dest), f"{path.name}: --{dest} is not read by bench.core.params.parse_params"
            assert uses.count(dest) == parsed_by[dest], f"{path.name}: args.{dest} is read outside parse_params"
        assert "partition(\"=\")" not in path.read_text() and "split(\"=\"" not in path.read_text(), path.name
        checked[path.stem] = sorted(dests)
    # the commands that take parameters on the command line, all of them checked above
    assert {"damage", "detect_holes", "generate", "info", "inpaint", "render"} <= set(checked)
    assert parse_params(["x=none"]) == {"x": None} and parse_params(["x=None"]) == {"x": None}


def test_user_terms_messages(work, capsys):
    code, _, err = run_cli(["run", "no-such-preset", "--dry-run"], capsys)
    assert_refused(code, err, "run", "no-such-preset: no such config file", "presets: colour, methods, paper, paper-ablation, paper-quick")
    assert "presets/toml" not in err
    # a message that ends with a quoted value keeps its closing quote
    code, _, err = run_cli(["damage", "seq", "--holes", "region", "--param", "shape=blob", "--out", "d"], capsys)
    assert_refused(code, err, "damage")
    assert err.rstrip().endswith("got 'blob'")
    code, _, err = run_cli(["inpaint", "seq", "--method", "nope", "--out", "o"], capsys)
    assert_refused(code, err, "inpaint", "unknown method 'nope'")


# -- silent wrong numbers -----------------------------------------------------------------------
def test_score_regions_without_points_are_refused_or_warned_and_recorded(work, capsys):
    record = json.loads((work / "holes.json").read_text())
    far = [{"shape": "ball", "center": [5000.0, 0.0, 0.0], "radius": 1.0}]
    everywhere = json.loads(json.dumps(record))
    for entry in everywhere["frames"]:
        entry["regions"] = far
    (work / "far.json").write_text(json.dumps(everywhere))
    code, _, err = run_cli(["score", "seq", "seq", "--region", "far.json"], capsys)
    assert_refused(code, err, "score", "no frame has a reference point inside its regions")

    record["frames"][1]["regions"] = far
    (work / "partly.json").write_text(json.dumps(record))
    code, out, err = run_cli(["score", "seq", "seq", "--region", "partly.json", "--json", "--metric", "chamfer"],
                             capsys)
    assert code == 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dpcbench score: warning:") and "frame(s) 1" in lines[0]
    scores = json.loads(out)
    assert scores["frames"][1]["chamfer"] is None and scores["frames"][0]["chamfer"] == 0.0
    assert len(scores["warnings"]) == 1 and "frame(s) 1" in scores["warnings"][0]


def test_score_refuses_a_negative_margin_and_bad_options(work, capsys):
    for extra, needle in ((["--region", "holes.json", "--region-margin", "-100"], "--region-margin -100"),
                          (["--region-margin", "2"], "only used with --region"),
                          (["--fscore-threshold", "0"], "positive distance"),
                          (["--peak", "abc"], "--peak abc")):
        code, _, err = run_cli(["score", "seq", "seq", *extra], capsys)
        assert_refused(code, err, "score", needle)


@pytest.mark.parametrize("method", ["temporal-copy", "temporal-graph"])
def test_regions_far_from_the_cloud_are_refused_by_both_temporal_methods(work, capsys, method):
    record = json.loads((work / "holes.json").read_text())
    for entry in record["frames"]:
        entry["regions"] = [{"shape": "ball", "center": [5000.0, 0.0, 0.0], "radius": 3.0}]
    (work / "far.json").write_text(json.dumps(record))
    code, _, err = run_cli(["inpaint", "seq", "--method", method, "--regions", "far.json", "--out", "o"], capsys)
    assert_refused(code, err, "inpaint", "do not belong to this cloud")
    assert not (work / "o").exists()


def test_temporal_copy_still_fills_regions_on_the_cloud():
    from dpcbench.methods.reference import TemporalCopy

    frames = [sphere(2000, f) for f in range(3)]
    hole = HoleRegion.ball(frames[1][0], 8.0)
    damaged = [f if i != 1 else f[~hole.contains(f)] for i, f in enumerate(frames)]
    out = TemporalCopy().inpaint(damaged, [[], [hole], []])
    assert len(out[1]) > len(damaged[1])


def test_ascii_ply_holding_more_rows_than_declared_is_refused(work, capsys):
    header = ("ply\nformat ascii 1.0\nelement vertex {}\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n")
    rows = "".join(f"{i} {i % 3} {i % 5}\n" for i in range(12))
    (work / "short.ply").write_text(header.format(10) + rows)
    code, _, err = run_cli(["info", "short.ply"], capsys)
    assert_refused(code, err, "info", "declares 10 vertex", "holds 12 data lines")
    (work / "exact.ply").write_text(header.format(12) + rows)
    assert run_cli(["info", "exact.ply", "--json"], capsys)[0] == 0


def test_binary_ply_with_bytes_beyond_the_declared_rows_is_refused(tmp_path):
    from dpcbench.bench.data.plyio import read_ply

    path = write_ply(tmp_path / "b.ply", sphere(50, 0))
    assert len(read_ply(path)) == 50
    with open(path, "ab") as handle:
        handle.write(b"\0" * 24)
    with pytest.raises(UserError, match="24 bytes follow the 50 rows"):
        read_ply(path)


# -- validation before anything runs ------------------------------------------------------------
CONFIG = """
[experiment]
name = "e"
[[sequences]]
name = "{name}"
params = {{ size = "tiny" }}
frames = 2
[[holes]]
generator = "region"
params = {{ cube_size = {cube} }}
[[methods]]
name = "none"
"""


@pytest.mark.parametrize("name,cube,needle", [
    ("human", '"abc"', "holes[0].params: hole generator region: parameter cube_size must be a number or none, "
                       "got 'abc'"),
    ("human", "[20, -1]", "cube_size must be positive, got -1"),
    ("humna", "20", "unknown sequence 'humna' (did you mean 'human'?)"),
])
def test_dry_run_validates_the_whole_grid(work, capsys, name, cube, needle):
    (work / "e.toml").write_text(CONFIG.format(name=name, cube=cube))
    code, _, err = run_cli(["run", "e.toml", "--dry-run"], capsys)
    assert_refused(code, err, "run", needle)


def test_dry_run_accepts_a_valid_grid(work, capsys):
    (work / "e.toml").write_text(CONFIG.format(name="human", cube="[20, 30]"))
    code, out, _ = run_cli(["run", "e.toml", "--dry-run"], capsys)
    assert code == 0 and "2 runs in experiment 'e': 2 to do" in out


def test_a_folder_named_like_an_embedded_sequence_says_which_one_is_taken(work, capsys):
    (work / "human").mkdir()
    (work / "human" / "f.ply").write_bytes((work / "seq" / "s_0000.ply").read_bytes())
    code, out, err = run_cli(["info", "human", "--json"], capsys)
    assert code == 0 and json.loads(out)["frames"] == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "warning:" in lines[0] and "using the folder" in lines[0]
    assert run_cli(["info", "./human", "--json"], capsys)[2] == ""  # unambiguous: no note


def test_config_sequence_names_never_read_a_folder_of_that_name(work):
    from dpcbench.bench.data.datasets import load_run_sequence

    (work / "human").mkdir()
    (work / "human" / "f.ply").write_bytes((work / "seq" / "s_0000.ply").read_bytes())
    seq = load_run_sequence({"name": "human", "params": {"size": "tiny"}, "frames": 1})
    assert len(seq.frames) == 1 and len(seq.frames[0]) > 10000  # the embedded figure, not the 800-point file


# -- store damage -------------------------------------------------------------------------------
def damaged_store(path: Path) -> Path:
    """A results store with 4000 results whose last data pages are overwritten by 8 KB of garbage
    (its schema still reads: only an integrity check finds the damage)."""
    from dpcbench.bench.results.store import ResultsStore

    for stale in (path, Path(f"{path}-wal"), Path(f"{path}-shm")):
        stale.unlink(missing_ok=True)
    store = ResultsStore(path)
    for r in range(40):
        store.record_run(f"run{r:03d}", {"sequence": "s", "method": "none", "spec": {}},
                         [{"frame": f, "metric": "chamfer", "scope": "frame", "peak": "", "value": float(f)}
                          for f in range(100)], ["e"])
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    conn.close()
    data = bytearray(path.read_bytes())
    start = len(data) - 8192 - 4096
    data[start:start + 8192] = np.random.default_rng(0).integers(0, 256, 8192, dtype=np.uint8).tobytes()
    path.write_bytes(bytes(data))
    return path


def test_a_damaged_store_is_refused_before_run_or_report(work, capsys):
    from dpcbench.bench.results.store import ResultsStore

    bad = damaged_store(work / "bad.sqlite")
    assert ResultsStore(bad, readonly=True).experiments() == ["e"]  # opening alone does not notice
    before = bad.read_bytes()
    (work / "e.toml").write_text(CONFIG.format(name="human", cube="20"))
    for argv in (["run", "e.toml", "--dry-run", "--store", bad],
                 ["report", bad, "--out", "rep"],
                 ["compare", "x.csv", bad],
                 ["cost", bad]):
        code, _, err = run_cli(argv, capsys)
        assert_refused(code, err, argv[0], "damaged", f"mv {bad} {bad}.bad")
    assert bad.read_bytes() == before and not (work / "rep").exists()


# -- end to end, as a user runs it ---------------------------------------------------------------
def test_subprocess_error_is_one_line_and_exit_2(work):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", "damage", "seq", "--holes", "region",
                           "--param", "cube_size=abc", "--out", "d"], capture_output=True, text=True, env=env)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "dpcbench.bench.cli", "render", "seq", "--out", "r.png", "--bogus"],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "unrecognized arguments: --bogus" in proc.stderr


# -- the generated family of bad inputs ----------------------------------------------------------
def bad_files(ws: Path) -> dict[str, Path]:
    """Corrupt inputs of every kind a command reads, written into ws/bad/."""
    bad = ws / "bad"
    bad.mkdir(exist_ok=True)
    good = (ws / "seq" / "s_0000.ply").read_bytes()
    files = {
        "garbage.ply": b"\x00\x01\x02not a ply at all",
        "truncated.ply": good[: len(good) // 2],
        "header_only.ply": good[: good.find(b"end_header") + 11],
        "short_ascii.ply": (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                            b"property float z\nend_header\n0 0 0\n1 1 1\n2 2 2\n"),
        "nan.ply": (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    b"property float z\nend_header\n0 0 0\nnan 1 1\n2 2 2\n"),
        "empty.ply": (b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                      b"property float z\nend_header\n"),
        "list.json": b"[1, 2, 3]",
        "brokenjson.json": b'{"format": "dpcbench-holes", "frames": [',
        "wrongformat.json": b'{"format": "other", "frames": []}',
        "badregion.json": b'{"format": "dpcbench-holes", "frames": [{"frame": 0, "regions": [{"shape": "ball"}]}]}',
        "binary.json": bytes(range(256)),
        "store.sqlite": b"SQLite format 3\x00" + b"\xff" * 200,
        "text.sqlite": b"hello",
        "config.toml": b"[experiment\nname = ",
        "summary.csv": b"# format: nope\n",
        "tolerances.toml": b"\xff\xfe",
    }
    out = {}
    for name, content in files.items():
        (bad / name).write_bytes(content)
        out[name] = bad / name
    for name in ("garbage", "truncated", "short_ascii", "nan", "empty"):  # sequences of one bad frame
        folder = bad / f"seq_{name}"
        folder.mkdir(exist_ok=True)
        (folder / "f_0000.ply").write_bytes(files[f"{name}.ply"])
        out[f"seq_{name}"] = folder
    (bad / "noply").mkdir(exist_ok=True)
    (bad / "noply" / "readme.txt").write_text("no frames here")
    out["noply"] = bad / "noply"
    out["damaged_store"] = damaged_store(bad / "damaged.sqlite")
    (bad / "a_file").write_text("x")
    out["a_file"] = bad / "a_file"
    return out


def bad_input_family(ws: Path) -> list[tuple[list[str], Path | None]]:
    """(argv, the --out path or None) for every command: each bad input alone, and every pair of a
    bad input with a bad parameter or a bad output path (the product of the families)."""
    f = {k: str(v) for k, v in bad_files(ws).items()}
    missing = str(ws / "no_such_thing")
    seq_inputs = [missing, f["noply"], f["a_file"] + "/x", *(f[k] for k in f if k.startswith("seq_")),
                  f["garbage.ply"], f["short_ascii.ply"]]
    holes_files = [missing, f["list.json"], f["brokenjson.json"], f["wrongformat.json"], f["badregion.json"],
                   f["binary.json"], f["seq_garbage"]]
    stores = [missing, f["store.sqlite"], f["text.sqlite"], f["damaged_store"], f["noply"], f["a_file"] + "/r.sqlite"]
    bad_params = [["--param", "nokey"], ["--param", "bogus=1"], ["--param", "k=[1,"],
                  ["--param", "a=1", "--param", "a=2"]]
    out_dir = str(ws / "out")
    folder_outs = [f["a_file"], f["a_file"] + "/sub", str(ws / "seq"), str(ws / "seq" / "inner")]
    file_outs = [f["a_file"] + "/x.json", str(ws / "seq" / "s_0001.ply"), str(ws / "seq")]
    good_seq, good_holes = str(ws / "seq"), str(ws / "holes.json")
    cases: list[tuple[list[str], Path | None]] = []

    def add(argv, out=None):
        cases.append((argv, Path(out) if out else None))

    templates = {
        "damage": lambda inp, params, out: ["damage", inp, "--holes", "region", *params, "--out", out],
        "inpaint": lambda inp, params, out: ["inpaint", inp, "--method", "temporal-copy", *params, "--regions",
                                             good_holes, "--out", out],
        "detect-holes": lambda inp, params, out: ["detect-holes", inp, *params, "--out", out],
        "render": lambda inp, params, out: ["render", inp, "--frames", "0", *params, "--out", out],
        "info": lambda inp, params, out: ["info", inp, *params],
    }
    json_out = {"detect-holes": ".json", "render": ".png"}
    for command, make in templates.items():
        target = out_dir + json_out.get(command, "")
        for inp in seq_inputs:
            add(make(inp, [], target), target)
        for inp, params in itertools.product(seq_inputs[:3], bad_params):
            add(make(inp, params if command != "render" else [], target), target)
        for params in bad_params:
            if command in ("damage", "inpaint", "detect-holes"):
                add(make(good_seq, params, target), target)
        outs = file_outs if command in json_out else folder_outs
        if command != "info":
            for out, inp in itertools.product(outs, [good_seq, missing]):
                add(make(inp, [], out))
    for holes in holes_files:
        add(["score", good_seq, good_seq, "--region", holes])
        add(["inpaint", good_seq, "--method", "none", "--regions", holes, "--out", out_dir], out_dir)
        add(["render", good_seq, "--holes", holes, "--out", out_dir + ".png"], out_dir + ".png")
        for bad_value in (["--region-margin", "-1"], ["--peak", "xyz"], ["--fscore-threshold", "-2"]):
            add(["score", good_seq, good_seq, "--region", holes, *bad_value])
    for ref, res in itertools.product(seq_inputs[:6], [good_seq, f["seq_nan"]]):
        add(["score", ref, res])
    for store in stores:
        add(["report", store, "--out", out_dir], out_dir)
        if store != missing:  # a new store path is valid: the dry run just says nothing is stored
            add(["run", "paper-quick", "--dry-run", "--store", store])
        add(["compare", f["summary.csv"], store])
        add(["dashboard", "--store", store, "--out", out_dir + ".html"], out_dir + ".html")
    for config in (missing, f["config.toml"], f["a_file"], f["noply"], "paper-quik"):
        add(["run", config, "--dry-run"])
    for args in (["compare", f["summary.csv"], f["summary.csv"]], ["compare", missing + ".csv", f["summary.csv"]],
                 ["compare", f["summary.csv"], f["summary.csv"], "--tolerances", f["tolerances.toml"]],
                 ["dashboard", "--summary", f["summary.csv"], "--out", out_dir + ".html"],
                 ["dashboard", "--benchmarks", f["binary.json"], "--summary", f["summary.csv"], "--out",
                  out_dir + ".html"],
                 ["generate", "humna", "--out", out_dir], ["generate", "human", "--frames", "0", "--out", out_dir],
                 ["generate", "human", "--param", "size=huge", "--out", out_dir],
                 ["generate", "human", "--out", f["a_file"]], ["info", "human", "--param", "bit_depth=abc"],
                 ["reproduce-paper", "--quick", "--frames", "1", "--out", out_dir],
                 ["reproduce-paper", "--quick", "--data-dir", missing, "--out", out_dir]):
        add(args, out_dir if "--out" in args and args[args.index("--out") + 1].startswith(out_dir) else None)
    return cases


def good_inputs(ws: Path):
    """A function that puts the good inputs (seq/, holes.json) back as they were now: a case that
    damaged them is reported by its own hash check, and must not make later cases fail for the
    wrong reason."""
    saved = {p: p.read_bytes() for p in [*(ws / "seq").iterdir(), ws / "holes.json"]}

    def restore():
        import shutil

        for p in (ws / "seq").iterdir():
            if p not in saved:
                shutil.rmtree(p) if p.is_dir() else p.unlink()
        for p, data in saved.items():
            if not p.is_file() or p.read_bytes() != data:
                p.write_bytes(data)
    return restore


def check_family(ws: Path, capsys) -> tuple[int, list[str]]:
    """Run every case in-process; (cases tried, descriptions of the cases not handled well)."""
    failures = []
    cases = bad_input_family(ws)
    restore = good_inputs(ws)
    for argv, out in cases:
        restore()
        before = tree_hashes(ws, skip=out)
        try:
            code = main(argv)
            _, err = capsys.readouterr()
        except BaseException as exc:  # any exception at all: a traceback is what this test hunts for
            capsys.readouterr()
            failures.append(f"{argv}: raised {type(exc).__name__}: {exc}")
            continue
        lines = err.strip().splitlines()
        if code != 2 or len(lines) != 1 or not lines[0].startswith(f"dpcbench {argv[0]}: error:"):
            failures.append(f"{argv}: exit {code}, stderr {err!r}")
        elif tree_hashes(ws, skip=out) != before:
            failures.append(f"{argv}: changed files outside --out")
    return len(cases), failures


def test_generated_bad_inputs_for_every_command(work, capsys):
    tried, failures = check_family(work, capsys)
    assert not failures, f"{len(failures)} of {tried} bad inputs mishandled:\n" + "\n".join(failures[:20])
    assert tried > 200
