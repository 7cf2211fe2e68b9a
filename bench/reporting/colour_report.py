"""The colour section of a report: colour PSNR tables for the sequences whose runs scored colour.

`colour_section(df, out_dir)` reads the store's tidy table (`bench.results.store.ResultsStore.results_frame`,
methods and rows already labelled as the report labels them) and returns Markdown: for each scope
present, one table per colour metric (cpsnr_y, cpsnr_u, cpsnr_v by default: pc_error's BT.709
Y'CbCr PSNRs, `metrics.colour`), rows = sequences, columns = methods, cells = mean ± std over frames
(`bench.reporting.tables.comparison_table`), and a line naming the sequences that have no colour values (their
frames carry no colours, or the experiment did not ask for colour metrics). The tables are also
written as .md / .tex / .csv under ``out_dir/tables`` when ``out_dir`` is given.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from dpcbench.bench.reporting.tables import comparison_table, write_table

#: the colour metrics a report shows, in this order
REPORT_COLOUR_METRICS = ("cpsnr_y", "cpsnr_u", "cpsnr_v", "cpsnr_rgb")


def colour_sequences(df: pd.DataFrame) -> tuple[list[str], list[str]]:
    """(sequences with colour values, sequences without), each in first-seen order."""
    sequences = list(dict.fromkeys(df["sequence"]))
    coloured = set(df.loc[df["metric"].isin(REPORT_COLOUR_METRICS) & (df["frame"] >= 0), "sequence"])
    return [s for s in sequences if s in coloured], [s for s in sequences if s not in coloured]


def colour_section(df: pd.DataFrame, out_dir: str | Path | None = None, *, heading: str = "## Colour PSNR",
                   column_of=None, columns: list[str] | None = None, notes: list[str] | None = None) -> str:
    """Markdown of the colour tables (see the module docstring); an explanatory line when no sequence
    has colour values. ``column_of``, ``columns`` and ``notes`` go to `comparison_table` (a report with its own
    columns, `reproduce-paper`'s, passes them)."""
    with_colour, without = colour_sequences(df)
    lines = [heading, ""]
    if not with_colour:
        lines += ["_No colour PSNR stored: " + (
            "none of the sequences " + ", ".join(without) + " has colour values" if without else "no sequence"
        ) + " (their frames carry no colours, or the experiment's metrics name no cpsnr_*)._", ""]
        return "\n".join(lines)
    lines += ["pc_error 0.14 `--color=1`: 10 log10(p^2 / max(MSE A->B, MSE B->A)) per channel, each point "
              "compared with the colour of its nearest point(s) in the other cloud; Y'CbCr BT.709 with p = 1 "
              "(`cpsnr_y/u/v`), RGB with p = 255 (`cpsnr_rgb`: the mean of the three channels' MSEs).", ""]
    scopes = [s for s in ("frame", "holes") if s in set(df["scope"])]
    for scope in scopes:
        for metric in REPORT_COLOUR_METRICS:
            table = comparison_table(df, metric, scope, "", title=f"{metric}, scope {scope}", decimals=2,
                                     column_of=column_of, columns=columns, notes=notes)
            if not table.rows:
                continue
            if out_dir is not None:

                write_table(table, Path(out_dir) / "tables", f"{metric}_{scope}")
            lines += [f"### {metric} ({scope})", "", table.markdown(), ""]
    if without:
        lines += [f"_No colour values for {', '.join(without)}: their frames carry no colours (or the runs did "
                  "not score colour)._", ""]
    return "\n".join(lines)


__all__ = ["REPORT_COLOUR_METRICS", "colour_section", "colour_sequences"]
