"""The ``vr_path`` integrator: a path tracer with selectable direction sampling."""
from __future__ import annotations

import warnings
import drjit as dr
import mitsuba as mi

from . import strategies, warps
from .strategies import DirectionSample, Strategy, VertexSample  # noqa: F401  (re-exported)

#: The built-in strategies' names, in order (``integrators.strategies.BUILTIN``); every
#: registered name: ``integrators.strategies.names()``.
STRATEGIES = strategies.BUILTIN

#: Largest survival probability of Russian roulette (as Mitsuba's ``path``).
RR_MAX_PROBABILITY = 0.95


# ------------------------------------------------ strategies at a vertex
#
# One function per concern, callable outside the render loop (the warp tests and the
# lab call them on a single BSDF): ``sample_direction`` draws the next direction of a
# strategy, ``sample_direction_and_eval`` also evaluates the BSDF at an emitter
# sample's direction, and ``direction_pdf`` reports the strategy's density at any
# direction. The strategies are objects (:mod:`.strategies`); this is where they meet
# the BSDFs of a scene: one ``dr.dispatch`` over the BSDF instances for strategies that
# ask for it, and there the fallback to the BSDF's own sampling on delta lobes.

def seed_value(seed) -> int:
    """A render's ``seed`` as a Python int: ``mi.render`` takes an int or a ``mi.UInt32``,
    and an integrator that nests this one (Mitsuba's ``aov``) passes its ``UInt32`` on."""
    return int(seed) if isinstance(seed, int) else int(dr.slice(mi.UInt32(seed)))


def _has_delta_lobe(bsdf) -> bool:
    """BSDFs with a Dirac delta lobe (mirrors, smooth dielectrics, ``plastic``, ``null``)
    cannot be hit by a sampled direction: every strategy uses their own sampling."""
    return mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta)


def _plain(value):
    """(Nested) NamedTuples as plain tuples of Dr.Jit arrays."""
    if isinstance(value, DirectionSample):
        return (mi.Vector3f(value.wo), mi.Float(value.pdf), mi.Spectrum(value.weight),
                mi.Bool(value.delta), mi.Float(value.eta), mi.Bool(value.null))
    return tuple(_plain(v) for v in value) if isinstance(value, tuple) else value


def _rebuild(result_type, out):
    if result_type is VertexSample:
        return VertexSample(DirectionSample(*out[0]), *out[1:])
    return out if result_type is None else result_type(*out)


def _at_vertex(result_type, method, fallback, strategy, bsdf, *args):
    """``method(bsdf, *args)`` (a method of ``strategy``) at the BSDF ``bsdf``.

    Strategies with ``dispatch`` (see :class:`~.strategies.Strategy`) are called per BSDF
    instance, in one ``dr.dispatch`` over a ``mi.BSDFPtr``, and BSDFs with a delta lobe
    get ``fallback`` (the same method of the BSDF's own sampling) instead. The others
    get ``bsdf`` as it is. Dr.Jit 1.5's ``dr.dispatch`` does not traverse NamedTuples
    (it compares the results of the BSDFs as opaque objects and fails), so the results
    cross it as plain nested tuples and are rebuilt as ``result_type``.
    """
    if not strategy.dispatch:
        return method(bsdf, *args)

    def per_instance(b, *a):
        return (fallback if _has_delta_lobe(b) else method)(b, *a)

    if not isinstance(bsdf, mi.BSDFPtr):
        return per_instance(bsdf, *args)
    out = dr.dispatch(bsdf, lambda b, *a: _plain(per_instance(b, *a)), *args)
    return _rebuild(result_type, out)


def sample_direction(strategy, bsdf, ctx, si, sample1, sample2,
                     active=True) -> DirectionSample:
    """Next direction of ``strategy`` (a registered name or a
    :class:`~.strategies.Strategy`) at the vertex ``si`` with BSDF ``bsdf``.

    ``bsdf``: a ``mi.BSDFPtr`` (one dispatch over the BSDFs) or one BSDF. A name
    registered with a factory gets a new strategy object at each call: pass the object
    to keep its state.
    """
    s = strategies.resolve(strategy)
    return _at_vertex(DirectionSample, s.sample, strategies.bsdf.sample, s, bsdf, ctx, si,
                      sample1, sample2, mi.Bool(active))


def sample_direction_and_eval(strategy, bsdf, ctx, si, sample1, sample2, wo_em,
                              active=True) -> VertexSample:
    """:func:`sample_direction`, and at ``wo_em`` (a local direction, e.g. of an
    emitter sample) the BSDF value and the strategy's density (for ``bsdf``: from the
    same BSDF call, ``eval_pdf_sample``)."""
    s = strategies.resolve(strategy)
    return _at_vertex(VertexSample, s.sample_and_eval, strategies.bsdf.sample_and_eval, s,
                      bsdf, ctx, si, sample1, sample2, wo_em, mi.Bool(active))


def direction_pdf(strategy, bsdf, ctx, si, wo, active=True):
    """Density with which ``strategy`` draws the local direction ``wo`` at ``si``
    (for BSDFs without a delta lobe; with one, the BSDF's own pdf)."""
    s = strategies.resolve(strategy)
    return _at_vertex(None, s.pdf, strategies.bsdf.pdf, s, bsdf, ctx, si, wo,
                      mi.Bool(active))


class VRPathIntegrator(mi.SamplingIntegrator):
    r"""
    .. _integrator-vr_path:

    Variance-reduction path tracer (:monosp:`vr_path`)
    --------------------------------------------------

    .. pluginparameters::

     * - strategy
       - |string|
       - How the next direction is drawn at every bounce: the name of a
         registered strategy (``integrators.strategies.names()``). Built in:
         ``uniform`` (uniform hemisphere, pdf :math:`1/2\pi`), ``cosine``
         (cosine-weighted hemisphere, pdf :math:`\cos\theta/\pi`), ``bsdf``
         (the BSDF's own importance sampling; for ``phong`` the Phong-lobe
         mixture) and ``mis`` (one-sample multiple importance sampling of
         ``cosine`` and ``bsdf``, see below); any name added with
         ``integrators.register_strategy`` (a
         :class:`~integrators.strategies.Strategy`; a name registered with a
         factory gives each ``vr_path`` its own strategy object). An unknown
         name is an error that lists the registered ones. (Default: ``bsdf``)

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
    Mitsuba's ``path``; for strategies that ask for it, the others, one
    ``dr.dispatch`` over the BSDF instances that draws the strategy's
    direction and evaluates it and the emitter sample's direction). Every
    bounce draws a direction with the chosen ``strategy`` and weights it by
    ``bsdf.eval / pdf`` (``eval`` includes the cosine). The strategies are
    objects (:mod:`integrators.strategies`: ``sample``, ``pdf`` and both for
    NEE); the direction sampling at a vertex is :func:`sample_direction` and
    its density :func:`direction_pdf`, callable outside the render loop with
    a strategy's name or object (the warp tests and the lab do).

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

    ``mis``, ``Mixture(cosine, bsdf, c)``, draws from the cosine strategy
    with probability :math:`c` = ``strategies.MIS_COSINE_WEIGHT`` = 0.25 and
    from the BSDF's own sampling otherwise, and weights every direction by
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
    sweep: see that study's section of the report (``results/index.html``).

    BSDFs with a Dirac delta lobe (mirrors, smooth dielectrics, ``plastic``,
    ``null``) cannot be hit by a sampled direction: at such vertices every
    strategy (registered ones too) falls back to the BSDF's own sampling, so
    those images stay correct. Without ``emitter_sampling`` delta emitters (point, spot,
    directional) are never reached; rendering such a scene warns. Participating
    media are not simulated: a scene with a medium is refused with an error
    that names it (use Mitsuba's ``volpath``). ``max_depth`` 0 renders black.

    Sample dimensions per bounce: 2 for the emitter sample (only with
    ``emitter_sampling``), 1 + 2 for the direction (``uniform`` and ``cosine``
    use the 1D sample only to pick a side for transmitting BSDFs; a mixture
    such as ``mis`` uses it to pick the technique and, rescaled, inside the
    technique; a registered strategy gets the same 1 + 2), 1 for Russian
    roulette.

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

    def make_strategy(self, name: str, props: mi.Properties):
        """The strategy object of the registered ``name`` (:func:`strategies.get`); a
        subclass may make its own from its ``props``."""
        return strategies.get(name)

    def __init__(self, props: mi.Properties):
        mi.SamplingIntegrator.__init__(self, props)
        #: The strategy's registered name, and the strategy object it names (for a name
        #: registered with a factory, this instance's own; see integrators.strategies).
        self.strategy = props.get("strategy", "bsdf")
        try:
            self.sampling_strategy = self.make_strategy(self.strategy, props)
        except strategies.UnknownStrategyError as error:
            raise ValueError(f"vr_path: {error}") from None

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
        """One path per lane: the symbolic loop body, traced once into one megakernel.

        long: one function, as Mitsuba's ``prb.py`` writes it: the loop state is declared up
        front and every vertex's steps (emission found, NEE, the next direction, roulette)
        read and update it in order; split into methods, each would take and return most
        of that state. A learning subclass's hooks run inside: its recorder
        (:meth:`_recorder`) gets the drawn direction sample and its roulette
        (:meth:`_roulette`) what the strategy drew, which that sample carries
        (``direction.guide``).
        """
        self._check_scene(scene)
        if dr.hint(self.max_depth == 0, mode='scalar'):
            return mi.Spectrum(0.0), mi.Bool(False), self._aovs(mi.UInt32(0), mi.UInt32(0))
        ctx = mi.BSDFContext()
        max_depth = mi.UInt32(0xFFFFFFFF if self.max_depth < 0 else self.max_depth)
        strategy = self.sampling_strategy
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
        recorder = self._recorder(scene, sampler, ray)   # learning integrators only
        record = recorder is not None
        roulette = self._roulette()             # None: the throughput rule below
        guided_rr = roulette is not None
        rr_reference = mi.Float(0.0)            # the roulette's estimate of the pixel

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
            emitted = beta * emitter.eval(si, visible) * w_dir
            L = dr.select(visible, L + emitted, L)
            if dr.hint(record & nee, mode='scalar'):
                # light that the previous vertex's NEE samples too (MIS): not learned
                recorder.emitted(depth, emitted, visible & ~prev_delta)

            active_next = on & si.is_valid() & (depth + 1 < max_depth)
            bsdf = si.bsdf(ray)
            flags = bsdf.flags()

            L_arrived = L                       # before this vertex's NEE (recorder)

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
                vertex = sample_direction_and_eval(strategy, bsdf, ctx, si, sample1, sample2,
                                                   si.to_local(ds_em.d), active_next)
                direction = vertex.direction
                w_em = dr.select(ds_em.delta, 1.0,
                                 warps.power_heuristic(ds_em.pdf, vertex.em_pdf))
                L = dr.select(active_em, L + beta * vertex.em_value * em_weight * w_em, L)
            else:
                sample1 = sampler.next_1d(active_next)
                sample2 = sampler.next_2d(active_next)
                direction = sample_direction(strategy, bsdf, ctx, si, sample1, sample2,
                                             active_next)

            # ------------------------------------------------ next direction
            if dr.hint(record, mode='scalar'):
                recorder.vertex(depth, si, direction, L, L_arrived, beta, active_next)
            survival = mi.Float(0.0)
            if dr.hint(guided_rr, mode='scalar'):
                survival, rr_reference = roulette.survival(depth, direction.guide, beta,
                                                           rr_reference, active_next)
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
            if dr.hint(guided_rr, mode='scalar'):
                rr_prob = dr.select(survival > 0, survival, rr_prob)
            rr_continue = sampler.next_1d(active_next) < rr_prob
            beta[rr_active] *= dr.rcp(dr.maximum(rr_prob, warps.PDF_EPSILON))
            active = skip | (active_next & (~rr_active | rr_continue) & (beta_max > 0)
                             & (direction.pdf > 0))

        if dr.hint(record, mode='scalar'):
            recorder.finish(L, valid_ray, segments, shadow_rays)
        result = dr.select(valid_ray, L, 0.0)
        return result, valid_ray, self._aovs(segments, shadow_rays, result)

    def _recorder(self, scene, sampler, ray):
        """What records the path's vertices for a learning subclass
        (``vertex(depth, si, direction, L, L_arrived, beta, active)`` after a direction is
        drawn, with its :class:`~.strategies.DirectionSample`; ``emitted`` with the
        emission a direction found; ``finish`` with the path's radiance); None here."""
        return None

    def _roulette(self):
        """What sets the Russian roulette's survival probability for a learning subclass
        (``survival(depth, direction.guide, beta, reference, active)`` before the
        direction's weight is applied, with what the strategy drew at the vertex: a
        probability, or 0 for the throughput rule, and the pixel estimate carried along
        the path); None here (the throughput rule)."""
        return None

    def _aovs(self, segments, shadow_rays, result=None):
        return [mi.Float(segments), mi.Float(shadow_rays)] if self.count_segments else []

    def aov_names(self):
        return ["segments", "shadow_rays"] if self.count_segments else []

    def to_string(self):
        return (f"VRPathIntegrator[strategy={self.strategy}, max_depth={self.max_depth}, "
                f"rr_depth={self.rr_depth}, emitter_sampling={self.emitter_sampling}, "
                f"hide_emitters={self.hide_emitters}]")


mi.register_integrator("vr_path", VRPathIntegrator)  # the class of this variant, bound now
