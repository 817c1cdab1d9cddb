"""Warps: chi-square goodness of fit (significance 0.01), inverses, normalisation.

The chi-square tests reject a density that is off by DETECTABLE_DENSITY_ERROR (3%)
in the direction of the samples; the negative controls are of that size.
"""
import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from integrators import warps

from _chi2 import CapDomain, cap_cos_min, run_chi2

EXPONENTS = [0, 1, 10, 100, 1000, 10000]


def chi2_test(sample, pdf, monkeypatch, tmp_path):
    """Chi-square test of a warp over the whole sphere."""
    domain = CapDomain((0, 0, 1), -1.0)
    run_chi2(domain, lambda u: (sample(u), mi.Float(1.0)), pdf, 2, monkeypatch, tmp_path)


def test_uniform_hemisphere_chi2(monkeypatch, tmp_path):
    chi2_test(warps.square_to_uniform_hemisphere, warps.square_to_uniform_hemisphere_pdf,
              monkeypatch, tmp_path)


def test_uniform_sphere_chi2(monkeypatch, tmp_path):
    chi2_test(warps.square_to_uniform_sphere, warps.square_to_uniform_sphere_pdf,
              monkeypatch, tmp_path)


def test_cosine_hemisphere_chi2(monkeypatch, tmp_path):
    chi2_test(warps.square_to_cosine_hemisphere, warps.square_to_cosine_hemisphere_pdf,
              monkeypatch, tmp_path)


@pytest.mark.parametrize("exponent", EXPONENTS)
def test_phong_lobe_chi2(exponent, monkeypatch, tmp_path):
    """Over a cap a dozen lobe widths wide about the axis (the whole sphere for n <= 5)."""
    n = mi.Float(exponent)
    domain = CapDomain((0, 0, 1), cap_cos_min(exponent))
    run_chi2(domain, lambda u: domain.restrict(warps.square_to_phong_lobe(u, n), mi.Float(1.0)),
             lambda v: warps.square_to_phong_lobe_pdf(v, n), 2, monkeypatch, tmp_path)


def _grid(n):
    i = dr.arange(mi.UInt32, n * n)
    return mi.Point2f((mi.Float(i % n) + 0.5) / n, (mi.Float(i // n) + 0.5) / n)


@pytest.mark.parametrize("exponent", EXPONENTS)
def test_phong_lobe_inverse(exponent):
    """phong_lobe_to_square inverts square_to_phong_lobe (a bijection of the square)."""
    u = _grid(200)
    n = mi.Float(exponent)
    v = warps.square_to_phong_lobe(u, n)
    back = warps.phong_lobe_to_square(v, n)
    assert np.allclose(np.array(dr.norm(v)), 1.0, atol=1e-5)
    # In float32, cos(alpha)^(n+1) loses ~ (n+1) ulps of cos(alpha) near 1.
    tol = 2e-5 * (exponent + 1)
    assert np.abs(np.array(back.x) - np.array(u.x)).max() < max(tol, 1e-4)
    assert np.abs(np.array(back.y) - np.array(u.y)).max() < 1e-4


@pytest.mark.parametrize("exponent", EXPONENTS)
def test_phong_lobe_pdf_integrates_to_one(exponent):
    """Midpoint rule over (cos alpha, phi), refined towards the lobe axis."""
    # Integrate over t in [0, 1] with cos(alpha) = 1 - t^4 (dense near the axis).
    m = 20000
    t = (np.arange(m) + 0.5) / m
    cos_a = 1.0 - t ** 4
    jac = 4 * t ** 3 / m
    v = mi.Vector3f(np.sqrt(1 - cos_a ** 2), 0.0, cos_a)
    pdf = np.array(warps.square_to_phong_lobe_pdf(v, mi.Float(exponent)), dtype=np.float64)
    integral = 2 * np.pi * np.sum(pdf * jac)
    assert integral == pytest.approx(1.0, abs=2e-3)


def test_pdfs_vanish_below_horizon():
    v = mi.Vector3f(0.6, 0.0, -0.8)
    assert warps.square_to_uniform_hemisphere_pdf(v)[0] == 0
    assert warps.square_to_cosine_hemisphere_pdf(v)[0] == 0
    for n in EXPONENTS:   # pow(0, 0) = 1 must not leak out of the lobe
        assert warps.square_to_phong_lobe_pdf(v, mi.Float(n))[0] == 0
        assert warps.square_to_phong_lobe_pdf(mi.Vector3f(1, 0, 0), mi.Float(n))[0] == 0


def test_exact_pdf_values():
    z = mi.Vector3f(0, 0, 1)
    assert warps.square_to_uniform_hemisphere_pdf(z)[0] == pytest.approx(1 / (2 * np.pi))
    assert warps.square_to_cosine_hemisphere_pdf(z)[0] == pytest.approx(1 / np.pi)
    assert warps.square_to_phong_lobe_pdf(z, mi.Float(30))[0] == pytest.approx(31 / (2 * np.pi))
    c = np.cos(0.3)
    v = mi.Vector3f(float(np.sin(0.3)), 0.0, float(c))
    assert warps.square_to_phong_lobe_pdf(v, mi.Float(7))[0] == pytest.approx(8 / (2 * np.pi) * c ** 7, rel=1e-5)


# ------------------------------------------- side warp, mixture, power heuristic

#: (hemisphere warp, wi_z, both sides) cases of the side warp.
SIDED = [(k, wi_z, both) for k in warps.HEMISPHERE_WARPS
         for wi_z, both in ((0.5, False), (-0.5, False), (0.5, True))]


def sided_chi2(kind, wi_z, both, monkeypatch, tmp_path, side_error=0.0, seed=0):
    """``side_error``: the density reported as if the far side (z < 0) were drawn with
    probability (1 + side_error) / 2 (a negative control)."""
    warp, pdf = warps.hemisphere_warp(kind)
    run_chi2(CapDomain((0, 0, 1), -1.0),
             lambda u: (warps.square_to_sided_hemisphere(warp, u.x, mi.Point2f(u.y, u.z),
                                                         mi.Float(wi_z), mi.Bool(both)),
                        mi.Float(1.0)),
             lambda v: warps.square_to_sided_hemisphere_pdf(pdf, v, mi.Float(wi_z),
                                                            mi.Bool(both))
             * dr.select(v.z < 0, 1 + side_error, 1 - side_error),
             3, monkeypatch, tmp_path, test_count=len(SIDED), seed=seed)


@pytest.mark.parametrize("kind,wi_z,both", SIDED,
                         ids=[f"{k}-wiz{z}-{'both' if b else 'one'}" for k, z, b in SIDED])
def test_sided_hemisphere_chi2(kind, wi_z, both, monkeypatch, tmp_path):
    """The side warp follows its density: one-sided on wi's side, two-sided on both."""
    sided_chi2(kind, wi_z, both, monkeypatch, tmp_path, seed=SIDED.index((kind, wi_z, both)))


#: Relative density error the chi-square tests claim to detect (1e6 samples, 101 x 101
#: cells): the negative controls below are of this size.
DETECTABLE_DENSITY_ERROR = 0.03


def test_sided_hemisphere_with_a_side_split_off_by_3_percent_fails(monkeypatch, tmp_path):
    """Negative control: the two-sided warp reported as if it picked the far side with
    probability 0.515 and the near side 0.485 (a density 3% off on each side)."""
    with pytest.raises(AssertionError):
        sided_chi2("cosine", 0.5, True, monkeypatch, tmp_path,
                   side_error=DETECTABLE_DENSITY_ERROR)


def test_cosine_warp_with_a_density_off_by_3_percent_fails(monkeypatch, tmp_path):
    """Negative control: the cosine warp reported with its density times
    1 + 0.03 cos(phi) (still normalised, 3% off at most)."""
    def tilted(v):
        cos_phi = v.x / dr.maximum(dr.sqrt(v.x * v.x + v.y * v.y), 1e-12)
        return (warps.square_to_cosine_hemisphere_pdf(v)
                * (1 + DETECTABLE_DENSITY_ERROR * cos_phi))
    with pytest.raises(AssertionError):
        chi2_test(warps.square_to_cosine_hemisphere, tilted, monkeypatch, tmp_path)


def test_unknown_hemisphere_warp_names_the_choices():
    with pytest.raises(ValueError, match="valid choices are uniform, cosine"):
        warps.hemisphere_warp("mis")


@pytest.mark.parametrize("weight", [0.25, 0.5, 0.9])
def test_mixture_split_reuses_the_sample_uniformly(weight):
    """u < weight picks a; within each technique the rescaled sample is the uniform
    grid of [0, 1) again (a stratified u stays stratified), clamped below 1."""
    n = 1 << 16
    u = (dr.arange(mi.Float, n) + 0.5) / n
    split = warps.split_mixture_sample(u, weight)
    use_a = np.array(split.use_a)
    assert abs(use_a.mean() - weight) < 1.0 / n
    for rescaled, chosen in ((np.array(split.u_a), use_a), (np.array(split.u_b), ~use_a)):
        v = np.sort(rescaled[chosen])
        assert v.min() >= 0 and v.max() < 1
        assert np.abs(v - (np.arange(len(v)) + 0.5) / len(v)).max() < 2.0 / len(v)
    top = warps.split_mixture_sample(mi.Float(warps.ONE_MINUS_EPSILON), weight)
    assert np.array(top.u_b)[0] < 1


def test_mixture_of_cosine_and_phong_lobe_chi2(monkeypatch, tmp_path):
    """The one-sample mixture (split_mixture_sample) follows mixture_pdf."""
    w, n = 0.25, mi.Float(20.0)

    def sample(u):
        split = warps.split_mixture_sample(u.x, w)
        u2 = mi.Point2f(u.y, u.z)
        wo = dr.select(split.use_a, warps.square_to_cosine_hemisphere(u2),
                       warps.square_to_phong_lobe(u2, n))
        return wo, mi.Float(1.0)

    run_chi2(CapDomain((0, 0, 1), -1.0), sample,
             lambda v: warps.mixture_pdf(w, warps.square_to_cosine_hemisphere_pdf(v),
                                         warps.square_to_phong_lobe_pdf(v, n)),
             3, monkeypatch, tmp_path)


def test_power_heuristic():
    a = mi.Float(1.0, 2.0, 0.0, float("inf"), 3.0)
    b = mi.Float(1.0, 1.0, 5.0, 1.0, float("inf"))
    got = np.array(warps.power_heuristic(a, b))
    assert np.allclose(got, [0.5, 0.8, 0.0, 1.0, 0.0]) and np.all(np.isfinite(got))
    # the weights of the two techniques sum to one wherever both densities are > 0
    x, y = mi.Float(0.3, 7.0, 1e-6), mi.Float(2.0, 0.1, 1e3)
    assert np.allclose(np.array(warps.power_heuristic(x, y) + warps.power_heuristic(y, x)), 1.0)
