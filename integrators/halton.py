"""The ``halton`` sampler: randomized Halton sequences (state in
:mod:`.sequence_sampler`, maths in :mod:`.qmc`)."""
from __future__ import annotations

import mitsuba as mi

from . import qmc
from .sequence_sampler import SequenceSampler


class HaltonSampler(SequenceSampler):
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

    Wavefront layout and multi-pass renders: as for every
    :class:`~integrators.sequence_sampler.SequenceSampler`, lane ``l`` of a render is
    sample ``l % k`` of pixel ``l // k``, ``k`` the samples per pixel of one pass: the
    sample count when it divides the lanes (one pass, Mitsuba's ``mi.render``), unless a
    caller that renders in passes declares ``k`` with ``set_samples_per_wavefront(k)``
    before ``seed()`` (for that seeding only). Mitsuba's own multi-pass renders (an
    integrator's ``samples_per_pass``, or more than 2^32 samples in one render) declare
    it through a C++ call a Python sampler never sees, so ``advance()`` after an
    undeclared seeding raises a ``RuntimeError`` (the render stops before any pass is
    evaluated) instead of continuing with wrong sample indices. Render in one pass per
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

    PLUGIN = "halton"
    PARAMETERS = ("randomization",)
    STATE = SequenceSampler.STATE + ("_pixel_seed",)

    def __init__(self, props: mi.Properties):
        self._check_sample_count(props.get("sample_count", 4))
        randomization = self._read_choice(props, "randomization", qmc.RANDOMIZATIONS, "owen")
        super().__init__(props, randomization=randomization)

    @staticmethod
    def _check_sample_count(spp) -> None:
        if not isinstance(spp, int) or isinstance(spp, bool) or spp <= 0:
            raise ValueError(f"halton: 'sample_count' must be an integer > 0, got {spp!r}")

    def set_sample_count(self, spp: int) -> None:
        self._check_sample_count(spp)
        mi.Sampler.set_sample_count(self, spp)

    def _seed_lanes(self, seed, pixel, wavefront_size: int) -> None:
        #: Per-pixel scramble seed.
        self._pixel_seed = qmc.pixel_seed(seed, pixel)

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


mi.register_sampler("halton", HaltonSampler)  # the class of this variant, bound now
