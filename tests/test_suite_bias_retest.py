"""A flagged cell's flag is tested again on fresh renders alone before it stands
(experiments/lib/studies/suite/bias_renders.py, ``confirmed``; study.py, ``retested``).

Synthetic renders of known law (48x36, per-sample standard deviation equal to the pixel's
mean, the reference 8 chunks of 128 spp): a right cell whose first renders drew 6% high
(what chance gives a cell at the run's level about once in a hundred default runs: in one,
mis+nee on veach_mis, +5.8% against a reference that every cell of the scene read 3% to 4%
low) is flagged by them, and not by 6 fresh renders of its law; a wrong cell, 6% high in
every render, is flagged by both.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from experiments.lib.studies.suite import bias_renders, bias_test, declare, measure, study

W, H, C = 48, 36, 3
ALPHA = bias_test.cell_level(9 * 15)


@dataclass(frozen=True)
class FakeMethod:
    name: str
    sampler: str = "independent"
    deterministic: bool = False
    learns: bool = False

    def trains(self, spp, pixels):
        return False


@dataclass
class Run:
    image: np.ndarray
    spp: int
    variance: None = None
    variance_var: None = None
    third: None = None


@dataclass
class Measured:
    runs: dict                           # {(method, budget): [Run]}
    methods: tuple = (FakeMethod("mine"), FakeMethod("path"))
    declaration: object = field(init=False)

    def __post_init__(self):
        self.declaration = type("D", (), {"methods": self.methods})()

    def failed_on(self, scene):
        return set()

    def final(self, cell):
        return self.runs[(cell.method, cell.budget)]


@dataclass(frozen=True)
class Plan:
    name: str = "scene"
    left_out: tuple = ()
    box: bool = True
    user_ref: None = None


@dataclass(frozen=True)
class Cfg:
    reference_method: FakeMethod = FakeMethod("path")


def draws(rng, mu, k, spp, factor=1.0) -> list:
    """k renders of spp samples per pixel: normal means, per-sample sd = mu."""
    return [Run(factor * (mu + mu / math.sqrt(spp) * rng.standard_normal((H, W, C))), spp)
            for _ in range(k)]


def first_and_fresh(seed: int, first: float, fresh: float):
    """The scene's first test (``mine`` drawn ``first`` times its law's mean at both
    budgets, path right), the reference's chunks and ``mine``'s 6 fresh renders at its
    equal-time count, ``fresh`` times the law's mean."""
    rng = np.random.default_rng(seed)
    mu = rng.uniform(0.05, 1.0, (H, W, C))
    runs = {("mine", declare.SPP): draws(rng, mu, 3, 16, first),
            ("mine", declare.TIME): draws(rng, mu, 3, 64, first),
            ("path", declare.SPP): draws(rng, mu, 3, 16),
            ("path", declare.TIME): draws(rng, mu, 3, 64)}
    chunks = np.stack([r.image for r in draws(rng, mu, 8, 128)])
    measured = Measured(runs)
    tests = measure.bias_tests(Cfg(), Plan(), measured, chunks, ALPHA)
    return measured, chunks, tests, {"mine": draws(rng, mu, 6, 64, fresh)}


@pytest.fixture(autouse=True)
def reached(monkeypatch):
    """Every lobe reached (no scene file to probe)."""
    monkeypatch.setattr(measure, "reach", lambda sp, method: math.inf)


@pytest.mark.parametrize("fresh, status, retest", [(1.0, "unbiased", "not confirmed"),
                                                   (1.06, "biased", "confirmed")])
def test_a_flag_is_tested_again_on_fresh_renders_alone(fresh, status, retest):
    measured, chunks, tests, more = first_and_fresh(3, 1.06, fresh)
    assert tests["mine"].status == "biased" and tests["path"].status == "unbiased"
    flagged = bias_renders.flagged({"scene": tests})
    assert flagged == {"scene": ["mine"]}
    out = study.retested(Cfg(), Plan(), measured, chunks, ALPHA, tests, more, {}, flagged)
    mine = out["mine"]
    assert (mine.status, mine.retest, mine.extra) == (status, retest, 6), mine
    assert mine.delta == tests["mine"].delta              # the first test's numbers kept
    assert (mine.retest_p < ALPHA) == (status == "biased"), mine.retest_p
    assert out["path"] == tests["path"]


def test_a_flag_stands_where_fresh_renders_cannot_tell():
    """Fresh renders whose tails void their test leave the first test's flag (it passed
    every gate)."""
    first = bias_test.CellBias("biased", p_pooled=1e-9, delta=(0.07,))
    void = bias_test.CellBias("untestable", "heavy_tails", p_pooled=0.3, extra=6)
    kept = bias_renders.confirmed(first, void)
    assert (kept.status, kept.retest, kept.retest_p, kept.extra) == ("biased", "void", 0.3, 6)
