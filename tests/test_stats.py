"""bench.results.stats against hand-computed and brute-force cases."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from dpcbench.bench.results import stats


def exact_signed_rank_p(d) -> float:
    """Two-sided exact signed-rank p by enumerating every sign pattern (no ties, no zeros)."""
    d = np.asarray(d, dtype=float)
    ranks = np.argsort(np.argsort(np.abs(d))) + 1
    w_plus = ranks[d > 0].sum()
    n = len(d)
    sums = [sum(r for r, s in zip(range(1, n + 1), signs) if s) for signs in itertools.product((0, 1), repeat=n)]
    mean = n * (n + 1) / 4
    extreme = [s for s in sums if abs(s - mean) >= abs(w_plus - mean) - 1e-12]
    return len(extreme) / len(sums)


def test_min_pairs_is_where_the_smallest_p_passes():
    # 2/2^5 = 0.0625 > 0.05, 2/2^6 = 0.03125: one comparison needs 6 pairs
    assert stats.min_pairs(1) == 6
    # seven comparisons (eight columns): 7 * 2/2^8 = 0.0547 > 0.05, 7 * 2/2^9 = 0.0273
    assert stats.min_pairs(7) == 9
    # the formula is the test's real floor: all-positive differences give exactly 2/2^n
    for n in (5, 6, 9):
        assert stats.signed_rank_p(np.arange(1, n + 1)) == pytest.approx(2 / 2 ** n)


def test_signed_rank_p_matches_enumeration():
    for d in ([1, -2, 3, 4, 5, 6], [-1, 2, -3, 4, 5, 6, 7], [0.5, -1.5, 2.5, -3.5, 4.5]):
        assert stats.signed_rank_p(d) == pytest.approx(exact_signed_rank_p(d))
    assert stats.signed_rank_p([0, 0, 0]) == 1.0


def test_holm_by_hand():
    # sorted 0.01, 0.03, 0.04 -> 3*0.01 = 0.03, max(0.03, 2*0.03) = 0.06, max(0.06, 1*0.04) = 0.06
    assert stats.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert stats.holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_bootstrap_interval_matches_the_exact_bootstrap_distribution():
    d = np.array([0.0, 1.0, 2.0, 6.0])
    # every resample of 4 from 4 is equally likely: 256 means, multiples of 1/4
    means = np.sort([np.mean(t) for t in itertools.product(d, repeat=4)])
    lo, hi = np.quantile(means, 0.025), np.quantile(means, 0.975)
    got = stats.mean_difference_interval(d)
    assert got[0] == pytest.approx(lo, abs=0.25) and got[1] == pytest.approx(hi, abs=0.25)
    assert got == stats.mean_difference_interval(d)  # seeded: the same interval every time
    assert stats.mean_difference_interval([2.0, 2.0, 2.0]) == (2.0, 2.0)
    assert all(math.isnan(x) for x in stats.mean_difference_interval([1.0]))



# -- whole damages resampled (a seed with all its frames) --------------------------------------------------------
def test_damages_whose_frames_agree_give_the_interval_from_the_lowest_damage_to_the_highest():
    # 3 damages x 4 frames, each damage's d the same in all its frames: a damage drawn three times has
    # probability 1/27 > 2.5 %, so the interval's ends are the lowest and the highest damage's means, exactly
    d = np.repeat([1.0, 2.0, 4.0], 4)
    seeds = np.repeat([7, 8, 9], 4)
    assert stats.mean_difference_interval(d, groups=seeds) == (1.0, 4.0)
    assert stats.mean_difference_interval(d, groups=seeds) == stats.mean_difference_interval(d, groups=seeds)
    # the pairs' interval reads the 12 frames as 12 damages: narrower, inside (1, 4)
    low, high = stats.mean_difference_interval(d)
    assert 1.0 < low < high < 4.0 and high - low < 2.0
    # one damage, or one value a damage: nothing to resample but the pairs
    assert stats.mean_difference_interval(d, groups=[0] * 12) == stats.mean_difference_interval(d)
    assert stats.mean_difference_interval(d, groups=range(12)) == stats.mean_difference_interval(d)
    with pytest.raises(ValueError, match="labels"):
        stats.mean_difference_interval(d, groups=[0, 1])


def test_two_stage_bootstrap_has_the_closed_form_variance():
    # G clusters of m values each: a replicate is the mean of G cluster means, each of m values drawn from a
    # cluster drawn at random, so Var = (between + within / m) / G with between = mean_c (mean_c - mean)^2 and
    # within = mean_c of each cluster's population variance
    rng = np.random.default_rng(3)
    m, clusters = 5, 4
    values = rng.normal(0.0, 1.0, (clusters, m)) + np.array([[0.0], [3.0], [-1.0], [5.0]])
    which = np.repeat(np.arange(clusters), m)
    reps = stats.cluster_bootstrap([values.ravel()], which, 40000, 0, lambda sums, counts: sums[0] / counts)
    cluster_means = values.mean(axis=1)
    between = np.mean((cluster_means - cluster_means.mean()) ** 2)
    within = np.mean(values.var(axis=1))
    assert np.var(reps) == pytest.approx((between + within / m) / clusters, rel=0.03)
    assert np.mean(reps) == pytest.approx(values.mean(), abs=0.03)
    # the pairs stay paired: a ratio of two sums over the same draws of proportional values is the factor
    ratios = stats.cluster_bootstrap([2.0 * values.ravel() + 40, values.ravel() + 20], which, 1000, 0,
                                           lambda sums, counts: sums[0] / sums[1])
    assert ratios == pytest.approx(np.full(1000, 2.0))


def test_a_winner_on_some_damages_only_is_not_bold():
    # 3 damages x 10 frames: the first method wins by 3 on two damages and loses by 1 on the third. Read as 30
    # independent pairs it is best beyond noise; over whole damages its margin's interval holds 0
    rng = np.random.default_rng(1)
    gain = {0: 3.0, 1: 3.0, 2: -1.0}
    base = {(f, s): 30.0 + rng.normal(0, 1) for s in gain for f in range(10)}
    a = {k: v + gain[k[1]] + rng.normal(0, 0.1) for k, v in base.items()}
    pairs = stats.row_verdict({"a": a, "b": base}, higher_is_better=True)
    damages = stats.row_verdict({"a": a, "b": base}, higher_is_better=True, damage=lambda key: key[1])
    assert pairs.bold == "a" and pairs.comparisons["b"].low > 0
    assert damages.bold is None and damages.verdicts == {"a": stats.TIED, "b": stats.TIED}
    assert damages.comparisons["b"].low < 0 < damages.comparisons["b"].high
    assert damages.comparisons["b"].p_value == pairs.comparisons["b"].p_value  # the same signed-rank test
    ratio, low, high = stats.ratio_interval(a, base, damage=lambda key: key[1])
    assert low < 1.0 < ratio < high

def test_mean_interval_is_students_t():
    lo, hi = stats.mean_interval([1.0, 2.0, 3.0])
    half = 4.302652729911275 / math.sqrt(3)  # t(0.975, 2) * s / sqrt(n), s = 1
    assert (lo, hi) == pytest.approx((2 - half, 2 + half))


def test_mean_interval_over_damages_is_the_t_interval_of_their_means():
    # three damages of four frames each: the frames' spread inside a damage is not the damage's noise
    frames = np.array([-1.5, -0.5, 0.5, 1.5])
    damage_means = np.array([20.0, 21.0, 23.0])
    values = np.concatenate([m + frames for m in damage_means])
    seeds = np.repeat([0, 1, 2], 4)
    half = 4.302652729911275 * damage_means.std(ddof=1) / math.sqrt(3)  # t(0.975, 2) * sd of the means / sqrt(G)
    assert stats.mean_interval(values, groups=seeds) == pytest.approx((damage_means.mean() - half,
                                                                      damage_means.mean() + half))
    ungrouped = stats.mean_interval(values)
    assert ungrouped[1] - ungrouped[0] < 2 * half  # twelve values read as twelve damages: too narrow
    # unequal damages: the cluster-robust form, by hand, over the finite values only
    values = np.array([1.0, 2.0, 4.0, 7.0, 8.0, np.nan])
    seeds = [0, 0, 0, 1, 1, 2]
    m = 22 / 5
    se = math.sqrt(2 / 1 * ((1 + 2 + 4 - 3 * m) ** 2 + (7 + 8 - 2 * m) ** 2)) / 5
    assert stats.mean_interval(values, groups=seeds) == pytest.approx((m - 12.706204736174707 * se,
                                                                      m + 12.706204736174707 * se))
    # one value a damage, or one damage: the ungrouped interval
    assert stats.mean_interval([1.0, 2.0, 3.0], groups=[5, 6, 7]) == pytest.approx(stats.mean_interval([1.0, 2.0, 3.0]))
    assert stats.mean_interval([1.0, 2.0, 3.0], groups=[5, 5, 5]) == pytest.approx(stats.mean_interval([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="labels"):
        stats.mean_interval([1.0, 2.0], groups=[0])


def _rows(values: dict[str, list[float]]) -> dict:
    return {m: {(f, 0): v for f, v in enumerate(vals)} for m, vals in values.items()}


def test_clear_winner_is_best_and_the_others_worse():
    rng = np.random.default_rng(1)
    base = rng.normal(20, 1, 9)
    obs = _rows({"a": list(base + 3 + rng.uniform(0, 0.5, 9)), "b": list(base), "c": list(base - 1)})
    v = stats.row_verdict(obs, higher_is_better=True)
    assert v.best == "a" and v.bold == "a"
    assert v.verdicts == {"a": stats.BEST, "b": stats.WORSE, "c": stats.WORSE}
    assert v.comparisons["b"].low > 0 and v.comparisons["b"].p_holm == pytest.approx(2 * 2 / 2 ** 9)


def test_tie_is_marked_for_both_and_nobody_is_bold():
    base = list(np.linspace(10, 12, 9))
    v = stats.row_verdict(_rows({"a": base, "b": base, "c": [x - 5 for x in base]}), higher_is_better=True)
    assert v.bold is None
    assert v.verdicts["a"] == v.verdicts["b"] == stats.TIED and v.verdicts["c"] == stats.WORSE


def test_noise_is_a_tie():
    # differences of both signs: the interval holds 0
    a = [10, 11, 9, 10.5, 9.5, 10, 11, 9, 10.2]
    b = [10.1, 10.8, 9.3, 10.2, 9.9, 9.8, 11.1, 8.7, 10.0]
    v = stats.row_verdict(_rows({"a": a, "b": b}), higher_is_better=True)
    assert v.verdicts == {"a": stats.TIED, "b": stats.TIED}


def test_lower_is_better():
    a = [1.0, 1.1, 0.9, 1.0, 1.2, 0.8, 1.0, 1.05]
    v = stats.row_verdict(_rows({"a": a, "b": [x + 1 for x in a]}), higher_is_better=False)
    assert v.best == "a" and v.bold == "a" and v.verdicts["b"] == stats.WORSE


def test_n_too_small_makes_no_claim():
    v = stats.row_verdict(_rows({"a": [30.0, 31.0, 32.0], "b": [1.0, 2.0, 3.0]}), higher_is_better=True)
    assert v.too_small and v.needed == 6 and v.n == 3
    assert v.bold is None and set(v.verdicts.values()) == {stats.NO_CLAIM}
    assert "n >= 6" in stats.too_small_text(3, 1)


def test_pairs_are_matched_by_key_not_position():
    # b misses pair 0; the comparison uses the 6 shared pairs only
    a = {(f, 0): 10.0 + f for f in range(7)}
    b = {(f, 0): 9.0 + f for f in range(1, 7)}
    v = stats.row_verdict({"a": a, "b": b}, higher_is_better=True)
    assert v.comparisons["b"].n == 6 and v.comparisons["b"].mean_difference == pytest.approx(1.0)


def test_no_direction_no_verdict():
    v = stats.row_verdict(_rows({"a": [1.0, 2.0], "b": [3.0, 4.0]}), higher_is_better=None)
    assert v.best is None and v.verdicts == {}


def test_ratio_interval_of_proportional_pairs_is_the_factor():
    a = {(f, 0): 3.0 * (f + 1) for f in range(6)}
    b = {(f, 0): float(f + 1) for f in range(6)}
    ratio, lo, hi = stats.ratio_interval(a, b)
    assert ratio == pytest.approx(3.0) and lo == pytest.approx(3.0) and hi == pytest.approx(3.0)
    c = {(f, 0): 2.0 * (f + 1) + (0.5 if f % 2 else -0.5) for f in range(6)}
    ratio, lo, hi = stats.ratio_interval(c, b)
    assert ratio == pytest.approx(np.mean(list(c.values())) / 3.5) and lo < ratio < hi


def test_paired_orients_by_direction():
    a, b = {(0, 0): 1.0, (1, 0): 2.0}, {(0, 0): 2.0, (1, 0): 4.0}
    assert stats.paired(a, b, True).mean_difference == pytest.approx(-1.5)
    assert stats.paired(a, b, False).mean_difference == pytest.approx(1.5)


def test_the_tables_judge_a_row_over_whole_damages():
    # the case above through a results table: (frame, seed) pairs, the seed the damage
    import pandas as pd

    from dpcbench.bench.reporting.tables import comparison_table

    rng = np.random.default_rng(1)
    records = []
    for seed, gain in ((0, 3.0), (1, 3.0), (2, -1.0)):
        for frame in range(10):
            base = 30.0 + rng.normal(0, 1)
            records += [{"sequence": "s", "method": "a", "frame": frame, "seed": seed, "value": base + gain},
                        {"sequence": "s", "method": "b", "frame": frame, "seed": seed, "value": base}]
    df = pd.DataFrame(records).assign(metric="gpsnr_d1", scope="frame", peak="intrinsic")
    table = comparison_table(df, "gpsnr_d1", peak="intrinsic", column_of=lambda sel: sel["method"])
    verdict = table.verdict("s")
    assert verdict.best == "a" and verdict.bold is None and verdict.tied == {"a", "b"}
    # without the damages, the 30 pairs would have made "a" bold
    assert stats.row_verdict({c: table.observations[("s", c)] for c in "ab"}, True).bold == "a"
    # a cell's interval is over the damages too: the t interval of a's three damage means (two degrees of freedom)
    a = table.observations[("s", "a")]
    means = [np.mean([v for (_, seed), v in a.items() if seed == s]) for s in range(3)]
    half = 4.302652729911275 * np.std(means, ddof=1) / math.sqrt(3)
    assert table.interval("s", "a") == pytest.approx((np.mean(means) - half, np.mean(means) + half))
