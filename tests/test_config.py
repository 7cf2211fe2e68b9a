"""Experiment configs: validation naming the offending key, grid expansion, stable run ids."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from dpcbench.bench.experiment.config import ConfigError, canonical_json, load_config, parse_config, stable_hash
from dpcbench.holes.detection import DETECT_HOLES_VERSION
from tests import runner_fixtures as helpers


@pytest.fixture
def seq_dir(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    return helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=200)


def _config(seq_dir):
    return {
        "experiment": {"name": "t", "timeout_s": 60},
        "sequences": [{"path": str(seq_dir), "frames": 2}],
        "holes": [{"generator": "test-ball", "params": {"radius": [0.2, 0.3]}, "seeds": [0, 1]}],
        "methods": [{"name": "test-identity", "params": {"shift": [0.0, 0.5, 1.0]}},
                    {"name": "test-raises"}],
        "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame", "holes"]},
    }


def _ids(cfg_dict):
    return [r.run_id for r in parse_config(cfg_dict).expand()]


def test_grid_is_the_cartesian_product(seq_dir):
    runs = parse_config(_config(seq_dir)).expand()
    # holes: 2 radii x 2 seeds; methods: 3 shifts + 1
    assert len(runs) == 4 * 4
    assert len({r.run_id for r in runs}) == 16
    combos = {(r.holes["params"]["radius"], r.holes["seed"], r.method["name"], r.method["params"].get("shift"))
              for r in runs}
    assert len(combos) == 16
    assert all(r.method["entry"].startswith("tests.") for r in runs)


def test_ids_are_stable_and_change_with_every_parameter(seq_dir):
    base = _config(seq_dir)
    ids = _ids(base)
    assert ids == _ids(copy.deepcopy(base))
    changes = [
        ("holes", 0, "seeds", [0, 2]),
        ("holes", 0, "params", {"radius": [0.2, 0.31]}),
        ("methods", 0, "params", {"shift": [0.0, 0.5, 1.5]}),
    ]
    for table, i, key, value in changes:
        changed = copy.deepcopy(base)
        changed[table][i][key] = value
        assert set(_ids(changed)) != set(ids), (table, key)
    for key, value in [("names", ["gpsnr_d1", "nshd"]), ("peaks", [1023]), ("scopes", ["frame"]),
                       ("region_margin", 2.0)]:
        changed = copy.deepcopy(base)
        changed["metrics"][key] = value
        new = parse_config(changed).expand()
        old = parse_config(base).expand()
        assert all(a.run_id != b.run_id for a, b in zip(new, old)), key
        # the inpainted frames do not depend on the metrics: they are reused
        assert [a.inpaint_key for a in new] == [b.inpaint_key for b in old]
    changed = copy.deepcopy(base)
    changed["sequences"][0]["frames"] = [0, 1]
    assert set(_ids(changed)).isdisjoint(ids)


def test_a_frame_step_loads_every_step_th_frame_under_its_own_ids(tmp_path, monkeypatch):
    """frames = [start, stop, step]: a lower frame rate of the same capture; the frames loaded are exactly
    start, start + step, ... < stop, and the runs are not those of [start, stop)."""
    from dpcbench.bench.data.datasets import load_run_sequence

    helpers.register(monkeypatch)
    folder = helpers.write_sequence(tmp_path / "seq", n_frames=5, n_points=200)
    every = _config(folder)
    every["sequences"][0]["frames"] = [0, 5]
    strided = copy.deepcopy(every)
    strided["sequences"][0]["frames"] = [1, 5, 2]
    assert set(_ids(strided)).isdisjoint(_ids(every))
    whole = load_run_sequence(parse_config(every).expand()[0].sequence)
    loaded = load_run_sequence(parse_config(strided).expand()[0].sequence)
    assert len(whole.frames) == 5 and len(loaded.frames) == 2
    for got, index in zip(loaded.frames, (1, 3)):
        np.testing.assert_array_equal(got.points, whole.frames[index].points)


def test_key_order_numbers_and_labels_do_not_change_ids(seq_dir):
    base = _config(seq_dir)
    reordered = {k: base[k] for k in reversed(list(base))}
    reordered["methods"] = [{"params": {"shift": [0.0, 0.5, 1.0]}, "name": "test-identity"}, {"name": "test-raises"}]
    reordered["metrics"] = dict(reversed(list(base["metrics"].items())))
    assert _ids(reordered) == _ids(base)
    floats = copy.deepcopy(base)
    floats["methods"][0]["params"]["shift"] = [0, 0.5, 1]  # ints for whole floats
    assert _ids(floats) == _ids(base)
    labelled = copy.deepcopy(base)
    labelled["methods"][0]["label"] = "Shifted"
    labelled["experiment"]["description"] = "words"
    assert _ids(labelled) == _ids(base)
    assert stable_hash({"a": 1, "b": [1.0, 2.5]}) == stable_hash({"b": [1, 2.5], "a": 1.0})


def test_stable_hash_is_pinned():
    """Run ids and store keys are stable_hash values: a change to the canonical JSON or the digest
    silently orphans every stored result, so one value is pinned literally."""
    value = {"d": None, "c": "text", "b": [1.0, 2.5], "a": 1}
    assert canonical_json(value) == '{"a":1,"b":[1,2.5],"c":"text","d":null}'
    assert stable_hash(value) == "bbf57cfc3d7358ce"


def test_method_version_and_data_change_ids(seq_dir, monkeypatch):
    base = _config(seq_dir)
    ids = _ids(base)
    monkeypatch.setattr(helpers.IdentityFill, "version", "2")
    assert set(_ids(base)) != set(ids)
    monkeypatch.setattr(helpers.IdentityFill, "version", "1")
    assert _ids(base) == ids
    helpers.write_sequence(seq_dir, n_frames=2, n_points=210)  # data changed on disk
    assert set(_ids(base)).isdisjoint(ids)


def test_a_coarser_voxel_grid_is_other_data_with_its_own_ids(seq_dir):
    """``voxel_size`` on PLY frames is part of the sequence's identity; 1 is the frames as they are, written or not
    (a grid axis of both gives two sets of runs)."""
    base = _config(seq_dir)
    coarse = copy.deepcopy(base)
    coarse["sequences"][0]["params"] = {"voxel_size": 2}
    assert set(_ids(coarse)).isdisjoint(_ids(base))
    grid = copy.deepcopy(base)
    grid["sequences"][0]["params"] = {"voxel_size": [1, 2]}
    assert len(_ids(grid)) == 2 * len(_ids(base))


def test_data_is_identified_by_content_not_by_place_or_mtime(seq_dir, tmp_path, monkeypatch):
    """Touched data and a copy of it elsewhere keep their run ids; the same size with other bytes does not."""
    import os
    import shutil

    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    ids = _ids(_config(seq_dir))
    for frame in seq_dir.iterdir():
        os.utime(frame, ns=(1_600_000_000_000_000_000, 1_600_000_000_000_000_000))
    assert _ids(_config(seq_dir)) == ids
    copy_dir = shutil.copytree(seq_dir, tmp_path / "elsewhere" / seq_dir.name)
    assert _ids(_config(copy_dir)) == ids
    frame = sorted(copy_dir.glob("*.ply"))[0]
    data = bytearray(frame.read_bytes())
    data[-1] ^= 1  # one bit of the last point's coordinates
    frame.write_bytes(bytes(data))
    assert set(_ids(_config(copy_dir))).isdisjoint(ids)


def test_file_digest_is_cached_by_path_size_and_mtime(tmp_path, monkeypatch):
    import hashlib
    import os

    from dpcbench.bench.data import file_digest

    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "frame.ply"
    path.write_bytes(b"x" * 3_000_000)  # more than one read chunk
    truth = hashlib.sha256(path.read_bytes()).hexdigest()
    assert file_digest.file_sha256(path) == truth
    entries = list((tmp_path / "cache" / "file-digests").iterdir())
    assert len(entries) == 1
    # unchanged file: the digest comes from the cache entry (a planted one shows it was not read again)
    entries[0].write_text(entries[0].read_text().split("\n")[0] + "\n" + "0" * 64 + "\n")
    assert file_digest.file_sha256(path) == "0" * 64
    # a new mtime is a new key: the file is read again
    os.utime(path, ns=(1_600_000_000_000_000_000, 1_600_000_000_000_000_000))
    assert file_digest.file_sha256(path) == truth
    # a corrupt entry is a re-read, not an error
    for entry in (tmp_path / "cache" / "file-digests").iterdir():
        entry.write_text("garbage")
    assert file_digest.file_sha256(path) == truth


@pytest.mark.parametrize("mutate, key", [
    (lambda c: c["methods"][0]["params"].update(shift="big"), "methods[0].params.shift: expected a number"),
    (lambda c: c["methods"][1].update(name="nope"), "methods[1].name: unknown method 'nope'"),
    (lambda c: c["methods"][0]["params"].update(shfit=1), "methods[0].params.shfit: unknown parameter"),
    (lambda c: c["holes"][0].update(generator="nope"), "holes[0].generator: unknown hole generator"),
    (lambda c: c["holes"][0].update(seeds=["a"]), "holes[0].seeds: expected a non-empty list of integers"),
    (lambda c: c["metrics"].update(peaks=[-1]), "metrics.peaks[0]"),
    (lambda c: c["metrics"].update(scopes=["everywhere"]), "metrics.scopes"),
    (lambda c: c["sequences"][0].update(frames=0), "sequences[0].frames"),
    (lambda c: c["sequences"][0].update(frames=[0, 2, 0]), "sequences[0].frames: expected a positive count"),
    (lambda c: c["sequences"][0].update(frames=[0, 2, 1, 1]), "sequences[0].frames"),
    (lambda c: c["sequences"][0].update(frames=[0, 5, 2]), "sequences[0].frames: asks for 5 frames"),
    (lambda c: c["sequences"][0].update(path="/does/not/exist"), "sequences[0].path"),
    (lambda c: c["sequences"][0].update(colour=1), "sequences[0].colour: unknown key"),
    (lambda c: c["sequences"][0].update(params={"size": "tiny"}), "sequences[0].params: unknown parameter(s) size"),
    (lambda c: c["sequences"][0].update(params={"voxel_size": 0}), "sequences[0].params: voxel_size must be"),
    (lambda c: c["experiment"].pop("name"), "experiment.name: missing"),
    (lambda c: c.pop("methods"), "methods: missing"),
    (lambda c: c["methods"][0]["params"].update(shift=[]), "methods[0].params.shift: an empty list"),
])
def test_validation_names_the_offending_key(seq_dir, mutate, key):
    cfg = _config(seq_dir)
    mutate(cfg)
    with pytest.raises(ConfigError) as info:
        parse_config(cfg).expand()
    assert key in str(info.value)


def test_toml_file_and_syntax_errors(seq_dir, tmp_path):
    path = tmp_path / "exp.toml"
    path.write_text('''
[experiment]
name = "file"

[[sequences]]
path = "seq"
frames = [0, 2]

[[holes]]
generator = "test-ball"
seed = 3

[[methods]]
name = "test-identity"
params = { shift = [0.0, 1.0] }

[metrics]
names = ["gpsnr_d1"]
''')
    (tmp_path / "seq").exists() or helpers.write_sequence(tmp_path / "seq", 2, 200)
    runs = load_config(path).expand()
    assert len(runs) == 2 and runs[0].sequence["path"] == str((tmp_path / "seq").resolve())
    assert runs[0].holes["seed"] == 3
    path.write_text("[experiment\nname = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(path)
    with pytest.raises(ConfigError, match="no such config file"):
        load_config(tmp_path / "missing.toml")


def test_blind_runs_carry_the_detector_version(seq_dir, monkeypatch):
    """regions = "none": each method runs detect_holes itself (defaults), so a detector version bump
    must give new run ids (never a result made with the old detector's regions); given-region runs keep theirs."""
    from dpcbench.holes import detection

    blind, given = _config(seq_dir), _config(seq_dir)
    blind["experiment"]["regions"] = "none"
    before = parse_config(blind).expand()
    assert before[0].versions["detector"] == DETECT_HOLES_VERSION
    assert "detection" not in before[0].protocol
    given_before = _ids(given)
    monkeypatch.setattr(detection, "DETECT_HOLES_VERSION", "2-test")
    assert set(_ids(blind)).isdisjoint(r.run_id for r in before)
    assert _ids(given) == given_before


def test_detection_parameters(seq_dir):
    base = _config(seq_dir)
    base["experiment"]["regions"] = "detected"
    plain = parse_config(base).expand()
    # every detect_holes parameter as the run calls it (defaults included), and the detector's version
    defaults = {"k": 32, "gap": 0.6 * np.pi, "link": 3.0, "min_points": 10, "min_inward": 0.1, "max_radius": 0.25}
    assert plain[0].protocol == {"regions": "detected", "detection": defaults}
    assert plain[0].versions["detector"] == DETECT_HOLES_VERSION
    tuned = copy.deepcopy(base)
    tuned["experiment"]["detection"] = {"min_points": 5}
    runs = parse_config(tuned).expand()
    assert runs[0].protocol["detection"] == {**defaults, "min_points": 5}
    assert runs[0].run_id != plain[0].run_id
    # naming a default explicitly is the same computation, so the same run
    explicit = copy.deepcopy(base)
    explicit["experiment"]["detection"] = {"min_points": 10}
    assert _ids(explicit) == [r.run_id for r in plain]
    for bad, key in [({"min_pionts": 5}, "experiment.detection.min_pionts: unknown parameter"),
                     ({"min_points": "many"}, "experiment.detection.min_points: expected a number")]:
        tuned["experiment"]["detection"] = bad
        with pytest.raises(ConfigError, match=key):
            parse_config(tuned)
    base["experiment"]["regions"] = "given"
    base["experiment"]["detection"] = {"min_points": 5}
    with pytest.raises(ConfigError, match="only used with regions"):
        parse_config(base)


_PRESETS = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "bench" / "presets").glob("*.toml"))


@pytest.mark.parametrize("preset", _PRESETS)
def test_shipped_presets_expand(preset):
    """Every preset under bench/presets parses and expands into runs with distinct ids; a held-out one names the
    tuning preset it holds out from."""
    from dpcbench.bench.reporting.paper import PRESETS_DIR

    config = load_config(PRESETS_DIR / f"{preset}.toml")
    if config.data_role == "heldout":
        tuning = {load_config(PRESETS_DIR / f"{p}.toml").name for p in _PRESETS if p.endswith("-targets")}
        assert config.holds_out in tuning
    specs = config.expand()  # optional sequences whose data is not here are skipped
    if not specs and config.skipped:
        pytest.skip(f"{preset}: every sequence is optional and none of their data is here ({config.skipped[0]})")
    assert specs and len({s.run_id for s in specs}) == len(specs)
    assert {s.method["name"] for s in specs} >= {"fu-nonlocal", "temporal-graph"}


def test_a_none_text_is_none_where_the_parameter_admits_none_and_no_text():
    """TOML has no null: "none" (or "null", any case, in a grid list too) is None for a parameter annotated
    ``int | None`` / ``float | None`` (a stand-in's bit_depth, a region's count, a method's off_surface) and stays
    text where the parameter takes text (temporal-graph's ``spacing: float | str | None``, whose own check then refuses
    it); the run id is that of None."""
    def config(sequence_params, hole_params, method_params):
        return {"experiment": {"name": "none-text"},
                "sequences": [{"name": "cow", "params": sequence_params, "frames": 2}],
                "holes": [{"generator": "region", "params": hole_params, "seed": 0}],
                "methods": [{"name": "temporal-graph", "params": method_params}],
                "metrics": {"names": ["gpsnr_d1"]}}

    texts = parse_config(config({"size": "tiny", "bit_depth": ["None", 10]}, {"count": "null"},
                                {"off_surface": "none"})).expand()
    assert [r.sequence["params"]["bit_depth"] for r in texts] == [None, 10]
    assert {r.holes["params"]["count"] for r in texts} == {None}
    assert {r.method["params"]["off_surface"] for r in texts} == {None}
    nones = parse_config(config({"size": "tiny", "bit_depth": None}, {"count": None},
                                {"off_surface": None})).expand()
    assert texts[0].run_id == nones[0].run_id
    with pytest.raises(ConfigError, match="spacing must be a positive number, got 'none'"):  # kept as text
        parse_config(config({"size": "tiny"}, {}, {"spacing": "none"}))
