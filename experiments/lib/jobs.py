"""Render jobs and their results as plain data: the base of the library (imports only the clock).

A :class:`Job` is one render (a scene, a parsed method, a resolution, a number of
samples per pixel, rendered in passes of at most ``pass_spp``); the planner
(:mod:`.plan`) fixes its seed and, for samplers that continue one sequence
(``halton``), its sample offset, so the same plan gives the same images
whichever process (or cluster worker) runs it. ``key`` names its entry in
the :class:`~.store.JobStore` and is a hash of everything the image depends on.

A :class:`JobResult` is what a job produced (:func:`~.execute.run_job`); the
store keeps one per finished job. :class:`Accumulator` adds results up
(weighted by their sample counts) and :func:`accumulate` gives the cumulative
image after each result of a sequence: the analysis side of a progressive
render (:func:`~.plan.ladder`), fed with results read back from the store
(:meth:`~.study.Study.accumulate`).

:func:`cpu_model` names the machine a result was measured on (``JobResult.cpu``).
"""
from __future__ import annotations

import dataclasses
import math
import platform
import zlib
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from . import clock

#: Largest number of samples (pixels x spp) rendered in one pass; bigger jobs
#: render in several passes, which bounds memory (1024x512 -> 8 spp per pass).
MAX_LANES = 2**22


@dataclass(frozen=True)
class Job:
    """One render job: plain, picklable data."""
    key: str                    # stable unique id = the store entry name
    scene: str                  # scene XML path
    scene_sha256: str
    method: object              # a methods.Method (parsed once; the key hashes its name)
    width: int
    height: int
    spp: int                    # samples per pixel of this job
    seed: int
    sample_offset: int = 0      # index of the first sample (halton continues sequences)
    pass_spp: int = 0           # spp per pass (0: the largest MAX_LANES allows)
    max_depth: int | None = None     # None: the integrator's default
    rr_depth: int | None = None
    hide_emitters: bool | None = None
    timing_group: str | None = None  # jobs whose times one comparison divides
    sequence_spp: int = 0       # samples per pixel of the whole sequence a job continues
                                # (samplers that order pixels by it, zsobol; 0: none)
    sample_moments: bool = False  # rendered through ``vr_moments``: every sample its own
                                  # pass for the per-pixel variances (independent, box)
    pilot: bool = False         # a count's pilot (.engine.Engine.piloted_spp): rendered
                                # once, a kernel compiled during it kept (its cost only)

    @property
    def lane_cap(self) -> int:
        """The most samples per pixel of one render of this film (:data:`MAX_LANES`)."""
        return max(1, MAX_LANES // (self.width * self.height))

    def split_lanes(self, spp: int) -> list[int]:
        """``spp`` samples per pixel of this film in renders of at most :attr:`lane_cap`
        each (a multi-pass method's pass: :func:`.execute.render_passes`)."""
        return [min(self.lane_cap, spp - s) for s in range(0, spp, self.lane_cap)]

    def render_parts(self, spp: int) -> list[int]:
        """A multi-pass method's pass of ``spp`` samples per pixel in renders: of at most
        :attr:`lane_cap` each (:meth:`split_lanes`), and where the sampler continues one
        sequence and would round a render's count up (zsobol: a Sobol' net, a power of two),
        each in powers of two, largest first, so that the pass takes exactly its samples
        of the sequence (needs a Mitsuba variant)."""
        parts = self.split_lanes(spp)
        spec = self.method.sampler_spec
        if not spec.continues_sequence:
            return parts
        return [p for n in parts
                for p in ([n] if spec.rendered_count(n) == n else powers_of_two(n))]

    def passes(self) -> list[int]:
        """The spp of each pass of this job. A sampler that continues one sequence over the
        passes gets passes of a power of two (but the last): zsobol rounds a render's count
        up to one (a Sobol' net), so a pass of another count would take more of the
        sequence than the job has. A job of a power of two gets passes of a power of two
        too: Mitsuba compiles another kernel for other counts (:func:`.execute.warm_spp`),
        so that a pass of 2427 spp (the lane cap of a 48x36 film) would compile during the
        timed render, which is then discarded and rendered again (2.5 s per such job on the
        guiding scenes in a cold run)."""
        cap = min(self.lane_cap, self.pass_spp) if self.pass_spp else self.lane_cap
        power_of_two = self.spp & (self.spp - 1) == 0
        if getattr(self.method, "continues_sequence", False) or power_of_two:
            cap = 1 << (cap.bit_length() - 1)
        return [min(cap, self.spp - s) for s in range(0, self.spp, cap)]


def powers_of_two(n: int) -> list[int]:
    """``n`` as a sum of distinct powers of two, largest first (its binary digits)."""
    return [1 << b for b in range(n.bit_length() - 1, -1, -1) if n >> b & 1]


def derive_seed(*parts) -> int:
    """A seed from any parts (distinct parts give distinct, stable seeds)."""
    return zlib.crc32("/".join(map(str, parts)).encode()) & 0x7FFFFFFF


@dataclass
class JobResult:
    """What a job produced: plain data, picklable."""
    image: np.ndarray            # (H, W, 3) float32, mean of the job's samples
    sq: np.ndarray | None        # (H, W, 3) sum over passes of k_i * m_i^2 (float64)
    spp: int
    passes: int
    wall_seconds: float          # warm render time (wall clock), summed over passes
    pass_seconds: list = field(default_factory=list)
    cpu_seconds: float = 0.0     # CPU time of this process (all threads) over the passes
    host: str = ""
    cpu: str = ""
    recompiled: int = 0          # renders discarded because a kernel compiled during them
    compiled_passes: int = 0     # timed passes that compiled even after the warm tries
    kernel_seconds: float = 0.0  # execution time of the timed passes' kernels (Dr.Jit's
                                 # kernel history): the sample work, no tracing or launch
    host_seconds: float = 0.0    # CPU time of the method's own host work between its passes
                                 # (:mod:`.clock`: the cost is kernel + host seconds)
    cubes: np.ndarray | None = None     # (H, W, 3) sums of the samples' cubes and fourth
    fourths: np.ndarray | None = None   # powers (float64): ``sample_moments`` jobs only
    variance_var: np.ndarray | None = None  # (H, W, 3) how sure the variance a MultiPass
                                            # method states is (multipass.stated_tails)

    def metadata(self) -> dict:
        return {"spp": self.spp, "passes": self.passes, "wall_seconds": self.wall_seconds,
                "pass_seconds": list(self.pass_seconds), "cpu_seconds": self.cpu_seconds,
                "host": self.host, "cpu": self.cpu, "recompiled": self.recompiled,
                "compiled_passes": self.compiled_passes, "kernel_seconds": self.kernel_seconds,
                "host_seconds": self.host_seconds}


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), or what ``platform`` knows of it."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


#: The CPU flags that name the widest SIMD extension Dr.Jit's LLVM backend vectorizes to
#: (its lanes per instruction), widest first.
SIMD_FLAGS = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("sse4_2", "SSE4.2"),
              ("asimd", "NEON"))


def cpu_simd(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The widest SIMD extension the CPU has (the flags in ``cpuinfo``, :data:`SIMD_FLAGS`),
    or "unknown": the LLVM backend's kernels are that wide, so the relative costs of methods
    (and every equal-time count) differ between an AVX2 and an AVX-512 machine."""
    try:
        with open(cpuinfo) as f:
            flags = next((set(line.split(":", 1)[1].split()) for line in f
                          if line.startswith(("flags", "Features"))), set())
    except OSError:
        flags = set()
    return next((name for flag, name in SIMD_FLAGS if flag in flags), "unknown")


# ------------------------------------------------------------ accumulation

@dataclass
class Accumulator:
    """Running mean of job images, weighted by their sample counts.

    ``sq`` is sum_i k_i m_i^2 over passes i with k_i samples and mean image
    m_i, from which :meth:`variance_of_mean` estimates per-pixel variances. Where every
    pass is one sample (``sample_moments``) and every result added has them, ``higher``
    holds the sums of the samples' cubes and fourth powers, from which
    :meth:`variance_of_variance` says how sure those variances are.
    """
    mean: np.ndarray
    sq: np.ndarray
    spp: int = 0
    passes: int = 0
    cost: float = 0.0            # seconds of the images added (:func:`.clock.cost`)
    higher: tuple | None = None  # (sum x^3, sum x^4) per pixel and channel; None: unknown
    stated: np.ndarray | None = None     # the one result's own variance_var (a MultiPass
                                         # method's; None once another result is added)

    @classmethod
    def empty(cls, height: int, width: int, channels: int = 3) -> "Accumulator":
        shape = (height, width, channels)
        return cls(np.zeros(shape), np.zeros(shape), higher=(np.zeros(shape), np.zeros(shape)))

    def add(self, image: np.ndarray, spp: int, cost: float = 0.0, sq=None,
            passes: int = 1, higher: tuple | None = None,
            variance_var: np.ndarray | None = None) -> None:
        """Fold in an image that averages ``spp`` samples per pixel (``passes`` passes whose
        sum of squares is ``sq``; one pass when None; ``higher``: the sums of its samples'
        cubes and fourth powers, None where it has none, which makes them unknown here;
        ``variance_var``: how sure its stated variance is, kept only while it is the one
        image added)."""
        image = np.asarray(image, np.float64)
        n = self.spp
        self.stated = variance_var if n == 0 else None
        self.mean = (self.mean * n + image * spp) / (n + spp)
        self.sq = self.sq + (spp * image * image if sq is None else np.asarray(sq, np.float64))
        self.higher = None if self.higher is None or higher is None else \
            tuple(a + np.asarray(b, np.float64) for a, b in zip(self.higher, higher))
        self.spp += spp
        self.passes += passes
        self.cost += cost

    def add_result(self, result: JobResult) -> None:
        higher = None if result.cubes is None or result.fourths is None else \
            (result.cubes, result.fourths)
        self.add(result.image, result.spp, clock.cost(result), result.sq, result.passes,
                 higher, result.variance_var)

    def variance_of_mean(self) -> np.ndarray:
        """Per-pixel variance of :attr:`mean`, from the spread of the pass images.

        Per-sample variance: sum_i k_i (m_i - mean)^2 / (passes - 1)
        = (sq - spp * mean^2) / (passes - 1); divided by spp for the mean.
        """
        if self.passes < 2:
            return np.full_like(self.mean, np.inf)
        s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / (self.passes - 1)
        return s2 / self.spp

    def variance_of_variance(self) -> np.ndarray | None:
        """Per pixel, the variance of :meth:`variance_of_mean` as an estimate:
        :func:`variance_of_variance` of the samples' raw moments, or the one result's own
        (a MultiPass method's, which states its variance); None where neither is known."""
        if self.higher is None or self.passes != self.spp or self.spp < 4:
            return None if self.stated is None else np.asarray(self.stated, np.float64)
        n = self.spp
        return variance_of_variance(self.mean, self.sq / n, self.higher[0] / n,
                                    self.higher[1] / n, n)


    def third_of_mean(self) -> np.ndarray | None:
        """Per pixel, the third cumulant of :attr:`mean` (:func:`third_of_mean` of the
        samples' raw moments); None where they are unknown (a MultiPass method states
        its variance alone)."""
        if self.higher is None or self.passes != self.spp or self.spp < 4:
            return None
        n = self.spp
        return third_of_mean(self.mean, self.sq / n, self.higher[0] / n, n)


#: Relative rounding of a film's single-precision sums (the raw moments' AOVs).
FILM_ROUNDING = 2.0 ** -24


def variance_of_variance(m1, m2, m3, m4, n: int) -> np.ndarray:
    """The variance of the estimate s^2 / n of the variance of a mean of ``n`` independent
    samples, from their raw moments ``m1`` .. ``m4`` (means of x, x^2, x^3, x^4):

        Var(s^2) = 2 mu2^2 / (n - 1) + (mu4 - 3 mu2^2) / n

    (mu_k the central moments; the second term is the excess kurtosis's, which a pixel
    ruled by rare bright samples makes many times the first, normal one). The excess term
    counts only above the rounding of the single-precision sums it is read from (the
    central moment is a difference of raw ones: a smooth pixel's would be rounding
    noise), and never below 0 (a light-tailed pixel keeps the normal term)."""
    m1, m2, m3, m4 = (np.asarray(m, np.float64) for m in (m1, m2, m3, m4))
    mu2 = np.maximum(m2 - m1 * m1, 0.0)
    mu4 = m4 - 4.0 * m1 * m3 + 6.0 * m1 * m1 * m2 - 3.0 * m1 ** 4
    rounding = FILM_ROUNDING * (math.sqrt(n) + 1.0) * 16.0 * (
        np.abs(m4) + 4.0 * np.abs(m1 * m3) + 6.0 * m1 * m1 * np.abs(m2) + 3.0 * m1 ** 4)
    excess = np.maximum(mu4 - 3.0 * mu2 * mu2 - rounding, 0.0)
    s2 = mu2 * n / (n - 1)
    return (2.0 * s2 * s2 / (n - 1) + excess / n) / (n * n)


def third_of_mean(m1, m2, m3, n: int) -> np.ndarray:
    """The third cumulant of a mean of ``n`` independent samples, k3 / n^2, from their raw
    moments ``m1`` .. ``m3`` (k3 estimated without bias: n^2 / ((n-1)(n-2)) times the
    sample's third central moment). Its sum over pixels against their variance's, to the
    power 3/2, is how skewed an image sum is: a sum ruled by rare bright samples is far
    from normal however many degrees of freedom its variance has."""
    m1, m2, m3 = (np.asarray(m, np.float64) for m in (m1, m2, m3))
    mu3 = m3 - 3.0 * m1 * m2 + 2.0 * m1 ** 3
    return mu3 * n * n / ((n - 1.0) * (n - 2.0)) / (n * n)


def accumulate(results: Iterable[JobResult]) -> list[Accumulator]:
    """The cumulative image after each of ``results`` (e.g. the jobs of a ladder, in order)."""
    out, acc = [], None
    for result in results:
        if acc is None:
            acc = Accumulator.empty(*result.image.shape[:2])
        acc.add_result(result)
        out.append(dataclasses.replace(acc))
    return out
