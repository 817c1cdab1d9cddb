"""The ``vr_path`` integrator: a path tracer with selectable direction sampling."""
from __future__ import annotations

import warnings
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from . import warps
from .choices import STRATEGIES  # noqa: F401  (the strategy list, defined once)

#: Probability with which the ``mis`` strategy draws from the cosine strategy
#: (else from the BSDF's own sampling). See :class:`VRPathIntegrator`.
MIS_COSINE_WEIGHT = 0.25

#: Largest survival probability of Russian roulette (as Mitsuba's ``path``).
RR_MAX_PROBABILITY = 0.95


class DirectionSample(NamedTuple):
    """The next direction of a path, as drawn by a strategy at one vertex."""
    wo: mi.Vector3f       # local direction
    pdf: mi.Float         # density of the strategy at wo (solid angle; Dirac lobes: as
                          # sampled); 0 where no direction was drawn (failed BSDF sample)
    weight: mi.Spectrum   # bsdf.eval(wo) / pdf  (the BSDF's own weight on delta lobes)
    delta: mi.Bool        # sampled from a Dirac delta lobe
    eta: mi.Float         # relative index of refraction crossed (1 for reflection)
    null: mi.Bool         # passed straight through a ``null`` component


class VertexSample(NamedTuple):
    """The next direction and the BSDF at an emitter sample's direction (for NEE)."""
    direction: DirectionSample
    em_value: mi.Spectrum  # bsdf.eval(wo_em) (f * cos)
    em_pdf: mi.Float       # density of the strategy at wo_em (for the MIS weight)


# ------------------------------------------------------------- strategies
#
# One function per concern, callable outside the render loop (the warp tests
# call them on a single BSDF): ``sample_direction`` draws the next direction of
# a strategy, ``sample_direction_and_eval`` also evaluates the BSDF at an
# emitter sample's direction, and ``direction_pdf`` reports the strategy's
# density at any direction. The sampling maths is in :mod:`.warps`.

def _hemisphere_sample(strategy, wi, transmits, sample1, sample2):
    """Direction of the ``uniform`` or ``cosine`` strategy: on the side of ``wi``;
    for a BSDF that transmits, on either side (``sample1 < 0.5``: z < 0)."""
    return warps.square_to_sided_hemisphere(warps.hemisphere_warp(strategy).warp,
                                            sample1, sample2, wi.z, transmits)


def _hemisphere_pdf(strategy, wi, wo, transmits):
    """Density of :func:`_hemisphere_sample` (the unbiasedness tests replace it)."""
    return warps.square_to_sided_hemisphere_pdf(warps.hemisphere_warp(strategy).pdf,
                                                wo, wi.z, transmits)


def _crossing_eta(bsdf, ctx, si, wo, transmits, active):
    """Relative index of refraction for a direction ``wo`` on the far side.

    Mitsuba's interface gives eta only with a sample, so the BSDF is sampled
    once with its transmission lobes alone (its eta does not depend on the
    sample). Only BSDFs that transmit pay for this call.
    """
    if not transmits:
        return mi.Float(1.0)
    ctx_t = mi.BSDFContext(ctx.mode, mi.BSDFFlags.Transmission)
    bs, _ = bsdf.sample(ctx_t, si, mi.Float(0.5), mi.Point2f(0.5, 0.5), active)
    crosses = (si.wi.z * wo.z) < 0
    return dr.select(crosses & (bs.eta > 0), bs.eta, 1.0)


def _vertex(bsdf, strategy, ctx, si, sample1, sample2, active) -> DirectionSample:
    """Per BSDF instance (inside ``dr.dispatch``) for ``uniform``, ``cosine`` and
    ``mis``: the next direction.

    BSDFs with a Dirac delta lobe (mirrors, smooth dielectrics, ``plastic``,
    ``null``) cannot be hit by a sampled direction: they use their own sampling.
    """
    flags = bsdf.flags()
    if mi.has_flag(flags, mi.BSDFFlags.Delta):
        return _bsdf_vertex(bsdf, ctx, si, sample1, sample2, active)
    transmits = mi.has_flag(flags, mi.BSDFFlags.Transmission)
    if strategy == "mis":
        c = MIS_COSINE_WEIGHT
        split = warps.split_mixture_sample(sample1, c)
        bs, bs_weight = bsdf.sample(ctx, si, split.u_b, sample2, active & ~split.use_a)
        wo_cos = _hemisphere_sample("cosine", si.wi, transmits, split.u_a, sample2)
        wo = dr.select(split.use_a, wo_cos, bs.wo)
        drawn = split.use_a | _drawn(bs_weight)
        value, bsdf_pdf = bsdf.eval_pdf(ctx, si, wo, active & drawn)
        pdf = warps.mixture_pdf(c, _hemisphere_pdf("cosine", si.wi, wo, transmits), bsdf_pdf)
        pdf = dr.select(drawn, pdf, 0.0)
        eta = dr.select(split.use_a, _crossing_eta(bsdf, ctx, si, wo, transmits, active),
                        bs.eta)
    else:
        wo = _hemisphere_sample(strategy, si.wi, transmits, sample1, sample2)
        value = bsdf.eval(ctx, si, wo, active)
        pdf = _hemisphere_pdf(strategy, si.wi, wo, transmits)
        eta = _crossing_eta(bsdf, ctx, si, wo, transmits, active)
        drawn = mi.Bool(True)
    weight = dr.select(drawn & (pdf > 0), value / dr.maximum(pdf, warps.PDF_EPSILON), 0.0)
    return DirectionSample(wo, pdf, weight, mi.Bool(False), eta, mi.Bool(False))


def _vertex_and_eval(bsdf, strategy, ctx, si, sample1, sample2, wo_em, active) -> VertexSample:
    """:func:`_vertex`, and at ``wo_em`` the BSDF value and the strategy's density
    (for NEE and its MIS weight)."""
    flags = bsdf.flags()
    if mi.has_flag(flags, mi.BSDFFlags.Delta):
        return _bsdf_vertex_and_eval(bsdf, ctx, si, sample1, sample2, wo_em, active)
    transmits = mi.has_flag(flags, mi.BSDFFlags.Transmission)
    direction = _vertex(bsdf, strategy, ctx, si, sample1, sample2, active)
    em_value, em_bsdf_pdf = bsdf.eval_pdf(ctx, si, wo_em, active)
    if strategy == "mis":
        em_pdf = warps.mixture_pdf(MIS_COSINE_WEIGHT,
                                   _hemisphere_pdf("cosine", si.wi, wo_em, transmits),
                                   em_bsdf_pdf)
    else:
        em_pdf = _hemisphere_pdf(strategy, si.wi, wo_em, transmits)
    return VertexSample(direction, em_value, em_pdf)


def _drawn(bsdf_weight):
    """Did ``bsdf.sample`` draw a direction? Mitsuba marks a failed sample (e.g.
    below the horizon of a one-sided BSDF) by a zero weight, its pdf may be > 0."""
    return dr.any(mi.unpolarized_spectrum(bsdf_weight) != 0)


def _bsdf_direction(bs, weight) -> DirectionSample:
    """A :class:`DirectionSample` from the BSDF's own sample and weight."""
    return DirectionSample(bs.wo, dr.select(_drawn(weight), bs.pdf, 0.0), weight,
                           mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta), bs.eta,
                           mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null))


def _bsdf_vertex(bsdf, ctx, si, sample1, sample2, active) -> DirectionSample:
    """The ``bsdf`` strategy: the BSDF's own sampling."""
    return _bsdf_direction(*bsdf.sample(ctx, si, sample1, sample2, active))


def _bsdf_vertex_and_eval(bsdf, ctx, si, sample1, sample2, wo_em, active) -> VertexSample:
    """The ``bsdf`` strategy, evaluated at ``wo_em`` in the same call
    (``eval_pdf_sample``, as Mitsuba's ``path``)."""
    em_value, em_pdf, bs, weight = bsdf.eval_pdf_sample(ctx, si, wo_em, sample1, sample2,
                                                        active)
    return VertexSample(_bsdf_direction(bs, weight), em_value, em_pdf)


def _plain(value):
    """(Nested) NamedTuples as plain tuples."""
    return tuple(_plain(v) for v in value) if isinstance(value, tuple) else value


def _per_bsdf(result_type, fn, bsdf, *args):
    """``fn(bsdf, *args)`` for one BSDF, or one ``dr.dispatch`` over a ``mi.BSDFPtr``.

    Dr.Jit 1.5's ``dr.dispatch`` does not traverse NamedTuples (it compares the
    results of the BSDFs as opaque objects and fails), so the results cross it
    as plain nested tuples and are rebuilt as ``result_type``.
    """
    if not isinstance(bsdf, mi.BSDFPtr):
        return fn(bsdf, *args)
    out = dr.dispatch(bsdf, lambda b, *a: _plain(fn(b, *a)), *args)
    if result_type is VertexSample:
        return VertexSample(DirectionSample(*out[0]), *out[1:])
    return result_type(*out)


def sample_direction(strategy, bsdf, ctx, si, sample1, sample2,
                     active=True) -> DirectionSample:
    """Next direction of ``strategy`` at the vertex ``si`` with BSDF ``bsdf``.

    ``bsdf``: a ``mi.BSDFPtr`` (one dispatch over the BSDFs) or one BSDF.
    """
    active = mi.Bool(active)
    if strategy == "bsdf":
        return _bsdf_vertex(bsdf, ctx, si, sample1, sample2, active)
    return _per_bsdf(DirectionSample, _vertex, bsdf, strategy, ctx, si, sample1, sample2,
                     active)


def sample_direction_and_eval(strategy, bsdf, ctx, si, sample1, sample2, wo_em,
                              active=True) -> VertexSample:
    """:func:`sample_direction`, and at ``wo_em`` (a local direction, e.g. of an
    emitter sample) the BSDF value and the strategy's density, from the same
    BSDF call (``bsdf``: ``eval_pdf_sample``)."""
    active = mi.Bool(active)
    if strategy == "bsdf":
        return _bsdf_vertex_and_eval(bsdf, ctx, si, sample1, sample2, wo_em, active)
    return _per_bsdf(VertexSample, _vertex_and_eval, bsdf, strategy, ctx, si, sample1,
                     sample2, wo_em, active)


def direction_pdf(strategy, bsdf, ctx, si, wo, active=True):
    """Density with which ``strategy`` draws the local direction ``wo`` at ``si``
    (for BSDFs without a delta lobe; with one, the BSDF's own pdf)."""
    flags = bsdf.flags()
    bsdf_pdf = bsdf.pdf(ctx, si, wo, active)
    if strategy == "bsdf":
        return bsdf_pdf
    transmits = mi.has_flag(flags, mi.BSDFFlags.Transmission)
    delta = mi.has_flag(flags, mi.BSDFFlags.Delta)
    if strategy == "mis":
        pdf = warps.mixture_pdf(MIS_COSINE_WEIGHT,
                                _hemisphere_pdf("cosine", si.wi, wo, transmits), bsdf_pdf)
    else:
        pdf = _hemisphere_pdf(strategy, si.wi, wo, transmits)
    return dr.select(delta, bsdf_pdf, pdf)


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
         hemisphere, pdf :math:`\cos\theta/\pi`), ``bsdf`` (the BSDF's own
         importance sampling; for ``phong`` the Phong-lobe mixture) or ``mis``
         (one-sample multiple importance sampling of ``cosine`` and ``bsdf``,
         see below). (Default: ``bsdf``)

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
       - Hide directly visible emitters, as Mitsuba's ``path``: camera rays
         pass through area emitters, and the environment is hidden (the
         alpha channel is 0 there). (Default: |false|)

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
    Mitsuba's ``path``; for the other strategies one ``dr.dispatch`` that
    draws the strategy's direction and evaluates it and the emitter sample's
    direction). Every bounce draws a direction with the chosen ``strategy``
    and weights it by ``bsdf.eval / pdf`` (``eval`` includes the cosine). The
    direction sampling is :func:`sample_direction` and its density
    :func:`direction_pdf`, callable outside the render loop (the warp tests do).

    The uniform and cosine strategies sample the hemisphere on the side of the
    incident direction; for BSDFs with a transmission lobe they sample the
    whole sphere (uniform: :math:`1/4\pi`; cosine: a side chosen with
    probability 1/2, :math:`|\cos\theta|/2\pi`). Where such a direction
    crosses the surface, the relative index of refraction is tracked as
    Mitsuba's ``path`` does for sampled refractions (read from the BSDF's
    own transmission sample), so that Russian roulette, whose survival
    probability is :math:`\min(p_\mathrm{max}, \max\beta\,\eta^2)` with
    :math:`p_\mathrm{max}` = ``RR_MAX_PROBABILITY`` = 0.95, treats paths inside
    glass the same for every strategy. These strategies are unbiased on any
    BSDF but are poor estimators of narrow glossy lobes: on rough glass
    (``roughdielectric``) lit by a small light their weights grow by orders
    of magnitude over a few vertices (a tail heavy enough for an infinite
    variance), so low-spp renders are usually too dark, with rare fireflies
    holding the missing energy.

    ``mis`` draws from the cosine strategy with probability
    :math:`c` = ``MIS_COSINE_WEIGHT`` = 0.25 and from the BSDF's own sampling
    otherwise, and weights every direction by
    :math:`f / (c\,p_\mathrm{cos} + (1-c)\,p_\mathrm{bsdf})`, whichever
    technique drew it (Veach's one-sample model with the balance heuristic).
    That mixture density is the one used everywhere, including the MIS
    weights against emitter sampling. Why 0.25: a mixture's second moment is
    at most :math:`1/c` times that of each of its techniques (defensive
    importance sampling, Hesterberg 1995), i.e. at most 1.33x that of ``bsdf``,
    which is the technique that follows narrow lobes (cosine sampling breaks
    down there by orders of magnitude), while the cosine share keeps a
    density of at least :math:`0.25\cos\theta/\pi` over the whole
    hemisphere, which bounds the weight wherever the BSDF's own sampling
    undersamples its integrand (a lobe clipped by the horizon, a diffuse part
    that a multi-lobe sampler picks rarely). How it compares with the better
    of ``cosine`` and ``bsdf`` over the stability study's Phong exponent
    sweep: see the README.

    BSDFs with a Dirac delta lobe (mirrors, smooth dielectrics, ``plastic``,
    ``null``) cannot be hit by a sampled direction: at such vertices every
    strategy falls back to the BSDF's own sampling, so those images stay
    correct. Without ``emitter_sampling`` delta emitters (point, spot,
    directional) are never reached; rendering such a scene warns. Participating
    media are not simulated: a scene with a medium is refused with an error
    that names it (use Mitsuba's ``volpath``). ``max_depth`` 0 renders black.

    Sample dimensions per bounce: 2 for the emitter sample (only with
    ``emitter_sampling``), 1 + 2 for the direction (``uniform`` and ``cosine``
    use the 1D sample only to pick a side for transmitting BSDFs; ``mis``
    uses it to pick the technique and, rescaled, inside the technique), 1 for
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

    # --------------------------------------------------------------- main loop

    def _check_scene(self, scene) -> None:
        """Refuse what this integrator does not simulate; warn about what it cannot see."""
        media = [(f"sensor '{s.id()}'", s.get_medium()) for s in scene.sensors()]
        for shape in scene.shapes():
            media += [(f"shape '{shape.id()}' (interior)", shape.interior_medium()),
                      (f"shape '{shape.id()}' (exterior)", shape.exterior_medium())]
        media = [(where, m) for where, m in media if m is not None]
        if media:
            where, medium = media[0]
            raise ValueError(
                f"vr_path: the scene has a participating medium ('{medium.id()}', "
                f"{str(medium).split('[')[0]}, on the {where}), which vr_path does not simulate "
                f"(it would render as if the medium were absent); use Mitsuba's 'volpath' "
                f"integrator for scenes with media.")
        if not self.emitter_sampling:
            delta = [e.id() for e in scene.emitters()
                     if mi.has_flag(e.flags(), mi.EmitterFlags.Delta)]
            if delta:
                warnings.warn(
                    f"vr_path: emitter_sampling is off, so the delta emitter(s) "
                    f"{', '.join(repr(d) for d in delta)} (point, spot, directional...) are "
                    f"never reached and light nothing; set emitter_sampling=true.",
                    RuntimeWarning, stacklevel=2)

    @dr.syntax
    def sample(self, scene, sampler, ray, medium=None, active=True):
        self._check_scene(scene)
        if dr.hint(self.max_depth == 0, mode='scalar'):
            return mi.Spectrum(0.0), mi.Bool(False), self._aovs(mi.UInt32(0), mi.UInt32(0))
        ctx = mi.BSDFContext()
        max_depth = mi.UInt32(0xFFFFFFFF if self.max_depth < 0 else self.max_depth)
        nee = self.emitter_sampling
        count = self.count_segments
        hide = self.hide_emitters

        ray = mi.Ray3f(ray)                    # current ray
        L = mi.Spectrum(0.0)                   # radiance accumulator
        beta = mi.Spectrum(1.0)                # path throughput
        eta = mi.Float(1.0)                    # relative index of refraction crossed so far
        depth = mi.UInt32(0)                   # vertices so far
        # Used for the alpha channel, and to hide the environment (as Mitsuba's path).
        valid_ray = mi.Bool(not hide and scene.environment() is not None)
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
            emitter = si.emitter(scene, active)

            # hide_emitters: camera rays pass through area emitters (Mitsuba's path).
            skip = mi.Bool(False)
            if dr.hint(hide, mode='scalar'):
                skip = active & (depth == 0) & si.is_valid() & (emitter != None)  # noqa: E711
            on = active & ~skip

            # ------------------------ emission found by the sampled direction
            visible = on & (emitter != None)  # noqa: E711  (Dr.Jit pointer test)
            w_dir = mi.Float(1.0)
            if dr.hint(nee, mode='scalar'):
                ds = mi.DirectionSample3f(scene, si, prev_it)
                em_pdf = scene.pdf_emitter_direction(prev_it, ds, visible & ~prev_delta)
                w_dir = dr.select(prev_delta, 1.0, warps.power_heuristic(prev_pdf, em_pdf))
            L = dr.select(visible, L + beta * emitter.eval(si, visible) * w_dir, L)

            active_next = on & si.is_valid() & (depth + 1 < max_depth)
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
                sample1 = sampler.next_1d(active_next)
                sample2 = sampler.next_2d(active_next)
                vertex = sample_direction_and_eval(self.strategy, bsdf, ctx, si, sample1,
                                                   sample2, si.to_local(ds_em.d), active_next)
                direction = vertex.direction
                w_em = dr.select(ds_em.delta, 1.0,
                                 warps.power_heuristic(ds_em.pdf, vertex.em_pdf))
                L = dr.select(active_em, L + beta * vertex.em_value * em_weight * w_em, L)
            else:
                sample1 = sampler.next_1d(active_next)
                sample2 = sampler.next_2d(active_next)
                direction = sample_direction(self.strategy, bsdf, ctx, si, sample1, sample2,
                                             active_next)

            # ------------------------------------------------ next direction
            valid_ray |= on & si.is_valid() & ~direction.null
            ray = dr.select(skip, si.spawn_ray(ray.d), si.spawn_ray(si.to_world(direction.wo)))
            beta *= dr.select(active_next, direction.weight, dr.select(skip, 1.0, 0.0))
            eta *= dr.select(active_next, direction.eta, 1.0)
            if dr.hint(nee, mode='scalar'):
                prev_it = dr.select(skip, prev_it, mi.Interaction3f(si))
            prev_pdf = dr.select(skip, prev_pdf, direction.pdf)
            prev_delta = dr.select(skip, prev_delta, direction.delta)
            depth[si.is_valid() & ~skip] += 1

            # ------------------------------------------------- Russian roulette
            # As Mitsuba's path: eta^2 undoes the radiance scaling at refractive
            # interfaces, so paths inside glass are not ended for it.
            beta_max = dr.max(mi.unpolarized_spectrum(beta))
            rr_active = depth >= self.rr_depth
            rr_prob = dr.minimum(beta_max * dr.square(eta), RR_MAX_PROBABILITY)
            rr_continue = sampler.next_1d(active_next) < rr_prob
            beta[rr_active] *= dr.rcp(dr.maximum(rr_prob, warps.PDF_EPSILON))
            active = skip | (active_next & (~rr_active | rr_continue) & (beta_max > 0)
                             & (direction.pdf > 0))

        return dr.select(valid_ray, L, 0.0), valid_ray, self._aovs(segments, shadow_rays)

    def _aovs(self, segments, shadow_rays):
        return [mi.Float(segments), mi.Float(shadow_rays)] if self.count_segments else []

    def aov_names(self):
        return ["segments", "shadow_rays"] if self.count_segments else []

    def to_string(self):
        return (f"VRPathIntegrator[strategy={self.strategy}, max_depth={self.max_depth}, "
                f"rr_depth={self.rr_depth}, emitter_sampling={self.emitter_sampling}, "
                f"hide_emitters={self.hide_emitters}]")


mi.register_integrator("vr_path", VRPathIntegrator)  # the class of this variant, bound now
