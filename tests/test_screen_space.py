"""The screen-space maths (experiments.lib.screen_space) on synthetic fields with known spectra.

Each property against a hand-computed case or a field whose expected spectrum is known,
with a negative control the size of a real effect (the blue-noise sampler's error has about
a quarter less power at low frequencies than white noise):

- a single cosine's power sits in its own ring, with the value the FFT gives by hand, and
  its share is 1 below the cutoff and 0 above;
- white noise gives the share of the grid's frequencies in the disc (about pi 0.125^2),
  within its sampling error; noise with 25% less (more) power below the cutoff gives a
  share that the same test tells apart, lower (higher); blurred noise is red, high-passed
  noise blue;
- a constant offset changes nothing (mean subtraction);
- the reference's white noise, subtracted as a floor, gives back the render's own share;
  left in, it pulls a blue share towards white's;
- the floor itself is the variance of the reference's luminance, from its chunks.
"""
import math

import numpy as np
import pytest
from scipy import stats

from experiments.lib import screen_space

N = 128
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def filtered(rng, gain2, n=N, fields=1) -> np.ndarray:
    """White noise of unit variance whose power at frequency |f| is multiplied by
    ``gain2(|f|)`` (a filter symmetric in f, so the field stays real)."""
    white = rng.standard_normal((fields, n, n))
    g = np.sqrt(gain2(screen_space.radius((n, n))))
    return np.real(np.fft.ifft2(np.fft.fft2(white) * g))


def low_gain(factor):
    return lambda r: np.where(r < screen_space.LOW, factor, 1.0)


def expected_share(factor, shape=(N, N)) -> float:
    """The share of a field whose power below the cutoff is ``factor`` times white's:
    (factor x low bins) / (factor x low bins + the other nonzero bins)."""
    w = screen_space.white_share(shape)
    return factor * w / (factor * w + 1 - w)


def shares(fields, floor=0.0) -> np.ndarray:
    return np.array([screen_space.low_share(screen_space.periodogram(f), floor) for f in fields])


def interval(x, level=0.999):
    """Student-t interval of the mean of ``x`` (a wide level: these tests must not flake)."""
    x = np.asarray(x)
    half = stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return x.mean() - half, x.mean() + half


# ------------------------------------------------------------------ hand-computed

@pytest.mark.parametrize("k", [4, 12])
def test_a_cosine_sits_in_its_ring(k):
    """cos(2 pi k x / n): |FFT|^2 = (n^2 / 2)^2 at (0, +-k), so the periodogram there is
    n^2 / 4 and 0 elsewhere; the ring at k / n averages it over the ring's bins."""
    n = 64
    x = np.arange(n)
    field = np.tile(np.cos(2 * np.pi * k * x / n), (n, 1))
    p = screen_space.periodogram(field)
    assert p[0, k] == pytest.approx(n * n / 4) and p[0, n - k] == pytest.approx(n * n / 4)
    assert p.sum() == pytest.approx(n * n / 2)
    freqs, power = screen_space.spectrum(p)
    assert len(freqs) == n // 2 and freqs[0] == pytest.approx(1 / n)
    ring = int(np.count_nonzero(np.rint(screen_space.radius((n, n)) * n) == k))
    expected = np.zeros(n // 2)
    expected[k - 1] = 2 * (n * n / 4) / ring
    np.testing.assert_allclose(power, expected, atol=1e-9)
    # k / n = 0.0625 is below the cutoff (share 1), 0.1875 above it (share 0)
    assert screen_space.low_share(p) == pytest.approx(1.0 if k / n < screen_space.LOW else 0.0, abs=1e-12)


def test_white_share_counts_the_disc():
    """The lattice points 0 < |k| < n / 8 over all n^2 - 1 nonzero ones, and pi / 64 in the
    limit."""
    n = 128
    inside = sum(1 for a in range(-n // 2, n // 2) for b in range(-n // 2, n // 2)
                 if 0 < a * a + b * b < (n // 8) ** 2)
    assert screen_space.white_share((n, n)) == pytest.approx(inside / (n * n - 1), rel=1e-12)
    assert screen_space.white_share((n, n)) == pytest.approx(math.pi * screen_space.LOW ** 2, rel=0.02)


def test_radial_average_is_the_mean_over_each_ring():
    """On an integer grid with step 1: the mean of the values whose radius rounds to f."""
    k = np.arange(-3, 4)
    r = np.sqrt(k[:, None] ** 2 + k[None, :] ** 2)
    values = np.arange(r.size, dtype=float).reshape(r.shape)
    freqs, out = screen_space.radial_average(values, r, 1, 3)
    assert list(freqs) == [1, 2, 3]
    for f in (1, 2, 3):
        assert out[f - 1] == pytest.approx(values[np.rint(r) == f].mean())
    # leading axes are kept: two stacked copies give the same averages twice
    _, both = screen_space.radial_average(np.stack([values, 2 * values]), r, 1, 3)
    np.testing.assert_allclose(both, [out, 2 * out])


# ------------------------------------------------------------------ white, red, blue

def test_white_noise_gives_the_discs_share_and_a_quarter_less_low_power_is_told():
    rng = np.random.default_rng(1)
    white = shares(filtered(rng, low_gain(1.0), fields=24))
    lo, hi = interval(white)
    assert lo < screen_space.white_share((N, N)) < hi
    assert abs(white.mean() - math.pi * screen_space.LOW ** 2) < 0.004
    # negative controls the size of the blue-noise sampler's effect (0.037 against 0.049)
    blue = shares(filtered(rng, low_gain(0.75), fields=24))
    lo_b, hi_b = interval(blue)
    assert lo_b < expected_share(0.75) < hi_b and hi_b < lo
    red = shares(filtered(rng, low_gain(1.25), fields=24))
    lo_r, hi_r = interval(red)
    assert lo_r < expected_share(1.25) < hi_r and lo_r > hi


def test_blurred_noise_is_red_and_high_passed_noise_is_blue():
    rng = np.random.default_rng(2)
    blur = lambda r: np.exp(-(2 * np.pi * 1.5 * r) ** 2)     # noqa: E731  Gaussian, 1.5 px
    red = shares(filtered(rng, blur, fields=4))
    blue = shares(filtered(rng, lambda r: (1 - np.sqrt(blur(r))) ** 2, fields=4))
    assert red.min() > 0.3 and blue.max() < 0.01


def test_a_constant_offset_changes_nothing():
    rng = np.random.default_rng(3)
    field = filtered(rng, low_gain(0.75))[0]
    p = screen_space.periodogram(field)
    np.testing.assert_allclose(screen_space.periodogram(field + 5.0), p, atol=1e-9)
    assert screen_space.low_share(screen_space.periodogram(field + 5.0)) == pytest.approx(screen_space.low_share(p))
    # the same through error_field: a grey offset of every pixel is a constant luminance
    ref = rng.random((N, N, 3))
    image = ref + field[..., None]
    np.testing.assert_allclose(screen_space.error_field(image + 0.3, ref), screen_space.error_field(image, ref),
                               atol=1e-12)
    np.testing.assert_allclose(screen_space.error_field(image, ref), field - field.mean(), atol=1e-12)
    # negative control: without the mean subtracted, the offset is all DC power
    raw = np.abs(np.fft.fft2(field + 5.0)) ** 2 / field.size
    assert raw[0, 0] > 1e3 * p.sum() / p.size


# ------------------------------------------------------------------ the reference's floor

def test_the_floor_gives_back_the_renders_own_share():
    """Blue error (half the low-frequency power) seen through a reference whose own white
    noise has the error's variance: with the floor subtracted the share is the error's;
    without it, it is pulled towards white noise's."""
    rng = np.random.default_rng(4)
    blue = filtered(rng, low_gain(0.5), fields=16)
    noisy = blue + rng.standard_normal(blue.shape)          # the reference's noise: variance 1
    kept = shares(noisy, floor=1.0)
    lo, hi = interval(kept)
    assert lo < expected_share(0.5) < hi
    left_in = shares(noisy)                                   # negative control
    assert interval(left_in)[0] > hi
    assert interval(left_in)[0] < expected_share(0.75) < interval(left_in)[1]
    # the normalized spectrum is white noise's 1 at high frequencies, 0.5 below the cutoff
    freqs, power = screen_space.spectrum(screen_space.normalized(np.mean([screen_space.periodogram(f) for f in noisy],
                                                     axis=0), 1.0))
    scale = (0.5 * screen_space.white_share((N, N)) + 1 - screen_space.white_share((N, N)))
    assert np.mean(power[freqs < 0.1]) * scale == pytest.approx(0.5, rel=0.1)
    assert np.mean(power[freqs > 0.2]) * scale == pytest.approx(1.0, rel=0.05)


def test_the_floor_is_the_variance_of_the_references_luminance():
    """Chunks of k_i samples around a truth, per channel noise of variance s^2 / k_i: the
    floor is s^2 sum(w^2) / sum(k), w the luminance weights."""
    rng = np.random.default_rng(5)
    truth = rng.random((64, 64, 3))
    counts = [32] * 12 + [16] * 4
    s2 = 0.04
    chunks = [truth + rng.normal(0, math.sqrt(s2 / k), truth.shape) for k in counts]
    expected = s2 * np.sum(LUMINANCE ** 2) / sum(counts)
    assert screen_space.reference_floor(chunks, counts) == pytest.approx(expected, rel=0.03)
    # negative control: the chunks weighted equally (their counts ignored) reads 9% high,
    # which the same tolerance rejects
    lum = np.stack([c @ LUMINANCE for c in chunks])
    unweighted = float(np.mean(lum.var(axis=0, ddof=1) / len(counts)))
    assert unweighted != pytest.approx(expected, rel=0.03)
    with pytest.raises(ValueError, match="no spread"):
        screen_space.reference_floor(chunks[:1], counts[:1])


# ------------------------------------------------------------------ bad input

def test_bad_input_is_refused_with_a_clear_error():
    ref = np.zeros((8, 8, 3))
    image = np.ones((8, 8, 3))
    image[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="1 non-finite pixel"):
        screen_space.error_field(image, ref)
    with pytest.raises(ValueError, match=r"\(8, 8, 3\) and \(8, 4, 3\)"):
        screen_space.error_field(ref, np.zeros((8, 4, 3)))
    with pytest.raises(ValueError, match="no power above the floor"):
        screen_space.low_share(screen_space.periodogram(np.zeros((8, 8))), 0.0)
