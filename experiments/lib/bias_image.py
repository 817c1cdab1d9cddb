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
:func:`.bias.side_of_halves`), V its variance (``pixels``: the pixels' spread over each
set's renders; ``renders``: the spread of each set's image sums over its renders), with
Welch-Satterthwaite degrees of freedom over the terms. Every pixel weighs the same (weights
from either side's variances would follow its tails). Its size holds where the sums are
close to normal: where no single pixel of one render holds more than
:data:`MAX_TERM_SHARE` of the pixels' variance of V_a + V_b (:attr:`ImageTest.top`; read
from the pixels also where V is the renders', whose few terms say nothing of the tails);
above that, or where not even a bias of 100% would be detected, the cell is untestable.
Measured size and power: docs/methodology.md.

What it cannot see: a bias that keeps the image's sum (energy moved between pixels), and a
tail that no render of the cell sampled.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from . import bias

#: Largest share of the statistic's variance one term may hold (:attr:`ImageTest.top`):
#: above it the image test's size is not known and the cell is untestable.
MAX_TERM_SHARE = 0.15


@dataclass(frozen=True)
class Sums:
    """One side's image sum per channel, its variance and the Welch-Satterthwaite
    denominator of its terms."""
    total: np.ndarray
    var: np.ndarray
    dof_part: np.ndarray
    top: np.ndarray      # the largest pixel-render term
    terms: np.ndarray    # the sum of the pixel-render terms (``var`` where ``pixels``)

    def scaled(self, factor: float) -> "Sums":
        f2 = factor * factor
        return Sums(self.total * factor, self.var * f2, self.dof_part * f2 * f2,
                    self.top * f2, self.terms * f2)


def side_sums(sets, samples, varying: np.ndarray, variance: str) -> Sums:
    """:class:`Sums` of a side made of independent ``sets`` of renders ((k >= 2, H, W, C)
    each), combined by ``samples`` (each set's samples per pixel in all)."""
    shares = np.asarray(samples, np.float64)
    shares = shares / shares.sum()
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


@dataclass(frozen=True)
class ImageTest:
    """Result of :func:`compare`, per channel."""
    delta: np.ndarray      # relative difference of the image sums, a over b, less 1
    t: np.ndarray
    dof: np.ndarray
    p: np.ndarray
    alpha: float
    top: float             # largest single term's share of the variance (any channel)
    detectable: float      # smallest uniform relative bias found about 90% of the time

    @property
    def testable(self) -> bool:
        """Whether its size holds (:data:`MAX_TERM_SHARE`) and it has power at all (a
        bias of 100% detected)."""
        return self.top <= MAX_TERM_SHARE and bool(np.isfinite(self.detectable))

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
    top = float(np.max(np.maximum(a.top, b.top) / np.maximum(a.terms + b.terms, 1e-300)))
    delta = (a.total - b.total) / np.where(b.total != 0, b.total, np.inf)
    common = Sums(b.total, a.var, a.dof_part, a.top, a.terms)     # no bias: a's sum is b's

    def test(x, y):
        return _statistic(x, y, rounding)[:2]
    return ImageTest(delta, t, dof, 2.0 * stats.t.sf(np.abs(t), dof), alpha, top,
                     bias.detectable(test, common, b, alpha))
