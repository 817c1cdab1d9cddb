"""The ``guided`` strategy: one-sample MIS of the BSDF's own sampling and a learned guide.

:class:`GuidedStrategy` (registered as ``guided``) draws from the BSDF's own sampling with
probability ``s``, the BSDF share of the vertex's unit, and from the learned guide of
:mod:`.sdtree` otherwise, density ``s p_bsdf + (1 - s) p_guide``. It owns the learned
state (:class:`~.sdtree.SDTree`, the shares); untrained, every share is 1: plain BSDF
sampling. The shares are learned from the records (:meth:`.sdtree.SDTree.add_moments`,
:meth:`.sdtree.SDTree.choose_shares`).

What it drew at a vertex comes back in its sample record, as pbrt-v4's ``BSDFSample``
carries what a BSDF drew: the ``guide`` field of the
:class:`~.strategies.DirectionSample`, a :class:`GuideDraw` (the vertex's unit, the
technique that drew, both densities, whether the BSDF has a Dirac lobe), which
``vr_path``'s loop hands to the recorder (:mod:`.guide_record`) and the roulette
(:mod:`.guide_roulette`). The strategy keeps no state of a trace. The integrator that
trains it is ``vr_guided_path`` (:mod:`.guided_path`).
"""
from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from . import strategies
from .sdtree import SDTree
from .strategies import (DirectionSample, Strategy, VertexSample, crossing_eta,
                         direction_weight)
from .warps import ONE_MINUS_EPSILON


class GuideDraw(NamedTuple):
    """What :class:`GuidedStrategy` drew at a vertex (the ``guide`` field of its
    :class:`~.strategies.DirectionSample`)."""
    unit: mi.UInt32       # the vertex's unit (leaf x normal class)
    from_guide: mi.Bool   # the guide drew the direction (else the BSDF's own sampling)
    p_bsdf: mi.Float      # the BSDF's density at the direction, 0 on a BSDF with a Dirac
                          # lobe (its share is always 1 and not learned)
    p_guide: mi.Float     # the guide's there (evaluated where s < 1 or while recording),
                          # 0 on a BSDF with a Dirac lobe
    delta: mi.Bool        # the BSDF has a Dirac lobe (share 1: its own sampling)


class GuidedStrategy(Strategy):
    """``s`` x BSDF sampling + ``(1 - s)`` x the learned guide (see the module)."""

    #: The methods take the ``mi.BSDFPtr`` itself: the guide's lookup, sampling and
    #: density run once per lane, outside a dispatch over the BSDFs (which would run them
    #: once per BSDF instance); only the BSDF's own calls dispatch. BSDFs with a Dirac
    #: lobe get share 1, i.e. their own sampling, per lane.
    dispatch = False
    integrator_type = "vr_guided_path"

    def __init__(self, res: int = 16, max_leaves: int = 1024, split_share: float = 0.0):
        self.tree = SDTree(res, max_leaves, split_share)
        #: The BSDF share per unit (an evaluated array, :meth:`set_share`).
        self.share = None
        #: Nonzero while a recorder needs p_guide at every drawn direction (share 1 too).
        self.recording = None
        self.set_share(np.ones(self.tree.max_units))
        self.set_recording(False)

    def reset(self) -> None:
        """Forget what was learned: a new tree of the same sizes (its box set again by the
        next scene rendered), every share 1. A job learns from its own samples alone. A
        tree that has not rendered yet (no box) is new already: kept (a new one costs
        20 ms of host work, a job's cost)."""
        tree = self.tree
        if not tree.has_bbox:
            return
        self.tree = SDTree(tree.res, tree.max_leaves, tree.split_share)
        self.set_share(np.ones(self.tree.max_units))

    def set_share(self, share: np.ndarray) -> None:
        """The BSDF share per unit (an evaluated array: a new one recompiles nothing)."""
        self.share = mi.Float(np.asarray(share, np.float32))
        dr.eval(self.share)

    def set_recording(self, on: bool) -> None:
        """Whether the draws evaluate the guide's density everywhere (a recorder's share
        statistics need it): an opaque flag, so both states share one kernel."""
        self.recording = dr.opaque(mi.UInt32, int(on), 1)

    def _unit(self, bsdf, si, active):
        """The vertex's unit (leaf x normal class), its BSDF share (1 for a BSDF with a
        Dirac lobe) and whether the BSDF has one."""
        unit = self.tree.lookup(si.p, si.n, active)
        delta = mi.Bool(mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta))
        return unit, dr.select(delta, 1.0, dr.gather(mi.Float, self.share, unit, active)), delta

    def _draw(self, bsdf, ctx, si, unit, s, delta, sample1, sample2, active, wo_em=None):
        """The mixture's direction, what it drew (:class:`GuideDraw`), and with ``wo_em``
        the BSDF's value and the mixture's density there (NEE). One BSDF call draws the
        BSDF's own direction (``sample``, or with ``wo_em`` ``eval_pdf_sample``, the same
        call as plain BSDF sampling); only lanes that draw from the guide evaluate the
        BSDF there, in a conditional that the kernel skips for packets of lanes with share
        1. For a BSDF-drawn direction, value and density come from the sample
        (``weight x pdf``)."""
        use_bsdf = sample1 < s
        u_bsdf = dr.minimum(sample1 / dr.maximum(s, 1e-6), ONE_MINUS_EPSILON)
        u_guide = dr.minimum((sample1 - s) / dr.maximum(1.0 - s, 1e-6), ONE_MINUS_EPSILON)
        em = None
        if wo_em is None:
            bs, weight = bsdf.sample(ctx, si, u_bsdf, sample2, active)
        else:
            *em, bs, weight = bsdf.eval_pdf_sample(ctx, si, wo_em, u_bsdf, sample2, active)
        wo, value, pdf_bsdf, eta = self._guide_draw(
            bsdf, ctx, si, unit, u_guide, sample2, active & ~use_bsdf,
            bs.wo, weight * bs.pdf, bs.pdf, bs.eta)
        drawn = ~use_bsdf | dr.any(mi.unpolarized_spectrum(weight) != 0)
        p = self._guide_pdf(unit, si.to_world(wo), active & ((s < 1.0) | (self.recording != 0)))
        pdf = dr.select(s < 1.0, dr.fma(s, pdf_bsdf - p, p), pdf_bsdf)
        pdf = dr.select(drawn, pdf, 0.0)
        guide = GuideDraw(unit, ~use_bsdf, dr.select(delta, 0.0, pdf_bsdf),
                          dr.select(delta, 0.0, p), delta)
        ds = DirectionSample(wo, pdf, direction_weight(value, pdf),
                             use_bsdf & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta),
                             eta, use_bsdf & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null),
                             guide)
        if wo_em is None:
            return ds
        p_em = self._guide_pdf(unit, si.to_world(wo_em), active & (s < 1.0))
        return VertexSample(ds, em[0], dr.select(s < 1.0, dr.fma(s, em[1] - p_em, p_em),
                                                 em[1]))

    # The guide's work only on lanes that need it: inside the render loop these are
    # symbolic conditionals, which the LLVM backend skips for a packet of lanes that all
    # have share 1 (directly lit scenes, once their units learned that guiding does not
    # help); the density there is exactly the BSDF's.
    @dr.syntax
    def _guide_draw(self, bsdf, ctx, si, unit, u, u2, need, wo, value, pdf_bsdf, eta):
        """On lanes ``need``: a direction from the guide, the BSDF's value and density
        there and the index of refraction crossed; elsewhere the given ones."""
        if need:
            wo = si.to_local(self.tree.sample(unit, u, u2, need))
            value, pdf_bsdf = bsdf.eval_pdf(ctx, si, wo, need)
            eta = crossing_eta(bsdf, ctx, si, wo, need)
        return wo, value, pdf_bsdf, eta

    @dr.syntax
    def _guide_pdf(self, unit, d, need):
        p = mi.Float(0.0)
        if need:
            p = self.tree.pdf(unit, d, need)
        return p

    def _eval_pdf(self, bsdf, ctx, si, unit, s, wo, active):
        value, pdf_bsdf = bsdf.eval_pdf(ctx, si, wo, active)
        guide = self._guide_pdf(unit, si.to_world(wo), active & (s < 1.0))
        return value, dr.select(s < 1.0, dr.fma(s, pdf_bsdf - guide, guide), pdf_bsdf)

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        return self._draw(bsdf, ctx, si, *self._unit(bsdf, si, active), sample1, sample2,
                          active)

    def pdf(self, bsdf, ctx, si, wo, active):
        return self.eval_pdf(bsdf, ctx, si, wo, active)[1]

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        unit, s, _ = self._unit(bsdf, si, active)
        return self._eval_pdf(bsdf, ctx, si, unit, s, wo, active)

    def sample_and_eval(self, bsdf, ctx, si, sample1, sample2, wo_em, active):
        """One unit lookup and one BSDF call for both (the direction and the NEE
        direction's value and density), as plain BSDF sampling."""
        return self._draw(bsdf, ctx, si, *self._unit(bsdf, si, active), sample1, sample2,
                          active, wo_em)

    def __repr__(self):
        return (f"GuidedStrategy(res={self.tree.res}, max_leaves={self.tree.max_leaves}, "
                f"split_share={self.tree.split_share})")


strategies.register("guided", GuidedStrategy, replace=True)
