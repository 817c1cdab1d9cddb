"""Intervals over repeats and the verdicts built on them (experiments/lib/stats.py).

Coverage is measured on synthetic data with a known efficiency ratio: per
repeat, MSEs are scaled gamma variates (an image MSE is a sum over many
pixels: gamma with shape k, coefficient of variation 1/sqrt(k)) and times
lognormal. The nominal 95% interval must cover the true ratio in at least
93% of 1000 trials for each configuration (a binomial 95% interval of 1000
trials at 95% coverage is 93.6-96.4%). A negative control with repeats that
are not independent (one draw copied R times would claim a zero spread;
here: the interval from R repeats applied to the mean of R times as many
draws, which is too narrow) must fail the bound.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from experiments.lib import stats

TRIALS = 1000
MIN_COVERAGE = 0.93


def synthetic(rng, R, k, cv_time, mse_a=1.0, mse_b=1.6, time_a=1.0, time_b=1.25):
    """Per-repeat MSEs and times of A and B; true efficiency A / B = (mse_b time_b) /
    (mse_a time_a) (lognormal times: E = median x exp(cv^2 / 2), which cancels)."""
    return (mse_a * rng.gamma(k, 1 / k, R), rng.lognormal(math.log(time_a), cv_time, R),
            mse_b * rng.gamma(k, 1 / k, R), rng.lognormal(math.log(time_b), cv_time, R))


@pytest.mark.parametrize("R, k, cv_time", [(3, 200, 0.02), (4, 50, 0.05), (4, 10, 0.1),
                                           (6, 5, 0.1), (8, 3, 0.2)])
def test_efficiency_ratio_coverage(R, k, cv_time):
    rng = np.random.default_rng(R * 1000 + k)
    true = 1.6 * 1.25
    hits = sum(stats.efficiency_ratio(*synthetic(rng, R, k, cv_time)).excludes(true) is False
               for _ in range(TRIALS))
    assert hits / TRIALS >= MIN_COVERAGE, hits / TRIALS


@pytest.mark.parametrize("R, k", [(3, 50), (5, 5)])
def test_mean_interval_coverage(R, k):
    rng = np.random.default_rng(7 + R)
    hits = sum(stats.mean_interval(2.5 * rng.gamma(k, 1 / k, R)).excludes(2.5) is False
               for _ in range(TRIALS))
    assert hits / TRIALS >= MIN_COVERAGE, hits / TRIALS


def test_negative_control_too_narrow_an_interval_undercovers():
    """Intervals whose spread is understated (values averaged over 4 draws each, as if
    repeats were not independent of each other's noise) must fail the coverage bound."""
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(TRIALS):
        a = 1.0 * rng.gamma(5, 1 / 5, (4, 4))
        b = 1.6 * rng.gamma(5, 1 / 5, (4, 4))
        est = stats.ratio_interval([b.mean(axis=0)], [a.mean(axis=0)])
        # claim the narrower interval of 16 independent repeats from 4 averaged values
        half = math.log(est.hi / est.value) / 2
        hits += math.exp(math.log(est.value) - half) <= 1.6 <= math.exp(math.log(est.value)
                                                                         + half)
    assert hits / TRIALS < MIN_COVERAGE


def test_known_values():
    e = stats.mean_interval([1.0, 1.0, 1.0])
    assert (e.value, e.lo, e.hi) == pytest.approx((1.0, 1.0, 1.0))
    e = stats.mean_interval([2.0, 4.0])
    # log-scale t interval: sd of log mean = s / (sqrt(n) m) = sqrt(2) / (sqrt(2) 3) = 1/3
    from scipy.stats import t
    half = t.ppf(0.975, 1) / 3
    assert e.value == pytest.approx(3.0)
    assert e.lo == pytest.approx(3 * math.exp(-half)) and e.hi == pytest.approx(3 * math.exp(half))
    single = stats.mean_interval([5.0])
    assert single.value == pytest.approx(5.0) and not single.known
    assert math.isnan(single.fields("mse")["mse_lo"])
    r = stats.efficiency_ratio([1.0, 1.0], [2.0, 2.0], [4.0, 4.0], [1.0, 1.0])
    assert r.value == pytest.approx(2.0)         # (4 x 1) / (1 x 2)
    with pytest.raises(ValueError, match="at least one repeat"):
        stats.mean_interval([])


def test_verdict_states_a_real_difference():
    rng = np.random.default_rng(11)
    ma, ta, mb, tb = synthetic(rng, 6, 50, 0.05)      # true ratio 2
    est = stats.efficiency_ratio(ma, ta, mb, tb)
    text = stats.verdict("A", "B", est)
    assert est.excludes(1.0) and text.startswith("A is more efficient than B by ")
    assert "95% CI" in text
    assert stats.verdict("B", "A", stats.efficiency_ratio(mb, tb, ma, ta)).startswith(
        "A is more efficient than B by ")


def test_verdict_says_not_distinguishable_when_there_is_no_difference():
    rng = np.random.default_rng(12)
    claims = 0
    for _ in range(200):
        ma, ta, mb, tb = synthetic(rng, 4, 10, 0.1, mse_b=1.0, time_b=1.0)   # true ratio 1
        text = stats.verdict("A", "B", stats.efficiency_ratio(ma, ta, mb, tb))
        claims += "not distinguishable at this budget" not in text
    assert claims / 200 <= 0.1          # a 95% interval claims a false difference ~5%
    one = stats.verdict("A", "B", stats.efficiency_ratio([1.0], [1.0], [2.0], [1.0]))
    assert "not distinguishable" in one and "1 run" in one


def test_log_interval_combines_terms_with_their_degrees_of_freedom():
    """Terms from thousands of values (infinite dof) give the normal quantile; one term on
    2 dof gives Student's 4.30; a sum takes Welch-Satterthwaite's dof in between."""
    import math
    from scipy.stats import t as student
    normal = stats.log_interval(0.0, [(0.01, math.inf)], 3)
    assert math.log(normal.hi) == pytest.approx(1.959964 * 0.1, rel=1e-5)
    few = stats.log_interval(0.0, [(0.01, 2)], 3)
    assert math.log(few.hi) == pytest.approx(4.302653 * 0.1, rel=1e-5)
    both = stats.log_interval(math.log(2.0), [(0.01, math.inf), (0.01, 2)], 3)
    dof = 0.02 ** 2 / (0.01 ** 2 / 2)
    assert both.value == pytest.approx(2.0)
    assert math.log(both.hi / 2) == pytest.approx(student.ppf(0.975, dof) * math.sqrt(0.02))
    assert stats.log_interval(0.0, [(math.inf, 2)], 3).known is False
