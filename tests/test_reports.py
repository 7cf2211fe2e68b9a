"""Tables (closed-form cells, bold best, paper rows, three formats), reports from a store, the paper
protocol's expansion and stand-in labelling."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pandas as pd
import pytest

from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.reporting import paper
from dpcbench.bench.reporting.reports import paper_tables, write_comparison_report, write_paper_report
from dpcbench.bench.reporting.tables import comparison_table
from dpcbench.bench.results.store import ResultsStore
from tests.runner_fixtures import tidy_results

METHODS = ["meshlab", "lozes-pde", "fu-nonlocal", "temporal-graph"]
#: each of the paper's columns as reproduce-paper runs it (the paper configurations)
PAPER_PARAMS = {name: params for name, _, params in paper.PAPER_METHODS}


def _store_with_results(path, sequences=("Human (stand-in)", "Bunny (stand-in)"), frames=3, experiment="exp",
                        seeds=(0,), coloured=()):
    """Per frame f of method k on sequence s, with every seed: gpsnr_d1 = 10 + 5k + f (+1 on the
    second sequence), nshd = (4 - k) * 1e-7 * (f + 1); on the sequences in ``coloured`` also cpsnr_y = 30 + k + f
    (whole frame)."""
    store = ResultsStore(path)
    for s_i, seq in enumerate(sequences):
        for k, method in enumerate(METHODS):
            for seed in seeds:
                rows = []
                for f in range(frames):
                    rows.append({"frame": f, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic",
                                 "value": 10.0 + 5 * k + f + s_i})
                    rows.append({"frame": f, "metric": "nshd", "scope": "frame", "peak": "",
                                 "value": (4 - k) * 1e-7 * (f + 1)})
                    rows.append({"frame": f, "metric": "time_s", "scope": "frame", "peak": "", "value": 0.5 * (k + 1)})
                    if seq in coloured:
                        rows.append({"frame": f, "metric": "cpsnr_y", "scope": "frame", "peak": "",
                                     "value": 30.0 + k + f})
                rows.append({"frame": -1, "metric": "time_s", "scope": "frame", "peak": "",
                             "value": 0.5 * (k + 1) * frames})
                rows.append({"frame": -1, "metric": "peak_mem_mb", "scope": "frame", "peak": "", "value": 100.0 + k})
                record = {"sequence": seq, "holes": "region", "holes_params": {"preset": "medium"}, "seed": seed,
                          "method": method, "method_params": PAPER_PARAMS[method], "method_version": "1",
                          "code_version": "abc", "spec": {},
                          "env": {"git_commit": "abc", "python": "3.11", "packages": {}, "machine": {}}}
                store.record_run(f"{seq[:3]}-{method}" + (f"-{seed}" if seed else ""), record, rows, [experiment])
    store.record_failure("bad-run", {"sequence": sequences[0], "method": "meshlab", "spec": {}}, "MeshlabError: boom",
                         [experiment])
    return store


def test_table_cells_best_and_formats(tmp_path):
    store = _store_with_results(tmp_path / "s.sqlite", seeds=(0, 1, 2))
    df = store.results_frame("exp")
    t1, t2 = paper_tables(df, standins=True)
    # closed form: mean over frames 0..2 (each for 3 seeds) of 10 + 5k + f + s_i = 11 + 5k + s_i;
    # sample std over the 9 values sqrt(6/8); the interval is over whole damages (the seeds), and the three
    # seeds' values are the same, so the damage means agree exactly and the interval has zero width
    half = 0.0
    assert t1.mean[("Human (stand-in)", "Proposed")] == pytest.approx(26.0)
    assert t1.mean[("Bunny (stand-in)", "Meshlab")] == pytest.approx(12.0)
    assert t1.std[("Human (stand-in)", "Hu")] == pytest.approx(np.sqrt(6 / 8))
    assert t1.interval("Human (stand-in)", "Hu") == pytest.approx((21 - half, 21 + half))
    assert t1.n[("Human (stand-in)", "Lozes")] == 9
    assert t1.best("Human (stand-in)", t1.mean) == "Proposed"  # highest GPSNR
    assert t2.best("Human (stand-in)", t2.mean) == "Proposed"  # lowest NSHD
    assert t2.mean[("Human (stand-in)", "Meshlab")] == pytest.approx(8e-7)
    md = t1.markdown()
    # Proposed is 5 dB above the next on every pair: best beyond every interval, in bold
    assert ("| Human (stand-in) | – | 11.00 [11.00, 11.00] | 16.00 [16.00, 16.00] | 21.00 [21.00, 21.00] | "
            "**26.00 [26.00, 26.00]** |") in md
    # the paper's rows with the table's decimals (2 for GPSNR; the CSV keeps the 4 the paper printed)
    assert "| *Loot (paper)* | – | 16.45 | 27.37 | 40.15 | **47.56** |" in md
    assert "peak intrinsic" in md and "scope `frame`" in md and "STAND-IN" in md
    assert "n = 3 frames x 3 seeds = 9" in md and "Wilcoxon signed-rank" in md and "Holm" in md
    md2 = t2.markdown()
    assert "**2.0000 [2.0000, 2.0000]**" in md2  # Proposed: (4-3) * (f+1) x1e-7 -> mean 2 in units of 1e-7
    assert "in units of 1e-7" in md2
    tex = t1.latex()
    # LaTeX: the symmetric interval as ± its half-width, the paper's rows in italics, 2 decimals too
    assert r"\textbf{26.00}{\scriptsize$\pm$0.00}" in tex
    assert r"\textit{Loot} & -- & 16.45 & 27.37 & 40.15 & \textbf{47.56} & " in tex
    rows = list(csv.DictReader(io.StringIO(t1.csv())))
    ours = {(r["sequence"], r["method"]): r for r in rows if r["source"] == "ours"}
    assert float(ours[("Bunny (stand-in)", "Hu")]["mean"]) == pytest.approx(22.0)
    assert float(ours[("Bunny (stand-in)", "Hu")]["ci95_low"]) == pytest.approx(22 - half)
    assert ours[("Bunny (stand-in)", "Proposed")]["verdict"] == "best"
    assert ours[("Bunny (stand-in)", "Hu")]["verdict"] == "worse"
    assert {r["sequence"] for r in rows if r["source"] == "paper"} == set(paper.TABLE1_GPSNR)


def test_one_seed_of_three_frames_is_too_small_for_any_claim(tmp_path):
    t1, _ = paper_tables(_store_with_results(tmp_path / "s.sqlite").results_frame("exp"), standins=True)
    md = t1.markdown()
    assert "**" not in md.split("(paper)")[0].split("\n", 1)[1]  # no bold among our rows
    assert "n = 3 pairs is too small for any claim" in md and "needs n >= 7" in md  # Holm over 3 comparisons


def test_paper_values_and_headline():
    gains = paper.paper_mean_gains()
    for col, value in paper.HEADLINE_GAIN_DB.items():
        assert gains[col] == pytest.approx(value, abs=0.01)
    assert paper.paper_table("nshd")["Soldier"]["Proposed"] == 1.2057


def test_the_paper_facts_have_one_source():
    """config, datasets, paper and the dashboard read bench.core.paper_facts; none keeps its own copy."""
    from dpcbench.bench.core import paper_facts
    from dpcbench.bench.data import datasets
    from dpcbench.bench.experiment import config
    from dpcbench.bench.reporting import dashboard

    assert config.PAPER_SEQUENCES is paper_facts.PAPER_SEQUENCES
    assert paper.PAPER_SEQUENCES is paper_facts.PAPER_SEQUENCES and paper.TABLE1_GPSNR is paper_facts.TABLE1_GPSNR
    assert list(datasets.PAPER) == list(paper_facts.PAPER_SEQUENCES)
    assert [d.title for d in datasets.PAPER.values()] == list(paper_facts.PAPER_SEQUENCES.values())
    assert tuple(paper.COLUMNS) == paper_facts.PAPER_COLUMNS
    assert [label for _, label, _ in paper.PAPER_METHODS] == list(paper_facts.PAPER_COLUMNS)
    assert set(paper_facts.TABLE1_GPSNR) == set(paper_facts.TABLE2_NSHD_E7) == set(paper_facts.PAPER_SEQUENCES.values())
    reference = dashboard.paper_reference()
    assert set(reference["sequence"]) == set(paper_facts.PAPER_SEQUENCES)
    nshd = reference[(reference["metric"] == "nshd") & (reference["sequence"] == "ulliwegner")]
    assert nshd.set_index("method")["value"].to_dict() == pytest.approx(
        {name: v * 1e-7 for (name, _, _), v in zip(paper.PAPER_METHODS, paper_facts.TABLE2_NSHD_E7["UlliWegner"])})
    # no other module of bench spells out a published value
    import pathlib

    for path in pathlib.Path(paper_facts.__file__).parent.rglob("*.py"):
        if path.name != "paper_facts.py":
            text = path.read_text()
            assert "47.5648" not in text and "0.3549" not in text, path


def test_missing_cells_and_order(tmp_path):
    df = _store_with_results(tmp_path / "s.sqlite").results_frame("exp")
    df = df[~((df.method == "lozes-pde") & (df.sequence == "Bunny (stand-in)"))]
    t1, _ = paper_tables(df, standins=True)
    assert ("Bunny (stand-in)", "Lozes") not in t1.mean
    assert "| Bunny (stand-in) | – | 12.00 [9.52, 14.48] | – |" in t1.markdown()
    generic = comparison_table(df, "gpsnr_d1", "frame", "intrinsic")
    assert set(generic.columns) == set(METHODS)


def test_comparison_report_and_cli(tmp_path, capsys):
    _store_with_results(tmp_path / "s.sqlite")
    _store_with_results(tmp_path / "s.sqlite", experiment="other")
    out = tmp_path / "report"
    assert cli_main(["report", str(tmp_path / "s.sqlite"), "--experiment", "exp", "--out", str(out)]) == 0
    text = (out / "REPORT.md").read_text()
    assert "gpsnr_d1 (frame)" in text and "Runtime" in text and "MeshlabError: boom" in text
    for name in ("gpsnr_d1_frame.png", "gpsnr_d1_frame_per_frame.png", "nshd_frame.png"):
        assert (out / "figures" / name).stat().st_size > 1000
    assert (out / "tables" / "nshd_frame.tex").is_file()
    # two experiments and no --experiment: a clear error, no traceback
    assert cli_main(["report", str(tmp_path / "s.sqlite"), "--out", str(out)]) == 2
    assert "choose one with --experiment" in capsys.readouterr().err
    assert cli_main(["report", str(tmp_path / "nope.sqlite"), "--out", str(out)]) == 2
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"garbage" * 100)
    assert cli_main(["report", str(junk), "--out", str(out)]) == 2
    assert "move it aside" in capsys.readouterr().err


def test_paper_report_labels_stand_ins_everywhere(tmp_path):
    store = _store_with_results(tmp_path / "s.sqlite")
    df = store.results_frame("exp")
    runs = store.runs_frame("exp")
    out = tmp_path / "paper"
    report = write_paper_report(df, runs, out, standins=True, preset="paper-quick",
                                command="dpcbench reproduce-paper --quick",
                                elapsed_s=60.0, figure_notes={})
    text = report.read_text()
    assert "STAND-IN" in text and "Proposed > Hu > Lozes > Meshlab" in text
    # our gains: Proposed - Meshlab = 15 dB on both rows
    assert "| Meshlab | +15.00 | +26.80 |" in text
    for f in (out / "tables").iterdir():
        assert "stand-in" in f.read_text().lower(), f.name
    assert (out / "figures" / "table1_gpsnr.png").stat().st_size > 1000
    assert (out / "figures" / "per_frame_nshd.png").stat().st_size > 1000


def test_paper_protocol_stand_ins_and_data_dir(tmp_path, monkeypatch):
    from dpcbench.bench.data.sources import meshes

    monkeypatch.setattr(meshes, "default_data_dirs", lambda: [])  # no real-motion row (samba) here
    proto = paper.paper_protocol(quick=True, size="tiny", frames=2)
    assert proto.standins
    columns = [(s.method["name"], s.method["params"]) for s in proto.synthetic[:len(paper.TABLE_COLUMNS)]]
    assert columns == [(name, params) for name, _, params, _ in paper.TABLE_COLUMNS]
    assert columns[:5] == [("none", {}), ("meshlab", {"output": "whole"}), ("lozes-pde", {}),
                           ("fu-nonlocal", {"variant": "paper"}), ("temporal-graph", {"variant": "paper"})]
    assert {s.holes["seed"] for s in proto.synthetic} == {0, 1, 2}
    assert {s.holes["seed"] for s in paper.paper_protocol(quick=True, size="tiny", frames=2, seeds=[0]).synthetic} == {0}
    seeded = paper.paper_protocol(quick=True, size="tiny", frames=2, seeds=[0, 1, 2])
    assert {s.holes["seed"] for s in seeded.synthetic} == {0, 1, 2}
    assert len(seeded.synthetic) == len(proto.synthetic)
    with pytest.raises(ValueError, match="--seeds"):
        paper.paper_protocol(quick=True, seeds=[-1])
    assert all("stand-in" in s.sequence_label for s in proto.synthetic + proto.real)
    assert {s.protocol["regions"] for s in proto.real} == {"detected"}
    assert {s.holes["generator"] for s in proto.real} == {"occlusion"}
    # a data folder with the paper's layout: the paper's sequences replace the stand-ins
    ply = tmp_path / "data" / "longdress" / "Ply"
    ply.mkdir(parents=True)
    from dpcbench.bench.data.plyio import write_ply

    for i in range(2):
        write_ply(ply / f"longdress_vox10_{1051 + i:04d}.ply",
                  np.random.default_rng(i).integers(0, 1023, (50, 3)).astype(float))
    proto = paper.paper_protocol(quick=True, data_dir=tmp_path / "data")
    assert not proto.standins
    assert {s.sequence_label for s in proto.synthetic} == {"Longdress"}
    assert {s.holes["generator"] for s in proto.real} == {"none"}
    with pytest.raises(ValueError, match="none of the paper's sequences"):
        paper.paper_protocol(quick=True, data_dir=tmp_path)


def test_flattest_region_prefers_a_hole_in_an_open_surface():
    """A ball through a thin cylinder (a limb) against one on a plane (a torso): the plane's."""
    from dpcbench.bench.reporting.figures import flattest_region
    from dpcbench.holes.regions import HoleRegion

    rng = np.random.default_rng(1)
    angle, height = rng.uniform(0, 2 * np.pi, 4000), rng.uniform(0, 40, 4000)
    limb = np.c_[3 * np.cos(angle), height, 3 * np.sin(angle)]
    torso = np.c_[rng.uniform(20, 60, 4000), rng.uniform(0, 40, 4000), np.zeros(4000)]
    points = np.vstack([limb, torso])
    regions = [HoleRegion.ball([0.0, 20.0, 0.0], 5.0), HoleRegion.ball([40.0, 20.0, 0.0], 5.0)]
    assert flattest_region(points, regions) == 1
    assert flattest_region(points, regions[::-1]) == 0
    assert flattest_region(points, [HoleRegion.ball([500.0, 0.0, 0.0], 1.0)]) == 0  # no point inside


def test_reproduce_paper_refuses_bad_input(tmp_path, capsys):
    store = str(tmp_path / "s.sqlite")
    assert cli_main(["reproduce-paper", "--quick", "--data-dir", str(tmp_path), "--store", store]) == 2
    assert "none of the paper's sequences" in capsys.readouterr().err
    assert cli_main(["reproduce-paper", "--quick", "--data-dir", str(tmp_path / "nope"), "--store", store]) == 2
    assert "no such folder" in capsys.readouterr().err
    assert cli_main(["reproduce-paper", "--quick", "--frames", "1", "--store", store]) == 2
    assert "at least 2 frames" in capsys.readouterr().err


def test_report_keeps_hole_configurations_apart_and_uses_config_labels(tmp_path):
    """Two hole configurations of one sequence are two rows (never averaged together); a method's
    configured label names its column, and a configuration on the defaults keeps the bare name;
    an older run of a cell (e.g. an earlier method version) is left out."""
    store = ResultsStore(tmp_path / "s.sqlite")
    old = {"sequence": "Human", "holes": "region", "holes_params": {"preset": "medium", "coherent": False},
           "seed": 0, "method": "temporal-graph", "method_params": {}, "method_version": "0", "code_version": "old",
           "spec": {}, "env": {}, "created_at": "2020-01-01T00:00:00+00:00", "finished_at": "2020-01-01T00:00:00+00:00"}
    store.record_run("old-run", old, [{"frame": 0, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic",
                                       "value": 99.0}], ["exp"])
    for coherent in (False, True):
        for label, params in ((None, {}), ("tg (paper)", {"intra_candidates": 1}), (None, {"beta": 0.25})):
            value = 20.0 + 3 * coherent + params.get("beta", 0) * 4 + params.get("intra_candidates", 0)
            rows = [{"frame": f, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic", "value": value}
                    for f in range(2)]
            holes = {"preset": "medium", "coherent": coherent}
            spec = {"method": {"name": "temporal-graph", "params": params, "label": label},
                    "holes": {"generator": "region", "params": holes, "label": None}}
            record = {"sequence": "Human", "holes": "region", "holes_params": holes, "seed": 0,
                      "method": "temporal-graph", "method_params": params, "method_version": "1",
                      "code_version": "abc", "spec": spec, "env": {"git_commit": "abc"}}
            store.record_run(f"run-{coherent}-{label}-{params}", record, rows, ["exp"])
    report = write_comparison_report(store.results_frame("exp"), store.runs_frame("exp"), tmp_path / "r", title="t")
    lines = [line.strip("|").split(" | ") for line in report.read_text().splitlines() if line.startswith("| ")]
    header, body = [c.strip() for c in lines[0]], lines[1:]
    cells = {(r[0].strip(), col): r[i].strip("* ") for r in body for i, col in enumerate(header) if i}
    assert sorted(header[1:]) == ["temporal-graph", "temporal-graph (beta=0.25)", "tg (paper)"]
    assert cells[("Human · region (coherent=False)", "temporal-graph")] == "20.00 [20.00, 20.00]"
    assert cells[("Human · region (coherent=False)", "tg (paper)")] == "21.00 [21.00, 21.00]"
    assert cells[("Human · region (coherent=True)", "temporal-graph")] == "23.00 [23.00, 23.00]"
    assert cells[("Human · region (coherent=True)", "temporal-graph (beta=0.25)")] == "24.00 [24.00, 24.00]"


def test_a_label_given_to_a_grid_keeps_its_configurations_apart():
    from dpcbench.bench.reporting.tables import config_labels

    names = pd.Series(["tg", "tg", "tg", "fu"])
    params = pd.Series(['{"beta":0.25}', '{"beta":0.5}', '{"beta":0.25}', "{}"])
    given = {("tg", '{"beta":0.25}'): "ours", ("tg", '{"beta":0.5}'): "ours"}
    labels = config_labels(names, params, given=given).tolist()
    assert labels == ["ours (beta=0.25)", "ours (beta=0.5)", "ours (beta=0.25)", "fu"]
    labels = config_labels(names, params, {"fu": "Hu"}).tolist()
    assert labels == ["tg (beta=0.25)", "tg (beta=0.5)", "tg (beta=0.25)", "Hu"]


def test_a_single_value_cell_shows_no_spread():
    df = pd.DataFrame({"sequence": ["S", "S", "S"], "method": ["a", "b", "b"], "method_params": ["{}"] * 3,
                       "metric": ["gpsnr_d1"] * 3, "scope": ["frame"] * 3, "peak": ["intrinsic"] * 3,
                       "frame": [0, 0, 1], "value": [30.0, 20.0, 22.0]})
    md = comparison_table(df, "gpsnr_d1", "frame", "intrinsic").markdown()
    # b: 21 ± t(0.975, 1) * sqrt(2) / sqrt(2) = 21 ± 12.706; one shared pair is too few for any claim
    assert "| S | 30.00 | 21.00 [8.29, 33.71] |" in md and "n = 1 pairs is too small for any claim" in md


def test_facing_view_looks_at_the_hole_from_outside():
    from dpcbench.bench.reporting.figures import facing_view

    body = np.array([[0.0, 0.0, 0.0], [0.0, 100.0, 0.0]])  # centroid (0, 50, 0)
    assert facing_view(body, [0.0, 50.0, 30.0]) == pytest.approx((0.0, 0.0))      # in front: front view
    assert facing_view(body, [30.0, 50.0, 0.0])[0] == pytest.approx(-90.0)         # a side
    assert facing_view(body, [0.0, 100.0, 0.0])[1] == pytest.approx(60.0)          # the crown: from above, clipped
    assert facing_view(body, [0.0, 50.0 - 10.0, 10.0])[1] == pytest.approx(-45.0)  # below the centroid


def test_paper_presets_list_the_table_columns():
    from dpcbench.bench.experiment.config import tomllib

    for preset in ("paper-quick", "paper"):
        data = tomllib.loads((paper.PRESETS_DIR / f"{preset}.toml").read_text())
        listed = [(m["name"], m.get("params", {}), m.get("label")) for m in data["methods"]]
        assert listed == [(m["name"], m["params"], m["label"]) for m in paper.table_methods()], preset


def test_paper_configuration_and_ours_are_separate_columns(tmp_path):
    """temporal-graph in the paper configuration is "Proposed"; our tuned one, and any other
    configuration, are columns of their own, never merged into the paper's."""
    store = _store_with_results(tmp_path / "s.sqlite")
    extra = [("temporal-graph", {}, 40.0), ("temporal-copy", {}, 45.0), ("temporal-graph", {"beta": 0.25}, 50.0),
             ("fu-nonlocal", {}, 55.0)]
    for i, (method, params, value) in enumerate(extra):
        rows = [{"frame": f, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic",
                 "value": value} for f in range(3)]
        rows += [{"frame": f, "metric": "nshd", "scope": "frame", "peak": "", "value": 1e-8} for f in range(3)]
        record = {"sequence": "Human (stand-in)", "holes": "region", "holes_params": {"preset": "medium"}, "seed": 0,
                  "method": method, "method_params": params, "method_version": "4", "code_version": "abc", "spec": {},
                  "env": {}}
        store.record_run(f"extra-{i}", record, rows, ["exp"])
    df = store.results_frame("exp")
    t1, t2 = paper_tables(df, standins=True)
    assert t1.columns == paper.ALL_COLUMNS
    assert t1.mean[("Human (stand-in)", "Proposed")] == pytest.approx(26.0)  # only variant=paper
    assert t1.mean[("Human (stand-in)", "Hu")] == pytest.approx(21.0)
    assert t1.mean[("Human (stand-in)", "temporal-graph tuned (ours)")] == pytest.approx(40.0)
    assert t1.mean[("Human (stand-in)", "temporal-copy (reference)")] == pytest.approx(45.0)
    # other configurations keep their own labels and are not columns of the table
    assert t1.mean[("Human (stand-in)", 'temporal-graph {"beta":0.25}')] == pytest.approx(50.0)
    assert t1.mean[("Human (stand-in)", "fu-nonlocal")] == pytest.approx(55.0)
    md = t1.markdown()
    assert "50.00" not in md and "55.00" not in md
    assert "Proposed = `temporal-graph` (variant=paper" in md and "Hu = `fu-nonlocal` (variant=paper" in md
    assert "temporal-graph tuned (ours) = `temporal-graph` (defaults" in md
    assert "Meshlab = `meshlab` (output=whole" in md
    assert "Proposed = `temporal-graph` (variant=paper" in t2.latex()
    # the ranking against the paper is over the paper's columns; ours is set beside them
    report = write_paper_report(df, store.runs_frame("exp"), tmp_path / "paper", standins=True, preset="paper-quick",
                                command="dpcbench reproduce-paper --quick", elapsed_s=1.0, figure_notes={})
    text = report.read_text()
    assert "Proposed > Hu > Lozes > Meshlab" in text
    assert "| temporal-graph tuned (ours) | +14.00 | +19.00 |" in text  # 40 - 26, 40 - 21
    # the Columns section names every parameter as run: the paper configuration's switches are off
    columns = text.split("## Columns", 1)[1].split("## Table 1", 1)[0]
    proposed = next(line for line in columns.splitlines() if line.startswith("| Proposed |"))
    for switch in ("link_cutoff=False", "known_points='fixed'", "intra_candidates=1", "temporal_source=False",
                   "variant='paper'"):
        assert switch in proposed
    ours = next(line for line in columns.splitlines() if line.startswith("| temporal-graph tuned (ours) |"))
    assert "variant='tuned'" in ours and "link_cutoff=True" in ours


def test_d2_tables_say_which_normals_d2_used(tmp_path):
    """The D2 table captions (Markdown, LaTeX) and REPORT.md name the normals the runs' D2 used, as
    the runner records them: from file for both sequences here, then mixed per sequence."""
    from dpcbench.bench.reporting.tables import d2_normals_note

    store = _store_with_results(tmp_path / "s.sqlite")
    for seq in ("Human (stand-in)", "Bunny (stand-in)"):
        for k, method in enumerate(METHODS):
            rows = [{"frame": f, "metric": "gpsnr_d2", "scope": "frame", "peak": "intrinsic", "value": 20.0 + k + f}
                    for f in range(3)]
            source = "estimated" if (seq.startswith("Bunny") and method == "meshlab") else "file"
            store.record_run(f"{seq[:3]}-{method}-d2", {
                "sequence": seq, "holes": "region", "holes_params": {"preset": "medium"}, "seed": 1,
                "method": method, "method_params": {}, "method_version": "1", "code_version": "abc", "spec": {},
                "env": {"d2_normals": source}}, rows, ["d2"])
    runs = store.runs_frame("d2")
    human_ids = set(runs[runs["sequence"] == "Human (stand-in)"]["run_id"])
    assert d2_normals_note(runs, human_ids) == ("D2 (point-to-plane): normals from file (the ground truth's own, "
                                                "as pc_error reads them).")
    mixed = d2_normals_note(runs)
    assert "Bunny (stand-in): normals estimated by PCA of 12 neighbours" in mixed and "normals from file" in mixed
    out = tmp_path / "paper"
    df = store.results_frame("d2")
    report = write_paper_report(df, runs, out, standins=True, preset="paper-quick", command="x", elapsed_s=1.0,
                                figure_notes={})
    md = (out / "tables" / "variant_gpsnr_d2_frame_peakintrinsic.md").read_text()
    tex = (out / "tables" / "variant_gpsnr_d2_frame_peakintrinsic.tex").read_text()
    assert "estimated by PCA of 12 neighbours" in md and "normals from file" in md
    assert "estimated by PCA of 12 neighbours" in tex
    assert "estimated by PCA of 12 neighbours" in report.read_text()
    assert "PCA" not in (out / "tables" / "table2_nshd.md").read_text()  # NSHD does not use normals


def test_the_floor_marks_cells_below_no_fill():
    from dpcbench.bench.reporting.tables import FLOOR_MARK, TIED_MARK

    df = tidy_results({("S", "none"): 15.0, ("S", "a"): 10.0, ("S", "b"): 20.0, ("S", "c"): 20.0, ("T", "none"): 5.0,
                ("T", "a"): 10.0})
    t = comparison_table(df, "gpsnr_d1", "frame", "intrinsic")
    assert t.floor == "none"
    assert t.below_floor("S", "a") and not t.below_floor("S", "b") and not t.below_floor("T", "a")
    md = t.markdown()
    row = next(line for line in md.splitlines() if line.startswith("| S |"))
    cells = [c.strip() for c in row.strip("|").split("|")][1:]
    # a is below the floor; b and c are identical: tied-best, nobody bold
    assert cells[1].endswith(FLOOR_MARK) and not cells[0].endswith(FLOOR_MARK)
    assert cells[2].endswith(TIED_MARK) and cells[3].endswith(TIED_MARK) and "**" not in row
    assert "below the floor" in md and f"{TIED_MARK}: tied-best" in md
    assert r"$^{\nabla}$" in t.latex()
    rows = list(csv.DictReader(io.StringIO(t.csv())))
    assert {r["method"] for r in rows if r["below_floor"] == "True"} == {"a"}
    # lower is better: a larger NSHD than no fill is below the floor
    t2 = comparison_table(tidy_results({("S", "none"): 1.0, ("S", "a"): 2.0}, metric="nshd"), "nshd", "frame")
    assert t2.below_floor("S", "a")


def test_labels_are_escaped_in_every_format():
    from dpcbench.bench.reporting.tables import csv_safe, latex_escape, md_escape

    evil = "x|y\n<b>z</b> 50% {a}_\\"
    assert md_escape(evil) == "x\\|y &lt;b>z&lt;/b> 50% {a}\\_\\\\"
    assert latex_escape(evil) == r"x|y \textless{}b\textgreater{}z\textless{}/b\textgreater{} 50\% \{a\}\_\textbackslash{}"
    assert [csv_safe(v) for v in ("=1+1", "+a", "-b", "@c", "ok", -1.5)] == ["'=1+1", "'+a", "'-b", "'@c", "ok", -1.5]
    df = tidy_results({("=HYPERLINK(1)", "a|b"): 10.0, ("=HYPERLINK(1)", "50%"): 11.0})
    t = comparison_table(df, "gpsnr_d1", "frame", "intrinsic")
    assert "| a\\|b |" in t.markdown() and r"50\%" in t.latex()
    rows = list(csv.reader(io.StringIO(t.csv())))
    assert {r[0] for r in rows[1:]} == {"'=HYPERLINK(1)"}


def test_one_precision_per_table():
    t = comparison_table(tidy_results({("S", "a"): 0.001, ("S", "b"): 12.0}, metric="nshd", step=1e-4), "nshd", "frame",
                         decimals=None)
    # the smallest mean (0.00111) gets 3 significant digits: 5 decimals for every value
    assert t.cell_text("S", "b").startswith("12.00011 [") and t.cell_text("S", "a").startswith("0.00111 [")


def test_the_paper_claims_are_judged(tmp_path):
    from dpcbench.bench.reporting.reports import claims_markdown, gains_claim, nshd_claim, ranking_claim

    df = _store_with_results(tmp_path / "s.sqlite", seeds=(0, 1, 2)).results_frame("exp")
    t1, t2 = paper_tables(df, standins=True)
    # Proposed > Hu > Lozes > Meshlab by 5 dB on every pair, and the reverse order in NSHD: the order holds
    ranking = ranking_claim(t1, t2)
    assert ranking["verdict"] == "reproduced", ranking
    assert ranking["measured"].startswith("12 of 12 claimed pairs hold, 0 reversed (n = 9 pairs each")
    # on stand-ins a dB gain and an NSHD factor are not testable, on the paper's data they are judged
    assert gains_claim(t1, standins=True)["verdict"] == "not testable on this data"
    gains = gains_claim(t1, standins=False)
    assert gains["verdict"] == "not reproduced"  # +15 / +10 / +5 dB, every interval below the paper's gains
    assert "over Meshlab +15.00 dB [+15.00, +15.00] (paper +26.80 dB)" in gains["measured"]
    nshd = nshd_claim(t2, standins=False)
    assert nshd["verdict"] == "not reproduced" and "x2.00" in nshd["measured"]  # Hu's NSHD is 2x Proposed's
    text = claims_markdown(t1, t2, standins=True)
    assert "**On stand-ins the order of the methods can be tested" in text
    assert text.count("| **") == 3


def test_a_reversed_order_is_not_reproduced_and_says_why(tmp_path):
    from dpcbench.bench.reporting.reports import ranking_claim

    df = _store_with_results(tmp_path / "s.sqlite", seeds=(0, 1, 2)).results_frame("exp")
    swap = {"lozes-pde": "temporal-graph", "temporal-graph": "lozes-pde"}
    flipped = df.assign(method=df["method"].map(lambda m: swap.get(m, m)),
                        method_params=[json.dumps(PAPER_PARAMS[swap.get(m, m)]) for m in df["method"]])
    t1, t2 = paper_tables(flipped, standins=True)
    ranking = ranking_claim(t1, t2)
    assert ranking["verdict"] == "not reproduced"
    assert "Lozes > Hu beyond the interval" in ranking["why"] and "Hu > Proposed" in ranking["why"]


def test_paper_report_has_a_colour_section_for_the_coloured_sequences(tmp_path):
    store = _store_with_results(tmp_path / "s.sqlite", coloured=("Human (stand-in)",))
    out = tmp_path / "paper"
    text = write_paper_report(store.results_frame("exp"), store.runs_frame("exp"), out, standins=True,
                              preset="paper-quick", command="c", elapsed_s=1.0, figure_notes={}).read_text()
    section = text[text.index("## Colour PSNR (not in the paper)"):]
    # the paper's columns in their order, each cell the mean over frames 0-2 of 30 + k + f (Meshlab k = 0 ...
    # Proposed k = 3), no fill and ours absent
    assert ("| Sequence | No fill (floor) | Meshlab | Lozes | Hu | Proposed | temporal-graph tuned (ours) | "
            "temporal-fusion (ours) | temporal-copy (reference) |") in section
    assert ("| Human (stand-in) | – | 31.00 [28.52, 33.48] | 32.00 [29.52, 34.48] | 33.00 [30.52, 35.48] | "
            "34.00 [31.52, 36.48] | – | – | – |") in section
    assert "No colour values for Bunny (stand-in)" in section
    assert "STAND-IN" in (out / "tables" / "cpsnr_y_frame.md").read_text()
    # without colour values the section says so
    plain = _store_with_results(tmp_path / "p.sqlite")
    text = write_paper_report(plain.results_frame("exp"), plain.runs_frame("exp"), tmp_path / "plain", standins=True,
                              preset="paper-quick", command="c", elapsed_s=1.0, figure_notes={}).read_text()
    assert "No colour PSNR stored: none of the sequences" in text


def test_paper_report_has_the_claims_and_its_provenance(tmp_path):
    store = _store_with_results(tmp_path / "s.sqlite", seeds=(0, 1, 2))
    df, runs = store.results_frame("exp"), store.runs_frame("exp")
    computed = set(runs["run_id"][:5])
    report = write_paper_report(df, runs, tmp_path / "out", standins=True, preset="paper-quick", command="c",
                                elapsed_s=60, figure_notes={}, store_path=store.path, computed=computed)
    text = report.read_text()
    assert "## The paper's claims" in text
    n = df["run_id"].nunique()
    assert (f"Provenance: {n} runs in this report: 5 computed now (code abc (5)); {n - 5} read from the store, "
            f"computed before (code abc ({n - 5})); results store `{store.path}`") in text


def test_provenance_says_where_the_runs_were_computed_and_warns_of_unpinned_greedy_fills(tmp_path):
    """Every report's provenance lists the instruction sets its runs recorded, and warns where a method whose scores
    move with the instruction set (Hu and Proposed here) ran unpinned; pinned, they get no warning."""
    from dpcbench.bench.reporting.computed_with import ISA_SENSITIVE
    from dpcbench.bench.reporting.reports import provenance_markdown

    store = _store_with_results(tmp_path / "s.sqlite")
    runs = store.runs_frame("exp").drop_duplicates("run_id")
    pinned = "x86_64; numpy dispatch up to X86_V3; pinned (OPENBLAS_CORETYPE=Haswell)"
    loose = "x86_64; numpy dispatch up to AVX512_ICL; unpinned"
    hu = runs["method"].isin(ISA_SENSITIVE)
    assert hu.any() and (~hu).any()
    runs = runs.assign(env=[json.dumps({"isa": pinned if h else loose}) for h in hu])
    text = provenance_markdown(runs, set(runs["run_id"]))
    assert f"- Instruction sets of the runs read: {loose} on {(~hu).sum()} runs; {pinned} on {hu.sum()} runs." in text \
        or f"- Instruction sets of the runs read: {pinned} on {hu.sum()} runs; {loose} on {(~hu).sum()} runs." in text
    assert "not computed pinned" not in text
    flipped = runs.assign(env=[json.dumps({"isa": loose if h else pinned}) for h in hu])
    warned = provenance_markdown(flipped, set(runs["run_id"]))
    assert f"- {hu.sum()} of the {hu.sum()} runs of fu-nonlocal, temporal-graph were not computed pinned" in warned
    assert "`--pin-isa` on `dpcbench run` and `dpcbench reproduce-paper`" in warned
