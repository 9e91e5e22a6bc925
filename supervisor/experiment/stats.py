"""The statistics of an experiment's report: pure functions of numbers, no files, no runs.

What a reviewer asks of a table of robot runs (docs/statistics.md explains each figure with
its reference):

* per cell: n (values present; runs missing the metric counted apart, never averaged as 0),
  mean, median, interquartile range (numpy's default quantile), interquartile mean
  (`scipy.stats.trim_mean(x, 0.25)`), Student's t interval, and a 95 % bootstrap interval —
  over instances, then seeds within each (`bootstrap_two_level`, percentile) when a cell has
  several instances with several seeds, otherwise BCa over the runs (`scipy.stats.bootstrap`);
  data whose values are all equal have no bootstrap interval and say so (`Describe.identical`);
* paired comparisons (other − baseline, matched runs): the mean difference and its bootstrap
  interval, the Wilcoxon signed-rank p-value (`scipy.stats.wilcoxon`, zero_method "wilcox",
  method "auto": exact for small n), Holm's step-down adjustment over a family, Vargha and
  Delaney's A12 over all cross pairs, and the probability of improvement over matched pairs;
* Dolan and Moré's performance profiles.

Every resampling draws from `numpy.random.default_rng(seed)` made afresh for each interval, so
the same numbers give the same report whatever order cells are computed in.
"""

from __future__ import annotations

import math
import statistics
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np

RESAMPLES = 10_000
BLOCK_CELLS = 1 << 21  # values drawn at once by the two-level bootstrap (16 MiB of floats)
CONFIDENCE = 0.95
SEED = 20211206  # fixed, written under every table (Agarwal et al.'s NeurIPS 2021, the date)
LOWER, HIGHER = "lower", "higher"  # which direction of a metric is better


def mean_ci(xs: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Mean and the half-width of its `confidence` interval: Student's t with n − 1 degrees of
    freedom, its quantile exact (scipy), not a table's. (nan, nan) without values; the
    half-width is nan for one value."""
    if not xs:
        return math.nan, math.nan
    m = statistics.fmean(xs)
    if len(xs) < 2:
        return m, math.nan
    from scipy.stats import t as student_t

    q = float(student_t.ppf(0.5 + confidence / 2, len(xs) - 1))
    return m, q * statistics.stdev(xs) / math.sqrt(len(xs))


@dataclass(frozen=True)
class Interval:
    low: float
    high: float
    method: str  # "BCa", "percentile, two-level", …: how it was made, for the table's note

    @property
    def half_width(self) -> float:
        return (self.high - self.low) / 2


def bootstrap_one_level(xs: Sequence[float], seed: int = SEED, resamples: int = RESAMPLES,
                        confidence: float = CONFIDENCE) -> Interval | None:
    """The BCa interval of the mean of `xs` (scipy.stats.bootstrap, as called in the tests);
    None for fewer than two values or all-equal ones (there is no interval to draw). When
    BCa's correction is undefined for these data (scipy warns and returns nan), the percentile
    interval of the same resamples is given instead and named so."""
    x = np.asarray(xs, dtype=float)
    if x.size < 2 or np.all(x == x[0]):
        return None
    from scipy.stats import DegenerateDataWarning, bootstrap

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegenerateDataWarning)
        res = bootstrap((x,), np.mean, n_resamples=resamples, confidence_level=confidence,
                        method="BCa", random_state=np.random.default_rng(seed))
    low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if math.isfinite(low) and math.isfinite(high):
        return Interval(low, high, "BCa")
    tail = (1 - confidence) / 2 * 100
    low, high = np.percentile(res.bootstrap_distribution, [tail, 100 - tail])
    return Interval(float(low), float(high), "percentile (BCa undefined)")


def bootstrap_two_level(groups: Sequence[Sequence[float]], seed: int = SEED,
                        resamples: int = RESAMPLES, confidence: float = CONFIDENCE
                        ) -> Interval | None:
    """The percentile interval of the mean over all runs when the runs come in groups (one per
    instance, the seeds within it): each resample draws as many instances as there are, with
    replacement, then within each drawn instance as many of its runs as it has, with
    replacement, and takes the mean of every value drawn. Resampling both levels keeps the
    spread between instances in the interval, which resampling runs alone would hide. None
    when there is nothing to resample (all values equal, or a single value)."""
    groups = [np.asarray(g, dtype=float) for g in groups if len(g)]
    values = np.concatenate(groups) if groups else np.array([])
    if values.size < 2 or np.all(values == values[0]):
        return None
    rng = np.random.default_rng(seed)
    k = len(groups)
    sizes = np.array([g.size for g in groups])
    width = int(sizes.max())
    padded = np.zeros((k, width))
    for i, g in enumerate(groups):
        padded[i, :g.size] = g
    sums = np.zeros(resamples)
    counts = np.zeros(resamples)
    columns = np.arange(width)
    # the draws of one instance slot, a block of resamples at a time: memory bounded by
    # BLOCK_CELLS whatever the file's size (one cell of 50,000 runs asked for 6 GiB at once),
    # and the same numbers as one draw of every resample (the generator's stream is sequential)
    block = max(1, BLOCK_CELLS // width)
    for _ in range(k):
        pick = rng.integers(0, k, size=resamples)             # an instance per resample
        for lo in range(0, resamples, block):
            part = pick[lo:lo + block]
            n = sizes[part][:, None]
            within = (rng.random((part.size, width)) * n).astype(int)  # its runs, replaced
            drawn = padded[part[:, None], within]
            sums[lo:lo + block] += np.where(columns[None, :] < n, drawn, 0.0).sum(axis=1)
        counts += sizes[pick]
    means = sums / counts
    tail = (1 - confidence) / 2 * 100
    low, high = np.percentile(means, [tail, 100 - tail])
    return Interval(float(low), float(high), "percentile, instances then seeds")


def bootstrap_mean(groups: Sequence[Sequence[float]], seed: int = SEED,
                   resamples: int = RESAMPLES) -> Interval | None:
    """The interval the report uses for values grouped by instance: two levels when there are
    several instances and some has several runs; one level (BCa over the values) otherwise —
    one instance (its runs), or one run per instance (the instances)."""
    groups = [list(g) for g in groups if len(g)]
    if len(groups) > 1 and any(len(g) > 1 for g in groups):
        return bootstrap_two_level(groups, seed, resamples)
    return bootstrap_one_level([x for g in groups for x in g], seed, resamples)


@dataclass(frozen=True)
class Describe:
    """One metric in one cell."""

    n: int                  # values present
    missing: int            # runs (that ended well) without the metric
    mean: float
    median: float
    q1: float
    q3: float
    iqm: float
    t_half_width: float     # Student's t, nan below two values
    interval: Interval | None
    identical: bool         # two values or more, all equal

    @property
    def iqr(self) -> float:
        return self.q3 - self.q1


def describe(groups: Sequence[Sequence[float]], missing: int = 0, seed: int = SEED,
             resamples: int = RESAMPLES) -> Describe:
    """The figures of one cell's values, grouped by instance (a single group: one instance)."""
    from scipy.stats import trim_mean

    values = [x for g in groups for x in g]
    if not values:
        nan = math.nan
        return Describe(0, missing, nan, nan, nan, nan, nan, nan, None, False)
    x = np.asarray(values, dtype=float)
    q1, median, q3 = (float(v) for v in np.quantile(x, [0.25, 0.5, 0.75]))
    return Describe(int(x.size), missing, float(x.mean()), median, q1, q3,
                    float(trim_mean(x, 0.25)), mean_ci(values)[1],
                    bootstrap_mean(groups, seed, resamples),
                    bool(x.size > 1 and np.all(x == x[0])))


# ------------------------------------------------------------------ comparisons
def wilcoxon_p(d: Sequence[float]) -> float | None:
    """The two-sided Wilcoxon signed-rank p-value of paired differences `d`
    (`scipy.stats.wilcoxon(d, zero_method="wilcox", method="auto")`: zero differences are
    dropped, exact for small n); None when no difference is non-zero."""
    d = np.asarray(d, dtype=float)
    if not np.any(d != 0):
        return None
    nonzero = d[d != 0]
    if (d.size <= _ENUMERATED and np.all(np.isfinite(d))
            and (nonzero.size < d.size or np.unique(np.abs(nonzero)).size < nonzero.size)):
        return _sign_flip_p(nonzero)
    from scipy.stats import wilcoxon

    with warnings.catch_warnings():
        # n of 1–5 non-zero differences cannot reach p < 0.05; scipy says so, the table shows it
        warnings.simplefilter("ignore", UserWarning)
        return float(wilcoxon(d, zero_method="wilcox", method="auto").pvalue)


_ENUMERATED = 13  # scipy's "auto" enumerates every sign flip up to 13 differences (2^13 < 9,999)


def _sign_flip_p(nonzero: np.ndarray) -> float:
    """The p-value scipy's "auto" gives differences with ties or zeros, n ≤ 13 (a permutation
    test over all 2^n sign flips, zeros dropped), computed as one matrix product: scipy
    evaluates the statistic once per flip (≈ 5 ms each, 2^13 of them per comparison), which
    made a study's report take minutes. Ranks are averages (multiples of ½), so the sums and
    the comparisons with the observed sum are exact."""
    from scipy.stats import rankdata

    ranks = rankdata(np.abs(nonzero))
    n = ranks.size
    flips = (np.arange(1 << n)[:, None] >> np.arange(n)) & 1  # every subset of positive signs
    totals = flips @ ranks
    observed = float(ranks[nonzero > 0].sum())
    low = np.count_nonzero(totals <= observed) / totals.size
    high = np.count_nonzero(totals >= observed) / totals.size
    return min(1.0, 2 * min(low, high))


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment, in the order given: sorted ascending, the i-th (from 0) of
    m is multiplied by m − i, kept monotone, capped at 1."""
    order = sorted(range(len(pvalues)), key=lambda i: pvalues[i])
    m = len(pvalues)
    adjusted = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * pvalues[i]))
        adjusted[i] = running
    return adjusted


def a12(baseline: Sequence[float], other: Sequence[float]) -> float:
    """Vargha and Delaney's A12 = P(baseline < other) + ½ P(equal), over every cross pair of
    the two samples (the rank form, computed by sorting: the same count, in n log n)."""
    b = np.sort(np.asarray(baseline, dtype=float))
    o = np.asarray(other, dtype=float)
    if b.size == 0 or o.size == 0:
        return math.nan
    below = np.searchsorted(b, o, side="left")   # baseline values < each other value
    upto = np.searchsorted(b, o, side="right")   # … ≤ it
    return float((below.sum() + 0.5 * (upto - below).sum()) / (b.size * o.size))


def improvement(d: Sequence[float], better: str) -> float:
    """The probability that the other run is better than its matched baseline run (paired
    differences other − baseline), ties counted half."""
    d = np.asarray(d, dtype=float)
    if d.size == 0:
        return math.nan
    wins = (d < 0) if better == LOWER else (d > 0)
    return float((wins.sum() + 0.5 * (d == 0).sum()) / d.size)


def profile_ratios(values: dict[str, list[float | None]], better: str) -> dict[str, list[float]]:
    """Dolan and Moré's performance ratios: `values[solver][p]` is solver's objective on problem
    p (None: no value — it never solved it, ratio ∞). For a lower-is-better objective the ratio
    is value / best; for a higher-is-better one best / value, so 1 is the best in both. A best
    of 0 makes another 0 a ratio of 1 and anything else ∞."""
    solvers = list(values)
    problems = len(next(iter(values.values()), []))
    out: dict[str, list[float]] = {s: [] for s in solvers}
    for p in range(problems):
        present = [values[s][p] for s in solvers if values[s][p] is not None]
        best = (min(present) if better == LOWER else max(present)) if present else None
        for s in solvers:
            v = values[s][p]
            out[s].append(ratio(v, best, better))
    return out


def ratio(v: float | None, best: float | None, better: str) -> float:
    if v is None or best is None:
        return math.inf
    num, den = (v, best) if better == LOWER else (best, v)
    if den == 0:
        return 1.0 if num == 0 else math.inf
    r = num / den
    return r if r > 0 else math.inf  # a sign change has no ratio


def profile(ratios: Sequence[float], taus: Sequence[float]) -> list[float]:
    """ρ(τ): the share of problems whose ratio is at most τ, for each τ."""
    r = np.asarray(ratios, dtype=float)
    if r.size == 0:
        return [math.nan for _ in taus]
    return [float((r <= t).mean()) for t in taus]
