"""The ``halton`` sampler: randomized Halton sequences (state only; maths in :mod:`.qmc`)."""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import qmc


class HaltonSampler(mi.Sampler):
    r"""
    .. _sampler-halton:

    Halton sampler (:monosp:`halton`)
    ---------------------------------

    .. pluginparameters::

     * - sample_count
       - |int|
       - Number of samples per pixel; must be > 0. (Default: 4)

     * - seed
       - |int|
       - Seed offset of the scrambling: ``seed(s)`` (e.g. by
         ``mi.render(scene, seed=s)``) scrambles with ``seed + s``, as
         Mitsuba's own samplers do. (Default: 0)

     * - randomization
       - |string|
       - How the sequence is randomized, as pbrt-v4's ``RandomizeStrategy``:
         ``none`` (the plain Halton sequence, identical in every pixel),
         ``permute_digits`` (a random permutation per dimension and digit,
         drawn per pixel) or ``owen`` (nested Owen scrambling, per pixel).
         (Default: ``owen``)

     * - sample_offset
       - |int|
       - Index of the first sample of each pixel: a render takes the Halton
         points ``sample_offset .. sample_offset + spp - 1``. Also settable
         between renders (attribute ``sample_offset`` or
         ``mi.traverse(scene)['<sensor>.sampler.sample_offset']``) without
         recompiling, to continue a sequence over several passes.
         (Default: 0)

    Sample ``i`` of a pixel is the point :math:`(\Phi_2(i), \Phi_3(i),
    \Phi_5(i), \ldots)` of the Halton sequence: dimension ``j`` (the
    ``j``-th value drawn by ``next_1d``/``next_2d`` since the last
    ``seed``/``advance``) is the radical inverse in the ``j``-th prime base,
    randomized as chosen (see :mod:`integrators.qmc`). The table holds 1000
    primes; dimension ``j >= 1000`` wraps around to base ``PRIMES[j % 1000]``
    as in pbrt (with ``none`` it repeats dimension ``j - 1000`` exactly; the
    scrambled variants use a new scramble per unwrapped dimension), so paths
    of any depth get valid samples in [0, 1). Sample indices must stay below
    2^31.

    Pixels are decorrelated by a per-pixel scramble seed (a hash of the seed
    and the pixel index), so neighbouring pixels get independent
    randomizations of the same well-stratified point set. ``none`` has no
    randomization: every pixel uses the same points, as in the writeup, and
    the image is deterministic (the seed is ignored).

    All state (sample index, dimension index, per-pixel seed) lives in Dr.Jit
    arrays, so the sampler advances correctly inside symbolic loops
    (``vr_path``, Mitsuba's ``path`` and any other integrator), and the seed
    and ``sample_offset`` are opaque, so reseeding does not recompile the
    render kernel.

    Wavefront layout: in a JIT render the wavefront has ``width * height * k``
    lanes, lane ``l`` being sample ``l % k`` of pixel ``l // k``, where ``k``
    is the number of samples per pixel of one pass. A caller that renders in
    passes declares ``k`` with ``set_samples_per_wavefront(k)`` before
    ``seed()``; it applies to that seeding only (the next ``seed`` starts
    over). Without it, ``seed(seed, wavefront_size)`` takes ``k =
    sample_count`` (one pass, Mitsuba's ``mi.render``) when ``sample_count``
    divides ``wavefront_size``, and one sample per lane otherwise.

    Multi-pass renders: when an integrator has ``samples_per_pass`` (or a
    single render exceeds 2^32 samples), Mitsuba's C++ render loop declares
    ``k`` through a C++ call that a Python sampler never sees, and calls
    ``advance()`` between the passes. The sampler cannot know ``k`` there, so
    ``advance()`` after a seeding whose layout was not declared raises a
    ``RuntimeError`` (the render stops before any pass is evaluated) instead
    of continuing with wrong sample indices. Render in one pass per
    ``mi.render`` call instead, and continue the sequence over calls with
    ``sample_offset`` (below).

    Sample counts: powers of two stratify dimension 0 fully, powers of three
    dimension 1; counts with both factors (72 = 2^3 3^2) stratify the pair
    into 2^a x 3^b boxes, so 81 or 72 spp can be more efficient than 64
    (measured efficiencies: docs/benchmarks.md).

    Progressive rendering: to render ``N`` samples in passes of ``k_1, k_2,
    ...`` samples, keep the seed fixed and set ``sample_offset`` to the
    number of samples already taken before each pass::

        sampler = scene.sensors()[0].sampler()
        done = 0
        for k in (1, 1, 2, 4):
            sampler.sample_offset = done
            img_k = mi.render(scene, seed=seed, spp=k)
            done += k
        # the pass images, weighted by k / N, average to one N-sample render

    Reseeding instead (new ``seed`` per pass, offset 0) makes the passes
    independent randomizations whose errors only average out as 1/passes.

    .. tabs::

        .. code-tab:: xml

            <sampler type="halton">
                <integer name="sample_count" value="64"/>
                <string name="randomization" value="owen"/>
            </sampler>

        .. code-tab:: python

            'type': 'halton',
            'sample_count': 64,
            'randomization': 'owen'
    """

    def __init__(self, props: mi.Properties):
        sample_count = props.get("sample_count", 4)
        self._check_sample_count(sample_count)
        randomization = props.get("randomization", "owen")
        if randomization not in qmc.RANDOMIZATIONS:
            raise ValueError(f"halton: unknown randomization {randomization!r}; "
                             f"valid choices are {', '.join(qmc.RANDOMIZATIONS)}")
        seed = props.get("seed", 0)
        if not isinstance(seed, int) or not 0 <= seed < 2**32:
            raise ValueError(f"halton: 'seed' must be an integer in [0, 2^32), got {seed!r}")
        offset = props.get("sample_offset", 0)
        mi.Sampler.__init__(self, props)
        self.randomization = randomization
        self.base_seed = seed
        #: Samples per pixel per pass declared for the next seed() (0: none).
        self._declared_spw = 0
        self.sample_offset = offset
        self._reset_state(mi.UInt32(seed), 1, 1, declared=False)

    # ------------------------------------------------------------ parameters

    @staticmethod
    def _check_sample_count(spp) -> None:
        if not isinstance(spp, int) or isinstance(spp, bool) or spp <= 0:
            raise ValueError(f"halton: 'sample_count' must be an integer > 0, got {spp!r}")

    @property
    def sample_offset(self) -> int:
        """Halton index of each pixel's first sample (see the class docs)."""
        return int(dr.slice(self._sample_offset, 0))

    @sample_offset.setter
    def sample_offset(self, value) -> None:
        value = int(value if not isinstance(value, dr.ArrayBase) else dr.slice(value, 0))
        if not 0 <= value <= qmc.MAX_INDEX:
            raise ValueError(f"halton: 'sample_offset' must lie in [0, 2^31), got {value}")
        self._sample_offset = dr.opaque(mi.UInt32, value)

    def set_sample_count(self, spp: int) -> None:
        self._check_sample_count(spp)
        mi.Sampler.set_sample_count(self, spp)

    def set_samples_per_wavefront(self, samples_per_wavefront: int) -> None:
        if samples_per_wavefront <= 0:
            raise ValueError(f"halton: samples per wavefront must be > 0, got "
                             f"{samples_per_wavefront}")
        mi.Sampler.set_samples_per_wavefront(self, samples_per_wavefront)
        self._declared_spw = samples_per_wavefront       # for the next seed() only

    def traverse(self, callback):
        callback.put("sample_offset", self._sample_offset, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=[]):
        self.sample_offset = self._sample_offset

    # ----------------------------------------------------------------- state

    def _reset_state(self, seed, wavefront_size: int, samples_per_wavefront: int,
                     declared: bool) -> None:
        lanes = dr.arange(mi.UInt32, wavefront_size)
        spw = dr.opaque(mi.UInt32, samples_per_wavefront)
        pixel = lanes // spw
        #: Sample of this lane within its pixel's samples of one pass.
        self._lane_sample = lanes - pixel * spw
        #: Per-pixel scramble seed.
        self._pixel_seed = qmc.pixel_seed(seed, pixel)
        #: Passes (``advance`` calls) since the last seed, times samples per wavefront.
        self._pass_offset = dr.opaque(mi.UInt32, 0)
        #: Next dimension to be drawn (one per lane).
        self._dimension = dr.zeros(mi.UInt32, wavefront_size)
        self._spw = samples_per_wavefront
        #: Whether a caller declared the layout (set_samples_per_wavefront before seed).
        self._declared = declared

    def seed(self, seed, wavefront_size: int = 0xFFFFFFFF) -> None:
        # Read before the base call: nanobind may dispatch it back into this
        # override once (nested), which must see the same declaration.
        declared_spw = self._declared_spw
        mi.Sampler.seed(self, seed, wavefront_size)
        if isinstance(seed, int):
            seed = dr.opaque(mi.UInt32, (seed + self.base_seed) & 0xFFFFFFFF)
        else:
            seed = mi.UInt32(seed) + self.base_seed
            dr.make_opaque(seed)
        wavefront_size = self.wavefront_size()
        spp = self.sample_count()
        declared = declared_spw > 0
        if declared:
            spw = declared_spw
        else:
            # one JIT render pass (width * height * spp lanes), else a sequence per lane
            spw = spp if wavefront_size % spp == 0 else 1
        self._reset_state(seed, wavefront_size, spw, declared)
        self._declared_spw = 0                   # the declaration is for this seeding only

    def advance(self) -> None:
        if not self._declared:
            raise RuntimeError(
                "halton: advance() after a seed() whose samples per pixel per pass were not "
                "declared. Mitsuba calls it when it renders in several passes (an integrator "
                "with 'samples_per_pass', or more than 2^32 samples in one render), and it does "
                "not tell a Python sampler how many samples each pass takes, so the Halton "
                "sample indices would be wrong. Render without 'samples_per_pass' (at most "
                "2^32 samples per mi.render call) and, for more samples, render in passes of "
                "your own: keep the seed and set the sampler's 'sample_offset' to the samples "
                "already taken before each mi.render call. A caller that drives the sampler "
                "itself calls set_samples_per_wavefront(k) before seed().")
        self._pass_offset = self._pass_offset + self._spw
        dr.make_opaque(self._pass_offset)
        self._dimension = dr.zeros(mi.UInt32, dr.width(self._dimension))

    def schedule_state(self) -> None:
        dr.schedule(self._lane_sample, self._pixel_seed, self._pass_offset,
                    self._dimension, self._sample_offset)

    def current_sample_index(self) -> mi.UInt32:
        """Halton index of every lane's current sample."""
        return self._sample_offset + self._pass_offset + self._lane_sample

    # -------------------------------------------------------------- sampling

    def next_1d(self, active=True) -> mi.Float:
        value = qmc.halton_sample(self._dimension, self.current_sample_index(),
                                  self._pixel_seed, self.randomization)
        self._dimension += 1
        return value

    def next_2d(self, active=True) -> mi.Point2f:
        x = self.next_1d(active)
        y = self.next_1d(active)
        return mi.Point2f(x, y)

    # ------------------------------------------------------------ copy/fork

    def _properties(self) -> mi.Properties:
        props = mi.Properties("halton")
        props["sample_count"] = self.sample_count()
        props["seed"] = self.base_seed
        props["randomization"] = self.randomization
        props["sample_offset"] = self.sample_offset
        return props

    def fork(self) -> mi.Sampler:
        return type(self)(self._properties())  # this variant's class

    def clone(self) -> mi.Sampler:
        sampler = self.fork()
        if self.wavefront_size() > 1:
            mi.Sampler.seed(sampler, 0, self.wavefront_size())
        sampler._lane_sample = mi.UInt32(self._lane_sample)
        sampler._pixel_seed = mi.UInt32(self._pixel_seed)
        sampler._pass_offset = mi.UInt32(self._pass_offset)
        sampler._dimension = mi.UInt32(self._dimension)
        sampler._spw = self._spw
        sampler._declared = self._declared
        return sampler

    def to_string(self):
        return (f"HaltonSampler[sample_count={self.sample_count()}, seed={self.base_seed}, "
                f"randomization={self.randomization}, sample_offset={self.sample_offset}]")


mi.register_sampler("halton", HaltonSampler)  # the class of this variant, bound now
