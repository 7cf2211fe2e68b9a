"""`dpcbench dashboard`: a static page built from a store with two code versions, checked in a real
browser (Debian's chromium, headless) when it is installed."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from dpcbench.bench import benchsuite, dashboard
from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.store import ResultsStore

METHODS = {"temporal-graph": (40.0, 1e-7, 2.0), "fu-nonlocal": (36.0, 3e-7, 1.5), "none": (12.0, 5e-6, 0.01)}
VERSIONS = [("1111111111aaaaaaaaaa", "2026-01-01T10:00:00+00:00"),
            ("2222222222bbbbbbbbbb", "2026-01-02T10:00:00+00:00")]


def make_store(path, *, versions=(0, 1), spec_ids=False):
    """Runs of 3 methods on 1 sequence at two code versions; at the second, fu-nonlocal loses 2 dB
    GPSNR D1 and doubles its NSHD (both scopes), everything else is identical."""
    store = ResultsStore(path)
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 0.01, size=3)
    for v in versions:
        version, when = VERSIONS[v]
        for method, (psnr, nshd, seconds) in METHODS.items():
            worse = v == 1 and method == "fu-nonlocal"
            rows = []
            for frame in range(3):
                for scope, offset in (("frame", 10.0), ("holes", 0.0)):
                    rows.append(dict(frame=frame, metric="gpsnr_d1", scope=scope, peak="intrinsic",
                                     value=psnr + offset + noise[frame] - (2.0 if worse else 0.0)))
                    rows.append(dict(frame=frame, metric="gpsnr_d2", scope=scope, peak="intrinsic",
                                     value=psnr + offset + 4 + noise[frame]))
                    rows.append(dict(frame=frame, metric="nshd", scope=scope, peak="",
                                     value=nshd * (2 if worse else 1)))
                rows.append(dict(frame=frame, metric="time_s", scope="frame", peak="", value=seconds))
            # spec_ids: ids that hash the spec only, as the runner's do: equal across commits
            store.record_run(method if spec_ids else f"{version[:4]}-{method}", dict(
                sequence="human", holes="region", holes_params={"preset": "small"}, seed=0, method=method,
                method_params={}, method_version="1", code_version=version, spec={}, created_at=when,
                finished_at=when, env={"packages": {"numpy": np.__version__}}), rows, ["regression"])
    if 1 not in versions:
        return store
    store.record_failure("broken", dict(sequence="human", holes="region", holes_params={}, seed=0, method="meshlab",
                                        method_params={}, code_version=VERSIONS[1][0], created_at=VERSIONS[1][1]),
                         "RuntimeError: pymeshlab said no", ["regression"])
    return store


def write_benchmark_sessions(folder):
    """Two pytest-benchmark JSON documents (the format pytest-benchmark 5 writes)."""
    folder.mkdir(parents=True, exist_ok=True)
    for i, (commit, when) in enumerate([("1111111111aaaaaaaaaa", "2026-01-01T10:30:00.000000+00:00"),
                                        ("2222222222bbbbbbbbbb", "2026-01-02T10:30:00.000000+00:00")]):
        benchmarks = []
        for name, seconds in (("test_gpsnr_100k", 0.2), ("test_gpsnr_1m", 2.5)):
            stats = {"min": seconds * 0.9, "max": seconds * 1.2, "mean": seconds * (1 + i), "stddev": 0.01,
                     "rounds": 5, "median": seconds * (1 + i), "iqr": 0.01, "q1": seconds, "q3": seconds,
                     "iqr_outliers": 0, "stddev_outliers": 0, "outliers": "0;0", "ld15iqr": seconds,
                     "hd15iqr": seconds, "ops": 1 / seconds, "total": 5 * seconds, "iterations": 1}
            benchmarks.append({"group": "metrics", "name": name,
                               "fullname": f"tests/benchmarks/test_bench_metrics.py::{name}",
                               "params": None, "param": None, "extra_info": {"points": 100000}, "options": {},
                               "stats": stats})
        doc = {"machine_info": {"node": "ci", "machine": "x86_64", "cpu": {"brand_raw": "Test CPU", "count": 2}},
               "commit_info": {"id": commit, "time": when, "dirty": False, "project": "dpcbench", "branch": "main"},
               "benchmarks": benchmarks, "datetime": when, "version": "5.3.1"}
        (folder / f"000{i + 1}_{commit}.json").write_text(json.dumps(doc))
    (folder / "unrelated.json").write_text('{"not": "a benchmark"}')
    return folder


def test_benchmark_loader(tmp_path):
    folder = write_benchmark_sessions(tmp_path / ".benchmarks")
    runs = benchsuite.load_benchmark_runs(folder)
    assert len(runs) == 4 and runs["commit"].nunique() == 2
    assert runs["median"].tolist() == [0.2, 2.5, 0.4, 5.0]  # ordered by session time, then name
    latest = benchsuite.latest_per_benchmark(runs)
    assert latest["median"].tolist() == [0.4, 5.0]
    assert "test_gpsnr_1m" in benchsuite.format_benchmarks(runs)
    with pytest.raises(ValueError, match="not a pytest-benchmark JSON"):
        benchsuite.load_benchmark_runs(folder / "unrelated.json", skip_invalid=False)
    with pytest.raises(ValueError, match="no such benchmark file"):
        benchsuite.load_benchmark_runs(tmp_path / "absent")


def test_page_is_self_contained_and_flags_the_regression(tmp_path):
    store = make_store(tmp_path / "s.sqlite")
    benchmarks = benchsuite.load_benchmark_runs(write_benchmark_sessions(tmp_path / "b"))
    page = dashboard.render_dashboard(store.results_frame(), runs=store.runs_frame(), benchmarks=benchmarks)
    assert dashboard.external_references(page) == []
    assert "<script" not in page.lower()
    # fu-nonlocal regressed in gpsnr_d1 and nshd, both scopes: 4 flagged rows in the "changes" table
    changes = page.split('<section id="comparison">')[1].split("<details>")[0]
    assert changes.count('class="regressed"') == 4
    assert set(re.findall(r'class="regressed" data-status="REGRESSED"><td>human</td><td>region</td><td>'
                          r'<span[^>]*></span>([^<]+)</td>', changes)) == {"fu-nonlocal"}
    assert 'data-commits="2"' in page
    assert "pymeshlab said no" in page  # failed run listed
    # against the paper: temporal-graph 40 dB vs fu-nonlocal 36 - 2 dB, NSHD 1e-7 vs 6e-7 (both scopes)
    gaps = page.split('<section id="paper">')[1].split("</section>")[0]
    assert gaps.count('<td class="num">+6.00 dB</td>') == 2 and gaps.count("x6.00") == 2
    assert '+5.26 dB' in gaps and '+26.80 dB' in gaps  # the paper's mean gains, from its Table 1
    # the detector of external requests works
    assert dashboard.external_references('<img src="https://example.org/x.png">')
    assert dashboard.external_references("<style>@import url(//cdn.example/x.css)</style>")


def test_css_is_package_data_inlined_and_each_section_is_one_function(tmp_path):
    from importlib import resources
    from pathlib import Path

    import tomllib

    css = resources.files("bench").joinpath("static", "dashboard.css").read_text(encoding="utf-8")
    assert dashboard.stylesheet() == css and ":root" in css and "tr.regressed td" in css
    assert not hasattr(dashboard, "CSS")  # no second copy in the code
    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    assert "*.css" in pyproject["tool"]["setuptools"]["package-data"]["dpcbench.bench.static"]  # shipped in the wheel
    store = make_store(tmp_path / "s.sqlite")
    page = dashboard.render_dashboard(store.results_frame(), runs=store.runs_frame())
    assert f"<style>\n{css}</style>" in page
    # each section function renders exactly its own section, in the order of SECTIONS
    prepared = dashboard.prepare_page(store.results_frame(), store.runs_frame(), None, None, None)
    undated = re.compile(r"<dc:date>[^<]*</dc:date>")  # matplotlib stamps each chart with its time
    page = undated.sub("", page)
    ids = []
    for section in dashboard.SECTIONS:
        html_text = undated.sub("", section(prepared))
        if html_text:
            assert html_text in page and html_text.count("<section") == 1
            ids.append(re.match(r'<section id="([a-z]+)"', html_text).group(1))
    assert ids == ["comparison", "quality", "paper", "latest", "speed", "runs"]
    assert dashboard.cards_section(prepared) in page
    assert dashboard.metric_label("gpsnr_d1") == "GPSNR D1 (dB)" and dashboard.metric_label("nshd") == "NSHD"
    assert dashboard.metric_label("time_s") == "time per frame (s)"


def test_history_and_colours_are_stable(tmp_path):
    store = make_store(tmp_path / "s.sqlite")
    history = dashboard.build_history(store.results_frame())
    assert history.versions == [v for v, _ in VERSIONS]
    first = history.table[history.table["code_version"] == VERSIONS[0][0]].set_index(["method", "metric", "scope"])
    assert first.loc[("none", "nshd", "frame"), "mean"] == pytest.approx(5e-6)
    colours = dashboard.method_colours(["none", "temporal-graph", "zzz", "fu-nonlocal"])
    assert colours["temporal-graph"] == dashboard.PALETTE[0] and colours["fu-nonlocal"] == dashboard.PALETTE[1]
    assert dashboard.short_version("0123456789abcdef0123+dirty") == "01234567+"
    paper = dashboard.paper_reference()
    row = paper[(paper["sequence"] == "loot") & (paper["method"] == "temporal-graph") & (paper["metric"] == "gpsnr_d1")]
    assert row["value"].tolist() == [pytest.approx(47.5648)]


def test_cli_dashboard_errors(tmp_path, capsys):
    assert cli_main(["dashboard", "--out", str(tmp_path / "x.png"), "--store", str(tmp_path / "s")]) == 2
    assert ".html" in capsys.readouterr().err
    assert cli_main(["dashboard", "--out", str(tmp_path / "x.html"), "--store", str(tmp_path / "absent.sqlite")]) == 2
    assert "no results store there" in capsys.readouterr().err


def run_chromium(args: list[str], profile) -> subprocess.CompletedProcess:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium; ./install.sh --dev installs it)")
    command = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               f"--user-data-dir={profile}", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


def test_dashboard_in_headless_chromium(tmp_path, capsys):
    """Two stores (one per code version, as two regression runs at two commits give) merged by
    --store twice; chromium loads the page and its DOM shows the flagged rows, the methods, both
    commits and the benchmark history."""
    make_store(tmp_path / "first.sqlite", versions=(0,), spec_ids=True)
    make_store(tmp_path / "second.sqlite", versions=(1,), spec_ids=True)
    out = tmp_path / "dash.html"
    bench_dir = write_benchmark_sessions(tmp_path / "bench")
    assert cli_main(["dashboard", "--out", str(out), "--store", str(tmp_path / "first.sqlite"),
                     "--store", str(tmp_path / "second.sqlite"), "--benchmarks", str(bench_dir)]) == 0
    assert "2 code version(s)" in capsys.readouterr().out
    result = run_chromium(["--dump-dom", out.resolve().as_uri()], tmp_path / "profile")
    assert result.returncode == 0, result.stderr[-2000:]
    dom = result.stdout
    assert "<svg" in dom and "Latest comparison" in dom
    assert len(re.findall(r'<tr class="regressed" data-status="REGRESSED"', dom)) >= 4
    assert 'data-card="regressions"' in dom and re.search(r'data-card="regressions">.*?<div class="v">4</div>', dom)
    for method in METHODS:
        assert method in dom
    # every quality chart has both commits on its x axis (matplotlib keeps text as <text> in the SVG)
    quality = re.findall(r'data-chart="quality"[^>]*data-commits="(\d+)"', dom)
    assert quality == ["2"]
    assert dom.count("11111111") >= 6 and dom.count("22222222") >= 6
    assert 'data-chart="benchmarks" data-sessions="2"' in dom
    assert "test_gpsnr_1m" in dom


def test_history_is_cumulative_over_versions(tmp_path):
    """A cell not rerun at the newer version keeps its last value there (measured False), so a
    partial rerun or a sweep spanning two commits shows no cell as missing."""
    store = make_store(tmp_path / "s.sqlite", versions=(0,))
    version, when = VERSIONS[1]
    previous = store.results_frame()
    previous = previous[previous["method"] == "none"]
    rows = [dict(frame=r.frame, metric=r.metric, scope=r.scope, peak=r.peak,
                 value=99.0 if (r.metric, r.scope) == ("gpsnr_d1", "frame") else r.value)
            for r in previous.itertuples(index=False)]
    store.record_run("only-none", dict(sequence="human", holes="region", holes_params={"preset": "small"}, seed=0,
                                       method="none", method_params={}, code_version=version, created_at=when,
                                       finished_at=when), rows, ["regression"])
    history = dashboard.build_history(store.results_frame())
    newest = history.table[history.table["code_version"] == version].set_index(["method", "metric", "scope"])
    assert newest.loc[("none", "gpsnr_d1", "frame"), "mean"] == 99.0
    assert bool(newest.loc[("none", "gpsnr_d1", "frame"), "measured"])
    carried = newest.loc[("temporal-graph", "gpsnr_d1", "frame")]
    assert carried["mean"] == pytest.approx(50.0, abs=0.1) and not bool(carried["measured"])
    # the page compares the cumulative states: nothing missing, the rerun cell improved
    page = dashboard.render_dashboard(store.results_frame(), runs=store.runs_frame())
    assert 'data-status="MISSING"' not in page and 'data-status="improved"' in page


def test_summary_files_join_the_history(tmp_path, capsys):
    """An older summary (e.g. a committed baseline) plus a store at a newer version: two versions,
    and the newer one's regression is flagged against the summary's values."""
    from dpcbench.bench import compare

    old = make_store(tmp_path / "old.sqlite", versions=(0,))
    summary = tmp_path / "old.csv"
    meta = compare.summary_meta(VERSIONS[0][0], environment={}, experiment="regression")
    meta["date"] = VERSIONS[0][1]  # the history orders versions by time: the summary's date stands for its runs
    compare.write_summary(compare.summarize(old.results_frame()), summary, meta)
    make_store(tmp_path / "new.sqlite", versions=(1,))
    out = tmp_path / "d.html"
    assert cli_main(["dashboard", "--out", str(out), "--store", str(tmp_path / "new.sqlite"),
                     "--summary", str(summary)]) == 0
    page = out.read_text()
    assert 'data-commits="2"' in page
    changes = page.split('<section id="comparison">')[1].split("<details>")[0]
    assert changes.count('data-status="REGRESSED"') == 4


def test_two_psnr_peaks_are_kept_apart(tmp_path):
    store = ResultsStore(tmp_path / "s.sqlite")
    rows = [dict(frame=0, metric="gpsnr_d1", scope="frame", peak="intrinsic", value=21.5),
            dict(frame=0, metric="gpsnr_d1", scope="frame", peak="1023", value=71.5)]
    store.record_run("r", dict(sequence="human", holes="region", holes_params={}, seed=0, method="none",
                               method_params={}, code_version="c1"), rows, ["x"])
    page = dashboard.render_dashboard(store.results_frame())
    latest = page.split('<section id="latest">')[1].split("</section>")[0]
    assert "peak 1023" in latest and ">21.5000<" in latest and ">71.5000<" in latest
    assert "dotted: PSNR peak 1023" in page


def test_comparison_against_a_baseline_summary(tmp_path):
    from dpcbench.bench import compare

    old = make_store(tmp_path / "old.sqlite", versions=(0,))
    baseline = (compare.summarize(old.results_frame()), {"code_version": VERSIONS[0][0], "date": "2026-01-01"})
    new = make_store(tmp_path / "new.sqlite", versions=(1,))
    page = dashboard.render_dashboard(new.results_frame(), baseline=baseline)
    changes = page.split('<section id="comparison">')[1].split("<details>")[0]
    assert "against the baseline summary (code 11111111" in changes
    assert changes.count('data-status="REGRESSED"') == 4


def test_paper_gaps_per_sequence_and_hole_configuration(tmp_path):
    """Two hole configurations of one generator on one sequence (reproduce-paper's independent and
    coherent holes) are two rows of the gaps table, each with its own gains, named by the labels
    the experiment config gave them (this raised "truth value of a Series is ambiguous")."""
    store = ResultsStore(tmp_path / "s.sqlite")
    psnr = {"temporal-graph": 30.0, "fu-nonlocal": 27.0, "lozes-pde": 22.0, "meshlab": 10.0}
    for coherent, label, shift in ((False, "independent holes", 0.0), (True, "coherent holes", -2.0)):
        holes_params = {"preset": "medium", "coherent": coherent}
        for method, value in psnr.items():
            # the proposed method loses 2 dB on coherent holes, the others do not
            gain = shift if method == "temporal-graph" else 0.0
            rows = [dict(frame=f, metric=m, scope="frame", peak=p, value=v) for f in range(2)
                    for m, p, v in (("gpsnr_d1", "intrinsic", value + gain), ("nshd", "", 1e-7))]
            store.record_run(f"{method}-{coherent}", dict(
                sequence="Human (stand-in)", holes="region", holes_params=holes_params, seed=0, method=method,
                method_params={"output": "whole"} if method == "meshlab" else {}, method_version="1",
                code_version="abc", spec={"holes": {"generator": "region", "label": label}},
                created_at=VERSIONS[0][1], finished_at=VERSIONS[0][1], env={}), rows, ["paper-quick"])
    history = dashboard.build_history(store.results_frame())
    html_text = dashboard.paper_gaps(history, dashboard.paper_reference(), store.runs_frame())
    rows = re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td><td>([^<]*)</td>(.*?)</tr>", html_text)
    by_holes = {holes: re.findall(r"([+-]\d+\.\d\d) dB", cells) for _, holes, _, cells in rows}
    assert set(by_holes) == {"independent holes", "coherent holes"}
    assert by_holes["independent holes"] == ["+20.00", "+8.00", "+3.00"]  # vs meshlab, lozes-pde, fu-nonlocal
    assert by_holes["coherent holes"] == ["+18.00", "+6.00", "+1.00"]


def test_reproduce_paper_then_dashboard_in_headless_chromium(tmp_path, monkeypatch, capsys):
    """The README's flow: `reproduce-paper --quick` (here with 2 frames a sequence and one seed to keep it short),
    then `dpcbench dashboard` on the same store, and the page opened in a real browser: the gaps to
    the paper are shown per sequence and hole configuration."""
    if shutil.which("chromium") is None and shutil.which("chromium-browser") is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium; ./install.sh --dev installs it)")
    monkeypatch.setenv("DPCBENCH_QUIET", "1")
    store = str(tmp_path / "results.sqlite")
    code = cli_main(["reproduce-paper", "--quick", "--frames", "2", "--seeds", "0", "--out", str(tmp_path / "r"), "--store", store])
    out = capsys.readouterr().out
    assert code == 0, out
    assert (tmp_path / "r" / "REPORT.md").is_file()
    page = tmp_path / "d.html"
    assert cli_main(["dashboard", "--out", str(page), "--store", store]) == 0
    assert "dashboard written" in capsys.readouterr().out
    result = run_chromium(["--dump-dom", page.resolve().as_uri()], tmp_path / "profile")
    assert result.returncode == 0, result.stderr[-2000:]
    dom = result.stdout
    assert "Against the paper" in dom
    assert "D2 (point-to-plane): normals from file" in dom  # the stand-ins' own normals
    gaps = dom[dom.index("class=\"gaps\"") if 'class="gaps"' in dom else dom.index("class='gaps'"):]
    gaps = gaps[:gaps.index("</table>")]
    rows = re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td><td>([^<]*)</td>", gaps)
    configurations = {(sequence, holes) for sequence, holes, _ in rows}
    for sequence in ("Human (stand-in)", "Bunny (stand-in)"):
        assert {(sequence, "independent holes"), (sequence, "coherent holes")} <= configurations, configurations
    assert len(re.findall(r" dB</td>", gaps)) >= 3 * len(rows)  # a gain vs every other method in each row
