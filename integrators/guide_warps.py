"""The directional warp of the path guide: an equal-area histogram on the sphere.

A direction is binned by its cylindrical coordinates (cos theta, phi) in world space
(Lambert's map: d omega = d cos(theta) d phi, so ``res x res`` equal cells of the rectangle
[-1, 1] x [0, 2 pi) are ``res^2`` bins of equal solid angle ``4 pi / res^2``). A histogram
of bin probabilities ``p`` is sampled in O(1) by Walker's alias method (one gather of a
bin's threshold and alias: :func:`alias_table`, :func:`sample_alias`) and a uniform point
inside the chosen bin; its density is ``p[bin] / (4 pi / res^2)``.
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


def alias_order(prob: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What :func:`alias_table` reads, per row of ``prob`` (rows of ``n`` bin
    probabilities, each summing to 1): the bins' scaled probabilities ``n p`` with the
    *light* bins (``n p < 1``) first and the *heavy* ones after them, and those bins'
    indices, both (rows, n)."""
    q = prob * prob.shape[1]
    order = np.argsort(q >= 1.0, axis=1, kind="stable")
    return np.take_along_axis(q, order, axis=1), order


@dr.syntax
def alias_table(table: mi.Float, first: mi.UInt32, q: mi.Float, order: mi.UInt32,
                bins: int) -> None:
    """Walker's alias tables of rows of ``bins`` bins, written into ``table`` in place:
    per bin the pair (threshold, alias), row ``k`` of the inputs at row ``first + k`` of
    ``table``. The inputs are :func:`alias_order`'s, flattened. Vose's method, one lane per
    row: a light bin keeps its own share ``n p`` and gives the rest of its slot to the
    current heavy bin, which pays it from its excess; a heavy bin whose scaled
    probability falls under 1 is a light one at once, filled by the next heavy bin. Bin
    ``i`` is then drawn with probability ``(threshold_i + sum over the bins aliased to
    i of (1 - threshold)) / n = p_i`` (:func:`alias_probabilities_np`)."""
    lane = dr.arange(mi.UInt32, dr.width(first))
    row = lane * bins
    out = first * bins
    light, heavy = mi.UInt32(0), mi.UInt32(bins - 1)
    excess = dr.gather(mi.Float, q, row + heavy)        # the current heavy bin's n p
    step = mi.UInt32(0)
    while step < bins:
        demoted = (excess < 1.0) & (heavy > light)
        share = dr.select(demoted, excess, dr.gather(mi.Float, q, row + light))
        small = dr.gather(mi.UInt32, order, row + dr.select(demoted, heavy, light))
        heavy = dr.select(demoted, heavy - 1, heavy)
        large = dr.gather(mi.UInt32, order, row + heavy)
        last = small == large                           # the row's last bin
        dr.scatter(table, dr.select(last, 1.0, dr.minimum(share, 1.0)), 2 * (out + small))
        dr.scatter(table, mi.Float(large), 2 * (out + small) + 1)
        excess = dr.select(demoted, dr.gather(mi.Float, q, row + heavy), excess)
        excess = excess - dr.select(last, 0.0, 1.0 - share)
        light = dr.select(demoted, light, light + 1)
        step += 1


def sample_alias(table: mi.Float, offset: mi.UInt32, u: mi.Float, u2: mi.Point2f,
                 res: int, active=True) -> mi.Vector3f:
    """A direction drawn from the histogram whose alias table (:func:`alias_table`)
    starts at bin ``offset`` of ``table``: the bin ``i = floor(u n)`` or its alias, as
    ``u n - i`` falls under its threshold or not, and the point inside it by ``u2``.
    Density: :func:`histogram_pdf`."""
    bins = res * res
    x = dr.minimum(u, ONE_MINUS_EPSILON) * bins
    index = dr.minimum(mi.UInt32(x), bins - 1)
    entry = dr.gather(mi.Point2f, table, offset + index, active)
    index = dr.select(x - mi.Float(index) < entry.x, index, mi.UInt32(entry.y))
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


def alias_probabilities_np(table: np.ndarray) -> np.ndarray:
    """The bin probabilities that alias tables (rows of ``n`` (threshold, alias) pairs,
    shape (rows, n, 2)) draw with: ``(threshold_i + sum over the bins aliased to i of
    (1 - threshold)) / n``."""
    rows, n, _ = table.shape
    prob = table[..., 0] / n
    index = (np.arange(rows)[:, None] * n + table[..., 1].astype(np.int64)).ravel()
    np.add.at(prob.reshape(-1), index, ((1.0 - table[..., 0]) / n).ravel())
    return prob


def histogram_pdf_np(probabilities: np.ndarray, d: np.ndarray, res: int) -> np.ndarray:
    """Density of the histogram ``probabilities`` (``res^2``) at the (N, 3) directions."""
    return probabilities[direction_to_bin_np(d, res)] / bin_solid_angle(res)
