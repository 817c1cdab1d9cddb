"""Agreement of an estimator with a reference, per pixel block and over the image, with its power.

The statistics of every bias test of the project: the suite's (:mod:`.studies.suite_bias`)
and the tests' (tests/_blocks.py, tests/test_unbiased.py). Two sides, ``a`` (the estimator
under test) and ``b`` (the reference), each independent renders (different seeds) of one
scene, agree when no block and no channel differs by more than its noise explains, and no
channel does over the whole image:

* **per block** (``block`` x ``block`` pixels, per channel): Welch's t-test of the two
  block means, with both sides' variances. A biased estimator can keep the image mean
  (energy moved between pixels); only a per-block test sees that.
* **pooled** (per channel): the best linear estimate of a uniform relative difference from
  all blocks, each weighted by its information (``mu / V``: its mean over the variance of
  the difference), and its z statistic. Each half of a side's renders is weighted by the
  other half's blocks, so that the weights and the variance do not follow the noise they
  are applied to (a skewed block mean that falls low has its variance underestimated too:
  the statistic would drift). A bias spread over the image (a missing factor, a clamp of
  large weights) moves every block a little; this test sees it with a standard error about
  ``sqrt(blocks)`` times smaller than a block's.

Pixels that are the same in every render of both sides (to :data:`ROUNDING`; a directly
visible constant environment or emitter) carry no estimate: they are left out of both
tests, so that the detectable bias is that of the estimated part of the image.

Variance. ``variance="pixels"``: the variance of a mean over pixels is the sum of the
pixels' own variances over the renders, with Welch-Satterthwaite degrees of freedom (about
``block^2 (renders - 1)`` for a block), so the tests need no large critical values even for
few renders. It assumes that the pixels of one render are independent: Mitsuba's
``independent`` sampler with a ``box`` reconstruction filter (a wider filter splats a
sample into several pixels; a QMC sampler correlates them). ``variance="renders"``: the
spread of the block means over the renders (``renders - 1`` degrees of freedom), valid for
any sampler whose renders are independent randomizations (seeds), but with few renders
its critical values are large.

A side is either one set of renders of one sample count (:func:`side_of_renders`: its
halves are the even and the odd renders) or two independent sets (:func:`side_of_halves`:
e.g. a method's equal-spp and equal-time repeats, combined by their sample counts).

Power. :attr:`Agreement.detectable` is the smallest uniform relative bias (side ``a``
scaled by ``1 + x`` and by ``1 - x``) at which the expected statistic of the more
sensitive of the two tests reaches its critical value plus :data:`POWER_Z` (a detection
probability of about 90%), from the measured means and variances.

Size. The caller gives the per-comparison levels, e.g. from :func:`sidak` over every
comparison of its family. Heavy-tailed estimators (uniform or cosine sampling of a narrow
lobe, a BSDF-sampled small light) have no t-test of nominal size: their variance estimates
fall short in most seeds. :func:`tail_share` flags them: one pixel of one render holds
most of a block's squared deviations in many blocks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

BLOCK = 8
#: Relative float32 rounding of a film sum: its square (times the mean squared)
#: is added to every variance, so that constant pixels summed over different
#: sample counts compare equal.
ROUNDING = 1e-4
#: Normal quantile added to the critical value for :attr:`Agreement.detectable`
#: (a one-sided detection probability of 0.9).
POWER_Z = 1.2816
VARIANCES = ("pixels", "renders")
#: Fewest terms (varying pixels times renders less one) of a block that
#: :func:`tail_share` reads: with fewer, one of light-tailed (normal) deviations
#: holds most of their sum by chance (8 pixels of 3 renders: in 1.4e-4 of blocks;
#: 4 pixels: 3%; 1 pixel: always).
TAIL_TERMS = 16


def sidak(alpha: float, n: int) -> float:
    """Per-comparison level for a family-wise level ``alpha`` over ``n`` comparisons."""
    return 1.0 - (1.0 - alpha) ** (1.0 / n)


# ------------------------------------------------------------------ renders

@dataclass(frozen=True)
class Renders:
    """k independent renders of one scene, (k, H, W, C) float64."""
    images: np.ndarray

    @property
    def count(self) -> int:
        return self.images.shape[0]

    def scaled(self, factor: float) -> "Renders":
        """These renders multiplied by ``factor`` (a uniform bias)."""
        return Renders(self.images * factor)


def summarize(images: np.ndarray, block: int = BLOCK) -> Renders:
    """:class:`Renders` of (k, H, W, C) images (k >= 2; H, W multiples of ``block``)."""
    images = np.asarray(images, dtype=np.float64)
    if images.ndim != 4 or images.shape[0] < 2 or images.shape[1] % block \
            or images.shape[2] % block:
        raise ValueError(f"summarize: need (k >= 2, H, W, C) renders with H, W divisible by "
                         f"{block}, got {images.shape}")
    return Renders(images)


# ---------------------------------------------------------------- the tests

@dataclass(frozen=True)
class Blocks:
    """Block means of one side over the varying pixels, (blocks_y, blocks_x, C) each."""
    mean: np.ndarray     # mean over the renders and the block's varying pixels
    var: np.ndarray      # variance of that mean (estimated)
    dof: np.ndarray      # degrees of freedom of the variance estimate
    pixels: np.ndarray   # varying pixels in the block (0: the block is left out)
    variance: str = "pixels"   # how ``var`` was estimated (:data:`VARIANCES`)

    def scaled(self, factor: float) -> "Blocks":
        return Blocks(self.mean * factor, self.var * factor ** 2, self.dof, self.pixels,
                      self.variance)

    def with_mean(self, mean: np.ndarray) -> "Blocks":
        return Blocks(mean, self.var, self.dof, self.pixels, self.variance)


@dataclass(frozen=True)
class Side:
    """One side's :class:`Blocks` over all its renders, and over each half of them
    (even and odd renders: the pooled test weights one half by the other)."""
    full: Blocks
    halves: tuple
    #: each half's samples per pixel in all (None: equal)
    samples: tuple | None = None

    def scaled(self, factor: float) -> "Side":
        return Side(self.full.scaled(factor), tuple(h.scaled(factor) for h in self.halves),
                    self.samples)

    def level(self, tested: int) -> float:
        """The variance of half ``tested`` over the other half's (their samples' ratio)."""
        if not self.samples:
            return 1.0
        return float(self.samples[1 - tested]) / float(self.samples[tested])


def block_sum(x: np.ndarray, block: int) -> np.ndarray:
    """(..., H, W, C) -> (..., H // block, W // block, C) sums over block x block tiles."""
    *lead, h, w, c = x.shape
    return x.reshape(*lead, h // block, block, w // block, block, c).sum(axis=(-4, -2))


def _blocks(images: np.ndarray, varying: np.ndarray, block: int, variance: str) -> Blocks:
    k = images.shape[0]
    n = block_sum(varying.astype(np.float64), block)
    n1 = np.maximum(n, 1.0)
    mean = block_sum(np.where(varying, images.mean(axis=0), 0.0), block) / n1
    if variance == "pixels":
        pixel_var = np.where(varying, images.var(axis=0, ddof=1), 0.0)
        s, s4 = block_sum(pixel_var, block), block_sum(np.square(pixel_var), block)
        var = s / (k * np.square(n1))
        dof = np.square(s) / np.maximum(s4 / (k - 1), 1e-300)
    else:
        per_render = block_sum(np.where(varying, images, 0.0), block) / n1
        var = per_render.var(axis=0, ddof=1) / k
        dof = np.full(var.shape, float(k - 1))
    return Blocks(mean, var, np.maximum(dof, 1.0), n, variance)


def _side(r: Renders, varying: np.ndarray, block: int, variance: str) -> Side:
    return Side(_blocks(r.images, varying, block, variance),
                tuple(_blocks(r.images[h::2], varying, block, variance) for h in (0, 1)))


def _variances(a: Blocks, b: Blocks, rounding: float):
    """Both sides' variances with the rounding floor, their sum, Welch's dof."""
    floor = np.square(rounding * np.maximum(np.abs(a.mean), np.abs(b.mean))) / 2
    va, vb = a.var + floor, b.var + floor
    se2 = np.maximum(va + vb, 1e-300)
    dof = np.square(se2) / np.maximum(np.square(va) / a.dof + np.square(vb) / b.dof, 1e-300)
    return va, vb, se2, np.maximum(dof, 1.0)


def _common_mean(a: Blocks, b: Blocks, rounding: float) -> np.ndarray:
    """(m_a v_b + m_b v_a) / (v_a + v_b): the blocks' mean estimated from both sides
    (uncorrelated with m_a - m_b)."""
    va, vb, se2, _ = _variances(a, b, rounding)
    return (a.mean * vb + b.mean * va) / se2


def _block_test(a: Side, b: Side, rounding: float):
    """Welch t and its degrees of freedom per block and channel (0 and inf where the
    block has no varying pixel)."""
    _, _, se2, dof = _variances(a.full, b.full, rounding)
    used = b.full.pixels > 0
    t = np.where(used, (a.full.mean - b.full.mean) / np.sqrt(se2), 0.0)
    return t, np.where(used, dof, np.inf)


def _variance_of(tested: Blocks, other: Blocks, used: np.ndarray, level: float) -> Blocks:
    """The block variances the pooled test gives the tested half, with their dof: the
    other half's times ``level`` (:meth:`Side.level`, the ratio of their samples: halves
    of unequal samples, the suite's two budgets of 16 and 256 spp, differ 16x; taken as
    they are, the pooled statistic's spread was sqrt((16 + 1/16) / 2) = 2.8, unbiased
    cells flagged); for ``renders`` variances (2 dof for a half of 3 renders) the tested
    half's own. The weights are the other half's inverse variances, so with few dof its
    variances fall low exactly where the weights are high: they would understate the
    statistic's variance (by nu / (nu - 2) at nu dof, without bound at 2). Where tails
    are heavy a firefly in the tested half meets a variance that never saw it: such cells
    are withheld (:func:`tail_share`); docs/methodology.md has the measurement."""
    if other.variance == "renders":
        return tested
    return Blocks(tested.mean, other.var * level, other.dof, tested.pixels, other.variance)


def _pooled_test(a: Side, b: Side, rounding: float):
    """Per channel: the relative difference of ``a`` from ``b`` over the image, its
    statistic and degrees of freedom.

    Each half h of the renders (even, odd) is tested with weights from the other half:
    block j gets the weight w_j = mu_j / V'_j (mu the blocks' common mean, V' the
    variance of their difference, both from the other half), the best weights for a
    uniform relative bias, and z_h = sum_j w_j d_hj / sqrt(sum_j w_j^2 V_hj), d_h the
    difference of half h's block means and V_h its variance (:func:`_variance_of`: the
    other half's at half h's samples, or with few dof half h's own). Weights or a variance
    estimated from the data they are applied to would correlate with it (a skewed block
    mean that falls low has its variance underestimated too: the statistic drifts); this
    way each z_h has mean 0 under no bias, whatever the skew. z = (z_0 + z_1) / sqrt(2);
    the relative difference: sum_h sum_j w_hj d_hj / sum_h sum_j w_hj mu_hj.
    """
    z = num = scale = 0.0
    dofs = []
    used = b.full.pixels > 0
    for h in (0, 1):
        oa, ob = a.halves[1 - h], b.halves[1 - h]     # the other half: the weights
        ta, tb = a.halves[h], b.halves[h]             # the tested half
        _, _, se2_o, _ = _variances(oa, ob, rounding)
        w = np.where(used, _common_mean(oa, ob, rounding) / se2_o, 0.0)
        ta, tb = _variance_of(ta, oa, used, a.level(h)), _variance_of(tb, ob, used, b.level(h))
        va, vb, se2, _ = _variances(ta, tb, rounding)
        diff = (w * (ta.mean - tb.mean)).sum(axis=(0, 1))
        den = (np.square(w) * se2).sum(axis=(0, 1))
        z = z + diff / np.sqrt(np.maximum(den, 1e-300)) / np.sqrt(2.0)
        num = num + diff
        scale = scale + (w * _common_mean(ta, tb, rounding)).sum(axis=(0, 1))
        parts = (np.square(np.square(w) * va) / ta.dof
                 + np.square(np.square(w) * vb) / tb.dof).sum(axis=(0, 1))
        dofs.append(np.square(den) / np.maximum(parts, 1e-300))
    delta = num / np.where(scale != 0, scale, np.inf)
    return delta, z, np.maximum(np.minimum(*dofs), 1.0)


def _p(t, dof):
    return 2.0 * stats.t.sf(np.abs(t), dof)


def _crit(alpha, dof):
    return stats.t.isf(alpha / 2, dof)


def _unbiased(a: Side, b: Side, rounding: float):
    """Both sides with their means replaced by the common means (a case of no bias)."""
    def one(x, y):
        mu = _common_mean(x, y, rounding)
        return x.with_mean(mu), y.with_mean(mu)
    full = one(a.full, b.full)
    halves = [one(x, y) for x, y in zip(a.halves, b.halves)]
    return (Side(full[0], tuple(h[0] for h in halves), a.samples),
            Side(full[1], tuple(h[1] for h in halves), b.samples))


def detectable(test, a, b, alpha: float, z: float = POWER_Z) -> float:
    """Smallest x such that ``a`` scaled by 1 + x and by 1 - x both make the expected
    statistic of some comparison of ``test`` reach its critical value (at the measured
    degrees of freedom) plus ``z`` (:data:`POWER_Z`); inf if none does up to x = 1. ``a`` and ``b`` have
    the common means (no bias): scaling ``a`` scales its means and variances as a
    uniform relative bias would. ``test(a, b)`` gives (statistics, degrees of freedom);
    ``a.scaled(factor)`` the scaled side (:class:`Side`, or :class:`.bias_image.Sums`)."""
    crit = _crit(alpha, test(a, b)[1]) + z

    def margin(factor):
        return np.max(np.abs(test(a.scaled(factor), b)[0]) - crit)

    out = []
    for sign in (1.0, -1.0):
        top = 1.0 - 1e-9
        if margin(1.0 + sign * top) < 0:
            return np.inf
        lo, hi = 0.0, top
        for _ in range(24):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if margin(1.0 + sign * mid) >= 0 else (mid, hi)
        out.append(hi)
    return max(out)


@dataclass(frozen=True)
class Agreement:
    """Result of :func:`agree`: per block and channel, and per channel (pooled)."""
    t_blocks: np.ndarray      # (blocks_y, blocks_x, C) Welch t
    p_blocks: np.ndarray
    delta: np.ndarray         # (C,) pooled relative difference of a from b
    z_pooled: np.ndarray      # (C,) its statistic
    p_pooled: np.ndarray
    alpha_blocks: float
    alpha_pooled: float
    detectable_blocks: float  # smallest uniform bias the per-block test detects (~90%)
    detectable_pooled: float  # the same for the pooled test
    varying: int              # varying pixels (largest over the channels)

    @property
    def detectable(self) -> float:
        """Smallest uniform relative bias (brighter or darker) that one of the two tests
        detects about 90% of the time, from the measured variances."""
        return min(self.detectable_blocks, self.detectable_pooled)

    @property
    def flagged(self) -> np.ndarray:
        """(blocks_y, blocks_x) bool: blocks whose test rejects in some channel."""
        return np.any(self.p_blocks <= self.alpha_blocks, axis=-1)

    @property
    def passed(self) -> bool:
        return bool(self.p_blocks.min() > self.alpha_blocks
                    and self.p_pooled.min() > self.alpha_pooled)

    def describe(self) -> str:
        worst = int(np.argmin(self.p_blocks))
        by, bx, ch = np.unravel_index(worst, self.p_blocks.shape)
        pw = int(np.argmin(self.p_pooled))
        return (f"worst block (row {by}, column {bx}) channel {ch}: t = "
                f"{self.t_blocks.flat[worst]:.2f}, p = {self.p_blocks.flat[worst]:.2e} "
                f"(level {self.alpha_blocks:.2e}); pooled over {self.varying} varying pixels, "
                f"channel {pw}: relative difference {self.delta[pw]:+.4f}, z = "
                f"{self.z_pooled[pw]:.2f}, p = {self.p_pooled[pw]:.2e} (level "
                f"{self.alpha_pooled:.2e}); detectable uniform bias {self.detectable:.2%} "
                f"(blocks {self.detectable_blocks:.2%}, pooled {self.detectable_pooled:.2%})")


def varying_pixels(a: Renders, b: Renders, rounding: float = ROUNDING) -> np.ndarray:
    """(H, W, C) bool: pixels whose values differ between the renders (of either side,
    by more than the rounding), or between the sides. The others (a directly visible
    constant environment or emitter) hold no estimate and are left out."""
    first = a.images[0]
    tol = rounding * np.abs(first)
    return (np.any(np.abs(a.images - first) > tol, axis=0)
            | np.any(np.abs(b.images - first) > tol, axis=0))


def agree(a: Renders, b: Renders, alpha_blocks: float, alpha_pooled: float,
          block: int = BLOCK, variance: str = "pixels",
          rounding: float = ROUNDING) -> Agreement:
    """Per-block and pooled tests of renders ``a`` against ``b`` (see the module
    docstring), at per-comparison levels ``alpha_blocks`` and ``alpha_pooled``.
    Each side needs at least 4 renders (2 per half)."""
    if variance not in VARIANCES:
        raise ValueError(f"agree: unknown variance {variance!r}; valid choices are "
                         f"{', '.join(VARIANCES)}")
    if a.images.shape[1:] != b.images.shape[1:]:
        raise ValueError(f"agree: image shapes differ: {a.images.shape[1:]} and "
                         f"{b.images.shape[1:]}")
    if min(a.count, b.count) < 4:
        raise ValueError(f"agree: need at least 4 renders per side, got {a.count} and "
                         f"{b.count}")
    varying = varying_pixels(a, b, rounding)
    return compare(_side(a, varying, block, variance), _side(b, varying, block, variance),
                   varying, alpha_blocks, alpha_pooled, rounding)


# ------------------------------------------------------------ sides from sets of renders

def padded(images: np.ndarray, block: int = BLOCK) -> np.ndarray:
    """(k, H, W, C) renders padded with zeros to multiples of ``block`` (the padding is
    constant: :func:`varying_pixels` leaves it out of every test)."""
    images = np.asarray(images, dtype=np.float64)
    h, w = images.shape[1:3]
    pad = ((0, 0), (0, -h % block), (0, -w % block), (0, 0))
    return np.pad(images, pad) if any(p[1] for p in pad) else images


def combine(parts, weights) -> Blocks:
    """The weighted mean (weights summing to 1 after normalisation) of independent
    estimates of the same blocks, its variance and Welch-Satterthwaite dof."""
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    mean = sum(x * p.mean for x, p in zip(w, parts))
    terms = [x * x * p.var for x, p in zip(w, parts)]
    var = sum(terms)
    dof = np.square(var) / np.maximum(sum(np.square(t) / p.dof for t, p in zip(terms, parts)),
                                      1e-300)
    return Blocks(mean, var, np.maximum(dof, 1.0), parts[0].pixels, parts[0].variance)


def side_of_renders(images: np.ndarray, varying: np.ndarray, block: int = BLOCK,
                    variance: str = "pixels") -> Side:
    """One set of renders of one sample count (k >= 4): halves even and odd renders."""
    return _side(Renders(np.asarray(images, dtype=np.float64)), varying, block, variance)


def side_of_halves(halves, samples, varying: np.ndarray, block: int = BLOCK,
                   variance: str = "pixels") -> Side:
    """Two independent sets of renders (each (k >= 2, H, W, C) of one sample count), the
    whole their mean weighted by ``samples`` (each set's samples per pixel in all)."""
    parts = tuple(_blocks(np.asarray(h, dtype=np.float64), varying, block, variance)
                  for h in halves)
    return Side(combine(parts, samples), parts, tuple(samples))


def tail_share(halves, varying: np.ndarray, block: int = BLOCK, dominance: float = 0.5) -> float:
    """Share of the blocks and channels where one pixel of one render holds more than
    ``dominance`` of the squared deviations from the renders' mean over the block (in either
    set of ``halves``). About 0 for light tails (a block has ``block^2 (renders - 1)`` terms
    of like size); high where rare large values rule the variance estimates (heavy tails:
    most renders miss them, the estimate falls short and the t tests lose their size).
    Blocks of fewer than :data:`TAIL_TERMS` terms are not read."""
    pixels = block_sum(varying.astype(np.float64), block)
    used = pixels * (min(len(h) for h in halves) - 1) >= TAIL_TERMS
    if not used.any():
        return 0.0
    ruled = np.zeros(used.shape, bool)
    for images in halves:
        images = np.where(varying, np.asarray(images, dtype=np.float64), 0.0)
        sq = np.square(images - images.mean(axis=0))
        total = block_sum(sq.sum(axis=0), block)
        *_, h, w, c = sq.shape
        top = sq.reshape(sq.shape[0], h // block, block, w // block, block, c).max(
            axis=(0, 2, 4))
        ruled |= (total > 0) & (top > dominance * total)
    return float(np.sum(ruled & used) / np.sum(used))


def compare(a: Side, b: Side, varying: np.ndarray, alpha_blocks: float, alpha_pooled: float,
            rounding: float = ROUNDING) -> "Agreement":
    """Per-block and pooled tests of side ``a`` against side ``b`` (see the module
    docstring), at per-comparison levels ``alpha_blocks`` and ``alpha_pooled``."""
    t, dof = _block_test(a, b, rounding)
    delta, z, zdof = _pooled_test(a, b, rounding)
    ua, ub = _unbiased(a, b, rounding)

    def blocks(x, y):
        return _block_test(x, y, rounding)

    def pooled(x, y):
        return _pooled_test(x, y, rounding)[1:]

    return Agreement(t, _p(t, dof), delta, z, _p(z, zdof), alpha_blocks, alpha_pooled,
                     detectable(blocks, ua, ub, alpha_blocks),
                     detectable(pooled, ua, ub, alpha_pooled),
                     int(varying.sum(axis=(0, 1)).max()))
