"""Issue 50's targets for the paper columns on real captured motion, judged with paired statistics.

The targets (docs/paper-reading.md, "The issue's targets"): on every row (a sequence and a damage) of a
real multi-frame capture, Proposed (`temporal-graph`, variant="paper") minus Hu (`fu-nonlocal`,
variant="paper") in whole-frame D1 (GPSNR, intrinsic peak) is at least ``TARGET_DB["independent"]``
(+1 dB) on independent holes and at least ``TARGET_DB["coherent"]`` (0 dB: never below) on coherent
holes. Beside it each row gives Hu and Proposed minus no fill (both must be above it) and Hu minus
Lozes (the paper's Hu > Lozes).

Each comparison pairs the two columns' values on the (frame, seed) pairs both have:
``d_i = x_a,i - x_b,i``; its mean, the bootstrap 95% interval that resamples whole damages (a seed with
all its frames) and the two-sided Wilcoxon signed-rank p of ``d`` (`bench.results.stats.paired`, the procedure of every table's marks). The
target's verdict tests ``d - t`` against 0 the same way (t the row's threshold): "reached" when the
interval lies at or above t and that p <= `stats.ALPHA`, "not reached" when the interval lies below
t and that p <= ALPHA, else "not decided at this n" (the mean says on which side it falls). One test a
row, no correction over rows: a row's verdict is a statement about that row only.

`target_rows` reads a `ComparisonTable` (REPORT.md of `reproduce-paper` judges its real-motion rows
with it); ``python -m dpcbench.bench.reporting.paper_targets STORE`` prints the table of the
`paper-targets` preset (`dpcbench run paper-targets --store STORE`).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dpcbench.bench.reporting.tables import damage_of
from dpcbench.bench.results import stats

#: Proposed - Hu (dB, whole-frame D1) each kind of hole must reach (issue 50)
TARGET_DB = {"independent": 1.0, "coherent": 0.0}
#: the column labels compared (bench.reporting.paper.TABLE_COLUMNS)
HU, PROPOSED, LOZES = "Hu", "Proposed", "Lozes"
REACHED, NOT_REACHED, UNDECIDED = "reached", "not reached", "not decided at this n"


def hole_kind(row: str) -> str:
    """"coherent" when the row's label names coherent holes, else "independent"."""
    return "coherent" if "coherent" in row.lower() else "independent"


@dataclass
class TargetRow:
    """One row's comparisons (`stats.PairedComparison`, None where a column is missing) and the verdict of
    Proposed - Hu against ``target`` (dB); ``p_target``: Wilcoxon p of (d - target)."""

    row: str
    target: float
    over_hu: stats.PairedComparison | None
    p_target: float
    verdict: str
    hu_floor: stats.PairedComparison | None
    proposed_floor: stats.PairedComparison | None
    hu_lozes: stats.PairedComparison | None


def _compare(table, row: str, a: str, b: str | None) -> stats.PairedComparison | None:
    if b is None or (row, a) not in table.observations or (row, b) not in table.observations:
        return None
    return stats.paired(table.observations[(row, a)], table.observations[(row, b)], True, f"{a} - {b}", damage_of)


def target_verdict(d, target: float, damages=None) -> tuple[str, float]:
    """(verdict, Wilcoxon p of d - target) of the paired differences ``d`` against ``target`` (module docstring);
    ``damages``: each difference's damage (hole seed), whole damages resampled for the interval."""
    d = np.asarray(d, dtype=float)
    if len(d) < 2:
        return UNDECIDED, math.nan
    shifted = d - target
    low, high = stats.mean_difference_interval(shifted, groups=damages)
    p = stats.signed_rank_p(shifted)
    if low >= 0 and p <= stats.ALPHA:
        return REACHED, p
    if high < 0 and p <= stats.ALPHA:
        return NOT_REACHED, p
    return UNDECIDED, p


def target_rows(table, rows: list[str] | None = None) -> list[TargetRow]:
    """The targets of ``rows`` (default: every row of ``table``, a whole-frame D1 `ComparisonTable` with
    columns Hu and Proposed) that have both columns."""
    out = []
    for row in rows if rows is not None else table.rows:
        over = _compare(table, row, PROPOSED, HU)
        if over is None:
            continue
        target = TARGET_DB[hole_kind(row)]
        a, b = table.observations[(row, PROPOSED)], table.observations[(row, HU)]
        keys = sorted(k for k in set(a) & set(b) if math.isfinite(a[k]) and math.isfinite(b[k]))
        verdict, p = target_verdict([a[k] - b[k] for k in keys], target, [damage_of(k) for k in keys])
        out.append(TargetRow(row, target, over, p, verdict, _compare(table, row, HU, table.floor),
                             _compare(table, row, PROPOSED, table.floor), _compare(table, row, HU, LOZES)))
    return out


def _cell(c: stats.PairedComparison | None) -> str:
    if c is None:
        return "–"
    if math.isnan(c.low):
        return f"{c.mean_difference:+.2f}"
    return f"{c.mean_difference:+.2f} [{c.low:+.2f}, {c.high:+.2f}]"


def targets_markdown(records: list[TargetRow]) -> str:
    """The targets as a Markdown table: per row n, Proposed - Hu with its interval against the target
    (verdict, by how much the mean misses or clears it, Wilcoxon p of d - target), and Hu / Proposed -
    no fill, Hu - Lozes (dB, mean [95% interval])."""
    lines = ["| row | n | Proposed - Hu | target | verdict (p) | mean - target | Hu - no fill | Proposed - no fill "
             "| Hu - Lozes |", "|---|---:|---|---:|---|---:|---|---|---|"]
    for r in records:
        assert r.over_hu is not None
        p = "" if math.isnan(r.p_target) else f" (p = {r.p_target:.2g})"
        lines.append(f"| {r.row} | {r.over_hu.n} | {_cell(r.over_hu)} | {r.target:+.0f} | {r.verdict}{p} | "
                     f"{r.over_hu.mean_difference - r.target:+.2f} | {_cell(r.hu_floor)} | "
                     f"{_cell(r.proposed_floor)} | {_cell(r.hu_lozes)} |")
    return "\n".join(lines) + "\n"


def store_table(store_path, experiment: str):
    """The whole-frame D1 (intrinsic peak) `ComparisonTable` of ``experiment`` in the results store at
    ``store_path``, rows = sequence · holes, columns as `reproduce-paper` labels them."""
    from dpcbench.bench.reporting.paper import paper_column
    from dpcbench.bench.reporting.tables import comparison_table, hole_rows
    from dpcbench.bench.results.compare import with_cells
    from dpcbench.bench.results.store import ResultsStore

    store = ResultsStore(store_path)
    results, runs = store.results_frame(experiment), store.runs_frame(experiment)
    if results.empty:
        from dpcbench.bench.core.errors import UserError

        raise UserError(f"{store_path}: no finished run of experiment {experiment!r}; run "
                        f"`dpcbench run {experiment} --store {store_path}` first")
    df = hole_rows(with_cells(results, runs), runs)
    return comparison_table(df, "gpsnr_d1", "frame", "intrinsic", column_of=paper_column)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dpcbench.bench.reporting.paper_targets",
                                     description="issue 50's targets (Proposed vs Hu, paper configuration) "
                                                 "with paired statistics, from a results store")
    parser.add_argument("store", type=Path, help="results store holding the experiment's runs")
    parser.add_argument("--experiment", default="paper-targets")
    parser.add_argument("--out", type=Path, help="write the Markdown table here too")
    args = parser.parse_args(argv)
    table = store_table(args.store, args.experiment)
    text = targets_markdown(target_rows(table, sorted(table.rows)))  # by sequence, then kind and size of holes
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
