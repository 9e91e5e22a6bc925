"""The report's statistics against independent computations: scipy called
directly, brute-force enumerations and the definitions, never the code under test."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from mrta_supervisor.experiment import stats
def test_one_level_bounds_are_scipys_bca_on_the_same_data_and_seed():
    import scipy.stats  # here, not at collection (≈ 2 CPU-s in each xdist worker)
    x = [3.1, 2.9, 3.4, 3.0, 3.8, 2.7, 3.3, 3.05]
    direct = scipy.stats.bootstrap((np.array(x),), np.mean, n_resamples=10_000,
                                   confidence_level=0.95, method="BCa",
                                   random_state=np.random.default_rng(1234))
    ours = stats.bootstrap_one_level(x, seed=1234)
    assert ours.method == "BCa"
    assert (ours.low, ours.high) == (direct.confidence_interval.low,
                                     direct.confidence_interval.high)
    # the same results give the same report: the seed is fixed, not drawn
    assert stats.bootstrap_one_level(x, seed=1234) == ours


def test_all_equal_values_have_no_bootstrap_interval_and_say_so():
    d = stats.describe([[2.3, 2.3, 2.3]])
    assert d.interval is None and d.identical and d.n == 3 and d.mean == 2.3
    one = stats.describe([[2.3]])
    assert one.interval is None and not one.identical and math.isnan(one.t_half_width)


def test_a_cell_figures_by_their_definitions_and_missing_values_apart():
    import scipy.stats  # here, not at collection (≈ 2 CPU-s in each xdist worker)
    x = [1.0, 2.0, 2.0, 3.0, 7.0, 9.0, 10.0, 4.0]
    d = stats.describe([x], missing=3)
    assert (d.n, d.missing) == (8, 3)  # missing runs are not zeros: the mean is over 8
    assert d.mean == pytest.approx(sum(x) / 8)
    q1, q3 = np.quantile(x, [0.25, 0.75])  # numpy's default (linear) quantile
    assert (d.q1, d.q3, d.iqr) == (q1, q3, q3 - q1)
    s = sorted(x)
    assert d.iqm == pytest.approx(sum(s[2:6]) / 4)  # the middle half of eight values
    assert d.iqm == pytest.approx(scipy.stats.trim_mean(x, 0.25))
    sd = np.std(x, ddof=1)
    assert d.t_half_width == pytest.approx(scipy.stats.t.ppf(0.975, 7) * sd / math.sqrt(8))


@pytest.mark.slow
def test_the_two_level_bootstrap_covers_a_known_mean_about_95_percent_of_the_time():
    """Synthetic experiments: 20 instances, each with its own mean around 5 (sd 1), 3 seeds each
    around it (sd 1). The interval over instances then seeds holds 5 in ≈ 95 % of them —
    resampling runs alone would hide the spread between instances and cover far less."""
    rng = np.random.default_rng(7)
    trials, hits, naive = 300, 0, 0
    for trial in range(trials):
        groups = [rng.normal(m, 1.0, size=3) for m in rng.normal(5.0, 1.0, size=20)]
        iv = stats.bootstrap_two_level(groups, seed=trial, resamples=1000)
        hits += iv.low <= 5.0 <= iv.high
        flat = np.concatenate(groups)
        boot = np.random.default_rng(trial).choice(flat, size=(1000, flat.size)).mean(axis=1)
        lo, hi = np.percentile(boot, [2.5, 97.5])
        naive += lo <= 5.0 <= hi
    assert 0.91 <= hits / trials <= 0.98, hits / trials
    assert naive / trials < hits / trials - 0.05  # what the second level is for


def test_the_two_level_resampler_draws_instances_then_seeds_within_them():
    """With one value per seed, instances far apart and seeds equal within each, every resample
    is a mean of whole instances: it can only take values k/4 between the two means."""
    iv = stats.bootstrap_two_level([[0.0, 0.0], [4.0, 4.0], [0.0, 0.0], [4.0, 4.0]],
                                   resamples=4000)
    assert iv.low >= 0.0 and iv.high <= 4.0 and iv.low in (0.0, 1.0) and iv.high in (3.0, 4.0)
    # a cell of one instance, or one run per instance, is one level: BCa over the values
    assert stats.bootstrap_mean([[1.0, 2.0, 4.0]]).method == "BCa"
    assert stats.bootstrap_mean([[1.0], [2.0], [4.0]]).method == "BCa"
    assert stats.bootstrap_mean([[1.0, 2.0], [4.0, 3.0]]).method.startswith("percentile")


def brute_force_wilcoxon(d: list[float]) -> float:
    """The exact two-sided signed-rank p-value by enumerating every sign assignment."""
    import scipy.stats  # here, not at collection (≈ 2 CPU-s in each xdist worker)
    d = [x for x in d if x != 0]
    ranks = scipy.stats.rankdata(np.abs(d))
    observed = sum(r for r, x in zip(ranks, d) if x > 0)
    totals = [sum(r for r, s in zip(ranks, signs) if s)
              for signs in itertools.product([False, True], repeat=len(d))]
    n = len(totals)
    low = sum(t <= observed for t in totals) / n
    high = sum(t >= observed for t in totals) / n
    return min(1.0, 2 * min(low, high))


@pytest.mark.parametrize("d", [[1.5, -0.5, 2.0, 3.5, 0.7], [0.3, 0.1, -0.2, 0.9, 1.1, 0.4, -0.6],
                               [2.0, 2.5, 3.0], [1.0, -2.0, 3.0, -4.0, 5.0, 6.0, -7.5, 8.25],
                               [0.0, 1.0, 2.0, -3.0, 4.0]])
def test_the_wilcoxon_p_value_is_the_sign_flip_enumeration(d):
    assert stats.wilcoxon_p(d) == pytest.approx(brute_force_wilcoxon(d), abs=1e-12)


def test_no_p_value_when_every_difference_is_zero():
    assert stats.wilcoxon_p([0.0, 0.0, 0.0]) is None


def test_a12_is_the_share_of_cross_pairs_where_the_baseline_is_below():
    base, other = [1.0, 2.0, 2.0, 5.0], [2.0, 3.0, 0.5]
    count = sum((b < o) + 0.5 * (b == o) for b in base for o in other)
    assert stats.a12(base, other) == pytest.approx(count / (len(base) * len(other)))
    assert stats.a12([1.0, 1.0], [1.0]) == 0.5 and stats.a12([0.0], [1.0]) == 1.0


def test_the_probability_of_improvement_counts_matched_pairs_and_ties_half():
    d = [-1.0, -0.5, 0.0, 2.0]  # other − baseline
    assert stats.improvement(d, stats.LOWER) == (2 + 0.5) / 4
    assert stats.improvement(d, stats.HIGHER) == (1 + 0.5) / 4


def holm_by_definition(p: list[float]) -> list[float]:
    """Holm 1979: sort ascending; reject H(i) while p(i) ≤ α/(m − i + 1); the adjusted p-value
    of H(i) is the smallest α at which it is rejected, max over j ≤ i of (m − j + 1) p(j)."""
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    out = [0.0] * m
    for pos, i in enumerate(order):
        out[i] = min(1.0, max((m - j) * p[order[j]] for j in range(pos + 1)))
    return out


def test_holm_is_the_step_down_definition():
    table = [0.01, 0.04, 0.03, 0.005, 0.20, 0.04]
    assert stats.holm(table) == pytest.approx(holm_by_definition(table))
    # decisions at 0.05: the step-down stops at the first p above α/(m − i + 1)
    rejected = [p <= 0.05 for p in stats.holm(table)]
    assert rejected == [True, False, False, True, False, False]


def test_a_performance_profile_by_hand():
    """Three problems; A: 10, 20, none (never solved); B: 12, 10, 30 (lower is better).
    Ratios A: 1, 2, ∞; B: 1.2, 1, 1. ρ_A(1) = 1/3, ρ_A(2) = 2/3; ρ_B(1) = 2/3, ρ_B(1.2) = 1."""
    ratios = stats.profile_ratios({"A": [10.0, 20.0, None], "B": [12.0, 10.0, 30.0]},
                                  stats.LOWER)
    assert ratios["A"] == [1.0, 2.0, math.inf]
    assert ratios["B"] == pytest.approx([1.2, 1.0, 1.0])
    taus = [1.0, 1.2, 2.0, 10.0]
    assert stats.profile(ratios["A"], taus) == pytest.approx([1 / 3, 1 / 3, 2 / 3, 2 / 3])
    assert stats.profile(ratios["B"], taus) == pytest.approx([2 / 3, 1.0, 1.0, 1.0])
    # higher is better: the ratio is best / value
    up = stats.profile_ratios({"A": [0.9, 0.5], "B": [0.45, 1.0]}, stats.HIGHER)
    assert up["A"] == [1.0, 2.0] and up["B"] == [2.0, 1.0]
