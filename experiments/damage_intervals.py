"""Each margin's 95 % interval two ways: resampling single (seed, frame) pairs, and resampling whole damages (a seed
with all its frames, then its frames; `bench.results.stats.mean_difference_interval` with groups), the way every
margin and table of the harness computes it.

    dpcbench run experiments/dfaust-coherent-seeds.toml --store S      # 30 runs, about 13 minutes on 2 cores
    .venv/bin/python experiments/damage_intervals.py S --method temporal-fusion [--experiments NAME ...]

Prints one line per row and target (`bench.reporting.margins.TARGETS` and `COLOUR_TARGETS`, where scored): the method it is measured against, n pairs,
the number of damages, the mean of d and both intervals, and the verdict each interval gives with the same Wilcoxon
signed-rank test of d minus the threshold (`bench.reporting.margins`). Where the frames of a damage agree with each
other more than the damages do, the pairs' interval is the narrower, and a verdict "beyond noise" may rest on it alone.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from dpcbench.bench.reporting import margins as margins_module
from dpcbench.bench.results import stats
from dpcbench.bench.results.store import ResultsStore


def _verdict(mean: float, low: float, high: float, p: float, threshold: float) -> str:
    met = "met" if mean >= threshold else "missed"
    beyond = p <= stats.ALPHA and (low > threshold if met == "met" else high < threshold)
    return met if beyond else f"{met}, within noise"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("store", help="results store (SQLite file)")
    parser.add_argument("--method", default="temporal-fusion")
    parser.add_argument("--experiments", nargs="+", default=None, metavar="NAME")
    args = parser.parse_args(argv)

    store = ResultsStore(args.store)
    runs = store.runs_frame()
    obs, _, notes = margins_module.store_observations(store.results_frame(), runs[runs["status"] == "done"],
                                                      args.experiments)
    for note in notes:
        print(f"note: {note}")
    for (experiment, _), block in obs.groupby(["experiment", "row"], sort=False):
        label = str(block["row_label"].iloc[0])
        for target in margins_module.TARGETS + margins_module.COLOUR_TARGETS:
            sub = block[(block["metric"] == target.metric) & (block["scope"] == target.scope)
                        & (block["peak"] == target.peak)]
            pairs = margins_module._pairs(sub)
            margin = margins_module.margin(pairs, args.method, target)
            if margin.against is None or margin.n < 2 or args.method not in pairs:
                continue
            sign = 1.0 if target.higher_is_better else -1.0
            keys = sorted(set(pairs[args.method]) & set(pairs[margin.against]))
            d = np.array([sign * (pairs[args.method][k] - pairs[margin.against][k]) for k in keys])
            seeds = [seed for seed, _ in keys]
            by_pairs = stats.mean_difference_interval(d)
            by_damages = stats.mean_difference_interval(d, groups=seeds)
            p = stats.signed_rank_p(d - target.threshold)
            mean = float(d.mean())
            print(f"{experiment} · {label} · {target.key} vs {margin.against}: n {len(d)}, {len(set(seeds))} damages, "
                  f"mean {mean:+.3g}; pairs [{by_pairs[0]:+.3g}, {by_pairs[1]:+.3g}] "
                  f"({_verdict(mean, *by_pairs, p, target.threshold)}); damages [{by_damages[0]:+.3g}, "
                  f"{by_damages[1]:+.3g}] ({_verdict(mean, *by_damages, p, target.threshold)})"
                  + ("" if math.isfinite(p) else "; no test"))


if __name__ == "__main__":
    main()
