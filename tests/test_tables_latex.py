"""LaTeX tables for a two-column paper (bench/reporting/latex_tables.py): booktabs structure, the column count of
every row, `table` or `table*` by the estimated width, short labels with their key, escaping of hostile
labels, the paper's rows with the table's decimals, a pdflatex compile (skipped without pdflatex); and
the config's [labels] renaming methods in `dpcbench report`."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pandas as pd
import pytest

from dpcbench.bench.cli import main as cli_main
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.experiment.config import ConfigError, load_labels, parse_config, parse_labels
from dpcbench.bench.reporting import latex_tables, paper
from dpcbench.bench.reporting.reports import paper_tables, rename_methods, write_comparison_report
from dpcbench.bench.reporting.tables import comparison_table
from dpcbench.bench.results.store import ResultsStore
from tests import runner_fixtures as helpers
from tests.runner_fixtures import tidy_results

HOSTILE = "a_b&c%\\end{table}"


def _table(methods, sequences=("S",), metric="gpsnr_d1", **kwargs):
    scale = 1e7 if metric == "nshd" else 1.0  # NSHD in units of 1e-7, as Table 2
    cells = {(seq, m): (10.0 + i + j) / scale for j, seq in enumerate(sequences) for i, m in enumerate(methods)}
    step = 1 / scale
    return comparison_table(tidy_results(cells, metric=metric, step=step), metric, "frame",
                            "intrinsic" if metric.startswith("gpsnr") else "", scale=scale, **kwargs)


def _paper_style_tables():
    """Table 1 and 2 as reproduce-paper writes them, from a tidy table with every column of ours."""
    frames = []
    for i, (name, _label, params, _role) in enumerate(paper.TABLE_COLUMNS):
        for j, seq in enumerate(("Human (stand-in)", "Bunny (stand-in)")):
            for metric, base, step in (("gpsnr_d1", 20.0 + i + 3 * j, 1.0), ("nshd", (20.0 + i + 3 * j) * 1e-7, 1e-7)):
                frames.append(tidy_results({(seq, name): base}, metric=metric, step=step).assign(
                    method_params=json.dumps(params, sort_keys=True)))
    return paper_tables(pd.concat(frames, ignore_index=True), standins=True)


def _without_comments(tex: str) -> str:
    return "\n".join(re.sub(r"(?<!\\)%.*$", "", line) for line in tex.splitlines())


def structure(tex: str) -> tuple[str, str]:
    """(environment, tabular spec) of a table's LaTeX after checking its structure: the booktabs
    comment first, no \\hline, balanced braces and begin/end, one \\toprule before the \\midrule(s)
    and one \\bottomrule after, every row with as many cells as the spec has columns."""
    assert tex.startswith(r"% needs \usepackage{booktabs}")
    body = _without_comments(tex)
    assert r"\hline" not in body
    depth, i = 0, 0
    while i < len(body):
        if body[i] == "\\":
            i += 2  # an escaped character (\{ \} \& \% \\) or the first letter of a command
            continue
        depth += {"{": 1, "}": -1}.get(body[i], 0)
        assert depth >= 0, body[:i]
        i += 1
    assert depth == 0
    stack = []
    for kind, name in re.findall(r"\\(begin|end)\{([^}]*)\}", body):
        if kind == "begin":
            stack.append(name)
        else:
            assert stack and stack.pop() == name
    assert not stack
    env = re.search(r"\\begin\{(table\*?)\}", body).group(1)
    spec = re.search(r"\\begin\{tabular\}\{([^}]*)\}", body).group(1)
    lines = body.splitlines()
    top, bottom = lines.index(r"\toprule"), lines.index(r"\bottomrule")
    assert lines.count(r"\toprule") == 1 and lines.count(r"\bottomrule") == 1
    assert all(top < k < bottom for k, line in enumerate(lines) if line == r"\midrule")
    rows = [line for line in lines[top + 1:bottom] if line != r"\midrule"]
    assert rows and lines[top + 2] == r"\midrule"  # a rule between the header and our rows
    for row in rows:
        assert row.endswith(r" \\"), row
        flat = re.sub(r"\\begin\{tabular\}\[t\].*?\\end\{tabular\}", "cell", row)  # a stacked cell is one cell
        assert len(re.findall(r"(?<!\\)&", flat)) + 1 == len(spec), row
    return env, spec


def test_booktabs_structure_and_rules_between_header_ours_and_the_papers():
    t1, t2 = _paper_style_tables()
    for table in (t1, t2):
        tex = table.latex()
        env, spec = structure(tex)
        assert spec == "l" + "c" * len(paper.ALL_COLUMNS)
        lines = tex.splitlines()
        # header, rule, our 2 rows, rule, the paper's 5 rows in italics, bottom rule
        top = lines.index(r"\toprule")
        assert lines[top + 2] == r"\midrule" and lines[top + 5] == r"\midrule"
        assert all(line.startswith(r"\textit{") for line in lines[top + 6:top + 11])
        assert lines[top + 11] == r"\bottomrule"
        assert env == "table*"  # 8 value columns do not fit one column


def test_table_or_table_star_by_the_estimated_width():
    small = _table(["a", "b"]).latex()
    assert structure(small)[0] == "table"
    width = float(re.search(r"estimated width ([\d.]+) in", small).group(1))
    assert width <= latex_tables.SINGLE_COLUMN_IN
    wide = _table([f"method{i}" for i in range(8)]).latex()
    assert structure(wide)[0] == "table*"
    assert float(re.search(r"estimated width ([\d.]+) in", wide).group(1)) > latex_tables.SINGLE_COLUMN_IN
    # four NSHD columns with 4 decimals: too wide on one line, in one column once stacked
    four = _table(["a", "b", "c", "d"], metric="nshd", decimals=4).latex()
    assert structure(four)[0] == "table" and "stacked cells" in four
    assert r"\begin{tabular}[t]{@{}c@{}}" in four
    # the rule itself, on widths in pt
    one_column = latex_tables.SINGLE_COLUMN_IN * latex_tables.PT_PER_IN
    assert latex_tables.placement({"inline": one_column, "stacked": 1.0}) == ("table", "inline", True)
    assert latex_tables.placement({"inline": one_column + 1, "stacked": one_column}) == ("table", "stacked", True)
    assert latex_tables.placement({"inline": 400.0, "stacked": 300.0}) == ("table*", "inline", True)
    assert latex_tables.placement({"inline": 900.0, "stacked": 800.0}) == ("table*", "stacked", False)


def test_long_labels_are_shortened_with_a_key_giving_them_in_full():
    shorts = latex_tables.short_labels(["temporal-graph (beta=0.25)", "temporal-graph (beta=0.5)", "Hu",
                                        "No fill (floor)", "No fill"], 11)
    assert shorts == {"temporal-graph (beta=0.25)": "temporal-g.1", "temporal-graph (beta=0.5)": "temporal-g.2",
                      "Hu": "Hu", "No fill (floor)": "No fill1", "No fill": "No fill"}
    t = _table(["temporal-graph (beta=0.25)", "temporal-graph (beta=0.5)", "Hu"],
               sequences=("Human (stand-in) · region (coherent=True)",))
    tex = t.latex()
    header = next(line for line in tex.splitlines() if line.startswith("Sequence &"))
    assert header == r"Sequence & temporal-g.1 & temporal-g.2 & Hu \\"
    assert "Columns: temporal-g.1: temporal-graph (beta=0.25); temporal-g.2: temporal-graph (beta=0.5)." in tex
    assert r"Rows: Human $\cdot$ region: Human (stand-in) $\cdot$ region (coherent=True)." in tex
    assert structure(tex)[0] == "table"


def test_hostile_labels_are_escaped():
    t = _table([HOSTILE, "[b]", "c~^#$}"], sequences=("[x] seq", HOSTILE))
    tex = t.latex()
    env, _ = structure(tex)
    body = _without_comments(tex)
    assert body.count(r"\end{table}") == 1 and body.count(r"\begin{table}") == 1
    assert r"a\_b\&c\%\textbackslash{}end\{table\}" in body  # in full, in the key
    assert "\n{[}x{]} seq & " in body  # a row starting with "[" is no optional argument of the \\ before it
    assert r"c\textasciitilde{}\textasciicircum{}\#\$\}" in body


def test_the_papers_rows_have_the_tables_decimals():
    t1, t2 = _paper_style_tables()
    for table, digits in ((t1, 2), (t2, 4)):
        assert table._digits() == digits
        for text in (table.latex(), table.markdown()):
            paper_lines = [line for line in text.splitlines() if line.startswith((r"\textit{Loot}", "| *Loot"))]
            assert len(paper_lines) == 1
            numbers = re.findall(r"\d+\.\d+", paper_lines[0])
            assert len(numbers) == 4 and all(len(n.split(".")[1]) == digits for n in numbers), paper_lines
    assert r"\textit{Loot} & -- & 16.45 & 27.37 & 40.15 & \textbf{47.56}" in t1.latex()
    assert "| *Loot (paper)* | – | 14.1925 | 8.9410 | 3.1102 | **0.3549** |" in t2.markdown()


def _overfull_pt(log: str) -> list[float]:
    return [float(x) for x in re.findall(r"Overfull \\hbox \(([\d.]+)pt too wide\)", log)]


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex is not installed (no TeX on this machine); "
                    "the compile check runs where it is")
def test_the_tables_compile_in_a_two_column_paper(tmp_path):
    t1, t2 = _paper_style_tables()
    tables = {"small": _table(["a", "b", HOSTILE], sequences=("[x] seq", HOSTILE)),
              "stacked": _table(["a", "b", "c", "d"], metric="nshd", decimals=4), "table1": t1, "table2": t2}
    for name, table in tables.items():
        tex = table.latex()
        (tmp_path / f"{name}.tex").write_text(tex)
        # IEEEtran's letter geometry: 516 pt of text, 12 pt between the columns: 252 pt columns
        (tmp_path / f"doc_{name}.tex").write_text(
            "\\documentclass[twocolumn]{article}\n\\usepackage{booktabs}\n\\setlength{\\textwidth}{516pt}\n"
            "\\setlength{\\columnsep}{12pt}\n\\begin{document}\n\\typeout{COLUMNWIDTH=\\the\\columnwidth}\n"
            f"\\input{{{name}.tex}}\nSome text of the paper.\n\\end{{document}}\n")
        done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", f"doc_{name}.tex"],
                              cwd=tmp_path, capture_output=True, text=True, timeout=120)
        log = (tmp_path / f"doc_{name}.log").read_text(errors="replace")
        assert done.returncode == 0, f"{name}: pdflatex failed:\n{log[-3000:]}"
        assert "COLUMNWIDTH=252.0pt" in log
        env = structure(tex)[0]
        if name in ("small", "stacked"):
            assert env == "table"
        assert max(_overfull_pt(log), default=0.0) <= 10.0, f"{name} ({env}): {_overfull_pt(log)}"


# -- [labels] ---------------------------------------------------------------------------------------------
def _store(path):
    """Two methods on one sequence: temporal-fusion labelled "temporal-fusion (ours)" by its config,
    meshlab with no label (shown as its name)."""
    store = ResultsStore(path)
    for k, (method, label) in enumerate((("temporal-fusion", "temporal-fusion (ours)"), ("meshlab", None))):
        spec = {"method": {"name": method, "params": {}, "label": label},
                "holes": {"generator": "region", "params": {}, "label": None}}
        rows = [{"frame": f, "metric": "gpsnr_d1", "scope": "frame", "peak": "intrinsic", "value": 20.0 + 5 * k + f}
                for f in range(3)]
        record = {"sequence": "Human", "holes": "region", "holes_params": {}, "seed": 0, "method": method,
                  "method_params": {}, "method_version": "1", "code_version": "abc", "spec": spec,
                  "env": {"git_commit": "abc"}}
        store.record_run(f"run-{method}", record, rows, ["exp"])
    return store


def test_labels_rename_methods_in_the_reports_tables(tmp_path, monkeypatch):
    import matplotlib.figure

    legends: list[list[str]] = []  # the labels of every figure legend the report draws
    draw_legend = matplotlib.figure.Figure.legend

    def recording_legend(fig, *args, **kwargs):
        legend = draw_legend(fig, *args, **kwargs)
        legends.append([text.get_text() for text in legend.get_texts()])
        return legend

    monkeypatch.setattr(matplotlib.figure.Figure, "legend", recording_legend)
    store = _store(tmp_path / "s.sqlite")
    config = tmp_path / "exp.toml"
    config.write_text('[experiment]\nname = "exp"\n\n[labels]\n"temporal-fusion (ours)" = "Ours & co_"\n'
                      'meshlab = "MeshLab"\n')
    out = tmp_path / "report"
    assert cli_main(["report", str(tmp_path / "s.sqlite"), "--out", str(out), "--labels", str(config)]) == 0
    md = (out / "tables" / "gpsnr_d1_frame.md").read_text()
    tex = (out / "tables" / "gpsnr_d1_frame.tex").read_text()
    csv_text = (out / "tables" / "gpsnr_d1_frame.csv").read_text()
    assert "| Sequence | MeshLab | Ours & co\\_ |" in md and "temporal-fusion" not in md
    assert r"Sequence & MeshLab & Ours \& co\_ \\" in tex and "temporal-fusion" not in tex
    assert "Ours & co_" in csv_text and "temporal-fusion" not in csv_text
    assert "MeshLab" in (out / "REPORT.md").read_text()
    assert len(legends) >= 2 and all(set(labels) == {"Ours & co_", "MeshLab"} for labels in legends), legends
    structure(tex)
    # without --labels the report keeps the labels of the runs
    report = write_comparison_report(store.results_frame("exp"), store.runs_frame("exp"), tmp_path / "plain",
                                     title="t")
    assert "| Sequence | meshlab | temporal-fusion (ours) |" in report.read_text()


def test_bad_labels_are_refused():
    assert parse_labels({"a (ours)": "A", "b": "B"}) == {"a (ours)": "A", "b": "B"}
    with pytest.raises(ConfigError, match=r'^labels\."a \(ours\)": expected a non-empty string'):
        parse_labels({"a (ours)": "  "})
    with pytest.raises(ConfigError, match=r"^labels\.\"b\": expected a non-empty string.*got 3"):
        parse_labels({"b": 3})
    with pytest.raises(ConfigError, match=r'^labels\."b": "a" is renamed \'Same\' too; give each method its own'):
        parse_labels({"a": "Same", "b": "Same"})
    with pytest.raises(ConfigError, match=r"^labels: expected a \[labels\] table"):
        parse_labels(["a", "b"])
    labels = pd.Series(["tf (ours)", "meshlab", "meshlab"])
    assert list(rename_methods(labels, {"meshlab": "MeshLab"})) == ["tf (ours)", "MeshLab", "MeshLab"]
    with pytest.raises(UserError, match=r"^labels: no method labelled 'mesh' in these runs; the methods' labels"):
        rename_methods(labels, {"mesh": "M"})
    with pytest.raises(UserError, match=r"^labels: 'meshlab' is renamed 'tf \(ours\)', the label of another"):
        rename_methods(labels, {"meshlab": "tf (ours)"})
    # swapping two names is no clash
    assert list(rename_methods(labels, {"meshlab": "tf (ours)", "tf (ours)": "meshlab"}))[:2] == ["meshlab", "tf (ours)"]


def test_labels_from_a_file(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text('[labels]\n"x (ours)" = ""\n')
    with pytest.raises(ConfigError, match=r"c\.toml: labels\.\"x \(ours\)\": expected a non-empty string"):
        load_labels(path)
    path.write_text('[experiment]\nname = "e"\n')
    with pytest.raises(ConfigError, match=r"c\.toml: no \[labels\] table"):
        load_labels(path)
    store = _store(tmp_path / "s.sqlite")
    del store
    path.write_text('[labels]\n"no such method" = "X"\n')
    assert cli_main(["report", str(tmp_path / "s.sqlite"), "--out", str(tmp_path / "r"), "--labels", str(path)]) == 2
    err = capsys.readouterr().err
    assert "labels: no method labelled 'no such method'" in err and len(err.strip().splitlines()) == 1


def test_a_config_with_labels_parses_and_bad_ones_are_refused(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    seq = helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=200)
    config = {"experiment": {"name": "t"}, "sequences": [{"path": str(seq), "frames": 2}],
              "holes": [{"generator": "test-ball", "params": {"radius": 0.2}, "seed": 0}],
              "methods": [{"name": "test-identity", "label": "identity (ours)"}],
              "metrics": {"names": ["gpsnr_d1"]}, "labels": {"identity (ours)": "Ours"}}
    cfg = parse_config(config)
    assert cfg.labels == {"identity (ours)": "Ours"}
    plain = parse_config({k: v for k, v in config.items() if k != "labels"})
    assert plain.labels == {} and [r.run_id for r in cfg.expand()] == [r.run_id for r in plain.expand()]
    with pytest.raises(ConfigError, match=r'^labels\."identity \(ours\)": expected a non-empty string'):
        parse_config({**config, "labels": {"identity (ours)": ""}})
    with pytest.raises(ConfigError, match=r"^config\.label: unknown key"):
        parse_config({**config, "label": {}})
