"""Tests of the QMC maths in ``integrators.qmc`` (radical inverses, randomizations).

Statistical checks use a significance level of 1e-3 (chi-square p-values; a
z of 3.29 for two-sided normal bounds), with fixed seeds so they are
deterministic.
"""
import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest
from scipy import stats
from scipy.stats import qmc as scipy_qmc

import _qmc_oracle as oracle
from integrators import qmc

ALPHA = 1e-3


def _values(dimension, index, seed=0, randomization="owen"):
    return np.array(qmc.halton_sample(mi.UInt32(dimension), mi.UInt32(index),
                                      mi.UInt32(seed), randomization), dtype=np.float64)


def _brev32(a: np.ndarray) -> np.ndarray:
    a = a.astype(np.uint64)
    out = np.zeros_like(a)
    for bit in range(32):
        out |= ((a >> np.uint64(bit)) & np.uint64(1)) << np.uint64(31 - bit)
    return out


def test_prime_table():
    assert len(qmc.PRIMES) == qmc.PRIME_TABLE_SIZE == 1000
    assert list(qmc.PRIMES[:10]) == [2, 3, 5, 7, 11, 13, 17, 19, 23, 29]
    assert qmc.PRIMES[-1] == 7919
    for p in qmc.PRIMES.astype(int):
        assert all(p % q for q in range(2, int(p**0.5) + 1))


def test_division_magic_is_exact():
    rng = np.random.default_rng(1)
    a = np.concatenate([rng.integers(0, 2**31, 4000), np.arange(0, 70000, 7),
                        [2**31 - 1, 2**31 - 2, 2**30]]).astype(np.uint64)
    for b in [int(p) for p in qmc.PRIMES] + [4, 16, 256]:
        m, s = qmc.division_magic(b)
        assert 0 < m < 2**32
        np.testing.assert_array_equal((a * np.uint64(m)) >> np.uint64(32 + s), a // np.uint64(b))


def test_permutation_table():
    """Each odd base's run in the table: permutations_per_base(b) permutations of
    {0..b-1} with T(0) = 0 (every one of them, equally often, for b <= 7), found
    at the offset the packed entry names; the Dr.Jit count agrees."""
    tables = qmc._NP_TABLES
    primes = qmc.PRIMES.astype(np.int64)
    counts = np.array(qmc._permutation_count(mi.UInt32(primes[1:])))
    for i, b in enumerate(primes[1:], start=1):
        count = qmc.permutations_per_base(int(b))
        assert counts[i - 1] == count
        offset = int((int(tables["packed"][i]) >> 17) & 0x7FFF) * qmc.PERM_ALIGN
        perms = tables["perms"][offset:offset + count * b].reshape(count, b).astype(np.int64)
        assert np.all(perms[:, 0] == 0)
        assert np.all(np.sort(perms, axis=1) == np.arange(b))
        if b <= 7:
            _, freq = np.unique(perms, axis=0, return_counts=True)
            assert len(freq) == math.factorial(b - 1) and np.all(freq == freq[0])


def test_base2_is_bit_reversal():
    rng = np.random.default_rng(2)
    a = np.concatenate([np.arange(4096), rng.integers(0, 2**31, 4096)]).astype(np.uint32)
    got = np.array(qmc.radical_inverse(0, mi.UInt32(a)))
    expected = np.minimum(_brev32(a).astype(np.float32) * np.float32(2.0**-32),
                          np.float32(qmc.ONE_MINUS_EPSILON))
    np.testing.assert_array_equal(got, expected)


def test_plain_halton_matches_scipy():
    n, dims = 600, 24
    expected = scipy_qmc.Halton(d=dims, scramble=False).random(n)
    index = dr.arange(mi.UInt32, n)
    for d in range(dims):
        got = np.array(qmc.radical_inverse(d, index), dtype=np.float64)
        # float32 result: within a few ulps of the exact value
        np.testing.assert_allclose(got, expected[:, d], rtol=0, atol=4e-7, err_msg=f"dim {d}")
    # large indices (many digits) against exact rational arithmetic
    rng = np.random.default_rng(3)
    big = rng.integers(0, 2**31, 200)
    for d in (1, 2, 10, 500, 999):
        b = int(qmc.PRIMES[d])
        exact = []
        for a in big:
            a, v, w = int(a), 0.0, 1.0 / b
            while a:
                v += (a % b) * w
                a //= b
                w /= b
            exact.append(v)
        np.testing.assert_allclose(np.array(qmc.radical_inverse(d, mi.UInt32(big))), exact,
                                   rtol=0, atol=4e-7)


#: Dimensions checked against the definition: every base up to 41, high bases (the
#: lab's deep pair, the last base with 64 table permutations, the first with 4), the
#: end of the prime table and its wrap-around.
ORACLE_DIMENSIONS = list(range(13)) + [30, 31, 127, 171, 172, 998, 999, 1000, 1001, 2999]


@pytest.mark.parametrize("randomization", qmc.RANDOMIZATIONS)
def test_halton_sample_is_its_definition(randomization):
    """qmc.halton_sample equals the numpy oracle of tests/_qmc_oracle.py (the
    definitions of the module docstring, digit by digit) for small and large indices
    and random seeds, in every dimension of ORACLE_DIMENSIONS, to float32 rounding;
    the oracle's own 'none' is scipy's Halton sequence. Negative controls: the next
    dimension's or the next index's values do not match."""
    rng = np.random.default_rng(8)
    index = np.concatenate([np.arange(300), rng.integers(0, 2**31 - 1, 300)]).astype(np.uint32)
    seeds = rng.integers(0, 2**32, index.size, dtype=np.uint64).astype(np.uint32)
    if randomization == "none":
        plain = scipy_qmc.Halton(d=13, scramble=False).random(300)
        for d in range(13):
            np.testing.assert_allclose(oracle.halton(d, index[:300], seeds[:300], "none"),
                                       plain[:, d], rtol=0, atol=1e-12)
    for d in ORACLE_DIMENSIONS:
        got = _values(d, index, seeds, randomization)
        np.testing.assert_allclose(got, oracle.halton(d, index, seeds, randomization), rtol=0,
                                   atol=oracle.TOLERANCE, err_msg=f"dimension {d}")
        for wrong in (oracle.halton(d + 1, index, seeds, randomization),
                      oracle.halton(d, index + 1, seeds, randomization)):
            assert np.mean(np.abs(got - wrong) > oracle.TOLERANCE) > 0.9, d


def test_dimensions_wrap_past_prime_table():
    index = dr.arange(mi.UInt32, 300)
    for d in (0, 1, 7):
        np.testing.assert_array_equal(_values(d + 1000, index, 0, "none"),
                                      _values(d, index, 0, "none"))
        np.testing.assert_array_equal(_values(d + 3000, index, 0, "none"),
                                      _values(d, index, 0, "none"))
    for r in ("permute_digits", "owen"):
        v = _values(1003, index, 5, r)
        assert np.all((v >= 0) & (v < 1))
        # same base (7) and still stratified, but a different scramble than dim 3
        assert np.histogram(v[:49], bins=49, range=(0, 1))[0].max() == 1
        assert not np.array_equal(v, _values(3, index, 5, r))


def test_unknown_randomization_raises():
    with pytest.raises(ValueError, match="'sobol'.*none, permute_digits, owen"):
        qmc.halton_sample(0, 0, 0, "sobol")


@pytest.mark.parametrize("randomization", ["permute_digits", "owen"])
def test_every_point_is_uniform_over_seeds(randomization):
    """Each single point (fixed index and dimension) is U[0,1) over the scramble seeds."""
    n_seeds, bins = 20000, 20
    seeds = dr.arange(mi.UInt32, n_seeds) * 7919 + 13
    for d in (0, 1, 2, 5, 40, 700):
        for index in (0, 1, 6, 250):
            v = _values(d, mi.UInt32(index) + dr.zeros(mi.UInt32, n_seeds), seeds, randomization)
            assert np.all((v >= 0) & (v < 1))
            counts = np.histogram(v, bins=bins, range=(0, 1))[0]
            p = stats.chisquare(counts).pvalue
            assert p > ALPHA, (d, index, p)


@pytest.mark.parametrize("randomization", ["none", "permute_digits", "owen"])
def test_projections_uniform_and_stratified(randomization):
    """The first b^m points of each 1-D projection fill the b^m strata once each."""
    for d, m in ((0, 10), (1, 6), (2, 4), (3, 3), (9, 2), (60, 1)):
        b = int(qmc.PRIMES[d])
        n = b**m
        v = _values(d, dr.arange(mi.UInt32, n), 12345, randomization)
        # plain Halton points sit on the stratum edges (up to float rounding)
        strata = np.round(v * n) if randomization == "none" else np.floor(v * n)
        np.testing.assert_array_equal(np.sort(strata), np.arange(n))
        # ... and so the histogram passes a chi-square test with coarse bins
        coarse = np.histogram(v, bins=min(n, 16), range=(0, 1))[0]
        assert stats.chisquare(coarse).pvalue > ALPHA


@pytest.mark.parametrize("randomization", ["none", "permute_digits", "owen"])
def test_deterministic_for_a_seed(randomization):
    index = dr.arange(mi.UInt32, 500)
    a = _values(3, index, 42, randomization)
    np.testing.assert_array_equal(a, _values(3, index, 42, randomization))
    other = _values(3, index, 43, randomization)
    if randomization == "none":
        np.testing.assert_array_equal(a, other)
    else:
        assert np.mean(a == other) < 0.01


@pytest.mark.parametrize("randomization", ["none", "permute_digits", "owen"])
def test_2d_discrepancy_lower_than_random(randomization):
    n, seeds = 256, 8
    rng = np.random.default_rng(4)
    index = dr.arange(mi.UInt32, n)
    for d0, d1 in ((0, 1), (2, 3), (4, 5), (1, 6)):
        disc_q, disc_r = [], []
        for s in range(seeds):
            pts = np.stack([_values(d0, index, s, randomization),
                            _values(d1, index, s, randomization)], axis=1)
            disc_q.append(scipy_qmc.discrepancy(pts))
            disc_r.append(scipy_qmc.discrepancy(rng.random((n, 2))))
        assert np.mean(disc_q) < 0.5 * np.mean(disc_r), (d0, d1, disc_q, disc_r)


@pytest.mark.parametrize("randomization", ["none", "owen"])
def test_works_inside_symbolic_loop(randomization):
    """Dimension and index as loop variables of a symbolic loop give the direct values."""
    n, steps = 64, 12
    index = dr.arange(mi.UInt32, n)
    out = dr.zeros(mi.Float, n * steps)

    def body(dim, acc):
        v = qmc.halton_sample(dim, index, 9, randomization)
        dr.scatter(out, v, index * steps + dim)
        return dim + 1, acc + v

    dim, _ = dr.while_loop(state=(dr.zeros(mi.UInt32, n), dr.zeros(mi.Float, n)),
                           cond=lambda dim, acc: dim < steps, body=body, mode="symbolic")
    got = np.array(out).reshape(n, steps)
    for d in range(steps):
        np.testing.assert_array_equal(got[:, d], _values(d, index, 9, randomization))


# ------------------------------------------------- permutation quality

def _permuted_digits(dimension, k, seeds, randomization, low=0):
    """pi_k(d) for d = 0 .. b-1 and each seed: digit k of the point of index
    d b^k + low (``low < b^k``), as a (seeds, b) integer array."""
    b = int(qmc.PRIMES[dimension])
    n = len(seeds)
    d = dr.tile(dr.arange(mi.UInt32, b), n)
    index = d * b**k + low
    seed = dr.repeat(mi.UInt32(seeds), b)
    v = np.array(qmc.halton_sample(dimension, index, seed, randomization), dtype=np.float64)
    return (np.floor(v * b ** (k + 1)).astype(np.int64) % b).reshape(n, b)


def _affine_permutations(b, n, rng):
    """The old scramble, d -> (A d + c) mod b: a negative control."""
    a, c = rng.integers(1, b, (n, 1)), rng.integers(0, b, (n, 1))
    return (a * np.arange(b) + c) % b


def _permutation_pvalues(perm):
    """p-values of chi-square tests that ``perm`` (seeds, b) holds uniform random
    permutations: each pi(d) uniform on {0..b-1} (1-D, per digit value), and the
    triple (pi(0), pi(1), pi(2)) uniform over the b(b-1)(b-2) distinct triples."""
    n, b = perm.shape
    # permutations (but for a few points whose float32 value rounds up onto
    # the next stratum's edge)
    assert np.mean(np.all(np.sort(perm, axis=1) == np.arange(b), axis=1)) > 0.97
    one_d = [stats.chisquare(np.bincount(perm[:, d], minlength=b)).pvalue for d in range(b)]
    if b > 7:
        return one_d, None
    triple = (perm[:, 0] * b + perm[:, 1]) * b + perm[:, 2]
    counts = np.bincount(triple, minlength=b**3)
    distinct = [(x * b + y) * b + z for x in range(b) for y in range(b) for z in range(b)
                if len({x, y, z}) == 3]
    return one_d, stats.chisquare(counts[distinct]).pvalue


@pytest.mark.parametrize("randomization", ["permute_digits", "owen"])
def test_digit_permutations_are_uniform(randomization):
    """Every digit position goes through a random permutation: each permuted
    digit is uniform (1-D, per digit value and position; bases 5, 7, 67 and
    719), and for bases up to 7, whose tables hold every permutation, triples
    of permuted digits are uniform over the distinct triples, which affine maps
    d -> A d + c (pi(2) = 2 pi(1) - pi(0)) fail. Significance 1e-3 per test,
    Sidak-corrected over the tests of one base and position."""
    seeds = (np.arange(6000, dtype=np.uint64) * 2654435761 % 2**32).astype(np.uint32)
    cases = [(2, 0, 0), (2, 1, 0), (2, 2, 3), (3, 0, 0), (3, 1, 5), (18, 0, 0), (18, 1, 2),
             (127, 0, 0)]
    for dimension, k, low in cases:
        b = int(qmc.PRIMES[dimension])
        alpha = 1 - (1 - ALPHA) ** (1.0 / (b + 1))
        perm = _permuted_digits(dimension, k, seeds, randomization, low)
        one_d, triple = _permutation_pvalues(perm)
        assert min(one_d) > alpha, (b, k, min(one_d))
        if b <= 7:
            assert triple > alpha, (b, k, triple)
    # negative control: the affine scramble fails the triple test
    rng = np.random.default_rng(5)
    for b in (5, 7):
        _, triple = _permutation_pvalues(_affine_permutations(b, len(seeds), rng))
        assert triple < 1e-6, (b, triple)


def _empty_cells(x, y, grid=8):
    """Empty cells of a grid x grid partition, per row of the (pixels, n) coordinates."""
    cell = np.floor(x * grid).astype(np.int64) * grid + np.floor(y * grid).astype(np.int64)
    occupied = np.zeros((x.shape[0], grid * grid), dtype=bool)
    np.put_along_axis(occupied, cell, True, axis=1)
    return grid * grid - occupied.sum(axis=1)


def _empty_tail_pvalue(empty, reference, threshold):
    """One-sided Fisher exact test: are counts >= threshold more frequent in
    ``empty`` than in ``reference`` (random points)?"""
    a, b = int(np.sum(empty >= threshold)), int(np.sum(reference >= threshold))
    table = [[a, len(empty) - a], [b, len(reference) - b]]
    return stats.fisher_exact(table, alternative="greater").pvalue


@pytest.mark.parametrize("randomization", ["permute_digits", "owen"])
def test_high_base_projections_no_worse_than_random(randomization):
    """Bases 67/71 (dimensions 18/19) and 127/131, 64 points per pixel, 8x8 grid:
    the fraction of pixels with >= 40 (and >= 30) of 64 cells empty is no larger
    than for 64 random points (one-sided Fisher exact test, significance 1e-3,
    and none at all at >= 40); the affine scramble's shifted lattices fail."""
    pixels, n = 3000, 64
    rng = np.random.default_rng(6)
    reference = _empty_cells(rng.random((pixels, n)), rng.random((pixels, n)))
    index = dr.tile(dr.arange(mi.UInt32, n), pixels)
    seed = dr.repeat(dr.arange(mi.UInt32, pixels), n) * 7919 + 17
    for d0, d1 in ((18, 19), (30, 31)):
        x, y = (np.array(qmc.halton_sample(d, index, seed, randomization)).reshape(pixels, n)
                for d in (d0, d1))
        empty = _empty_cells(x, y)
        assert np.sum(empty >= 40) == 0, (d0, d1)
        for threshold in (40, 30):
            p = _empty_tail_pvalue(empty, reference, threshold)
            assert p > ALPHA, (d0, d1, threshold, p)
    # negative control: the affine scramble (plus a shared random tail per pixel)
    tail = rng.random((pixels, 2))
    x = (_affine_permutations(67, pixels, rng)[:, :n] + tail[:, :1]) / 67
    y = (_affine_permutations(71, pixels, rng)[:, :n] + tail[:, 1:]) / 71
    empty = _empty_cells(x, y)
    assert _empty_tail_pvalue(empty, reference, 40) < 1e-6


def test_pixel_seeds_are_distinct_and_balanced():
    """qmc.pixel_seed (the halton sampler's per-pixel seed): no two of 2^16 pixels share
    a seed, every bit is set in half the pixels (within 5 sigma), and another render
    seed gives another set. The sampler takes its seeds from it."""
    n = 1 << 16
    pixels = dr.arange(mi.UInt32, n)
    a = np.array(qmc.pixel_seed(mi.UInt32(3), pixels), dtype=np.uint32)
    b = np.array(qmc.pixel_seed(mi.UInt32(4), pixels), dtype=np.uint32)
    assert len(np.unique(a)) == n
    bits = (a[:, None] >> np.arange(32, dtype=np.uint32)) & 1
    assert np.all(np.abs(bits.mean(axis=0) - 0.5) < 5 * 0.5 / np.sqrt(n))
    assert np.mean(a == b) < 1e-3
    sampler = mi.load_dict({"type": "halton", "sample_count": 4, "seed": 0})
    sampler.seed(3, 4 * 16)
    assert np.array_equal(np.array(sampler._pixel_seed),
                          np.repeat(a[:16], 4))
