"""Uncertainty of measured errors and efficiencies over independent repeats, and verdicts.

Every comparison in the report renders each method R times with independent
randomizations (``--repeats``). A quantity measured once per repeat (an MSE, a
render time) is summarised by :func:`mean_interval`; a ratio of efficiencies
by :func:`efficiency_ratio`. Both are **delta-method intervals on the log
scale** with Student-t quantiles:

* the mean m of R values with sample standard deviation s has
  Var[log m] ~ s^2 / (R m^2) (its squared coefficient of variation over R);
* a ratio of products of independent means, e.g. efficiency A / B =
  (MSE_B x T_B) / (MSE_A x T_A), has Var[log ratio] = the sum of those terms,
  with Welch-Satterthwaite degrees of freedom.

The interval is exp(log estimate +- t x sd): positive, asymmetric like the
quantities themselves, and a ratio's interval is the inverse of the inverse
ratio's. Covariances between the factors are left out: render times of two
methods timed side by side under the same machine load are positively
correlated, so leaving the covariance out widens the interval (conservative).
Coverage on synthetic data with a known ratio is tested (``tests/test_stats.py``).

:func:`verdict` turns an interval into a sentence that only claims a
difference when the interval excludes 1.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

def g(x: float) -> str:
    """A number as the report's tables and prose print it: three significant digits."""
    return f"{x:.3g}"


#: Nominal coverage of every interval in the report.
LEVEL = 0.95
METHOD = ("delta-method interval on the log scale over independent repeats (Student t, "
          "Welch-Satterthwaite degrees of freedom)")


@dataclass(frozen=True)
class Estimate:
    """A point estimate with its ``level`` confidence interval [lo, hi] from ``n`` repeats
    (lo = hi = NaN when fewer than two repeats give no interval)."""
    value: float
    lo: float
    hi: float
    n: int
    level: float = LEVEL
    #: True when the quantity could not be told from zero and only its upper bound ``hi``
    #: is known (an error below the reference's own noise, see :func:`excess_interval`);
    #: ``value`` is then ``hi`` and ``lo`` is 0.
    bound: bool = False

    @property
    def known(self) -> bool:
        """Has an interval (at least two repeats with a finite spread)."""
        return math.isfinite(self.lo) and math.isfinite(self.hi)

    def excludes(self, x: float = 1.0) -> bool:
        return self.known and not self.bound and not (self.lo <= x <= self.hi)

    def fields(self, name: str) -> dict:
        """``{name: value, name_lo: lo, name_hi: hi}`` for tables and summary.json rows."""
        return {name: self.value, f"{name}_lo": self.lo, f"{name}_hi": self.hi}

    def cells(self) -> list[str]:
        """``[value, lo, hi]`` as table cells (:func:`g`)."""
        return [g(self.value), g(self.lo), g(self.hi)]

    def text(self, fmt: str = "{:.3g}") -> str:
        """'v (95% CI lo-hi)', 'v (one run, no interval)', or '< hi (...)' for a bound."""
        if self.bound:
            return (f"< {fmt.format(self.hi)} (below the reference's own noise: an upper "
                    f"bound at {self.level:.0%})")
        if not self.known:
            return f"{fmt.format(self.value)} (no interval: {self.n} run)"
        return (f"{fmt.format(self.value)} ({self.level:.0%} CI {fmt.format(self.lo)}-"
                f"{fmt.format(self.hi)})")


@functools.lru_cache(maxsize=4096)
def _t_quantile(dof: float, level: float) -> float:
    from scipy.stats import t
    return float(t.ppf(0.5 + level / 2, dof))


def _log_term(values) -> tuple[float, float, int]:
    """(log of the mean, variance of that log by the delta method, n)."""
    x = np.asarray(values, np.float64)
    n = x.size
    if n == 0:
        raise ValueError("no values: an estimate needs at least one repeat")
    m = float(x.mean())
    if not m > 0 or not math.isfinite(m):
        return (math.log(m) if m > 0 else float("nan")), float("nan"), n
    var = float(x.var(ddof=1)) / (n * m * m) if n > 1 else float("nan")
    return math.log(m), var, n


def _combine(terms: list[tuple[float, float, int, int]], level: float) -> Estimate:
    """exp(sum sign x log mean) with its interval; terms are (log m, var, n, sign)."""
    log_value = sum(sign * lm for lm, _, _, sign in terms)
    value = math.exp(log_value) if math.isfinite(log_value) else float("nan")
    n = min(t[2] for t in terms)
    variances = [v for _, v, _, _ in terms]
    if n < 2 or not all(math.isfinite(v) for v in variances):
        return Estimate(value, float("nan"), float("nan"), n, level)
    total = sum(variances)
    if total == 0:
        return Estimate(value, value, value, n, level)
    dof = total ** 2 / sum(v * v / (k - 1) for _, v, k, _ in terms if v > 0)
    half = _t_quantile(dof, level) * math.sqrt(total)
    return Estimate(value, math.exp(log_value - half), math.exp(log_value + half), n, level)


def normal_quantile(level: float = LEVEL) -> float:
    """The two-sided normal quantile of ``level`` (1.96 at 95%)."""
    return _t_quantile(math.inf, level)


def log_interval(log_value: float, terms: list, n: int, level: float = LEVEL) -> Estimate:
    """exp(log_value) with the interval of a sum of independent log-scale terms, each
    (variance, degrees of freedom; ``math.inf`` for a term from thousands of values): Student
    t on the Welch-Satterthwaite degrees of freedom of the sum, exp(log_value +- t sd)."""
    value = math.exp(log_value)
    total = sum(v for v, _ in terms)
    if not math.isfinite(total):
        return Estimate(value, float("nan"), float("nan"), n, level)
    if total == 0:
        return Estimate(value, value, value, n, level)
    spread = sum(v * v / d for v, d in terms if v > 0 and math.isfinite(d))
    dof = total ** 2 / spread if spread > 0 else math.inf
    half = math.sqrt(total) * _t_quantile(dof, level)
    return Estimate(value, math.exp(log_value - half), math.exp(log_value + half), n, level)


#: Robust z beyond which :func:`winsorize` clips a value (median +- k x 1.4826 MAD): 5
#: keeps the coverage of Gaussian costs (tests/test_suite_errors.py: 91-99% at 95%).
WINSOR_K = 5.0


def winsorize(values, k: float = WINSOR_K) -> np.ndarray:
    """``values`` each clipped to median +- k robust standard deviations (1.4826 x the
    median absolute deviation): a value from a normal sample is clipped rarely, a lone spike
    (a render slowed by the machine) is brought in. With a MAD of 0 (most values equal)
    nothing is clipped."""
    x = np.asarray(values, np.float64)
    center = float(np.median(x))
    scale = 1.4826 * float(np.median(np.abs(x - center)))
    return np.clip(x, center - k * scale, center + k * scale) if scale > 0 else x


def mean_interval(values, level: float = LEVEL) -> Estimate:
    """The mean of positive per-repeat values (MSEs, seconds) with its interval."""
    lm, var, n = _log_term(values)
    return _combine([(lm, var, n, 1)], level)


def excess_interval(values, floor: float, level: float = LEVEL) -> Estimate:
    """The expected error of a method over the reference's own expected error ``floor``.

    ``values`` are the per-repeat errors measured against the (noisy) reference; their mean
    overstates the method's error by ``floor``. The estimate is ``mean - floor`` with the
    interval of the mean shifted by the floor. Where the interval's lower end does not clear
    the floor, the method's error cannot be told from the reference's noise: the result is
    an upper bound (:attr:`Estimate.bound`: value = hi = the interval's upper end minus the
    floor, lo = 0), never a negative or NaN error. The cure is a better reference.
    """
    x = np.asarray(values, np.float64)
    raw = mean_interval(x, level)
    floor = float(floor)
    value = float(x.mean()) - floor
    if raw.known and raw.lo - floor > 0:
        return Estimate(value, raw.lo - floor, raw.hi - floor, raw.n, level)
    if not raw.known and value > 0:            # one run: no interval, the point estimate
        return Estimate(value, float("nan"), float("nan"), raw.n, level)
    upper = (raw.hi if raw.known else float(x.mean())) - floor
    upper = max(upper, 0.0)
    return Estimate(upper, 0.0, upper, raw.n, level, bound=True)


def ratio_interval(numerators: list, denominators: list, level: float = LEVEL) -> Estimate:
    """prod(mean of each numerator list) / prod(mean of each denominator list)."""
    terms = [(*_log_term(v), 1) for v in numerators] + \
            [(*_log_term(v), -1) for v in denominators]
    return _combine(terms, level)


def efficiency_ratio(mse_a, seconds_a, mse_b, seconds_b, level: float = LEVEL) -> Estimate:
    """Efficiency of A over B, (1 / (MSE_A T_A)) / (1 / (MSE_B T_B)), from per-repeat values
    (expected MSE and mean time per repeat of each)."""
    return ratio_interval([mse_b, seconds_b], [mse_a, seconds_a], level)


def verdict(a: str, b: str, ratio: Estimate, quantity: str = "efficient") -> str:
    """'A is more efficient than B by x (95% CI lo-hi)' when the interval of A / B excludes
    1; otherwise 'A and B are not distinguishable at this budget'."""
    if ratio.excludes(1.0):
        if ratio.value >= 1:
            return f"{a} is more {quantity} than {b} by {ratio.text()}x"
        inverse = Estimate(1 / ratio.value, 1 / ratio.hi, 1 / ratio.lo, ratio.n, ratio.level)
        return f"{b} is more {quantity} than {a} by {inverse.text()}x"
    if not math.isfinite(ratio.value):
        return (f"{a} and {b} cannot be compared at this budget: an error is below the "
                f"reference's own noise (a better reference is needed)")
    why = (f"{ratio.level:.0%} CI {ratio.lo:.3g}-{ratio.hi:.3g} contains 1" if ratio.known
           else f"{ratio.n} run gives no interval")
    return (f"{a} and {b} are not distinguishable at this budget (ratio {ratio.value:.3g}, "
            f"{why})")
