"""Path guiding: the ``guided`` strategy and the ``vr_guided_path`` integrator that trains it.

* :class:`GuidedStrategy` (registered as ``guided``): one-sample MIS of the BSDF's own
  sampling (probability ``s``, the per-leaf BSDF share) and the learned guide of
  :mod:`.sdtree` (probability ``1 - s``), density ``s p_bsdf + (1 - s) p_guide``. It owns
  the learned state (:class:`~.sdtree.SDTree`). Untrained, every share is 1: plain BSDF
  sampling.
* :class:`Recorder`: per path vertex, where its record goes (leaf, direction bin), the
  radiance accumulated so far and ``1 / (beta' pdf)`` (beta' the throughput after the
  vertex's weight, before roulette), scattered into arrays indexed by depth x lane;
  after the loop, the radiance that arrived along each vertex's sampled direction is
  ``(L_end - L_vertex) / beta'`` (every emission and NEE term found further down the
  path: the suffix sum), divided by the sampling pdf as PPG weights its records, and
  added into the tree's per-bin energies.
* :class:`GuidedPathIntegrator` (``vr_guided_path``): ``vr_path`` with the recorder and
  the executor's multi-pass hooks (``pass_schedule``, ``after_pass``, ``combine``):
  training iterations of doubling samples, each split into renders of at most
  ``max_pass_spp``, the guide refined after each iteration but the last, every
  iteration's image combined with inverse-variance weights (:func:`pass_weights`).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from . import strategies
from .path import VRPathIntegrator
from .sdtree import SDTree
from .strategies import (DirectionSample, Strategy, VertexSample, crossing_eta,
                         direction_weight)
from .warps import ONE_MINUS_EPSILON

#: Largest size of a render's record arrays (bytes): larger renders are refused.
RECORD_CAP_BYTES = 256 * 2 ** 20
#: Bytes per record: the target index (4), the radiance so far (12), 1 / (beta' pdf) (12).
RECORD_BYTES = 28
#: Samplers that compile the sample count into the kernel: each pass would recompile.
BAKES_SPP = {"StratifiedSampler": "stratified", "MultijitterSampler": "multijitter",
             "OrthogonalSampler": "orthogonal", "LowDiscrepancySampler": "ldsampler"}
INVALID = 0xFFFFFFFF


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
        self.set_share(np.ones(self.tree.max_units))

    def set_share(self, share: np.ndarray) -> None:
        """The BSDF share per leaf (an evaluated array: a new one recompiles nothing)."""
        self.share = mi.Float(np.asarray(share, np.float32))
        dr.eval(self.share)

    def _unit(self, bsdf, si, active):
        """The vertex's unit (leaf x normal class) and its BSDF share (1 for a BSDF with
        a Dirac lobe)."""
        unit = self.tree.lookup(si.p, si.n, active)
        delta = mi.Bool(mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta))
        return unit, dr.select(delta, 1.0, dr.gather(mi.Float, self.share, unit, active))

    def _draw(self, bsdf, ctx, si, unit, s, sample1, sample2, active):
        """The mixture's direction: the guide's direction is drawn first, so that one BSDF
        call (``eval_pdf_sample``) evaluates it and draws the BSDF's own direction; for a
        BSDF-drawn direction, value and density come from the sample (``weight x pdf``)."""
        use_bsdf = sample1 < s
        u_bsdf = dr.minimum(sample1 / dr.maximum(s, 1e-6), ONE_MINUS_EPSILON)
        u_guide = dr.minimum((sample1 - s) / dr.maximum(1.0 - s, 1e-6), ONE_MINUS_EPSILON)
        guide = si.to_local(self.tree.sample(unit, u_guide, sample2, active & ~use_bsdf))
        value_g, pdf_g, bs, weight = bsdf.eval_pdf_sample(ctx, si, guide, u_bsdf, sample2,
                                                          active)
        wo = dr.select(use_bsdf, bs.wo, guide)
        value = dr.select(use_bsdf, weight * bs.pdf, value_g)
        pdf_bsdf = dr.select(use_bsdf, bs.pdf, pdf_g)
        drawn = ~use_bsdf | dr.any(mi.unpolarized_spectrum(weight) != 0)
        pdf = dr.fma(s, pdf_bsdf - (p := self.tree.pdf(unit, si.to_world(wo), active)), p)
        pdf = dr.select(drawn, pdf, 0.0)
        eta = dr.select(use_bsdf, bs.eta, crossing_eta(bsdf, ctx, si, wo, active & ~use_bsdf))
        return DirectionSample(wo, pdf, direction_weight(value, pdf),
                               use_bsdf & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta),
                               eta, use_bsdf & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null))

    def _eval_pdf(self, bsdf, ctx, si, unit, s, wo, active):
        value, pdf_bsdf = bsdf.eval_pdf(ctx, si, wo, active)
        guide = self.tree.pdf(unit, si.to_world(wo), active)
        return value, dr.fma(s, pdf_bsdf - guide, guide)

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        unit, s = self._unit(bsdf, si, active)
        return self._draw(bsdf, ctx, si, unit, s, sample1, sample2, active)

    def pdf(self, bsdf, ctx, si, wo, active):
        return self.eval_pdf(bsdf, ctx, si, wo, active)[1]

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        return self._eval_pdf(bsdf, ctx, si, *self._unit(bsdf, si, active), wo, active)

    def sample_and_eval(self, bsdf, ctx, si, sample1, sample2, wo_em, active):
        """One unit lookup for both (the direction and the NEE direction's density)."""
        unit, s = self._unit(bsdf, si, active)
        return VertexSample(self._draw(bsdf, ctx, si, unit, s, sample1, sample2, active),
                            *self._eval_pdf(bsdf, ctx, si, unit, s, wo_em, active))

    def __repr__(self):
        return f"GuidedStrategy(res={self.tree.res}, max_leaves={self.tree.max_leaves})"


class Recorder:
    """The records of one render (see the module): arrays of ``depth x lanes`` entries."""

    def __init__(self, tree: SDTree, lanes: int, depth: int, on):
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
        self.index = dr.full(mi.UInt32, INVALID, depth * lanes)
        self.radiance = dr.zeros(mi.Color3f, depth * lanes)
        self.inverse = dr.zeros(mi.Color3f, depth * lanes)
        dr.make_opaque(self.index, self.radiance, self.inverse)

    def vertex(self, depth, si, direction, L, beta, active):
        """After vertex ``depth`` drew ``direction`` (``beta``: the throughput with its
        weight, ``L``: the radiance with the vertex's own NEE)."""
        active = active & ~direction.delta & (direction.pdf > 0) & (depth < self.depth) \
            & (self.on != 0)
        leaf = self.tree.lookup(si.p, si.n, active)
        index = self.tree.record_index(leaf, si.to_world(direction.wo))
        scale = mi.Color3f(mi.unpolarized_spectrum(beta)) * direction.pdf
        inverse = dr.select(scale > 0, dr.rcp(scale), 0.0)
        slot = depth * self.lanes + self.lane
        dr.scatter(self.index, index, slot, active)
        dr.scatter(self.radiance, mi.Color3f(mi.unpolarized_spectrum(L)), slot, active)
        dr.scatter(self.inverse, inverse, slot, active)

    def finish(self, L, *outputs):
        """Add every vertex's record (radiance found after it / pdf) to the tree. The
        path loop's outputs (``L``, ``outputs``) and the records are evaluated first, in
        one kernel: read lazily, the loop would run again for the film."""
        dr.eval(L, *outputs, self.index, self.radiance, self.inverse)
        L = mi.Color3f(mi.unpolarized_spectrum(L))
        for d in range(self.depth):
            slot = d * self.lanes + self.lane
            index = dr.gather(mi.UInt32, self.index, slot)
            valid = index != INVALID
            before = dr.gather(mi.Color3f, self.radiance, slot, valid)
            inverse = dr.gather(mi.Color3f, self.inverse, slot, valid)
            value = dr.mean((L - before) * inverse)
            value = dr.select(dr.isfinite(value), dr.maximum(value, 0.0), 0.0)
            dr.scatter_add(self.tree.energy, value, index, valid)
            dr.scatter_add(self.tree.counts, mi.UInt32(1), index // self.tree.bins, valid)


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


def image_variance(mean_lum: np.ndarray, m2: np.ndarray, spp: int) -> float:
    """Mean over pixels of the variance of a pixel's mean luminance, from the per-pixel
    mean and mean square of the samples' luminance (``spp`` of them; inf for 1)."""
    if spp < 2:
        return float("inf")
    return float(np.mean(np.maximum(m2 - mean_lum ** 2, 0.0)) / (spp - 1))


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
       - Probability of drawing from the BSDF's own sampling once a leaf has learned a
         histogram, in [0.1, 1]; the guide draws otherwise. (Default: 0.5)

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
       - Vertices per path that record (the first ones), 1 to 32. (Default: 8)

     * - max_pass_spp
       - |int|
       - Most samples per pixel of one render: an iteration above it is split into
         several renders (records cost 28 bytes x record_depth per sample, at most
         256 MiB per render). (Default: 64)

     * - first_pass_spp
       - |int|
       - Samples per pixel of the first iteration (then doubled), >= 2. (Default: 2)

    and every parameter of ``vr_path`` (``max_depth``, ``rr_depth``, ``hide_emitters``,
    ``emitter_sampling``). See docs/guiding.md for the method, its costs and when it loses.
    Samplers that compile the sample count into the kernel (stratified, multijitter,
    orthogonal, ldsampler) are refused: every pass would recompile.
    """

    def __init__(self, props: mi.Properties):
        if "strategy" not in props:
            props["strategy"] = "guided"
        VRPathIntegrator.__init__(self, props)
        # by the attribute, not the class: the strategy registry outlives a variant switch,
        # which defines this module's classes anew
        if getattr(self.sampling_strategy, "integrator_type", None) != "vr_guided_path":
            raise ValueError(f"vr_guided_path: 'strategy' must be a strategy that learns "
                             f"(guided), got {self.strategy!r}")

        def number(name, default, low, high, kind=int):
            value = props.get(name, default)
            if not isinstance(value, (int, float)) or (kind is int and value != int(value)) \
                    or not low <= value <= high:
                raise ValueError(f"vr_guided_path: '{name}' must be "
                                 f"{'an integer' if kind is int else 'a number'} in "
                                 f"[{low}, {high}], got {value!r}")
            return kind(value)
        self.bsdf_fraction = number("bsdf_fraction", 0.5, 0.1, 1.0, float)
        res = number("directional_resolution", 16, 2, 64)
        max_leaves = number("max_leaves", 1024, 1, 65536)
        self.spatial_threshold = number("spatial_threshold", 4000.0, 1.0, 1e12, float)
        self.record_depth = number("record_depth", 8, 1, 32)
        self.max_pass_spp = number("max_pass_spp", 64, 1, 1 << 20)
        self.first_pass_spp = number("first_pass_spp", 2, 2, 1 << 20)
        self.sampling_strategy = GuidedStrategy(res, max_leaves)
        self.guide = self.sampling_strategy
        self.recording = dr.opaque(mi.UInt32, 1, 1)
        self._passes, self._m2 = [], []

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
        return Recorder(tree, dr.width(ray.o), self.record_depth, self.recording)

    def _aovs(self, segments, shadow_rays, result=None):
        lum = mi.Float(0.0) if result is None else dr.mean(mi.unpolarized_spectrum(result))
        return VRPathIntegrator._aovs(self, segments, shadow_rays) + [dr.square(lum)]

    def aov_names(self):
        return VRPathIntegrator.aov_names(self) + ["guiding_m2"]

    # ------------------------------------------------------------------ multi-pass

    def pass_schedule(self, spp: int) -> list:
        """Iterations of doubling samples (:func:`iterations`), each split into renders
        of at most ``max_pass_spp`` (:func:`split`): a function of ``spp`` alone."""
        self._iterations = iterations(spp, self.first_pass_spp)
        self._passes = [(k, n) for k, it in enumerate(self._iterations)
                        for n in split(it, self.max_pass_spp)]
        self._m2 = []
        self.recording = dr.opaque(mi.UInt32, int(len(self._iterations) > 1), 1)
        return [n for _, n in self._passes]

    def after_pass(self, index: int, image, spp: int) -> None:
        """Keep the pass's per-pixel mean square; after an iteration's last render (not
        the last iteration's), refine the guide from its records."""
        self._m2.append(np.array(image, dtype=np.float64)[..., -1])
        k = self._passes[index][0]
        last_of_iteration = index + 1 == len(self._passes) or self._passes[index + 1][0] != k
        if not last_of_iteration or k + 1 == len(self._iterations):
            return
        self.guide.tree.refine(self.spatial_threshold * np.sqrt(2.0 ** k))
        learned = self.guide.tree.learned
        self.guide.set_share(np.where(learned, self.bsdf_fraction, 1.0))
        if k + 2 == len(self._iterations):     # the last iteration only renders
            self.recording = dr.opaque(mi.UInt32, 0, 1)

    def combine(self, images: list, spps: list):
        """The iterations' images, weighted by :func:`pass_weights`."""
        means, variances, counts = [], [], []
        for k in range(len(self._iterations)):
            idx = [i for i, (it, _) in enumerate(self._passes) if it == k and i < len(images)]
            n = sum(spps[i] for i in idx)
            mean = sum(images[i] * spps[i] for i in idx) / n
            m2 = sum(self._m2[i] * spps[i] for i in idx) / n
            means.append(mean)
            variances.append(image_variance(mean.mean(axis=-1), m2, n))
            counts.append(n)
        self.weights = pass_weights(variances, counts)
        return sum(w * m for w, m in zip(self.weights, means))

    def to_string(self):
        return (f"GuidedPathIntegrator[{VRPathIntegrator.to_string(self)}, "
                f"bsdf_fraction={self.bsdf_fraction}, leaves={self.guide.tree.leaves}]")


strategies.register("guided", GuidedStrategy, replace=True)
mi.register_integrator("vr_guided_path", GuidedPathIntegrator)
