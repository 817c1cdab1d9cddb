"""The sampler study's table and conclusion are computed from its numbers.

Synthetic ladders with a known answer: every count of a ladder has R repeats
whose MSEs scatter around a known value (a fixed relative spread, the same
pattern for every sampler, so the expected values and ratios are exact). The
conclusion must name the winner with the factor that follows from the numbers
and say "not distinguishable" when the interval contains 1; change the
numbers and it changes. An order change along the ladder (crossing curves)
must be found at the count where it happens.
"""
import math

import pytest

from experiments.lib import sampler_study as SS
from experiments.lib import stats

PIXELS = 100
#: Relative scatter of the repeats around their mean (mean exactly 1).
SPREAD = (0.9, 1.0, 1.1)


def ladder(mse_at_1: float, slope: float, us: float, spps=(1, 4, 16, 64), spread=SPREAD):
    """MSE = mse_at_1 * spp^slope (scattered by ``spread``); time = us per sample."""
    return [SS.Point(n, tuple(us * 1e-6 * n * PIXELS for _ in spread),
                     tuple(mse_at_1 * n ** slope * f for f in spread),
                     tuple(2 * mse_at_1 * n ** slope * f for f in spread)) for n in spps]


def synthetic(orthogonal_mse=0.07, halton_mse=0.2, halton_time=1.1, spread=SPREAD):
    return {
        2: {"independent": ladder(1.0, -1.0, 10.0, spread=spread),
            "orthogonal": ladder(orthogonal_mse, -1.0, 20.0, spread=spread),   # eff 7.1x
            "halton:owen": ladder(halton_mse, -1.0, 10.0 * halton_time, spread=spread)},
        8: {"independent": ladder(1.0, -1.0, 10.0, spread=spread),
            "multijitter": ladder(0.4, -1.0, 13.0, spread=spread),
            "halton:owen": ladder(0.5, -1.0, 11.0, spread=spread)},
    }


def test_table_numbers_follow_from_the_points():
    rows = {(r.depth, r.sampler): r for r in SS.table(synthetic(), PIXELS)}
    o = rows[(2, "orthogonal")]
    assert o.relative_mse.value == pytest.approx(0.07)
    assert o.relative_efficiency.value == pytest.approx(1 / (0.07 * 2.0))
    assert o.relative_efficiency.lo < o.relative_efficiency.value < o.relative_efficiency.hi
    assert o.us_per_sample == pytest.approx(20.0)
    assert o.slope == pytest.approx(-1.0)
    assert (o.spp, o.repeats) == (64, 3)
    assert rows[(2, "independent")].relative_efficiency.value == pytest.approx(1.0)
    record = o.record()
    assert record["relative_efficiency_lo"] < record["relative_efficiency"] \
        < record["relative_efficiency_hi"]
    assert {"mse_lo", "mse_hi", "relmse_lo", "relmse_hi"} <= set(record)


def test_conclusion_names_the_known_winner_and_its_factor():
    points = synthetic()
    depth2, depth8 = SS.conclude(SS.table(points, PIXELS), points)
    eff_o, eff_h = 1 / (0.07 * 2.0), 1 / (0.2 * 1.1)
    assert depth2.startswith(f"At max_depth 2 and 64 spp (3 independent runs each), "
                             f"orthogonal has the highest efficiency 1/(MSE x time): "
                             f"{eff_o:.3g} (95% CI")
    assert f"orthogonal is more efficient than halton:owen by {eff_o / eff_h:.3g} (95% CI" \
        in depth2
    eff_mj, eff_h8 = 1 / (0.4 * 1.3), 1 / (0.5 * 1.1)
    assert depth8.startswith(f"At max_depth 8 and 64 spp (3 independent runs each), "
                             f"multijitter has the highest efficiency 1/(MSE x time): "
                             f"{eff_mj:.3g} (95% CI")
    # 6% apart with a 10% scatter over 3 repeats: no verdict either way
    assert f"multijitter and halton:owen are not distinguishable at this budget (ratio " \
           f"{eff_mj / eff_h8:.3g}" in depth8
    assert "lowest expected MSE is multijitter's (0.4 (95% CI" in depth8


def test_conclusion_follows_the_numbers_when_halton_wins():
    points = synthetic(orthogonal_mse=0.5, halton_mse=0.05)
    depth2, _ = SS.conclude(SS.table(points, PIXELS), points)
    assert "halton:owen has the highest efficiency" in depth2
    # orthogonal (MSE 0.5 at twice the time) only ties independent: the best native is the
    # first of the two
    assert "against the best native sampler, independent: halton:owen is more efficient " \
           "than independent by" in depth2
    assert "against orthogonal, halton:owen is more efficient at 1-64 spp" in depth2
    assert "lowest expected MSE is halton:owen's (0.05 (95% CI" in depth2


def test_close_samplers_are_not_distinguishable():
    """Negative control: a 3% difference with a 20% scatter is no verdict."""
    wide = (0.8, 1.0, 1.2)
    points = {2: {"independent": ladder(1.0, -1.0, 10.0, spread=wide),
                  "multijitter": ladder(0.5, -1.0, 10.0, spread=wide),
                  "halton:owen": ladder(0.5 / 1.03, -1.0, 10.0, spread=(1.2, 1.0, 0.8))}}
    text, = SS.conclude(SS.table(points, PIXELS), points)
    assert "halton:owen and multijitter are not distinguishable at this budget" in text
    assert "is more efficient than multijitter" not in text


def test_order_change_along_the_ladder_is_found():
    """Halton's MSE falls faster (slope -1.5) than orthogonal's (-1): it loses at 1 and 4 spp,
    ties about 16 and wins from 64 spp."""
    spps = (1, 4, 16, 64, 256)
    ortho = ladder(0.1, -1.0, 10.0, spps)
    halton = ladder(0.4, -1.5, 10.0, spps)        # ratio 0.25 x spp^0.5: 0.25, 0.5, 1, 2, 4
    changes = SS.order_changes(halton, ortho)
    assert [c[1] for c in changes] == [-1, -1, 0, 1, 1]
    assert changes[3][2].value == pytest.approx(2.0)
    text = SS.describe_order("halton:owen", "orthogonal", changes)
    assert text == ("against orthogonal, halton:owen is less efficient at 1-4 spp, not "
                    "distinguishable at 16 spp, more efficient from 64 spp (halton:owen "
                    "overtakes orthogonal from 64 spp)")
    same = SS.describe_order("a", "b", SS.order_changes(ortho, ortho))
    assert same == "against b, a is not distinguishable at any count of the ladder (1-256 spp)"


def test_curves_give_the_ratio_at_every_count():
    curves = SS.curves(synthetic())
    pts = curves[2]["orthogonal"]
    assert [spp for spp, _ in pts] == [1, 4, 16, 64]
    assert all(e.value == pytest.approx(1 / (0.07 * 2.0)) for _, e in pts)


def test_slope_of_a_qmc_like_ladder():
    rows = SS.table({2: {"independent": ladder(1.0, -1.0, 10.0),
                         "ldsampler": ladder(1.0, -1.5, 20.0)}}, PIXELS)
    assert [r.slope for r in rows] == pytest.approx([-1.0, -1.5])
    assert math.isfinite(rows[1].relative_efficiency.value)


def test_one_repeat_gives_no_interval_and_no_verdict():
    points = synthetic(spread=(1.0,))
    rows = SS.table(points, PIXELS)
    assert not any(r.relative_efficiency.known for r in rows if r.sampler != "independent")
    depth2, _ = SS.conclude(rows, points)
    assert "no interval" in depth2 and "is more efficient than" not in depth2
    assert isinstance(rows[0].mse, stats.Estimate)
