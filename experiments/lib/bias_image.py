"""Agreement of an estimator with a reference over the whole image: the bias test of a cell
whose blocks are ruled by heavy tails.

Where rare large values rule the variance of many blocks (:func:`.bias.tail_share`), the
per-block and pooled tests of :mod:`.bias` lose their size: a block that missed its
fireflies has its mean and its variance both low, and the pooled test weights such a block
the most. Over the whole image the same tails are many: the sum of the image's varying
pixels, per channel, is a sum of thousands of pixel-renders, and its t statistic keeps its
size as long as no single pixel-render holds much of its variance.

The statistic, per channel: t = (S_a - S_b) / sqrt(V_a + V_b), S the sum over the varying
pixels of a side's mean (a side's sets of renders combined by their samples, as in
:func:`.bias.side_of_halves`), V its variance, with Welch-Satterthwaite degrees of freedom
over its terms. V is read, by the side's variance kind:

* ``moments``: from each render's own per-pixel variance, which its samples' moments
  state (thousands of samples per pixel where a few renders' spread has two degrees of
  freedom), the degrees of freedom from how sure each is (their fourth moments:
  :func:`.jobs.variance_of_variance`);
* ``pixels``: from the pixels' spread over each set's renders;
* ``renders``: from the spread of each set's image sums over its renders.

Every pixel weighs the same (weights from either side's variances would follow its tails).
Its size holds where the sums are close to normal and their variance is known. A side of
spread terms (``pixels``, ``renders``) says neither where one pixel of one render holds
more than :data:`MAX_TERM_SHARE` of the pixels' variance of V_a + V_b
(:attr:`ImageTest.top`; read from the pixels also where V is the renders', whose few terms
say nothing of the tails); a side of ``moments`` where its variance has fewer than
:data:`MIN_DOF` degrees of freedom (rare large samples rule a pixel's moments: its
fourth moment makes its variance unsure, and the sum is far from normal). There, or where
not even a bias of 100% would be detected, the cell is untestable. Measured size and
power: docs/methodology.md.

What it cannot see: a bias that keeps the image's sum (energy moved between pixels), and a
tail that no render of the cell sampled.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from . import bias

#: Largest share of the statistic's variance one term may hold (:attr:`ImageTest.top`):
#: above it the image test's size is not known and the cell is untestable.
MAX_TERM_SHARE = 0.15
#: Fewest Welch-Satterthwaite degrees of freedom of a ``moments`` side's variance: below
#: them the image test's size is not known and the cell is untestable.
MIN_DOF = 30
#: Largest skewness (third cumulant over the variance to the power 3/2) of a ``moments``
#: side's image sum: above it the sum is far from normal (rare bright samples that most
#: renders miss: its typical value is low, and so is its variance) and the cell is
#: untestable.
MAX_SKEW = 0.15
#: Normal quantile over the critical value at which the image test's stated power
#: (:attr:`ImageTest.detectable`) puts the expected statistic: 0.95 one-sided, not the
#: block test's 0.9 (:data:`.bias.POWER_Z`). The image test serves heavy-tailed blocks,
#: and there its statistic spreads wider than its variance says: on phong_highlight
#: fresh draws of `path` at the run's counts put 2 of 20 unscaled ones under p 0.011 and
#: detected the 0.9 margin's bias (0.64%) in 31 and 32 of 40, not 36; this margin's
#: (0.68%) in 38 of 40, and half of it in 8 (tests/test_suite_bias_plugins.py).
POWER_Z = 1.6449


@dataclass(frozen=True)
class Sums:
    """One side's image sum per channel, its variance and the Welch-Satterthwaite
    denominator of its terms."""
    total: np.ndarray
    var: np.ndarray
    dof_part: np.ndarray
    top: np.ndarray      # the largest pixel-render term
    terms: np.ndarray    # the sum of the pixel-render terms (``var`` but for ``renders``)
    spread: bool = True  # the terms are spreads over renders (else each render's own)
    third: np.ndarray | float = 0.0   # its third cumulant (each render's own; 0: unknown)

    def scaled(self, factor: float) -> "Sums":
        f2 = factor * factor
        return Sums(self.total * factor, self.var * f2, self.dof_part * f2 * f2,
                    self.top * f2, self.terms * f2, self.spread, self.third * f2 * factor)

    @property
    def skew(self) -> np.ndarray:
        """Skewness of the sum per channel (0 where its third cumulant is unknown)."""
        return np.abs(self.third) / np.maximum(self.var, 1e-300) ** 1.5

    @property
    def dof(self) -> np.ndarray:
        """Welch-Satterthwaite degrees of freedom of ``var``, per channel."""
        return np.square(self.var) / np.maximum(self.dof_part, 1e-300)


def side_sums(sets, samples, varying: np.ndarray, variance: str, own=None) -> Sums:
    """:class:`Sums` of a side made of independent ``sets`` of renders ((k >= 2, H, W, C)
    each), combined by ``samples`` (each set's samples per pixel in all); ``variance``
    ``moments`` reads ``own``: per set, (the variance of each render's pixel means, how
    sure each is, their third cumulants), (k, H, W, C) each."""
    shares = np.asarray(samples, np.float64)
    shares = shares / shares.sum()
    if variance == "moments":
        return _own_sums(sets, shares, varying, own)
    total = var = dof_part = top = spread_sum = 0.0
    for share, images in zip(shares, sets):
        images = np.where(varying, np.asarray(images, np.float64), 0.0)
        k = images.shape[0]
        scale = share * share / (k * (k - 1))
        terms = np.square(images - images.mean(axis=0)) * scale
        top = np.maximum(top, terms.max(axis=(0, 1, 2)))
        per_pixel = terms.sum(axis=0)
        spread_sum = spread_sum + per_pixel.sum(axis=(0, 1))
        if variance == "pixels":
            var = var + per_pixel.sum(axis=(0, 1))
            dof_part = dof_part + (np.square(per_pixel) / (k - 1)).sum(axis=(0, 1))
        else:
            sums = images.sum(axis=(1, 2))
            spread = (np.square(sums - sums.mean(axis=0)) * scale).sum(axis=0)
            var = var + spread
            dof_part = dof_part + np.square(spread) / (k - 1)
        total = total + share * images.mean(axis=0).sum(axis=(0, 1))
    return Sums(total, var, dof_part, top, spread_sum)


def _own_terms(own, shares, varying: np.ndarray) -> tuple:
    """Per pixel and channel, the terms of a side's variance from its renders' own pixel
    variances ``v`` and their variances ``vv`` (``own``, per set, (k, H, W, C) each), their
    Welch-Satterthwaite parts and their third cumulants ``k3``, summed over the renders: a
    render's term is c v with c = share^2 / k^2, its part (c v)^2 / nu = c^2 vv / 2
    (Var(v) = 2 v^2 / nu), its third cumulant (share / k)^3 k3."""
    var = dof_part = third = 0.0
    for share, (v, vv, k3) in zip(shares, own):
        v, vv, k3 = (np.where(varying, np.asarray(x, np.float64), 0.0) for x in (v, vv, k3))
        c = share * share / v.shape[0] ** 2
        var = var + c * v.sum(axis=0)
        dof_part = dof_part + 0.5 * c * c * vv.sum(axis=0)
        third = third + (share / v.shape[0]) ** 3 * k3.sum(axis=0)
    return var, dof_part, third


def _own_sums(sets, shares, varying: np.ndarray, own) -> Sums:
    """:func:`side_sums` from the renders' own pixel variances (:func:`_own_terms`)."""
    var, dof_part, third = _own_terms(own, shares, varying)
    total = sum(share * np.where(varying, np.asarray(images, np.float64), 0.0).mean(
        axis=0).sum(axis=(0, 1)) for share, images in zip(shares, sets))
    return Sums(total, var.sum(axis=(0, 1)), dof_part.sum(axis=(0, 1)),
                var.max(axis=(0, 1)), var.sum(axis=(0, 1)), spread=False,
                third=third.sum(axis=(0, 1)))


def own_tail_share(own, samples, varying: np.ndarray, block: int = bias.BLOCK) -> float:
    """Share of the blocks with varying pixels whose variance, read from the renders' own
    samples (``own`` and ``samples`` as in :func:`side_sums`; the images padded to
    ``block``), has fewer than :data:`MIN_DOF` Welch-Satterthwaite degrees of freedom in
    some channel: blocks where rare large samples rule the pixels' moments. It sees the
    tails that the spread of a few renders misses (:func:`.bias.tail_share`: its block
    ruled by one pixel of one render): a block whose renders all missed them, or all
    caught one."""
    shares = np.asarray(samples, np.float64) / np.sum(samples)
    var, dof_part = (bias.block_sum(x, block) for x in _own_terms(own, shares, varying)[:2])
    used = np.any(var > 0, axis=-1)
    if not used.any():
        return 0.0
    few = (var > 0) & (np.square(var) < MIN_DOF * np.maximum(dof_part, 1e-300))
    return float(np.sum(np.any(few, axis=-1) & used) / np.sum(used))


@dataclass(frozen=True)
class ImageTest:
    """Result of :func:`compare`, per channel."""
    delta: np.ndarray      # relative difference of the image sums, a over b, less 1
    t: np.ndarray
    dof: np.ndarray
    p: np.ndarray
    alpha: float
    top: float             # largest single term of a side of spreads, as a share of the
                           # variance (any channel; 0 where neither side is of spreads)
    detectable: float      # smallest uniform relative bias found about 90% of the time
    own_dof: float = math.inf   # fewest degrees of freedom of a side of ``moments``
    own_skew: float = 0.0       # largest skewness of a side of ``moments``

    @property
    def size_holds(self) -> bool:
        """Whether the statistic's variance is known and the sum close to normal
        (:data:`MAX_TERM_SHARE`, :data:`MIN_DOF`, :data:`MAX_SKEW`)."""
        return self.top <= MAX_TERM_SHARE and self.own_dof >= MIN_DOF and \
            self.own_skew <= MAX_SKEW

    @property
    def testable(self) -> bool:
        """Whether its size holds (:attr:`size_holds`) and it has power at all (a bias of
        100% detected)."""
        return self.size_holds and bool(np.isfinite(self.detectable))

    @property
    def passed(self) -> bool:
        return bool(self.p.min() > self.alpha)


def _statistic(a: Sums, b: Sums, rounding: float):
    se2 = a.var + b.var + np.square(rounding * b.total)
    t = (a.total - b.total) / np.sqrt(np.maximum(se2, 1e-300))
    dof = np.square(se2) / np.maximum(a.dof_part + b.dof_part, 1e-300)
    return t, np.maximum(dof, 1.0), se2


def compare(a: Sums, b: Sums, alpha: float, rounding: float = bias.ROUNDING) -> ImageTest:
    """The image test of side ``a`` against side ``b`` at per-channel level ``alpha``."""
    t, dof, se2 = _statistic(a, b, rounding)
    spread = [x.top for x in (a, b) if x.spread]
    top = float(np.max(np.max(spread, axis=0) / np.maximum(a.terms + b.terms, 1e-300))) \
        if spread else 0.0
    own_dof = min([float(x.dof.min()) for x in (a, b) if not x.spread], default=math.inf)
    own_skew = max([float(x.skew.max()) for x in (a, b) if not x.spread], default=0.0)
    delta = (a.total - b.total) / np.where(b.total != 0, b.total, np.inf)
    common = dataclasses.replace(a, total=b.total)     # no bias: a's sum is b's

    def test(x, y):
        return _statistic(x, y, rounding)[:2]
    return ImageTest(delta, t, dof, 2.0 * stats.t.sf(np.abs(t), dof), alpha, top,
                     bias.detectable(test, common, b, alpha, POWER_Z), own_dof, own_skew)
