"""The lazy registries (`metrics.lazy`, re-exported by `holes.lazy`) behind hole generators, methods and
metrics, their plug-ins (entry points, import paths) and versions, and "no holes" as the
registered generator ``none`` (`holes.base.NoHoles`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


# -- lazy registries ------------------------------------------------------------------------------
def test_lazy_registry_loads_on_demand_and_names_the_known_entries():
    from dpcbench.holes.lazy import LazyRegistry, import_entry
    from dpcbench.holes.registry import GENERATORS
    from dpcbench.methods.registry import METHODS

    registry = LazyRegistry("widget", {"path": "pathlib:PurePosixPath", "gone": "no_such_module_xyz:Thing"})
    assert registry.load("path") is __import__("pathlib").PurePosixPath
    with pytest.raises(KeyError, match=r"unknown widget 'nope'; known widgets: gone, path"):
        registry.load("nope")
    status = registry.available()
    assert status["path"] is None and "ModuleNotFoundError" in status["gone"]
    with pytest.raises(ValueError, match="expected 'package.module:Attr'"):
        import_entry("pathlib.PurePosixPath")
    assert isinstance(GENERATORS, LazyRegistry) and isinstance(METHODS, LazyRegistry)
    with pytest.raises(KeyError, match="unknown method 'nope'; known methods: "):
        METHODS.load("nope")
    with pytest.raises(KeyError, match="unknown hole generator 'nope'; known generators: "):
        GENERATORS.load("nope")


# -- "no holes" ----------------------------------------------------------------------------------
def test_no_holes_is_a_registered_generator_that_removes_nothing():
    from dpcbench.holes.registry import generator_class, get_generator

    frames = [np.random.default_rng(1).random((30, 3)), np.random.default_rng(2).random((20, 3))]
    colors = [np.zeros((30, 3), np.uint8), np.ones((20, 3), np.uint8)]
    result = get_generator("none").damage(frames, 0, colors=colors)
    for out, frame in zip(result.frames, frames):
        np.testing.assert_array_equal(out, frame)
        assert out is not frame
    assert result.removed_fraction == [0.0, 0.0] and result.regions == [[], []] and result.colors is colors
    assert generator_class("none").removes_points is False and generator_class("region").removes_points is True


def test_no_holes_in_a_config_keeps_its_run_identity():
    """The same identity (so the same run ids and stored results) as when "none" was a special case."""
    from dpcbench.bench.experiment.config import parse_config

    cfg = {"experiment": {"name": "real"}, "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 1}],
           "holes": [{"generator": "none", "seeds": [3, 4]}], "methods": [{"name": "none"}]}
    specs = parse_config(cfg).expand()
    assert len(specs) == 1  # the seed plays no part: one run
    assert specs[0].identity()["holes"] == {"generator": "none", "params": {}, "seed": 0}
    assert specs[0].versions["generator"] == "1" and specs[0].holes["entry"] == "dpcbench.holes.base:NoHoles"
    # the ids the special-cased "none" gave at 1a064a3 (run folders and stored runs stay valid)
    assert (specs[0].run_id, specs[0].inpaint_key) == ("828a587a394c3200", "02c0df3394862278")


def test_a_run_without_holes_stores_no_quality_score(tmp_path, monkeypatch):
    from dpcbench.bench.execution.runner import run_experiment
    from dpcbench.bench.experiment.config import parse_config
    from dpcbench.bench.results.store import ResultsStore
    from tests import runner_fixtures as helpers

    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)  # the worker imports tests.runner_fixtures from the repo root
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=300)
    specs = parse_config({"experiment": {"name": "real", "timeout_s": 120}, "sequences": [{"path": str(seq)}],
                          "holes": [{"generator": "none"}], "methods": [{"name": "test-identity"}],
                          "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]}}).expand()
    store = ResultsStore(tmp_path / "store.sqlite")
    summary = run_experiment(specs, store, executor="serial", quiet=True)
    assert len(summary.done) == 1, summary.errors
    rows = store.results_frame()
    assert set(rows.metric) == {"time_s", "cpu_time_s", "peak_mem_mb", "removed_fraction"}
    assert (rows[rows.metric == "removed_fraction"].value == 0.0).all()
    holes = json.loads((tmp_path / "runs" / specs[0].inpaint_key / "holes.json").read_text())
    assert holes["generator"] == "none"


# -- plug-ins: entry points of installed distributions, import paths --------------------------------
PLUGIN_MODULE = '''
import numpy as np
from dpcbench.holes.base import DamageResult, HoleGenerator
from dpcbench.methods.base import PerFrameMethod
from dpcbench.metrics.registry import Metric


class CentroidFill(PerFrameMethod):
    """Adds each region's centre as one point (a toy fill for the registry tests)."""

    name = "centroid-fill"
    summary = "adds each hole region's centre"
    needs_regions = True

    def __init__(self, copies: int = 1):
        self.copies = copies

    def inpaint_frame(self, points, regions):
        centres = [np.asarray(r.center, dtype=float) for r in regions for _ in range(self.copies)]
        return np.vstack([points, *[c[None] for c in centres]])


class HalfHoles(HoleGenerator):
    """Removes every second point."""

    name = "half"

    def __init__(self):
        pass

    def damage(self, frames, seed, colors=None):
        removed = [np.arange(len(f)) % 2 == 1 for f in frames]
        return DamageResult([f[~m] for f, m in zip(frames, removed)], removed, [[] for _ in frames], colors)


def _size_ratio(pair, selection, settings):
    return len(pair.result) / len(pair.reference)


SIZE_RATIO = Metric("size_ratio", None, "1", "7", "result points over reference points", _size_ratio)
'''

ENTRY_POINTS = """[dpcbench.methods]
centroid-fill = dpcb_testplug:CentroidFill
broken-fill = dpcb_testplug_broken:Fill
temporal-graph = dpcb_testplug:CentroidFill
not-a-method = dpcb_testplug:_size_ratio

[dpcbench.holes]
half = dpcb_testplug:HalfHoles

[dpcbench.metrics]
size_ratio = dpcb_testplug:SIZE_RATIO
"""


@pytest.fixture()
def plugin_site(tmp_path):
    """A folder holding an 'installed' distribution (its .dist-info with entry_points.txt) and its
    modules, as pip would lay them out in site-packages; on PYTHONPATH it is found by
    importlib.metadata like any installed distribution."""
    site = tmp_path / "site"
    info = site / "dpcb_testplug-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: dpcb-testplug\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    (site / "dpcb_testplug.py").write_text(PLUGIN_MODULE)
    (site / "dpcb_testplug_broken.py").write_text("raise RuntimeError('this plug-in is broken on purpose')\n")
    return site


def _python(code: str, site, cwd=REPO):
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_entry_point_plugins_are_registered_lazily_and_a_broken_or_colliding_one_is_reported(plugin_site):
    code = """
import json, sys
from dpcbench.methods.registry import METHODS, method_class, method_version
from dpcbench.holes.registry import GENERATORS
from dpcbench.metrics.registry import METRICS, get_metric
names = sorted(METHODS)
lazy = "dpcb_testplug" not in sys.modules and "dpcb_testplug_broken" not in sys.modules
cls = method_class("centroid-fill")
status = METHODS.available()
from dpcbench.bench.experiment.config import parse_config
cfg = parse_config({"experiment": {"name": "d"}, "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 1}],
                    "holes": [{"generator": "region"}], "methods": [{"name": "none"}]})
print(json.dumps({"default_metrics": cfg.metrics["names"], "names": names, "lazy": lazy, "cls": cls.__name__, "builtin_tg": METHODS["temporal-graph"],
                  "plugins": METHODS.plugins, "status": status, "version": method_version("centroid-fill"),
                  "holes": sorted(GENERATORS), "metric": get_metric("size_ratio").version,
                  "metric_level": METRICS["size_ratio"].level}))
"""
    proc = _python(code, plugin_site)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert "centroid-fill" in out["names"] and "broken-fill" in out["names"] and out["lazy"]
    assert out["cls"] == "CentroidFill" and out["plugins"]["centroid-fill"] == "dpcb-testplug"
    # the colliding entry point is refused; the built-in keeps its name
    assert out["builtin_tg"] == "dpcbench.methods.temporal_graph:TemporalGraph"
    refused = out["status"]["temporal-graph (dpcb-testplug)"]
    assert "refused: 'temporal-graph' is a built-in method" in refused and "another name" in refused
    assert "RuntimeError: this plug-in is broken on purpose" in out["status"]["broken-fill"]
    assert "not a subclass of dpcbench.methods.base.InpaintingMethod" in out["status"]["not-a-method"]
    assert out["status"]["centroid-fill"] is None and out["status"]["temporal-graph"] is None
    # no declared version: keyed by the sha256 of the module's source
    import hashlib

    digest = hashlib.sha256((plugin_site / "dpcb_testplug.py").read_bytes()).hexdigest()[:16]
    assert out["version"] == f"sha256:{digest}"
    assert "half" in out["holes"] and out["metric"] == "7" and out["metric_level"] == "frame"
    # an installed metric plug-in is scored where named, never added to a config's default metrics
    assert "size_ratio" not in out["default_metrics"] and "gpsnr_d1" in out["default_metrics"]


def test_list_shows_plugins_and_a_broken_plugin_breaks_no_other_command(plugin_site, tmp_path):
    code = """
import sys
from dpcbench.bench.cli import main
sys.exit(main(sys.argv[1:]))
"""
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(plugin_site), "DPCBENCH_CACHE": str(tmp_path / "cache")}

    def cli(*argv):
        return subprocess.run([sys.executable, "-c", code, *argv], cwd=REPO, env=env, capture_output=True,
                              text=True, timeout=300)

    proc = cli("list")
    assert proc.returncode == 0, proc.stderr
    lines = {line.split()[0]: line for line in proc.stdout.splitlines() if line.startswith("  ")}
    assert "[plug-in from dpcb-testplug] adds each hole region's centre" in lines["centroid-fill"]
    assert "unavailable: ImportError: method 'broken-fill'" in lines["broken-fill"]
    assert "failed to import: RuntimeError" in lines["broken-fill"]
    assert "refused: 'temporal-graph' is a built-in method" in proc.stdout
    assert "[plug-in from dpcb-testplug]" in lines["half"] and "[plug-in from dpcb-testplug]" in lines["size_ratio"]
    # the broken plug-in is reported where it is used, in one line, exit 2; other methods still run
    proc = cli("inpaint", "human", "--param", "x=1", "--method", "broken-fill", "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "cannot be used here" in proc.stderr and "RuntimeError: this plug-in is broken on purpose" in proc.stderr
    seq = tmp_path / "seq"
    assert cli("generate", "human", "--param", "size=tiny", "--frames", "1", "--out", str(seq)).returncode == 0
    damaged = tmp_path / "damaged"
    assert cli("damage", str(seq), "--holes", "region", "--seed", "0", "--out", str(damaged)).returncode == 0
    proc = cli("inpaint", str(damaged), "--method", "centroid-fill", "--param", "copies=2",
               "--regions", str(damaged / "holes.json"), "--out", str(tmp_path / "filled"))
    assert proc.returncode == 0, proc.stderr
    regions = json.loads((damaged / "holes.json").read_text())["frames"][0]["regions"]
    from dpcbench.bench.data.plyio import read_ply

    before = read_ply(next(damaged.glob("*.ply"))).points
    after = read_ply(next((tmp_path / "filled").glob("*.ply"))).points
    assert len(after) == len(before) + 2 * len(regions)


def test_an_import_path_names_a_method_and_its_version_follows_its_source(tmp_path, monkeypatch):
    """``name = "pkg.mod:Class"`` in a config: no registration; the run ids follow a declared
    ``version`` when there is one, else the module's source (a changed plug-in is rerun)."""
    from dpcbench.bench.experiment.config import parse_config
    from dpcbench.methods.registry import METHODS, method_class

    source = PLUGIN_MODULE.replace("CentroidFill", "PathFill")
    (tmp_path / "dpcb_pathplug.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))

    def ids():
        import sys

        sys.modules.pop("dpcb_pathplug", None)
        cfg = {"experiment": {"name": "p"}, "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 1}],
               "holes": [{"generator": "region"}], "methods": [{"name": "dpcb_pathplug:PathFill"}]}
        spec = parse_config(cfg).expand()[0]
        return spec.run_id, spec.versions["method"], spec.method["entry"]

    assert "dpcb_pathplug:PathFill" in METHODS and METHODS.is_plugin("dpcb_pathplug:PathFill")
    first = ids()
    assert first[1].startswith("sha256:") and first[2] == "dpcb_pathplug:PathFill"
    assert ids() == first  # the same source: the same ids
    (tmp_path / "dpcb_pathplug.py").write_text(source + "\n# a comment changes the source\n")
    second = ids()
    assert second[0] != first[0] and second[1] != first[1]
    (tmp_path / "dpcb_pathplug.py").write_text(source.replace('needs_regions = True', 'needs_regions = True\n    version = "3"'))
    third = ids()
    assert third[1] == "3"
    (tmp_path / "dpcb_pathplug.py").write_text(source.replace('needs_regions = True', 'needs_regions = True\n    version = "3"') + "\n#\n")
    assert ids() == third  # a declared version is the key: a source edit without a bump keeps the ids
    # a built-in named by its import path keeps its own version
    assert METHODS.version_of("dpcbench.methods.reference:NoFill") == method_class("none").version
    with pytest.raises(ImportError, match=r"method 'dpcb_nowhere:X' \(dpcb_nowhere:X, by import path\) cannot be imported"):
        method_class("dpcb_nowhere:X")


def test_an_import_path_resolves_against_the_current_directory(tmp_path):
    """A module beside the config (not installed, not on sys.path) is found by import path."""
    (tmp_path / "dpcb_cwdplug.py").write_text(PLUGIN_MODULE)
    proc = _python("from dpcbench.methods.registry import method_class; print(method_class('dpcb_cwdplug:CentroidFill').name)",
                   tmp_path / "empty", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "centroid-fill"


def test_discover_refuses_a_second_distribution_of_the_same_name_and_a_bad_value():
    from types import SimpleNamespace

    from dpcbench.holes.lazy import LazyRegistry

    def ep(name, value, dist):
        return SimpleNamespace(name=name, value=value, dist=SimpleNamespace(name=dist))

    registry = LazyRegistry("widget", {"path": "pathlib:PurePosixPath"}, group="dpcbench.widgets")
    registry.discover([ep("a", "pathlib:Path", "one"), ep("a", "os:getcwd", "two"), ep("b", "not an import path", "one"),
                       ep("path", "os:sep", "three")])
    assert sorted(registry) == ["a", "path"] and registry["a"] == "pathlib:Path" and registry.plugins == {"a": "one"}
    assert "already registered by distribution one" in registry.refused["a (two)"]
    assert "is not 'package.module:Attr'" in registry.refused["b (one)"]
    assert "'path' is a built-in widget" in registry.refused["path (three)"]


def _points_ratio(pair, selection, settings):
    """Result points over reference points (a plug-in metric for the test below)."""
    return len(pair.result) / len(pair.reference)


def _metric():
    from dpcbench.metrics.registry import Metric

    return Metric("points_ratio", None, "1", "2", "result points over reference points", _points_ratio)


POINTS_RATIO = _metric()


def test_a_metric_named_by_import_path_is_scored_and_stored_by_a_run(tmp_path, monkeypatch):
    from dpcbench.bench.execution.runner import run_experiment
    from dpcbench.bench.experiment.config import parse_config
    from dpcbench.bench.results.store import ResultsStore
    from dpcbench.metrics import score_frame
    from tests import runner_fixtures as helpers

    name = "tests.test_registries:POINTS_RATIO"
    assert score_frame(np.zeros((4, 3)) + np.arange(4)[:, None], np.arange(6.0).reshape(2, 3), [name, "chamfer"])[name] == 0.5
    helpers.register(monkeypatch)
    monkeypatch.chdir(REPO)  # the worker imports tests.* from the repo root
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=300)
    specs = parse_config({"experiment": {"name": "m", "timeout_s": 120}, "sequences": [{"path": str(seq)}],
                          "holes": [{"generator": "test-ball", "params": {"radius": 0.3}}],
                          "methods": [{"name": "none"}],
                          "metrics": {"names": ["chamfer", name], "peaks": ["intrinsic"], "scopes": ["frame"]}}).expand()
    assert specs[0].versions["metrics"][name] == "2"
    store = ResultsStore(tmp_path / "store.sqlite")
    summary = run_experiment(specs, store, executor="serial", quiet=True)
    assert len(summary.done) == 1, summary.errors
    rows = store.results_frame()
    ratio = rows[rows.metric == name]
    removed = rows[rows.metric == "removed_fraction"].sort_values("frame").value.to_numpy()
    # "none" returns the damaged frame: result points / reference points = 1 - removed fraction
    np.testing.assert_allclose(ratio.sort_values("frame").value.to_numpy(), 1 - removed)
