"""The ``vr_guided_path`` integrator: ``vr_path`` that trains the ``guided`` strategy.

:class:`GuidedPathIntegrator` is ``vr_path`` (:mod:`.path`) with the guide's recorder
(:mod:`.guide_record`) and roulette (:mod:`.guide_roulette`) in its loop and the
executor's multi-pass hooks (``pass_schedule``, ``after_pass``, ``combine``): training
iterations of doubling samples, each split into renders of at most ``max_pass_spp``, the
guide (:mod:`.guided`) refined after each iteration but the last, every iteration's image
combined with inverse-variance weights. The schedule, the stop rule and the weights are
pure functions (:mod:`.guide_passes`); this class keeps a job's state between its passes.
"""
from __future__ import annotations

import functools
import warnings

import drjit as dr
import mitsuba as mi
import numpy as np

from . import guide_passes, guide_quadtree, guide_record, moments, strategies
from .guide_record import Recorder
from .guide_roulette import Roulette
from .guided import GuidedStrategy
from .path import VRPathIntegrator, seed_value
from .sequence_sampler import SequenceSampler

#: The values of the ``roulette`` parameter.
ROULETTES = ("adjoint", "throughput")
#: The AOVs of each sample's squared radiance per channel (the passes' per-pixel variances:
#: their weights, and the variance of the combined image).
M2_AOVS = ("guiding_m2_r", "guiding_m2_g", "guiding_m2_b")
#: Then those of their cubes and fourth powers (how sure each pass's variances are), in
#: the order of :func:`.moments.powers`.
MOMENT_AOVS = M2_AOVS + tuple(f"guiding_m{k}_{c}" for k in (3, 4) for c in "rgb")
#: Samplers that compile the sample count into the kernel: each pass would recompile.
BAKES_SPP = {"StratifiedSampler": "stratified", "MultijitterSampler": "multijitter",
             "OrthogonalSampler": "orthogonal", "LowDiscrepancySampler": "ldsampler"}


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

     * - directional_split
       - |float|
       - Fit PPG's adaptive quadtree to each histogram (:mod:`.guide_quadtree`): a node
         of the (cos theta, phi) square splits where it holds more than this share of
         the unit's energy, a leaf's bins share its energy; 0 keeps every bin. Needs a
         power-of-two ``directional_resolution``. At the records a suite job has, the
         finer models lose to 16 x 16 raw bins (docs/guiding.md). (Default: 0)

     * - max_leaves
       - |int|
       - Most leaves of the spatial tree (its tables are this size), 1 to 65536.
         (Default: 1024)

     * - spatial_threshold
       - |float|
       - A leaf splits after an iteration in which it received more than
         ``spatial_threshold * sqrt(2^k)`` records (k the iteration). (Default: 1000)

     * - record_depth
       - |int|
       - Vertices per path that record (the first ones), 1 to 32. (Default: 4)

     * - max_pass_spp
       - |int|
       - Most samples per pixel of one render of an iteration that records: one above it
         is split into several renders (records cost 56 bytes x record_depth per sample, at
         most 256 MiB per render: on a larger film a render takes fewer, down to 1). The
         last iteration, and the rest of a job whose training stopped, are one render
         each. (Default: 64)

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
    ``emitter_sampling``). One ``mi.render`` call trains and renders the whole job in its
    own passes, from a new guide (nothing an earlier call learned carries over), and
    returns the combined RGB image (nested in Mitsuba's ``aov``, which calls it, the
    image too). Nested in an integrator that calls its ``sample`` and not its ``render``
    (Mitsuba's ``moment``), it cannot train: it renders plain BSDF sampling (``vr_path``'s
    bsdf strategy) and warns. See docs/guiding.md for the method, its
    costs and when it loses.
    Samplers that compile the sample count into the kernel (stratified, multijitter,
    orthogonal, ldsampler) are refused: every pass would recompile.
    """


    def make_strategy(self, name: str, props: mi.Properties):
        """The guide this integrator trains, of its ``directional_resolution`` and
        ``max_leaves`` (where ``name`` is a strategy that learns; another is refused in
        ``__init__``), made once: the registry's own would be thrown away."""
        if strategies.integrator_type(name) != "vr_guided_path":
            return strategies.get(name)
        res = _number(props, "directional_resolution", 16, 2, 64)
        split = _number(props, "directional_split", 0.0, 0.0, 1.0, float)
        if split > 0:
            try:
                guide_quadtree.levels(res)
            except ValueError:
                raise ValueError(f"vr_guided_path: 'directional_split' {split} needs a "
                                 f"power-of-two 'directional_resolution' (2, 4, 8, 16, 32 "
                                 f"or 64), got {res}") from None
        return GuidedStrategy(res, _number(props, "max_leaves", 1024, 1, 65536), split)

    def __init__(self, props: mi.Properties):
        if "strategy" not in props:
            props["strategy"] = "guided"
        VRPathIntegrator.__init__(self, props)
        # by the attribute, not the class: the strategy registry outlives a variant switch,
        # which defines the strategy's class anew
        if getattr(self.sampling_strategy, "integrator_type", None) != "vr_guided_path":
            raise ValueError(f"vr_guided_path: 'strategy' must be a strategy that learns "
                             f"(guided), got {self.strategy!r}")

        number = functools.partial(_number, props)
        # None: learned per unit (sdtree.SDTree.choose_shares)
        self.bsdf_fraction = (number("bsdf_fraction", 0.5, 0.1, 1.0, float)
                              if "bsdf_fraction" in props else None)
        self.spatial_threshold = number("spatial_threshold", 1000.0, 1.0, 1e12, float)
        self.record_depth = number("record_depth", 4, 1, 32)
        self.max_pass_spp = number("max_pass_spp", 64, 1, 1 << 20)
        self.first_pass_spp = number("first_pass_spp", 2, 2, 1 << 20)
        self.min_train_spp = number("min_train_spp", guide_passes.MIN_TRAIN_SPP, 2, 1 << 30)
        self.min_train_samples = number("min_train_samples", guide_passes.MIN_TRAIN_SAMPLES,
                                        1, 1 << 40)
        self.roulette = props.get("roulette", "adjoint")
        if self.roulette not in ROULETTES:
            raise ValueError(f"vr_guided_path: 'roulette' must be one of "
                             f"{', '.join(ROULETTES)}, got {self.roulette!r}")
        #: The strategy this integrator trains (``sampling_strategy`` while it is in use).
        self.guide = self.sampling_strategy
        #: Whether the next renders record (:meth:`_set_recording`).
        self.recording = False
        self._set_recording(True)
        # A job's state between its passes, made anew by pass_schedule:
        self._iterations = []   # samples per pixel of each training iteration
        self._passes = []       # (iteration, samples per pixel) of each render
        self._estimator = []    # per iteration: -1 plain BSDF sampling, else the
                                # iteration whose refinement rendered it
        self._raw, self._spp = [], []   # per render done: its image (every channel: the
                                        # moments' AOVs too, :meth:`_moments`), its samples
        self._groups = []       # the renders pooled per estimator (:meth:`combine`)
        self._stopped = False   # training stopped (or never started): vr_path's kernel
        #: Per refinement, the predicted gain of its shares (None: nothing measured).
        self.gains = []
        #: The weights of :meth:`combine`'s groups, and the combined image's variance.
        self.weights, self.variance = None, None
        #: A driver renders the passes, one ``mi.render`` call each, between
        #: :meth:`pass_schedule` and :meth:`combine` (else :meth:`render` drives them).
        self._driven = False
        #: Inside this integrator's own :meth:`render` (else another integrator calls its
        #: ``sample``: :meth:`_nested`).
        self._rendering = False

    # ------------------------------------------------------------------- render side

    def _recorder(self, scene, sampler, ray):
        name = str(sampler).split("[")[0].strip()
        if name in BAKES_SPP:
            raise ValueError(
                f"vr_guided_path: the sampler '{BAKES_SPP[name]}' compiles the sample count "
                f"into the kernel, so every training pass would recompile; valid choices: "
                f"independent or a sampler that does not (halton, zsobol), not "
                f"{', '.join(BAKES_SPP.values())}")
        if not self._rendering:
            self._nested()
            return None
        tree = self.guide.tree
        if not tree.has_bbox:
            tree.set_bbox(scene.bbox())
        if not self.recording:      # a kernel without records (compiled once, cached)
            return None
        return Recorder(tree, dr.width(ray.o), self.record_depth, self.guide.recording)

    def _nested(self) -> None:
        """Another integrator calls this one's ``sample`` outside its ``render``: no passes
        of its own, so nothing to learn from. That call renders plain BSDF sampling
        (``vr_path``'s bsdf strategy, roulette and kernel) and records nothing. Where no job
        of its own has rendered (Mitsuba's ``moment`` nesting it: its whole image is
        untrained) it says so; Mitsuba's ``aov`` renders the nested integrator's own job
        for the image and calls ``sample`` for the AOVs alone."""
        if not self._iterations:
            warnings.warn("vr_guided_path: called by another integrator (its sample(), not "
                          "its own render), it cannot train: plain BSDF sampling (vr_path's "
                          "bsdf strategy). The guide learns in the passes of its own "
                          "mi.render: make it the scene's integrator to guide", stacklevel=3)
        self._set_recording(False)
        self._stopped = True
        self.sampling_strategy = strategies.get("bsdf")

    def _roulette(self):
        """The guided roulette while the guide is in use (``roulette`` adjoint), else None
        (vr_path's throughput rule; after training stops the kernel is vr_path's own)."""
        if self.roulette != "adjoint" or self._stopped:
            return None
        return Roulette(self.guide.tree)

    def _set_recording(self, on: bool) -> None:
        """Whether the next renders record: a host switch (the render kernel without
        records is another kernel, compiled once) mirrored in the strategy's opaque flag
        (it evaluates the guide's density everywhere while recording)."""
        self.recording = bool(on)
        self.guide.set_recording(on)

    def _aovs(self, segments, shadow_rays, result=None):
        return VRPathIntegrator._aovs(self, segments, shadow_rays) + \
            moments.powers(mi.Color3f(0.0) if result is None else result)

    def aov_names(self):
        return VRPathIntegrator.aov_names(self) + list(MOMENT_AOVS)

    # ------------------------------------------------------------------ multi-pass

    def pass_schedule(self, spp: int, pixels: int) -> list:
        """Iterations of doubling samples (:func:`.guide_passes.iterations`), each split
        into renders of at most ``max_pass_spp`` (:func:`.guide_passes.renders`): a
        function of ``spp`` and the film's ``pixels`` alone; one iteration without
        training below ``min_train_spp`` or ``min_train_samples``. Starts the job's state
        anew, the guide too (:meth:`.guided.GuidedStrategy.reset`): a second job of this
        integrator, of this scene or another, learns from its own samples alone."""
        self.guide.reset()
        small = guide_passes.training_refusals(spp, pixels, self.min_train_spp,
                                               self.min_train_samples)
        if small:
            warnings.warn(f"vr_guided_path: {' and '.join(small)}: no training, plain BSDF "
                          f"sampling (vr_path's bsdf strategy)", stacklevel=2)
        self._iterations = guide_passes.iterations(spp, self.first_pass_spp) \
            if not small else [spp]
        most = min(self.max_pass_spp,
                   max(1, guide_record.most_spp(pixels, self.record_depth)))
        self._passes = guide_passes.renders(self._iterations, most, not small)
        self._raw, self._spp, self.gains, self._groups = [], [], [], []
        self.weights, self.variance = None, None
        self._estimator = [-1] * len(self._iterations)
        trains = len(self._iterations) > 1       # one iteration has nothing to learn for
        self._set_recording(trains)
        # without training: vr_path's own bsdf strategy and roulette (its kernel)
        self._stopped = not trains
        self.sampling_strategy = self.guide if trains else strategies.get("bsdf")
        self._driven = True
        return [n for _, n in self._passes]

    def after_pass(self, index: int, image, spp: int) -> list | None:
        """Keep the pass's image (its moments' AOVs with it); after an iteration's last
        render (not the last iteration's), refine the guide from its records
        (:meth:`_refine`). Where training stops there, the renders left are one render of
        all their samples (:func:`.guide_passes.merged_rest`), returned as the new rest of
        the schedule (None: the schedule stands)."""
        self._raw.append(np.asarray(image, dtype=np.float64))
        self._spp.append(spp)
        k = self._passes[index][0]
        last_of_iteration = index + 1 == len(self._passes) or self._passes[index + 1][0] != k
        if not last_of_iteration or k + 1 == len(self._iterations):
            return None
        if self._stopped:
            self._estimator[k + 1] = self._estimator[k]
            return None
        self._refine(k)
        self._estimator[k + 1] = -1 if np.all(self.guide.tree.share == 1.0) else k
        if k + 2 == len(self._iterations):     # the last iteration only renders
            self._set_recording(False)
        if not self._stopped:
            return None
        self._passes = guide_passes.merged_rest(self._passes, index)
        self._iterations = self._iterations[:k + 1] + [sum(self._iterations[k + 1:])]
        self._estimator = self._estimator[:k + 2]
        return [n for _, n in self._passes[index + 1:]]

    def _refine(self, k: int) -> None:
        """Refine the guide from iteration ``k``'s records, predict the new shares' gain
        and stop training where the rule says (:func:`.guide_passes.stops`)."""
        tree = self.guide.tree
        tree.refine(self.spatial_threshold * np.sqrt(2.0 ** k), self.bsdf_fraction)
        idx = [i for i, (it, _) in enumerate(self._passes) if it == k]
        gain = guide_passes.predicted_gain(
            tree.moment_sums, *guide_passes.pixel_moments(self._moments(0), self._moments(1),
                                                          self._spp, idx))
        # no unit learned anything (every record dark: all its light found by NEE): the
        # guide is the BSDF's own sampling, no gain
        self.gains.append(1.0 if gain is None and not tree.learned.any() else gain)
        if self.bsdf_fraction is None and guide_passes.stops(self.gains, k):
            # guiding does not help anywhere: plain BSDF sampling, no more training; the
            # rest renders with vr_path's own bsdf strategy (its kernel: the same estimator
            # as every share 1, without the guide's lookups and dispatch)
            tree.share[:] = 1.0
            self._stopped = True
            self._set_recording(False)
            self.sampling_strategy = strategies.get("bsdf")
        self.guide.set_share(tree.share)

    def combine(self, images: list, spps: list):
        """The iterations' images, weighted by :func:`.guide_passes.cross_weights` (inverse
        to each group's variance, read from the other pixels of a checkerboard: a weight
        read from the samples it weights would bias the image low); iterations rendered
        by the same estimator (plain BSDF sampling before a unit
        learns and after training stops; the frozen guide after it stops) are pooled
        first, by their samples (:func:`.guide_passes.combine`): weights estimated per
        identical iteration would only add noise (and, with rare bright samples, favour
        the iterations that missed them)."""
        groups = [[i for i, (it, _) in enumerate(self._passes)
                   if self._estimator[it] == e and i < len(images)]
                  for e in dict.fromkeys(self._estimator)]
        # one estimator (the job did not train, or learned nothing): its pooled image, no
        # mean squares read
        m2s = self._moments(1) if len(groups) > 1 else [None] * len(images)
        image, self.weights = guide_passes.weighted(images, m2s, spps, groups)
        self._groups, self.variance = groups, None
        self._driven = False
        return image

    def combined_variance(self) -> np.ndarray:
        """Per pixel and channel, the variance of the image :meth:`combine` returned: the
        sum over its groups of weight^2 x the variance of the group's mean (from its
        samples' mean squares, the ``guiding_m2_*`` AOVs), the weights taken as fixed
        (each pixel's are read from other pixels' samples). The experiments' per-pixel
        errors use it for this method (:func:`experiments.lib.execute.render_passes`):
        the spread of its passes would treat the untrained and the trained ones as one
        estimator. Measurement, not the method's work: computed when asked for, so that a
        plain ``mi.render`` and the clock (:mod:`experiments.lib.execute` times
        :meth:`combine` alone) do not pay for it."""
        if self.variance is None:
            self.variance = guide_passes.weighted_variance(
                self._moments(0), self._moments(1), self._spp, self._groups, self.weights)
        return self.variance

    def combined_moments(self) -> list:
        """Per group of :meth:`combine` (the renders of one estimator): (its weight per
        pixel, its samples per pixel, and per pixel and channel the means of its samples,
        of their squares, cubes and fourth powers), from which the experiments bound how sure
        :meth:`combined_variance` is (the sum over groups of weight^4 x the variance of
        the group's variance, :func:`experiments.lib.jobs.variance_of_variance`)."""
        out = []
        for w, idx in zip(self.weights, self._groups):
            n = sum(self._spp[i] for i in idx)
            pooled = [sum(a[i] * self._spp[i] for i in idx) / n
                      for a in map(self._moments, range(4))]
            out.append((w, n, *pooled))
        return out

    def _moments(self, power: int) -> list:
        """Per render done, the per-pixel mean of its samples' radiance to the power
        ``power`` + 1 (0: its image, 1: its mean squares, then cubes and fourth powers),
        RGB: views of the images :meth:`after_pass` kept."""
        if power == 0:
            return [image[..., :3] for image in self._raw]
        at = -len(MOMENT_AOVS) + 3 * (power - 1)
        return [image[..., at:at + 3 if at + 3 < 0 else None] for image in self._raw]

    # ------------------------------------------------------------ one mi.render call

    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        """``mi.render`` with this integrator: the whole job, trained, in its own passes
        (:meth:`_render_job`); the combined RGB image (H, W, 3). Between a driver's
        :meth:`pass_schedule` and :meth:`combine` (the experiments' executor), each call
        renders one pass, its image with the moment AOVs."""
        self._rendering = True
        try:
            if self._driven or not develop:
                return super().render(scene, sensor, seed, spp, develop, evaluate)
            return self._render_job(scene, sensor, seed, spp)
        finally:
            self._rendering = False

    def _render_job(self, scene, sensor, seed: int, spp: int) -> mi.TensorXf:
        """Every pass of :meth:`pass_schedule` with :meth:`after_pass` between them, then
        :meth:`combine`, as the executor drives them: a sampler of the project that takes
        a sequence per pixel (``halton``, ``zsobol``) continues it from pass to pass (its
        ``sample_offset``, restored after), any other is reseeded per pass."""
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        sampler = sensor.sampler()
        spp = spp or sampler.sample_count()
        size = sensor.film().crop_size()
        schedule = self.pass_schedule(spp, int(size.x) * int(size.y))
        sequence = isinstance(sampler, SequenceSampler)
        kept = {n: getattr(sampler, n) for n in ("sample_offset", "sequence_length")
                if sequence and hasattr(sampler, n)}
        images, spps = [], []
        try:
            while len(images) < len(schedule):
                i, k = len(images), schedule[len(images)]
                if sequence:
                    sampler.sample_offset = kept["sample_offset"] + sum(spps)
                    if "sequence_length" in kept:
                        sampler.sequence_length = kept["sample_offset"] + spp
                image = np.array(super().render(scene, sensor, seed if sequence else
                                                _pass_seed(seed, i), k), dtype=np.float64)
                rest = self.after_pass(i, image, k)
                schedule = schedule if rest is None else schedule[:i + 1] + list(rest)
                images.append(image[..., :3])
                spps.append(k)
            image = self.combine(images, spps)
        finally:
            self._driven = False
            for name, value in kept.items():
                setattr(sampler, name, value)
        return mi.TensorXf(np.ascontiguousarray(image, dtype=np.float32))

    def to_string(self):
        return (f"GuidedPathIntegrator[{VRPathIntegrator.to_string(self)}, "
                f"bsdf_fraction={self.bsdf_fraction}, leaves={self.guide.tree.leaves}]")


def _pass_seed(seed: int, index: int) -> int:
    """The seed of pass ``index`` of a job seeded ``seed`` (a stream of its own per pass)."""
    return (seed_value(seed) * 0x9E3779B1 + (index + 1) * 0x85EBCA77) & 0xFFFFFFFF


mi.register_integrator("vr_guided_path", GuidedPathIntegrator)
