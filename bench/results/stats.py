"""Paired statistics behind every "best" of a comparison table.

A table row (one sequence and one damage) compares methods on the same damaged inputs: every
method is run on the same frames with the same hole seeds, so its observations pair up by
(frame, seed). The procedure, per row (`row_verdict`):

1. **The row's best method**: the highest mean (lowest for a lower-is-better metric) over its
   observations, as the table prints it.
2. **Paired differences** against it, for every other method m, over the (frame, seed) pairs both
   have with finite values: ``d_i = s * (x_best,i - x_m,i)`` with ``s = +1`` when higher is better,
   ``-1`` otherwise, so ``d_i > 0`` means the best did better on pair i.
3. **A 95% interval of the mean difference**, percentile bootstrap, ``n_resamples = N_RESAMPLES``, random
   generator seeded with `SEED` (the same interval on every run), resampling whole *damages*: the
   damages (hole seeds) are drawn with replacement, then each drawn damage's pairs (its frames) with
   replacement, and the statistic is the mean of every d drawn (a two-stage cluster bootstrap,
   `mean_difference_interval` with ``groups``; Davison and Hinkley 1997, sec. 3.8). The frames of one damage
   are not independent pairs: coherent holes and occlusion rigs hide the same surface in every frame, and a
   method carries its fill from frame to frame, so resampling single pairs reads ten frames of one damage as
   ten damages (`experiments/damage_intervals.py` prints both intervals of every margin). With one damage,
   or one pair a damage, the pairs are resampled (`scipy.stats.bootstrap`, the paired bootstrap). With
   three damages whose frames agree (each damage's d the same in all its frames), the interval runs from
   the lowest damage's mean to the highest's (a damage drawn three times has probability 1/27 > 2.5 %).
   Differences that are all equal give the one-point interval ``[d, d]``.
4. **A Wilcoxon signed-rank test** of ``d`` (`scipy.stats.wilcoxon`, two-sided, zero differences
   dropped, ``method="auto"``: the exact null distribution for small samples without ties); all
   differences zero gives p = 1. It counts the pairs as independent; the interval of step 3 is the check
   across damages, and every verdict below asks both.
5. **Holm's correction** over the row's k = (methods - 1) comparisons (`holm`): the sorted p-values
   ``p_(1) <= ... <= p_(k)`` become ``max_{j<=i} min(1, (k - j + 1) p_(j))``.
6. **Verdicts**: m is *worse* than the best when its interval lies above 0 (``low > 0``) and its
   Holm-adjusted p <= `ALPHA`; otherwise it is *tied-best* (not distinguishable from the best). The
   best is *best* (bold in the tables) when every other method is worse, else *tied-best* too, with
   the same mark as the methods it cannot be told apart from.
7. **n too small for any claim**: the smallest p-value an exact two-sided signed-rank test can give
   on n non-zero differences is ``2 / 2**n`` (all of one sign), so after Holm over k comparisons no
   difference can pass ALPHA unless ``k * 2 / 2**n <= ALPHA`` (`min_pairs`: n >= 6 for one comparison
   at 0.05, n >= 9 for seven). Below that every method of the row gets the verdict "no claim" and
   nothing is bold; the table says so.

Everything here takes numbers and returns numbers; the tables (`bench.reporting.tables`) turn them into marks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats as _st

#: significance level of every claim (two-sided), after Holm's correction
ALPHA = 0.05
#: confidence level of every interval
CONFIDENCE = 0.95
#: bootstrap resamples of each interval of a mean difference
N_RESAMPLES = 9999
#: seed of the bootstrap's random generator (every interval is reproducible)
SEED = 0

BEST, TIED, WORSE, NO_CLAIM = "best", "tied-best", "worse", "no claim"
TEST_NAME = ("paired Wilcoxon signed-rank test against the row's best (two-sided), Holm-corrected over the "
             "row's methods, with a bootstrap 95% interval of the mean difference that resamples whole damages "
             "(hole seeds, all their frames)")


def min_pairs(comparisons: int = 1, alpha: float = ALPHA) -> int:
    """The smallest number of pairs n at which an exact two-sided Wilcoxon signed-rank test, Holm-
    corrected over ``comparisons`` tests, can reach ``alpha``: the least n with
    ``comparisons * 2 / 2**n <= alpha`` (2 / 2**n is the test's smallest p-value, all signs equal)."""
    k = max(1, int(comparisons))
    n = 1
    while k * 2.0 / 2.0 ** n > alpha:
        n += 1
    return n


def holm(p_values: list[float]) -> list[float]:
    """Holm-adjusted p-values, in the order given: with the p-values sorted ascending,
    ``adj_(i) = max_{j<=i} min(1, (k - j + 1) * p_(j))`` (k = their count, j from 1)."""
    p = np.asarray(p_values, dtype=float)
    k = len(p)
    order = np.argsort(p, kind="stable")
    adjusted = np.empty(k)
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (k - rank) * p[index]))
        adjusted[index] = running
    return adjusted.tolist()


def mean_difference_interval(d, confidence: float = CONFIDENCE, n_resamples: int = N_RESAMPLES,
                             seed: int = SEED, groups=None) -> tuple[float, float]:
    """Percentile-bootstrap ``confidence`` interval of mean(d), generator seeded with ``seed``: resampling the
    pairs' differences ``d`` (`scipy.stats.bootstrap`), or with ``groups`` (one label a value: its damage,
    e.g. the hole seed) and at least two damages, some with several values, resampling whole damages
    (`cluster_bootstrap`); ``(d0, d0)`` when every d is d0, ``(nan, nan)`` for fewer than 2 values."""
    d = np.asarray(d, dtype=float)
    if len(d) < 2:
        return (math.nan, math.nan)
    if np.all(d == d[0]):
        return (float(d[0]), float(d[0]))
    clustered = _clusters(groups, len(d))
    if clustered is not None:
        means = cluster_bootstrap([d], clustered, n_resamples, seed, lambda sums, counts: sums[0] / counts)
        low, high = np.percentile(means, [50 * (1 - confidence), 50 * (1 + confidence)])
        return (float(low), float(high))
    res = _st.bootstrap((d,), np.mean, confidence_level=confidence, n_resamples=n_resamples, method="percentile",
                        rng=np.random.default_rng(seed), vectorized=True)
    return (float(res.confidence_interval.low), float(res.confidence_interval.high))


def _clusters(groups, n: int) -> np.ndarray | None:
    """Each value's damage index (0..G-1) from its labels ``groups`` (n,), or None where a cluster bootstrap
    is not called for: no labels, one damage (nothing to resample but its frames) or one value a damage (the
    same as resampling pairs)."""
    if groups is None:
        return None
    which = _damage_index(groups, n)
    damages = int(which.max()) + 1
    return which if 1 < damages < n else None


def _damage_index(groups, n: int) -> np.ndarray:
    """Each value's damage index (n,), 0..G-1 in order of first appearance, from its labels ``groups`` (n,)."""
    labels = list(groups)
    if len(labels) != n:
        raise ValueError(f"groups has {len(labels)} labels for {n} values")
    index: dict = {}
    return np.array([index.setdefault(label, len(index)) for label in labels])


def cluster_bootstrap(values: list[np.ndarray], which: np.ndarray, n_resamples: int, seed: int, statistic):
    """The two-stage bootstrap replicates of ``statistic(sums, counts)`` (n_resamples,): G clusters (``which``
    (n,): each value's cluster, 0..G-1) drawn G times with replacement, then, for each cluster drawn, as many of
    its values as it has, drawn with replacement; ``sums[j]`` the sum of ``values[j]`` (n,) over the values
    drawn (the same positions for every j: pairs stay paired), ``counts`` their number. Resampling within a
    cluster too keeps its frames' own spread, which resampling clusters alone loses when few clusters agree
    (two seeds with equal means would give a zero-width interval). By hand: scipy's ``bootstrap`` resamples
    single observations, not groups of them."""
    rng = np.random.default_rng(seed)
    groups = int(which.max()) + 1
    members = [np.flatnonzero(which == c) for c in range(groups)]
    draw = rng.integers(0, groups, size=(n_resamples, groups))
    sums = [np.zeros(n_resamples) for _ in values]
    counts = np.zeros(n_resamples)
    for c, index in enumerate(members):
        rows, _ = np.nonzero(draw == c)  # one row per time cluster c is drawn, in row-major order
        picks = index[rng.integers(0, len(index), size=(len(rows), len(index)))]  # (times drawn, its size)
        for total, v in zip(sums, values):
            np.add.at(total, rows, v[picks].sum(axis=1))
        np.add.at(counts, rows, len(index))
    return statistic(sums, counts)


def signed_rank_p(d) -> float:
    """Two-sided p-value of `scipy.stats.wilcoxon` on the differences ``d`` (zeros dropped); 1.0
    when no difference is non-zero, nan for no values."""
    d = np.asarray(d, dtype=float)
    if len(d) == 0:
        return math.nan
    if not np.any(d != 0):
        return 1.0
    return float(_st.wilcoxon(d, zero_method="wilcox", alternative="two-sided", method="auto").pvalue)


def mean_interval(values, confidence: float = CONFIDENCE, groups=None) -> tuple[float, float]:
    """Student-t ``confidence`` interval of the mean m of ``values`` (finite ones), ``(nan, nan)`` for fewer than 2.

    Without ``groups``: ``m ± t_{(1+c)/2, n-1} * s / sqrt(n)``, s the sample standard deviation (ddof=1).
    With ``groups`` (one label a value: its damage, e.g. the hole seed) and G >= 2 damages, the values of one
    damage are not independent (they share its holes), so the damage is the unit: ``m ± t_{(1+c)/2, G-1} * se``,
    ``se**2 = G / (G - 1) * sum_g (sum_{i in g} (x_i - m))**2 / n**2`` (the cluster-robust standard error with
    its small-sample factor and G - 1 degrees of freedom; Cameron and Miller 2015, sec. VI). With equal
    damages it is the t interval of the G damage means; with one value a damage, the ungrouped interval. One
    damage: the ungrouped interval over its values (the only spread there is). By hand: no core dependency
    computes it (statsmodels does, for regressions).
    """
    v = np.asarray(values, dtype=float)
    finite = np.isfinite(v)
    v = v[finite]
    if len(v) < 2:
        return (math.nan, math.nan)
    m = float(v.mean())
    # the damages that keep a finite value, renumbered 0..G-1
    which = None if groups is None else np.unique(_damage_index(groups, len(finite))[finite], return_inverse=True)[1]
    if which is not None and which.max() >= 1:
        damages = int(which.max()) + 1
        residual_sums = np.bincount(which, weights=v - m, minlength=damages)
        se = math.sqrt(damages / (damages - 1) * float(np.sum(residual_sums ** 2))) / len(v)
        half = float(_st.t.ppf((1 + confidence) / 2, damages - 1)) * se
    else:
        half = float(_st.t.ppf((1 + confidence) / 2, len(v) - 1)) * float(v.std(ddof=1)) / math.sqrt(len(v))
    return (m - half, m + half)


@dataclass
class PairedComparison:
    """The best method against one other, over ``n`` pairs: mean of d (positive = the best did
    better), its bootstrap interval, the raw and Holm-adjusted Wilcoxon p-values."""

    method: str
    n: int
    mean_difference: float
    low: float
    high: float
    p_value: float
    p_holm: float = math.nan

    @property
    def distinguishable(self) -> bool:
        return self.low > 0 and self.p_holm <= ALPHA


@dataclass
class RowVerdict:
    """One row's verdicts: method -> BEST / TIED / WORSE / NO_CLAIM (empty without a direction)."""

    best: str | None
    n: int                      # the fewest pairs of any comparison of the row
    needed: int                 # `min_pairs` for this row's number of comparisons
    comparisons: dict[str, PairedComparison] = field(default_factory=dict)
    verdicts: dict[str, str] = field(default_factory=dict)

    @property
    def too_small(self) -> bool:
        return bool(self.comparisons) and self.n < self.needed

    @property
    def bold(self) -> str | None:
        """The method that is best beyond every other's interval, if one is."""
        return self.best if self.best is not None and self.verdicts.get(self.best) == BEST else None

    @property
    def tied(self) -> set[str]:
        return {m for m, v in self.verdicts.items() if v == TIED}


def paired(a: dict, b: dict, higher_is_better: bool = True, name: str = "", damage=None) -> PairedComparison:
    """``a`` against ``b`` over their shared pair keys (finite values): d = s * (a - b), s = +1 when
    higher is better, else -1 (d > 0: a did better); mean, bootstrap interval and Wilcoxon p (raw;
    ``p_holm`` is set to it: correct several with `holm`). ``damage``: a function of a pair key giving its
    damage (e.g. the hole seed of a (frame, seed) key): the interval resamples whole damages
    (`mean_difference_interval`)."""
    sign = 1.0 if higher_is_better else -1.0
    keys = sorted(k for k in set(a) & set(b) if math.isfinite(a[k]) and math.isfinite(b[k]))
    d = np.array([sign * (a[k] - b[k]) for k in keys])
    low, high = mean_difference_interval(d, groups=None if damage is None else [damage(k) for k in keys])
    p = signed_rank_p(d)
    return PairedComparison(name, len(d), float(d.mean()) if len(d) else math.nan, low, high, p, p)


def ratio_interval(a: dict, b: dict, confidence: float = CONFIDENCE, n_resamples: int = N_RESAMPLES,
                   seed: int = SEED, damage=None) -> tuple[float, float, float]:
    """(mean(a) / mean(b), low, high) over the shared pair keys: a percentile-bootstrap interval of the
    ratio of means, resampling whole pairs (`scipy.stats.bootstrap` with ``paired=True``, seeded), or with
    ``damage`` (a function of a pair key giving its damage, as in `paired`) whole damages."""
    keys = sorted(k for k in set(a) & set(b) if math.isfinite(a[k]) and math.isfinite(b[k]))
    x, y = np.array([a[k] for k in keys]), np.array([b[k] for k in keys])
    if len(keys) == 0 or y.mean() == 0:
        return (math.nan, math.nan, math.nan)
    ratio = float(x.mean() / y.mean())
    if len(keys) < 2 or (np.all(x == x[0]) and np.all(y == y[0])):
        return (ratio, ratio, ratio) if len(keys) >= 2 else (ratio, math.nan, math.nan)
    clustered = _clusters(None if damage is None else [damage(k) for k in keys], len(keys))
    if clustered is not None:
        ratios = cluster_bootstrap([x, y], clustered, n_resamples, seed, lambda sums, counts: sums[0] / sums[1])
        low, high = np.percentile(ratios, [50 * (1 - confidence), 50 * (1 + confidence)])
        return (ratio, float(low), float(high))
    res = _st.bootstrap((x, y), lambda u, v, axis=-1: u.mean(axis=axis) / v.mean(axis=axis), paired=True,
                        confidence_level=confidence, n_resamples=n_resamples, method="percentile",
                        rng=np.random.default_rng(seed), vectorized=True)
    return (ratio, float(res.confidence_interval.low), float(res.confidence_interval.high))


def row_verdict(observations: dict[str, dict], higher_is_better: bool | None, damage=None) -> RowVerdict:
    """The verdicts of one row (see the module docstring for the procedure).

    observations: method -> {pair key (e.g. (frame, seed)): value}. Non-finite values are left out.
    higher_is_better: the metric's direction; None gives no best and no verdicts.
    damage: a function of a pair key giving its damage (`paired`); the intervals resample whole damages.
    """
    obs = {m: {k: float(v) for k, v in pairs.items() if v is not None and math.isfinite(float(v))}
           for m, pairs in observations.items()}
    obs = {m: pairs for m, pairs in obs.items() if pairs}
    if higher_is_better is None or not obs:
        return RowVerdict(best=None, n=0, needed=min_pairs(1))
    sign = 1.0 if higher_is_better else -1.0
    means = {m: float(np.mean(list(p.values()))) for m, p in obs.items()}
    best = max(means, key=lambda m: sign * means[m])
    others = [m for m in obs if m != best]
    needed = min_pairs(len(others))
    if not others:
        return RowVerdict(best=best, n=len(obs[best]), needed=needed, verdicts={best: NO_CLAIM})
    comparisons = {m: paired(obs[best], obs[m], higher_is_better, m, damage) for m in others}
    for m, p in zip(others, holm([comparisons[m].p_value if not math.isnan(comparisons[m].p_value) else 1.0
                                  for m in others])):
        comparisons[m].p_holm = p
    n = min(c.n for c in comparisons.values())
    verdict = RowVerdict(best=best, n=n, needed=needed, comparisons=comparisons)
    if verdict.too_small:
        verdict.verdicts = {m: NO_CLAIM for m in obs}
        return verdict
    verdict.verdicts = {m: (WORSE if comparisons[m].distinguishable else TIED) for m in others}
    verdict.verdicts[best] = BEST if all(comparisons[m].distinguishable for m in others) else TIED
    return verdict


def too_small_text(n: int, comparisons: int, alpha: float = ALPHA) -> str:
    """The sentence a table prints when its n is too small for any claim."""
    needed = min_pairs(comparisons, alpha)
    return (f"n = {n} pairs is too small for any claim: the smallest two-sided Wilcoxon signed-rank p-value on "
            f"n pairs is 2/2^n = {2 / 2 ** n:.3g}, and Holm over {comparisons} comparison(s) at {alpha} needs "
            f"n >= {needed}; nothing is marked best.")
