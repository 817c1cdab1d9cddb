"""The guide's O(1) directional sampling (integrators/guide_warps.py: alias_order,
alias_table, sample_alias), as the SD-tree uploads it (integrators/sdtree.py): the
probabilities its alias tables draw with are the histogram's, exactly; a bin of
probability 0 is never drawn; directions drawn by the kernel pass a chi-square against
the histogram, and the same test rejects a table with a realistic bug (the negative
control). The frozen guide's whole warp is checked in test_guiding.py."""
import drjit as dr
import mitsuba as mi
import numpy as np
import pytest
from scipy import stats

from integrators import guide_warps, sdtree

RES = 16
BINS = RES * RES
#: Significance of the chi-square tests here.
ALPHA = 1e-3


def histograms(rows: int, seed: int = 1) -> np.ndarray:
    """Rows of bin probabilities a guide learns and some it may: lumpy and skewed, with
    empty bins; one bin holding everything; uniform; a single heavy bin among light
    ones."""
    rng = np.random.default_rng(seed)
    prob = rng.random((rows, BINS)) ** 8
    prob[:, :30] = 0.0
    prob[0, 50:] = 0.0
    prob[1] = 1.0
    prob[2] = 0.0
    prob[2, 7] = 1.0
    prob[3] = 1.0
    prob[3, 100] = 400.0
    return prob / prob.sum(axis=1, keepdims=True)


def uploaded(prob: np.ndarray) -> sdtree.SDTree:
    tree = sdtree.SDTree(RES, 64)
    tree.prob[:len(prob)] = prob
    tree.upload(len(prob))
    return tree


def tables(tree: sdtree.SDTree) -> np.ndarray:
    return np.array(tree.alias_table, np.float64).reshape(-1, BINS, 2)


def test_alias_tables_draw_the_histograms_probabilities():
    prob = histograms(200)
    table = tables(uploaded(prob))
    drawn = guide_warps.alias_probabilities_np(table[:len(prob)])
    assert np.abs(drawn - prob).max() < 1e-6 * prob.max()
    # the rows not in use keep the uniform histogram they started with
    assert np.allclose(guide_warps.alias_probabilities_np(table[len(prob):]), 1.0 / BINS)
    assert np.all((table[..., 0] >= 0) & (table[..., 0] <= 1))


def test_a_bin_of_probability_zero_is_never_drawn():
    prob = histograms(200)
    table = tables(uploaded(prob))[:len(prob)]
    assert np.all(table[..., 0][prob == 0] == 0)
    rows = np.repeat(np.arange(len(prob))[:, None], BINS, axis=1)
    aliased = table[..., 0] < 1
    assert np.all(prob[rows[aliased], table[..., 1].astype(int)[aliased]] > 0)


def bin_counts(tree: sdtree.SDTree, unit: int, n: int, seed: int) -> np.ndarray:
    u = mi.Float(np.random.default_rng(seed).random(n, dtype=np.float32))
    d = tree.sample(mi.UInt32(unit), u, mi.Point2f(0.5, 0.5))
    return np.bincount(guide_warps.direction_to_bin_np(np.array(d).T, RES),
                       minlength=BINS)


def chi2_p(counts: np.ndarray, prob: np.ndarray) -> float:
    """Chi-square of drawn bin counts against ``prob``: bins expecting under 5 draws
    pooled into one; a draw in a bin of probability 0 fails outright."""
    if counts[prob == 0].any():
        return 0.0
    expected = prob * counts.sum()
    small = expected < 5
    obs = np.append(counts[~small], counts[small & (prob > 0)].sum())
    exp = np.append(expected[~small], expected[small].sum())
    keep = exp > 0
    return float(stats.chisquare(obs[keep], exp[keep]).pvalue)


@pytest.mark.parametrize("unit", [0, 3, 5, 9])
def test_drawn_bins_pass_a_chi_square(unit):
    prob = histograms(12)
    tree = uploaded(prob)
    assert chi2_p(bin_counts(tree, unit, 500_000, unit), prob[unit]) > ALPHA


def test_the_chi_square_rejects_a_table_whose_heavy_bins_keep_their_overshoot():
    """Negative control: a demoted heavy bin that keeps its whole slot (threshold 1: the
    overshoot it owes its alias dropped) moves about 1% of a lumpy row's probability; the
    test at the same draws rejects it."""
    prob = histograms(12)
    tree = uploaded(prob)
    table = tables(tree)
    heavy = prob[5] * BINS >= 1
    wrong = table.copy()
    wrong[5, heavy, 0] = 1.0
    moved = np.abs(guide_warps.alias_probabilities_np(wrong[5:6])[0] - prob[5]).sum() / 2
    assert 0.003 < moved < 0.1
    tree.alias_table = mi.Float(wrong.astype(np.float32).ravel())
    dr.eval(tree.alias_table)
    assert chi2_p(bin_counts(tree, 5, 500_000, 5), prob[5]) < ALPHA
