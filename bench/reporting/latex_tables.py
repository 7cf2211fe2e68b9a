"""A `ComparisonTable` as LaTeX that fits a two-column paper (IEEEtran-like: 3.5 in columns).

booktabs rules (``\\toprule``, ``\\midrule`` between the header, our rows and the paper's rows,
the paper's in italics, ``\\bottomrule``); each of our cells as the mean and, in ``\\scriptsize``,
``±`` the half-width of its 95% interval (the Student-t interval is symmetric, so this is the
interval of the Markdown table), on one line or stacked; row and column labels shortened
(`short_labels`) with a key under the table giving each shortened label in full; the placement and
layout chosen by the table's estimated width (`placement`). Every label goes through
`latex_escape`.
"""

from __future__ import annotations

import math
import re
from collections import defaultdict
from typing import TYPE_CHECKING

from dpcbench.bench.results.compare import FLOOR_MARK, TIED_MARK

if TYPE_CHECKING:  # pragma: no cover  (a type only: tables imports this module)
    from dpcbench.bench.reporting.tables import ComparisonTable

#: the widths the placement is judged against: one column and the full text of an IEEEtran
#: two-column page (516 pt = 7.14 in; 1 in = 72.27 pt)
SINGLE_COLUMN_IN = 3.5
TEXT_WIDTH_IN = 7.14
PT_PER_IN = 72.27
#: the width per character (pt) of the tabular's text (\footnotesize, 8 pt in a 10 pt class:
#: cmr8 digits are 4.25 pt) and of the interval (\scriptsize, 7 pt: cmr7 digits about 4 pt), and
#: \tabcolsep as this table sets it; an estimate from characters, a little above the typeset width
TEXT_CHAR_PT = 4.3
SMALL_CHAR_PT = 4.0
TABCOLSEP_PT = 4.0
#: labels longer than these are shortened in the tabular (the key under the table gives them in full)
SHORT_COLUMN_CHARS = 11
SHORT_ROW_CHARS = 20
PREAMBLE_COMMENT = r"% needs \usepackage{booktabs} in the preamble (\toprule, \midrule, \bottomrule)"


_LATEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
          "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "±": r"$\pm$", "–": "--", "—": "---",
          "·": r"$\cdot$", "×": r"$\times$", "≈": r"$\approx$", "<": r"\textless{}", ">": r"\textgreater{}",
          "[": "{[}", "]": "{]}", TIED_MARK: r"$^{\dagger}$", FLOOR_MARK: r"$^{\nabla}$", "\n": " ", "\r": " "}


def latex_escape(text) -> str:
    """Text for LaTeX: its special characters (``\\ & % $ # _ { } ~ ^``) escaped, ``[`` and ``]`` braced
    (so that a cell starting with one is not taken for the optional argument of the ``\\\\`` or
    ``\\midrule`` before it), ``±·×≈–—`` and the cell marks as LaTeX, line breaks as spaces."""
    return "".join(_LATEX.get(ch, ch) for ch in str(text))


def _shortened(label: str, limit: int) -> str:
    """``label`` without its parenthesised parts and parameter JSON (``temporal-graph (beta=0.25)``
    -> ``temporal-graph``), cut to ``limit`` characters ending in "." when still longer."""
    base = re.sub(r"\s*\([^()]*\)", "", label)
    base = re.sub(r"\s*\{.*\}\s*$", "", base).strip() or label
    if len(base) > limit:
        base = base[:limit - 1].rstrip(" -·,;:_") + "."
    return base


def short_labels(labels: list[str], limit: int) -> dict[str, str]:
    """label -> a unique short label, in the order given: a label of at most ``limit`` characters
    stays as it is; a longer one is `_shortened`; shortened labels that come out equal to each
    other or to a kept label are numbered (``temporal-g.1``, ``temporal-g.2``)."""
    labels = list(dict.fromkeys(labels))
    out = {label: label for label in labels if len(label) <= limit}
    taken = set(out)
    groups: dict[str, list[str]] = defaultdict(list)
    for label in labels:
        if label not in out:
            groups[_shortened(label, limit)].append(label)
    for short, members in groups.items():
        if len(members) == 1 and short not in taken:
            out[members[0]] = short
            taken.add(short)
            continue
        number = 1
        for label in members:
            while f"{short}{number}" in taken:
                number += 1
            out[label] = f"{short}{number}"
            taken.add(out[label])
    return {label: out[label] for label in labels}


def _text_pt(text: str, char_pt: float = TEXT_CHAR_PT) -> float:
    """Estimated width of ``text``: ``char_pt`` a character, capitals 1.5 times that (cmr8 "M" is 7.3 pt)."""
    return sum(1.5 if ch.isupper() else 1.0 for ch in text) * char_pt


#: the layouts tried, in order, with the width each must fit: our cells on one line (``mean±h``) or
#: stacked (``±h`` under the mean, half as wide, twice as tall), in one column, then across both
PLACEMENTS = (("table", "inline", SINGLE_COLUMN_IN), ("table", "stacked", SINGLE_COLUMN_IN),
              ("table*", "inline", TEXT_WIDTH_IN), ("table*", "stacked", TEXT_WIDTH_IN))


def placement(widths_pt: dict[str, float]) -> tuple[str, str, bool]:
    """(environment, layout, fits) for a table of estimated width ``widths_pt[layout]``: the first of
    `PLACEMENTS` whose width it fits: ``table`` (one column, `SINGLE_COLUMN_IN`) with one-line cells,
    else with stacked cells, else ``table*`` (both columns, `TEXT_WIDTH_IN`) likewise; a table wider
    than that is ``table*`` with stacked cells and ``fits`` False."""
    for env, layout, limit_in in PLACEMENTS:
        if widths_pt[layout] <= limit_in * PT_PER_IN:
            return env, layout, True
    return "table*", "stacked", False


def _stacked(first: str, second: str) -> str:
    """Two lines in one cell, the first on the row's baseline (a nested tabular, no package needed)."""
    return rf"\begin{{tabular}}[t]{{@{{}}c@{{}}}}{first}\\{second}\end{{tabular}}"


class _LatexTable:
    """The LaTeX of one `ComparisonTable` (one instance per call of `comparison_latex`)."""

    def __init__(self, table: ComparisonTable):
        self.table, self.esc = table, latex_escape
        self.columns = short_labels(table.columns, SHORT_COLUMN_CHARS)
        self.rows = short_labels(table.rows + list(table.paper or {}), SHORT_ROW_CHARS)

    def cell(self, row: str, col: str) -> dict[str, tuple[str, float]]:
        """layout -> (LaTeX, estimated width in pt) of one of our cells: the mean (bold when it is the
        row's best) with its marks, and ``±`` the interval's half-width in \\scriptsize."""
        t = self.table
        if (row, col) not in t.mean:
            return dict.fromkeys(("inline", "stacked"), ("--", TEXT_CHAR_PT))
        bold, suffix = t.marks(row, col)
        mean = t._fmt(t.mean[(row, col)] * t.scale)
        first = (rf"\textbf{{{mean}}}" if bold else mean) + self.esc(suffix)
        first_pt = _text_pt(mean) + len(suffix) * SMALL_CHAR_PT
        low, high = t.interval(row, col)
        if math.isnan(low):
            return dict.fromkeys(("inline", "stacked"), (first, first_pt))
        half = t._fmt((high - low) / 2 * t.scale)
        second, second_pt = rf"{{\scriptsize$\pm${half}}}", _text_pt(half, SMALL_CHAR_PT) + 2 * SMALL_CHAR_PT  # ±: ~2 digits
        return {"inline": (first + second, first_pt + second_pt),
                "stacked": (_stacked(first, second), max(first_pt, second_pt))}

    def paper_cell(self, values: dict, col: str, best: str | None) -> tuple[str, float]:
        if col not in values:
            return "--", TEXT_CHAR_PT
        text = self.table._fmt(values[col])
        return (rf"\textbf{{{text}}}" if col == best else text), _text_pt(text)

    def grid(self) -> tuple[dict[str, list[list[tuple[str, float]]]], list[list[tuple[str, float]]]]:
        """(layout -> our rows, the paper's rows in italics): rows of (LaTeX, width) cells, the label first."""
        t, esc = self.table, self.esc
        ours: dict[str, list] = {"inline": [], "stacked": []}
        for row in t.rows:
            cells = [self.cell(row, c) for c in t.columns]
            for layout, rows in ours.items():
                rows.append([(esc(self.rows[row]), _text_pt(self.rows[row]))] + [cell[layout] for cell in cells])
        theirs = [[(rf"\textit{{{esc(self.rows[row])}}}", _text_pt(self.rows[row]))]
                  + [self.paper_cell(values, c, best) for c in t.columns] for row, values, best in t._paper_rows()]
        return ours, theirs

    def header(self) -> list[tuple[str, float]]:
        return [("Sequence", _text_pt("Sequence"))] + [(self.esc(self.columns[c]), _text_pt(self.columns[c]))
                                                       for c in self.table.columns]

    def key(self) -> str:
        """The full label of every shortened column and row ("Columns: temporal-g.: temporal-graph
        tuned (ours); ..."), escaped; "" when none was shortened."""
        parts = []
        for what, mapping in (("Columns", self.columns), ("Rows", self.rows)):
            pairs = [f"{self.esc(short)}: {self.esc(full)}" for full, short in mapping.items() if short != full]
            if pairs:
                parts.append(f"{what}: " + "; ".join(pairs) + ".")
        return " ".join(parts)

    def latex(self) -> str:
        t, esc = self.table, self.esc
        header = self.header()
        ours, theirs = self.grid()
        widths_pt = {layout: sum(max(cell[1] for cell in column) for column in zip(header, *rows, *theirs))
                     + 2 * TABCOLSEP_PT * len(header) for layout, rows in ours.items()}
        env, layout, fits = placement(widths_pt)
        width_in = widths_pt[layout] / PT_PER_IN
        out = [PREAMBLE_COMMENT, f"% {env}, {layout} cells: estimated width {width_in:.2f} in "
               f"(one column: {SINGLE_COLUMN_IN} in, both columns: {TEXT_WIDTH_IN} in)"]
        if not fits:
            out.append(f"% wider than the text of a two-column page ({TEXT_WIDTH_IN} in): rename the columns "
                       "shorter ([labels] in the experiment config), drop columns or split the table")
        out += [rf"\begin{{{env}}}[t]", r"\centering", rf"\caption{{{esc(t.title)}}}", r"\footnotesize",
                rf"\setlength{{\tabcolsep}}{{{TABCOLSEP_PT:g}pt}}",
                r"\begin{tabular}{l" + "c" * len(t.columns) + "}", r"\toprule",
                " & ".join(text for text, _ in header) + r" \\", r"\midrule"]
        out += [" & ".join(text for text, _ in row) + r" \\" for row in ours[layout]]
        if theirs:
            out.append(r"\midrule")
            out += [" & ".join(text for text, _ in row) + r" \\" for row in theirs]
        paragraph = [self.key(), esc(t.conventions(latex=True))] + [esc(n) for n in t.notes if n]
        out += [r"\bottomrule", r"\end{tabular}", "", r"\smallskip",
                r"{\footnotesize\sloppy " + " ".join(part for part in paragraph if part) + r"\par}", rf"\end{{{env}}}"]
        return "\n".join(out) + "\n"


def comparison_latex(table: ComparisonTable) -> str:
    """The table as a LaTeX float (see the module docstring); the first line names the package it
    needs (booktabs), the second the placement, layout and estimated width (`placement`)."""
    return _LatexTable(table).latex()
