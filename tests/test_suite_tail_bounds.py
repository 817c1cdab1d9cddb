"""An efficiency whose error one pixel of one render rules is a bound, not an interval
(experiments/lib/studies/suite errors.ruled, errors.without_top, ratios._tail_bound).

A cell's expected relMSE E is the mean of its renders' per-pixel terms (each pixel's
variance of its mean over the reference squared). Where one pixel of one render holds most
of E (a caustic firefly in one of three renders of Mitsuba's rough-dielectric render test:
`bsdf+nee` over `path`, one estimator, 2.63 [0.69, 10]; on its environment-map test
168 [24, 1180]) the interval says nothing. That error is at least its estimate without the
term, so the efficiency has a bound on that side. Synthetic cells here: per-pixel terms
of three renders, light-tailed, and where a firefly lands one pixel of one render
thousands of times its usual term."""
from __future__ import annotations

import math

import numpy as np
import pytest

from experiments.lib.studies.suite import analysis as A
from experiments.lib.studies.suite import ratios
from experiments.lib.studies.suite import errors as E

PIXELS, REPEATS, TRIALS = 400, 3, 400
#: A pixel's usual term and a firefly's, as a multiple of the image's usual E.
FIREFLY = 3000.0


def runs(rng, scale: float = 1.0, firefly: bool = False) -> A.Runs:
    """Three renders' per-pixel terms (gamma, mean ``scale`` x 1e-3) with their own
    variances (10% of each term, squared); ``firefly``: one pixel of one render
    :data:`FIREFLY` times the usual E (its own variance as large as itself squared)."""
    maps = [scale * 1e-3 * rng.gamma(4.0, 0.25, PIXELS) for _ in range(REPEATS)]
    tails = [(0.1 * m) ** 2 for m in maps]
    if firefly:
        r, p = rng.integers(REPEATS), rng.integers(PIXELS)
        maps[r][p] = FIREFLY * scale * 1e-3
        tails[r][p] = maps[r][p] ** 2
    costs = tuple(1.0 + 0.01 * rng.standard_normal(REPEATS))
    return A.Runs(256, (0.0,) * REPEATS, (), (), tuple(256.0 * c for c in costs),
                  expected=E.pooled(maps, tails), costs=((16, costs), (256, costs)),
                  each=tuple(float(m.mean()) for m in maps), top=E.top_share(maps),
                  rest=E.without_top(maps, tails))


def test_top_share_and_the_rest_by_hand():
    maps = [np.array([1.0, 1.0]), np.array([1.0, 7.0])]
    assert E.top_share(maps) == pytest.approx(0.7)
    value, _ = E.without_top(maps)
    assert value == pytest.approx(3.0 / 4)              # (1 + 1 + 1 + 0) / 4 terms
    assert E.pooled(maps)[0] == pytest.approx(10.0 / 4)


def test_a_firefly_in_the_baseline_makes_a_lower_bound_that_holds():
    """One estimator, the baseline's renders with a firefly: every ratio is a lower bound
    ('>'), below the true 1 in at least 95% of the trials and informative (above 0.5 in
    most); the mean-based interval would span over a factor 10."""
    rng = np.random.default_rng(3)
    values, widths = [], []
    for _ in range(TRIALS):
        a, b = runs(rng), runs(rng, firefly=True)
        assert E.ruled(b) and not E.ruled(a)
        r = ratios.efficiency(a, b, 0.0)
        assert r.side == ">" and r.why == ratios.TAIL and not r.less()
        values.append(r.value)
        loose = E.efficiency(a, b)
        widths.append(loose.hi / loose.lo)
    values = np.array(values)
    assert np.mean(values > 1.0) <= 0.05, np.mean(values > 1.0)
    assert np.median(values) > 0.5
    assert np.median(widths) > 10


def test_light_tailed_cells_keep_their_interval():
    """The negative control: no firefly, the ratio an interval (never a bound) that holds
    the true 1 in about 95% of the trials (at least 90% of 200), and a real factor of 3
    found in every trial."""
    rng = np.random.default_rng(4)
    held = 0
    for _ in range(200):
        a, b = runs(rng), runs(rng)
        assert not (E.ruled(a) or E.ruled(b))
        r = ratios.efficiency(a, b, 0.0)
        assert r.side == ""
        held += r.est.lo < 1 < r.est.hi
        assert ratios.efficiency(a, runs(rng, scale=3.0), 0.0).greater()
    assert held >= 180, held


def test_which_side_the_bound_is_on():
    """A ruled numerator gives an upper bound, both ruled nothing, a cell over itself its
    interval."""
    rng = np.random.default_rng(5)
    a, b = runs(rng, firefly=True), runs(rng)
    up = ratios.efficiency(a, b, 0.0)
    assert up.side == "<" and up.value < 1.5 and "rules" in up.text()
    both = ratios.efficiency(a, runs(rng, firefly=True), 0.0)
    assert both.side == "?" and "one pixel of one render" in both.text()
    assert ratios.efficiency(a, a, 0.0).side == ""
    assert math.isfinite(up.value)
