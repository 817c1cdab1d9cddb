"""The suite's precise errors (experiments/lib/studies/suite/errors.py): the expected relMSE
from the pixels' sample variances (``vr_moments``) agrees with many independent repeats on a real scene, its
intervals have their coverage (A/A: vr_path bsdf+nee and Mitsuba's path at equal spp), and
the pooled standard error and the paired efficiency on synthetic numbers, with negative
controls."""
from __future__ import annotations

import math

import numpy as np
import pytest

import scenes
from experiments.lib import execute, metrics, plan, stats
from experiments.lib.jobs import Accumulator
from experiments.lib.methods import parse_method
from experiments.lib.scenes import effective_depth, read_scene
from experiments.lib.studies.suite import errors as suite_errors
from experiments.lib.studies.suite import precision
from experiments.lib.studies.suite.analysis import Runs

VARIANT = "llvm_ad_rgb"
SCENE = scenes.path("suite/small_light.xml")
FILM = (48, 36)          # the suite's film of this scene


def _render(method: str, spp: int, seed: int, size=(16, 12), moments=True, scene=SCENE):
    """(mean image, per-pixel variance of the mean) of one render with its samples' second
    moments (``moments``; else in 4 passes, whose spread gives the variance)."""
    info = read_scene(scene)
    job = plan.make_job(f"errors/{method}/{seed}", info, parse_method(method), *size, spp,
                        seed, effective_depth(info, None, None), VARIANT,
                        pass_spp=0 if moments else spp // 4, sample_moments=moments)
    acc = Accumulator.empty(size[1], size[0])
    acc.add_result(execute.run_job(job, VARIANT))
    assert acc.passes == (spp if moments else 4)
    return acc.mean, acc.variance_of_mean()


#: The equal-spp count of the synthetic runs' first renders.
EQUAL_SPP = 16


def _runs(expected, spp=16, costs=(), seconds=None, repeats=3):
    """Runs whose ``costs`` (per sample, 2R renders) are the equal-spp renders' (EQUAL_SPP)
    then the equal-time renders' (``spp``); their seconds per repeat (unless given) as the
    suite's: the repeat's two renders' costs weighted by their samples, times ``spp``."""
    c = np.asarray(costs, np.float64)
    r = c.size // 2
    if seconds is None:
        seconds = spp * (EQUAL_SPP * c[:r] + spp * c[r:]) / (EQUAL_SPP + spp) if c.size else ()
    return Runs(spp, (0.0,) * repeats, (), (), tuple(seconds), expected=tuple(expected),
                costs=((EQUAL_SPP, tuple(c[:r])), (spp, tuple(c[r:]))) if c.size else ())


def test_expected_relmse_agrees_with_the_spread_of_many_repeats():
    """The mean of the per-render estimates equals the expected relMSE measured from the
    spread of 64 independent renders around their mean (an unbiased estimator's error
    against its truth), within a few percent; the estimate without the division of the
    variance by the samples (the variance of one sample, not of the mean) is 16x off."""
    images, terms = [], []
    for seed in range(64):
        mean, var = _render("bsdf+nee", 16, 100 + seed)
        images.append(mean)
        terms.append(var)
    images = np.stack(images)
    truth_image = images.mean(axis=0)
    spread = images.var(axis=0, ddof=1)
    measured = float(np.mean(spread / (truth_image ** 2 + metrics.RELMSE_EPS)))
    value, var = suite_errors.pooled([suite_errors.pixel_map(v, truth_image) for v in terms])
    # the repeats' measurement has 63 dof per pixel, but a few bright pixels rule it
    assert value == pytest.approx(measured, rel=0.1)
    assert math.sqrt(var) / value < 0.05
    assert value * 16 != pytest.approx(measured, rel=0.5)


def test_aa_relmse_interval_contains_one_in_36_of_40_seeds():
    """bsdf+nee and Mitsuba's path are the same estimator: their equal-spp relMSE ratio from
    the pixels' variances (3 repeats each, 16 spp with their second moments, the suite's 48x36 film) contains 1 in at
    least 36 of 40 seeds (95% intervals), and its intervals are narrower than those of the
    repeats' measured relMSE (Student t on 2 degrees of freedom)."""
    ref = _render("path", 1024, 7, FILM)[0]    # the reference both are measured against
    inside, widths, repeat_widths = 0, [], []
    for seed in range(40):
        sides, measured = [], []
        for method in ("bsdf+nee", "path"):
            reps = [_render(method, 16, 1000 * seed + 10 * r + (method == "path"), FILM)
                    for r in range(3)]
            sides.append(_runs(suite_errors.pooled([suite_errors.pixel_map(v, ref)
                                                    for _, v in reps])))
            measured.append([metrics.relmse(m, ref) for m, _ in reps])
        ratio = suite_errors.error_ratio(*sides)
        inside += ratio.lo <= 1 <= ratio.hi
        widths.append(ratio.hi / ratio.lo)
        repeat = stats.ratio_interval([measured[1]], [measured[0]])
        repeat_widths.append(repeat.hi / repeat.lo)
    assert inside >= 36, inside
    assert math.log(np.median(widths)) < 0.7 * math.log(np.median(repeat_widths))


def test_pooled_standard_error_has_its_coverage_on_synthetic_pixels():
    """Synthetic pass images of known variance: the 95% interval of the expected relMSE
    covers the truth in 91-99% of 400 trials (each pixel's variance across 3 repeats); from
    one repeat, the spread over the pixels (which also counts their differing variances)
    over-covers."""
    rng = np.random.default_rng(5)
    h, w, passes, k = 12, 16, 4, 4
    sigma = rng.uniform(0.2, 2.0, (h, w, 1)) * np.ones((1, 1, 3))
    ref = np.ones((h, w, 3))
    truth = float(np.mean(sigma ** 2 / (k * passes) / (1 + metrics.RELMSE_EPS)))
    hits = wide = 0
    for _ in range(400):
        maps = []
        for _ in range(3):
            acc = Accumulator.empty(h, w)
            for _ in range(passes):
                acc.add(1 + sigma * rng.standard_normal((h, w, 3)) / math.sqrt(k), k)
            maps.append(suite_errors.pixel_map(acc.variance_of_mean(), ref))
        e = suite_errors.estimate(*suite_errors.pooled(maps), 3)
        hits += e.lo <= truth <= e.hi
        one = suite_errors.estimate(*suite_errors.pooled(maps[:1]), 1)
        wide += one.lo <= truth <= one.hi
    assert 365 <= hits <= 395, hits
    assert wide >= 390, wide


def test_paired_efficiency_follows_the_table_and_cancels_shared_load():
    """The efficiency's value is (E_b seconds_b) / (E_a seconds_a); a load shared by both
    methods' paired renders (a factor 3 on one pair) leaves the interval narrow, where the
    unpaired spread of the same costs would not; without pixel terms: None (the
    repeat-based interval applies)."""
    load = np.array([1.0, 3.0, 1.0, 1.2, 1.0, 0.9])
    a = _runs((0.01, 1e-8), 64, 2e-6 * load, [64 * 2e-6] * 3)
    b = _runs((0.02, 4e-8), 64, 3e-6 * load * [1, 1.01, 0.99, 1, 1, 1],
              [64 * 3e-6] * 3)
    eff = suite_errors.efficiency(a, b)
    assert eff.value == pytest.approx(0.02 * 3 / (0.01 * 2))
    assert eff.hi / eff.lo < 1.1
    unpaired = stats.ratio_interval([[c for _, g in b.costs for c in g]],
                                    [[c for _, g in a.costs for c in g]])
    assert unpaired.hi / unpaired.lo > 3
    assert suite_errors.efficiency(a, Runs(64, (), (), (), ())) is None


def test_sample_moments_agree_with_the_spread_of_passes_and_are_tighter():
    """The per-pixel variance of the mean from the samples' second moments (15 dof per
    pixel at 16 spp) and from 4 passes (3 dof) estimate the same thing: their expected
    relMSE over 24 renders each agree within 3.3 standard errors of their difference (a
    z test at 0.1%); each pixel's estimate varies less from render to render with the
    moments (median over the pixels of the relative spread; Gaussian pixels would give
    sqrt(3/15) = 0.45 of the passes', a glossy highlight's heavy-tailed ones ~0.77)."""
    scene = scenes.path("suite/phong_highlight.xml")
    ref = _render("path", 1024, 3, scene=scene)[0]
    sides = []
    for moments in (True, False):
        sides.append(np.stack([suite_errors.pixel_map(_render(
            "bsdf+nee", 16, 500 + seed, moments=moments, scene=scene)[1], ref)
            for seed in range(24)]))
    totals = [m.mean(axis=(1, 2)) for m in sides]
    se = math.sqrt(sum(v.var(ddof=1) / v.size for v in totals))
    assert abs(totals[0].mean() - totals[1].mean()) < 3.3 * se
    spread = [np.nanmedian(m.std(axis=0) / np.where(m.mean(axis=0) > 0, m.mean(axis=0), np.nan))
              for m in sides]
    assert spread[0] < 0.9 * spread[1], spread


def test_the_suite_declares_sample_moments_only_where_pixels_are_independent():
    """Precise cells (independent sampler, box filter) render with ``sample_moments``, a QMC
    sampler or another filter without (their renders are not independent samples)."""
    assert precision.precise(parse_method("bsdf+nee"), True)
    assert not precision.precise(parse_method("bsdf+nee"), False)
    assert not precision.precise(parse_method("bsdf+nee+halton"), True)


def test_precision_scale_rounds_up_to_a_power_of_two_within_its_cap():
    """The factor brings the error to the target: (se / target)^2 rounded up to a power of
    two; at least 1 (never fewer samples), at most the cap."""
    assert precision.scale_for(0.07, 0.035) == 4.0
    assert precision.scale_for(0.08, 0.035) == 8.0      # 5.2 -> 8: the target is met
    assert precision.scale_for(0.01, 0.035) == 1.0
    assert precision.scale_for(5.0, 0.035, cap=32) == 32.0


def test_the_error_predicted_from_few_samples_matches_the_one_measured_at_more():
    """The rule behind the suite's equal-time factor: the relative standard error of the
    pooled expected relMSE falls as 1/sqrt(samples). From 3 renders at 16 spp, the error
    predicted at 128 spp agrees with the spread of 3-render estimates at 128 spp (8 sets)
    within a factor 1.6 on cbox (0.84 seen); without the sqrt(16/128) scaling it is 2.4
    times too large (the negative control)."""
    scene = scenes.path("suite/cbox.xml")
    ref = _render("path", 1024, 3, scene=scene)[0]

    def pooled(spp, seeds):
        maps = [suite_errors.pixel_map(_render("path", spp, s, scene=scene)[1], ref)
                for s in seeds]
        return suite_errors.pooled(maps)

    value, var = pooled(16, range(700, 703))
    predicted = math.sqrt(var) / value * math.sqrt(16 / 128)
    estimates = np.array([pooled(128, range(800 + 3 * k, 803 + 3 * k))[0] for k in range(8)])
    measured = estimates.std(ddof=1) / estimates.mean()
    assert 1 / 1.6 < predicted / measured < 1.6, (predicted, measured)
    unscaled = math.sqrt(var) / value
    assert not 1 / 1.6 < unscaled / measured < 1.6


def test_a_lone_slow_render_does_not_rule_the_cost_interval_and_coverage_holds(monkeypatch):
    """The paired costs' deviations are winsorized (stats.winsorize): one equal-time render
    of one method slowed 2x (a machine spike) leaves an A/A interval narrow, where the plain
    variance makes it wide (the negative control); on 400 synthetic A/A runs with 3%
    Gaussian timing noise the 95% interval still contains the true ratio (1) in 91-99%."""
    rng = np.random.default_rng(11)
    ca, cb = (2e-6 * (1 + 0.02 * rng.standard_normal(6)) for _ in range(2))
    cb[4] *= 2.0
    a = _runs((0.01, 1e-8), 64, ca, [64 * 2e-6] * 3)
    b = _runs((0.01, 1e-8), 64, cb, [64 * 2e-6] * 3)
    eff = suite_errors.efficiency(a, b)
    assert eff.hi / eff.lo < 1.5, (eff.lo, eff.hi)      # 3 repeats: Student t of 2 dof
    with monkeypatch.context() as m:
        m.setattr(stats, "winsorize", lambda values: np.asarray(values, np.float64))
        plain = suite_errors.efficiency(a, b)
    assert plain.hi / plain.lo > 3, (plain.lo, plain.hi)
    hits = 0
    for _ in range(400):
        ca, cb = (2e-6 * (1 + 0.03 * rng.standard_normal(6)) for _ in range(2))
        e = suite_errors.efficiency(_runs((0.01, 1e-12), 64, ca), _runs((0.01, 1e-12), 64, cb))
        hits += e.lo <= 1.0 <= e.hi
    assert 365 <= hits <= 396, hits


def test_a_cost_per_sample_that_differs_between_budgets_is_not_noise():
    """A method that learns costs twice as much per sample in its equal-time renders (it
    trains there) as in its short equal-spp ones: each budget's renders are compared with
    their own mean, so with 2% timing noise the interval stays as narrow as a plain pair's
    (hi/lo < 1.3), where one mean over both budgets (the negative control) reads the
    budgets' difference as noise (hi/lo > 2); on 400 synthetic runs with 3% noise the 95%
    interval contains the true ratio in 91-99%."""
    rng = np.random.default_rng(5)

    def pair(noise):
        ca = 2e-6 * (1 + noise * rng.standard_normal(6))
        cb = 3e-6 * np.array([1, 1, 1, 2, 2, 2]) * (1 + noise * rng.standard_normal(6))
        return _runs((0.02, 1e-8), 1024, ca), _runs((0.01, 1e-8), 1024, cb)
    a, b = pair(0.02)
    eff = suite_errors.efficiency(a, b)
    assert eff.hi / eff.lo < 1.3, (eff.lo, eff.hi)
    pooled = [np.array([c for _, g in r.costs for c in g]) for r in (b, a)]
    dev = pooled[0] / pooled[0].mean() - pooled[1] / pooled[1].mean()
    wide = stats.log_interval(math.log(eff.value), [(float(stats.winsorize(dev).var(ddof=1)) / 6, 5)],
                              3)
    assert wide.hi / wide.lo > 2, (wide.lo, wide.hi)
    weight = (EQUAL_SPP * 1 + 1024 * 2) / (EQUAL_SPP * 1 + 1024 * 1)
    truth, hits = (0.01 * 3 * weight) / (0.02 * 2), 0
    for _ in range(400):
        e = suite_errors.efficiency(*pair(0.03))
        hits += e.lo <= truth <= e.hi
    assert 365 <= hits <= 396, hits


def test_vr_moments_adds_the_raw_moments_after_the_nested_image_and_refuses_no_nested():
    """vr_moments: the nested integrator's image unchanged (same seed, same samples) in
    front, the means of the squares, cubes and fourth powers behind (for samples >= 0:
    m2 >= m1^2 and m4 >= m2^2 by Jensen, m1 m3 >= m2^2 by Cauchy-Schwarz), and a clear
    error without a nested integrator."""
    import mitsuba as mi
    import integrators  # noqa: F401
    mi.set_variant(VARIANT)
    scene = mi.load_file(scenes.path("suite/cbox.xml"), width=16, height=12)
    nested = {"type": "vr_path", "strategy": "bsdf", "emitter_sampling": True}
    wrapped = mi.load_dict({"type": "vr_moments", "nested": nested})
    assert list(wrapped.aov_names()) == [f"m{k}.{c}" for k in (2, 3, 4) for c in "RGB"]
    image = np.array(mi.render(scene, integrator=wrapped, spp=8, seed=3), dtype=np.float64)
    plain = np.array(mi.render(scene, integrator=mi.load_dict(nested), spp=8, seed=3))
    assert image.shape[-1] == plain.shape[-1] + 9
    assert np.allclose(image[..., :plain.shape[-1]], plain, rtol=1e-5, atol=1e-6)
    m1, (m2, m3, m4) = image[..., :3], np.split(image[..., -9:], 3, axis=-1)
    assert np.all(m2 >= m1 ** 2 * (1 - 1e-4) - 1e-7)
    assert np.all(m4 >= m2 ** 2 * (1 - 1e-4) - 1e-7)
    assert np.all(m1 * m3 >= m2 ** 2 * (1 - 1e-4) - 1e-7)
    assert np.any(m4 > 2 * m2 ** 2)        # not the squares again
    with pytest.raises(Exception, match="exactly one nested"):
        mi.load_dict({"type": "vr_moments"})


def test_the_adaptive_ceiling_is_the_oracle_allocations_gain():
    """Exact values: pixels of equal relative variance gain nothing; two pixels of relative
    variances 1 and 100 gain mean(v) / mean(sqrt v)^2 = 50.5 / 5.5^2; the repeats' maps are
    averaged first; no maps, no ceiling."""
    from experiments.lib.studies.suite import errors as E
    assert E.oracle_gain([np.full((4, 4), 0.3)]) == pytest.approx(1.0)
    assert E.oracle_gain([np.array([[1.0, 100.0]])]) == pytest.approx(50.5 / 5.5 ** 2)
    assert E.oracle_gain([np.array([[2.0, 50.0]]), np.array([[0.0, 150.0]])]) == \
        pytest.approx(50.5 / 5.5 ** 2)
    assert math.isnan(E.oracle_gain([])) and math.isnan(E.oracle_gain([None]))


def test_a_noisy_reference_is_said_to_touch_no_verdict_only_where_no_cell_uses_it():
    """The report's sentence on a scene whose every cell's relMSE comes from its pixels'
    variances; not where one cell (a QMC sampler's, from the repeats) is measured against
    the reference."""
    from types import SimpleNamespace as NS
    from experiments.lib.studies.suite import report
    precise = NS(runs={"equal_time": NS(expected=(0.1, 1e-4))})
    repeats = NS(runs={"equal_time": NS(expected=())})
    assert report.precise_only(NS(cells={"path": precise, "guided+nee": precise}))
    assert not report.precise_only(NS(cells={"path": precise, "zsobol": repeats}))
    assert not report.precise_only(NS(cells={}))

