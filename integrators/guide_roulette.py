"""The guided Russian roulette: survival from what a path's continuation is expected to bring.

After Vorba and Krivanek 2016 ("Adjoint-driven Russian roulette and splitting"), as Open
PGL's ``GuidedRussianRoulette``: a path survives a vertex with probability
``WINDOW x beta x L_r / I`` (``beta`` the throughput that reaches the vertex, ``L_r`` the
radiance its unit learned to reflect after the vertex's NEE, per unit throughput, ``I``
the pixel's, estimated at the path's first vertex), clamped to [:data:`MIN_SURVIVAL`,
``RR_MAX_PROBABILITY``]. :class:`Roulette` reads the units' estimates
(:meth:`.sdtree.SDTree.reflected_at`, filed by :mod:`.guide_record`) at the unit the
strategy's draw names (:class:`.guided.GuideDraw`), which the path loop hands it.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from .guide_record import channel_mean
from .path import RR_MAX_PROBABILITY

#: Survival is this times the expected contribution over the pixel's (docs/guiding.md).
WINDOW = 3.0
#: Least survival probability of the guided roulette (docs/guiding.md).
MIN_SURVIVAL = 0.05


class Roulette:
    """The guided Russian roulette (see the module), from the learned estimates of
    ``tree`` (an :class:`~.sdtree.SDTree`)."""

    def __init__(self, tree):
        self.tree = tree

    def survival(self, depth, drawn, beta, reference, active):
        """(the probability that the path goes on after vertex ``depth``, 0 where the
        throughput rule decides: its unit or the pixel has no estimate; the pixel's
        estimate, set at the first vertex). ``drawn``: what the strategy drew at the
        vertex (:class:`.guided.GuideDraw`: its unit); ``beta``: the throughput reaching
        the vertex."""
        after, nee = self.tree.reflected_at(drawn.unit, active)
        reference = dr.select(active & (depth == 0), dr.select(after >= 0, after + nee, 0.0),
                              reference)
        b = channel_mean(mi.Color3f(mi.unpolarized_spectrum(beta)))
        q = dr.clip(WINDOW * b * after / dr.maximum(reference, 1e-30), MIN_SURVIVAL,
                    RR_MAX_PROBABILITY)
        return dr.select(active & (after >= 0) & (reference > 0), q, 0.0), reference
