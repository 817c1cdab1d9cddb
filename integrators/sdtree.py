"""The guide's learned state: a binary tree over space with a direction histogram per leaf.

A simplified SD-tree (Mueller, Gross, Novak 2017). Space: a binary tree over the scene's
bounding box, each level halving its node along x, y, z in turn (PPG's rule), a leaf split
between training passes when it received more than ``threshold`` records (and again, as
if its records halved with each split, up to :data:`MAX_DEPTH` levels). Directions: per
leaf an equal-area histogram of ``res x res`` bins (:mod:`.guide_warps`), rebuilt from the
pass's records, their energy smoothed by a 3x3 box blur (:func:`blur`: a bin of a lit
region is not left at density 0 by short training; a leaf with fewer than
:data:`MIN_RECORDS` keeps its previous histogram; children start with their parent's).

The tree lives on the host as numpy arrays of **fixed maximum sizes** (``max_leaves``
leaves, ``2 max_leaves`` nodes), refined there, and uploaded as evaluated Dr.Jit arrays:
the render kernel gathers from them and bakes only the sizes (res, :data:`MAX_DEPTH`), so
a refined tree does not recompile anything. The bounding box is an opaque array too.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from . import guide_warps

#: Levels of the spatial tree the kernel descends (unrolled): 8 splits per axis at most.
MAX_DEPTH = 24
#: Records a leaf needs in a pass to get a new directional histogram.
MIN_RECORDS = 32
#: Smooth each new histogram's energy with :func:`blur` (off: the raw records' shares, as
#: the tests of what the records hold need).
SMOOTH = True


def blur(energy: np.ndarray, res: int) -> np.ndarray:
    """A 3x3 box blur of each row of ``energy`` (rows of ``res x res`` bins, index
    ``i_cos * res + i_phi``): periodic in phi, the cos(theta) edges averaging over the
    neighbours they have. The total of a row is not kept (the caller normalises)."""
    e = energy.reshape(-1, res, res)
    e = e + np.roll(e, 1, axis=2) + np.roll(e, -1, axis=2)
    out = e.copy()
    out[:, 1:] += e[:, :-1]
    out[:, :-1] += e[:, 1:]
    rows = np.full(res, 3.0)
    rows[[0, -1]] = 2.0
    return (out / rows[None, :, None]).reshape(energy.shape)


class SDTree:
    """Host tree + device tables. ``res``: bins per side of a leaf's histogram;
    ``max_leaves``: the spatial budget (splits stop when it is spent)."""

    def __init__(self, res: int = 16, max_leaves: int = 1024):
        self.res, self.bins, self.max_leaves = res, res * res, max_leaves
        self.max_nodes = 2 * max_leaves
        self.child = np.zeros(self.max_nodes, np.uint32)     # first child (0: a leaf)
        self.leaf = np.zeros(self.max_nodes, np.uint32)      # leaf id of a leaf node
        self.depth = np.zeros(self.max_nodes, np.int64)
        self.nodes, self.leaves = 1, 1
        self.prob = np.full((max_leaves, self.bins), 1.0 / self.bins)
        self.learned = np.zeros(max_leaves, bool)            # has a histogram from records
        self.lower = mi.Point3f(dr.opaque(mi.Float, 0.0, 1), dr.opaque(mi.Float, 0.0, 1),
                                dr.opaque(mi.Float, 0.0, 1))
        self.inv_extent = mi.Vector3f(dr.opaque(mi.Float, 1.0, 1),
                                      dr.opaque(mi.Float, 1.0, 1), dr.opaque(mi.Float, 1.0, 1))
        self.has_bbox = False
        self.upload()
        self.reset_records()

    # ------------------------------------------------------------------ device side

    def set_bbox(self, bbox) -> None:
        """The root's box: ``bbox`` (a ``mi.ScalarBoundingBox3f``), grown by 1%."""
        lo, hi = np.array(bbox.min, float), np.array(bbox.max, float)
        pad = 0.01 * np.maximum(hi - lo, 1e-3)
        lo, hi = lo - pad, hi + pad
        self.lower = mi.Point3f(*[dr.opaque(mi.Float, float(v), 1) for v in lo])
        self.inv_extent = mi.Vector3f(*[dr.opaque(mi.Float, float(1.0 / v), 1)
                                        for v in hi - lo])
        self.has_bbox = True

    def upload(self) -> None:
        """The host tree as evaluated Dr.Jit arrays (fixed sizes: no recompilation)."""
        self.child_table = mi.UInt32(self.child)
        self.leaf_table = mi.UInt32(self.leaf)
        self.prob_table = mi.Float(self.prob.ravel().astype(np.float32))
        cdf = np.cumsum(self.prob, axis=1)
        cdf /= np.maximum(cdf[:, -1:], 1e-30)
        self.cdf_table = mi.Float(cdf.ravel().astype(np.float32))
        dr.eval(self.child_table, self.leaf_table, self.prob_table, self.cdf_table)

    def reset_records(self) -> None:
        """Empty record accumulators (energy per leaf bin, records per leaf)."""
        self.energy = dr.zeros(mi.Float, self.max_leaves * self.bins)
        self.counts = dr.zeros(mi.UInt32, self.max_leaves)
        dr.make_opaque(self.energy, self.counts)

    def lookup(self, p: mi.Point3f, active=True) -> mi.UInt32:
        """The leaf id of the world point ``p`` (points outside the box: the nearest leaf)."""
        q = dr.clip((p - self.lower) * self.inv_extent, 0.0, 1.0 - 1e-7)
        x, y, z = mi.Float(q.x), mi.Float(q.y), mi.Float(q.z)
        node = mi.UInt32(0)
        for level in range(MAX_DEPTH):
            child = dr.gather(mi.UInt32, self.child_table, node, active)
            inner = child != 0
            coord = (x, y, z)[level % 3]
            upper = coord >= 0.5
            node = dr.select(inner, child + mi.UInt32(upper), node)
            coord = dr.select(inner, dr.fma(coord, 2.0, dr.select(upper, -1.0, 0.0)), coord)
            if level % 3 == 0:
                x = coord
            elif level % 3 == 1:
                y = coord
            else:
                z = coord
        return dr.gather(mi.UInt32, self.leaf_table, node, active)

    def pdf(self, leaf: mi.UInt32, d: mi.Vector3f, active=True) -> mi.Float:
        """The guide's density at the world direction ``d`` in ``leaf``."""
        index = leaf * self.bins + guide_warps.direction_to_bin(d, self.res)
        return guide_warps.histogram_pdf(dr.gather(mi.Float, self.prob_table, index, active),
                                         self.res)

    def sample(self, leaf: mi.UInt32, u: mi.Float, u2: mi.Point2f, active=True):
        """A world direction from ``leaf``'s histogram (density :meth:`pdf`)."""
        return guide_warps.sample_histogram(self.cdf_table, leaf * self.bins, u, u2,
                                            self.res, active)

    def record_index(self, leaf: mi.UInt32, d: mi.Vector3f) -> mi.UInt32:
        """Where a record of radiance arriving along the world direction ``d`` goes."""
        return leaf * self.bins + guide_warps.direction_to_bin(d, self.res)

    # -------------------------------------------------------------------- host side

    def records(self) -> tuple[np.ndarray, np.ndarray]:
        """The accumulated (energy (leaves, bins), records per leaf) as numpy."""
        energy = np.array(self.energy, dtype=np.float64).reshape(self.max_leaves, self.bins)
        return energy, np.array(self.counts, dtype=np.int64)

    def refine(self, threshold: float) -> None:
        """Learn from the accumulated records, then reset them: new histograms where a
        leaf has enough records, then split the leaves over ``threshold`` records."""
        energy, counts = self.records()
        energy = np.where(np.isfinite(energy) & (energy > 0), energy, 0.0)
        total = energy.sum(axis=1)
        fresh = (counts >= MIN_RECORDS) & (total > 0)
        learned = blur(energy[fresh], self.res) if SMOOTH else energy[fresh]
        self.prob[fresh] = learned / learned.sum(axis=1, keepdims=True)
        self.learned |= fresh
        self._split(counts, threshold)
        self.upload()
        self.reset_records()

    def _split(self, counts: np.ndarray, threshold: float) -> None:
        queue = [(n, float(counts[self.leaf[n]])) for n in range(self.nodes)
                 if self.child[n] == 0]
        while queue:
            node, n = queue.pop()
            if (n <= threshold or self.depth[node] >= MAX_DEPTH
                    or self.nodes + 2 > self.max_nodes or self.leaves + 1 > self.max_leaves):
                continue
            first, old = self.nodes, int(self.leaf[node])
            self.child[node] = first
            for k, leaf in enumerate((old, self.leaves)):
                self.child[first + k] = 0
                self.leaf[first + k] = leaf
                self.depth[first + k] = self.depth[node] + 1
                self.prob[leaf] = self.prob[old]
                self.learned[leaf] = self.learned[old]
                queue.append((first + k, n / 2))
            self.nodes += 2
            self.leaves += 1
