"""The A/A pair's round of more renders where the precision rule's factor is capped.

Where the equal-spp renders of the baseline or the timed pair predict their equal-time
error known to worse than ``precision.PRECISION``, the pair and the baseline render the
one round of more renders (``bias_renders.imprecise``), whose renders join their
expected errors but not their costs (``measure._runs``). The round is chosen from the
equal-spp renders alone: pooling more renders into a cell because its own equal-time
draws caught a rare bright sample would bias its error low (optional stopping).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from experiments.lib.measurements import Run
from experiments.lib.methods import parse_method
from experiments.lib.studies.suite import bias_renders, declare, measure, precision

H = W = 8


def runs(rng, k: int, spp: int, spread: float) -> list:
    """k renders of ``spp`` samples per pixel on a reference of 1 everywhere whose pixels'
    variances of the mean are lognormal across the renders (``spread``: its sigma; 0: the
    same in every render)."""
    out = []
    for _ in range(k):
        var = np.exp(spread * rng.standard_normal((H, W, 1))) * np.ones((H, W, 3)) / spp
        out.append(Run(spp, 1.0, 0.0, 0.0, np.ones((H, W, 3)), variance=var))
    return out


def test_the_predicted_error_falls_as_one_over_the_root_of_the_samples():
    """Exact: the same renders predict at 4 times their count half the relative standard
    error of their own count; without pixel variances, None."""
    rng = np.random.default_rng(1)
    spp_runs = runs(rng, 3, 16, 1.0)
    ref = np.ones((H, W, 3))
    own = bias_renders.predicted_error(spp_runs, ref, 16)
    assert own > 0
    assert bias_renders.predicted_error(spp_runs, ref, 64) == pytest.approx(own / 2, rel=1e-12)
    plain = [Run(16, 1.0, 0.0, 0.0, np.ones((H, W, 3)))]
    assert bias_renders.predicted_error(plain, ref, 64) is None


class Measured:
    """One scene's renders per (method, budget), what bias_renders.imprecise reads."""

    def __init__(self, cells: dict):
        self.cells = cells

    def failed_on(self, scene):
        return {}

    def final(self, cell):
        return self.cells[(cell.method, cell.budget)]


def chosen(spp_spread: float, time_spread: float) -> dict:
    rng = np.random.default_rng(7)
    cfg = SimpleNamespace(baseline=parse_method("path"),
                          methods=[parse_method(n) for n in ("cosine", "bsdf+nee", "path")])
    cells = {(m, b): runs(rng, 3, spp, spread) for m in ("path", "bsdf+nee", "cosine")
             for b, spp, spread in ((declare.SPP, 16, spp_spread),
                                    (declare.TIME, 64, time_spread))}
    sp = declare.ScenePlan("s", "s.xml", box=True)
    return bias_renders.imprecise(cfg, [sp], Measured(cells),
                                  lambda plan: SimpleNamespace(image=np.ones((H, W, 3))))


def test_the_round_is_chosen_from_the_equal_spp_renders_alone():
    """Equal-spp renders whose pixel variances spread widely (lognormal sigma 3: an error
    known to 38% at their count, 19% at the equal-time count, over 3.5%): the baseline
    and the timed pair render the round, not the other methods. Equal-spp renders that
    agree (sigma 0) choose none, however widely the equal-time renders spread."""
    assert precision.PRECISION == 0.035
    assert chosen(3.0, 0.0) == {"s": ["bsdf+nee", "path"]}
    assert chosen(0.0, 3.0) == {}


def test_the_rounds_renders_join_the_expected_error_and_not_the_costs():
    """Three renders and six more of the round: the expected relMSE is the mean of the
    nine renders' own (exact), each listed; the per-repeat errors and seconds stay the
    three's."""
    rng = np.random.default_rng(3)
    first, more = runs(rng, 3, 64, 1.0), runs(rng, 6, 64, 1.0)
    ref = SimpleNamespace(image=np.ones((H, W, 3)), floor_map=lambda: np.zeros((H, W, 3)))
    got, _ = measure._runs(first, ref, [1e-9] * 3, "none", extra=more)
    own = [float(np.mean(r.variance / 1.01)) for r in first + more]
    assert got.expected[0] == pytest.approx(float(np.mean(own)), rel=1e-12)
    assert len(got.each) == 9 and len(got.relmse) == 3 and len(got.seconds) == 3
    alone, _ = measure._runs(first, ref, [1e-9] * 3, "none")
    assert alone.expected[0] == pytest.approx(float(np.mean(own[:3])), rel=1e-12)
    assert math.isfinite(got.expected[1]) and got.expected[1] < alone.expected[1]


def test_each_round_serves_the_reason_it_was_chosen_for():
    """The round's renders of a cell go to its bias test where its test was void, to its
    errors where the pair's error was unsure, each only there (exact selections)."""
    more = {"path": ["p"], "bsdf+nee": ["b"], "cosine": ["c"]}
    void, unsure = ["cosine", "path"], ["bsdf+nee", "path"]
    assert bias_renders.only(more, void) == {"path": ["p"], "cosine": ["c"]}
    assert bias_renders.only(more, unsure) == {"path": ["p"], "bsdf+nee": ["b"]}
    assert bias_renders.union({"s": void}, {"s": unsure}) == \
        {"s": ["cosine", "path", "bsdf+nee"]}
