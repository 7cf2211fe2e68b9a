"""dpcbench.bench.results.compare and `dpcbench compare`: summaries, tolerances, regression verdicts, exit codes."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.results import compare
from dpcbench.bench.results.store import ResultsStore


def results_frame(cells, code_version="c1", created_at="2026-01-01T00:00:00", experiment="regression",
                  run_prefix="r"):
    """A store-shaped results table. cells: {(method, metric, scope): [per-frame values]}."""
    rows = []
    for (method, metric, scope), values in cells.items():
        for frame, value in enumerate(values):
            rows.append(dict(
                run_id=f"{run_prefix}-{method}", experiment=experiment, sequence="human", holes="region",
                holes_params='{"preset": "small"}', seed=0, method=method, method_params="{}", method_version="1",
                code_version=code_version, frame=frame, metric=metric, scope=scope,
                peak="intrinsic" if metric.startswith("gpsnr") else "", value=value, created_at=created_at))
    return pd.DataFrame(rows)


def summary(values: dict) -> pd.DataFrame:
    """A one-frame-per-row summary: {(method, metric, scope): mean}."""
    return compare.summarize(results_frame({k: [v] for k, v in values.items()}))


# ---------------------------------------------------------------------------------------------
# summarize
def test_summarize_mean_std_count_closed_form():
    df = results_frame({("none", "gpsnr_d1", "frame"): [30.0, 32.0, 34.0], ("none", "nshd", "holes"): [1e-7, 3e-7]})
    s = compare.summarize(df).set_index(["metric", "scope"])
    assert s.loc[("gpsnr_d1", "frame"), "mean"] == pytest.approx(32.0)
    assert s.loc[("gpsnr_d1", "frame"), "std"] == pytest.approx(math.sqrt(8 / 3))  # population std
    assert s.loc[("gpsnr_d1", "frame"), "n_frames"] == 3
    assert s.loc[("nshd", "holes"), "mean"] == pytest.approx(2e-7)
    assert s.loc[("gpsnr_d1", "frame"), "peak"] == "intrinsic"
    assert list(compare.summarize(df).columns) == compare.SUMMARY_COLUMNS


def test_summarize_keeps_newest_run_and_filters():
    old = results_frame({("none", "gpsnr_d1", "frame"): [10.0, 10.0]}, code_version="c1",
                        created_at="2026-01-01T00:00:00", run_prefix="old")
    new = results_frame({("none", "gpsnr_d1", "frame"): [20.0, 22.0]}, code_version="c2",
                        created_at="2026-01-02T00:00:00", run_prefix="new")
    other = results_frame({("none", "gpsnr_d1", "frame"): [99.0]}, experiment="other", run_prefix="x",
                          created_at="2026-01-03T00:00:00", code_version="c3")
    both = pd.concat([old, new, other], ignore_index=True)
    assert compare.summarize(both, experiment="regression")["mean"].tolist() == [21.0]
    assert compare.summarize(both, code_version="c1")["mean"].tolist() == [10.0]
    # the same run listed under two experiments is counted once
    twice = pd.concat([new, new.assign(experiment="again")], ignore_index=True)
    assert compare.summarize(twice)["n_frames"].tolist() == [2]
    # equal params written differently are the same cell
    spaced = new.assign(method_params='{"b": 1, "a": 2}')
    compact = new.assign(method_params='{"a":2,"b":1}', run_id="new2", created_at="2026-01-05T00:00:00")
    merged = compare.summarize(pd.concat([spaced, compact]))
    assert len(merged) == 1 and merged["method_params"].iloc[0] == '{"a":2,"b":1}'


def test_sequence_level_values_are_not_mixed_with_frame_values():
    # a per-frame method: time per frame + the run total at frame -1 (ignored, per-frame rows exist)
    per_frame = results_frame({("lozes-pde", "time_s", "frame"): [1.0, 3.0]})
    per_frame = pd.concat([per_frame, per_frame.iloc[[0]].assign(frame=-1, value=4.0)])
    # a temporal method: only the total (6 s over 3 frames, known from its quality rows) -> 2 s a frame
    temporal = results_frame({("temporal-graph", "gpsnr_d1", "frame"): [30.0, 31.0, 32.0],
                              ("temporal-graph", "time_s", "frame"): [6.0]}).copy()
    temporal.loc[temporal["metric"] == "time_s", "frame"] = -1
    # a sequence-level metric stays as it is
    tc = results_frame({("none", "temporal_consistency", "holes"): [0.7]}).assign(frame=-1)
    s = compare.summarize(pd.concat([per_frame, temporal, tc], ignore_index=True)).set_index(["method", "metric"])
    assert s.loc[("lozes-pde", "time_s"), "mean"] == pytest.approx(2.0)
    assert s.loc[("lozes-pde", "time_s"), "n_frames"] == 2
    assert s.loc[("temporal-graph", "time_s"), "mean"] == pytest.approx(2.0)
    assert s.loc[("none", "temporal_consistency"), "mean"] == pytest.approx(0.7)


def test_input_facts_are_shown_not_gated():
    base = summary({("m", "removed_fraction", "frame"): 0.03, ("m", "gpsnr_d1", "frame"): 30.0})
    cur = summary({("m", "removed_fraction", "frame"): 0.05, ("m", "gpsnr_d1", "frame"): 30.0})
    result = compare.compare_summaries(base, cur)
    row = result.table[result.table["metric"] == "removed_fraction"].iloc[0]
    assert row["status"] == compare.STATUS_CHANGED and not row["gated"] and not result.failed
    assert "changed (not gated)" in result.format() and "info" in result.format()


def test_summarize_errors():
    with pytest.raises(ValueError, match="lacks the columns"):
        compare.summarize(pd.DataFrame({"value": [1.0]}))
    df = results_frame({("none", "gpsnr_d1", "frame"): [1.0]})
    with pytest.raises(ValueError, match="experiment 'nope'"):
        compare.summarize(df, experiment="nope")


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_summary_file_round_trip(tmp_path, suffix):
    df = results_frame({("none", "gpsnr_d1", "frame"): [30.123456789, 31.5],
                        ("fu-nonlocal", "nshd", "holes"): [1.234567e-7, 2e-7],
                        ("none", "time_s", "frame"): [0.25, float("nan")]})
    s = compare.summarize(df)
    meta = compare.summary_meta("abc123", experiment="regression")
    path = compare.write_summary(s, tmp_path / f"base{suffix}", meta)
    back, back_meta = compare.read_summary(path)
    pd.testing.assert_frame_equal(back, s, rtol=1e-10)
    assert back_meta["code_version"] == "abc123"
    assert back_meta["experiment"] == "regression"
    assert {"env.python", "env.numpy", "env.scipy", "env.open3d", "env.pymeshlab", "env.machine"} <= set(back_meta)


def test_read_summary_rejects_other_files(tmp_path):
    bad = tmp_path / "x.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="not a dpcbench summary"):
        compare.read_summary(bad)
    broken = tmp_path / "x.json"
    broken.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        compare.read_summary(broken)
    with pytest.raises(ValueError, match="no such summary file"):
        compare.read_summary(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match=r"\.csv or \.json"):
        compare.write_summary(compare.summarize(results_frame({("none", "nshd", "frame"): [1.0]})),
                              tmp_path / "x.txt")


# ---------------------------------------------------------------------------------------------
# the verdicts
def status_of(base: float, cur: float, metric: str, tolerance: float | None = None, **kw) -> str:
    tolerances = dict(compare.DEFAULT_TOLERANCES)
    if tolerance is not None:
        tolerances[metric] = tolerance
    result = compare.compare_summaries(summary({("m", metric, "frame"): base}),
                                       summary({("m", metric, "frame"): cur}), tolerances, **kw)
    return result.table["status"].iloc[0]


def test_psnr_is_compared_in_db():
    assert status_of(40.0, 39.95, "gpsnr_d1", 0.1) == compare.STATUS_OK
    assert status_of(40.0, 39.85, "gpsnr_d1", 0.1) == compare.STATUS_REGRESSED
    assert status_of(40.0, 40.25, "gpsnr_d1", 0.1) == compare.STATUS_IMPROVED
    result = compare.compare_summaries(summary({("m", "gpsnr_d2", "frame"): 40.0}),
                                       summary({("m", "gpsnr_d2", "frame"): 38.5}))
    assert result.table["change"].iloc[0] == pytest.approx(-1.5)
    assert "-1.500 dB" in result.format()


def test_distances_are_compared_as_ratios():
    # lower is better: x1.05 within x1.10, x1.2 regressed, x0.8 improved
    assert status_of(2e-7, 2.1e-7, "nshd", 1.10) == compare.STATUS_OK
    assert status_of(2e-7, 2.4e-7, "nshd", 1.10) == compare.STATUS_REGRESSED
    assert status_of(2e-7, 1.6e-7, "nshd", 1.10) == compare.STATUS_IMPROVED
    assert status_of(5.0, 6.0, "hausdorff", 1.10) == compare.STATUS_REGRESSED
    assert status_of(0.0, 0.0, "chamfer", 1.10) == compare.STATUS_OK  # 0/0 -> x1
    assert status_of(0.0, 1e-9, "chamfer", 1.10) == compare.STATUS_REGRESSED  # x inf
    result = compare.compare_summaries(summary({("m", "nshd", "frame"): 2e-7}), summary({("m", "nshd", "frame"): 3e-7}))
    assert result.table["change"].iloc[0] == pytest.approx(1.5)
    assert "x1.500" in result.format()


def test_time_is_reported_but_gated_only_on_request():
    base, cur = summary({("m", "time_s", "frame"): 1.0}), summary({("m", "time_s", "frame"): 3.0})
    loose = compare.compare_summaries(base, cur)
    assert loose.table["status"].iloc[0] == compare.STATUS_SLOWER and not loose.failed
    assert "not gated" in loose.format()
    strict = compare.compare_summaries(base, cur, gate_time=True)
    assert strict.failed and len(strict.failures) == 1
    # memory is shown, never gated, even with gate_time
    mem = compare.compare_summaries(summary({("m", "peak_mem_mb", "frame"): 100.0}),
                                    summary({("m", "peak_mem_mb", "frame"): 400.0}), gate_time=True)
    assert mem.table["status"].iloc[0] == compare.STATUS_MORE_MEMORY and not mem.failed
    # tiny per-frame times are noise: never flagged
    assert status_of(0.001, 0.01, "time_s", gate_time=True) == compare.STATUS_OK


def test_missing_rows_fail_new_rows_do_not():
    base = summary({("a", "gpsnr_d1", "frame"): 30.0, ("b", "gpsnr_d1", "frame"): 30.0})
    cur = summary({("a", "gpsnr_d1", "frame"): 30.0, ("c", "gpsnr_d1", "frame"): 30.0})
    result = compare.compare_summaries(base, cur)
    statuses = dict(zip(result.table["method"], result.table["status"]))
    assert statuses == {"a": compare.STATUS_OK, "b": compare.STATUS_MISSING, "c": compare.STATUS_NEW}
    assert result.failed and result.failures["method"].tolist() == ["b"]


def test_nan_becoming_defined_is_flagged():
    assert status_of(float("nan"), float("nan"), "gpsnr_d1") == compare.STATUS_OK
    assert status_of(30.0, float("nan"), "gpsnr_d1") == compare.STATUS_REGRESSED
    assert status_of(float("inf"), float("inf"), "gpsnr_d1") == compare.STATUS_OK


def test_direction_and_change_kind_come_from_the_metric_registry_only():
    from dpcbench.bench.reporting import tables
    from dpcbench.metrics import registry

    assert not hasattr(compare, "HIGHER_IS_BETTER") and not hasattr(compare, "CHANGE_KIND")
    assert not hasattr(tables, "LOWER_IS_BETTER")
    for name, metric in {**registry.METRICS, **registry.RESOURCE_METRICS}.items():
        assert compare.higher_is_better(name) is metric.higher_is_better
        assert tables.higher_is_better(name) is metric.higher_is_better
        assert compare.change_kind(name) == metric.change
        assert metric.change == ("delta" if metric.unit == "dB" or name == "fscore" else "ratio")
    # the resource and input metrics the runner stores are described there too
    assert set(compare.RESOURCE_METRICS) == {"time_s", "cpu_time_s", "peak_mem_mb"} and compare.INFO_METRICS == ("removed_fraction",)
    assert registry.describe("time_s").unit == "s" and registry.describe("peak_mem_mb").unit == "MB"
    assert registry.describe("removed_fraction").higher_is_better is None
    assert tables.higher_is_better("removed_fraction") is None
    with pytest.raises(ValueError, match="unknown direction"):  # a metrics.errors.UserError
        compare.higher_is_better("no_such_metric")
    with pytest.raises(ValueError, match="unknown direction"):
        compare.higher_is_better("removed_fraction")


def test_peak_dependence_comes_from_the_registry():
    from dpcbench.bench.execution.worker import _uses_peak
    from dpcbench.metrics import registry

    assert [n for n in registry.METRICS if _uses_peak(n)] == ["gpsnr_d1", "gpsnr_d2", "hausdorff_psnr"]
    assert not _uses_peak("time_s") and not _uses_peak("psnr_of_a_metric_nobody_registered")


def test_a_metric_without_direction_has_no_best_cell():
    from dpcbench.bench.reporting.tables import ComparisonTable

    table = ComparisonTable("t", "removed_fraction", "frame", "", None, ["r"], ["a", "b"],
                            {("r", "a"): 0.1, ("r", "b"): 0.2}, {("r", "a"): 0.0, ("r", "b"): 0.0},
                            {("r", "a"): 1, ("r", "b"): 1})
    assert table.best("r", table.mean) is None
    assert "**" not in table.markdown().split("\n", 1)[1] and "no better direction" in table.conventions()
    ranked = ComparisonTable("t", "nshd", "frame", "", False, ["r"], ["a", "b"], table.mean, table.std, table.n)
    assert ranked.best("r", ranked.mean) == "a"


def test_tolerances_file(tmp_path):
    good = tmp_path / "tol.toml"
    good.write_text("[tolerances]\ngpsnr_d1 = 0.5  # dB\nnshd = 1.3\n")
    tol = compare.load_tolerances(good)
    assert tol["gpsnr_d1"] == 0.5 and tol["nshd"] == 1.3 and tol["gpsnr_d2"] == compare.DEFAULT_TOLERANCES["gpsnr_d2"]
    assert status_of(40.0, 39.7, "gpsnr_d1", tol["gpsnr_d1"]) == compare.STATUS_OK
    for text, message in [("[tolerances]\nnshd = 0.9\n", "tolerances.nshd: a ratio tolerance"),
                          ("[tolerances]\ngpsnr_d1 = 'x'\n", "tolerances.gpsnr_d1: expected a number"),
                          ("[other]\na = 1\n", "no \\[tolerances\\] table"),
                          ("[tolerances\n", "not valid TOML")]:
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(ValueError, match=message):
            compare.load_tolerances(bad)
    with pytest.raises(ValueError, match="not found"):
        compare.load_tolerances(tmp_path / "absent.toml")


def test_committed_tolerances_and_baseline_are_valid():
    """results/tolerances.toml loads; the committed baseline (when present) is a readable summary."""
    from dpcbench.bench.cli.options import DEFAULT_BASELINE, TOLERANCES_FILE

    tol = compare.load_tolerances(TOLERANCES_FILE)
    assert set(compare.DEFAULT_TOLERANCES) <= set(tol)
    if DEFAULT_BASELINE.is_file():
        table, meta = compare.read_summary(DEFAULT_BASELINE)
        assert len(table) > 0 and meta["code_version"] and "env.numpy" in meta
        assert {"gpsnr_d1", "gpsnr_d2", "nshd", "time_s"} <= set(table["metric"])
        assert set(table["scope"]) >= {"frame", "holes"}


# ---------------------------------------------------------------------------------------------
# the command
def write_store(path, cells, code_version="c1"):
    store = ResultsStore(path)
    by_run = {}
    for (method, metric, scope), values in cells.items():
        by_run.setdefault(method, []).extend(
            dict(frame=f, metric=metric, scope=scope, peak="intrinsic" if metric.startswith("gpsnr") else "", value=v)
            for f, v in enumerate(values))
    for method, rows in by_run.items():
        store.record_run(f"{code_version}-{method}", dict(
            sequence="human", holes="region", holes_params={"preset": "small"}, seed=0, method=method,
            method_params={}, method_version="1", code_version=code_version, spec={},
            env={"packages": {"numpy": np.__version__}, "python": "3.x"}), rows, ["regression"])
    return path


def test_cli_compare_store_against_baseline(tmp_path, capsys):
    cells = {("none", "gpsnr_d1", "frame"): [30.0, 31.0], ("none", "nshd", "frame"): [2e-7, 2e-7],
             ("none", "time_s", "frame"): [0.5, 0.5]}
    store = write_store(tmp_path / "a.sqlite", cells)
    baseline = tmp_path / "baseline.csv"
    assert cli_main(["compare", str(baseline), str(store), "--save-current", str(baseline)]) == 0
    table, meta = compare.read_summary(baseline)
    assert meta["env.numpy"] == np.__version__ and meta["experiment"] == "regression" and len(table) == 3
    capsys.readouterr()
    assert cli_main(["compare", str(baseline), "--store", str(store)]) == 0
    assert "PASSED" in capsys.readouterr().out

    worse = dict(cells)
    worse[("none", "gpsnr_d1", "frame")] = [29.0, 30.0]
    worse[("none", "time_s", "frame")] = [5.0, 5.0]
    store2 = write_store(tmp_path / "b.sqlite", worse, code_version="c2")
    out_csv = tmp_path / "cmp.csv"
    assert cli_main(["compare", str(baseline), str(store2), "--out", str(out_csv)]) == 1
    text = capsys.readouterr().out
    assert "REGRESSED" in text and "-1.000 dB" in text and "FAILED: 1 regression" in text
    assert "slower (not gated)" in text
    assert pd.read_csv(out_csv)["status"].tolist().count("REGRESSED") == 1
    assert cli_main(["compare", str(baseline), str(store2), "--changes-only"]) == 1
    changed = capsys.readouterr().out
    assert "gpsnr_d1" in changed and "nshd" not in changed  # only rows that are not ✓
    # time gated on request: now two failures
    assert cli_main(["compare", str(baseline), str(store2), "--gate-time"]) == 1
    assert "FAILED: 2 regression" in capsys.readouterr().out


def test_cli_compare_errors(tmp_path, capsys):
    store = write_store(tmp_path / "a.sqlite", {("none", "gpsnr_d1", "frame"): [30.0]})
    absent = tmp_path / "absent.sqlite"
    assert cli_main(["compare", str(tmp_path / "b.csv"), "--store", str(absent)]) == 2
    assert "no results store there" in capsys.readouterr().err and not absent.exists()
    assert cli_main(["compare", str(tmp_path / "nope.csv"), str(store)]) == 2
    assert "no such summary file" in capsys.readouterr().err
    assert cli_main(["compare", str(tmp_path / "b.txt"), str(store)]) == 2
    assert "BASELINE must be a summary" in capsys.readouterr().err
    base = tmp_path / "b.json"
    compare.write_summary(compare.summarize(results_frame({("none", "gpsnr_d1", "frame"): [1.0]})), base)
    assert cli_main(["compare", str(base), str(store), "--experiment", "other"]) == 2
    assert "no runs of experiment 'other'" in capsys.readouterr().err
    corrupt = tmp_path / "corrupt.sqlite"
    corrupt.write_bytes(b"this is not sqlite" * 100)
    assert cli_main(["compare", str(base), str(corrupt)]) == 2
    assert "results store is damaged" in capsys.readouterr().err
    bad_tol = tmp_path / "t.toml"
    bad_tol.write_text("[tolerances]\nnshd = -1\n")
    assert cli_main(["compare", str(base), str(store), "--tolerances", str(bad_tol)]) == 2
    assert "tolerances.nshd" in capsys.readouterr().err
    json.loads(base.read_text())  # the JSON summary is plain JSON


# ---------------------------------------------------------------------------------------------
# must show: a degraded method setting fails `dpcbench compare`, the normal setting passes
def score_into_store(store_path, code_version, frames, damage, method, seconds):
    """Score a method's output like the runner does (both scopes, intrinsic peak) into a store,
    under the regression preset's cell: temporal-graph with its default parameters."""
    import dpcbench.metrics as metrics

    names = ["gpsnr_d1", "gpsnr_d2", "nshd"]
    rows = []
    for f, (reference, result) in enumerate(zip(frames, method)):
        for scope, regions in (("frame", None), ("holes", damage.regions[f])):
            scores = metrics.score_frame(reference, result, names, peak="intrinsic", regions=regions)
            rows += [dict(frame=f, metric=m, scope=scope, peak="intrinsic" if m.startswith("gpsnr") else "",
                          value=scores[m]) for m in names]
        rows.append(dict(frame=f, metric="time_s", scope="frame", peak="", value=seconds))
    store = ResultsStore(store_path)
    store.record_run(f"run-{code_version}", dict(
        sequence="human", holes="region", holes_params={"preset": "medium", "count": 1, "coherent": True}, seed=0,
        method="temporal-graph", method_params={}, method_version="1", code_version=code_version, spec={}),
        rows, ["regression"])
    return store_path


def test_degraded_method_fails_compare_and_normal_passes(tmp_path, capsys):
    """Baseline: temporal-graph with its defaults on 2 small frames (~7k points) with a medium hole.
    The normal setting run again passes; the same cell run with icp_iterations = 0 (structure
    matching switched off: source cubes are copied in without the rotation/translation that fits them
    to the target's known points; measured -3.9 dB whole-frame D1 on this case), standing for a code
    change that degrades the method, fails with a readable table."""
    import time

    from dpcbench.bench.data.datasets import load_dataset
    from dpcbench.holes.registry import get_generator
    from dpcbench.methods.registry import get_method

    # a ~7k-point figure (height 100 voxels) keeps the three method runs well under a second each
    frames = load_dataset("human", frames=2, size="tiny", height=100, progress=False).points
    damage = get_generator("region", preset="medium", count=1, coherent=True).damage(frames, seed=0)

    def inpaint(**params):
        method = get_method("temporal-graph").set_params(**params)
        start = time.perf_counter()
        out = method.inpaint(damage.frames, damage.regions)
        return out, (time.perf_counter() - start) / len(frames)

    normal, seconds = inpaint()
    base_store = score_into_store(tmp_path / "base.sqlite", "base", frames, damage, normal, seconds)
    again, seconds_again = inpaint()
    normal_store = score_into_store(tmp_path / "normal.sqlite", "normal", frames, damage, again, seconds_again)
    degraded, seconds_degraded = inpaint(icp_iterations=0)
    degraded_store = score_into_store(tmp_path / "degraded.sqlite", "degraded", frames, damage, degraded,
                                      seconds_degraded)

    baseline = tmp_path / "regression-baseline.csv"
    assert cli_main(["compare", str(baseline), str(base_store), "--save-current", str(baseline)]) == 0
    capsys.readouterr()
    assert cli_main(["compare", str(baseline), str(normal_store)]) == 0
    passed = capsys.readouterr().out
    assert "PASSED" in passed and "REGRESSED" not in passed

    assert cli_main(["compare", str(baseline), str(degraded_store)]) == 1
    failed = capsys.readouterr().out
    print(failed)  # the readable table, shown with pytest -s
    assert "FAILED" in failed
    regressed = [line for line in failed.splitlines() if line.rstrip().endswith("REGRESSED")]
    assert any(line.split()[1:3] == ["gpsnr_d1@intrinsic", "frame"] for line in regressed)
    assert all(line.split()[0] == "temporal-graph" for line in regressed)
    assert "== human · holes: region (coherent=True, count=1, preset=medium)" in failed
    header = next(line for line in failed.splitlines() if line.startswith("method"))
    assert header.split() == ["method", "metric", "scope", "baseline", "current", "change", "tolerance", "floor", "status"]


# ---------------------------------------------------------------------------------------------
# one identity per cell
TWO_HUMANS = """
[experiment]
name = "twohuman"

[[sequences]]
name = "human"
params = { size = "tiny", motion = "walk" }
frames = 2

[[sequences]]
name = "human"
params = { size = "tiny", motion = "dance" }
frames = 2

[[holes]]
generator = "region"
params = { preset = "medium" }
seeds = [0, 1]

[[methods]]
name = "none"

[metrics]
names = ["gpsnr_d1"]
peaks = ["intrinsic"]
scopes = ["frame"]
"""


def test_cell_identity_ignores_seed_and_versions_not_data():
    from dpcbench.bench.experiment.config import parse_config, tomllib

    specs = parse_config(tomllib.loads(TWO_HUMANS), source="t").expand()
    cells = {}
    for spec in specs:
        cells.setdefault(compare.cell_identity(json.dumps(spec.to_dict())), set()).add(
            (spec.sequence["params"]["motion"], spec.holes["seed"]))
    # two cells (walk, dance), each holding both seeds
    assert sorted(map(sorted, cells.values())) == [[("dance", 0), ("dance", 1)], [("walk", 0), ("walk", 1)]]
    bumped = specs[0].to_dict()
    bumped["versions"]["method"] = "999"
    bumped["method"]["label"] = "another label"
    assert compare.cell_identity(json.dumps(bumped)) == compare.cell_identity(json.dumps(specs[0].to_dict()))
    assert compare.cell_identity("{}") is None


def test_two_sequences_with_one_label_stay_apart_in_report_and_summary(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DPCBENCH_CACHE", str(tmp_path / "cache"))
    config = tmp_path / "two.toml"
    config.write_text(TWO_HUMANS)
    store = tmp_path / "s.sqlite"
    assert cli_main(["run", str(config), "--store", str(store), "--quiet", "--executor", "serial"]) == 0
    runs = ResultsStore(store, readonly=True).runs_frame()
    assert runs["run_id"].nunique() == 4 and set(runs["sequence"]) == {"human"}
    assert cli_main(["report", str(store), "--out", str(tmp_path / "rep")]) == 0
    text = (tmp_path / "rep" / "REPORT.md").read_text()
    rows = [line.split(" | ")[0] for line in text.splitlines() if line.startswith("| human")]
    assert "| human (motion=dance)" in rows and "| human (motion=walk)" in rows
    assert cli_main(["compare", "--store", str(store), "--experiment", "twohuman",
                     "--save-current", str(tmp_path / "cur.csv")]) in (0, 1)
    current, _ = compare.read_summary(tmp_path / "cur.csv")
    gpsnr = current[current["metric"] == "gpsnr_d1"].set_index("sequence")
    assert sorted(gpsnr.index) == ["human (motion=dance)", "human (motion=walk)"]
    assert gpsnr["n_frames"].tolist() == [4, 4]  # 2 frames x 2 seeds each, never merged
    # each value is its own data's: the walk's mean is the mean of the walk runs only
    df = ResultsStore(store, readonly=True).results_frame()
    walk = set(runs[runs["spec"].str.contains('"walk"')]["run_id"])
    expected = df[(df["metric"] == "gpsnr_d1") & (df["frame"] >= 0) & df["run_id"].isin(walk)]["value"].mean()
    assert gpsnr.loc["human (motion=walk)", "mean"] == pytest.approx(expected)


def test_compare_marks_rows_below_the_floor():
    values = {("none", "gpsnr_d1", "frame"): 15.0, ("a", "gpsnr_d1", "frame"): 10.0,
              ("b", "gpsnr_d1", "frame"): 20.0, ("none", "nshd", "frame"): 1e-7, ("a", "nshd", "frame"): 5e-8,
              ("b", "nshd", "frame"): 2e-7, ("a", "time_s", "frame"): 9.0, ("none", "time_s", "frame"): 0.1}
    result = compare.compare_summaries(summary(values), summary(values))
    below = compare.below_floor(result.table)
    flagged = set(zip(result.table.loc[below, "method"], result.table.loc[below, "metric"]))
    assert flagged == {("a", "gpsnr_d1"), ("b", "nshd")}  # lower PSNR / higher NSHD than no fill; time never
    text = result.format()
    line_a = next(line for line in text.splitlines() if line.startswith("a ") and "gpsnr_d1" in line)
    line_b = next(line for line in text.splitlines() if line.startswith("b ") and "gpsnr_d1" in line)
    assert line_a.split()[-2:] == [compare.FLOOR_MARK, "✓"] and compare.FLOOR_MARK not in line_b
    assert "worse than not filling at all (2 rows)" in text


def test_dashboard_latest_table_marks_the_floor():
    from dpcbench.bench.reporting import dashboard

    df = results_frame({("none", "gpsnr_d1", "frame"): [15.0], ("a", "gpsnr_d1", "frame"): [10.0],
                        ("b", "gpsnr_d1", "frame"): [20.0]})
    history = dashboard.build_history(df)
    html_text = dashboard.latest_table(history, dashboard.method_colours(history.table["label"]), ["gpsnr_d1"])
    rows = {r.split("</span>", 1)[1].split("</td>", 1)[0]: r for r in html_text.split("<tr>")[2:]}
    assert compare.FLOOR_MARK in rows["a"] and compare.FLOOR_MARK not in rows["b"].split("</tr>")[0]
    assert "below the floor" in html_text
