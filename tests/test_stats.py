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


def test_mean_interval_is_students_t():
    lo, hi = stats.mean_interval([1.0, 2.0, 3.0])
    half = 4.302652729911275 / math.sqrt(3)  # t(0.975, 2) * s / sqrt(n), s = 1
    assert (lo, hi) == pytest.approx((2 - half, 2 + half))


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
