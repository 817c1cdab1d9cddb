"""The sampler study's table and conclusion are computed from its numbers.

Synthetic ladders with a known winner: the conclusion must name it, with the
factor that follows from the numbers; change the numbers and it changes.
"""
import math

import pytest

from experiments.lib import sampler_study as SS

PIXELS = 100


def ladder(mse_at_1: float, slope: float, us: float, spps=(1, 4, 16, 64)):
    """MSE = mse_at_1 * spp^slope; time = us per sample."""
    return [SS.Point(n, us * 1e-6 * n * PIXELS, mse_at_1 * n ** slope, 2 * mse_at_1 * n ** slope)
            for n in spps]


def synthetic(orthogonal_mse=0.07, halton_mse=0.2, halton_time=1.1):
    return {
        2: {"independent": ladder(1.0, -1.0, 10.0),
            "orthogonal": ladder(orthogonal_mse, -1.0, 20.0),      # eff 0.5 / 0.07 = 7.1x
            "halton:owen": ladder(halton_mse, -1.0, 10.0 * halton_time)},   # 1 / (0.2 * 1.1)
        8: {"independent": ladder(1.0, -1.0, 10.0),
            "multijitter": ladder(0.4, -1.0, 13.0),
            "halton:owen": ladder(0.5, -1.0, 11.0)},
    }


def test_table_numbers_follow_from_the_points():
    rows = {(r.depth, r.sampler): r for r in SS.table(synthetic(), PIXELS)}
    o = rows[(2, "orthogonal")]
    assert o.relative_mse == pytest.approx(0.07)
    assert o.relative_efficiency == pytest.approx(1 / (0.07 * 2.0))
    assert o.us_per_sample == pytest.approx(20.0)
    assert o.slope == pytest.approx(-1.0)
    assert o.spp == 64
    assert rows[(2, "independent")].relative_efficiency == pytest.approx(1.0)


def test_conclusion_names_the_known_winner_and_its_factor():
    depth2, depth8 = SS.conclude(SS.table(synthetic(), PIXELS))
    eff_o, eff_h = 1 / (0.07 * 2.0), 1 / (0.2 * 1.1)
    assert depth2.startswith(f"At max_depth 2, orthogonal is the most efficient sampler: "
                             f"{eff_o:.2f}x")
    assert f"{eff_o / eff_h:.2f}x the next best (halton:owen)" in depth2
    assert f"{eff_h / eff_o:.2f}x the best native sampler's (orthogonal), so it does not win" \
        in depth2
    eff_mj, eff_h8 = 1 / (0.4 * 1.3), 1 / (0.5 * 1.1)
    assert eff_h8 < eff_mj
    assert depth8.startswith(f"At max_depth 8, multijitter is the most efficient sampler: "
                             f"{eff_mj:.2f}x")
    assert "lowest MSE is multijitter's (0.40x" in depth8


def test_conclusion_follows_the_numbers_when_halton_wins():
    depth2, _ = SS.conclude(SS.table(synthetic(orthogonal_mse=0.5, halton_mse=0.05), PIXELS))
    assert depth2.startswith("At max_depth 2, halton:owen is the most efficient sampler")
    assert depth2.endswith("so it wins.")
    assert "lowest MSE is halton:owen's (0.05x" in depth2


def test_slope_of_a_qmc_like_ladder():
    rows = SS.table({2: {"independent": ladder(1.0, -1.0, 10.0),
                         "ldsampler": ladder(1.0, -1.5, 20.0)}}, PIXELS)
    assert [r.slope for r in rows] == pytest.approx([-1.0, -1.5])
    assert math.isfinite(rows[1].relative_efficiency)
