"""Colour through runs: a run on coloured data stores coloured inpainted frames (the method's colours,
fill "auto") and scores the cpsnr_* metrics; on data without colour they are left out; a run folder
written without colours is made anew."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dpcbench.bench.data.plyio import PointCloud
from dpcbench.bench.data.sequences import save_sequence
from dpcbench.bench.execution.provenance import read_run_folder
from dpcbench.bench.execution.runner import run_experiment
from dpcbench.bench.experiment.config import parse_config
from dpcbench.bench.results.store import ResultsStore
from tests.runner_fixtures import sphere_frames

REPO = Path(__file__).resolve().parents[1]


def _write(folder: Path, coloured: bool) -> Path:
    frames = sphere_frames(3, 900)
    clouds = []
    for f in frames:  # colour varies smoothly over the sphere, so a fill can be told from a wrong one
        colours = np.clip(np.rint((f[:, :3] + 1.2) * 100), 0, 255).astype(np.uint8) if coloured else None
        clouds.append(PointCloud(f, colours))
    save_sequence(clouds, folder, prefix="sphere")
    return folder


def _cfg(seq: Path, methods: list[str], metrics=("gpsnr_d1", "cpsnr_y")) -> dict:
    return {
        "experiment": {"name": "colour", "timeout_s": 300},
        "sequences": [{"path": str(seq), "label": "sphere"}],
        "holes": [{"generator": "region", "params": {"preset": "small", "count": 1}, "seed": 3}],
        "methods": [{"name": m} for m in methods],
        "metrics": {"names": list(metrics), "peaks": ["intrinsic"], "scopes": ["frame", "holes"]},
    }


def _run(tmp_path, seq, methods, **kw):
    metrics = kw.pop("metrics", ("gpsnr_d1", "cpsnr_y"))
    store = ResultsStore(tmp_path / "store.sqlite")
    summary = run_experiment(parse_config(_cfg(seq, methods, metrics)).expand(), store, executor="serial",
                             quiet=True, runs_dir=tmp_path / "runs", **kw)
    return store, summary


@pytest.fixture
def in_repo(monkeypatch):
    monkeypatch.chdir(REPO)


def test_a_run_on_coloured_data_scores_colour_psnr_of_coloured_frames(tmp_path, in_repo):
    from dpcbench.methods._colour import colour_outputs

    seq = _write(tmp_path / "seq", coloured=True)
    store, summary = _run(tmp_path, seq, ["none", "lozes-pde"])
    assert not summary.failed
    df = store.results_frame()
    colour = df[df.metric == "cpsnr_y"]
    assert set(colour.scope) == {"frame", "holes"} and set(colour.method) == {"none", "lozes-pde"}
    assert len(colour[colour.scope == "frame"]) == 2 * 3 and np.isfinite(colour.value).all()
    # the stored frames carry exactly the colours `inpaint_with_colours` gives (fill "auto")
    runs = store.runs_frame().set_index("method")
    folder = read_run_folder(Path(runs.loc["lozes-pde", "output_dir"]))
    assert folder["inpainted_colors"] is not None
    damaged_colours = [c for c in _damaged_colours(Path(runs.loc["lozes-pde", "output_dir"]))]
    expected = colour_outputs(folder["damaged"], damaged_colours, folder["inpainted"], None, "auto")
    for got, want in zip(folder["inpainted_colors"], expected):
        np.testing.assert_array_equal(got, want)


def _damaged_colours(run_dir: Path) -> list[np.ndarray]:
    from dpcbench.bench.data.plyio import read_ply

    return [read_ply(p).colors for p in sorted((run_dir / "damaged").glob("*.ply"))]


def test_data_without_colour_has_no_colour_rows(tmp_path, in_repo):
    seq = _write(tmp_path / "seq", coloured=False)
    store, summary = _run(tmp_path, seq, ["none"])
    assert not summary.failed
    df = store.results_frame()
    assert "cpsnr_y" not in set(df.metric) and "gpsnr_d1" in set(df.metric)


def test_a_run_folder_without_colours_is_made_anew(tmp_path, in_repo):
    import json

    from dpcbench.bench.data.plyio import read_ply, write_ply
    from dpcbench.bench.execution.provenance import folder_checksums

    seq = _write(tmp_path / "seq", coloured=True)
    store, _ = _run(tmp_path, seq, ["none"], metrics=("gpsnr_d1",))
    run_dir = Path(store.runs_frame()["output_dir"].iloc[0])
    # the folder as a dpcbench before coloured run folders wrote it: inpainted frames without colours
    for path in (run_dir / "inpainted").glob("*.ply"):
        write_ply(path, PointCloud(read_ply(path).points))
    manifest = json.loads((run_dir / "manifest.json").read_text())
    manifest["sha256"] = folder_checksums(run_dir)
    (run_dir / "manifest.json").write_text(json.dumps(manifest))
    assert read_run_folder(run_dir)["inpainted_colors"] is None
    # a new metric on the same inpainting (same run folder, reused when it can be): the colourless folder is
    # made anew, and colour is scored
    store, summary = _run(tmp_path, seq, ["none"])
    assert not summary.failed and len(summary.done) == 1
    assert read_run_folder(run_dir)["inpainted_colors"] is not None
    assert "cpsnr_y" in set(store.results_frame().metric)


def test_colour_fill_of_an_experiment_is_used_and_named_in_the_run_identity(tmp_path, in_repo):
    from dpcbench.bench.experiment.config import ConfigError

    seq = _write(tmp_path / "seq", coloured=True)
    default = parse_config(_cfg(seq, ["lozes-pde"])).expand()
    cfg = _cfg(seq, ["lozes-pde"])
    cfg["experiment"]["colour_fill"] = "auto"
    assert [s.run_id for s in parse_config(cfg).expand()] == [s.run_id for s in default]  # the default: same ids
    cfg["experiment"]["colour_fill"] = "nearest"
    nearest = parse_config(cfg).expand()
    assert nearest[0].protocol["colour_fill"] == "nearest" and nearest[0].run_id != default[0].run_id
    assert nearest[0].inpaint_key != default[0].inpaint_key  # its own run folder: the colours differ
    store = ResultsStore(tmp_path / "store.sqlite")
    assert not run_experiment(nearest, store, executor="serial", quiet=True, runs_dir=tmp_path / "runs").failed
    folder = read_run_folder(Path(store.runs_frame()["output_dir"].iloc[0]))
    from dpcbench.methods._colour import colour_outputs

    want = colour_outputs(folder["damaged"], _damaged_colours(Path(store.runs_frame()["output_dir"].iloc[0])),
                          folder["inpainted"], None, "nearest")
    for got, expected in zip(folder["inpainted_colors"], want):
        np.testing.assert_array_equal(got, expected)
    cfg["experiment"]["colour_fill"] = "sepia"
    with pytest.raises(ConfigError, match="colour_fill: expected one of auto, nearest, harmonic, source"):
        parse_config(cfg)
