"""The ``vr_path`` integrator: a path tracer with selectable direction sampling."""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import warps

#: Valid values of the ``strategy`` parameter.
STRATEGIES = ("uniform", "cosine", "bsdf")


def mis_weight(pdf_a, pdf_b):
    """Power heuristic (beta = 2) weight of technique a against b.

    Written as 1 / (1 + (b/a)^2) so that an infinite density (an emitter seen
    exactly edge-on) gives 1 or 0 instead of inf / inf = NaN.
    """
    ratio = pdf_b / dr.select(pdf_a > 0, pdf_a, 1.0)
    return dr.select(pdf_a > 0, dr.rcp(1.0 + dr.square(ratio)), 0.0)



def _strategy_calls(bsdf, ctx, si, wo, sample1, sample2, active):
    """Per BSDF (inside ``dr.dispatch``), for the uniform and cosine strategies:
    ``eval`` at the strategy's direction, or, for a BSDF with a delta lobe
    (which those directions cannot hit), its own ``sample`` instead."""
    if mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta):
        bs, weight = bsdf.sample(ctx, si, sample1, sample2, active)
        return dr.zeros(mi.Spectrum), bs, weight
    return bsdf.eval(ctx, si, wo, active), dr.zeros(mi.BSDFSample3f), dr.zeros(mi.Spectrum)


def _strategy_calls_nee(bsdf, ctx, si, wo, sample1, sample2, wo_em, active_em, active):
    """:func:`_strategy_calls` and ``eval_pdf`` at the emitter sample's direction.

    ``active`` comes last: ``dr.dispatch`` takes the last argument, if a mask,
    as the mask of the whole call (``active_em`` is a subset of it)."""
    value, bs, weight = _strategy_calls(bsdf, ctx, si, wo, sample1, sample2, active)
    nee_value, nee_pdf = bsdf.eval_pdf(ctx, si, wo_em, active_em)
    return value, bs, weight, nee_value, nee_pdf


class VRPathIntegrator(mi.SamplingIntegrator):
    r"""
    .. _integrator-vr_path:

    Variance-reduction path tracer (:monosp:`vr_path`)
    --------------------------------------------------

    .. pluginparameters::

     * - strategy
       - |string|
       - How the next direction is drawn at every bounce: ``uniform``
         (uniform hemisphere, pdf :math:`1/2\pi`), ``cosine`` (cosine-weighted
         hemisphere, pdf :math:`\cos\theta/\pi`) or ``bsdf`` (the BSDF's own
         importance sampling; for ``phong`` the Phong-lobe mixture).
         (Default: ``bsdf``)

     * - max_depth
       - |int|
       - Longest path depth in the output image, as in Mitsuba's ``path``:
         -1 is unbounded, 1 shows only directly visible emitters, 2 adds
         direct illumination, and so on. (Default: -1)

     * - rr_depth
       - |int|
       - Depth from which Russian roulette may end paths; must be > 0.
         (Default: 5)

     * - hide_emitters
       - |bool|
       - Hide directly visible emitters. (Default: |false|)

     * - emitter_sampling
       - |bool|
       - Next-event estimation: sample a point on an emitter at every vertex
         and combine it with the direction-sampling strategy by multiple
         importance sampling (power heuristic), so the estimate stays unbiased
         for every strategy. Off, as in the writeup, emitters are only found by
         the sampled directions. (Default: |false|)

    A unidirectional path tracer written in Python: one ``@dr.syntax`` loop,
    compiled into a single megakernel, with one dispatch over the BSDFs per
    vertex (``eval_pdf_sample`` for ``bsdf`` with emitter sampling, as
    Mitsuba's ``path``; for ``uniform``/``cosine`` one ``dr.dispatch`` that
    evaluates the strategy's direction and the emitter sample's direction).
    Every bounce draws a direction with the chosen ``strategy`` and weights it
    by ``bsdf.eval / pdf`` (``eval`` includes the cosine). The uniform and cosine strategies sample the
    hemisphere on the side of the incident direction; for BSDFs with a
    transmission lobe they sample the whole sphere (uniform: :math:`1/4\pi`;
    cosine: a side chosen with probability 1/2, :math:`|\cos\theta|/2\pi`).

    BSDFs with a Dirac delta lobe (mirrors, smooth dielectrics, ``plastic``)
    cannot be hit by a sampled direction: at such vertices every strategy
    falls back to the BSDF's own sampling, so those images stay correct.

    Sample dimensions per bounce: 2 for the emitter sample (only with
    ``emitter_sampling``), 1 + 2 for the direction (``uniform`` and ``cosine``
    use the 1D sample only to pick a side for transmitting BSDFs), 1 for
    Russian roulette.

    .. tabs::

        .. code-tab:: xml

            <integrator type="vr_path">
                <string name="strategy" value="cosine"/>
                <integer name="max_depth" value="8"/>
            </integrator>

        .. code-tab:: python

            'type': 'vr_path',
            'strategy': 'cosine',
            'max_depth': 8
    """

    def __init__(self, props: mi.Properties):
        mi.SamplingIntegrator.__init__(self, props)
        strategy = props.get("strategy", "bsdf")
        if strategy not in STRATEGIES:
            raise ValueError(f"vr_path: unknown strategy {strategy!r}; "
                             f"valid choices are {', '.join(STRATEGIES)}")
        self.strategy = strategy

        max_depth = props.get("max_depth", -1)
        if not isinstance(max_depth, int) or max_depth < -1:
            raise ValueError(f"vr_path: 'max_depth' must be -1 (unbounded) or an "
                             f"integer >= 0, got {max_depth!r}")
        self.max_depth = max_depth
        rr_depth = props.get("rr_depth", 5)
        if not isinstance(rr_depth, int) or rr_depth <= 0:
            raise ValueError(f"vr_path: 'rr_depth' must be an integer > 0, got {rr_depth!r}")
        self.rr_depth = rr_depth
        self.hide_emitters = bool(props.get("hide_emitters", False))
        self.emitter_sampling = bool(props.get("emitter_sampling", False))
        #: Benchmark instrumentation, off by default and then absent from the
        #: compiled kernel: when True (set on the instance before rendering),
        #: ``sample`` also returns two AOVs, ``segments`` (rays traced by the
        #: path loop) and ``shadow_rays`` (NEE visibility rays), per sample.
        self.count_segments = False

    # ------------------------------------------------------- direction sampling

    def _strategy_pdf(self, wi: mi.Vector3f, wo: mi.Vector3f, transmits: mi.Bool) -> mi.Float:
        """Density of the uniform or cosine strategy at local direction ``wo``."""
        same_side = (wi.z * wo.z) > 0
        flipped = mi.Vector3f(wo.x, wo.y, dr.abs(wo.z))
        if self.strategy == "uniform":
            pdf = warps.square_to_uniform_hemisphere_pdf(flipped)
        else:
            pdf = warps.square_to_cosine_hemisphere_pdf(flipped)
        return dr.select(transmits, 0.5 * pdf, dr.select(same_side, pdf, 0.0))

    def _sample_direction(self, bsdf, ctx, si, sample1, sample2, active, bsdf_sample=None,
                          emitter_dir=None):
        """Next direction: ((local wo, pdf, weight, sampled delta lobe, eta, uses BSDF
        pdf), NEE evaluation).

        ``bsdf_sample``: the result of ``bsdf.sample`` with these samples if the
        caller already has it (from ``eval_pdf_sample``), for ``strategy=bsdf``.
        ``emitter_dir = (wo_em, active_em)``: for uniform and cosine, also
        evaluate ``bsdf.eval_pdf`` there, in the same BSDF call; the second
        return value is then its ``(value, pdf)``, else None.
        """
        if self.strategy == "bsdf":
            if bsdf_sample is None:
                bsdf_sample = bsdf.sample(ctx, si, sample1, sample2, active)
            bs, bsdf_weight = bsdf_sample
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            return (bs.wo, bs.pdf, bsdf_weight, delta, bs.eta, mi.Bool(True)), None

        flags = bsdf.flags()
        use_bsdf = mi.has_flag(flags, mi.BSDFFlags.Delta)
        transmits = mi.has_flag(flags, mi.BSDFFlags.Transmission)
        if self.strategy == "uniform":
            wo = warps.square_to_uniform_hemisphere(sample2)
        else:
            wo = warps.square_to_cosine_hemisphere(sample2)
        # Hemisphere of the incident direction; either one, by sample1, for transmission.
        flip = dr.select(transmits, sample1 < 0.5, si.wi.z < 0)
        wo.z = dr.select(flip, -wo.z, wo.z)
        pdf = self._strategy_pdf(si.wi, wo, transmits)
        # One dispatch over the BSDFs for all their work at this vertex.
        if emitter_dir is None:
            value, bs, bsdf_weight = dr.dispatch(bsdf, _strategy_calls, ctx, si, wo, sample1,
                                                 sample2, active)
            nee = None
        else:
            value, bs, bsdf_weight, nee_value, nee_pdf = dr.dispatch(
                bsdf, _strategy_calls_nee, ctx, si, wo, sample1, sample2, *emitter_dir, active)
            nee = (nee_value, nee_pdf)
        delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        weight = value / dr.maximum(pdf, 1e-20)
        return (dr.select(use_bsdf, bs.wo, wo),
                dr.select(use_bsdf, bs.pdf, pdf),
                dr.select(use_bsdf, bsdf_weight, weight),
                use_bsdf & delta,
                dr.select(use_bsdf, bs.eta, 1.0),
                use_bsdf), nee

    def _direction_pdf(self, bsdf_pdf, si, wo, flags, use_bsdf):
        """Density with which this strategy would have produced ``wo``."""
        if self.strategy == "bsdf":
            return bsdf_pdf
        transmits = mi.has_flag(flags, mi.BSDFFlags.Transmission)
        return dr.select(use_bsdf, bsdf_pdf, self._strategy_pdf(si.wi, wo, transmits))

    # --------------------------------------------------------------- main loop

    @dr.syntax
    def sample(self, scene, sampler, ray, medium=None, active=True):
        ctx = mi.BSDFContext()
        max_depth = mi.UInt32(0xFFFFFFFF if self.max_depth < 0 else self.max_depth)
        nee = self.emitter_sampling
        count = self.count_segments
        # strategy=bsdf with NEE: evaluate the emitter direction and sample the
        # next one in a single BSDF call, as Mitsuba's path does.
        joint = nee and self.strategy == "bsdf"

        ray = mi.Ray3f(ray)                    # current ray
        L = mi.Spectrum(0.0)                   # radiance accumulator
        beta = mi.Spectrum(1.0)                # path throughput
        eta = mi.Float(1.0)                    # relative index of refraction so far
        depth = mi.UInt32(0)                   # vertices so far
        valid_ray = mi.Bool(False)             # did the camera ray hit anything?
        prev_it = dr.zeros(mi.Interaction3f)   # previous vertex (for MIS)
        prev_pdf = mi.Float(1.0)               # pdf of the direction that led here
        prev_delta = mi.Bool(True)             # was that direction a delta lobe?
        segments = mi.UInt32(0)                # rays traced (count_segments only)
        shadow_rays = mi.UInt32(0)             # shadow rays (count_segments only)
        active = mi.Bool(active)

        while dr.hint(active, label="vr_path"):
            si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All,
                                     coherent=(depth == 0), active=active)
            if dr.hint(count, mode='scalar'):
                segments += mi.UInt32(active)

            # ------------------------ emission found by the sampled direction
            emitter = si.emitter(scene, active)
            visible = active & (emitter != None)  # noqa: E711  (Dr.Jit pointer test)
            if dr.hint(self.hide_emitters, mode='scalar'):
                visible &= depth > 0
            w_dir = mi.Float(1.0)
            if dr.hint(nee, mode='scalar'):
                ds = mi.DirectionSample3f(scene, si, prev_it)
                em_pdf = scene.pdf_emitter_direction(prev_it, ds, visible & ~prev_delta)
                w_dir = dr.select(prev_delta, 1.0, mis_weight(prev_pdf, em_pdf))
            L = dr.select(visible, L + beta * emitter.eval(si, visible) * w_dir, L)

            active_next = active & si.is_valid() & (depth + 1 < max_depth)
            valid_ray |= active & si.is_valid()
            bsdf = si.bsdf(ray)
            flags = bsdf.flags()

            # ------------------------------------------ next-event estimation
            if dr.hint(nee, mode='scalar'):
                active_em = active_next & mi.has_flag(flags, mi.BSDFFlags.Smooth)
                ds_em, em_weight = scene.sample_emitter_direction(
                    si, sampler.next_2d(active_em), True, active_em)
                if dr.hint(count, mode='scalar'):
                    shadow_rays += mi.UInt32(active_em)
                active_em &= ds_em.pdf != 0
                wo_em = si.to_local(ds_em.d)
                sample1 = sampler.next_1d(active_next)
                sample2 = sampler.next_2d(active_next)
                if dr.hint(joint, mode='scalar'):
                    bsdf_val, bsdf_pdf, bs, bs_weight = bsdf.eval_pdf_sample(
                        ctx, si, wo_em, sample1, sample2, active_next)
                    bsdf_sample = (bs, bs_weight)
                    direction = self._sample_direction(bsdf, ctx, si, sample1, sample2,
                                                       active_next, bsdf_sample)[0]
                else:
                    direction, (bsdf_val, bsdf_pdf) = self._sample_direction(
                        bsdf, ctx, si, sample1, sample2, active_next,
                        emitter_dir=(wo_em, active_em))
                use_bsdf_em = mi.has_flag(flags, mi.BSDFFlags.Delta)
                pdf_em_dir = self._direction_pdf(bsdf_pdf, si, wo_em, flags, use_bsdf_em)
                w_em = dr.select(ds_em.delta, 1.0, mis_weight(ds_em.pdf, pdf_em_dir))
                L = dr.select(active_em, L + beta * bsdf_val * em_weight * w_em, L)
            else:
                sample1 = sampler.next_1d(active_next)
                sample2 = sampler.next_2d(active_next)
                direction = self._sample_direction(bsdf, ctx, si, sample1, sample2,
                                                   active_next)[0]

            # ------------------------------------------------ next direction
            wo, pdf, weight, delta, eta_s, _ = direction
            ray = si.spawn_ray(si.to_world(wo))
            beta *= dr.select(active_next, weight, 0.0)
            eta *= eta_s
            if dr.hint(nee, mode='scalar'):
                prev_it = mi.Interaction3f(si)
            prev_pdf = pdf
            prev_delta = delta
            depth[si.is_valid()] += 1

            # ------------------------------------------------- Russian roulette
            beta_max = dr.max(mi.unpolarized_spectrum(beta))
            rr_active = depth >= self.rr_depth
            rr_prob = dr.minimum(beta_max * dr.square(eta), 0.95)
            rr_continue = sampler.next_1d(active_next) < rr_prob
            beta[rr_active] *= dr.rcp(dr.maximum(rr_prob, 1e-20))
            active = active_next & (~rr_active | rr_continue) & (beta_max > 0) & (pdf > 0)

        if dr.hint(count, mode='scalar'):
            return L, valid_ray, [mi.Float(segments), mi.Float(shadow_rays)]
        return L, valid_ray, []

    def aov_names(self):
        return ["segments", "shadow_rays"] if self.count_segments else []

    def to_string(self):
        return (f"VRPathIntegrator[strategy={self.strategy}, max_depth={self.max_depth}, "
                f"rr_depth={self.rr_depth}, emitter_sampling={self.emitter_sampling}, "
                f"hide_emitters={self.hide_emitters}]")


mi.register_integrator("vr_path", VRPathIntegrator)  # the class of this variant, bound now
