"""Sample warps and their densities: the only place with sampling maths.

Every warp maps a point ``u`` of the unit square to a unit direction in local
coordinates (z is the axis of the hemisphere or lobe) and is paired with its
density in solid angle measure, as in pbrt-v4's ``util/sampling.h`` and Nori's
``warp.h``. All functions are pure, vectorised Dr.Jit code, safe inside
symbolic loops. The uniform and cosine warps are Mitsuba's own (``mi.warp``).
Besides the warps: the side warp of the ``vr_path`` strategies, the
one-sample mixture (its sample split and its density) and the power
heuristic, each paired with its density.
"""
from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

#: Largest float32 below 1 (``0x1.fffffep-1``): the upper clamp of every
#: value meant to lie in [0, 1) (rescaled samples, radical inverses).
ONE_MINUS_EPSILON = 1.0 - 2.0**-24

#: Floor of a density (or of a probability, or the normaliser of a lobe
#: choice) in a division: ``x / max(pdf, PDF_EPSILON)``. Used where the
#: result is kept only for ``pdf > 0`` (or is a path weight that must stay
#: finite), so it guards the discarded lanes and changes no division by a
#: value above it.
PDF_EPSILON = 1e-30


def square_to_uniform_hemisphere(u: mi.Point2f) -> mi.Vector3f:
    """Uniform direction on the hemisphere z >= 0."""
    return mi.warp.square_to_uniform_hemisphere(u)


def square_to_uniform_hemisphere_pdf(v: mi.Vector3f) -> mi.Float:
    """1 / (2 pi) on the hemisphere z > 0, 0 below it."""
    return dr.select(v.z > 0, dr.inv_two_pi, 0.0)


def square_to_uniform_sphere(u: mi.Point2f) -> mi.Vector3f:
    """Uniform direction on the whole sphere (for BSDFs that transmit)."""
    return mi.warp.square_to_uniform_sphere(u)


def square_to_uniform_sphere_pdf(v: mi.Vector3f) -> mi.Float:
    """1 / (4 pi) everywhere."""
    return mi.warp.square_to_uniform_sphere_pdf(v)


def square_to_cosine_hemisphere(u: mi.Point2f) -> mi.Vector3f:
    """Cosine-weighted direction on the hemisphere z >= 0 (Malley's method)."""
    return mi.warp.square_to_cosine_hemisphere(u)


def square_to_cosine_hemisphere_pdf(v: mi.Vector3f) -> mi.Float:
    """cos(theta) / pi on the hemisphere z > 0, 0 below it."""
    return dr.maximum(v.z, 0.0) * dr.inv_pi


class HemisphereWarp(NamedTuple):
    """A warp onto the hemisphere z > 0 and its density."""
    warp: object   # square_to_X(u: mi.Point2f) -> mi.Vector3f
    pdf: object    # square_to_X_pdf(v: mi.Vector3f) -> mi.Float


#: The hemisphere warps by name (``vr_path``'s ``uniform`` and ``cosine`` strategies).
HEMISPHERE_WARPS = {
    "uniform": HemisphereWarp(square_to_uniform_hemisphere, square_to_uniform_hemisphere_pdf),
    "cosine": HemisphereWarp(square_to_cosine_hemisphere, square_to_cosine_hemisphere_pdf),
}


def hemisphere_warp(kind: str) -> HemisphereWarp:
    """The warp named ``kind`` (a key of :data:`HEMISPHERE_WARPS`) and its density."""
    try:
        return HEMISPHERE_WARPS[kind]
    except KeyError:
        raise ValueError(f"warps: unknown hemisphere warp {kind!r}; "
                         f"valid choices are {', '.join(HEMISPHERE_WARPS)}") from None


def reflect_to_side(v: mi.Vector3f, below: mi.Bool) -> mi.Vector3f:
    """``v`` (a direction with z >= 0) mirrored to z < 0 where ``below``."""
    return mi.Vector3f(v.x, v.y, dr.select(below, -v.z, v.z))


def square_to_sided_hemisphere(warp, u1: mi.Float, u2: mi.Point2f, wi_z: mi.Float,
                               both_sides: mi.Bool) -> mi.Vector3f:
    """``warp(u2)`` (a hemisphere warp) put on a side by :func:`reflect_to_side`.

    One-sided (``both_sides`` False): the side of the incident direction
    (``wi_z``'s sign). Two-sided: z < 0 where ``u1 < 0.5``, else z > 0.
    Density: :func:`square_to_sided_hemisphere_pdf`.
    """
    below = dr.select(both_sides, u1 < 0.5, wi_z < 0)
    return reflect_to_side(warp(u2), below)


def square_to_sided_hemisphere_pdf(hemisphere_pdf, v: mi.Vector3f, wi_z: mi.Float,
                                   both_sides: mi.Bool) -> mi.Float:
    """Density of :func:`square_to_sided_hemisphere` (a hemisphere warp put on a side).

    ``hemisphere_pdf`` is the warp's density on z > 0. One-sided (``both_sides``
    False): the hemisphere of the incident direction (``wi_z``'s sign), 0 on the
    other. Two-sided: either hemisphere with probability 1/2, so half the density
    of the mirrored direction on both.
    """
    mirrored = hemisphere_pdf(mi.Vector3f(v.x, v.y, dr.abs(v.z)))
    same_side = (wi_z * v.z) > 0
    return dr.select(both_sides, 0.5 * mirrored, dr.select(same_side, mirrored, 0.0))


def mixture_pdf(weight_a: mi.Float, pdf_a: mi.Float, pdf_b: mi.Float) -> mi.Float:
    """Density of a one-sample mixture that draws from a with probability ``weight_a``.

    ``weight_a * pdf_a + (1 - weight_a) * pdf_b``, whichever technique produced
    the sample (Veach's one-sample model with the balance heuristic: the
    weight f / mixture pdf is the balance-heuristic MIS estimator).
    """
    return dr.fma(weight_a, pdf_a - pdf_b, pdf_b)


class MixtureSample(NamedTuple):
    """A 1-D sample split between the two techniques of a one-sample mixture."""
    use_a: mi.Bool   # technique a draws (probability weight_a)
    u_a: mi.Float    # the sample rescaled to [0, 1) for technique a
    u_b: mi.Float    # the sample rescaled to [0, 1) for technique b


def split_mixture_sample(u: mi.Float, weight_a: float) -> MixtureSample:
    """Choose the technique of a one-sample mixture (a where ``u < weight_a``) and
    reuse ``u``, rescaled to [0, 1) within the chosen technique (the other
    technique's value is meaningless in that lane). Density: :func:`mixture_pdf`.
    """
    return MixtureSample(u < weight_a,
                         dr.minimum(u / weight_a, ONE_MINUS_EPSILON),
                         dr.minimum((u - weight_a) / (1.0 - weight_a), ONE_MINUS_EPSILON))


def power_heuristic(pdf_a: mi.Float, pdf_b: mi.Float) -> mi.Float:
    """Power heuristic (beta = 2) MIS weight of technique a against b.

    Written as 1 / (1 + (b/a)^2) so that an infinite density (an emitter seen
    exactly edge-on) gives 1 or 0 instead of inf / inf = NaN; 0 where ``pdf_a`` is 0.
    """
    ratio = pdf_b / dr.select(pdf_a > 0, pdf_a, 1.0)
    return dr.select(pdf_a > 0, dr.rcp(1.0 + dr.square(ratio)), 0.0)


def square_to_phong_lobe(u: mi.Point2f, exponent: mi.Float) -> mi.Vector3f:
    """Direction about the z axis with density proportional to cos^n(alpha).

    Inverts the CDF of ``(n + 1) / (2 pi) cos^n(alpha)``: cos(alpha) =
    u.x^(1 / (n + 1)), phi = 2 pi u.y. Exponent 0 is the uniform hemisphere.
    """
    cos_alpha = dr.power(u.x, dr.rcp(exponent + 1.0))
    sin_alpha = dr.safe_sqrt(dr.fma(-cos_alpha, cos_alpha, 1.0))
    sin_phi, cos_phi = dr.sincos(dr.two_pi * u.y)
    return mi.Vector3f(cos_phi * sin_alpha, sin_phi * sin_alpha, cos_alpha)


def square_to_phong_lobe_pdf(v: mi.Vector3f, exponent: mi.Float) -> mi.Float:
    """(n + 1) / (2 pi) cos^n(alpha) for cos(alpha) = v.z > 0, else 0.

    The sign is tested before the power: pow(0, 0) = 1 would otherwise give
    exponent 0 a density outside the lobe.
    """
    inside = v.z > 0
    cos_alpha = dr.select(inside, v.z, 1.0)
    pdf = (exponent + 1.0) * dr.inv_two_pi * dr.power(cos_alpha, exponent)
    return dr.select(inside, pdf, 0.0)


def phong_lobe_to_square(v: mi.Vector3f, exponent: mi.Float) -> mi.Point2f:
    """Inverse of :func:`square_to_phong_lobe` (for tests and stratification checks)."""
    u_x = dr.power(dr.maximum(v.z, 0.0), exponent + 1.0)
    phi = dr.atan2(v.y, v.x)
    u_y = dr.select(phi < 0, phi + dr.two_pi, phi) * dr.inv_two_pi
    return mi.Point2f(u_x, u_y)
