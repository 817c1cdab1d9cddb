"""A direction-sampling strategy of one's own, in one file: a cos^n lobe about the mirror
direction, mixed with cosine sampling (registered as ``mirror_lobe``).

Load it with ``--plugin examples/mirror_lobe.py`` (any experiment script), or import it in
Python before loading a scene; then ``mirror_lobe`` is a strategy like the built-in ones:
``vr_path``'s ``strategy`` parameter, the method grammar (``mirror_lobe+nee+halton``), the
chi-square tests, the sampling lab's warp panels and every study. See docs/extending.md.
"""
import mitsuba as mi

import integrators
from integrators import strategies, warps

#: The lobe's exponent: the larger, the closer to a mirror.
EXPONENT = 20.0
#: Share of the lobe in the mixture. The lobe alone has density 0 where a diffuse BSDF's
#: f cos is not (directions far from the mirror direction): mixing in cosine sampling keeps
#: the estimator unbiased on every BSDF.
LOBE_SHARE = 0.5


class MirrorLobe(strategies.Strategy):
    """cos^n(alpha) about the mirror direction of the incident one (alpha: the angle to it);
    ``sample`` and ``pdf`` only, the maths from :mod:`integrators.warps`."""

    def __init__(self, exponent: float = EXPONENT):
        self.exponent = exponent

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        wo = mi.Frame3f(mi.reflect(si.wi)).to_world(
            warps.square_to_phong_lobe(sample2, self.exponent))
        return strategies.weighted_direction(bsdf, ctx, si, wo,
                                             self.pdf(bsdf, ctx, si, wo, active), active)

    def pdf(self, bsdf, ctx, si, wo, active):
        local = mi.Frame3f(mi.reflect(si.wi)).to_local(wo)
        return warps.square_to_phong_lobe_pdf(local, self.exponent)


def mirror_lobe() -> strategies.Strategy:
    """The registered strategy: the lobe, defensively mixed with cosine sampling."""
    return strategies.Mixture(MirrorLobe(), strategies.cosine, LOBE_SHARE)


integrators.register_strategy("mirror_lobe", mirror_lobe, replace=True)
