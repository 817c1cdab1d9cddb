"""The ``zsobol`` sampler: Owen-scrambled Sobol' points in Morton order across
pixels (state in :mod:`.sequence_sampler`, maths in :mod:`.qmc`)."""
from __future__ import annotations

import warnings

import drjit as dr
import mitsuba as mi

from . import qmc, qmc_sobol
from .sequence_sampler import SequenceSampler


def _round_up_pow2(n: int) -> int:
    return 1 << max(0, (n - 1).bit_length())


class ZSobolSampler(SequenceSampler):
    r"""
    .. _sampler-zsobol:

    Z-order Sobol' sampler (:monosp:`zsobol`)
    -----------------------------------------

    .. pluginparameters::

     * - sample_count
       - |int|
       - Number of samples per pixel; must be > 0. A count that is not a
         power of two is rounded up to the next one, with a warning (as
         pbrt-v4 does); ``sample_count()`` reports the rounded count, which
         is what a render takes. (Default: 4)

     * - film_width
       - |int|
       - Width in pixels of the image block a render samples (the film's
         width, or its crop window's): the sampler learns only the number of
         lanes of a render, not which pixel a lane belongs to, so it needs
         the width to place pixels in Morton order. A scene sets it from the
         film's parameter (``<integer name="film_width" value="$width"/>``);
         also settable as the attribute ``film_width`` before a render. A
         render without it, or whose lane count is not ``film_width * height
         * spp`` for a whole number ``height``, stops with an error.
         (Default: 0, unset)

     * - seed
       - |int|
       - Seed offset of the scrambling: ``seed(s)`` (e.g. by
         ``mi.render(scene, seed=s)``) scrambles with ``seed + s``, as
         Mitsuba's own samplers do. (Default: 0)

     * - randomization
       - |string|
       - How the sequence is randomized, as pbrt-v4's ``RandomizeStrategy``:
         ``none`` (the plain Sobol' points: a deterministic image, the seed
         ignored), ``permute_digits`` (a random digital shift, an XOR of the
         coordinate's bits) or ``owen`` (nested uniform scrambling by
         hashing, pbrt's ``FastOwenScrambler``). (Default: ``owen``)

     * - sequence_length
       - |int|
       - Samples per pixel of the whole sequence that one or several renders
         take together (rounded up to a power of two, with a warning): pixel
         ``p`` owns the indices ``morton(p) * sequence_length + i``. Set it
         when a sequence is rendered in several ``mi.render`` calls with
         ``sample_offset``; 0 means the sample count of the render itself.
         (Default: 0)

     * - sample_offset
       - |int|
       - Index of the first sample of each pixel within its sequence: a
         render takes the samples ``sample_offset .. sample_offset + spp -
         1``, which must fit in ``sequence_length``. Also settable between
         renders (attribute ``sample_offset`` or
         ``mi.traverse(scene)['<sensor>.sampler.sample_offset']``) without
         recompiling, to continue a sequence over several renders.
         (Default: 0)

    The sequence (Ahmed and Wonka, "Screen-space blue-noise diffusion of
    Monte Carlo sampling error via hierarchical ordering of pixels", 2020;
    pbrt-v4's ``ZSobolSampler``): sample ``i`` of pixel ``(x, y)`` is point
    ``P_d(morton(x, y) * L + i)`` of the 2-D Sobol' (0,2)-sequence, ``L`` the
    sequence length and ``P_d`` a nested random permutation of the index per
    dimension pair ``d`` (see :func:`integrators.qmc_sobol.zsobol_permute_index`):
    each Morton digit, the quad of pixels it selects, is permuted depending
    only on the digits above it, so every aligned ``2^k x 2^k`` block of
    pixels owns an aligned block of the sequence and neighbouring pixels get
    complementary parts of one (0,2)-net. A pixel's error is that of padded
    (0,2)-sequences (as Mitsuba's ``ldsampler``); across pixels the errors
    are anticorrelated, so the error image is blue noise. The image is
    placed in the smallest power-of-two square that holds it; Morton indices
    outside the film are never used. The Morton digits and ``log2 L`` must
    fit in 32 bits (e.g. 1024 x 1024 pixels and 4096 samples per pixel).

    Dimensions: ``next_2d`` at dimension ``d`` (the number of values drawn
    since the last ``seed``/``advance``) returns Sobol' dimensions 0 and 1
    of the pair scrambled for ``d`` and counts as two dimensions; ``next_1d``
    returns Sobol' dimension 0 (the van der Corput sequence) of the pair
    scrambled for ``d`` and counts as one. Every call hashes the seed and
    its dimension into the seeds of its index permutation and of its
    coordinates' scrambles, so no two calls share points.

    Every pixel's ``L`` points (and the first ``2^j`` of them, and every
    aligned run of ``2^j`` such as one render of a continued sequence) are a
    (0, j, 2)-net in each pair, with every randomization. ``owen`` and
    ``permute_digits`` make every point uniform on [0, 1)^2 over the seeds,
    so the image is unbiased.

    All state (the index of every lane, the dimension) lives in Dr.Jit
    arrays, so the sampler advances correctly inside symbolic loops, and the
    seed, ``sample_offset``, the film width and the sequence length are
    opaque: reseeding or a new count does not recompile the render kernel.

    Wavefront layout and multi-pass renders: as for every
    :class:`~integrators.sequence_sampler.SequenceSampler`, lane ``l`` of
    a render is sample ``l % k`` of pixel ``l // k``, ``k`` the samples per
    pixel of one pass: the sample count, unless a caller that renders in
    passes declares ``k`` with ``set_samples_per_wavefront(k)`` before
    ``seed()``. Mitsuba's own multi-pass renders (an integrator's
    ``samples_per_pass``, or more than 2^32 samples in one render) declare
    it through a C++ call a Python sampler never sees, so ``advance()``
    after an undeclared seeding raises a ``RuntimeError`` instead of
    continuing with wrong indices. Render one pass per ``mi.render`` call
    and continue the sequence with ``sample_offset``::

        sampler = scene.sensors()[0].sampler()
        sampler.sequence_length = 8
        done = 0
        for k in (1, 1, 2, 4):
            sampler.sample_offset = done
            img_k = mi.render(scene, seed=seed, spp=k)
            done += k
        # the pass images, weighted by k / 8, average to one 8-sample render

    Keep each pass a power of two aligned to its offset (as above) for
    every pass to be a net on its own.

    .. tabs::

        .. code-tab:: xml

            <sampler type="zsobol">
                <integer name="sample_count" value="16"/>
                <integer name="film_width" value="$width"/>
                <string name="randomization" value="owen"/>
            </sampler>

        .. code-tab:: python

            'type': 'zsobol',
            'sample_count': 16,
            'film_width': 256,
            'randomization': 'owen'
    """

    PLUGIN = "zsobol"
    PARAMETERS = ("randomization", "film_width", "sequence_length")
    STATE = SequenceSampler.STATE + ("_pixel_base", "_x_mask", "_seed", "_error")
    ADVANCE_HINT = ", set the sampler's 'sequence_length' to the total"
    #: Why the current seeding cannot be drawn from (None: it can).
    _error = "zsobol: seed() the sampler before drawing samples"

    def __init__(self, props: mi.Properties):
        sample_count = props.get("sample_count", 4)
        self._check_count("sample_count", sample_count)
        randomization = self._read_choice(props, "randomization", qmc.RANDOMIZATIONS, "owen")
        sample_count = self._rounded("sample_count", sample_count)
        super().__init__(props, randomization=randomization,
                         film_width=props.get("film_width", 0),
                         sequence_length=props.get("sequence_length", 0))
        mi.Sampler.set_sample_count(self, sample_count)

    # ------------------------------------------------------------ parameters

    @staticmethod
    def _check_count(name: str, n, minimum: int = 1) -> None:
        if not isinstance(n, int) or isinstance(n, bool) or n < minimum:
            raise ValueError(f"zsobol: '{name}' must be an integer >= {minimum}, got {n!r}")

    @staticmethod
    def _rounded(name: str, n: int) -> int:
        rounded = _round_up_pow2(n)
        if rounded != n:
            warnings.warn(f"zsobol: '{name}' {n} is not a power of two; rounded up to "
                          f"{rounded} (Sobol' nets need power-of-two counts)", stacklevel=3)
        return rounded

    @property
    def film_width(self) -> int:
        """Width of the sampled image block (0: unset; see the class docs)."""
        return self._film_width

    @film_width.setter
    def film_width(self, value) -> None:
        self._check_count("film_width", value, minimum=0)
        if value > 1 << 16:
            raise ValueError(f"zsobol: 'film_width' must be at most 65536, got {value}")
        self._film_width = value

    @property
    def sequence_length(self) -> int:
        """Samples per pixel of the whole sequence (0: the sample count)."""
        return self._sequence_length

    @sequence_length.setter
    def sequence_length(self, value) -> None:
        self._check_count("sequence_length", value, minimum=0)
        self._sequence_length = self._rounded("sequence_length", value) if value else 0

    def _length(self) -> int:
        return self._sequence_length or self.sample_count()

    def set_sample_count(self, spp: int) -> None:
        self._check_count("sample_count", spp)
        mi.Sampler.set_sample_count(self, self._rounded("sample_count", spp))

    # ----------------------------------------------------------------- state

    def _fit_error(self, taken: int) -> str | None:
        length = self._length()
        if self._offset + taken > length:
            return (f"zsobol: samples {self._offset} .. {self._offset + taken - 1} of each pixel "
                    f"do not fit in its sequence of {length} (sequence_length "
                    f"{self._sequence_length or 'unset: the sample count'}); set "
                    f"'sequence_length' to the samples per pixel that all renders of the "
                    f"sequence take together")
        return None

    def _samples_per_wavefront(self, wavefront_size: int, declared: int) -> int:
        spw = declared or self.sample_count()
        # A layout that does not fit is refused when the sampler is drawn from,
        # not here: Mitsuba's render reseeds with seed(0, 1) after every render.
        self._error = self._layout_error(wavefront_size, spw)
        return spw if self._error is None else 1

    def _pixels(self, lanes, samples_per_wavefront: int) -> mi.UInt32:
        # No vector integer division (x86 executes it lane by lane): a shift for
        # the samples per pixel (a power of two: they divide the sample count,
        # Mitsuba checks it).
        return lanes >> dr.opaque(mi.UInt32, samples_per_wavefront.bit_length() - 1)

    def _seed_lanes(self, seed, pixel, wavefront_size: int) -> None:
        # The row by a float64 reciprocal of the width (exact: (pixel + 1/2) / width
        # lies at least 2^-17 from an integer, the product's error is below 2^-20).
        width = self._film_width if self._error is None else wavefront_size
        Float64 = dr.float64_array_t(mi.Float)
        row = mi.UInt32(dr.floor((Float64(pixel) + 0.5) * dr.opaque(Float64, 1.0 / width)))
        log2_length = self._length().bit_length() - 1
        morton = qmc_sobol.morton_encode(pixel - row * dr.opaque(mi.UInt32, width), row)
        #: First sequence index of every lane's pixel (its Morton index times the length).
        self._pixel_base = morton << dr.opaque(mi.UInt32, log2_length)
        #: The Morton digits' x bits of a reversed index (qmc_sobol.morton_x_mask).
        self._x_mask = dr.opaque(mi.UInt32, qmc_sobol.morton_x_mask(log2_length))
        self._seed = seed

    def _layout_error(self, wavefront_size: int, spw: int) -> str | None:
        """Why ``wavefront_size`` lanes of ``spw`` samples per pixel cannot be
        placed in Morton order (None: they can)."""
        width = self._film_width
        if width == 0:
            return ("zsobol: 'film_width' is not set. The sampler needs the width of the image "
                    "it samples to put its pixels in Morton order (a render tells it only the "
                    "number of lanes): set <integer name=\"film_width\" value=\"$width\"/> in "
                    "the scene's sampler, 'film_width' in its dict, or sampler.film_width = "
                    "width before rendering")
        if spw & (spw - 1):
            return (f"zsobol: {spw} samples per pixel per pass is not a power of two; "
                    f"declare passes of a power of two (set_samples_per_wavefront)")
        if wavefront_size % (width * spw) != 0:
            return (f"zsobol: a wavefront of {wavefront_size} lanes is not film_width {width} x "
                    f"height x {spw} samples per pixel for any whole height: 'film_width' does "
                    f"not match the film (or its crop window) being rendered")
        height = wavefront_size // (width * spw)
        length = self._length()
        side_bits = 2 * (_round_up_pow2(max(width, height)).bit_length() - 1)
        log2_length = length.bit_length() - 1
        if side_bits + log2_length > qmc_sobol.ZSOBOL_INDEX_BITS:
            return (f"zsobol: {width} x {height} pixels (a Morton square of {side_bits} bits) "
                    f"with sequences of {length} samples need {side_bits + log2_length} index "
                    f"bits; at most {qmc_sobol.ZSOBOL_INDEX_BITS} are available: render fewer "
                    f"pixels or samples per pixel")
        return self._fit_error(spw)

    def _advanced(self) -> None:
        self._error = self._error or self._fit_error((self._passes + 1) * self._spw)

    def current_sample_index(self) -> mi.UInt32:
        """Sequence index of every lane's current sample, before the permutation
        (``morton(pixel) * sequence_length + sample``)."""
        return self._pixel_base + super().current_sample_index()

    # -------------------------------------------------------------- sampling

    def _check_layout(self) -> None:
        if self._error is not None:
            raise RuntimeError(self._error)

    def next_1d(self, active=True) -> mi.Float:
        self._check_layout()
        index = self.current_sample_index()
        (x,) = qmc_sobol.zsobol_sample(index, self._dimension, self._seed, self._x_mask,
                                 self.randomization, components=1)
        self._dimension += 1
        return x

    def next_2d(self, active=True) -> mi.Point2f:
        self._check_layout()
        index = self.current_sample_index()
        x, y = qmc_sobol.zsobol_sample(index, self._dimension, self._seed, self._x_mask,
                                 self.randomization)
        self._dimension += 2
        return mi.Point2f(x, y)


mi.register_sampler("zsobol", ZSobolSampler)  # the class of this variant, bound now
