"""The paper's experiment: its methods, sequences, published Tables 1-2, and the metric conventions
`reproduce-paper` uses to print ours beside them.

Source: Fu, Hu, Guo, "3D Dynamic Point Cloud Inpainting via Temporal Consistency on Graphs", ICME 2020,
Tables 1 (GPSNR, dB, higher is better) and 2 (NSHD, x1e-7, lower is better), averaged over the frames
of each sequence with synthetic holes (copied from /work/shared/SPEC.md section 1).
"""

from __future__ import annotations

#: (registry name, column label in the paper, parameters) in the paper's column order
PAPER_METHODS: list[tuple[str, str, dict]] = [
    ("meshlab", "Meshlab", {"output": "whole"}),
    ("lozes-pde", "Lozes", {}),
    ("fu-nonlocal", "Hu", {}),
    ("temporal-graph", "Proposed", {}),
]
METHOD_LABELS = {name: label for name, label, _ in PAPER_METHODS}
COLUMNS = [label for _, label, _ in PAPER_METHODS]

#: dataset names (bench.datasets) -> the paper's row label
PAPER_SEQUENCES = {"longdress": "Longdress", "loot": "Loot", "redandblack": "Redandblack",
                   "soldier": "Soldier", "ulliwegner": "UlliWegner"}

#: embedded stand-ins used when the paper's data is not given -> row label (always says stand-in)
STANDINS = {"human": "Human (stand-in)", "bunny": "Bunny (stand-in)"}

TABLE1_GPSNR: dict[str, tuple[float, float, float, float]] = {
    "Longdress": (11.7926, 30.3883, 41.5686, 43.1301),
    "Loot": (16.4451, 27.3715, 40.1546, 47.5648),
    "Redandblack": (13.1772, 24.4810, 33.9921, 39.0103),
    "Soldier": (17.4697, 23.1571, 34.5062, 42.2980),
    "UlliWegner": (24.9424, 31.5455, 41.3037, 45.8411),
}

#: NSHD in units of 1e-7 as printed
TABLE2_NSHD_E7: dict[str, tuple[float, float, float, float]] = {
    "Longdress": (24.8631, 7.1362, 2.9174, 0.9131),
    "Loot": (14.1925, 8.9410, 3.1102, 0.3549),
    "Redandblack": (22.8300, 9.6233, 5.9856, 1.9324),
    "Soldier": (17.1376, 10.0044, 5.2145, 1.2057),
    "UlliWegner": (11.2509, 6.7370, 1.9658, 0.6362),
}

#: the paper's headline: average GPSNR gain of Proposed over each method (dB)
HEADLINE_GAIN_DB = {"Meshlab": 26.80, "Lozes": 16.18, "Hu": 5.26}


def paper_table(metric: str) -> dict[str, dict[str, float]]:
    """row label -> {column label: paper value} for "gpsnr" (dB) or "nshd" (x1e-7)."""
    source = TABLE1_GPSNR if metric.startswith("gpsnr") else TABLE2_NSHD_E7
    return {row: dict(zip(COLUMNS, values)) for row, values in source.items()}


def paper_mean_gains() -> dict[str, float]:
    """Average over the five sequences of Proposed minus each method, from Table 1 (dB).

    Recomputed from the table: Meshlab 26.80, Lozes 16.18, Hu 5.26 (the paper's text)."""
    rows = list(TABLE1_GPSNR.values())
    proposed = [r[3] for r in rows]
    return {col: sum(p - r[i] for p, r in zip(proposed, rows)) / len(rows) for i, col in enumerate(COLUMNS[:3])}
