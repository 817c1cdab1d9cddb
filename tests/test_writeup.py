"""The writeup study's analysis is computed from its numbers (no rendering here).

Its headline is the RMSE ratio B/A of each pair at equal spp: above 1, A has less error.
Inverting it once made the report name the wrong method while the end-to-end test still
passed; here a synthetic pair whose better method is known must be named, its mirror must
name the other (the negative control), and a tie must read "not distinguishable".
Per-repeat MSEs are a known expected MSE times a zero-mean jitter plus the reference's own
expected MSE (the floor), which the analysis must subtract.
"""
import math

import pytest

from experiments.lib import stats
from experiments.lib.studies import conclusion as C
from experiments.lib.studies import writeup_analysis as A

JITTER = (0.94, 0.98, 1.02, 1.06)            # four repeats, mean exactly 1
FLOOR = 1e-4
BIAS = {"mean_diff": [1e-4, -2e-4, 0.0], "ci_half_width": [3e-4, 3e-4, 3e-4],
        "ci_contains_zero": [True, True, True], "pass_fraction": 0.99,
        "pass_fraction_per_channel": [0.99, 0.991, 0.989]}
CONVERGES = {"spp": [12, 25, 50], "mse": [4e-3, 1.1e-3, 3e-4],
             "mean_diff": [[1e-3, 1e-3, 1e-3]] * 3, "slope": -1.87, "converges": True}


def side(method, mse, jitter=JITTER, floor=FLOOR, deterministic=False):
    values = (mse + floor,) if deterministic else tuple(mse * k + floor for k in jitter)
    values = values * len(JITTER) if deterministic else values
    return A.Side(method, values, math.sqrt(mse + floor), deterministic)


def pair(a_mse, b_mse, a="cosine", b="uniform", spp=20, **kw):
    a_side = side(a, a_mse, deterministic=kw.pop("deterministic", False), **kw)
    check = CONVERGES if a_side.deterministic else BIAS
    return A.PairMeasured(a_side, side(b, b_mse, **kw), spp, check)


def analyse(*pairs, floor=FLOOR):
    return A.analyse(A.Measured(list(pairs), [], floor, len(JITTER)))


def test_the_headline_ratio_names_the_method_with_less_error():
    res = analyse(pair(0.01, 0.04))                       # cosine has a quarter the MSE
    p, row = res.pairs[0], res.conclusion[0]
    assert p.rmse_ratio.value == pytest.approx(2.0) and p.rmse_ratio.lo > 1
    assert p.variance_ratio.value == pytest.approx(4.0)
    assert (p.rmse_a, p.rmse_b) == (pytest.approx(0.1), pytest.approx(0.2))
    assert row.better == "cosine" and row.verdict() == "cosine is more accurate"
    assert res.sentences == [p.verdict]
    assert res.sentences[0].startswith("After 20 spp: cosine is more accurate than uniform "
                                       "by 2 (95% CI")
    cells = C.rows(res.conclusion)[0]
    assert cells[:3] == ["cosine vs uniform", "RMSE B/A at 20 spp", "2"]
    assert cells[5] == "cosine is more accurate"
    # negative control: the mirror (A has four times the MSE) names B, ratio 1/2
    res = analyse(pair(0.04, 0.01))
    p, row = res.pairs[0], res.conclusion[0]
    assert p.rmse_ratio.value == pytest.approx(0.5) and p.rmse_ratio.hi < 1
    assert row.better == "uniform" and "uniform is more accurate than cosine" in p.verdict


def test_a_tie_reads_not_distinguishable():
    res = analyse(pair(0.02, 0.02, jitter=(0.5, 1.5, 0.7, 1.3)))
    row = res.conclusion[0]
    assert row.better is None and row.verdict() == "not distinguishable"
    assert "not distinguishable" in res.sentences[0]


def test_the_reference_floor_is_subtracted_from_the_expected_mse():
    """Raw MSE = true MSE + a floor as large: the RMSE reported is the true one."""
    res = analyse(pair(0.01, 0.04, floor=0.01), floor=0.01)
    p = res.pairs[0]
    assert p.mse_a.value == pytest.approx(0.01) and p.mse_a.lo < 0.01 < p.mse_a.hi
    assert (p.rmse_a, p.rmse_b) == (pytest.approx(0.1), pytest.approx(0.2))
    assert p.rmse_ratio.value == pytest.approx(2.0)
    # negative control: without the subtraction the ratio would be sqrt(0.05 / 0.02)
    raw = stats.ratio_interval([[0.04 * k + 0.01 for k in JITTER]],
                               [[0.01 * k + 0.01 for k in JITTER]])
    assert math.sqrt(raw.value) == pytest.approx(math.sqrt(2.5))


def test_an_error_below_the_floor_is_a_bound_and_its_pair_cannot_be_told():
    res = analyse(pair(1e-4 * FLOOR, 0.04, jitter=(0.2, 1.8, 0.4, 1.6)))
    p, row = res.pairs[0], res.conclusion[0]
    assert p.mse_a.bound and not p.mse_b.bound
    assert math.isfinite(p.rmse_a) and p.rmse_a >= 0 and p.bounds() == ["RMSE A"]
    assert row.verdict() == C.UNTOLD and "cannot be told" in res.sentences[0]
    assert C.ratio_cells(p.rmse_ratio) == ["n/a"] * 3
    resolved = analyse(pair(0.01, 0.04)).pairs[0]                  # control
    assert not resolved.mse_a.bound and resolved.bounds() == []


def test_plain_halton_gets_the_convergence_check_not_the_z_test():
    res = analyse(pair(0.01, 0.04), pair(0.005, 0.04, a="uniform+halton", spp=50,
                                         deterministic=True))
    assert [r[0] for r in res.bias_rows] == ["cosine − uniform (20 spp)"]
    assert [r[0] for r in res.deterministic_rows] == ["uniform+halton"] * 3
    assert res.deterministic_rows[-1][-1] == "yes"
    assert [c.a for c in res.conclusion] == ["cosine", "uniform+halton"]
    # plain Halton's one run stands for every repeat: no spread, its MSE exact
    assert res.pairs[1].mse_a.value == pytest.approx(0.005)
    assert len(res.sentences) == 2 <= C.MAX_SENTENCES
