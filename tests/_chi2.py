"""Chi-square helpers shared by the warp and BSDF tests.

Mitsuba's ``SphericalDomain`` bins (phi, cos theta) over the whole sphere; a
Phong lobe with exponent 10^4 is about 0.01 rad wide and falls into one row of
cells, where the tabulated pdf cannot be integrated accurately. ``CapDomain``
bins (phi, cos alpha) over a spherical cap about the lobe axis instead (the
same unit Jacobian: d omega = d phi d cos alpha), sized to a dozen lobe widths.
Samples outside the cap get weight 0, so histogram and pdf both integrate to
the mass inside the cap. Where the cap is the whole sphere, use the z axis: the
horizon, where BSDF densities jump to 0, is then a cell boundary; elsewhere the
cells are integrated with ires x ires points so that cells cut by the horizon
are tabulated accurately.

:func:`mass_and_albedo` checks what a chi-square test cannot see, a density off by a
constant factor: the density's integral over the sphere against the share of directions
drawn, and E[f cos / pdf] against the BSDF's albedo (the sampling lab's own checks,
:mod:`experiments.lib.studies.lab.mass`, on one lab panel).
"""
import math

import drjit as dr
import mitsuba as mi

# One definition of the chi-square grid and the interaction, the plugins' own (shared with
# the lab): a cap (phi, cos alpha) about an axis, the whole sphere for cos_min = -1.
from integrators.chi2 import EqualAreaDomain as CapDomain  # noqa: F401
from integrators.chi2 import cap_cos_min, interaction  # noqa: F401

SIGNIFICANCE = 0.01


def incident(cos_theta: float) -> mi.Vector3f:
    """Local incident direction in the xz plane with cos(theta) = ``cos_theta``."""
    return mi.Vector3f(math.sqrt(max(0.0, 1 - cos_theta ** 2)), 0.0, cos_theta)


def run_chi2(domain, sample, pdf, sample_dim, monkeypatch, tmp_path, test_count=1,
             sample_count=1_000_000, ires=16, seed=0):
    """Run Mitsuba's ChiSquareTest (from tmp_path: it writes chi2_data.py on failure).

    ``sample(u)`` returns (directions, weights). Returns the p-value; fails the
    test when the null hypothesis is rejected at SIGNIFICANCE (Sidak-corrected
    for ``test_count`` tests). Give every test of a grid its own ``seed``: with
    one seed all of them draw the same uniform variates and their p-values are
    correlated (seen: a Phong grid whose p-values had median 0.17 with seed 0
    everywhere, uniform over 20 seeds per case, KS p = 0.88).
    """
    monkeypatch.chdir(tmp_path)
    test = mi.chi2.ChiSquareTest(domain=domain, sample_func=sample, pdf_func=pdf,
                                 sample_dim=sample_dim, sample_count=sample_count, res=101,
                                 ires=ires, seed=seed)
    ok = test.run(SIGNIFICANCE, test_count=test_count, quiet=True)
    assert ok, test.messages
    return test.p_value


def panel_checks(strategy, bsdf: dict, cos_i: float, test_count=1, samples=250_000, seed=0):
    """The sampling lab's mass and albedo checks of ``strategy`` (a registered name or a
    Strategy object) on ``bsdf`` (a Mitsuba dict) at incidence cos(theta_i) = ``cos_i``:
    one lab panel (:func:`experiments.lib.studies.lab.warps.compute`), checked by
    :func:`experiments.lib.studies.lab.mass.checks` at SIGNIFICANCE, Sidak-corrected over
    ``test_count`` panels (two checks each). Returns (mass check, albedo check, panel)."""
    from experiments.lib.studies.lab import warps
    from experiments.lib.studies.lab.mass import checks, z_value
    spec = warps.PanelSpec("test", bsdf, strategy, math.degrees(math.acos(cos_i)), samples,
                           seed)
    panel = warps.compute(spec)
    mass, albedo = checks(panel, samples, z_value(2 * test_count, SIGNIFICANCE))
    return mass, albedo, panel


def mass_and_albedo(strategy, bsdf: dict, cos_i: float, test_count=1, samples=250_000, seed=0,
                    undecided_ok=False):
    """:func:`panel_checks`, failing the test when either check fails, and when one cannot
    decide (too wide, heavy tails) unless ``undecided_ok``. Returns what it returns."""
    from experiments.lib.studies.lab.mass import FAIL, PASS
    mass, albedo, panel = panel_checks(strategy, bsdf, cos_i, test_count, samples, seed)
    for name, c in (("mass / share drawn", mass), ("E[w] / albedo", albedo)):
        where = f"{strategy!r} on {bsdf} at cos_i={cos_i}: {name} = {c.ratio:.4g}"
        assert c.verdict != FAIL, f"{where}, interval [{c.low:.4g}, {c.high:.4g}]"
        assert undecided_ok or c.verdict == PASS, \
            f"{where}: cannot decide ({c.reason}, half-width {c.half_width:.3g})"
    return mass, albedo, panel
