"""The ``vr_adaptive`` integrator: another integrator's image, its samples where the error is.

A pilot pass gives every pixel the same few samples; their per-pixel spread says where the
image's relative error is; the rest of the budget goes to the pixels in proportion to their
relative standard deviation (the allocation that minimises the image's relMSE at a fixed
number of samples), with a floor so that no pixel starves. A pixel's relative variance is
read half from its own pilot and half from its 8 neighbours' (:data:`OWN_SHARE`): its own
finds a highlight a pixel wide, its neighbours' a rare bright path its own pilot missed.

Because the count depends on the pixel's own pilot, the pilot does not enter the image by
its count: the mean of all its samples would be optional stopping (a pixel whose pilot
missed a rare bright path gets few samples and keeps its low pilot mean: a synthetic pixel
whose sample is 50 with probability 0.02 came out 20% dark so, tests/test_adaptive.py).
The pilot's mean gets the fixed weight ``n_p / (n_p + m)``, ``m`` the count the pixel's
neighbours alone would give it (independent of its own samples), and the final pass's mean
the rest: the pilot's weight does not depend on its own samples, and given its count the
final pass is the mean of fresh samples, so the image is unbiased (:func:`combine`).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import guided_path, moments
from .path import seed_value

#: Default ``relmse_eps``: the offset of the relative error's denominator, as the
#: experiments' relMSE has it (``experiments.lib.metrics.RELMSE_EPS``).
RELMSE_EPS = 0.01
#: Default ``pilot_share``: the share of the samples the pilot spends, every pixel alike.
PILOT_SHARE = 0.25
#: The fewest pilot samples per pixel: two in each half, whose variances
#: :meth:`AdaptiveIntegrator.predicted_gain` reads.
MIN_PILOT = 4
#: Default ``min_share``: every pixel's floor, as a share of the final pass's average count.
MIN_SHARE = 0.1
#: The share of a pixel's own pilot in the relative variance its count is read from (the
#: rest its 8 neighbours'): docs/methodology.md, "Adaptive sampling".
OWN_SHARE = 0.5
#: Default ``min_gain``: the allocation's gain predicted from the pilot below which every
#: pixel gets the same count (docs/methodology.md, "Adaptive sampling").
MIN_GAIN = 1.3


class AdaptiveIntegrator(mi.SamplingIntegrator):
    r"""
    .. _integrator-vr_adaptive:

    Adaptive sampling (:monosp:`vr_adaptive`)
    -----------------------------------------

    .. pluginparameters::

     * - nested
       - |integrator|
       - The integrator whose samples are spent (required): a sampling integrator such as
         ``path`` or ``vr_path`` (not one that learns between passes, ``vr_guided_path``).
     * - pilot_share
       - |float|
       - Share of the samples per pixel spent on the pilot pass, which every pixel gets
         alike, at least 4 samples per pixel. (Default: 0.25)
     * - min_share
       - |float|
       - Share of the final pass's average samples per pixel that every pixel gets at
         least: the floor that keeps a pixel whose pilot missed its rare bright paths
         from starving. (Default: 0.1)
     * - min_spp
       - |int|
       - Fewest samples per pixel of the final pass. (Default: 1)
     * - min_gain
       - |float|
       - The gain at equal samples that the pilot predicts for the render, below which
         the final pass gives every pixel the same count, rendered by the nested
         integrator itself: where the pixels' errors hardly differ, or a pilot of few
         samples cannot tell them apart, moving samples gains less than it costs. The
         prediction is cross-validated: the counts allocated from one half of each
         pixel's pilot samples, judged by the other half's variances (the pilot's noise
         is no gain). 0: always allocate. (Default: 1.3)
     * - relmse_eps
       - |float|
       - Offset of the relative error's denominator: a pixel's relative variance is
         var / (mean^2 + eps), as the experiments' relMSE measures it (a dark pixel's
         error then counts little; 0: purely relative, dark pixels ruling). (Default: 0.01)

    Renders ``spp`` samples per pixel on average in two passes. The pilot (``pilot_share``
    of them) estimates each pixel's relative variance of one sample,
    sigma_i^2 / (mu_i^2 + ``relmse_eps``), from the luminance of its samples; pixel i's count
    in the final pass is read from the square root of the mean of its own and of the mean
    over its 8 neighbours: its floor (``min_share`` of the pass's average count, at least
    ``min_spp``) plus its share of the remaining samples in proportion to that relative
    deviation (rounded down). The image is, per pixel, the pilot's mean with the fixed
    weight n_p / (n_p + m_i) plus the final pass's mean with the rest, m_i the count the
    neighbours alone would give the pixel: unbiased, because that weight does not depend on
    the pixel's own samples (its mean over all its samples would not be: a pixel whose
    pilot missed a rare bright path would keep its low pilot mean).
    The per-pixel counts are not a power of two nor equal: the ``independent`` sampler
    only, and a ``box`` filter (each sample in its own pixel); the film's developed image
    is returned without AOVs. After a render, ``last_counts`` holds every pixel's samples
    (pilot and final, row-major): where the budget went. Nested in another integrator
    that calls its ``sample`` (Mitsuba's ``moment``, ``aov``) it is refused: that call
    would skip the pilot and the counts.
    """

    def __init__(self, props: mi.Properties):
        super().__init__(props)
        self.nested = moments.nested_integrator(props, "vr_adaptive")
        #: Every pixel's samples in the last render (None before one).
        self.last_counts = None
        if isinstance(self.nested, guided_path.GuidedPathIntegrator):
            raise ValueError("vr_adaptive: the nested integrator (vr_guided_path) learns "
                             "between its own passes, which one pass of per-pixel counts "
                             "cannot hold; nest a plain sampling integrator (path, vr_path)")
        self.pilot_share = float(props.get("pilot_share", PILOT_SHARE))
        self.min_spp = int(props.get("min_spp", 1))
        self.min_share = float(props.get("min_share", MIN_SHARE))
        self.relmse_eps = float(props.get("relmse_eps", RELMSE_EPS))
        self.min_gain = float(props.get("min_gain", MIN_GAIN))
        #: The last render's predicted gain (:meth:`predicted_gain`) and whether it allocated.
        self.last_gain, self.last_allocated = None, None
        if not 0.0 < self.pilot_share < 1.0:
            raise ValueError(f"vr_adaptive: pilot_share must be in (0, 1), got "
                             f"{self.pilot_share}")
        if self.min_spp < 1:
            raise ValueError(f"vr_adaptive: min_spp must be >= 1, got {self.min_spp}")
        if not 0.0 <= self.min_share < 1.0:
            raise ValueError(f"vr_adaptive: min_share must be in [0, 1), got "
                             f"{self.min_share}")
        if not self.relmse_eps >= 0.0:
            raise ValueError(f"vr_adaptive: relmse_eps must be >= 0, got {self.relmse_eps}")
        if not self.min_gain >= 0.0:
            raise ValueError(f"vr_adaptive: min_gain must be >= 0, got {self.min_gain}")

    # ------------------------------------------------------------ the render
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        film, sampler = sensor.film(), sensor.sampler()
        _check(film, sampler)
        if spp:
            sampler.set_sample_count(spp)     # as Mitsuba's render(): the count it ran
        spp = sampler.sample_count()
        pilot, final = split(spp, self.pilot_share)
        size = film.crop_size()
        pixels = int(size.x) * int(size.y)
        if final < self.min_spp:
            raise ValueError(f"vr_adaptive: {spp} spp leaves the final pass {final} samples "
                             f"per pixel after a pilot of {pilot} (pilot_share "
                             f"{self.pilot_share}, at least {MIN_PILOT}), fewer than min_spp "
                             f"{self.min_spp}: render more samples")
        # counts enter the kernels as opaque values: one kernel for every count (a
        # literal would compile new kernels whenever spp changes, e.g. after a warm-up)
        n_pilot = dr.opaque(mi.Float, pilot)
        counts = dr.opaque(mi.UInt32, pilot, pixels)
        total, halves = self._pass(scene, sensor, sampler, seed, counts, pilot * pixels, True)
        self.last_gain = self.predicted_gain(halves, pilot, final * pixels, size)
        self.last_allocated = self.last_gain >= self.min_gain
        if not self.last_allocated:
            image = self._uniform(scene, sensor, seed, total, pilot, final)
            self.last_counts = dr.full(mi.UInt32, spp, pixels)
            return mi.TensorXf(dr.ravel(image), shape=(int(size.y), int(size.x), 3))
        sums, squares = halves
        counts, planned = self.allocate((_half(sums, 0) + _half(sums, 1)) / n_pilot,
                                        (_half(squares, 0) + _half(squares, 1)) / n_pilot,
                                        pilot, final * pixels, size)
        n = int(dr.sum(counts)[0]) if dr.width(counts) else 0
        rest, _ = self._pass(scene, sensor, sampler, _other_seed(seed), counts, n)
        image = combine(total, n_pilot, rest, mi.Float(counts), mi.Float(planned))
        self.last_counts = counts + pilot
        return mi.TensorXf(dr.ravel(image), shape=(int(size.y), int(size.x), 3))

    def _uniform(self, scene, sensor, seed, total: mi.Color3f, pilot: int,
                 final: int) -> mi.Color3f:
        """The image where the pilot predicts too little gain (:attr:`min_gain`): the
        nested integrator's own render of ``final`` samples per pixel (its kernel, no
        per-pixel counts), pooled with the pilot's sums ``total`` by their samples. The
        weights are fixed given the decision, which reads every pixel's pilot, a pixel's
        own in a share of one over the pixel count."""
        sampler = sensor.sampler()
        rendered = self.nested.render(scene, sensor, seed=_other_seed(seed), spp=final)
        sampler.set_sample_count(pilot + final)
        rest = mi.Color3f(*[dr.ravel(rendered[..., c]) for c in range(3)])
        return (total + rest * float(final)) / float(pilot + final)

    def allocate(self, mean: mi.Float, second: mi.Float, pilot: int, budget: int,
                 size) -> tuple[mi.UInt32, mi.UInt32]:
        """(per-pixel counts of the final pass, the counts the neighbours alone would
        give): the floor each plus the rest of ``budget`` in proportion to the pilot's
        relative standard deviation of one sample (its luminance's: the square root of
        var / (mean^2 + ``relmse_eps``), :data:`OWN_SHARE` the pixel's own and the rest the
        mean over its 8 neighbours; for the second, the neighbours' mean alone), rounded
        down. ``mean`` and ``second`` are the mean of the pilot's ``pilot`` luminances and
        of their squares, per pixel."""
        return self._allocated(self._relative(mean, second, pilot), budget, size)

    def _allocated(self, relative: mi.Float, budget: int, size, planned: bool = True):
        """:meth:`allocate`'s counts from the pixels' relative variances ``relative``; the
        neighbours' alone only with ``planned`` (else None)."""
        neighbours = _blur(relative, int(size.x), int(size.y))
        own = dr.fma(OWN_SHARE, relative - neighbours, neighbours)
        return (self._counts(dr.sqrt(own), budget, size),
                self._counts(dr.sqrt(neighbours), budget, size) if planned else None)

    def predicted_gain(self, halves, pilot: int, budget: int, size) -> float:
        """The gain at equal samples that the pilot predicts for the whole render (pilot,
        floor and rounding included): the counts :meth:`allocate` would give from one half
        of the pilot's samples (a pixel's even-numbered ones, or its odd), judged by the
        other half's per-pixel relative variances v, mean(v) / spp over mean(v / n) with n
        a pixel's pilot and final samples, the mean of the two ways round. Cross-validated:
        judged by the samples it allocated by, a pilot's noise would look like differences
        between the pixels worth allocating to (a pixel whose few samples caught a rare
        bright path looks dear, and is, by those samples alone)."""
        sums, squares = halves
        n = [(pilot + 1) // 2, pilot // 2]
        v = [self._relative(_half(sums, h) / n[h], _half(squares, h) / n[h], n[h])
             for h in (0, 1)]
        spp = pilot + budget / (int(size.x) * int(size.y))
        gains = []
        for h in (0, 1):
            counts, _ = self._allocated(v[h], budget, size, planned=False)
            judge = v[1 - h]
            uniform = dr.mean(judge)[0] / spp
            allocated = dr.mean(judge / (pilot + mi.Float(counts)))[0]
            gains.append(uniform / allocated if allocated > 0 else 1.0)
        return float(sum(gains) / 2)

    def _relative(self, mean: mi.Float, second: mi.Float, n: int) -> mi.Float:
        """Per pixel, the relative variance of one sample from ``n`` samples' mean
        luminance and mean square: var / (mean^2 + ``relmse_eps``), var unbiased."""
        var = dr.maximum(second - dr.square(mean), 0.0) * dr.opaque(mi.Float, n / (n - 1.0))
        return var / dr.maximum(dr.square(mean) + self.relmse_eps, 1e-24)

    def _counts(self, ratio: mi.Float, budget: int, size) -> mi.UInt32:
        """The floor each plus the rest of ``budget`` in proportion to ``ratio``, rounded
        down."""
        pixels = int(size.x) * int(size.y)
        least = max(self.min_spp, int(self.min_share * budget / pixels))
        spare = max(0, budget - least * pixels)
        total = dr.sum(ratio)
        share = dr.select(total > 0, ratio / dr.maximum(total, 1e-30), 1.0 / pixels)
        return dr.opaque(mi.UInt32, least) + mi.UInt32(dr.floor(share *
                                                                dr.opaque(mi.Float, spare)))

    def _pass(self, scene, sensor, sampler, seed, counts: mi.UInt32, n: int,
              halves: bool = False):
        """``counts[i]`` samples in pixel i, every count at least 1 (``n`` in all), laid out
        pixel by pixel: :meth:`render_samples`, with ``halves`` each sample's number within
        its pixel given."""
        start = dr.prefix_sum(counts)                 # exclusive: the pixel's first sample
        marks = dr.zeros(mi.UInt32, n)
        dr.scatter(marks, 1, start, counts > 0)
        index = dr.cumsum(marks) - 1                  # the pixel of every sample
        ordinal = dr.arange(mi.UInt32, n) - dr.gather(mi.UInt32, start, index) \
            if halves else None
        return self.render_samples(scene, sensor, sampler, seed, index, ordinal)

    def render_samples(self, scene, sensor, sampler, seed, pixels: mi.UInt32,
                       ordinal: mi.UInt32 | None = None):
        """One sample of the nested integrator per entry of ``pixels`` (a pixel's row-major
        index on the film), seeded ``seed``: (the per-pixel sums of the samples' RGB, and
        with ``ordinal``, each sample's number within its pixel, the per-pixel sums of
        their luminance and of its square over each half of the pixel's samples, its
        even-numbered and its odd, pixel i's at 2i and 2i + 1; else None)."""
        width, height = int(sensor.film().crop_size().x), int(sensor.film().crop_size().y)
        pixels_n, n = width * height, dr.width(pixels)
        sampler = sampler.clone()
        sampler.seed(seed, n)
        pos = mi.Vector2f(mi.Float(pixels % width), mi.Float(pixels // width))
        pos += sampler.next_2d()
        scale = dr.rcp(mi.ScalarVector2f(width, height))
        aperture = sampler.next_2d() if sensor.needs_aperture_sample() else mi.Point2f(0.5)
        time = sensor.shutter_open()
        if sensor.shutter_open_time() > 0:
            time += sampler.next_1d() * sensor.shutter_open_time()
        ray, weight = sensor.sample_ray_differential(time, sampler.next_1d(),
                                                     mi.Point2f(pos * scale), aperture)
        L, valid, _ = self.nested.sample(scene, sampler, ray, None, True)
        rgb = mi.Color3f(dr.select(valid, weight * L, 0.0))
        total = dr.zeros(mi.Color3f, pixels_n)
        for c in range(3):
            dr.scatter_reduce(dr.ReduceOp.Add, total[c], rgb[c], pixels)
        if ordinal is None:
            dr.eval(total)
            return total, None
        lum = mi.luminance(rgb)
        slot = 2 * pixels + (ordinal & 1)
        sums, squares = dr.zeros(mi.Float, 2 * pixels_n), dr.zeros(mi.Float, 2 * pixels_n)
        dr.scatter_reduce(dr.ReduceOp.Add, sums, lum, slot)
        dr.scatter_reduce(dr.ReduceOp.Add, squares, dr.square(lum), slot)
        dr.eval(total, sums, squares)
        return total, (sums, squares)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        """Refused: an integrator that nests this one and calls its ``sample`` (Mitsuba's
        ``moment``) would skip the pilot and the per-pixel counts of :meth:`render`."""
        raise ValueError("vr_adaptive: called by another integrator (its sample(), not its "
                         "own render): its pilot and per-pixel counts need its own render; "
                         "make vr_adaptive the scene's integrator and nest the other one in "
                         "it, not it in another")

    def aov_names(self):
        return []

    def to_string(self):
        return (f"AdaptiveIntegrator[nested={self.nested}, pilot_share={self.pilot_share}, "
                f"min_share={self.min_share}, min_spp={self.min_spp}, "
                f"min_gain={self.min_gain}, relmse_eps={self.relmse_eps}]")


def split(spp: int, pilot_share: float = PILOT_SHARE) -> tuple[int, int]:
    """(the pilot's, the final pass's) samples per pixel of a render of ``spp``."""
    pilot = max(MIN_PILOT, round(spp * pilot_share))
    return pilot, spp - pilot


def _check(film, sampler) -> None:
    """Refuse what per-pixel counts cannot serve, naming why."""
    if not film.rfilter().is_box_filter():
        raise ValueError("vr_adaptive: the film's reconstruction filter must be a 'box' (each "
                         "sample in its own pixel, so that a pixel's count is its own); got "
                         f"{type(film.rfilter()).__name__} (Mitsuba's default is gaussian)")
    kind = str(sampler).split("[", 1)[0]
    if kind != "IndependentSampler":
        raise ValueError(f"vr_adaptive: the sampler must be 'independent' (per-pixel counts "
                         f"that are neither equal nor a power of two break a stratified or "
                         f"low-discrepancy sampler's points); got {kind}")


def combine(pilot: mi.Color3f, n_pilot: mi.Float, final: mi.Color3f, n_final: mi.Float,
            planned: mi.Float) -> mi.Color3f:
    """The pixel estimate from the passes' sums and counts: the pilot's mean with the
    weight ``n_pilot / (n_pilot + planned)``, ``planned`` the count the neighbours alone
    would give the pixel, and the final pass's mean with the rest. Unbiased: the weight
    does not depend on the pixel's own samples, and given its count ``n_final`` (which
    does) the final pass's mean is the mean of fresh samples."""
    weight = n_pilot / (n_pilot + planned)
    return weight * (pilot / n_pilot) + (1.0 - weight) * (final / n_final)


def _half(x: mi.Float, h: int) -> mi.Float:
    """Every pixel's entry of half ``h`` (0: its even-numbered samples, 1: its odd) of a
    per-pixel pair of sums, pixel i's at 2i and 2i + 1 (:meth:`AdaptiveIntegrator._pass`)."""
    return dr.gather(mi.Float, x, 2 * dr.arange(mi.UInt32, dr.width(x) // 2) + h)


def _other_seed(seed) -> int:
    """The final pass's seed: another stream than the pilot's."""
    return (seed_value(seed) * 0x9E3779B1 + 0x7F4A7C15) & 0xFFFFFFFF


def _blur(x: mi.Float, width: int, height: int) -> mi.Float:
    """The mean of ``x`` (one value per pixel) over each pixel's neighbours on the film (8
    inside, fewer at its edge), the pixel itself never among them (see the module)."""
    i = dr.arange(mi.UInt32, width * height)
    px, py = mi.Int32(i % width), mi.Int32(i // width)
    total, count = dr.zeros(mi.Float, width * height), dr.zeros(mi.Float, width * height)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dx == 0 and dy == 0:
                continue
            qx, qy = px + dx, py + dy
            inside = (qx >= 0) & (qx < width) & (qy >= 0) & (qy < height)
            total += dr.gather(mi.Float, x, mi.UInt32(qy * width + qx), inside)
            count += dr.select(inside, 1.0, 0.0)
    return total / dr.maximum(count, 1.0)


mi.register_integrator("vr_adaptive", lambda props: AdaptiveIntegrator(props))
