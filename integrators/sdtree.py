"""The guide's learned state: a binary tree over space with a direction histogram per leaf.

A simplified SD-tree (Mueller, Gross, Novak 2017). Space: a binary tree over the scene's
bounding box, each level halving its node along x, y, z in turn (PPG's rule), a leaf split
between training passes when it received more than ``threshold`` records (and again, as
if its records halved with each split, up to :data:`MAX_DEPTH` levels). Directions: per
leaf and normal class (a *unit*, :data:`CLASSES`) an equal-area histogram of
``res x res`` bins (:mod:`.guide_warps`), fitted after each iteration to every record the
unit has received (:data:`POOLED`; a unit with fewer than :data:`MIN_RECORDS` keeps its
previous histogram; children start with their parent's) by :mod:`.guide_quadtree`
(PPG's adaptive quadtree, flattened onto the bins; ``split_share`` 0: the raw bins;
:func:`blur` smooths the energies when :data:`SMOOTH` is on).

The tree lives on the host as numpy arrays of **fixed maximum sizes** (``max_leaves``
leaves, ``2 max_leaves`` nodes), refined there, and uploaded as evaluated Dr.Jit arrays:
the render kernel finds a point's leaf in a grid filled from the tree (one gather) and
bakes only the sizes (res, :data:`GRID`), so a refined tree does not recompile anything.
The bounding box is an opaque array too.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from . import guide_quadtree, guide_warps

#: Levels of the spatial tree (6 splits per axis at most): the kernel finds a point's leaf
#: in a grid of ``2^(MAX_DEPTH / 3)`` cells per axis that the host fills from the tree.
MAX_DEPTH = 18
#: Cells per axis of that grid.
GRID = 2 ** (MAX_DEPTH // 3)
#: Normal classes per leaf: the dominant axis of the geometric normal and its sign. A
#: leaf keeps one distribution per class, so that the two sides of a thin wall, or the
#: floor and the wall of a corner, do not share one (each class's directions lie mostly
#: above its surfaces).
CLASSES = 6
#: Records a leaf needs in a pass to get a new directional histogram.
MIN_RECORDS = 32
#: Candidate BSDF shares a unit chooses from (:meth:`SDTree.refine`): 0.1, 0.2, ..., 1.
SHARES = np.round(np.arange(1, 11) / 10, 1)
#: How the records' share statistics are added: few addresses, many records each.
MOMENTS_MODE = dr.ReduceMode.Auto
#: The share of a unit that just learned its first histogram (its records were evaluated
#: against a uniform guide, which says nothing about the new one): BSDF sampling until
#: the next iteration's records, evaluated against the learned guide, say otherwise.
PRIOR_SHARE = 1.0
#: Smooth each new histogram's energy with :func:`blur` (off: the raw records' shares, as
#: the tests of what the records hold need).
SMOOTH = False
#: Pool every iteration's records (a unit's histogram is fitted to all the records it has
#: received, a split leaf's children each starting with half of its sums), instead of the
#: last iteration's alone (PPG): the earlier records are fewer and from worse guides, but
#: weighted by their own densities they estimate the same radiance (docs/guiding.md).
POOLED = True
#: Learn incident radiance times |cos| to the unit's normal-class axis (the product a
#: diffuse surface needs), not the radiance alone (PPG's): docs/guiding.md.
COSINE_PRODUCT = True


def class_cosines(res: int) -> np.ndarray:
    """(CLASSES, res^2): |cos| between each normal class's axis (+x, -x, +y, -y, +z, -z,
    :meth:`SDTree.lookup`'s order) and the direction through each bin's centre."""
    i = np.arange(res * res)
    cos_t = ((i // res) + 0.5) * (2.0 / res) - 1.0
    phi = ((i % res) + 0.5) * (2.0 * np.pi / res)
    sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
    d = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t])
    return np.abs(np.repeat(d, 2, axis=0))


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
    ``max_leaves``: the spatial budget (splits stop when it is spent); ``split_share``:
    :func:`.guide_quadtree.density`'s (0: the raw bins). The directional
    tables have a row per *unit*: ``leaf * CLASSES + normal class``."""

    def __init__(self, res: int = 16, max_leaves: int = 1024, split_share: float = 0.0):
        self.res, self.bins, self.max_leaves = res, res * res, max_leaves
        self.split_share = split_share
        self.max_units = max_leaves * CLASSES
        self.max_nodes = 2 * max_leaves
        self.child = np.zeros(self.max_nodes, np.uint32)     # first child (0: a leaf)
        self.leaf = np.zeros(self.max_nodes, np.uint32)      # leaf id of a leaf node
        self.depth = np.zeros(self.max_nodes, np.int64)
        self.nodes, self.leaves = 1, 1
        self.prob = np.full((self.max_units, self.bins), 1.0 / self.bins)
        self.learned = np.zeros(self.max_units, bool)        # has a histogram from records
        self.share = np.ones(self.max_units)                 # BSDF share per unit
        # per unit: the energy and records of every iteration so far (:data:`POOLED`)
        self.kept_energy = np.zeros((self.max_units, self.bins))
        self.kept_counts = np.zeros(self.max_units)
        # per unit: the radiance reflected after the vertex's NEE and by its NEE, per unit
        # throughput (the roulette's estimate; -1: none yet)
        self.reflected = np.full((self.max_units, 2), -1.0)
        self.lower = mi.Point3f(dr.opaque(mi.Float, 0.0, 1), dr.opaque(mi.Float, 0.0, 1),
                                dr.opaque(mi.Float, 0.0, 1))
        self.scale = mi.Vector3f(dr.opaque(mi.Float, 1.0, 1),
                                 dr.opaque(mi.Float, 1.0, 1), dr.opaque(mi.Float, 1.0, 1))
        self.has_bbox = False
        # the device tables (:meth:`upload`) and their float32 host copies
        self._prob32 = np.empty((self.max_units, self.bins), np.float32)
        self._grid_nodes = 0                                 # nodes of grid_table (0: none)
        self.grid_table = self.prob_table = self.alias_table = self.reflected_table = None
        # the record accumulators (:meth:`reset_records`)
        self.energy = self.counts = self.moments = self.reflected_sums = None
        #: The last refinement's summed second moments (None: nothing evaluated).
        self.moment_sums = None
        self.upload()
        self.reset_records()

    # ------------------------------------------------------------------ device side

    def set_bbox(self, bbox) -> None:
        """The root's box: ``bbox`` (a ``mi.ScalarBoundingBox3f``), grown by 1%."""
        lo, hi = np.array(bbox.min, float), np.array(bbox.max, float)
        pad = 0.01 * np.maximum(hi - lo, 1e-3)
        lo, hi = lo - pad, hi + pad
        self.lower = mi.Point3f(*[dr.opaque(mi.Float, float(v), 1) for v in lo])
        self.scale = mi.Vector3f(*[dr.opaque(mi.Float, float(GRID / v), 1)
                                   for v in hi - lo])
        self.has_bbox = True

    def grid(self) -> np.ndarray:
        """The leaf id of every cell of the ``GRID^3`` grid (index ``(x GRID + y) GRID + z``)."""
        out = np.zeros((GRID, GRID, GRID), np.uint32)
        stack = [(0, (0, 0, 0), (GRID, GRID, GRID))]
        while stack:
            node, lo, size = stack.pop()
            if self.child[node] == 0:
                out[lo[0]:lo[0] + size[0], lo[1]:lo[1] + size[1],
                    lo[2]:lo[2] + size[2]] = self.leaf[node]
                continue
            axis = int(self.depth[node]) % 3
            half = list(size)
            half[axis] //= 2
            upper = list(lo)
            upper[axis] += half[axis]
            stack.append((int(self.child[node]), lo, tuple(half)))
            stack.append((int(self.child[node]) + 1, tuple(upper), tuple(half)))
        return out.ravel()

    def upload(self, rows: int | None = None) -> None:
        """The host tree as evaluated Dr.Jit arrays (fixed sizes: no recompilation);
        ``rows``: only the first units changed (the host work then scales with the
        units in use, not with ``max_leaves``)."""
        rows = self.max_units if rows is None or self.prob_table is None else rows
        self._prob32[:rows] = self.prob[:rows]
        if self._grid_nodes != self.nodes:                   # the tree changed
            self.grid_table = mi.UInt32(self.grid())
            self._grid_nodes = self.nodes
        self.reflected_table = mi.Float(self.reflected.ravel().astype(np.float32))
        if rows == self.max_units:
            self.prob_table = mi.Float(self._prob32.ravel())
            self.alias_table = dr.zeros(mi.Float, 2 * self.max_units * self.bins)
            dr.make_opaque(self.alias_table)
        else:       # only the rows in use, written into the tables in place
            index = dr.arange(mi.UInt32, rows * self.bins)
            dr.scatter(self.prob_table, mi.Float(self._prob32[:rows].ravel()), index)
        q, order = guide_warps.alias_order(self.prob[:rows])
        guide_warps.alias_table(self.alias_table, dr.arange(mi.UInt32, rows),
                                mi.Float(q.ravel().astype(np.float32)),
                                mi.UInt32(order.ravel().astype(np.uint32)), self.bins)
        dr.eval(self.grid_table, self.prob_table, self.alias_table, self.reflected_table)

    def reset_records(self, rows: int | None = None) -> None:
        """Empty record accumulators (energy per unit bin, records per unit, the share
        candidates' second moments per unit: ``unit * (len(SHARES) + 1) + candidate``);
        ``rows``: only the first units can hold records (zeroed in place)."""
        if rows is None or self.energy is None:
            self.energy = dr.zeros(mi.Float, self.max_units * self.bins)
            self.counts = dr.zeros(mi.UInt32, self.max_units)
            self.moments = dr.zeros(mi.Float, self.max_units * (len(SHARES) + 1))
            self.reflected_sums = dr.zeros(mi.Float, self.max_units * 2)
            dr.make_opaque(self.energy, self.counts, self.moments, self.reflected_sums)
            return
        # in place, each table referenced once (a second reference would make the scatter
        # copy the whole table first)
        dr.scatter(self.energy, mi.Float(0), dr.arange(mi.UInt32, rows * self.bins))
        dr.scatter(self.counts, mi.UInt32(0), dr.arange(mi.UInt32, rows))
        dr.scatter(self.moments, mi.Float(0), dr.arange(mi.UInt32, rows * (len(SHARES) + 1)))
        dr.scatter(self.reflected_sums, mi.Float(0), dr.arange(mi.UInt32, rows * 2))
        dr.eval(self.energy, self.counts, self.moments, self.reflected_sums)

    def _prefix(self, table, kind, n: int) -> np.ndarray:
        """The first ``n`` entries of a device table as numpy."""
        return np.array(dr.gather(kind, table, dr.arange(mi.UInt32, n)))

    def add_moments(self, unit: mi.UInt32, x: mi.Float, a: mi.Float, b: mi.Float,
                    active=True) -> None:
        """Add one record to every candidate share's second moment in ``unit``:
        ``x^2 / (s a + (1 - s) b)``, with ``x = beta f cos L / q`` (q the density the
        record's direction was drawn with, beta the path's throughput before the vertex:
        what the direction brought to the pixel), ``a = p_bsdf / q``, ``b = p_guide / q``:
        the importance-reweighted sample of ``E_q[(beta f cos L)^2 / (q p_s)]``, the
        second moment of the one-sample mixture ``p_s = s p_bsdf + (1 - s) p_guide``
        (Mueller 2019, weighted by what reaches the pixel). The last column sums ``x``."""
        x2 = dr.square(x)
        active = active & (x2 > 0) & dr.isfinite(x2)
        row = unit * (len(SHARES) + 1)
        for k, share in enumerate(SHARES):
            mix = dr.fma(float(share), a - b, b)
            dr.scatter_add(self.moments, x2 / dr.maximum(mix, 1e-20), row + k,
                           active & (mix > 0), mode=MOMENTS_MODE)
        dr.scatter_add(self.moments, x, row + len(SHARES), active,     # for the mean
                       mode=MOMENTS_MODE)

    def add_reflected(self, unit: mi.UInt32, after: mi.Float, nee: mi.Float,
                      active=True) -> None:
        """Add one record's reflected radiance per unit throughput (what the vertex's
        direction brought, and its NEE) to ``unit``'s sums (means: :meth:`refine`)."""
        row = unit * 2
        dr.scatter_add(self.reflected_sums, after, row, active, mode=MOMENTS_MODE)
        dr.scatter_add(self.reflected_sums, nee, row + 1, active, mode=MOMENTS_MODE)

    def reflected_at(self, unit: mi.UInt32, active=True) -> tuple[mi.Float, mi.Float]:
        """``unit``'s learned (radiance reflected after the NEE, by the NEE) per unit
        throughput; -1 where it has none yet."""
        return (dr.gather(mi.Float, self.reflected_table, unit * 2, active),
                dr.gather(mi.Float, self.reflected_table, unit * 2 + 1, active))

    def lookup(self, p: mi.Point3f, n: mi.Vector3f, active=True) -> mi.UInt32:
        """The unit (leaf x normal class) of the world point ``p`` with geometric normal
        ``n`` (points outside the box: the nearest cell)."""
        q = dr.clip((p - self.lower) * self.scale, 0.0, GRID - 0.5)
        cell = (mi.UInt32(q.x) * GRID + mi.UInt32(q.y)) * GRID + mi.UInt32(q.z)
        leaf = dr.gather(mi.UInt32, self.grid_table, cell, active)
        a = dr.abs(n)
        axis = dr.select((a.x >= a.y) & (a.x >= a.z), 0, dr.select(a.y >= a.z, 2, 4))
        comp = dr.select(axis == 0, n.x, dr.select(axis == 2, n.y, n.z))
        return leaf * CLASSES + mi.UInt32(axis) + dr.select(comp < 0, 1, 0)

    def pdf(self, unit: mi.UInt32, d: mi.Vector3f, active=True) -> mi.Float:
        """The guide's density at the world direction ``d`` in ``unit``."""
        index = unit * self.bins + guide_warps.direction_to_bin(d, self.res)
        return guide_warps.histogram_pdf(dr.gather(mi.Float, self.prob_table, index, active),
                                         self.res)

    def sample(self, unit: mi.UInt32, u: mi.Float, u2: mi.Point2f, active=True):
        """A world direction from ``unit``'s histogram (density :meth:`pdf`)."""
        return guide_warps.sample_alias(self.alias_table, unit * self.bins, u, u2,
                                        self.res, active)

    def record_index(self, unit: mi.UInt32, d: mi.Vector3f) -> mi.UInt32:
        """Where a record of radiance arriving along the world direction ``d`` goes."""
        return unit * self.bins + guide_warps.direction_to_bin(d, self.res)

    # -------------------------------------------------------------------- host side

    def records(self, rows: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The accumulated (energy (units, bins), records per unit) as numpy (the first
        ``rows`` units; all by default)."""
        rows = self.max_units if rows is None else rows
        energy = self._prefix(self.energy, mi.Float, rows * self.bins).reshape(rows, -1)
        return (energy.astype(np.float64),
                self._prefix(self.counts, mi.UInt32, rows).astype(np.int64))

    @staticmethod
    def choose_shares(moments: np.ndarray, counts: np.ndarray, was_learned: np.ndarray,
                      share: np.ndarray) -> np.ndarray:
        """Per unit, the candidate share (:data:`SHARES`) of least estimated second
        moment, where the unit sampled with a learned histogram and has at least
        :data:`MIN_RECORDS` records; ties go to the larger share (1 where no record
        carried light). Other units keep their share."""
        moments = np.where(np.isfinite(moments), moments, np.inf)[:, :len(SHARES)][:, ::-1]
        best = SHARES[::-1][np.argmin(moments, axis=1)]
        ok = was_learned & (counts >= MIN_RECORDS) & np.isfinite(moments.min(axis=1))
        return np.where(ok, best, share)

    @staticmethod
    def moment_at(moments: np.ndarray, share: np.ndarray) -> np.ndarray:
        """Per unit, the summed second moment at ``share`` (one of :data:`SHARES`)."""
        k = np.clip(np.rint(share * 10).astype(int) - 1, 0, len(SHARES) - 1)
        return moments[np.arange(len(moments)), k]

    def refine(self, threshold: float, fixed_share: float | None = None) -> None:
        """Learn from the accumulated records, then reset them: new histograms where a
        unit has enough records, the BSDF shares (``fixed_share`` where learned, if given;
        else :meth:`choose_shares`, :data:`PRIOR_SHARE` for a unit's first histogram,
        1 where none), then split the leaves over ``threshold`` records."""
        rows = self.leaves * CLASSES            # the units in use (records land there only)
        energy, counts = self.records(rows)
        moments = self._prefix(self.moments, mi.Float, rows * (len(SHARES) + 1))
        moments = moments.astype(np.float64).reshape(rows, -1)
        energy = np.where(np.isfinite(energy) & (energy > 0), energy, 0.0)
        if POOLED:
            energy = energy + self.kept_energy[:rows]
            pooled = counts + self.kept_counts[:rows]
            self.kept_energy[:rows], self.kept_counts[:rows] = energy, pooled
        else:
            pooled = counts
        total = energy.sum(axis=1)
        fresh = np.zeros(self.max_units, bool)
        fresh[:rows] = (pooled >= MIN_RECORDS) & (total > 0)
        learned = energy[fresh[:rows]]
        if COSINE_PRODUCT:
            units = np.flatnonzero(fresh[:rows])
            learned = learned * class_cosines(self.res)[units % CLASSES]
        learned = blur(learned, self.res) if SMOOTH else learned
        if self.split_share > 0:
            learned = guide_quadtree.density(learned, self.res, self.split_share)
        self.prob[fresh] = learned / learned.sum(axis=1, keepdims=True)
        was_learned = self.learned.copy()
        self.learned |= fresh
        # what the integrator's stop rule reads: second moments at the shares the records
        # were drawn with, at share 1 and at the new shares (summed over units)
        old = self.share[:rows].copy()
        if fixed_share is None:
            self.share[:rows] = self.choose_shares(moments, counts, was_learned[:rows],
                                                   self.share[:rows])
            self.share[self.learned & ~was_learned] = PRIOR_SHARE
        else:
            self.share = np.full(self.max_units, float(fixed_share))
        self.share[~self.learned] = 1.0
        sums = self._prefix(self.reflected_sums, mi.Float, rows * 2).reshape(rows, 2)
        enough = (counts >= MIN_RECORDS) & np.all(np.isfinite(sums), axis=1)
        self.reflected[:rows][enough] = np.maximum(sums[enough], 0.0) \
            / counts[enough, None]
        m = np.where(np.isfinite(moments), moments, 0.0)
        evaluated = was_learned[:rows] & (counts >= MIN_RECORDS)
        self.moment_sums = None if not evaluated.any() else {"drawn": float(self.moment_at(m, old).sum()),
                            "bsdf": float(m[:, len(SHARES) - 1].sum()),
                            "chosen": float(self.moment_at(m, self.share[:rows]).sum())}
        self._split(counts.reshape(-1, CLASSES).sum(axis=1), threshold)
        self.upload(self.leaves * CLASSES)
        self.reset_records(self.leaves * CLASSES)

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
            parent = slice(old * CLASSES, (old + 1) * CLASSES)
            kept = 0.5 * self.kept_energy[parent], 0.5 * self.kept_counts[parent]
            for k, leaf in enumerate((old, self.leaves)):
                self.child[first + k] = 0
                self.leaf[first + k] = leaf
                self.depth[first + k] = self.depth[node] + 1
                units = slice(leaf * CLASSES, (leaf + 1) * CLASSES)
                self.prob[units] = self.prob[parent]
                self.kept_energy[units], self.kept_counts[units] = kept
                self.learned[units] = self.learned[parent]
                self.share[units] = self.share[parent]
                self.reflected[units] = self.reflected[parent]
                queue.append((first + k, n / 2))
            self.nodes += 2
            self.leaves += 1
