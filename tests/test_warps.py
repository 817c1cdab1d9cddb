"""Warps: chi-square goodness of fit (significance 0.01), inverses, normalisation."""
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
