"""The passes of a guided job and their weights: pure functions of counts and images.

``vr_guided_path`` (:mod:`.guided_path`) renders a job in training iterations of doubling
samples (:func:`iterations`), each split into renders of bounded size (:func:`renders`);
a job too small to pay for training is not trained (:func:`training_refusals`); training
stops where the records predict no gain (:func:`predicted_gain`, :func:`stops`); the
iterations' images are pooled per estimator and combined with inverse-variance weights
read from the other pixels of a checkerboard (:func:`combine`, :func:`cross_weights`,
:func:`pass_weights`). Here only numpy: no Dr.Jit, no Mitsuba, so that
every rule is testable and readable on its own. Why the constants have their values:
docs/guiding.md, "Why these defaults".
"""
from __future__ import annotations

import numpy as np

#: Training stops below this predicted gain over BSDF sampling (docs/guiding.md).
STOP_GAIN = 1.03
#: ... after this many iterations in a row below it (docs/guiding.md).
STOP_PATIENCE = 2
#: ... and not before this iteration (docs/guiding.md).
STOP_FIRST = 2
#: Default ``min_train_spp``: fewer samples per pixel do not train (docs/guiding.md).
MIN_TRAIN_SPP = 256
#: Default ``min_train_samples``: fewer samples in all do not train (docs/guiding.md).
MIN_TRAIN_SAMPLES = 2 ** 20


def iterations(spp: int, first: int = 2) -> list[int]:
    """Training iterations of doubling samples (``first``, 2 ``first``, ...), the last one
    taking the rest once it would be less than twice the next (PPG's rule)."""
    out, n, left = [], first, spp
    while left > 0:
        if left < 3 * n:
            out.append(left)
            break
        out.append(n)
        left, n = left - n, 2 * n
    return out


def split(spp: int, most: int) -> list[int]:
    """``spp`` in near-equal renders of at most ``most`` samples each."""
    k = -(-spp // most)
    return [spp // k + (i < spp % k) for i in range(k)]


def renders(counts: list[int], most: int, trains: bool) -> list[tuple[int, int]]:
    """(iteration, samples per pixel) of every render of iterations of ``counts`` samples:
    each iteration that records (every one but the last, where the job trains) split into
    renders of at most ``most`` (:func:`split`: the records' memory), the others one render
    each (the executor splits a render over its lane cap, as it does vr_path's): many small
    renders cost more kernel time per sample than one large one."""
    return [(k, n) for k, it in enumerate(counts)
            for n in (split(it, most) if trains and k + 1 < len(counts) else [it])]


def merged_rest(passes: list[tuple[int, int]], index: int) -> list[tuple[int, int]]:
    """``passes`` (as :func:`renders`) with every render after ``index`` merged into one
    render of the next iteration: where training stopped, the rest is one estimator (plain
    BSDF sampling) and records nothing, so one render of all its samples does. Unchanged
    where at most one render follows."""
    rest = passes[index + 1:]
    if len(rest) <= 1:
        return list(passes)
    return passes[:index + 1] + [(rest[0][0], sum(n for _, n in rest))]


def training_refusals(spp: int, pixels: int, min_spp: int, min_samples: int) -> list[str]:
    """Why a job of ``spp`` samples per pixel on ``pixels`` pixels does not train (below
    ``min_train_spp`` = ``min_spp``, below ``min_train_samples`` = ``min_samples``), one
    sentence per rule; empty where it trains."""
    out = [f"{spp} spp is below 'min_train_spp' ({min_spp})"] if spp < min_spp else []
    if spp * pixels < min_samples:
        out.append(f"{spp} spp x {pixels} pixels is below 'min_train_samples' "
                   f"({min_samples})")
    return out


def trains(spp: int, pixels: int, min_spp: int = MIN_TRAIN_SPP,
           min_samples: int = MIN_TRAIN_SAMPLES) -> bool:
    """Whether a job of ``spp`` samples per pixel on ``pixels`` pixels trains (at the
    default thresholds unless given): none of :func:`training_refusals`."""
    return not training_refusals(spp, pixels, min_spp, min_samples)


def stops(gains: list, iteration: int) -> bool:
    """Does training stop after ``iteration`` (0 the first), given the predicted gains of
    every iteration so far (:func:`predicted_gain`, None where nothing was measured)? Yes
    from iteration :data:`STOP_FIRST` on, once the last :data:`STOP_PATIENCE` gains are
    all below :data:`STOP_GAIN`."""
    low = [g is not None and g < STOP_GAIN for g in gains[-STOP_PATIENCE:]]
    return iteration >= STOP_FIRST and all(low)


def pass_weights(variances, spps) -> np.ndarray:
    """One scalar weight per iteration, inverse to its image's estimated variance
    (Mueller 2019), summing to 1. A variance that is 0 or not finite (a black image, one
    sample per pixel) falls back to weights proportional to the samples."""
    v = np.asarray(variances, float)
    spps = np.asarray(spps, float)
    if len(v) == 1 or not np.all(np.isfinite(v) & (v > 0)):
        return spps / spps.sum()
    w = 1.0 / v
    return w / w.sum()


def predicted_gain(sums: dict, variance: float, samples: int) -> float | None:
    """The image's per-sample variance with every share 1 over that with the new shares,
    predicted from an iteration's records: ``variance`` (the pixels' per-sample variance
    measured, at the shares the records were drawn with) shifted by the records' summed
    second moments (:meth:`.sdtree.SDTree.refine`'s ``moment_sums``: at the drawn shares,
    at share 1, at the chosen ones) per sample (``samples``: the iteration's camera
    samples). None when nothing was measured."""
    if sums is None or samples <= 0 or not variance > 0:
        return None
    bsdf = variance + (sums["bsdf"] - sums["drawn"]) / samples
    chosen = variance + (sums["chosen"] - sums["drawn"]) / samples
    return float(bsdf / chosen) if chosen > 0 and bsdf > 0 else None


def sample_spread(mean: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """Per pixel and channel, the samples' spread from their mean and mean square:
    m2 - mean^2 (0 where rounding makes it negative)."""
    return np.maximum(m2 - mean ** 2, 0.0)


def pixel_variance(mean: np.ndarray, m2: np.ndarray, spp: int) -> np.ndarray:
    """Per pixel and channel, the variance of the mean of ``spp`` samples, from their mean
    and mean square: (m2 - mean^2) / (spp - 1) (inf for one sample)."""
    if spp < 2:
        return np.full(np.shape(mean), np.inf)
    return sample_spread(mean, m2) / (spp - 1)


def pixel_moments(means: list, m2s: list, spps: list, idx) -> tuple[float, int]:
    """(the per-sample variance of the pixels' values averaged over pixels and channels,
    camera samples) of the renders ``idx`` (their per-pixel means ``means``, mean squares
    ``m2s`` and samples per pixel ``spps``), pooled by their samples."""
    n = sum(spps[i] for i in idx)
    mean = sum(means[i] * spps[i] for i in idx) / n
    m2 = sum(m2s[i] * spps[i] for i in idx) / n
    return float(np.mean(sample_spread(mean, m2))), n * mean[..., 0].size


def cross_weights(variances: list, spps: list) -> np.ndarray:
    """Per group and pixel, the group's weight (:func:`pass_weights`) from the groups'
    per-pixel variances ``variances`` ((H, W, C) each) averaged over the pixels of the
    other colour of a checkerboard: a weight estimated from the samples it weights
    correlates with them (a group whose samples missed rare bright values reads a low
    variance and a low mean, and weighs more: the image reads low), one from other pixels
    (independent samples, given the guides) does not. A one-pixel image takes its own.
    Shape (groups, H, W, 1)."""
    h, w = variances[0].shape[:2]
    y, x = np.indices((h, w))
    black = (y + x) % 2 == 0
    out = np.empty((len(variances), h, w, 1))
    for colour in (black, ~black):
        other = ~colour if (~colour).any() else colour
        weights = pass_weights([float(np.mean(v[other])) for v in variances], spps)
        out[:, colour] = weights[:, None, None]
    return out


def pooled(images: list, m2s: list, spps: list, idx: list) -> tuple:
    """(per-pixel mean, mean square, samples per pixel) of the renders ``idx`` (per-pixel
    means ``images``, mean squares ``m2s``, ``spps`` samples per pixel) pooled by their
    samples; one render is itself. Mean squares given as None are not pooled (None)."""
    if len(idx) == 1:
        return images[idx[0]], m2s[idx[0]], spps[idx[0]]
    n = sum(spps[i] for i in idx)
    m2 = None if m2s[idx[0]] is None else sum(m2s[i] * spps[i] for i in idx) / n
    return sum(images[i] * spps[i] for i in idx) / n, m2, n


def weighted(images: list, m2s: list, spps: list, groups: list) -> tuple:
    """(the combined image, the groups' weights per pixel) of renders with per-pixel means
    ``images``, mean squares ``m2s`` and ``spps`` samples per pixel: the renders of each
    group (a list of indices: the renders of one estimator) pooled by their samples
    (:func:`pooled`), then the groups weighted by :func:`cross_weights` (from the mean over
    the other checkerboard colour's pixels and the channels of each group's
    :func:`pixel_variance`). One group (a job that did not train, or stopped before a unit
    learned) is its pooled mean, with no weights to estimate (nor mean squares read)."""
    if len(groups) == 1:
        mean = pooled(images, m2s, spps, groups[0])[0]
        return mean, np.ones((1,) + mean.shape[:2] + (1,))
    pools = [pooled(images, m2s, spps, idx) for idx in groups]
    weights = cross_weights([pixel_variance(*p) for p in pools], [p[2] for p in pools])
    return sum(w * p[0] for w, p in zip(weights, pools)), weights


def weighted_variance(images: list, m2s: list, spps: list, groups: list,
                      weights: np.ndarray) -> np.ndarray:
    """Per pixel and channel, the variance of the image :func:`weighted` combined from the
    renders' ``groups`` with ``weights``, the weights taken as fixed: sum_g w_g^2 x
    :func:`pixel_variance` of group g pooled (:func:`pooled`)."""
    return sum(w * w * pixel_variance(*pooled(images, m2s, spps, idx))
               for w, idx in zip(weights, groups))


def combine(images: list, m2s: list, spps: list, groups: list):
    """(the combined image, the groups' weights per pixel, its per-pixel variance) of
    renders with per-pixel means ``images``, mean squares ``m2s`` and ``spps`` samples per
    pixel (:func:`weighted`, :func:`weighted_variance`)."""
    image, weights = weighted(images, m2s, spps, groups)
    return image, weights, weighted_variance(images, m2s, spps, groups, weights)
