"""The colour section of reports (`bench.reporting.colour_report`)."""

from __future__ import annotations

import pandas as pd

from dpcbench.bench.reporting.colour_report import colour_section, colour_sequences


def _tidy(rows):
    return pd.DataFrame([{"method_params": "{}", "peak": "", **r} for r in rows])


def test_colour_tables_for_coloured_sequences_only(tmp_path):
    rows = []
    for frame, (a, b) in enumerate([(30.0, 34.0), (32.0, 36.0)]):
        for metric, shift in (("cpsnr_y", 0.0), ("cpsnr_u", 5.0), ("cpsnr_v", 6.0)):
            rows += [{"sequence": "Human", "method": "none", "metric": metric, "scope": "holes", "frame": frame,
                      "value": a + shift},
                     {"sequence": "Human", "method": "temporal-copy", "metric": metric, "scope": "holes",
                      "frame": frame, "value": b + shift}]
        rows.append({"sequence": "Plain", "method": "none", "metric": "gpsnr_d1", "scope": "holes", "frame": frame,
                     "value": 20.0})
    df = _tidy(rows)
    assert colour_sequences(df) == (["Human"], ["Plain"])
    md = colour_section(df, tmp_path)
    assert "### cpsnr_y (holes)" in md and "### cpsnr_u (holes)" in md
    human = next(line for line in md.splitlines() if line.startswith("| Human") and "31.00" in line)
    # temporal-copy's mean Y over the two frames with its 95% interval; two pairs are too few for a claim: no bold
    assert "35.00 [22.29, 47.71]" in human and "**" not in human
    assert "No colour values for Plain" in md
    assert (tmp_path / "tables" / "cpsnr_y_holes.csv").is_file()


def test_no_colour_anywhere_says_so():
    df = _tidy([{"sequence": "Plain", "method": "none", "metric": "gpsnr_d1", "scope": "frame", "frame": 0,
                 "value": 20.0}])
    md = colour_section(df)
    assert "No colour PSNR stored" in md and "Plain" in md
