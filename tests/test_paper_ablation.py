"""The ablation of the paper configuration (issue 50): `bench.reporting.paper_ablation` and its preset."""

from __future__ import annotations

import numpy as np
import pandas as pd

from dpcbench.bench.experiment.config import tomllib
from dpcbench.bench.reporting.paper import PRESETS_DIR
from dpcbench.bench.reporting.paper_ablation import ROWS, TEMPORAL_ONLY, ablation_markdown, diagnostics, method_params
from dpcbench.methods.temporal_graph import VARIANTS


def test_the_preset_lists_every_row_for_both_methods_against_no_fill():
    preset = tomllib.loads((PRESETS_DIR / "paper-ablation.toml").read_text())
    listed = [(m["name"], m.get("params", {}), m.get("label")) for m in preset["methods"]]
    assert ("none", {}, "none") in listed
    expected = [(method, method_params(row), f"{row} | {method}") for method in ("fu-nonlocal", "temporal-graph")
                for row in ROWS if not (method == "fu-nonlocal" and TEMPORAL_ONLY & set(ROWS[row]))]
    assert [x for x in listed if x[0] in ("fu-nonlocal", "temporal-graph")] == expected
    # every switch a row sets is a switch of the variants, with a value the paper configuration does not have
    for row, flips in ROWS.items():
        for name, value in flips.items():
            assert name == "variant" or name in VARIANTS["paper"], row
            if name != "variant" and len(flips) == 1:
                assert VARIANTS["paper"][name] != value, f"{row} repeats the paper configuration"


def test_diagnostics_count_moved_off_grid_and_unfilled_points():
    damaged = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    output = np.array([[0.0, 0, 0], [1, 0.5, 0], [2, 0, 0], [5, 0, 0]])
    truth = np.array([[5.0, 0, 0], [9, 0, 0]])
    d = diagnostics(damaged, output, truth, spacing=1.0)
    assert d == {"moved": 1, "off_grid": 1, "unfilled": 0.5}
    # unvoxelized input: off-grid is not counted
    assert diagnostics(damaged + 0.1, output + 0.1, truth, 1.0)["off_grid"] == 0


def test_the_section_gives_each_row_against_no_fill():
    frame = pd.DataFrame([
        {"sequence": "S", "holes": "h", "row": "none", "method": "none", "d1": 10.0},
        {"sequence": "S", "holes": "h", "row": "paper", "method": "fu-nonlocal", "d1": 12.5, "moved": 0.0,
         "off_grid": 0.0, "unfilled": 0.25},
        {"sequence": "S", "holes": "h", "row": "literal", "method": "fu-nonlocal", "d1": 7.0},
    ])
    text = ablation_markdown(frame)
    assert "### S, h (no fill: 10.00 dB)" in text
    assert "| paper | fu-nonlocal | 12.50 | +2.50 | 0 | 0 | 0.250 |" in text
    assert "| literal | fu-nonlocal | 7.00 | -3.00 |  |  |  |" in text
    assert "No ablation runs" in ablation_markdown(frame.iloc[0:0])


def test_the_calibration_table_gives_the_rms_distance_to_the_papers_longdress_values():
    from dpcbench.bench.reporting.paper_ablation import PAPER_LONGDRESS, calibration_markdown

    rows = []
    for seed, shift in ((0, 1.0), (1, -1.0)):  # mean over the seeds: Lozes 2 dB above the paper, Meshlab 2 below
        for method, d1 in (("none", 20.0), ("lozes-pde", PAPER_LONGDRESS["lozes-pde"] + 2 + shift),
                           ("meshlab", PAPER_LONGDRESS["meshlab"] - 2 + shift)):
            rows.append({"count": 3, "radius_spacings": 10.0, "seed": seed, "method": method, "d1": d1,
                         "removed": 0.01})
    text = calibration_markdown(pd.DataFrame(rows))
    assert "| 3 x 10 | 1.00% | 20.00 | 32.39 | 9.79 | 2.00 |" in text


def test_store_results_are_mapped_to_their_rows():
    import json

    from dpcbench.bench.reporting.paper_ablation import ablation_frame, row_of
    from dpcbench.methods.registry import get_method

    assert row_of("none", {}) == "none" and row_of("lozes-pde", {}) == "lozes"
    assert row_of("fu-nonlocal", {"variant": "paper"}) == "paper"
    resolved = get_method("temporal-graph", variant="paper", known_points="free").get_params()
    assert row_of("temporal-graph", resolved) == "known_points=free"
    assert row_of("temporal-graph", {"variant": "paper", "beta": 0.1}) is None
    assert row_of("meshlab", {}) is None
    tidy = pd.DataFrame([
        {"sequence": "S", "holes": "h", "method": "none", "method_params": "{}", "metric": "gpsnr_d1",
         "scope": "frame", "peak": "intrinsic", "value": v} for v in (10.0, 12.0)] + [
        {"sequence": "S", "holes": "h", "method": "fu-nonlocal", "method_params": json.dumps({"variant": "paper"}),
         "metric": m, "scope": sc, "peak": "intrinsic", "value": 20.0} for m, sc in
        (("gpsnr_d1", "frame"), ("gpsnr_d1", "holes"), ("nshd", "frame"))])
    frame = ablation_frame(tidy)
    assert frame.to_dict("records") == [
        {"sequence": "S", "holes": "h", "row": "none", "method": "none", "d1": 11.0},
        {"sequence": "S", "holes": "h", "row": "paper", "method": "fu-nonlocal", "d1": 20.0}]
