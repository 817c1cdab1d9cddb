"""Path guiding: the ``guided`` strategy and the ``vr_guided_path`` integrator that trains it.

* :class:`GuidedStrategy` (registered as ``guided``): one-sample MIS of the BSDF's own
  sampling (probability ``s``, the BSDF share of the vertex's unit) and the learned guide
  of :mod:`.sdtree` (probability ``1 - s``), density ``s p_bsdf + (1 - s) p_guide``. It
  owns the learned state (:class:`~.sdtree.SDTree`). Untrained, every share is 1: plain
  BSDF sampling. The shares are learned from the records
  (:meth:`.sdtree.SDTree.add_moments`, :meth:`.sdtree.SDTree.choose_shares`).
* :class:`Recorder`: per path vertex, where its record goes (leaf, direction bin), the
  radiance accumulated so far and ``1 / (beta' pdf)`` (beta' the throughput after the
  vertex's weight, before roulette), scattered into arrays indexed by depth x lane;
  after the loop, the radiance that arrived along each vertex's sampled direction is
  ``(L_end - L_vertex) / beta'`` (every emission and NEE term found further down the
  path: the suffix sum), divided by the sampling pdf as PPG weights its records, and
  added into the tree's per-bin energies; with the BSDF's and the guide's densities at
  the direction over the drawing density, each record also adds to its unit's second
  moment at every candidate BSDF share.
* :class:`GuidedPathIntegrator` (``vr_guided_path``): ``vr_path`` with the recorder and
  the executor's multi-pass hooks (``pass_schedule``, ``after_pass``, ``combine``):
  training iterations of doubling samples, each split into renders of at most
  ``max_pass_spp``, the guide refined after each iteration but the last, every
  iteration's image combined with inverse-variance weights (:func:`pass_weights`).
"""
from __future__ import annotations

import functools
import warnings

import drjit as dr
import mitsuba as mi
import numpy as np

from . import strategies
from .path import RR_MAX_PROBABILITY, VRPathIntegrator
from .sdtree import SDTree
from .strategies import (DirectionSample, Strategy, VertexSample, crossing_eta,
                         direction_weight)
from .warps import ONE_MINUS_EPSILON

#: Largest size of a render's record arrays (bytes): larger renders are refused.
RECORD_CAP_BYTES = 256 * 2 ** 20
#: Bytes per record: the target index (4), the radiance so far (12), 1 / (beta' pdf) (12),
#: the emission its direction found that NEE samples too (12), for the BSDF share:
#: p_bsdf / pdf (4), p_guide / pdf (4), and for the roulette's estimate of the reflected
#: radiance: 1 / beta (4), the vertex's NEE / beta (4).
RECORD_BYTES = 56
#: The guided Russian roulette (Vorba and Krivanek 2016, "Adjoint-driven Russian roulette
#: and splitting", as Open PGL's ``GuidedRussianRoulette``): a path survives a vertex with
#: probability ``WINDOW x beta x L_r / I`` (``beta`` the throughput that reaches the vertex,
#: ``L_r`` its unit's learned radiance reflected by what follows the vertex, ``I`` the
#: pixel's, estimated at the path's first vertex), the lower end of a weight window of
#: width 5 (``2 / (1 + 5)``), clamped to [:data:`MIN_SURVIVAL`, 0.95].
WINDOW = 3.0
MIN_SURVIVAL = 0.05
ROULETTES = ("adjoint", "throughput")
#: The AOVs of each sample's squared radiance per channel (the passes' per-pixel variances:
#: their weights, and the variance of the combined image).
M2_AOVS = ("guiding_m2_r", "guiding_m2_g", "guiding_m2_b")
#: Samplers that compile the sample count into the kernel: each pass would recompile.
BAKES_SPP = {"StratifiedSampler": "stratified", "MultijitterSampler": "multijitter",
             "OrthogonalSampler": "orthogonal", "LowDiscrepancySampler": "ldsampler"}
INVALID = 0xFFFFFFFF
#: Training stops (every share 1, no more records) after :data:`STOP_PATIENCE`
#: consecutive iterations whose records predict that the learned shares lower the
#: image's per-sample variance by less than this factor against BSDF sampling
#: (:func:`predicted_gain`): guiding does not help. The first guides' predictions are
#: low where a trained guide pays (48x36, 1024 spp, iterations 1 and 2, four seeds each:
#: glossy_indirect 1.005-1.043, hidden_lamp 1.012-1.32, door_room 1.04-1.6) and where it
#: does not (cbox 1.000-1.010; scenes/cbox.xml with its light turned up to the ceiling,
#: 64x32, where a trained guide gains 1.07 per sample: 1.006-1.012, then 1.02-1.05 up to
#: iteration 6, and guided+nee trained to the end reached 0.57 of path's efficiency): the
#: bar lets hidden_lamp and door_room train at every seed tried, glossy_indirect at three
#: of four, and stops the others.
STOP_GAIN = 1.03
STOP_PATIENCE = 2
#: ... and not before this iteration: guides learned from the first samples understate
#: what a trained guide gains (door_room at 256 spp, predicted gains after iterations 1,
#: 2: 1.06-3.2 at 48x36 and 64x48, but 1.01 at 24x18, where iterations 3, 4 show 1.3).
STOP_FIRST = 2
#: A job trains only with at least :data:`MIN_TRAIN_SPP` samples per pixel and
#: :data:`MIN_TRAIN_SAMPLES` samples in all (``min_train_spp``, ``min_train_samples``); a
#: smaller one renders with plain BSDF sampling, and says so. Training has costs that do
#: not shrink with the job: the iterations up to the first stop decision (2 + 4 + 8 = 14
#: spp at the default first pass) record, at 300-400 ns per sample more than vr_path's
#: kernel (1.3-7x its time on the suite's scenes), and each refinement takes 1.5-2.5 ms of
#: host work. Where guiding does not help, the 14 spp are over 1/20 of a job below 256
#: spp, and the host work alone over 1/10 of a job below 2^20 samples at the cheapest
#: suite scenes' 50 ns per sample (grazing at 48x24 and 256 spp trained: 0.56 of
#: bsdf+nee's efficiency).
MIN_TRAIN_SPP = 256
MIN_TRAIN_SAMPLES = 2 ** 20


class GuidedStrategy(Strategy):
    """``s`` x BSDF sampling + ``(1 - s)`` x the learned guide (see the module)."""

    #: The methods take the ``mi.BSDFPtr`` itself: the guide's lookup, sampling and
    #: density run once per lane, outside a dispatch over the BSDFs (which would run them
    #: once per BSDF instance); only the BSDF's own calls dispatch. BSDFs with a Dirac
    #: lobe get share 1, i.e. their own sampling, per lane.
    dispatch = False
    integrator_type = "vr_guided_path"

    def __init__(self, res: int = 16, max_leaves: int = 1024):
        self.tree = SDTree(res, max_leaves)
        self.share = None
        self.unit = None        # the last traced vertex's unit (recorder, roulette)
        self.drawn = None       # (p_bsdf, p_guide) of the last traced draw (the recorder's)
        #: nonzero while a recorder needs p_guide at every drawn direction (share 1 too)
        self.recording = dr.opaque(mi.UInt32, 0, 1)
        self.set_share(np.ones(self.tree.max_units))

    def set_share(self, share: np.ndarray) -> None:
        """The BSDF share per leaf (an evaluated array: a new one recompiles nothing)."""
        self.share = mi.Float(np.asarray(share, np.float32))
        dr.eval(self.share)

    def _unit(self, bsdf, si, active):
        """The vertex's unit (leaf x normal class) and its BSDF share (1 for a BSDF with
        a Dirac lobe)."""
        unit = self.tree.lookup(si.p, si.n, active)
        self.unit = unit            # the vertex's unit, for the recorder and the roulette
        self._delta = mi.Bool(mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta))
        return unit, dr.select(self._delta, 1.0,
                               dr.gather(mi.Float, self.share, unit, active))

    def _draw(self, bsdf, ctx, si, unit, s, sample1, sample2, active, wo_em=None):
        """The mixture's direction, and with ``wo_em`` the BSDF's value and density there
        (NEE). One BSDF call draws the BSDF's own direction (``sample``, or with
        ``wo_em`` ``eval_pdf_sample``, the same call as plain BSDF sampling); only lanes
        that draw from the guide evaluate the BSDF there, in a conditional that the
        kernel skips for packets of lanes with share 1. For a BSDF-drawn direction,
        value and density come from the sample (``weight x pdf``)."""
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
        # for the recorder (traced in the same loop body): the two techniques' densities;
        # 0 on BSDFs with a Dirac lobe, whose share is always 1 and not learned
        self.drawn = (dr.select(self._delta, 0.0, pdf_bsdf), dr.select(self._delta, 0.0, p))
        ds = DirectionSample(wo, pdf, direction_weight(value, pdf),
                             use_bsdf & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta),
                             eta, use_bsdf & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null))
        if wo_em is None:
            return ds
        guide = self._guide_pdf(unit, si.to_world(wo_em), active & (s < 1.0))
        return VertexSample(ds, em[0], dr.select(s < 1.0, dr.fma(s, em[1] - guide, guide),
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
        unit, s = self._unit(bsdf, si, active)
        return self._draw(bsdf, ctx, si, unit, s, sample1, sample2, active)

    def pdf(self, bsdf, ctx, si, wo, active):
        return self.eval_pdf(bsdf, ctx, si, wo, active)[1]

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        return self._eval_pdf(bsdf, ctx, si, *self._unit(bsdf, si, active), wo, active)

    def sample_and_eval(self, bsdf, ctx, si, sample1, sample2, wo_em, active):
        """One unit lookup and one BSDF call for both (the direction and the NEE
        direction's value and density), as plain BSDF sampling."""
        unit, s = self._unit(bsdf, si, active)
        return self._draw(bsdf, ctx, si, unit, s, sample1, sample2, active, wo_em)

    def __repr__(self):
        return f"GuidedStrategy(res={self.tree.res}, max_leaves={self.tree.max_leaves})"


def channel_mean(color) -> mi.Float:
    """The mean of a colour's three channels, lane by lane. (``dr.mean`` of a ``Color3f``
    divides a sum over every channel of every lane by their count: the lane count is a
    literal in the kernel, and every pass of another size would compile it again.)"""
    return (color[0] + color[1] + color[2]) * (1.0 / 3.0)


class Recorder:
    """The records of one render (see the module): arrays of ``depth x lanes`` entries."""

    def __init__(self, guide: GuidedStrategy, lanes: int, depth: int, on):
        need = RECORD_BYTES * depth * lanes
        if need > RECORD_CAP_BYTES:
            raise ValueError(
                f"vr_guided_path: this render would keep {need / 2 ** 20:.0f} MiB of guiding "
                f"records ({lanes} samples x record_depth {depth} x {RECORD_BYTES} bytes), "
                f"over the cap of {RECORD_CAP_BYTES // 2 ** 20} MiB: lower 'max_pass_spp' "
                f"(the largest render of a pass) or 'record_depth', or render a smaller film")
        self.guide, self.tree, self.depth, self.on = guide, guide.tree, depth, on
        self.lanes = dr.opaque(mi.UInt32, lanes, 1)
        self.lane = dr.arange(mi.UInt32, lanes)
        self.index = dr.full(mi.UInt32, INVALID, depth * lanes)
        self.radiance = dr.zeros(mi.Color3f, depth * lanes)
        self.inverse = dr.zeros(mi.Color3f, depth * lanes)
        self.direct = dr.zeros(mi.Color3f, depth * lanes)
        self.ratios = dr.zeros(mi.Vector2f, depth * lanes)
        self.reflected = dr.zeros(mi.Vector2f, depth * lanes)
        dr.make_opaque(self.index, self.radiance, self.inverse, self.direct, self.ratios,
                       self.reflected)

    def vertex(self, depth, si, direction, L, L_arrived, beta, active):
        """After vertex ``depth`` drew ``direction`` (``beta``: the throughput that reached
        the vertex, ``L``: the radiance with the vertex's own NEE, ``L_arrived``: before it)."""
        active = active & ~direction.delta & (direction.pdf > 0) & (depth < self.depth) \
            & (self.on != 0)
        # the unit the strategy looked up for this vertex's direction
        index = self.tree.record_index(self.guide.unit, si.to_world(direction.wo))
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
        p_bsdf, p_guide = self.guide.drawn
        rcp = dr.rcp(dr.maximum(direction.pdf, 1e-20))
        dr.scatter(self.ratios, mi.Vector2f(p_bsdf * rcp, p_guide * rcp), slot, active)

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


class Roulette:
    """The guided Russian roulette (:data:`WINDOW`): survival probabilities from the
    units' learned reflected radiance (:meth:`.sdtree.SDTree.reflected_at`)."""

    def __init__(self, guide: GuidedStrategy):
        self.guide, self.tree = guide, guide.tree

    def survival(self, depth, si, beta, reference, active):
        """(the probability that the path goes on after vertex ``depth``, 0 where the
        throughput rule decides: its unit or the pixel has no estimate; the pixel's
        estimate, set at the first vertex). ``beta``: the throughput reaching the vertex."""
        # the unit the strategy looked up for this vertex's direction
        after, nee = self.tree.reflected_at(self.guide.unit, active)
        reference = dr.select(active & (depth == 0), dr.select(after >= 0, after + nee, 0.0),
                              reference)
        b = channel_mean(mi.Color3f(mi.unpolarized_spectrum(beta)))
        q = dr.clip(WINDOW * b * after / dr.maximum(reference, 1e-30), MIN_SURVIVAL,
                    RR_MAX_PROBABILITY)
        return dr.select(active & (after >= 0) & (reference > 0), q, 0.0), reference


# ------------------------------------------------------------ passes and their weights

def iterations(spp: int, first: int = 2) -> list[int]:
    """Training iterations of doubling samples (``first``, 2 ``first``, ...), the last one
    taking the rest once it would be less than twice the next (PPG's rule)."""
    out, n, left = [], first, spp
    while left > 0:
        if left < 3 * n:
            out.append(left)
            break
        out.append(n)
        left, n = left - n, 2 * n
    return out


def split(spp: int, most: int) -> list[int]:
    """``spp`` in near-equal renders of at most ``most`` samples each."""
    k = -(-spp // most)
    return [spp // k + (i < spp % k) for i in range(k)]


def pass_weights(variances, spps) -> np.ndarray:
    """One scalar weight per iteration, inverse to its image's estimated variance
    (Mueller 2019), summing to 1. A variance that is 0 or not finite (a black image, one
    sample per pixel) falls back to weights proportional to the samples."""
    v = np.asarray(variances, float)
    spps = np.asarray(spps, float)
    if len(v) == 1 or not np.all(np.isfinite(v) & (v > 0)):
        return spps / spps.sum()
    w = 1.0 / v
    return w / w.sum()


def predicted_gain(sums: dict, variance: float, samples: int) -> float | None:
    """The image's per-sample variance with every share 1 over that with the new shares,
    predicted from an iteration's records: ``variance`` (the pixels' per-sample variance
    measured, at the shares the records were drawn with) shifted by the records' summed
    second moments (:meth:`.sdtree.SDTree.refine`'s ``moment_sums``: at the drawn shares,
    at share 1, at the chosen ones) per sample (``samples``: the iteration's camera
    samples). None when nothing was measured."""
    if sums is None or samples <= 0 or not variance > 0:
        return None
    bsdf = variance + (sums["bsdf"] - sums["drawn"]) / samples
    chosen = variance + (sums["chosen"] - sums["drawn"]) / samples
    return float(bsdf / chosen) if chosen > 0 and bsdf > 0 else None


def sample_spread(mean: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """Per pixel and channel, the samples' spread from their mean and mean square:
    m2 - mean^2 (0 where rounding makes it negative)."""
    return np.maximum(m2 - mean ** 2, 0.0)


def pixel_variance(mean: np.ndarray, m2: np.ndarray, spp: int) -> np.ndarray:
    """Per pixel and channel, the variance of the mean of ``spp`` samples, from their mean
    and mean square: (m2 - mean^2) / (spp - 1) (inf for one sample)."""
    if spp < 2:
        return np.full(np.shape(mean), np.inf)
    return sample_spread(mean, m2) / (spp - 1)


def _number(props: mi.Properties, name: str, default, low, high, kind=int):
    """The parameter ``name`` of ``props`` (``default`` where absent), checked to be a
    ``kind`` in [low, high]."""
    value = props.get(name, default)
    if not isinstance(value, (int, float)) or (kind is int and value != int(value)) \
            or not low <= value <= high:
        raise ValueError(f"vr_guided_path: '{name}' must be "
                         f"{'an integer' if kind is int else 'a number'} in "
                         f"[{low}, {high}], got {value!r}")
    return kind(value)


class GuidedPathIntegrator(VRPathIntegrator):
    r"""
    .. _integrator-vr_guided_path:

    Guided path tracer (:monosp:`vr_guided_path`)
    ---------------------------------------------

    .. pluginparameters::

     * - strategy
       - |string|
       - A strategy that learns (``guided``); ``Method.integrator_dict`` picks this
         integrator for it. (Default: ``guided``)

     * - bsdf_fraction
       - |float|
       - A fixed probability of drawing from the BSDF's own sampling once a unit has
         learned a histogram, in [0.1, 1]; the guide draws otherwise. Absent, the share is
         learned per unit: the candidate in 0.1, 0.2, ..., 1 of least estimated second
         moment of the one-sample mixture, ``sum x^2 / (s a + (1 - s) b)`` over the
         unit's records (``x``: what the recorded direction brought to the pixel,
         ``a, b``: the BSDF's and the guide's density over the density it was drawn
         with), 1 until a unit has been evaluated; training stops, every share 1, where
         the records predict no gain. (Default: learned)

     * - directional_resolution
       - |int|
       - Bins per side of each leaf's equal-area (cos theta, phi) histogram, 2 to 64
         (res^2 bins). (Default: 16)

     * - max_leaves
       - |int|
       - Most leaves of the spatial tree (its tables are this size), 1 to 65536.
         (Default: 1024)

     * - spatial_threshold
       - |float|
       - A leaf splits after an iteration in which it received more than
         ``spatial_threshold * sqrt(2^k)`` records (k the iteration). (Default: 4000)

     * - record_depth
       - |int|
       - Vertices per path that record (the first ones), 1 to 32. (Default: 4)

     * - max_pass_spp
       - |int|
       - Most samples per pixel of one render of a training job: an iteration above it is
         split into several renders (records cost 56 bytes x record_depth per sample, at most
         256 MiB per render). (Default: 64)

     * - first_pass_spp
       - |int|
       - Samples per pixel of the first iteration (then doubled), >= 2. (Default: 2)

     * - min_train_spp, min_train_samples
       - |int|
       - A job trains only with at least ``min_train_spp`` samples per pixel (>= 2) and
         ``min_train_samples`` samples in all (pixels x spp, >= 1); a smaller one is
         plain BSDF sampling (``vr_path``'s ``bsdf`` strategy), with a warning: before
         training can first stop (14 spp at the default ``first_pass_spp``) its records
         and refinements cost the same where guiding does not help.
         (Default: 256, 1048576)

     * - roulette
       - |string|
       - ``adjoint``: while the guide is in use, a path past ``rr_depth`` survives a
         vertex with probability ``3 beta L_r / I`` clamped to [0.05, 0.95] (``L_r`` the
         radiance its unit learned to reflect after the vertex's NEE, per unit throughput;
         ``I`` the pixel's, learned at the path's first vertex: Vorba and Krivanek's
         adjoint-driven roulette), the throughput rule where a unit has no estimate yet;
         ``throughput``: ``vr_path``'s rule. (Default: ``adjoint``)

    and every parameter of ``vr_path`` (``max_depth``, ``rr_depth``, ``hide_emitters``,
    ``emitter_sampling``). See docs/guiding.md for the method, its costs and when it loses.
    Samplers that compile the sample count into the kernel (stratified, multijitter,
    orthogonal, ldsampler) are refused: every pass would recompile.
    """

    def make_strategy(self, name: str, props: mi.Properties):
        """The guide this integrator trains, of its ``directional_resolution`` and
        ``max_leaves`` (where ``name`` is a strategy that learns; another is refused in
        ``__init__``), made once: the registry's own would be thrown away."""
        if strategies.integrator_type(name) != "vr_guided_path":
            return strategies.get(name)
        return GuidedStrategy(_number(props, "directional_resolution", 16, 2, 64),
                              _number(props, "max_leaves", 1024, 1, 65536))

    def __init__(self, props: mi.Properties):
        if "strategy" not in props:
            props["strategy"] = "guided"
        VRPathIntegrator.__init__(self, props)
        # by the attribute, not the class: the strategy registry outlives a variant switch,
        # which defines this module's classes anew
        if getattr(self.sampling_strategy, "integrator_type", None) != "vr_guided_path":
            raise ValueError(f"vr_guided_path: 'strategy' must be a strategy that learns "
                             f"(guided), got {self.strategy!r}")

        number = functools.partial(_number, props)
        # None: learned per unit (sdtree.SDTree.choose_shares)
        self.bsdf_fraction = (number("bsdf_fraction", 0.5, 0.1, 1.0, float)
                              if "bsdf_fraction" in props else None)
        self.spatial_threshold = number("spatial_threshold", 4000.0, 1.0, 1e12, float)
        self.record_depth = number("record_depth", 4, 1, 32)
        self.max_pass_spp = number("max_pass_spp", 64, 1, 1 << 20)
        self.first_pass_spp = number("first_pass_spp", 2, 2, 1 << 20)
        self.min_train_spp = number("min_train_spp", MIN_TRAIN_SPP, 2, 1 << 30)
        self.min_train_samples = number("min_train_samples", MIN_TRAIN_SAMPLES, 1, 1 << 40)
        self.roulette = props.get("roulette", "adjoint")
        if self.roulette not in ROULETTES:
            raise ValueError(f"vr_guided_path: 'roulette' must be one of "
                             f"{', '.join(ROULETTES)}, got {self.roulette!r}")
        self.guide = self.sampling_strategy
        self._set_recording(True)
        self._passes, self._m2, self._mean, self._spp = [], [], [], []
        self.gains, self._stopped = [], False

    # ------------------------------------------------------------------- render side

    def _recorder(self, scene, sampler, ray):
        name = str(sampler).split("[")[0].strip()
        if name in BAKES_SPP:
            raise ValueError(
                f"vr_guided_path: the sampler '{BAKES_SPP[name]}' compiles the sample count "
                f"into the kernel, so every training pass would recompile; valid choices: "
                f"independent or a sampler that does not (halton, zsobol), not "
                f"{', '.join(BAKES_SPP.values())}")
        tree = self.guide.tree
        if not tree.has_bbox:
            tree.set_bbox(scene.bbox())
        if not self.recording:      # a kernel without records (compiled once, cached)
            return None
        return Recorder(self.guide, dr.width(ray.o), self.record_depth, self.guide.recording)

    def _roulette(self):
        """The guided roulette while the guide is in use (``roulette`` adjoint), else None
        (vr_path's throughput rule; after training stops the kernel is vr_path's own)."""
        if self.roulette != "adjoint" or self._stopped:
            return None
        return Roulette(self.guide)

    def _set_recording(self, on: bool) -> None:
        """Whether the next renders record: a host switch (the render kernel without
        records is another kernel, compiled once) mirrored in an opaque array the
        strategy reads (it evaluates the guide's density everywhere while recording)."""
        self.recording = bool(on)
        self.guide.recording = dr.opaque(mi.UInt32, int(on), 1)

    def _aovs(self, segments, shadow_rays, result=None):
        c = mi.Color3f(0.0) if result is None else \
            mi.Color3f(mi.unpolarized_spectrum(result))
        return VRPathIntegrator._aovs(self, segments, shadow_rays) + \
            [dr.square(c.x), dr.square(c.y), dr.square(c.z)]

    def aov_names(self):
        return VRPathIntegrator.aov_names(self) + list(M2_AOVS)

    # ------------------------------------------------------------------ multi-pass

    def pass_schedule(self, spp: int, pixels: int) -> list:
        """Iterations of doubling samples (:func:`iterations`), each split into renders
        of at most ``max_pass_spp`` (:func:`split`): a function of ``spp`` and the film's
        ``pixels`` alone; one iteration without training below ``min_train_spp`` or
        ``min_train_samples``."""
        small = [f"{spp} spp is below 'min_train_spp' ({self.min_train_spp})"] \
            if spp < self.min_train_spp else []
        if spp * pixels < self.min_train_samples:
            small.append(f"{spp} spp x {pixels} pixels is below 'min_train_samples' "
                         f"({self.min_train_samples})")
        trains = not small
        if small:
            warnings.warn(f"vr_guided_path: {' and '.join(small)}: no training, plain BSDF "
                          f"sampling (vr_path's bsdf strategy)", stacklevel=2)
        self._iterations = iterations(spp, self.first_pass_spp) if trains else [spp]
        # renders of at most max_pass_spp; without training one pass (the executor splits
        # a pass over its lane cap), as vr_path's bsdf+nee renders
        self._passes = [(k, n) for k, it in enumerate(self._iterations)
                        for n in (split(it, self.max_pass_spp) if trains else [it])]
        self._m2, self._mean, self._spp, self.gains = [], [], [], []
        # per iteration, which estimator rendered it: -1 plain BSDF sampling (every share
        # 1: untrained, or training stopped), else the iteration whose refinement it uses
        self._estimator = [-1] * len(self._iterations)
        trains = len(self._iterations) > 1       # one iteration has nothing to learn for
        self._set_recording(trains)
        # without training: vr_path's own bsdf strategy and roulette (its kernel)
        self._stopped = not trains
        self.sampling_strategy = self.guide if trains else strategies.get("bsdf")
        return [n for _, n in self._passes]

    def after_pass(self, index: int, image, spp: int) -> None:
        """Keep the pass's per-pixel mean square; after an iteration's last render (not
        the last iteration's), refine the guide from its records."""
        image = np.array(image, dtype=np.float64)
        self._m2.append(image[..., -len(M2_AOVS):])
        self._mean.append(image[..., :3])
        self._spp.append(spp)
        k = self._passes[index][0]
        last_of_iteration = index + 1 == len(self._passes) or self._passes[index + 1][0] != k
        if not last_of_iteration or k + 1 == len(self._iterations):
            return
        if self._stopped:
            self._estimator[k + 1] = self._estimator[k]
            return
        tree = self.guide.tree
        # the last trace's variables read the tables: dropped, so that the refinement
        # writes the tables in place instead of copying them whole
        self.guide.drawn = self.guide._delta = self.guide.unit = None
        tree.refine(self.spatial_threshold * np.sqrt(2.0 ** k), self.bsdf_fraction)
        idx = [i for i, (it, _) in enumerate(self._passes) if it == k]
        gain = predicted_gain(tree.moment_sums, *self._pixel_moments(idx))
        # no unit learned anything (every record dark: all its light found by NEE): the
        # guide is the BSDF's own sampling, no gain
        self.gains.append(1.0 if gain is None and not tree.learned.any() else gain)
        low = [g is not None and g < STOP_GAIN for g in self.gains[-STOP_PATIENCE:]]
        if self.bsdf_fraction is None and k >= STOP_FIRST and all(low):
            # guiding does not help anywhere: plain BSDF sampling, no more training; the
            # rest renders with vr_path's own bsdf strategy (its kernel: the same estimator
            # as every share 1, without the guide's lookups and dispatch)
            tree.share[:] = 1.0
            self._stopped = True
            self._set_recording(False)
            self.sampling_strategy = strategies.get("bsdf")
        self.guide.set_share(tree.share)
        self._estimator[k + 1] = -1 if np.all(tree.share == 1.0) else k
        if k + 2 == len(self._iterations):     # the last iteration only renders
            self._set_recording(False)

    def _pixel_moments(self, idx):
        """(per-sample variance of the pixels' values averaged over pixels and channels,
        camera samples) of the renders ``idx`` (their images and mean squares, kept by
        after_pass)."""
        n = sum(self._spp[i] for i in idx)
        mean = sum(self._mean[i] * self._spp[i] for i in idx) / n
        m2 = sum(self._m2[i] * self._spp[i] for i in idx) / n
        return float(np.mean(sample_spread(mean, m2))), n * mean[..., 0].size

    def combine(self, images: list, spps: list):
        """The iterations' images, weighted by :func:`pass_weights`; iterations rendered
        by the same estimator (plain BSDF sampling before a unit learns and after training
        stops; the frozen guide after it stops) are pooled first, by their samples:
        weights estimated per identical iteration would only add noise (and, with rare
        bright samples, favour the iterations that missed them)."""
        means, pixels, counts = [], [], []
        for e in dict.fromkeys(self._estimator):
            idx = [i for i, (it, _) in enumerate(self._passes)
                   if self._estimator[it] == e and i < len(images)]
            n = sum(spps[i] for i in idx)
            mean = sum(images[i] * spps[i] for i in idx) / n
            m2 = sum(self._m2[i] * spps[i] for i in idx) / n
            means.append(mean)
            pixels.append(pixel_variance(mean, m2, n))
            counts.append(n)
        self.weights = pass_weights([float(np.mean(p)) for p in pixels], counts)
        # the combined image's per-pixel variance, the weights taken as fixed
        self.variance = sum(w * w * p for w, p in zip(self.weights, pixels))
        return sum(w * m for w, m in zip(self.weights, means))

    def combined_variance(self) -> np.ndarray:
        """Per pixel and channel, the variance of the image :meth:`combine` returned: the
        sum over its groups of weight^2 x the variance of the group's mean (from its
        samples' mean squares, the ``guiding_m2_*`` AOVs), the weights taken as fixed
        (they are estimated from the same samples: Mueller 2019 reports the correlation
        negligible). The experiments' per-pixel errors use it for this method
        (:func:`experiments.lib.execute.render_passes`): the spread of its passes would
        treat the untrained and the trained ones as one estimator."""
        return self.variance

    def to_string(self):
        return (f"GuidedPathIntegrator[{VRPathIntegrator.to_string(self)}, "
                f"bsdf_fraction={self.bsdf_fraction}, leaves={self.guide.tree.leaves}]")


strategies.register("guided", GuidedStrategy, replace=True)
mi.register_integrator("vr_guided_path", GuidedPathIntegrator)
