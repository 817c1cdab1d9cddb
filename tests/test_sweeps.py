"""Each stability sweep's analysis is computed from its numbers (no rendering here).

Synthetic measurements whose conclusion is known: the analysis must find the
onset where it was planted, say "nowhere in the sweep" where there is none
(negative controls), and claim a difference only when the repeats' interval
excludes none. Repeats are synthetic too: value x (1 + small noise), so the
95% intervals are narrow, or two wildly different values, so they are wide.
"""

import numpy as np
import pytest

from experiments.lib import stats
from experiments.lib.sweeps import (REGISTRY, SWEEPS, exponent, grazing, halton_randomization,
                                    light)
from experiments.lib.sweeps import adaptive_pilot
from experiments.lib.sweeps.base import BREAK_FACTOR, Run, exceeds, mean_interval, onset

NOISE = (0.97, 1.0, 1.03)          # three repeats, +-3%


def runs(value, seconds=1.0, noise=NOISE, level=1.0):
    """Repeats of one method at one point with relMSE ``value`` x noise."""
    return [Run(value * k, value * k, level, seconds) for k in noise]


# ----------------------------------------------------------------- shared

def test_registry_lists_every_sweep_with_the_whole_protocol():
    assert SWEEPS == ("exponent", "light", "grazing", "halton", "adaptive")
    for name, sweep in REGISTRY.items():
        assert sweep.name == name
        for step in ("declare", "measure", "analyse", "report"):
            assert callable(getattr(sweep, step)), (name, step)


def test_onset_and_interval_decisions():
    assert onset("exponent", None, str) == "nowhere in the sweep"
    assert onset("exponent", 100, str) == "from exponent 100"
    narrow = stats.mean_interval([11.0, 12.0, 11.5])
    wide = stats.mean_interval([0.5, 40.0])
    assert exceeds(narrow, BREAK_FACTOR) and not exceeds(wide, BREAK_FACTOR)
    one = stats.mean_interval([12.0])                 # one run: the point estimate decides
    assert not one.known and exceeds(one, BREAK_FACTOR)
    assert mean_interval([0.0, 0.0]).value == 0.0


# ----------------------------------------------------------------- exponent

XS = [1, 10, 100, 1000, 10000]


def exponent_data(cos=(1.0, 1.0, 30.0, 90.0, 270.0), noise=NOISE, mis=True):
    """bsdf relMSE 1 everywhere; cosine ``cos`` (explodes from exponent 100); uniform 3x it."""
    data = {"bsdf": [runs(1.0, noise=noise) for _ in XS],
            "cosine": [runs(c, noise=noise) for c in cos],
            "uniform": [runs(3.0 * c, noise=noise) for c in cos]}
    if mis:
        data["mis"] = [runs(1.2, noise=noise) for _ in XS]
    return exponent.ExponentData(XS, data, spp=32, mask_pixels=50, pixels=1000)


def test_exponent_sweep_reports_where_cosine_explodes():
    res = exponent.analyse(exponent_data())
    words = exponent.sentences(res)
    cos = next(c for c in res.comparisons if c.other == "cosine")
    assert cos.explodes_from == 100 and cos.pays_from == 100 and cos.worse_at == []
    assert cos.relmse_ratio[2].lo < 30 < cos.relmse_ratio[2].hi
    text = next(s for s in words if "vs cosine" in s)
    assert "cosine sampling explodes (relMSE > 10x lobe sampling's) from exponent 100" in text
    assert "bsdf is more efficient than cosine by" in text
    assert "over 3 repeats" in text
    # uniform is 3x cosine: lobe sampling pays off (>= 2x) from the start, explodes from 100
    uni = next(c for c in res.comparisons if c.other == "uniform")
    assert uni.pays_from == 1 and uni.explodes_from == 100
    assert res.mis is not None and res.mis[0].value == pytest.approx(1.2)
    assert "relMSE(mis) / min(relMSE(cosine), relMSE(bsdf))" in words[-1]


def test_exponent_sweep_without_explosion_says_nowhere():
    res = exponent.analyse(exponent_data(cos=(1.0,) * 5, mis=False))
    words = exponent.sentences(res)
    cos = next(c for c in res.comparisons if c.other == "cosine")
    assert cos.explodes_from is None and cos.pays_from is None
    text = next(s for s in words if "vs cosine" in s)
    assert "explodes (relMSE > 10x lobe sampling's) nowhere in the sweep" in text
    assert "bsdf and cosine are not distinguishable at this budget" in text
    assert res.mis is None


def test_exponent_onset_needs_the_interval_above_the_factor():
    """Cosine's mean ratio is 30 at exponent 100, but its repeats (0.5 and 59.5) are too
    spread for the interval's lower bound to exceed 10: no explosion is claimed there."""
    data = exponent_data()
    wild = (0.5 / 30, 59.5 / 30)
    data.runs["cosine"] = [runs(1.0), runs(1.0), runs(30.0, noise=wild), runs(90.0),
                           runs(270.0)]
    data.runs["bsdf"] = [runs(1.0, noise=(1.0, 1.0)) for _ in XS]
    cos = next(c for c in exponent.analyse(data).comparisons if c.other == "cosine")
    assert cos.relmse_ratio[2].value == pytest.approx(30.0)
    assert cos.explodes_from == 1000


def test_exponent_sweep_with_one_repeat_says_it_has_no_interval():
    res = exponent.analyse(exponent_data(noise=(1.0,)))
    words = exponent.sentences(res)
    text = next(s for s in words if "vs cosine" in s)
    assert "from exponent 100" in text and "one run: no interval" in text
    assert "1 run gives no interval" in text


# ----------------------------------------------------------------- light

SIZES = [2, 1, 0.5, 0.2, 0.05, 0.02]


def light_data(growth=(1, 2, 4, 20, 200, 2000), nee=(1, 1, 1.1, 1.2, 1.3, 1.4)):
    return light.LightData(SIZES, {"bsdf": [runs(v) for v in growth],
                                   "bsdf+nee": [runs(v) for v in nee]},
                           nee="bsdf+nee", spp=32, radiance=[1.0] * len(SIZES))


def test_light_sweep_nee_wins_on_small_lights():
    res = light.analyse(light_data())
    words = light.sentences(res)
    (c,) = res.comparisons
    # 20 / 1.2 = 16.7 > 10 at size 0.2, 4 / 1.1 = 3.6 at 0.5
    assert c.breaks_from == 0.2
    assert c.growth.value == pytest.approx(2000)
    assert "relMSE exceeds 10x bsdf + NEE's from light size 0.2" in words[0]
    assert "bsdf + NEE is more efficient than bsdf by" in words[0]
    assert words[-1].endswith("next-event estimation + MIS holds.")


def test_light_sweep_without_breakdown_negative_control():
    flat = (1, 1, 1, 1, 1, 1)
    res = light.analyse(light_data(growth=flat, nee=flat))
    words = light.sentences(res)
    (c,) = res.comparisons
    assert c.breaks_from is None
    assert "nowhere in the sweep" in words[0]
    assert "bsdf + NEE and bsdf are not distinguishable at this budget" in words[0]


def test_light_sweep_says_when_nee_degrades_too():
    res = light.analyse(light_data(nee=(1, 2, 10, 30, 100, 300)))
    words = light.sentences(res)
    assert "degrades too" in words[-1]


# ----------------------------------------------------------------- adaptive

def runs_dark(value, dark, noise=NOISE):
    """Repeats with whole-image relMSE ``value`` and dark-pixel relMSE ``dark``."""
    return [Run(value * k, dark * k, 1.0, 1.0) for k in noise]


def adaptive_data(bsdf=(1, 1, 1, 1, 1, 1), bsdf_dark=(1, 1, 1, 1, 1, 1)):
    """Plain methods at relMSE 1 everywhere; ``bsdf+adaptive`` at ``bsdf`` x that (whole
    image) and ``bsdf_dark`` (dark pixels); ``bsdf+nee+adaptive`` at 0.5 (a gain)."""
    runs = {"bsdf": [runs_dark(1, 1) for _ in SIZES],
            "bsdf+adaptive": [runs_dark(w, d) for w, d in zip(bsdf, bsdf_dark)],
            "bsdf+nee": [runs_dark(1, 1) for _ in SIZES],
            "bsdf+nee+adaptive": [runs_dark(0.5, 0.5) for _ in SIZES]}
    return adaptive_pilot.AdaptiveData(SIZES, runs, ("bsdf", "bsdf+nee"), spp=11)


def test_adaptive_sweep_finds_where_the_pilot_misleads_it():
    res = adaptive_pilot.analyse(adaptive_data(bsdf=(0.9, 0.9, 1.0, 2.0, 3.0, 3.0),
                                         bsdf_dark=(1, 1, 1, 1, 1, 4.0)))
    plain, nee = res.comparisons
    assert plain.method == "bsdf" and plain.ratio[3].value == pytest.approx(2.0)
    assert plain.loses_from == 0.2 and plain.dark_loses_from == 0.02
    assert nee.loses_from is None and nee.ratio[0].value == pytest.approx(0.5)
    words = adaptive_pilot.sentences(res)
    assert "bsdf + adaptive against bsdf at equal samples (11 spp)" in words[0]
    assert "it loses (ratio above 1) from light size 0.2" in words[0]
    assert "it loses there from light size 0.02" in words[0]
    assert "bsdf + NEE + adaptive against bsdf + NEE" in words[1]
    assert "loses (ratio above 1) nowhere in the sweep" in words[1]


def test_adaptive_sweep_negative_control_no_loss_claimed_without_the_interval():
    flat = adaptive_pilot.analyse(adaptive_data())
    assert all(c.loses_from is None and c.dark_loses_from is None for c in flat.comparisons)
    # two wildly different repeats: a ratio of 3 whose interval holds 1 is not a loss
    wide = adaptive_data()
    wide.runs["bsdf+adaptive"][4] = [Run(v, 1.0, 1.0, 1.0) for v in (0.05, 5.95)]
    assert adaptive_pilot.analyse(wide).comparisons[0].loses_from is None


def test_dark_mask_is_the_darkest_share_of_the_reference():
    ref = np.zeros((2, 4, 3))
    ref[..., :] = np.arange(8, dtype=float).reshape(2, 4, 1)[::-1]      # 7 ... 0
    mask = adaptive_pilot.dark_mask(ref, 0.25)
    assert mask.sum() == 2 and (ref[mask] <= 1.0).all()
    assert adaptive_pilot.dark_mask(ref, 0.01).sum() == 1                     # at least one pixel


# ----------------------------------------------------------------- grazing

ANGLES = [0, 30, 60, 85, 89]


def graz(wasted, relvar, noise=NOISE):
    return [[{"albedo": 0.5, "wasted": w, "relvar": rv * k, "nonfinite": 0} for k in noise]
            for w, rv in zip(wasted, relvar)]


def test_grazing_reports_the_wasted_fraction_and_the_efficiency_loss():
    data = grazing.GrazingData(ANGLES, {
        ("bsdf", 100): graz([0, 0.01, 0.1, 0.6, 0.9], [1, 1.1, 1.5, 8, 50]),
        ("cosine", 100): graz([0, 0, 0, 0, 0], [5, 5, 5, 5, 5])}, samples=1000)
    res = grazing.analyse(data)
    words = grazing.sentences(res)
    bsdf = next(c for c in res.curves if c.strategy == "bsdf")
    cosine = next(c for c in res.curves if c.strategy == "cosine")
    assert bsdf.half_from == 85 and bsdf.loss_from == 85
    assert bsdf.efficiency[-1].value == pytest.approx(1 / 50)
    assert bsdf.wasted[-1] == pytest.approx(0.9)
    # negative control: nothing wasted, efficiency flat
    assert cosine.half_from is None and cosine.loss_from is None
    assert cosine.efficiency[-1].value == pytest.approx(1.0)
    text = words[0]
    assert text.startswith("Grazing, bsdf at exponent 100: 90% of the samples are wasted")
    assert "half are wasted from 85 degrees" in text
    assert "below half of normal incidence's from 85 degrees" in text
    assert words[-1] == f"Grazing: 0 non-finite sample weights over {1000 * 3 * 5 * 2} samples."


def test_grazing_efficiency_loss_needs_the_interval_below_half():
    """A relVar ratio of 2.5 whose repeats disagree wildly is not claimed as a loss."""
    data = grazing.GrazingData(ANGLES, {("mis", 10): graz(
        [0, 0, 0, 0, 0], [1, 1, 1, 1, 2.5], noise=(1.0, 1.0))}, samples=10)
    data.stats[("mis", 10)][-1] = [{"albedo": 0.5, "wasted": 0, "relvar": v, "nonfinite": 0}
                                   for v in (0.1, 4.9)]
    (c,) = grazing.analyse(data).curves
    assert c.efficiency[-1].value == pytest.approx(1 / 2.5)
    assert c.loss_from is None


# ----------------------------------------------------------------- halton

SPP = [1, 2, 4, 8, 16, 32, 64]


def ladder(errors, noise=NOISE):
    return [[(n, 0.01 * n, e * k) for n, e in zip(SPP, errors)] for k in noise]


def halton_data(none_errors):
    indep = [1.0 / n for n in SPP]
    owen = [0.5 / n ** 1.5 for n in SPP]
    curves = {2: {"uniform": ladder(indep), "uniform+halton:none": ladder(none_errors, (1, 1, 1)),
                  "uniform+halton:owen": ladder(owen)}}
    corr = {2: {"uniform": [0.0] * 3, "uniform+halton:none": [0.8] * 3,
                "uniform+halton:owen": [0.01] * 3}}
    return halton_randomization.HaltonData("uniform", curves, corr)


def test_halton_none_is_worse_than_independent_from_n_spp():
    # plain Halton: better at first, stuck at 0.05 from 16 spp on (independent 1/16 = 0.0625)
    res = halton_randomization.analyse(halton_data([0.5, 0.25, 0.12, 0.07, 0.05, 0.05, 0.05]))
    words = halton_randomization.sentences(res)
    assert res.worse_from[2] == 32                      # 0.05 > 1/32 first at 32 spp
    text = words[0]
    assert "'none' is worse than independent sampling from 32 spp" in text
    assert "'none' is deterministic: its repeats are identical" in text
    assert "At 64 spp, uniform is more accurate than uniform+halton:none by" in text
    assert "At 64 spp, uniform+halton:owen is more accurate than uniform by" in text
    assert res.lines[2]["uniform+halton:owen"].slope == pytest.approx(-1.5)
    assert "none 0.80" in text


def test_halton_none_worse_only_at_low_spp_is_not_called_an_onset():
    res = halton_randomization.analyse(halton_data([2.0, 1.0, 0.01, 0.005, 0.002, 0.001, 0.0005]))
    words = halton_randomization.sentences(res)
    assert res.worse_at[2] == [1, 2]
    assert "worse than independent sampling at 1, 2 spp only" in words[0]


def test_halton_none_never_worse_negative_control():
    res = halton_randomization.analyse(halton_data([0.5 / n for n in SPP]))
    words = halton_randomization.sentences(res)
    assert res.worse_from[2] is None
    assert "worse than independent sampling nowhere in the sweep" in words[0]
