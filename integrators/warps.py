"""Sample warps and their densities: the only place with sampling maths.

Every warp maps a point ``u`` of the unit square to a unit direction in local
coordinates (z is the axis of the hemisphere or lobe) and is paired with its
density in solid angle measure, as in pbrt-v4's ``util/sampling.h`` and Nori's
``warp.h``. All functions are pure, vectorised Dr.Jit code, safe inside
symbolic loops. The uniform and cosine warps are Mitsuba's own (``mi.warp``).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi


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


def reflect_to_side(v: mi.Vector3f, below: mi.Bool) -> mi.Vector3f:
    """``v`` (a direction with z >= 0) mirrored to z < 0 where ``below``."""
    return mi.Vector3f(v.x, v.y, dr.select(below, -v.z, v.z))


def sided_pdf(hemisphere_pdf, v: mi.Vector3f, wi_z: mi.Float, both_sides: mi.Bool) -> mi.Float:
    """Density of a hemisphere warp put on a side by :func:`reflect_to_side`.

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
