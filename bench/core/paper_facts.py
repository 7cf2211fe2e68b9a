"""The paper's facts, in one place: its sequences, its method columns and its published Tables 1-2.

Source: Fu, Hu, Guo, "3D Dynamic Point Cloud Inpainting via Temporal Consistency on Graphs", ICME
2020 (/work/shared/paper, copied in /work/shared/SPEC.md section 1). Tables 1 (GPSNR, dB, higher is
better) and 2 (NSHD, x1e-7, lower is better) are averaged over the frames of each sequence with
synthetic holes. Everything else (`bench.reporting.paper`'s protocol, `bench.experiment.config`, `bench.data.datasets`, the
dashboard, the reports) reads these names; none keeps a copy. This module imports nothing, so any
module of `bench` can read it without an import cycle.
"""

from __future__ import annotations

#: the paper, as cited in captions
CITATION = ('Fu, Hu, Guo, "3D Dynamic Point Cloud Inpainting via Temporal Consistency on Graphs", '
            "IEEE ICME 2020")

#: Hu et al. as the paper cites it: "Hu et al." with the key [Fu18TIP], an IEEE Transactions on Image
#: Processing article. The paper's bibliography file (ref.bib) is not in /work/shared/paper, so the
#: key is the only bibliographic fact the paper gives; every mention in dpcbench uses this form.
HU_ET_AL = "Hu et al. [Fu18TIP] (IEEE TIP)"

#: the paper's sequences: dataset name (bench.data.datasets.PAPER) -> the paper's row label, in its order
PAPER_SEQUENCES: dict[str, str] = {"longdress": "Longdress", "loot": "Loot", "redandblack": "Redandblack",
                                   "soldier": "Soldier", "ulliwegner": "UlliWegner"}

#: the paper's method columns, in its order (Tables 1-2). "Hu" is Hu et al. [Fu18TIP], the static
#: non-local graph method the paper extends (run frame by frame); `HU_ET_AL` is how dpcbench cites it.
PAPER_COLUMNS: tuple[str, ...] = ("Meshlab", "Lozes", "Hu", "Proposed")

#: Table 1: GPSNR (dB) per row label, values in `PAPER_COLUMNS` order
TABLE1_GPSNR: dict[str, tuple[float, float, float, float]] = {
    "Longdress": (11.7926, 30.3883, 41.5686, 43.1301),
    "Loot": (16.4451, 27.3715, 40.1546, 47.5648),
    "Redandblack": (13.1772, 24.4810, 33.9921, 39.0103),
    "Soldier": (17.4697, 23.1571, 34.5062, 42.2980),
    "UlliWegner": (24.9424, 31.5455, 41.3037, 45.8411),
}

#: Table 2: NSHD in units of 1e-7 as printed, per row label, values in `PAPER_COLUMNS` order
TABLE2_NSHD_E7: dict[str, tuple[float, float, float, float]] = {
    "Longdress": (24.8631, 7.1362, 2.9174, 0.9131),
    "Loot": (14.1925, 8.9410, 3.1102, 0.3549),
    "Redandblack": (22.8300, 9.6233, 5.9856, 1.9324),
    "Soldier": (17.1376, 10.0044, 5.2145, 1.2057),
    "UlliWegner": (11.2509, 6.7370, 1.9658, 0.6362),
}
#: the scale of Table 2's printed values
NSHD_SCALE = 1e-7

#: the paper's headline (its text): average GPSNR gain of Proposed over each method (dB)
HEADLINE_GAIN_DB = {"Meshlab": 26.80, "Lozes": 16.18, "Hu": 5.26}

#: the claims of the paper's text (section 4, "Objective results") that `reproduce-paper` judges, in its words:
#: "our scheme outperforms all the competing methods in GPSNR and NSHD significantly. Specifically, in Table 1 we
#: achieve 26.80 dB gain in GPSNR on average over Meshlab, 16.18 dB over [Lozes15] and 5.26 dB over [Fu18TIP]. In
#: Table 2, we produce much lower NSHD than the other methods, at least three times lower compared to the next best
#: method [Fu18TIP]."
#: the ranking of Tables 1-2 on every sequence, best first
CLAIMED_RANKING: tuple[str, ...] = ("Proposed", "Hu", "Lozes", "Meshlab")
#: NSHD of Hu over NSHD of Proposed, at least (Table 2: 3.09 on UlliWegner to 8.76 on Loot)
CLAIMED_NSHD_FACTOR_OVER_HU = 3.0
CLAIMS: dict[str, str] = {
    "ranking": "Proposed > Hu > Lozes > Meshlab in GPSNR and in NSHD on every sequence (\"outperforms all the "
               "competing methods in GPSNR and NSHD significantly\")",
    "gains": "mean GPSNR gain of Proposed: +26.80 dB over Meshlab, +16.18 dB over Lozes, +5.26 dB over Hu",
    "nshd": "NSHD at least 3x lower than Hu, the next best method",
}
