"""The lazy registries (`holes.lazy`) behind hole generators and methods, and "no holes" as the
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
    from dpcbench.bench.config import parse_config

    cfg = {"experiment": {"name": "real"}, "sequences": [{"name": "human", "params": {"size": "tiny"}, "frames": 1}],
           "holes": [{"generator": "none", "seeds": [3, 4]}], "methods": [{"name": "none"}]}
    specs = parse_config(cfg).expand()
    assert len(specs) == 1  # the seed plays no part: one run
    assert specs[0].identity()["holes"] == {"generator": "none", "params": {}, "seed": 0}
    assert specs[0].versions["generator"] == "1" and specs[0].holes["entry"] == "dpcbench.holes.base:NoHoles"
    # the ids the special-cased "none" gave at 1a064a3 (run folders and stored runs stay valid)
    assert (specs[0].run_id, specs[0].inpaint_key) == ("828a587a394c3200", "02c0df3394862278")


def test_a_run_without_holes_stores_no_quality_score(tmp_path, monkeypatch):
    from dpcbench.bench.config import parse_config
    from dpcbench.bench.runner import run_experiment
    from dpcbench.bench.store import ResultsStore
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
