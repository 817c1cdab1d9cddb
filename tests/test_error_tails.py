"""How sure a cell's expected relMSE is where a few pixels rule it: the variance of a pixel's
variance from its samples' fourth moments (experiments/lib/jobs.py), against the spread of
many synthetic pixels and of many renders of a real scene, with negative controls (the
normal theory alone; the film's rounding taken at face value); the suite's pooled variance
taking the larger of the repeats' spread and the renders' own; a method that renders its
own passes (the guide) stating it through ``combined_moments``."""
from __future__ import annotations

import numpy as np
import pytest

import scenes
from experiments.lib import execute, jobs, multipass, plan
from experiments.lib.jobs import Accumulator
from experiments.lib.methods import parse_method
from experiments.lib.scenes import effective_depth, read_scene
from experiments.lib.studies.suite import errors as suite_errors

VARIANT = "llvm_ad_rgb"
SCENE = scenes.path("suite/small_light.xml")


def _raw_moments(x: np.ndarray, dtype=np.float64):
    """Means over the last axis of x, x^2, x^3, x^4, each summed in ``dtype`` one sample
    after the other (as a film adds its samples' AOVs, in single precision)."""
    x = x.astype(dtype)
    n = x.shape[-1]
    return [np.cumsum(x ** k, axis=-1, dtype=dtype)[..., -1].astype(np.float64) / n
            for k in (1, 2, 3, 4)]


@pytest.mark.parametrize("kind", ["rare bright", "lognormal", "normal"])
def test_the_variance_of_a_pixels_variance_matches_its_spread_over_many_pixels(kind):
    """For 4000 pixels of n = 64 independent samples each, the mean over the pixels of
    :func:`jobs.variance_of_variance` (from each pixel's own raw moments) equals the spread
    of their variance-of-the-mean estimates s^2 / n within 15%, for a normal, a lognormal
    (sigma 1) and a rare-bright sample (50 with probability 0.02, else uniform in [0, 1]).
    Negative control: the normal theory's term alone, 2 s^4 / (n - 1) / n^2, reads the
    rare-bright pixels' at under a third of their spread."""
    rng = np.random.default_rng(7)
    n, pixels = 64, 4000
    if kind == "rare bright":
        x = np.where(rng.random((pixels, n)) < 0.02, 50.0, rng.random((pixels, n)))
    elif kind == "lognormal":
        x = rng.lognormal(0.0, 1.0, (pixels, n))
    else:
        x = rng.normal(2.0, 0.5, (pixels, n))
    estimate = x.var(axis=-1, ddof=1) / n
    vv = jobs.variance_of_variance(*_raw_moments(x), n)
    assert float(np.mean(vv)) == pytest.approx(float(np.var(estimate)), rel=0.15)
    normal = 2 * np.square(x.var(axis=-1, ddof=1)) / (n - 1) / n ** 2
    if kind == "rare bright":
        assert float(np.mean(normal)) < float(np.var(estimate)) / 3
    elif kind == "normal":
        assert float(np.mean(normal)) == pytest.approx(float(np.var(estimate)), rel=0.15)


def test_the_variance_of_a_smooth_pixels_variance_is_not_the_films_rounding(monkeypatch):
    """A smooth pixel (4096 samples of 100 +- 1) whose raw moments were summed in single
    precision, as a film sums its AOVs: the central fourth moment read from them is
    rounding (m4 ~ 1e8 for mu4 = 3), and the excess kurtosis's term stays out (the normal
    theory's term of the same moments, within 1%); in double precision the formula agrees
    with the normal theory. Negative control: without the rounding's bound the single
    precision moments give over 10 times it on average (a few pixels hundreds of times)."""
    rng = np.random.default_rng(3)
    n = 4096
    x = rng.normal(100.0, 1.0, (200, n))
    moments = _raw_moments(x, np.float32)
    s2 = np.maximum(moments[1] - moments[0] ** 2, 0.0) * n / (n - 1)
    normal = 2 * s2 * s2 / (n - 1) / n ** 2
    single = jobs.variance_of_variance(*moments, n)
    assert np.allclose(single, normal, rtol=0.01)
    double = jobs.variance_of_variance(*_raw_moments(x), n)
    exact = 2 * np.square(x.var(axis=-1, ddof=1)) / (n - 1) / n ** 2
    assert float(np.mean(double / exact)) == pytest.approx(1.0, abs=0.2)
    monkeypatch.setattr(jobs, "FILM_ROUNDING", 0.0)
    assert float(np.mean(jobs.variance_of_variance(*moments, n) / normal)) > 10


def test_the_pooled_variance_takes_the_larger_of_the_repeats_spread_and_the_renders_own():
    """Exact values: R = 2 identical maps (no spread across repeats) with their own tail
    variances t give sum(t) / (R^2 N^2); where the repeats' spread is larger it stands; a
    missing tail map (a render without its fourth moments) leaves the spread alone."""
    maps = [np.full((2, 2), 0.5)] * 2
    tails = [np.full((2, 2), 0.04), np.full((2, 2), 0.08)]
    value, var = suite_errors.pooled(maps, tails)
    assert value == pytest.approx(0.5)
    assert var == pytest.approx((0.16 + 0.32) / (4 * 16))
    spread = [np.array([[0.0, 1.0], [0.0, 1.0]]), np.array([[1.0, 0.0], [1.0, 0.0]])]
    assert suite_errors.pooled(spread, tails)[1] == pytest.approx(4 * 0.5 / (2 * 16))
    assert suite_errors.pooled(maps, [tails[0], None])[1] == pytest.approx(0.0)
    assert suite_errors.pooled(maps)[1] == pytest.approx(0.0)


def test_each_renders_own_variance_of_its_error_agrees_with_the_spread_of_many_renders(
        monkeypatch):
    """small_light (a light smaller than many pixels: a few bright samples rule its
    error), bsdf+nee at 64 spp on a 32x24 film, 64 renders with their samples' moments:
    the median over the renders of each one's own standard error of its expected relMSE
    (:func:`errors.pixel_map_variance`, from its samples' fourth moments) lies within
    [0.6, 1.6] of the spread of the 64 renders' expected relMSEs. Negative control: the
    normal theory's term alone (the excess kurtosis's left out) reads under 0.4 of it."""
    size, n = (32, 24), 64
    info = read_scene(SCENE)
    accs = []
    for seed in range(64):
        job = plan.make_job(f"errors/tails/{seed}", info, parse_method("bsdf+nee"), *size, n,
                            500 + seed, effective_depth(info, None, None), VARIANT,
                            sample_moments=True)
        acc = Accumulator.empty(size[1], size[0])
        acc.add_result(execute.run_job(job, VARIANT))
        accs.append(acc)
    ref = np.mean([a.mean for a in accs], axis=0)
    values = np.array([suite_errors.pixel_map(a.variance_of_mean(), ref).mean() for a in accs])
    spread = values.std(ddof=1)

    def own():
        return float(np.median([np.sqrt(suite_errors.pixel_map_variance(
            a.variance_of_variance(), ref).sum()) / (size[0] * size[1])
            for a in accs]))
    assert 0.6 * spread <= own() <= 1.6 * spread, (own(), spread)
    monkeypatch.setattr(jobs, "FILM_ROUNDING", 1e9)     # the excess term never counts
    assert own() < 0.4 * spread


class _TwoGroups:
    """A stand-in MultiPass method: two groups of independent samples, weights 0.25 and
    0.75, each group one render."""

    def __init__(self, groups):
        self.groups = groups

    def combine(self, images, spps):
        return sum(w * m1 for w, _, m1, *_ in self.groups)

    def combined_variance(self):
        return sum(w * w * np.maximum(m2 - m1 * m1, 0) / (n - 1)
                   for w, n, m1, m2, *_ in self.groups)

    def combined_moments(self):
        return self.groups


def test_a_method_that_states_its_groups_moments_states_how_sure_its_variance_is():
    """Exact value: multipass.stated_tails gives sum over groups of weight^4 x the variance
    of the group's variance (the weights fixed, the groups independent); without
    ``combined_moments`` none; an Accumulator keeps it for its one result and drops it
    when a second is added."""
    rng = np.random.default_rng(1)
    groups = []
    for w, n in ((0.25, 16), (0.75, 64)):
        x = rng.lognormal(0.0, 1.0, (2, 3, 3, n))
        groups.append((w, n, *[np.mean(x ** k, axis=-1) for k in (1, 2, 3, 4)]))
    method = _TwoGroups(groups)
    mean, sq, passes = multipass.stated(method, method.combine([None, None], [16, 64]), 80)
    vv = multipass.stated_tails(method)
    expect = sum(w ** 4 * jobs.variance_of_variance(m1, m2, m3, m4, n)
                 for w, n, m1, m2, m3, m4 in groups)
    assert np.allclose(vv, expect) and passes == 80
    del _TwoGroups.combined_moments
    try:
        assert multipass.stated_tails(method) is None
    finally:
        _TwoGroups.combined_moments = lambda self: self.groups
    result = jobs.JobResult(image=mean, sq=sq, spp=80, passes=80, wall_seconds=0.0,
                            variance_var=vv)
    acc = Accumulator.empty(2, 3)
    acc.add_result(result)
    assert np.allclose(acc.variance_of_variance(), expect)
    acc.add_result(result)
    assert acc.variance_of_variance() is None


def test_a_guided_job_states_how_sure_its_variance_is_and_the_store_keeps_it(tmp_path):
    """guided+nee on door_room at 64x48, 384 spp (it trains: guided iterations, several
    groups): its result carries a finite, positive variance_var of the shape of its image,
    below its variance squared times a generous factor (a sanity bound, not a fit), and
    the job store gives it back unchanged."""
    from experiments.lib.store import JobStore
    info = read_scene(scenes.path("suite/door_room.xml"))
    job = plan.make_job("tails/guided", info, parse_method("guided+nee"), 64, 48, 384, 11,
                        effective_depth(info, None, None), VARIANT)
    result = execute.run_job(job, VARIANT)
    acc = Accumulator.empty(48, 64)
    acc.add_result(result)
    vv, var = acc.variance_of_variance(), acc.variance_of_mean()
    assert vv is not None and vv.shape == (48, 64, 3) and np.all(np.isfinite(vv))
    assert np.all(vv >= 0) and np.any(vv > 0)
    assert np.all(vv <= 1e6 * var ** 2 + 1e-30)
    store = JobStore(str(tmp_path))
    store.put(job, result)
    assert np.array_equal(store.get(job.key).variance_var, result.variance_var)
