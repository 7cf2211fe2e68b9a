"""The harness's structure: no import cycles, layers respected, the run modules importing one way,
one atomic-write helper, one provenance probe (git commit, environment, run folders)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests import import_graph

REPO = Path(__file__).resolve().parents[1]


# -- import graph --------------------------------------------------------------------------------
def test_the_project_has_no_import_cycle():
    cycles = import_graph.find_cycles(import_graph.import_graph())
    assert cycles == [], f"import cycles among the project's modules: {cycles}"


def test_find_cycles_finds_a_cycle_through_a_function_level_import(tmp_path):
    """The checker itself: a lazy import inside a function closes a cycle and is reported."""
    pkg = tmp_path / "bench"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from bench.b import thing\n")
    (pkg / "b.py").write_text("def thing():\n    from bench import a\n    return a\n")
    (pkg / "c.py").write_text("import bench.a\nfrom . import b\n")
    for other in ("metrics", "holes", "methods"):
        (tmp_path / other).mkdir()
    graph = import_graph.import_graph(tmp_path)
    assert graph["bench.a"] == {"bench.b"} and graph["bench.b"] == {"bench.a"}
    assert graph["bench.c"] == {"bench.a", "bench.b"}
    assert import_graph.find_cycles(graph) == [["bench.a", "bench.b"]]
    assert import_graph.find_cycles({"x": {"y"}, "y": set()}) == []


def test_a_type_only_import_is_no_dependency(tmp_path):
    """An import under ``if TYPE_CHECKING:`` never runs (a type for the checker): no edge, no cycle; the same
    import outside the block, or under an ``if`` with an ``else``, is one."""
    pkg = tmp_path / "bench"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from bench.b import B\n")
    (pkg / "b.py").write_text("import typing\nif typing.TYPE_CHECKING:\n    import bench.a\nelse:\n    import bench.c\n")
    (pkg / "c.py").write_text("def f():\n    from bench import a\n")
    for other in ("metrics", "holes", "methods"):
        (tmp_path / other).mkdir()
    graph = import_graph.import_graph(tmp_path)
    assert graph["bench.a"] == set() and graph["bench.b"] == {"bench.a", "bench.c"} and graph["bench.c"] == {"bench.a"}


def test_the_run_modules_import_one_way():
    """runner (sweep) -> executors -> worker -> provenance; paper and tables read run folders
    through provenance, never through the sweep driver."""
    graph = import_graph.import_graph()
    assert "bench.execution.runner" not in graph["bench.execution.executors"]
    assert "bench.execution.executors" in graph["bench.execution.runner"] and "bench.execution.worker" in graph["bench.execution.executors"]
    for module in ("bench.reporting.paper", "bench.reporting.tables", "bench.execution.worker", "bench.execution.provenance"):
        assert "bench.execution.runner" not in graph[module], module
    assert not graph["bench.execution.provenance"] & {"bench.execution.worker", "bench.execution.executors", "bench.execution.runner"}


def test_lower_layers_import_nothing_from_a_higher_layer():
    """metrics < holes < methods < bench: `UserError` and the parameter check live in metrics (the
    lowest layer that raises them), so no module imports upwards (tests/test_layering.py checks the
    same rule file by file)."""
    graph = import_graph.import_graph()
    assert import_graph.layer_violations(graph) == []
    # the checker does see an upward import when there is one
    assert import_graph.layer_violations({"metrics.pairs": {"bench.core.errors"}}) == [("metrics.pairs", "bench.core.errors")]


# -- atomic writes -------------------------------------------------------------------------------
def test_atomic_write_keeps_the_old_file_when_the_writer_fails(tmp_path):
    from dpcbench.bench.core.atomic import atomic_path, atomic_write_text

    out = atomic_write_text(tmp_path / "sub" / "summary.csv", "a,b\n1,2\n")
    assert out.read_text() == "a,b\n1,2\n"
    with pytest.raises(RuntimeError), atomic_path(out) as tmp:
        assert tmp.parent == out.parent and tmp.name.startswith(".summary.") and tmp.suffix == ".csv"
        tmp.write_text("half a fi")
        raise RuntimeError("killed half-way")
    assert out.read_text() == "a,b\n1,2\n"
    assert sorted(p.name for p in out.parent.iterdir()) == ["summary.csv"]  # no temporary left


def test_atomic_folder_replaces_a_folder_whole_and_stale_ones_are_removed(tmp_path):
    from dpcbench.bench.core.atomic import atomic_folder, remove_stale_folders

    run = tmp_path / "runs" / "abc"
    with atomic_folder(run) as tmp:
        (tmp / "manifest.json").write_text("1")
    with atomic_folder(run) as tmp:
        (tmp / "other.json").write_text("2")
    assert sorted(p.name for p in run.iterdir()) == ["other.json"]
    with pytest.raises(ValueError), atomic_folder(run) as tmp:
        (tmp / "manifest.json").write_text("3")
        raise ValueError("failed run")
    assert sorted(p.name for p in run.iterdir()) == ["other.json"]
    assert sorted(p.name for p in run.parent.iterdir()) == ["abc"]

    # a folder of a writer that is gone (a pid no process has) goes, one of a live writer stays
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (run.parent / f".tmp-x-{int(dead.stdout)}-deadbeef").mkdir()
    live = run.parent / f".tmp-y-{os.getpid()}-cafe0000"
    live.mkdir()
    (run.parent / ".tmp-old-abc-12345678").mkdir()
    assert remove_stale_folders(run.parent) == 2
    assert sorted(p.name for p in run.parent.iterdir()) == [live.name, "abc"]


# -- provenance ----------------------------------------------------------------------------------
def _git(cwd, *args):
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()


def test_git_commit_names_the_commit_and_a_dirty_tree(tmp_path):
    from dpcbench.bench.execution.provenance import git_commit
    from dpcbench.bench.results import compare

    assert compare.git_commit is git_commit  # one probe
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    (repo / "f.txt").write_text("1")
    _git(repo, "add", "f.txt")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "one")
    head = _git(repo, "rev-parse", "HEAD")
    assert git_commit(repo) == head
    (repo / "f.txt").write_text("2")
    assert git_commit(repo) == head + "+dirty"
    (repo / "new.txt").write_text("untracked files do not make it dirty")
    (repo / "f.txt").write_text("1")
    assert git_commit(repo) == head
    plain = tmp_path / "plain"
    plain.mkdir()
    assert git_commit(plain) == "unknown"


def test_environment_and_summary_header_come_from_one_probe():
    import platform

    from dpcbench.bench.execution.provenance import environment, summary_environment

    env = environment()
    flat = summary_environment()
    assert env["python"] == flat["python"] == platform.python_version()
    assert env["packages"]["numpy"] == flat["numpy"] == np.__version__
    assert flat["machine"] == f"{platform.system()} {platform.machine()}, {os.cpu_count()} cpus"
    assert env["machine"]["cpus"] == os.cpu_count()


def test_run_folder_round_trip(tmp_path):
    from dpcbench.bench.execution.provenance import is_complete_run_folder, read_run_folder, write_run_folder
    from dpcbench.holes.regions import HoleRegion, regions_to_json

    rng = np.random.default_rng(0)
    damaged = [rng.random((50, 3)), rng.random((40, 3))]
    inpainted = [rng.random((60, 3)), rng.random((45, 3))]
    regions = [[HoleRegion.ball([0.5, 0.5, 0.5], 0.2)], []]
    run = tmp_path / "key"
    write_run_folder(run, damaged=damaged, damaged_colors=None, inpainted=inpainted,
                     holes=regions_to_json(regions), detected=None, manifest={"frames": 2, "extra": np.float32(1.5)})
    assert is_complete_run_folder(run)
    back = read_run_folder(run)
    for a, b in zip(back["inpainted"] + back["damaged"], inpainted + damaged):
        np.testing.assert_array_equal(a, b)  # float64 frames that float32 cannot hold: written as double
    assert b"property double x" in (run / "damaged" / "frame_0000.ply").read_bytes()[:300]
    exact = [np.round(d * 1000) for d in damaged]  # voxel-like data, which float32 holds exactly
    write_run_folder(tmp_path / "f32", damaged=exact, damaged_colors=None, inpainted=inpainted,
                     holes=regions_to_json(regions), detected=None, manifest={})
    assert b"property float x" in (tmp_path / "f32" / "inpainted" / "frame_0000.ply").read_bytes()[:300]
    np.testing.assert_array_equal(read_run_folder(tmp_path / "f32")["inpainted"][0], inpainted[0].astype(np.float32))
    sha = back["manifest"].pop("sha256")
    assert back["manifest"] == {"frames": 2, "extra": "1.5"} and back["detected"] is None
    assert len(back["regions"][0]) == 1 and back["regions"][1] == []
    import hashlib

    frame = run / "inpainted" / "frame_0000.ply"
    assert sha["inpainted/frame_0000.ply"] == hashlib.sha256(frame.read_bytes()).hexdigest()
    assert set(sha) == {"holes.json"} | {f"{s}/frame_{i:04d}.ply" for s in ("damaged", "inpainted") for i in (0, 1)}
    # a frame replaced (here by the damaged one), deleted, or the folder renamed: never trusted
    from dpcbench.bench.core.errors import UserError

    frame.write_bytes((run / "damaged" / "frame_0000.ply").read_bytes())
    with pytest.raises(UserError, match="inpainted/frame_0000.ply"):
        read_run_folder(run)
    write_run_folder(run, damaged=damaged, damaged_colors=None, inpainted=inpainted,
                     holes=regions_to_json(regions), detected=None, manifest={"inpaint_key": "key"})
    (run / "damaged" / "frame_0001.ply").unlink()
    with pytest.raises(UserError, match="missing"):
        read_run_folder(run)
    write_run_folder(run, damaged=damaged, damaged_colors=None, inpainted=inpainted,
                     holes=regions_to_json(regions), detected=None, manifest={"inpaint_key": "key"})
    run.rename(tmp_path / "other")
    with pytest.raises(UserError, match="belongs to run folder key"):
        read_run_folder(tmp_path / "other")


def test_every_package_folder_is_listed_for_the_wheel():
    """A sub-package missing from pyproject's `packages` installs editable but is absent from the wheel."""
    from dpcbench.bench.experiment.config import tomllib

    root = Path(__file__).resolve().parents[1]
    config = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    folders = {folder: name for name, folder in config["package-dir"].items()}
    missing = []
    for top in ("bench", "methods", "metrics", "holes"):
        for init in sorted((root / top).rglob("__init__.py")):
            rel = init.parent.relative_to(root).as_posix()
            base = max((f for f in folders if rel == f or rel.startswith(f + "/")), key=len)
            name = folders[base] + rel[len(base):].replace("/", ".")
            if name not in listed:
                missing.append(name)
    assert missing == [], f"add to [tool.setuptools] packages in pyproject.toml: {missing}"
