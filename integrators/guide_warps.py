"""The directional warp of the path guide: an equal-area histogram on the sphere.

A direction is binned by its cylindrical coordinates (cos theta, phi) in world space
(Lambert's map: d omega = d cos(theta) d phi, so ``res x res`` equal cells of the rectangle
[-1, 1] x [0, 2 pi) are ``res^2`` bins of equal solid angle ``4 pi / res^2``). A histogram
of bin probabilities ``p`` is sampled by inverting its cumulative sum (a binary search)
and a uniform point inside the chosen bin; its density is ``p[bin] / (4 pi / res^2)``.
Every warp here has its pdf beside it (Dr.Jit versions for the render kernel, numpy
versions for the host and the tests). Pure functions only: the tables live in
:mod:`.sdtree`.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from .warps import ONE_MINUS_EPSILON


def bin_solid_angle(res: int) -> float:
    """Solid angle of one of the ``res x res`` equal-area bins: 4 pi / res^2."""
    return 4.0 * math.pi / (res * res)


def direction_to_bin(d: mi.Vector3f, res: int) -> mi.UInt32:
    """Index ``i_cos * res + i_phi`` of the bin holding the unit direction ``d``."""
    cos_theta = dr.clip(d.z, -1.0, 1.0)
    phi = dr.atan2(d.y, d.x)
    phi = dr.select(phi < 0, phi + dr.two_pi, phi)
    i_cos = dr.minimum(mi.UInt32(dr.maximum((cos_theta + 1.0) * (0.5 * res), 0.0)), res - 1)
    i_phi = dr.minimum(mi.UInt32(dr.maximum(phi * (res * dr.inv_two_pi), 0.0)), res - 1)
    return i_cos * res + i_phi


def bin_to_direction(index: mi.UInt32, u: mi.Point2f, res: int) -> mi.Vector3f:
    """The direction at the point ``u`` (in [0, 1)^2) of bin ``index``: uniform over the
    bin's solid angle for uniform ``u``."""
    i_cos = index // res
    i_phi = index - i_cos * res
    cos_theta = dr.fma(mi.Float(i_cos) + u.x, 2.0 / res, -1.0)
    phi = (mi.Float(i_phi) + u.y) * (dr.two_pi / res)
    sin_theta = dr.safe_sqrt(1.0 - dr.square(cos_theta))
    s, c = dr.sincos(phi)
    return mi.Vector3f(sin_theta * c, sin_theta * s, cos_theta)


def sample_histogram(cdf: mi.Float, offset: mi.UInt32, u: mi.Float, u2: mi.Point2f,
                     res: int, active=True) -> mi.Vector3f:
    """A direction drawn from the histogram whose inclusive cumulative sum starts at
    ``offset`` in ``cdf`` (``res^2`` entries ending at 1): the bin by inverting the sum with
    ``u``, the point inside it by ``u2``. Density: :func:`histogram_pdf`."""
    bins = res * res
    u = dr.minimum(u, ONE_MINUS_EPSILON)
    index = dr.binary_search(
        0, bins - 1,
        lambda i: dr.gather(mi.Float, cdf, offset + i, active) <= u)
    index = dr.minimum(index, bins - 1)
    return bin_to_direction(index, u2, res)


def histogram_pdf(probability: mi.Float, res: int) -> mi.Float:
    """Density in solid angle of a direction in a bin of probability ``probability``."""
    return probability * (1.0 / bin_solid_angle(res))


# ------------------------------------------------------------ numpy twins (host, tests)

def direction_to_bin_np(d: np.ndarray, res: int) -> np.ndarray:
    """:func:`direction_to_bin` for an (N, 3) numpy array of unit directions."""
    cos_theta = np.clip(d[:, 2], -1.0, 1.0)
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
    i_cos = np.minimum(((cos_theta + 1.0) * 0.5 * res).astype(np.int64), res - 1)
    i_phi = np.minimum((phi * res / (2 * np.pi)).astype(np.int64), res - 1)
    return i_cos * res + i_phi


def histogram_pdf_np(probabilities: np.ndarray, d: np.ndarray, res: int) -> np.ndarray:
    """Density of the histogram ``probabilities`` (``res^2``) at the (N, 3) directions."""
    return probabilities[direction_to_bin_np(d, res)] / bin_solid_angle(res)
