"""The guide's records of one render: what each path vertex's direction brought.

:class:`Recorder` keeps, per path vertex, where its record goes (leaf, direction bin), the
radiance accumulated so far and ``1 / (beta' pdf)`` (beta' the throughput after the
vertex's weight, before roulette), scattered into arrays indexed by depth x lane, from the
direction sample the path loop hands it (the strategy's draw, :class:`.guided.GuideDraw`,
rides in it). After the loop, the radiance that arrived along each vertex's sampled
direction is ``(L_end - L_vertex) / beta'`` (every emission and NEE term found further
down the path: the suffix sum), divided by the sampling pdf as PPG weights its records,
and added into the tree's per-bin energies; with the BSDF's and the guide's densities at
the direction over the drawing density, each record also adds to its unit's second moment
at every candidate BSDF share, and to the unit's reflected radiance (the roulette's
estimate, :mod:`.guide_roulette`).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

#: Largest size of a render's record arrays (bytes): larger renders are refused.
RECORD_CAP_BYTES = 256 * 2 ** 20
#: Bytes per record, the sum of the arrays below (docs/guiding.md, "Why these defaults").
RECORD_BYTES = 56
#: A record slot that no vertex filled.
INVALID = 0xFFFFFFFF


def channel_mean(color) -> mi.Float:
    """The mean of a colour's three channels, lane by lane. (``dr.mean`` of a ``Color3f``
    divides a sum over every channel of every lane by their count: the lane count is a
    literal in the kernel, and every pass of another size would compile it again.)"""
    return (color[0] + color[1] + color[2]) * (1.0 / 3.0)


def most_spp(pixels: int, depth: int) -> int:
    """The most samples per pixel of one recording render of ``pixels`` pixels whose
    records (``depth`` per sample) stay within :data:`RECORD_CAP_BYTES` (0: not even one)."""
    return RECORD_CAP_BYTES // (RECORD_BYTES * depth * max(1, pixels))


class Recorder:
    """The records of one render (see the module) into ``tree`` (an
    :class:`~.sdtree.SDTree`): arrays of ``depth x lanes`` entries, for the first
    ``depth`` vertices of ``lanes`` paths; ``on``: an opaque flag, nonzero while the
    renders record (the kernel reads it)."""

    def __init__(self, tree, lanes: int, depth: int, on):
        need = RECORD_BYTES * depth * lanes
        if need > RECORD_CAP_BYTES:
            raise ValueError(
                f"vr_guided_path: this render would keep {need / 2 ** 20:.0f} MiB of guiding "
                f"records ({lanes} samples x record_depth {depth} x {RECORD_BYTES} bytes), "
                f"over the cap of {RECORD_CAP_BYTES // 2 ** 20} MiB: lower 'max_pass_spp' "
                f"(the largest render of a pass) or 'record_depth', or render a smaller film")
        self.tree, self.depth, self.on = tree, depth, on
        self.lanes = dr.opaque(mi.UInt32, lanes, 1)
        self.lane = dr.arange(mi.UInt32, lanes)
        self.index = dr.full(mi.UInt32, INVALID, depth * lanes)   # target (unit x bin)
        self.radiance = dr.zeros(mi.Color3f, depth * lanes)       # the radiance so far
        self.inverse = dr.zeros(mi.Color3f, depth * lanes)        # 1 / (beta' pdf)
        self.direct = dr.zeros(mi.Color3f, depth * lanes)         # emission NEE samples too
        self.ratios = dr.zeros(mi.Vector2f, depth * lanes)        # p_bsdf / pdf, p_guide / pdf
        self.reflected = dr.zeros(mi.Vector2f, depth * lanes)     # 1 / beta, NEE / beta
        dr.make_opaque(self.index, self.radiance, self.inverse, self.direct, self.ratios,
                       self.reflected)

    def vertex(self, depth, si, direction, L, L_arrived, beta, active):
        """After vertex ``depth`` drew ``direction`` (a
        :class:`~.strategies.DirectionSample` whose ``guide`` is what the guided strategy
        drew: the vertex's unit and the two techniques' densities), ``beta``: the
        throughput that reached the vertex, ``L``: the radiance with the vertex's own NEE,
        ``L_arrived``: before it."""
        drawn = direction.guide
        active = active & ~direction.delta & (direction.pdf > 0) & (depth < self.depth) \
            & (self.on != 0)
        index = self.tree.record_index(drawn.unit, si.to_world(direction.wo))
        beta = mi.Color3f(mi.unpolarized_spectrum(beta))
        scale = beta * mi.Color3f(mi.unpolarized_spectrum(direction.weight)) * direction.pdf
        inverse = dr.select(scale > 0, dr.rcp(scale), 0.0)
        slot = depth * self.lanes + self.lane
        L = mi.Color3f(mi.unpolarized_spectrum(L))
        dr.scatter(self.index, index, slot, active)
        dr.scatter(self.radiance, L, slot, active)
        dr.scatter(self.inverse, inverse, slot, active)
        # for the roulette: 1 / beta and the vertex's NEE / beta (channel means)
        b = channel_mean(beta)
        rcp_b = dr.select(b > 0, dr.rcp(b), 0.0)
        nee = channel_mean(L - mi.Color3f(mi.unpolarized_spectrum(L_arrived))) * rcp_b
        dr.scatter(self.reflected, mi.Vector2f(rcp_b, nee), slot, active)
        # for the share: p_bsdf / pdf, p_guide / pdf
        rcp = dr.rcp(dr.maximum(direction.pdf, 1e-20))
        dr.scatter(self.ratios, mi.Vector2f(drawn.p_bsdf * rcp, drawn.p_guide * rcp), slot,
                   active)

    def emitted(self, depth, emitted, active):
        """The emission found at vertex ``depth`` (MIS-weighted against NEE) by the
        direction vertex ``depth - 1`` drew: that vertex's NEE samples the same light, so
        its record leaves it out (the guide learns the light NEE cannot find; where it
        learned direct light too, its records would rate the mixture with the drawn
        direction's MIS weight, which a denser guide lowers, and overrate the guide)."""
        active = active & (depth > 0) & (depth <= self.depth) & (self.on != 0)
        slot = (depth - 1) * self.lanes + self.lane
        # one add per lane and slot: no reduction to expand per thread (Expand, what
        # Auto picks on the CPU, writes the array's size into the kernel)
        dr.scatter_add(self.direct, mi.Color3f(mi.unpolarized_spectrum(emitted)), slot, active,
                       mode=dr.ReduceMode.Direct)

    def finish(self, L, *outputs):
        """Add every vertex's record (radiance found after it / pdf) to the tree. The
        path loop's outputs (``L``, ``outputs``) and the records are evaluated first, in
        one kernel: read lazily, the loop would run again for the film."""
        dr.eval(L, *outputs, self.index, self.radiance, self.inverse, self.direct,
                self.ratios)
        L = mi.Color3f(mi.unpolarized_spectrum(L))
        for d in range(self.depth):
            slot = d * self.lanes + self.lane
            index = dr.gather(mi.UInt32, self.index, slot)
            valid = index != INVALID
            after = L - dr.gather(mi.Color3f, self.radiance, slot, valid)
            learned = after - dr.gather(mi.Color3f, self.direct, slot, valid)
            # where the direct emission was all of it, the difference is rounding
            learned = dr.select(learned > 1e-4 * after, learned, 0.0)
            inverse = dr.gather(mi.Color3f, self.inverse, slot, valid)
            value = channel_mean(learned * inverse)
            value = dr.select(dr.isfinite(value), dr.maximum(value, 0.0), 0.0)
            # what the vertex's direction brought to the pixel (beta f cos L / pdf), less
            # the emission it found that NEE samples too
            brought = dr.maximum(channel_mean(learned), 0.0)
            dr.scatter_add(self.tree.energy, value, index, valid)
            unit = index // self.tree.bins
            dr.scatter_add(self.tree.counts, mi.UInt32(1), unit, valid)
            # the share's statistics: x = beta f cos L / pdf, p_bsdf / pdf, p_guide / pdf
            ratios = dr.gather(mi.Vector2f, self.ratios, slot, valid)
            self.tree.add_moments(unit, brought, ratios.x, ratios.y,
                                  valid & (ratios.x + ratios.y > 0))
            # the roulette's: the radiance the vertex reflects after its NEE (all of it:
            # the path goes on for the emission too), and its NEE
            reflected = dr.gather(mi.Vector2f, self.reflected, slot, valid)
            self.tree.add_reflected(unit, dr.maximum(channel_mean(after), 0.0) * reflected.x,
                                    reflected.y, valid & (reflected.x > 0))
