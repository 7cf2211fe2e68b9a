"""`dpcbench dashboard`: a static page built from a store with two code versions, checked in a real
browser (Debian's chromium, headless) when it is installed."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.reporting import dashboard, palette
from dpcbench.bench.results import benchsuite
from dpcbench.bench.results.store import ResultsStore

METHODS = {"temporal-graph": (40.0, 1e-7, 2.0), "fu-nonlocal": (36.0, 3e-7, 1.5), "none": (12.0, 5e-6, 0.01)}
VERSIONS = [("1111111111aaaaaaaaaa", "2026-01-01T10:00:00+00:00"),
            ("2222222222bbbbbbbbbb", "2026-01-02T10:00:00+00:00")]


def make_store(path, *, versions=(0, 1), spec_ids=False, machine=None):
    """Runs of 3 methods on 1 sequence at two code versions; at the second, fu-nonlocal loses 2 dB
    GPSNR D1 and doubles its NSHD (both scopes), everything else is identical. ``machine``: the node
    name the runs' env records (none by default)."""
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
                finished_at=when, env={"packages": {"numpy": np.__version__},
                                       **({"machine": {"node": machine, "arch": "x86_64", "cpus": 2}}
                                          if machine else {})}), rows, ["regression"])
    if 1 not in versions:
        return store
    store.record_failure("broken", dict(sequence="human", holes="region", holes_params={}, seed=0, method="meshlab",
                                        method_params={}, code_version=VERSIONS[1][0], created_at=VERSIONS[1][1]),
                         "RuntimeError: pymeshlab said no", ["regression"])
    return store


def page_figures(page: str) -> dict:
    """The plotly figures of a page, by chart id (its JSON blocks merged)."""
    figures = {}
    for block in re.findall(r'<script type="application/json" class="dash-figures">(.*?)</script>', page, re.S):
        figures.update(json.loads(block.replace("<\\/", "</")))
    return figures


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
    # scripts: plotly.js once, the page's own, and the figures as (inert) JSON blocks
    scripts = re.findall(r"<script([^>]*)>", page)
    assert scripts.count(f' id="{dashboard.PLOTLY_SCRIPT_ID}"') == 1
    assert set(scripts) == {f' id="{dashboard.PLOTLY_SCRIPT_ID}"', "", ' type="application/json" class="dash-figures"'}
    # fu-nonlocal regressed in gpsnr_d1 and nshd, both scopes: 4 flagged rows in the "changes" table
    changes = page.split('<section id="comparison">')[1].split("<details>")[0]
    assert changes.count('class="regressed"') == 4
    assert set(re.findall(r'class="regressed" data-status="REGRESSED"><td>human</td><td>region</td><td>'
                          r'<span[^>]*></span>([^<]+)</td>', changes)) == {"fu-nonlocal"}
    assert all(len(trace["x"]) == 2 for figure in page_figures(page).values() for trace in figure["data"])
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
    assert colours["temporal-graph"] == palette.METHOD_COLOURS["temporal-graph"]
    assert colours["fu-nonlocal"] == palette.METHOD_COLOURS["fu-nonlocal"]
    assert dashboard.method_colours(["zzz", "temporal-graph (variant=paper)"])["temporal-graph (variant=paper)"] == (
        colours["temporal-graph"])  # by name, whatever else is listed
    assert dashboard.short_version("0123456789abcdef0123+dirty") == "01234567+"
    paper = dashboard.paper_reference()
    row = paper[(paper["sequence"] == "loot") & (paper["method"] == "temporal-graph") & (paper["metric"] == "gpsnr_d1")]
    assert row["value"].tolist() == [pytest.approx(47.5648)]


def test_cli_dashboard_errors(tmp_path, capsys):
    assert cli_main(["dashboard", "--out", str(tmp_path / "x.png"), "--store", str(tmp_path / "s")]) == 2
    assert ".html" in capsys.readouterr().err
    assert cli_main(["dashboard", "--out", str(tmp_path / "x.html"), "--store", str(tmp_path / "absent.sqlite")]) == 2
    assert "no results store there" in capsys.readouterr().err
    assert cli_main(["dashboard", "--store", str(tmp_path / "s")]) == 2
    assert "give --out FILE.html" in capsys.readouterr().err
    assert cli_main(["dashboard", "--out", str(tmp_path / "x.html"), "--history", str(tmp_path / "none")]) == 2
    assert "no such history folder" in capsys.readouterr().err
    (tmp_path / "h").mkdir()
    (tmp_path / "h" / "notes.csv").write_text("a,b\n1,2\n")
    assert cli_main(["dashboard", "--out", str(tmp_path / "x.html"), "--history", str(tmp_path / "h")]) == 2
    assert "notes.csv: not a dpcbench summary" in capsys.readouterr().err


def run_chromium(args: list[str], profile) -> subprocess.CompletedProcess:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium; ./install.sh --dev installs it)")
    command = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               f"--user-data-dir={profile}", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


#: injected first into <head>: collects uncaught errors and console.error calls of the page
BROWSER_HOOK = ("<script>window.__errors=[];window.addEventListener('error',function(e){window.__errors.push("
                "String(e.message))});var __err=console.error;console.error=function(){window.__errors.push("
                "Array.prototype.join.call(arguments,' '));__err.apply(console,arguments)};</script>")


def browse(page, checks_js: str, profile, width: int = 1400) -> tuple[dict, str]:
    """Open a copy of ``page`` in headless chromium (window ``width`` px wide), run ``checks_js``
    (the body of a function of ``r``, an object it fills) after the load event, and return (r plus
    the page's errors and the count of resources it fetched, the DOM)."""
    probe = page.with_name(page.stem + ".probe.html")
    runner = ("<script>window.addEventListener('load',function(){var r={};try{(function(r){" + checks_js +
              "})(r);}catch(e){r.check_error=String(e)}r.errors=window.__errors;"
              "r.resources=performance.getEntriesByType('resource').map(function(x){return x.name});"
              "var pre=document.createElement('pre');pre.id='probe';pre.textContent=JSON.stringify(r);"
              "document.body.appendChild(pre);});</script>")
    text = page.read_text(encoding="utf-8")
    probe.write_text(text.replace("<head>", "<head>" + BROWSER_HOOK, 1).replace("</body>", runner + "</body>"),
                     encoding="utf-8")
    result = run_chromium([f"--window-size={width},900", "--virtual-time-budget=5000", "--dump-dom",
                           probe.resolve().as_uri()], profile)
    assert result.returncode == 0, result.stderr[-2000:]
    found = re.search(r'<pre id="probe">(.*?)</pre>', result.stdout, re.S)
    assert found, result.stdout[-2000:]
    return json.loads(html.unescape(found.group(1))), result.stdout


def test_dashboard_in_headless_chromium(tmp_path, capsys):
    """Two regression runs at two commits on two machines, each saved to a history folder; the page
    from the newer store plus the folder, opened in chromium at 1400 px: no console error, nothing
    fetched, the charts of the first metric drawn with a point per commit, the filters change what
    is shown, the speed chart marks the machine change, no section scrolls sideways, the flagged
    rows and the benchmark history are there."""
    history = tmp_path / "history"
    for v, node in ((0, "ci-a"), (1, "ci-b")):
        make_store(tmp_path / f"{v}.sqlite", versions=(v,), spec_ids=True, machine=node)
        assert cli_main(["dashboard", "--save-history", str(history), "--store", str(tmp_path / f"{v}.sqlite")]) == 0
    out = tmp_path / "dash.html"
    bench_dir = write_benchmark_sessions(tmp_path / "bench")
    assert cli_main(["dashboard", "--history", str(history), "--out", str(out), "--store", str(tmp_path / "1.sqlite"),
                     "--benchmarks", str(bench_dir)]) == 0
    assert "2 code version(s)" in capsys.readouterr().out
    checks = """
      function shown(kind) { return [].filter.call(document.querySelectorAll('.plot-box[data-kind="' + kind + '"]'),
                                                   function (b) { return !b.hidden; }); }
      function pick(name, value) { var s = document.querySelector('select[data-filter="' + name + '"]');
                                   s.value = value; s.dispatchEvent(new Event('change')); }
      r.boxes = document.querySelectorAll('.plot-box').length;
      r.first = shown('quality').map(function (b) { return b.dataset.metric + '/' + b.dataset.scope; });
      r.drawn_first = document.querySelectorAll('.js-plotly-plot').length;
      r.points = shown('quality').map(function (b) {
        return b.querySelector('.plot').data.map(function (t) { return t.x.length; }); });
      pick('metric', 'nshd'); pick('scope', 'holes');
      r.nshd_holes = shown('quality').map(function (b) { return b.dataset.metric + '/' + b.dataset.scope; });
      r.count_text = document.getElementById('filter-count').textContent;
      pick('metric', ''); pick('scope', '');
      r.all = shown('quality').length;
      r.drawn_all = document.querySelectorAll('.js-plotly-plot').length;
      r.wide = [].filter.call(document.querySelectorAll('section'), function (s) {
        return s.scrollWidth > s.clientWidth + 1; }).map(function (s) { return s.id; });
    """
    r, dom = browse(out, checks, tmp_path / "profile")
    assert r.get("check_error") is None and r["errors"] == [] and r["resources"] == []
    # quality: 3 metrics x 2 scopes; time per frame: 1 (no CPU time in these runs); benchmarks: 1 group
    assert r["boxes"] == 6 + 1 + 1
    assert r["first"] == ["gpsnr_d1/frame", "gpsnr_d1/holes"] and r["drawn_first"] == 2 + 1 + 1
    assert r["points"] == [[2, 2, 2], [2, 2, 2]]  # each method: a point per commit
    # the time and benchmark charts have no metric or scope: they stay (3 = nshd/holes + time + benchmarks)
    assert r["nshd_holes"] == ["nshd/holes"] and r["count_text"] == "3 of 8 charts shown"
    assert r["all"] == 6 and r["drawn_all"] == 8
    assert r["wide"] == []
    assert "machine changed" in dom  # the speed chart's label, drawn by plotly
    assert len(re.findall(r'<tr class="regressed" data-status="REGRESSED"', dom)) >= 4
    assert re.search(r'data-card="regressions">.*?<div class="v">4</div>', dom)
    for method in METHODS:
        assert method in dom
    assert 'data-chart="benchmarks" data-sessions="2"' in dom and "test_gpsnr_1m" in dom
    assert (tmp_path / "dash_pages").is_dir() and 'href="dash_pages/run-' in dom


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
    from dpcbench.bench.results import compare

    old = make_store(tmp_path / "old.sqlite", versions=(0,))
    summary = tmp_path / "old.csv"
    meta = compare.summary_meta(VERSIONS[0][0], environment={}, experiment="regression")
    meta["date"] = VERSIONS[0][1]  # the history orders versions by time: the summary's date stands for its runs
    compare.write_summary(compare.summarize(old.results_frame()), summary, meta)
    make_store(tmp_path / "new.sqlite", versions=(1,))
    out = tmp_path / "d.html"
    assert cli_main(["dashboard", "--no-history", "--out", str(out), "--store", str(tmp_path / "new.sqlite"),
                     "--summary", str(summary)]) == 0
    page = out.read_text()
    quality = [f for k, f in page_figures(page).items() if k.startswith("quality")]
    assert quality and all(f["layout"]["xaxis"]["categoryarray"] == ["11111111", "22222222"] for f in quality)
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
    assert "<span class='note'>frame @1023</span>" in latest and ">21.5000<" in latest and ">71.5000<" in latest
    assert '&quot;@1023&quot;: PSNR with peak 1023' in latest
    traces = [t for f in page_figures(page).values() for t in f["data"] if t["name"].endswith("@peak 1023")]
    assert len(traces) == 1 and traces[0]["line"]["dash"] == "dot" and traces[0]["y"] == [71.5]


def test_comparison_against_a_baseline_summary(tmp_path):
    from dpcbench.bench.results import compare

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
    from dpcbench.bench.reporting import paper

    # without the real-motion rows (D-FAUST's 100k points a frame would double this test's time, and samba is a
    # third of it; tests/test_meshseq.py and test_paper_targets.py cover them): the page is checked on the stand-ins
    monkeypatch.setattr(paper, "REAL_MOTION", {})
    store = str(tmp_path / "results.sqlite")
    code = cli_main(["reproduce-paper", "--quick", "--frames", "2", "--seeds", "0", "--out", str(tmp_path / "r"), "--store", store])
    out = capsys.readouterr().out
    assert code == 0, out
    assert (tmp_path / "r" / "REPORT.md").is_file()
    page = tmp_path / "d.html"
    assert cli_main(["dashboard", "--no-history", "--out", str(page), "--store", store]) == 0
    assert "dashboard written" in capsys.readouterr().out
    # at 1400 px no section scrolls sideways (the latest results table has 4 metrics x 2 scopes here)
    r, dom = browse(page, "r.wide = [].filter.call(document.querySelectorAll('section'), function (s) {"
                          "return s.scrollWidth > s.clientWidth + 1; }).map(function (s) { return s.id; });",
                    tmp_path / "profile")
    assert r["errors"] == [] and r["resources"] == [] and r["wide"] == []
    assert "Against the paper" in dom
    # the stand-ins' own normals (per sequence when a real capture without normals, D-FAUST punching, is a row too)
    assert ("D2 (point-to-plane): normals from file" in dom
            or all(f"{s} (stand-in): normals from file" in dom for s in ("Bunny", "Human"))), dom
    gaps = dom[dom.index("class=\"gaps\"") if 'class="gaps"' in dom else dom.index("class='gaps'"):]
    gaps = gaps[:gaps.index("</table>")]
    rows = re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td><td>([^<]*)</td>", gaps)
    configurations = {(sequence, holes) for sequence, holes, _ in rows}
    for sequence in ("Human (stand-in)", "Bunny (stand-in)"):
        assert {(sequence, "independent holes"), (sequence, "coherent holes")} <= configurations, configurations
    assert len(re.findall(r" dB</td>", gaps)) >= 3 * len(rows)  # a gain vs every other method in each row


def test_history_folder_over_two_commits_marks_the_machine_change(tmp_path, capsys):
    """Two regression runs at two commits on two machines, each saved to a history folder with
    --save-history (one summary file per commit), then the page from the folder alone: every chart
    has one point per commit, the hover names commit, date and machine, and the speed chart marks
    the change of machine."""
    from dpcbench.bench.results import compare

    folder = tmp_path / "history"
    for v, node in ((0, "ci-a"), (1, "ci-b")):
        make_store(tmp_path / f"{v}.sqlite", versions=(v,), machine=node)
        assert cli_main(["dashboard", "--save-history", str(folder), "--store", str(tmp_path / f"{v}.sqlite")]) == 0
    assert "summary of code 22222222" in capsys.readouterr().out
    files = sorted(p.name for p in folder.iterdir())
    assert files == ["20260101T100000_1111111111aaaaaaaaaa.csv", "20260102T100000_2222222222bbbbbbbbbb.csv"]
    # saving the same commit again replaces its file; one dpcbench did not write only with --overwrite
    assert cli_main(["dashboard", "--save-history", str(folder), "--store", str(tmp_path / "1.sqlite")]) == 0
    assert len(list(folder.iterdir())) == 2
    newest = folder / files[1]
    newest.write_text(newest.read_text() + "\n")  # edited by hand (or checked out by git): not dpcbench's now
    assert cli_main(["dashboard", "--save-history", str(folder), "--store", str(tmp_path / "1.sqlite")]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert cli_main(["dashboard", "--save-history", str(folder), "--store", str(tmp_path / "1.sqlite"),
                     "--overwrite"]) == 0
    assert len(list(folder.iterdir())) == 2
    table, meta = compare.read_summary(folder / files[0])
    assert meta["code_version"] == VERSIONS[0][0] and meta["env.node"] == "ci-a" and meta["experiment"] == "regression"
    # mean, std and n of each cell survive the round trip through the history
    again = compare.summarize(dashboard.summary_as_results(table, meta))
    merged = table.merge(again, on=compare.KEY_COLUMNS, suffixes=("", "_again"))
    assert len(merged) == len(table)
    assert np.allclose(merged["mean"], merged["mean_again"]) and np.allclose(merged["std"], merged["std_again"])
    assert (merged["n_frames"] == merged["n_frames_again"]).all()

    out = tmp_path / "d.html"
    assert cli_main(["dashboard", "--out", str(out), "--history", str(folder), "--summary", str(folder / files[0]),
                     "--no-pages"]) == 0
    assert "2 code version(s), 0 runs, 3 summaries" in capsys.readouterr().out
    assert re.search(r'data-card="runs"><div class="k">runs</div><div class="v">0</div>', out.read_text())
    figures = page_figures(out.read_text())
    quality = [f for k, f in figures.items() if k.startswith("quality")]
    assert len(quality) == 3 * 2  # gpsnr_d1, gpsnr_d2, nshd x frame, holes
    for figure in quality:
        assert figure["layout"]["xaxis"]["categoryarray"] == ["11111111", "22222222"]
        assert all(trace["x"] == ["11111111", "22222222"] for trace in figure["data"])
    fu = [t for t in quality[0]["data"] if t["name"] == "fu-nonlocal"][0]
    assert fu["y"] == pytest.approx([46.0, 44.0], abs=0.02)  # GPSNR D1, frame scope: the regression
    assert "commit 2222222222bbbbbbbbbb" in fu["text"][1] and "2026-01-02 10:00" in fu["text"][1]
    assert "± 0.0" in fu["text"][1] and "n = 3" in fu["text"][1]
    speed = figures["time_s-0"]
    assert [s["x0"] for s in speed["layout"]["shapes"]] == ["22222222"]
    assert all("machine changed: ci-a, x86_64, 2 cpus → ci-b, x86_64, 2 cpus" in t["text"][1] for t in speed["data"])
    assert "machine changed" not in speed["data"][0]["text"][0]


def test_regressions_card_compares_with_the_committed_baseline(tmp_path, capsys):
    """A store of the regression preset's cells (the committed baseline's values, one cell 1 dB
    worse): by default the card and the comparison are against results/regression-baseline.csv,
    as `dpcbench compare` is; `--baseline previous` compares code versions instead (one here: none)."""
    from dpcbench.bench.cli.options import DEFAULT_BASELINE
    from dpcbench.bench.results import compare

    table, meta = compare.read_summary(DEFAULT_BASELINE)
    results = dashboard.summary_as_results(table, meta)
    worse = ((results["method"] == "fu-nonlocal") & (results["metric"] == "gpsnr_d1") & (results["scope"] == "frame")
             & (results["sequence"] == results["sequence"].iloc[0]))
    assert worse.any()
    results.loc[worse, "value"] -= 1.0
    store = ResultsStore(tmp_path / "s.sqlite")
    for run_id, rows in results.groupby("run_id"):
        first = rows.iloc[0]
        store.record_run(run_id, dict(sequence=first["sequence"], holes=first["holes"],
                                      holes_params=json.loads(first["holes_params"]), seed=0, method=first["method"],
                                      method_params=json.loads(first["method_params"]), code_version="abcdef0123456789",
                                      created_at="2026-02-01T00:00:00+00:00"),
                         rows[["frame", "metric", "scope", "peak", "value"]].to_dict("records"), ["regression"])
    out = tmp_path / "d.html"
    assert cli_main(["dashboard", "--no-history", "--no-pages", "--out", str(out), "--store", str(tmp_path / "s.sqlite")]) == 0
    page = out.read_text()
    assert re.search(r'data-card="regressions">.*?<div class="v">1</div>', page)
    comparison = page.split('<section id="comparison">')[1].split("</section>")[0]
    assert "results/regression-baseline.csv" in comparison
    assert comparison.split("<details>")[0].count('data-status="REGRESSED"') == 1
    assert cli_main(["dashboard", "--no-history", "--no-pages", "--out", str(out), "--store", str(tmp_path / "s.sqlite"),
                     "--baseline", "previous"]) == 0
    assert '<section id="comparison">' not in out.read_text()


def test_method_and_run_pages_beside_the_page(tmp_path, capsys):
    """`dashboard --out d.html` writes d_pages/: a page per method configuration (its rows at both
    code versions) and per run (its per-frame values as stored, a thumbnail of the fill and links
    to its run folder and log where they exist), each linked from the page and back to it."""
    import base64
    import io
    import sqlite3

    import matplotlib.image

    from dpcbench.bench.data.plyio import PointCloud, write_ply
    from dpcbench.bench.reporting import dashboard_pages

    store = make_store(tmp_path / "s.sqlite")
    # one run with its folder (frame 0: 150 points kept, 50 added by the method) and its log
    runs_dir = tmp_path / "runs"
    folder = runs_dir / "inpaint-key"
    points = np.random.default_rng(1).uniform(-1, 1, size=(200, 3))
    write_ply(folder / "damaged" / "frame_0000.ply", PointCloud(points[:150]))
    write_ply(folder / "inpainted" / "frame_0000.ply", PointCloud(points))
    (folder / "manifest.json").write_text("{}")
    run_id = "2222-temporal-graph"
    (runs_dir / "logs").mkdir()
    (runs_dir / "logs" / f"{run_id}.log").write_text("worker log")
    with sqlite3.connect(tmp_path / "s.sqlite") as conn:
        conn.execute("UPDATE runs SET output_dir = ? WHERE run_id = ?", (str(folder), run_id))
    out = tmp_path / "d.html"
    assert cli_main(["dashboard", "--no-history", "--out", str(out), "--store", str(tmp_path / "s.sqlite")]) == 0
    assert "10 method and run pages beside it" in capsys.readouterr().out  # 3 methods, 6 runs done, 1 failed
    pages = tmp_path / "d_pages"
    main = out.read_text()
    links = set(re.findall(r'href="(d_pages/[^"]+)"', main))
    assert {p.name for p in pages.iterdir()} == {link.split("/")[1] for link in links} and len(links) == 10
    for page in pages.iterdir():
        text = page.read_text()
        assert 'href="../d.html"' in text and dashboard.external_references(text) == [] and "<script" not in text
    method = (pages / dashboard_pages.method_file("fu-nonlocal")).read_text()
    assert re.findall(r'data-version="([^"]+)"', method) == [VERSIONS[1][0], VERSIONS[0][0]]
    assert method.count('href="run-') == 2  # its run at each version
    # the run page: per-frame values as stored, links, thumbnail with the 50 added points in red
    run = (pages / dashboard_pages.run_file(run_id)).read_text()
    stored = store.results_frame()
    stored = stored[(stored["run_id"] == run_id) & (stored["metric"] == "gpsnr_d1") & (stored["scope"] == "holes")]
    table = run.split("class='per-frame'")[1]
    head = re.findall(r"<th>(.*?)</th>", table.split("</thead>")[0])
    column = [i for i, h in enumerate(head) if h.startswith("GPSNR D1") and ">holes<" in h][0]
    for frame, value in zip(stored["frame"], stored["value"]):
        cells = re.findall(r"<td[^>]*>([^<]*)</td>", table.split(f'data-frame="{frame}">')[1].split("</tr>")[0])
        assert float(cells[column]) == pytest.approx(value, abs=1e-4)
    assert f'href="{folder.resolve().as_uri()}"' in run and (runs_dir / "logs" / f"{run_id}.log").resolve().as_uri() in run
    png = base64.b64decode(re.search(r'src="data:image/png;base64,([^"]+)"', run).group(1))
    image = matplotlib.image.imread(io.BytesIO(png), format="png")[..., :3]
    red = (image[..., 0] > 0.8) & (image[..., 1] < 0.2)
    left, right = red[:, : image.shape[1] // 2], red[:, image.shape[1] // 2:]
    assert right.sum() > 0 and left.sum() == 0  # the fill is red in the output, the input has none
    # a large frame is drawn from a subset of its points: same size of picture
    small = matplotlib.image.imread(io.BytesIO(dashboard_pages.thumbnail_png(folder, max_points=120)), format="png")
    assert small.shape == image.shape[:2] + small.shape[2:]
    other = (pages / dashboard_pages.run_file("1111-none")).read_text()
    assert "No thumbnail" in other and "none on this machine" in other
    failed = (pages / dashboard_pages.run_file("broken")).read_text()
    assert "pymeshlab said no" in failed


def test_readable_times_intervals_and_benchmark_machine_change(tmp_path):
    from scipy import stats

    assert [dashboard.readable_seconds(v) for v in (None, float("nan"), 0.00917, 12.34, 33.0 * 60, 5.4 * 3600)] == [
        "-", "-", "9.17 ms", "12.3 s", "33 min", "5.4 h"]
    values = np.array([3.0, 4.5, 4.0, 7.5])
    low, high = dashboard.t_interval(values.mean(), values.std(), len(values))  # population std, as summaries keep
    assert (low, high) == pytest.approx(stats.t.interval(0.95, len(values) - 1, loc=values.mean(),
                                                         scale=stats.sem(values)))
    assert dashboard.t_interval(1.0, 0.5, 1) is None
    # the second benchmark session ran on another machine: marked on the chart and in its hover
    folder = write_benchmark_sessions(tmp_path / "b")
    second = sorted(folder.glob("0002_*.json"))[0]
    doc = json.loads(second.read_text())
    doc["machine_info"]["node"] = "other"
    second.write_text(json.dumps(doc))
    charts = dashboard.benchmark_charts(benchsuite.load_benchmark_runs(folder))
    assert len(charts) == 1 and len(charts[0].figure["data"]) == 2
    layout = charts[0].figure["layout"]
    assert len(layout["shapes"]) == 1 and layout["shapes"][0]["x0"] == layout["xaxis"]["categoryarray"][1]
    assert all("machine changed: ci Test CPU" in t["text"][1] and "machine changed" not in t["text"][0]
               for t in charts[0].figure["data"])
