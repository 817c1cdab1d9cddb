"""More renders for a cell whose bias test its tails voided
(experiments/lib/studies/suite/bias_renders.py), tested with them
(experiments/lib/studies/suite/measure.py's ``bias_tests``), and the image test's skewness
gate (``bias_image.MAX_SKEW``).

Synthetic cells at the suite's film (48x36): most pixels of light tails, and a few rare-sample
pixels (a sample of mu / q with probability q, else 0: a light seen through a narrow lobe)
that rule the image sum's variance. At the run's 3 + 3 renders those pixels' own moments
say the sum is skewed (untestable); with the round's more renders it is tested, its size
and power measured here. Real scenes: the suite's own runs (docs/methodology.md).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from experiments.lib import bias_image
from experiments.lib.declaration import Cell
from experiments.lib.jobs import third_of_mean, variance_of_variance
from experiments.lib.measurements import Run
from experiments.lib.studies.suite import bias_renders, declare, measure
from experiments.lib.studies.suite.bias_test import CellBias
from test_suite_bias import ALPHA, SEEDS, C, FakeMethod, H, W, renders

#: Rare-sample pixels, their mean and the probability of their one bright sample.
RARE, RARE_MEAN, RARE_Q = 10, 5.0, 0.001
#: The equal-time count of the synthetic cell.
SPP = 1024


@pytest.fixture(autouse=True)
def reach_every_lobe(monkeypatch):
    """The scene here is a stand-in with no file: every cell's samples reach every lobe
    (measure.reach, tested in tests/test_bias_reach.py)."""
    monkeypatch.setattr(measure, "reach", lambda sp, method: 1.0)


def own_renders(rng, mu, rare, k, spp, factor=1.0):
    """k renders of ``spp`` samples per pixel as the suite keeps them (a
    :class:`~experiments.lib.measurements.Run` each: means, own variances, how sure they
    are, third cumulants): normal samples (sd = mu), but in the ``rare`` pixels one
    bright sample of mu / q with probability q."""
    out = []
    for _ in range(k):
        hits = rng.binomial(spp, RARE_Q, mu.shape) / spp
        m = [hits * (factor * mu / RARE_Q) ** p for p in (1, 2, 3, 4)]
        mean = factor * (mu + mu / math.sqrt(spp) * rng.standard_normal(mu.shape))
        s2 = np.square(factor * mu) * rng.chisquare(spp - 1, mu.shape) / (spp - 1)
        image = np.where(rare, m[0], mean)
        var = np.where(rare, np.maximum(m[1] - m[0] ** 2, 0.0) / (spp - 1), s2 / spp)
        vv = np.where(rare, variance_of_variance(*m, spp), 2.0 * s2 * s2 / ((spp - 1) * spp * spp))
        k3 = np.where(rare, third_of_mean(m[0], m[1], m[2], spp), 0.0)
        out.append(Run(spp, 1.0, 0.0, 0.0, image, variance=var, variance_var=vv, third=k3))
    return out


class Measured:
    """What :func:`measure.bias_tests` reads of the engine's measurements: one scene, one
    method, its renders per budget."""

    def __init__(self, runs: dict):
        self.runs = runs
        self.declaration = SimpleNamespace(methods=(FakeMethod(),))

    def failed_on(self, scene):
        return {}

    def final(self, cell):
        return self.runs[cell.budget]


def rare_cell(seed: int, more: int, factor: float = 1.0) -> CellBias:
    """The cell's bias test at the run's level: 3 renders of 16 spp, 3 of :data:`SPP` and
    ``more`` of :data:`SPP` from the round (the reference: 32 chunks of 256 spp)."""
    rng = np.random.default_rng(seed)
    mu = rng.uniform(0.05, 1.0, (H, W, C))
    rare = np.zeros(mu.shape, bool)
    rare[rng.choice(H, RARE), rng.choice(W, RARE)] = True
    mu[rare] = RARE_MEAN
    measured = Measured({declare.SPP: own_renders(rng, mu, rare, 3, 16, factor),
                         declare.TIME: own_renders(rng, mu, rare, 3, SPP, factor)})
    extra = {"mine": own_renders(rng, mu, rare, more, SPP, factor)} if more else None
    sp = declare.ScenePlan("s", "s.xml", box=True)
    cfg = SimpleNamespace(reference_method=FakeMethod("path"))
    return measure.bias_tests(cfg, sp, measured, renders(rng, mu, 32, 256), ALPHA, extra)["mine"]


def test_a_void_cell_is_tested_with_its_round_of_more_renders():
    """At the run's renders the rare pixels make the image sum skewed (own skewness over
    bias_image.MAX_SKEW): untestable, heavy tails, in every seed. With the round's
    renders (bias_renders.MORE x 3 at the equal-time count, added to that budget's) the
    same cells are tested in at least 18 of 20 seeds (20 measured), none flagged, and a 5%
    darkening is found in at least 18 of 20 (20 measured; detectable about 3%)."""
    more = bias_renders.MORE * 3
    tested = flagged = found = 0
    for seed in range(SEEDS):
        first = rare_cell(seed, 0)
        assert first.status == "untestable" and first.reason == "heavy_tails", first
        assert first.own_skew > bias_image.MAX_SKEW and first.extra == 0
        again = rare_cell(seed, more)
        assert again.extra == more and again.variance == "moments"
        tested += again.status != "untestable"
        flagged += again.biased is True
        found += rare_cell(100 + seed, more, 0.95).biased is True
    assert tested >= 0.9 * SEEDS and flagged == 0 and found >= 0.9 * SEEDS, \
        (tested, flagged, found)


def test_the_round_picks_the_cells_whose_tails_voided_their_test():
    """Only ``heavy_tails`` cells render again: not a cell without power (its variance is
    known), not a deterministic sampler's, not a tested one."""
    tests = {"a": {"m1": CellBias("untestable", "heavy_tails"),
                   "m2": CellBias("untestable", "no_power"),
                   "m3": CellBias("unbiased"), "m4": CellBias("untestable", "deterministic")},
             "b": {"m1": CellBias("biased")},
             "c": {"m5": CellBias("untestable", "heavy_tails")}}
    assert bias_renders.void(tests) == {"a": ["m1"], "c": ["m5"]}


def test_a_cell_the_round_cannot_help_is_left_untestable():
    """A cell whose own moments say the round's samples (about 1 + bias_renders.MORE times
    its own) would leave its sum over twice the skewness gate, or its variance under half
    the degrees of freedom (infinite variance: rough glass sampled by the cosine, skewness
    0.6-1, 2-9 dof), renders nothing more; one just over either gate does."""
    def tails(skew, dof):
        return CellBias("untestable", "heavy_tails", "moments", own_dof=dof, own_skew=skew)
    gain = math.sqrt(1 + bias_renders.MORE)
    edge = 2 * bias_image.MAX_SKEW * gain
    tests = {"s": {"infinite": tails(0.9, 4.0), "skewed": tails(1.05 * edge, 500.0),
                   "few": tails(0.05, 0.9 * bias_image.MIN_DOF / 2 / (1 + bias_renders.MORE)),
                   "near": tails(0.95 * edge, 20.0), "spread": CellBias(
                       "untestable", "heavy_tails", "renders")}}
    assert bias_renders.void(tests) == {"s": ["near", "spread"]}


def test_the_rounds_renders_are_their_own_jobs_at_each_cells_equal_time_count():
    """One declaration per scene and equal-time count, its methods those void cells,
    bias_renders.MORE x the run's repeats, job keys of their own (their seeds differ from
    the suite's renders)."""
    plans = [declare.ScenePlan(n, f"{n}.xml", info=SimpleNamespace(name=n), box=True)
             for n in ("a", "b")]
    counts = {("a", "m1"): 256, ("a", "m2"): 256, ("a", "m3"): 1024, ("b", "m1"): 64}
    runs = {Cell(s, m, declare.TIME): [SimpleNamespace(spp=n)] * 3
            for (s, m), n in counts.items()}
    measured = SimpleNamespace(final=lambda cell: runs[cell])
    methods = tuple(FakeMethod(n) for n in ("m1", "m2", "m3"))
    cfg = SimpleNamespace(methods=methods, repeats=3, reference_spp=64,
                          reference_method=FakeMethod("path"), reference_typical_spp=None)
    got = bias_renders.declarations(cfg, plans, measured,
                                    {"a": ["m1", "m2", "m3"], "b": ["m1"]})
    seen = {(d.scenes[0].name, d.budgets[0].spp): [m.name for m in d.methods] for d in got}
    assert seen == {("a", 256): ["m1", "m2"], ("a", 1024): ["m3"], ("b", 64): ["m1"]}
    assert all(d.repeats == bias_renders.MORE * 3 and d.name == bias_renders.NAME and
               d.name != declare.NAME for d in got)
