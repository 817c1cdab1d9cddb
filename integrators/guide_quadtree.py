"""The guide's directional model: PPG's adaptive quadtree, flattened onto the fine histogram.

Mueller, Gross and Novak (2017) keep, per spatial leaf, a quadtree over the cylindrical
map of the sphere (cos theta, phi): a node is split into four where it holds more than a
fraction ``rho`` of the leaf's energy, so the model is fine where light arrives and
coarse (few records pooled) where it does not; a direction is drawn from a leaf of the
tree with probability its energy, uniformly inside it.

Here the records are binned in the ``res x res`` equal-area histogram of
:mod:`.guide_warps` (``res`` a power of two: the quadtree's finest level) and
:func:`density` fits the quadtree to them on the host: a node of level ``l`` (``4^l``
nodes, each a square block of bins) is a leaf where it holds at most ``rho`` of the
energy (its parent holding more, or it is the root), or at the finest level. Every bin of
a leaf gets the leaf's energy over its bins, so the fitted tree **is** a histogram of
``res x res`` bins: the render kernel's density lookup (one gather) and sampling
(the alias table of :func:`.guide_warps.alias_table`) do not change, nor their cost, and the tree's
shape recompiles nothing. Pure numpy: no Dr.Jit, no Mitsuba.
"""
from __future__ import annotations

import numpy as np

#: PPG's rho: a node splits where it holds more than this share of its unit's energy
#: (``vr_guided_path``'s ``directional_split`` takes it; its default is 0, the raw bins).
SPLIT_SHARE = 0.01


def levels(res: int) -> int:
    """The quadtree's depth over a ``res x res`` histogram (``res`` a power of two)."""
    depth = int(res).bit_length() - 1
    if res < 1 or 2 ** depth != res:
        raise ValueError(f"the adaptive quadtree needs a power-of-two resolution, got {res}")
    return depth


def node_energies(energy: np.ndarray, res: int, level: int) -> np.ndarray:
    """Per row of ``energy`` (rows of ``res x res`` bins, index ``i_cos * res + i_phi``),
    the energy of each node of ``level``: shape ``(rows, 2^level, 2^level)``."""
    n, side = 2 ** level, res >> level
    return energy.reshape(-1, n, side, n, side).sum(axis=(2, 4))


def density(energy: np.ndarray, res: int, split_share: float = SPLIT_SHARE) -> np.ndarray:
    """Per row of ``energy``, the fitted quadtree's energy spread over the ``res x res``
    bins (see the module): each bin holds its leaf's energy over the leaf's bins, so a row
    keeps its total. A node splits where it holds more than ``split_share`` of its row's
    total; ``split_share`` 0 keeps every bin (the raw histogram)."""
    energy = np.asarray(energy, np.float64).reshape(-1, res * res)
    depth = levels(res)
    total = energy.sum(axis=1)[:, None, None]
    out = np.zeros_like(energy).reshape(-1, res, res)
    open_ = np.ones(out.shape, bool)           # bins whose leaf is not found yet
    for level in range(depth + 1):
        nodes = node_energies(energy, res, level)
        side = res >> level
        leaf = (nodes <= split_share * total) | (level == depth)
        spread = np.repeat(np.repeat(nodes / (side * side), side, axis=1), side, axis=2)
        here = open_ & np.repeat(np.repeat(leaf, side, axis=1), side, axis=2)
        out[here] = spread[here]
        open_ &= ~here
    return out.reshape(-1, res * res)


def leaf_count(energy: np.ndarray, res: int, split_share: float = SPLIT_SHARE) -> np.ndarray:
    """Per row of ``energy``, the number of leaves of its fitted quadtree (the model's
    size, for the docs and the tests)."""
    energy = np.asarray(energy, np.float64).reshape(-1, res * res)
    depth = levels(res)
    total = energy.sum(axis=1)[:, None, None]
    count = np.zeros(len(energy), np.int64)
    parent_split = np.ones((len(energy), 1, 1), bool)
    for level in range(depth + 1):
        nodes = node_energies(energy, res, level)
        split = (nodes > split_share * total) & (level < depth)
        count += (parent_split & ~split).sum(axis=(1, 2))
        parent_split = np.repeat(np.repeat(split, 2, axis=1), 2, axis=2)
    return count
