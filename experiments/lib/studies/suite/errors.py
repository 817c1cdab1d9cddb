"""The suite's precise errors: a cell's expected relMSE from the per-pixel variances of its
renders' samples, and efficiency intervals from them and from paired costs.

Where a cell's pixels are independent estimates (the ``independent`` sampler under a box
filter: :func:`.bias_test.variance_kind` is ``pixels``) each render keeps its samples'
per-pixel second moments (the job's ``sample_moments``: ``vr_moments``,
:mod:`integrators.moments`), which give the per-pixel variance of its mean image
(:meth:`.jobs.Accumulator.variance_of_mean`, every sample a pass: spp - 1 degrees of freedom
per pixel; a method that renders its own passes, :class:`.multipass.MultiPass`, gives the
spread of those instead). The expected relMSE of an unbiased render is then

    E = mean over pixels of  v_p,   v_p = mean over channels of  var_p / (ref_p^2 + eps)

(the variance part of the relMSE; the bias is tested apart, :mod:`.bias_test`), with no
floor to subtract (the reference's noise enters only through the denominators). Pooled over
the R repeats, its standard error is the larger of two estimates of the same thing:

* each pixel's variance of v_p across the repeats, summed over the pixels: thousands of
  terms with R - 1 degrees of freedom each;
* each render's own variance of its v_p, from its samples' fourth central moments
  (:func:`.jobs.variance_of_variance`, where the renders kept their cubes and fourth
  powers), summed over the pixels and the repeats.

Either is unbiased, but where a few pixels hold most of E (a light smaller than a pixel,
caustic fireflies, a narrow lobe sampled uniformly) the first rests on R values of each of
them and is usually far too small; the second reads all of a pixel's samples (on
small_light, `bsdf+nee` at 64 spp: 16% of E per render where the spread of 64 renders says
14%; docs/methodology.md).
Hence a normal quantile instead of Student's t with R - 1. What both can miss: a heavy tail
that no render of the run has sampled (its variance is then understated, as every estimate
from these renders would be).

The cost side of an efficiency pairs the two methods' renders (same repeat, same budget: a
timing group renders them one after the other, :meth:`...engine.Engine.run`), so that the
machine's load, shared by both, cancels in their ratio: the ratio of the mean seconds (as the
tables give them) with the variance of its log from each budget's R paired renders'
relative deviations of their costs per sample, weighted by the budget's share of the
seconds (delta method; :func:`cost_terms`: winsorized at 5 robust standard deviations,
:func:`.stats.winsorize`, since a lone render slowed 2x by the machine, seen in about 1% of
renders, would otherwise rule the interval), Student's t on R - 1 degrees of freedom per
budget. Three paired renders know their own variance on 2 degrees of freedom only, so a
pair whose renders agree by chance would claim a precision the machine does not have: each
budget's variance is at least the scene's, pooled over every method paired with the
baseline (:func:`cost_jitter`: every method of a scene renders about as long at equal time
and meets the same machine), on its degrees of freedom. Cells of QMC samplers or other
filters keep the repeat-based relMSE (:mod:`.analysis`).
"""
from __future__ import annotations

import math

import numpy as np

from ... import metrics, stats


def pixel_map(variance: np.ndarray | None, ref: np.ndarray) -> np.ndarray | None:
    """v_p of one render, (H, W): its per-pixel variance of the mean (H, W, 3) over the
    reference's ref^2 + eps, averaged over channels; None without passes."""
    if variance is None or not np.all(np.isfinite(variance)):
        return None
    ref = np.asarray(ref, np.float64)
    return (np.asarray(variance, np.float64) / (ref * ref + metrics.RELMSE_EPS)).mean(axis=-1)


def pixel_map_variance(variance_var: np.ndarray | None, ref: np.ndarray) -> np.ndarray | None:
    """The variance of one render's :func:`pixel_map` as an estimate, (H, W), from its
    per-pixel variance of the variance (:meth:`.jobs.Accumulator.variance_of_variance`):
    the channels' standard deviations added (as if fully correlated, which bounds the
    variance of their mean); None without it."""
    if variance_var is None or not np.all(np.isfinite(variance_var)):
        return None
    ref = np.asarray(ref, np.float64)
    sd = np.sqrt(np.maximum(np.asarray(variance_var, np.float64), 0.0)) \
        / (ref * ref + metrics.RELMSE_EPS)
    return np.square(sd.mean(axis=-1))


def oracle_gain(maps) -> float:
    """How many times an oracle's allocation of the same samples would lower the relMSE of
    the renders whose :func:`pixel_map` values are ``maps``: pixel p's samples in
    proportion to its relative standard deviation sqrt(v_p) give mean(v) / mean(sqrt v)^2
    (the repeats' maps averaged first; nan without maps). Per-pixel variances from a few
    renders make it read a little high (their noise adds spread to sqrt v): the ceiling
    that adaptive sampling could reach, not a measurement of a method."""
    if not maps or any(m is None for m in maps):
        return math.nan
    v = np.mean(np.stack([np.asarray(m, np.float64).ravel() for m in maps]), axis=0)
    root = float(np.mean(np.sqrt(np.maximum(v, 0.0))))
    return float(np.mean(v)) / (root * root) if root > 0 else math.nan


def pooled(maps, tails=None) -> tuple[float, float]:
    """(expected relMSE over the repeats' :func:`pixel_map` values, the variance of that
    estimate): the larger of the sum over pixels of each pixel's variance across the R
    repeats, over R N^2 (R - 1 degrees of freedom per pixel, thousands of pixels; with one
    repeat, the spread over the pixels, which also counts their differences: wider), and,
    where every repeat has its :func:`pixel_map_variance` (``tails``), their sum over
    pixels and repeats over R^2 N^2 (see the module). (nan, nan) without maps."""
    if not maps or any(m is None for m in maps):
        return math.nan, math.nan
    v = np.stack([np.asarray(m, np.float64).ravel() for m in maps])
    repeats, n = v.shape
    value = float(v.mean())
    if repeats > 1:
        var = float(v.var(axis=0, ddof=1).sum()) / (repeats * n * n)
    else:
        var = float(v.var(ddof=1)) / n if n > 1 else math.nan
    if tails and len(tails) == repeats and all(t is not None for t in tails):
        own = float(sum(np.sum(t) for t in tails)) / (repeats * repeats * n * n)
        var = own if math.isnan(var) else max(var, own)
    return value, var


#: Share of a cell's pooled expected relMSE (:func:`pooled`) above which one pixel of one
#: render holds it: its estimate rests on that one term, so its efficiencies are bounds
#: (:func:`without_top`), not intervals.
TAIL_SHARE = 0.5


def top_share(maps) -> float:
    """The largest share of the sum of ``maps`` (each render's :func:`pixel_map`) that one
    pixel of one render holds (0 where the sum is not positive)."""
    v = np.stack([np.asarray(m, np.float64).ravel() for m in maps])
    total = float(v.sum())
    return float(v.max()) / total if total > 0 else 0.0


def without_top(maps, tails=None) -> tuple[float, float]:
    """:func:`pooled` with the one term that holds the most of it (a pixel of one render,
    its value and its tail) left out: an estimate of the cell's expected relMSE that is
    low where that term is a rare sample of a heavy tail (the error it left out is real),
    so its interval's lower end bounds the error from below."""
    v = [np.asarray(m, np.float64).copy() for m in maps]
    r = int(np.argmax([m.max() for m in v]))
    p = np.unravel_index(int(np.argmax(v[r])), v[r].shape)
    v[r][p] = 0.0
    t = None
    if tails and all(x is not None for x in tails):
        t = [np.asarray(x, np.float64).copy() for x in tails]
        t[r][p] = 0.0
    return pooled(v, t)


def estimate(value: float, var: float, n: int, level: float = stats.LEVEL) -> stats.Estimate:
    """The pooled expected relMSE (:func:`pooled`) with its interval (log scale, normal
    quantile); ``n``: the repeats."""
    if not value > 0 or not math.isfinite(var):
        return stats.Estimate(value, math.nan, math.nan, n, level)
    half = stats.normal_quantile(level) * math.sqrt(var) / value
    return stats.Estimate(value, value * math.exp(-half), value * math.exp(half), n, level)


def _error_terms(a, b) -> tuple | None:
    """(log of E_b / E_a, its two log-scale terms (variance, dof)) of runs with pixel terms;
    None where either lacks them or has no error."""
    if not (a.expected and b.expected):
        return None
    (ea, va), (eb, vb) = a.expected, b.expected
    if not (ea > 0 and eb > 0 and math.isfinite(va + vb)):
        return None
    return math.log(eb / ea), [(va / ea ** 2, math.inf), (vb / eb ** 2, math.inf)]


def ruled(runs) -> bool:
    """Whether one pixel of one render holds more than :data:`TAIL_SHARE` of the cell's
    expected relMSE (``Runs.top``)."""
    return bool(runs.expected) and runs.top > TAIL_SHARE


def error_ratio(a, b, level: float = stats.LEVEL) -> stats.Estimate | None:
    """Expected relMSE of runs ``b`` over runs ``a`` (above 1: ``a`` has the lower error)
    with its interval; None where either lacks pixel terms."""
    terms = _error_terms(a, b)
    if terms is None:
        return None
    return stats.log_interval(terms[0], terms[1], min(len(a.relmse), len(b.relmse)), level)


def efficiency(a, b, level: float = stats.LEVEL) -> stats.Estimate | None:
    """Efficiency 1/(relMSE x seconds) of runs ``a`` over ``b`` (:class:`.analysis.Runs`
    with pixel terms and cost readings, paired render by render) with its interval: the
    error ratio's terms and the paired costs' (:func:`cost_terms`); None where either lacks
    them (the repeat-based interval is used there)."""
    terms = _error_terms(a, b)
    costs = cost_terms(a, b)
    if terms is None or costs is None:
        return None
    log_value = terms[0] + math.log(float(np.mean(b.seconds)) / float(np.mean(a.seconds)))
    return stats.log_interval(log_value, terms[1] + costs, min(len(a.relmse), len(b.relmse)),
                              level)


def typical_efficiency(a, b) -> float:
    """:func:`efficiency`'s value with each cell's error the median of its renders' own
    expected relMSEs (``Runs.each``) instead of their mean: where one render of a cell
    caught a rare firefly (its own variance huge, the others' not) the mean is ruled by it
    and the other cell's renders may simply have missed theirs (two renders of one
    estimator on a scene of Mitsuba's render tests came out 177 [25, 1252] times apart by
    the mean, 1.0 by the median). nan where either lacks them."""
    if not (a.each and b.each) or not all(x > 0 for x in (*a.each, *b.each)):
        return math.nan
    return float(np.median(b.each) * np.mean(b.seconds) /
                 (np.median(a.each) * np.mean(a.seconds)))


def cost_terms(a, b) -> list | None:
    """The log-scale terms (variance, dof) of the seconds' ratio, mean(b.seconds) /
    mean(a.seconds), from the paired renders' costs per sample (``Runs.costs``: per budget,
    its count and each repeat's cost per sample). A repeat's seconds are its renders' costs
    weighted by their samples, so each budget enters with its share of them (the equal-time
    render's, nearly all, where it has hundreds of times the equal-spp count), and its
    renders are compared with their method's mean at that budget: a method's cost per sample
    may differ between the budgets (one that learns trains in its equal-time renders only),
    which is not noise. Per budget, the variance of the paired relative deviations over the
    repeats, :func:`.stats.winsorize` d (a lone slow render does not rule it), R - 1
    degrees of freedom, or the scene's pooled variance (``Runs.jitter``,
    :func:`cost_jitter`) with its degrees of freedom where that is larger. None without
    paired costs."""
    if not (a.costs and [len(g) for _, g in a.costs] == [len(g) for _, g in b.costs]):
        return None
    budgets = [(n_a, np.asarray(ga, np.float64), n_b, np.asarray(gb, np.float64))
               for (n_a, ga), (n_b, gb) in zip(a.costs, b.costs)]
    if not all(ga.size > 1 and np.all(ga > 0) and np.all(gb > 0) and np.all(np.isfinite(ga * gb))
               for _, ga, _, gb in budgets):
        return None
    share_a = np.array([n * ga.mean() for n, ga, _, _ in budgets])
    share_b = np.array([n * gb.mean() for _, _, n, gb in budgets])
    weight = (share_a / share_a.sum() + share_b / share_b.sum()) / 2
    # about each budget's medians (a mean would spread a lone slow render over the others),
    # clipped on the spread of every budget's deviations (a budget's few repeats alone
    # would give no robust scale), then each budget's variance about its own mean
    devs = [gb / np.median(gb) - ga / np.median(ga) for _, ga, _, gb in budgets]
    clipped = _clipped(devs)
    pooled = a.jitter or b.jitter
    out = []
    for k, (w, c) in enumerate(zip(weight, clipped)):
        var, dof = float(c.var(ddof=1)), c.size - 1
        if len(pooled) == len(clipped) and pooled[k][0] > var:
            var, dof = pooled[k]
        out.append((w * w * var / c.size, dof))
    return out


def _clipped(devs: list) -> list:
    """Each array of ``devs`` with every value :func:`.stats.winsorize` d on the spread of
    them all (a few repeats alone would give no robust scale)."""
    return np.split(stats.winsorize(np.concatenate(devs)),
                    np.cumsum([d.size for d in devs])[:-1])


def cost_jitter(runs: list, baseline) -> tuple:
    """Per budget of ``baseline.costs``, the variance of one repeat's paired relative cost
    deviation (a method's cost per sample over its median, less the baseline's), pooled
    over every Runs of ``runs`` but the baseline's, with its degrees of freedom (each
    method's repeats less one, summed): () where none pairs. The repeats of one pair are
    too few to know their own (2 degrees of freedom at 3 repeats); every method of a scene
    at one budget renders about as long and meets the same machine, so a pair's cost term
    takes the pooled variance where it is the larger (:func:`cost_terms`)."""
    if not baseline.costs:
        return ()
    out = []
    for k, (_, gb) in enumerate(baseline.costs):
        gb = np.asarray(gb, np.float64)
        devs = []
        for r in runs:
            if r is baseline or len(r.costs) != len(baseline.costs):
                continue
            ga = np.asarray(r.costs[k][1], np.float64)
            if ga.size == gb.size > 1 and np.all(ga > 0) and np.all(gb > 0):
                devs.append(ga / np.median(ga) - gb / np.median(gb))
        if not devs:
            return ()
        clipped = _clipped(devs)
        dof = sum(c.size - 1 for c in clipped)
        out.append((sum(float(np.sum((c - c.mean()) ** 2)) for c in clipped) / dof, dof))
    return tuple(out)
