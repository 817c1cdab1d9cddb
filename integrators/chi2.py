"""Chi-square helpers for testing the plugins' sampling, beside :mod:`mitsuba.chi2`.

As ``mitsuba.chi2`` belongs to the library whose plugins its tests check, these belong to
the plugins: the tests (``tests/_chi2.py``) and the sampling lab
(``experiments.lib.studies.lab.warps``) import them from here, one definition for both.

* :class:`EqualAreaDomain`: a ``mitsuba.chi2`` domain over a spherical cap (phi, cos alpha)
  about an axis, the whole sphere for ``cos_min = -1``. Mitsuba's ``SphericalDomain`` bins
  (phi, cos theta) over the whole sphere; a Phong lobe of exponent 10^4 is about 0.01 rad
  wide and falls into one row of cells there, where the tabulated density cannot be
  integrated accurately. A cap about the lobe axis has the same unit Jacobian
  (d omega = d phi d cos alpha) and resolves it.
* :func:`cap_cos_min`: the cap that holds a Phong lobe (a dozen lobe widths).
* :func:`interaction`: surface interactions with a given local incident direction, to
  call a BSDF or a strategy outside a render.

Importable before a Mitsuba variant is set; ``mi.*`` types are used at call time only.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

#: Width of :func:`cap_cos_min`'s cap, in Phong lobe widths.
CAP_LOBE_WIDTHS = 12.0


class EqualAreaDomain:
    """mitsuba.chi2 domain: (phi, cos alpha) about ``axis``, cos alpha in
    [``cos_min``, 1], square grid (aspect 1); y grows towards the axis. The
    default is the whole sphere about the normal (y = cos theta)."""

    def __init__(self, axis=(0.0, 0.0, 1.0), cos_min: float = -1.0):
        self.axis = tuple(float(a) for a in axis)
        self.cos_min = float(cos_min)

    def _frame(self):
        return mi.Frame3f(dr.normalize(mi.Vector3f(*self.axis)))

    def bounds(self):
        return mi.ScalarBoundingBox2f([-math.pi, self.cos_min], [math.pi, 1.0])

    def aspect(self):
        return 1.0

    def map_forward(self, p):
        sin_t = dr.safe_sqrt(1.0 - dr.square(p.y))
        sin_p, cos_p = dr.sincos(p.x)
        return self._frame().to_world(mi.Vector3f(cos_p * sin_t, sin_p * sin_t, p.y))

    def map_backward(self, v):
        local = self._frame().to_local(v)
        return mi.Vector2f(dr.atan2(local.y, local.x), dr.clip(local.z, self.cos_min, 1.0))

    def inside(self, v):
        """Directions inside the domain (all of them for the whole sphere)."""
        return self._frame().to_local(v).z >= self.cos_min

    def restrict(self, v, weight):
        """Zero the weight of (and park at the axis) the directions outside the domain, so
        that histogram and density both integrate to the mass inside it."""
        inside = self.inside(v)
        return (dr.select(inside, v, dr.normalize(mi.Vector3f(*self.axis))),
                dr.select(inside, weight, 0.0))

    def describe(self) -> str:
        if self.cos_min <= -1.0:
            return "whole sphere, (phi, cos theta)"
        return (f"cap of half-angle {math.degrees(math.acos(self.cos_min)):.1f} deg about the "
                f"mirror direction, (phi, cos alpha)")


def cap_cos_min(exponent: float, lobe_widths: float = CAP_LOBE_WIDTHS) -> float:
    """cos of the half-angle of a cap ``lobe_widths`` Phong lobe widths wide:
    1 - lobe_widths / (n + 1), at least -1 (the whole sphere)."""
    return max(-1.0, 1.0 - lobe_widths / (exponent + 1.0))


def interaction(wi, n: int):
    """``n`` surface interactions with local incident direction ``wi``, z-up frame."""
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = wi
    si.uv = mi.Point2f(0.5, 0.5)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.n = mi.Normal3f(0, 0, 1)
    return si
