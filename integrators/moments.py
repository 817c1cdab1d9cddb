"""The ``vr_moments`` integrator: another integrator's image with its samples' raw moments.

Mitsuba's own ``moment`` integrator gives the second moments of its nested integrator's
colour as XYZ; the per-channel variances of an RGB image need the RGB squares, and how
sure those variances are needs the third and fourth powers: this wrapper adds them as
nine AOVs.
"""
from __future__ import annotations

import mitsuba as mi

#: The AOV names of the squares, after the nested integrator's own AOVs.
SQUARES = ("m2.R", "m2.G", "m2.B")
#: Then those of the cubes and the fourth powers.
CUBES = ("m3.R", "m3.G", "m3.B")
FOURTHS = ("m4.R", "m4.G", "m4.B")
#: Every moment AOV, in order.
MOMENTS = SQUARES + CUBES + FOURTHS


class MomentsIntegrator(mi.SamplingIntegrator):
    r"""
    .. _integrator-vr_moments:

    Sample moments (:monosp:`vr_moments`)
    -------------------------------------

    .. pluginparameters::

     * - nested
       - |integrator|
       - The integrator whose samples are measured (required): a sampling integrator
         such as ``path`` or ``vr_path``.

    Renders with the nested integrator and adds the per-pixel mean of each sample's
    squared R, G and B (AOVs ``m2.R``, ``m2.G``, ``m2.B``, after the nested integrator's
    own AOVs), then of their cubes (``m3.*``) and fourth powers (``m4.*``). Mitsuba's own
    ``moment`` integrator gives the second moments of the colour as XYZ; per-channel RGB
    variances need the RGB squares, and the variance of those variances (a pixel ruled by
    rare bright samples has a far less certain variance than a normal one) needs the
    fourth central moment.

    Under a box filter (radius 0.5) with the ``independent`` sampler each sample lands in
    one pixel with weight 1, so a pixel's ``m2`` and colour are the means of its samples'
    squares and values: ``(m2 - mean^2) / (spp - 1)`` estimates the variance of the
    pixel's mean with ``spp - 1`` degrees of freedom (the experiments' accumulators keep it
    as every sample its own pass). Under another filter, or a sampler whose samples are not
    independent, these are not a sample variance.

    The AOV channels cost little kernel time on the 2-core machine (three of them: grazing,
    128 spp, 21.8 against 21.6 ns per sample); compare methods both wrapped or both not.
    The film sums them in single precision: a central moment read from them is exact only
    to that rounding (:func:`experiments.lib.jobs.variance_of_variance` bounds it).
    """

    def __init__(self, props: mi.Properties):
        super().__init__(props)
        self.nested = nested_integrator(props, "vr_moments")

    def sample(self, scene, sampler, ray, medium=None, active=True):
        L, valid, aovs = self.nested.sample(scene, sampler, ray, medium, active)
        return L, valid, list(aovs) + powers(L)

    def aov_names(self):
        return list(self.nested.aov_names()) + list(MOMENTS)

    def to_string(self):
        return f"MomentsIntegrator[nested={self.nested}]"


def powers(L) -> list:
    """The AOV values of :data:`MOMENTS` for one sample's radiance ``L``: its R, G, B
    squared, cubed and to the fourth power."""
    c = mi.Color3f(mi.unpolarized_spectrum(L))
    c2 = c * c
    c3, c4 = c2 * c, c2 * c2
    return [c2.x, c2.y, c2.z, c3.x, c3.y, c3.z, c4.x, c4.y, c4.z]


def nested_integrator(props: mi.Properties, plugin: str):
    """The one nested sampling integrator of a wrapper ``plugin``'s ``props``; ValueError
    naming the plugin otherwise."""
    nested = [props[name] for name in props.keys()
              if isinstance(props[name], mi.SamplingIntegrator)]
    if len(nested) != 1:
        raise ValueError(f"{plugin}: give exactly one nested sampling integrator (got "
                         f"{len(nested)}), e.g. {{'type': '{plugin}', 'nested': "
                         f"{{'type': 'path'}}}}")
    return nested[0]


mi.register_integrator("vr_moments", lambda props: MomentsIntegrator(props))
