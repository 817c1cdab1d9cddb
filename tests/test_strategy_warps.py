"""Every built-in ``vr_path`` strategy as a warp: the directions it draws follow the density it
reports (user strategies go through the same :func:`strategy_chi2` in test_strategies.py).

``integrators.path.sample_direction`` (the render loop's own direction
sampling, called here outside it through the same ``dr.dispatch``) draws
directions for one BSDF at one incident direction; ``direction_pdf`` is the
density the strategy reports (and the render loop uses in its weights and in
the MIS against emitter sampling). A chi-square test (``mitsuba.chi2``,
significance 0.01, Sidak-corrected over the whole grid) compares the two for
``diffuse``, ``phong``, ``roughconductor`` and ``roughdielectric`` at normal,
oblique and grazing incidence, below the horizon (one-sided BSDFs: the
strategies that ignore the BSDF still draw there, the BSDF's own sampling
draws nothing) and inside the object (``roughdielectric``, including total
internal reflection). Directions the strategy does not draw (density 0, e.g. a
failed BSDF sample) count with weight 0, so the histogram and the density both
integrate to the probability of drawing a direction at all.

Negative control: the uniform strategy reporting a density off by the
direction-dependent factor 1 + 0.04 cos(phi) (still normalised, about the smallest
error the chi-square test of this grid rejects) must fail.
"""
import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import integrators.path as vr_path
from integrators import strategies
from _chi2 import CapDomain, incident, interaction, run_chi2

BSDFS = {
    "diffuse": {"type": "diffuse"},
    "phong": {"type": "phong", "diffuse_reflectance": 0.3, "specular_reflectance": 0.6,
              "exponent": 20.0},
    "roughconductor": {"type": "roughconductor", "alpha": 0.3},
    "roughdielectric": {"type": "roughdielectric", "alpha": 0.3, "int_ior": 1.5},
}
#: cos(theta_i): normal, oblique, grazing, below the horizon / inside the object.
COS_THETA_I = {"diffuse": [1.0, 0.6, 0.1, -0.6], "phong": [1.0, 0.6, 0.1, -0.6],
               "roughconductor": [1.0, 0.6, 0.1, -0.6],
               "roughdielectric": [1.0, 0.6, 0.1, -0.6, -0.9, -0.1]}
GRID = [(s, b, c) for s in vr_path.STRATEGIES for b in BSDFS for c in COS_THETA_I[b]]


def strategy_chi2(strategy, bsdf, cos_i, monkeypatch, tmp_path, test_count, seed=0):
    """Chi-square test of ``strategy`` (a registered name or a Strategy object) on ``bsdf``
    at incidence cos(theta_i) = ``cos_i``, over the whole sphere."""
    wi = incident(cos_i)
    ctx = mi.BSDFContext()
    ptr = mi.BSDFPtr(bsdf)          # through dr.dispatch, as in the render loop
    domain = CapDomain((0, 0, 1), -1.0)

    def sample(u):
        n = dr.width(u)
        ds = vr_path.sample_direction(strategy, ptr, ctx, interaction(wi, n), u.x,
                                      mi.Point2f(u.y, u.z))
        drawn = ds.pdf > 0           # not drawn: weight 0, parked at a valid direction
        return dr.select(drawn, ds.wo, mi.Vector3f(0, 0, 1)), dr.select(drawn, 1.0, 0.0)

    def pdf(wo):
        return vr_path.direction_pdf(strategy, bsdf, ctx, interaction(wi, dr.width(wo)), wo)

    return run_chi2(domain, sample, pdf, 3, monkeypatch, tmp_path, test_count=test_count,
                    seed=seed)


@pytest.mark.parametrize("strategy,name,cos_i", GRID,
                         ids=[f"{s}-{b}-cos{c}" for s, b, c in GRID])
def test_strategy_density_matches_its_samples(strategy, name, cos_i, monkeypatch, tmp_path):
    strategy_chi2(strategy, mi.load_dict(BSDFS[name]), cos_i, monkeypatch, tmp_path, len(GRID),
                  seed=GRID.index((strategy, name, cos_i)))


class TiltedUniform(strategies.HemisphereSampling):
    """Negative control: uniform sampling that reports (and weights by) its density times
    1 + TILT cos(phi): still normalised, off by at most TILT, about the smallest error a
    chi-square test of this grid (1e6 samples, its Sidak-corrected level) rejects."""
    TILT = 0.04

    def __init__(self):
        super().__init__("uniform")

    def pdf(self, bsdf, ctx, si, wo, active):
        cos_phi = wo.x / dr.maximum(dr.sqrt(wo.x * wo.x + wo.y * wo.y), 1e-12)
        return super().pdf(bsdf, ctx, si, wo, active) * (1 + self.TILT * cos_phi)


def test_reported_pdf_off_by_a_direction_dependent_factor_fails(monkeypatch, tmp_path):
    """Uniform sampling that reports a density 4% off (:class:`TiltedUniform`) must be
    rejected."""
    with pytest.raises(AssertionError):
        strategy_chi2(TiltedUniform(), mi.load_dict(BSDFS["diffuse"]), 0.6,
                      monkeypatch, tmp_path, len(GRID))


def test_mis_density_is_the_mixture():
    """mis reports w * cosine + (1 - w) * BSDF density, w = MIS_COSINE_WEIGHT, exactly."""
    bsdf = mi.load_dict(BSDFS["phong"])
    ctx = mi.BSDFContext()
    si = interaction(incident(0.6), 1)
    wo = dr.normalize(mi.Vector3f(-0.5, 0.2, 0.7))
    w = strategies.MIS_COSINE_WEIGHT
    expected = w * wo.z[0] / math.pi + (1 - w) * bsdf.pdf(ctx, si, wo)[0]
    assert vr_path.direction_pdf("mis", bsdf, ctx, si, wo)[0] == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize("strategy", [s for s in vr_path.STRATEGIES if s != "bsdf"])
def test_eta_of_a_crossing_direction_is_the_relative_ior(strategy):
    """As Mitsuba's path tracks bs.eta for sampled refractions: entering glass (int_ior
    1.5) eta is 1.5, leaving it 1/1.5, reflecting 1, whichever strategy drew wo."""
    bsdf = mi.load_dict({"type": "roughdielectric", "alpha": 0.3, "int_ior": 1.5})
    n = 4096
    u = dr.arange(mi.Float, n) / n
    for cos_i, eta in [(0.6, 1.5), (-0.6, 1 / 1.5)]:
        ds = vr_path.sample_direction(strategy, mi.BSDFPtr(bsdf), mi.BSDFContext(),
                                      interaction(incident(cos_i), n), u,
                                      mi.Point2f(u * 37.0 - dr.floor(u * 37.0),
                                                 u * 101.0 - dr.floor(u * 101.0)))
        crosses = (ds.wo.z * cos_i < 0) & (ds.pdf > 0)
        got = dr.select(crosses, ds.eta, 1.0)
        assert dr.all(dr.abs(got - dr.select(crosses, eta, 1.0)) < 1e-3)
        assert dr.all(dr.select(crosses | (ds.pdf == 0), 1.0, ds.eta) == 1.0)
        assert dr.any(crosses) and dr.any(~crosses & (ds.pdf > 0))


@pytest.mark.parametrize("strategy", vr_path.STRATEGIES)
@pytest.mark.parametrize("name", ["phong", "roughdielectric", "dielectric"])
def test_sample_and_eval_is_sample_plus_the_bsdf_at_wo_em(strategy, name):
    """The NEE form returns a VertexSample (through dr.dispatch as in the render loop):
    its direction is sample_direction's, its em_value the BSDF's eval at wo_em and its
    em_pdf the strategy's density there (a delta BSDF: 0 and 0)."""
    bsdf = mi.load_dict(BSDFS.get(name, {"type": name}))
    ctx, n = mi.BSDFContext(), 1024
    u = (dr.arange(mi.Float, n) + 0.5) / n
    u2 = mi.Point2f(u * 37.0 - dr.floor(u * 37.0), u * 101.0 - dr.floor(u * 101.0))
    si = interaction(incident(0.6), n)
    wo_em = dr.normalize(mi.Vector3f(u2.x - 0.5, u2.y - 0.5, u - 0.3))
    for b in (mi.BSDFPtr(bsdf), bsdf):
        vs = vr_path.sample_direction_and_eval(strategy, b, ctx, si, u, u2, wo_em)
        ds = vr_path.sample_direction(strategy, b, ctx, si, u, u2)
        assert isinstance(vs, vr_path.VertexSample)
        assert isinstance(vs.direction, vr_path.DirectionSample) and isinstance(
            ds, vr_path.DirectionSample)
        for field in vr_path.DirectionSample._fields:
            got, want = (np.array(getattr(t, field)) for t in (vs.direction, ds))
            assert np.array_equal(*np.broadcast_arrays(got, want)), field
        value, pdf = bsdf.eval_pdf(ctx, si, wo_em)
        assert dr.allclose(vs.em_value, value, rtol=1e-5, atol=1e-7)
        assert dr.allclose(vs.em_pdf, vr_path.direction_pdf(strategy, bsdf, ctx, si, wo_em),
                           rtol=1e-5, atol=1e-7)
