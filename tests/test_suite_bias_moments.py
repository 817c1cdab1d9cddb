"""The image test's variance from each render's own samples (experiments/lib/bias_image.py,
variance ``moments``), on synthetic renders of known law at the suite's film (48x36).

Where a few bright pixels of light tails rule the image sum's variance (veach_mis' light
silhouettes and highlights), the spread of three renders reads each pixel's variance with
two degrees of freedom and one pixel of one render holds more than
``bias_image.MAX_TERM_SHARE`` of it: untestable. Each render's own samples state the same
variance with thousands of degrees of freedom, and their fourth moments say how sure it is:
tested, its size and power measured here. Samples of infinite variance are the negative
control: their moments' degrees of freedom stay under ``bias_image.MIN_DOF``.
"""
from __future__ import annotations

import math

import numpy as np

from experiments.lib import bias_image
from experiments.lib.jobs import third_of_mean, variance_of_variance
from experiments.lib.studies.suite import bias_test as suite_bias
from test_suite_bias import ALPHA, SEEDS, C, FakeMethod, H, W, renders


def own_renders(rng, mu, k, spp, factor=1.0):
    """k renders of ``spp`` normal samples per pixel (sd = mu): (their means, spp, each
    render's own variance of its means s^2 / spp, how sure it is: 2 s^4 / ((spp-1) spp^2),
    its third cumulant: 0)."""
    out = []
    for _ in range(k):
        mean = factor * (mu + mu / math.sqrt(spp) * rng.standard_normal(mu.shape))
        s2 = np.square(factor * mu) * rng.chisquare(spp - 1, mu.shape) / (spp - 1)
        out.append((mean, spp, s2 / spp, 2.0 * s2 * s2 / ((spp - 1) * spp * spp),
                    np.zeros_like(mean)))
    return out


def bright_cell(rng, factor=1.0, own=True, unstated=0):
    """Three pixels of mean 100 and twelve of 20 (per-sample sd = mean) among pixels of
    0.05-1: the three hold most of the image sum's variance; the method's side 3 renders
    of 16 spp and 3 of 1024, the reference 32 chunks of 256. ``own``: the renders state
    their variances (but the first ``unstated`` of the larger budget)."""
    mu = rng.uniform(0.05, 1.0, (H, W, C))
    for count, value in ((3, 100.0), (12, 20.0)):
        mu[rng.choice(H, count, replace=False), rng.choice(W, count, replace=False)] = value
    budgets = [own_renders(rng, mu, 3, 16, factor), own_renders(rng, mu, 3, 1024, factor)]
    if not own:
        budgets = [[r[:2] for r in b] for b in budgets]
    budgets[1][:unstated] = [r[:2] + (None, None, None) for r in budgets[1][:unstated]]
    return suite_bias.check_cell(FakeMethod(), budgets, renders(rng, mu, 32, 256), True, True,
                                 FakeMethod("path"), ALPHA)


def test_bright_pixels_of_light_tails_are_tested_by_their_own_variances():
    """Size: no right cell flagged in 20 seeds at the run's level; power: a 3% darkening
    flagged in at least 18 of 20 (the stated detectable bias, 1.5%, under 2%). Control: the
    same renders without their own variances are untestable in every seed (one pixel of
    one render holds 16-39% of the spread's variance)."""
    flagged = found = 0
    for seed in range(SEEDS):
        right = bright_cell(np.random.default_rng(seed))
        assert right.scope == "image" and right.variance == "moments", right
        assert right.status != "untestable" and right.own_dof >= bias_image.MIN_DOF
        assert right.detectable < 0.02, right.detectable
        flagged += right.biased is True
        found += bright_cell(np.random.default_rng(100 + seed), 0.97).biased is True
        spread = bright_cell(np.random.default_rng(seed), own=False)
        assert spread.status == "untestable" and spread.variance == "pixels"
        assert spread.term_share > bias_image.MAX_TERM_SHARE
    assert flagged == 0 and found >= 0.9 * SEEDS, (flagged, found)


def pareto_renders(rng, mu, k, spp, a):
    """k renders of ``spp`` samples per pixel of a Pareto law of index ``a`` scaled to mean
    mu, with their own variances read from their samples' raw moments (as ``vr_moments``
    gives them)."""
    out = []
    for _ in range(k):
        x = (rng.pareto(a, (spp,) + mu.shape) + 1.0) * mu * (a - 1) / a
        m1, m2, m3, m4 = (np.mean(x ** p, axis=0) for p in (1, 2, 3, 4))
        out.append((m1, spp, np.maximum(m2 - m1 * m1, 0.0) / (spp - 1),
                    variance_of_variance(m1, m2, m3, m4, spp), third_of_mean(m1, m2, m3, spp)))
    return out


def test_infinite_variance_is_untestable_by_its_own_moments_too(monkeypatch):
    """Pareto samples of index 1.2 (infinite variance: uniform sampling of rough glass is of
    this kind): the renders' own variances have 2-14 degrees of freedom (a few samples
    rule each pixel's moments), under bias_image.MIN_DOF in every seed: untestable.
    Negative control: with that gate and the skewness gate off the t test flags right cells
    (4 of 20 measured)."""
    def cells():
        out = []
        for seed in range(SEEDS):
            rng = np.random.default_rng(seed)
            mu = rng.uniform(0.05, 1.0, (H, W, C))
            budgets = [pareto_renders(rng, mu, 3, 16, 1.2), pareto_renders(rng, mu, 3, 64, 1.2)]
            out.append(suite_bias.check_cell(FakeMethod(), budgets, renders(rng, mu, 8, 128),
                                             True, True, FakeMethod("path"), ALPHA))
        return out
    gated = cells()
    assert all(c.status == "untestable" and c.reason == "heavy_tails" and
               c.variance == "moments" and c.own_dof < bias_image.MIN_DOF for c in gated)
    monkeypatch.setattr(bias_image, "MAX_SKEW", math.inf)
    assert all(c.status == "untestable" for c in cells())     # the dof gate alone
    monkeypatch.setattr(bias_image, "MIN_DOF", 0)
    assert sum(c.biased is True for c in cells()) >= 2


def test_renders_without_their_own_variances_keep_the_spread():
    """A render that does not state its variance (a QMC sampler's, a split job's without
    its samples' moments) leaves the cell's image test on the spread over the renders."""
    got = bright_cell(np.random.default_rng(5), unstated=1)
    assert got.scope == "image" and got.variance == "pixels"
    assert bright_cell(np.random.default_rng(5)).variance == "moments"


#: Rows and columns of the hot pixels: one in every other 8x8 block.
HOT = (slice(0, None, 8), slice(0, None, 16))


def test_blocks_whose_renders_all_caught_one_rare_sample_are_heavy_tailed():
    """In half of the blocks one pixel's samples are all 0 but one, in every render alike
    (within 0.1%): the renders agree (no render rules the spread: bias.tail_share is 0)
    but each pixel's variance rests on one sample (its own moments say so:
    bias_image.own_tail_share), so the cell is tested by its image sum, where without its
    own variances it would be tested per block."""
    rng = np.random.default_rng(6)
    mu = rng.uniform(0.2, 1.0, (H, W, C))

    def budget(spp):
        x = mu + mu * rng.standard_normal((3, spp, H, W, C))
        x[:, :, HOT[0], HOT[1]] = 0.0                  # a hot pixel in half the blocks
        x[:, 0, HOT[0], HOT[1]] = 100.0 * spp * rng.uniform(0.999, 1.001, (3, 5, 3, C))
        m1, m2, m3, m4 = (np.mean(x ** p, axis=1) for p in (1, 2, 3, 4))
        return [(m1[i], spp, np.maximum(m2[i] - m1[i] ** 2, 0.0) / (spp - 1),
                 variance_of_variance(m1[i], m2[i], m3[i], m4[i], spp),
                 third_of_mean(m1[i], m2[i], m3[i], spp)) for i in range(3)]
    budgets = [budget(16), budget(64)]
    chunks = renders(rng, mu, 8, 128)
    chunks[:, HOT[0], HOT[1]] = 100.0
    own = suite_bias.check_cell(FakeMethod(), budgets, chunks, True, True, FakeMethod("path"),
                                ALPHA)
    spread = suite_bias.check_cell(FakeMethod(), [[r[:2] for r in b] for b in budgets], chunks,
                                   True, True, FakeMethod("path"), ALPHA)
    assert spread.scope == "blocks" and spread.tail_share <= suite_bias.TAILS_SHARE
    assert own.scope == "image" and own.tail_share > suite_bias.TAILS_SHARE, own


def test_a_known_variance_too_large_for_any_bias_is_no_power_not_heavy_tails():
    """Light tails, but a per-sample spread 400 times each pixel's mean: the renders' own
    variances are sure (thousands of degrees of freedom) and the image sum close to
    normal, but not even a 100% bias would be found: untestable for want of power, not
    for heavy tails (the report counts them apart)."""
    rng = np.random.default_rng(7)
    mu = rng.uniform(0.05, 1.0, (H, W, C))
    for count, value in ((3, 100.0), (12, 20.0)):
        mu[rng.choice(H, count, replace=False), rng.choice(W, count, replace=False)] = value

    def noisy(k, spp):
        out = []
        for _ in range(k):
            mean = mu + 400.0 * mu / math.sqrt(spp) * rng.standard_normal(mu.shape)
            s2 = np.square(400.0 * mu) * rng.chisquare(spp - 1, mu.shape) / (spp - 1)
            out.append((mean, spp, s2 / spp, 2.0 * s2 * s2 / ((spp - 1) * spp * spp),
                        np.zeros_like(mean)))
        return out
    got = suite_bias.check_cell(FakeMethod(), [noisy(3, 16), noisy(3, 1024)],
                                renders(rng, mu, 32, 256), True, True, FakeMethod("path"),
                                ALPHA)
    assert got.scope == "image" and got.variance == "moments", got
    assert got.own_dof >= bias_image.MIN_DOF and not math.isfinite(got.detectable)
    assert got.status == "untestable" and got.reason == "no_power"
