"""Render jobs as plain data: what to render, with which seed and sample offset.

Data flows one way: plan -> execute -> store -> analyse -> present. A
:class:`Job` is one render (a scene, a method, a resolution, a number of
samples per pixel, rendered in passes of at most ``pass_spp``); the planner
fixes its seed and, for samplers that continue one sequence (``halton``), its
sample offset, so the same plan gives the same images whichever process
(or cluster worker) runs it. ``key`` names its entry in the
:class:`~.store.JobStore` and is a hash of everything the image depends on.

A progressive render is a :func:`ladder` of jobs, one per stretch between
two sample counts; the analysis adds them up (:func:`accumulate`):
independent samplers get a new seed per stretch, ``halton`` keeps its seed
and continues the sequence (``sample_offset`` = samples already taken), so
the stretches together are exactly one render of all their samples.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import zlib
from dataclasses import dataclass

import numpy as np

from .methods import Depth, Method, SceneInfo, parse_method, plugins_version

#: Largest number of samples (pixels x spp) rendered in one pass; bigger jobs
#: render in several passes, which bounds memory (1024x512 -> 8 spp per pass).
MAX_LANES = 2**22


@dataclass(frozen=True)
class Job:
    """One render job: plain, picklable data."""
    key: str                    # stable unique id = the store entry name
    scene: str                  # scene XML path
    scene_sha256: str
    method: str                 # a method name (see experiments.lib.methods)
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

    @property
    def depth(self) -> Depth:
        return Depth(self.max_depth, self.rr_depth, self.hide_emitters)

    def method_obj(self) -> Method:
        return parse_method(self.method)

    def passes(self) -> list[int]:
        """The spp of each pass of this job."""
        cap = max(1, MAX_LANES // (self.width * self.height))
        cap = min(cap, self.pass_spp) if self.pass_spp else cap
        return [min(cap, self.spp - s) for s in range(0, self.spp, cap)]


def derive_seed(*parts) -> int:
    """A seed from any parts (distinct parts give distinct, stable seeds)."""
    return zlib.crc32("/".join(map(str, parts)).encode()) & 0x7FFFFFFF


def make_job(prefix: str, info: SceneInfo, method: str, width: int, height: int, spp: int,
             seed: int, depth: Depth, variant: str, sample_offset: int = 0, pass_spp: int = 0,
             timing_group: str | None = None) -> Job:
    """A :class:`Job` whose key is ``prefix`` + a hash of everything its image depends on
    (the plugin sources and the variant included)."""
    fields = dict(scene=info.path, scene_sha256=info.sha256, method=method, width=width,
                  height=height, spp=spp, seed=seed, sample_offset=sample_offset,
                  pass_spp=pass_spp, **dataclasses.asdict(depth))
    digest = hashlib.sha256(json.dumps([fields, variant, plugins_version()],
                                       sort_keys=True).encode()).hexdigest()[:12]
    safe = prefix.replace(":", "-").replace("+", "_")
    return Job(key=f"{safe}-{digest}", timing_group=timing_group, **fields)


def ladder(prefix: str, info: SceneInfo, method: str, width: int, height: int,
           targets, base_seed: int, depth: Depth, variant: str, pass_spp: int = 0,
           timing_group: str | None = None) -> list[Job]:
    """Jobs rendering ``method`` progressively to every sample count in ``targets``.

    Job ``i`` renders the samples between targets ``i-1`` and ``i``; the
    images at each target are :func:`accumulate` of the first jobs.
    """
    m = parse_method(method)
    jobs, done = [], 0
    for i, target in enumerate(sorted(set(int(t) for t in targets))):
        seed = derive_seed(base_seed, prefix, 0 if m.continues_sequence else i)
        jobs.append(make_job(f"{prefix}/spp{done:05d}-{target:05d}", info, method, width,
                             height, target - done, seed, depth, variant,
                             sample_offset=done if m.continues_sequence else 0,
                             pass_spp=pass_spp, timing_group=timing_group))
        done = target
    return jobs


def doubling_targets(max_spp: int, factor: int = 2) -> list[int]:
    """1, 2, 4, ... (or another factor) up to ``max_spp`` (always ending with ``max_spp``)."""
    targets, t = [], 1
    while t < max_spp:
        targets.append(t)
        t *= factor
    return targets + [max_spp]


@dataclass
class Accumulator:
    """Running mean of job images, weighted by their sample counts.

    ``sq`` is sum_i k_i m_i^2 over passes i with k_i samples and mean image
    m_i, from which :meth:`variance_of_mean` estimates per-pixel variances.
    """
    mean: np.ndarray
    sq: np.ndarray
    spp: int = 0
    passes: int = 0
    seconds: float = 0.0

    @classmethod
    def empty(cls, height: int, width: int, channels: int = 3) -> "Accumulator":
        shape = (height, width, channels)
        return cls(np.zeros(shape), np.zeros(shape))

    def add(self, image: np.ndarray, spp: int, seconds: float = 0.0, sq=None,
            passes: int = 1) -> None:
        """Fold in an image that averages ``spp`` samples per pixel (``passes`` passes whose
        sum of squares is ``sq``; one pass when None)."""
        image = np.asarray(image, np.float64)
        n = self.spp
        self.mean = (self.mean * n + image * spp) / (n + spp)
        self.sq = self.sq + (spp * image * image if sq is None else np.asarray(sq, np.float64))
        self.spp += spp
        self.passes += passes
        self.seconds += seconds

    def add_result(self, result) -> None:
        self.add(result.image, result.spp, result.seconds, result.sq, result.passes)

    def variance_of_mean(self) -> np.ndarray:
        """Per-pixel variance of :attr:`mean`, from the spread of the pass images.

        Per-sample variance: sum_i k_i (m_i - mean)^2 / (passes - 1)
        = (sq - spp * mean^2) / (passes - 1); divided by spp for the mean.
        """
        if self.passes < 2:
            return np.full_like(self.mean, np.inf)
        s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / (self.passes - 1)
        return s2 / self.spp


def accumulate(store, jobs: list[Job]) -> list[Accumulator]:
    """The cumulative image after each job of a :func:`ladder` (read from ``store``)."""
    out, acc = [], None
    for job in jobs:
        result = store.get(job.key)
        if acc is None:
            acc = Accumulator.empty(*result.image.shape[:2])
        acc.add_result(result)
        out.append(dataclasses.replace(acc))
    return out


def reference_jobs(info: SceneInfo, width: int, height: int, spp: int, method: str,
                   depth: Depth, variant: str, seed: int = 0, chunk_spp: int = 0) -> list[Job]:
    """The high-spp reference as jobs of ``chunk_spp`` samples (resumable pieces; by default
    at least 8, so that the spread of their images estimates the reference's own error)."""
    chunk = chunk_spp or max(1, min(MAX_LANES // (width * height), spp // 8))
    targets = list(range(chunk, spp, chunk)) + [spp]
    return ladder(f"reference/{method}-{width}x{height}-{spp}spp", info, method, width, height,
                  targets, seed, depth, variant)
