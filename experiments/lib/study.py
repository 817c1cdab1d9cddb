"""What every experiment script shares: the job store, the executor, the reference image.

A :class:`Study` is built from a study's typed settings (a
:class:`StudySettings`, or any value with the fields it reads, such as
the suite's settings), never from the command line. Scripts plan jobs
(:mod:`.plan`), hand them to :meth:`Study.run` (which executes what the store
lacks, :func:`.execute.execute`), then read the results back from the store
(:meth:`Study.accumulate`: the cumulative images of a ladder).
The store lives in ``<out>/store``; jobs that several experiments share (a
reference at the same settings) are rendered once.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from . import plan
from .execute import execute
from .jobs import Accumulator, Job, accumulate as accumulate_results, derive_seed
from .methods import Depth, Method
from .references import REFERENCES_DIR, RefSpec, ReferenceStore, chunk_spp_for
from .scenes import SceneInfo
from .store import STORE_DIR, JobStore


@dataclass(frozen=True)
class StudySettings:
    """What every study's typed settings share (a study subclasses it with its own
    options; :func:`.cli.common_fields` makes these fields from the command line): the
    field names :class:`Study` reads."""
    out: str                          # the report directory (``--out``)
    scene: str                        # the scene file
    info: SceneInfo
    resolution: tuple                 # (width, height)
    depth: Depth                      # the scene's path settings with --max-depth etc.
    methods: tuple                    # Method values, in order
    repeats: int                      # independent randomizations (--repeats)
    variant: str
    seed: int
    reference_spp: int
    reference_method: Method
    executor: object                  # a Dask executor, or None (the local loop)
    #: the reference store (``--reference-cache``); None: ``<out>/references``
    reference_cache: str | None = field(default=None, kw_only=True)
    #: the study's default --reference-spp, which sizes a reference's chunks whatever this
    #: run asks for (:func:`~..references.chunk_spp_for`); None: this run's reference_spp
    reference_spp_default: int | None = field(default=None, kw_only=True)
    #: an earlier run's --out whose equal-time counts are replayed (``--replay-counts``)
    replay_counts: str | None = field(default=None, kw_only=True)


def repeat_prefix(prefix: str, repeat: int) -> str:
    """Job prefix of repeat ``repeat`` (0: the prefix itself, so earlier single runs are
    reused as the first repeat; others: ``prefix/rN``, hence another seed)."""
    return prefix if repeat == 0 else f"{prefix}/r{repeat}"


class Study:
    """The stores, the executor and the job factory of one study run, made from its typed
    settings: a :class:`StudySettings` or any value with its fields
    ``out``, ``variant``, ``info``, ``depth``, ``seed``, ``resolution``, ``repeats``,
    ``reference_cache``, ``reference_spp``, ``reference_spp_default``,
    ``reference_method`` and ``executor``."""

    def __init__(self, settings, executor=None):
        self.settings = settings
        self.out = settings.out
        self.variant = settings.variant
        self.info: SceneInfo = settings.info
        self.depth: Depth = settings.depth
        self.seed = settings.seed
        self.width, self.height = settings.resolution
        self.store = JobStore(os.path.join(settings.out, STORE_DIR))
        #: The reference store every study and run shares (``--reference-cache``).
        self.references = ReferenceStore(settings.reference_cache
                                         or os.path.join(settings.out, REFERENCES_DIR))
        self.executor = executor if executor is not None else settings.executor
        self.repeats: int = settings.repeats
        #: an earlier run's --out whose equal-time counts are replayed (None: measure them)
        self.replay_counts: str | None = settings.replay_counts
        self._reference_of: dict[str, RefSpec] = {}       # chunk key -> its reference

    def run(self, jobs: list, label: str = "render jobs") -> int:
        """Execute the jobs the stores lack (reference chunks in the reference store, the
        others in the job store); return how many were rendered."""
        specs: dict[str, tuple[RefSpec, list]] = {}
        others = []
        for job in jobs:
            spec = self._reference_of.get(job.key)
            if spec is None:
                others.append(job)
            else:
                specs.setdefault(spec.key, (spec, []))[1].append(job)
        done = 0
        if specs:
            done += self.references.render(list(specs.values()), self.executor, self.variant,
                                           progress=f"{label} (references)")
        return done + execute(others, self.store, self.executor, progress=label,
                              variant=self.variant)

    def _store_of(self, job: Job):
        return self.references.store if job.key in self._reference_of else self.store

    def repeats_of(self, method: Method) -> int:
        """Independent randomizations rendered of ``method``: ``--repeats``, but 1 for a
        deterministic method (plain Halton: every run gives the same image)."""
        return 1 if method.deterministic else self.repeats

    def per_repeat(self, values) -> tuple:
        """Per-repeat values as a tuple of :attr:`repeats` entries: a deterministic method's
        one run (see :meth:`repeats_of`) stands for every repeat, its error has no spread."""
        values = tuple(values)
        return values * self.repeats if len(values) == 1 else values

    def job(self, prefix: str, method: Method, spp: int, info: SceneInfo | None = None,
            depth: Depth | None = None, **options) -> Job:
        """One job at this study's resolution, seed derived from the base seed and prefix."""
        width, height = options.pop("resolution", (self.width, self.height))
        return plan.make_job(prefix, info or self.info, method, width, height, spp,
                          derive_seed(self.seed, prefix), depth or self.depth, self.variant,
                          **options)

    def ladder(self, prefix: str, method: Method, targets, info: SceneInfo | None = None,
               depth: Depth | None = None, **options) -> list[Job]:
        width, height = options.pop("resolution", (self.width, self.height))
        return plan.ladder(prefix, info or self.info, method, width, height, targets, self.seed,
                        depth or self.depth, self.variant, **options)

    def reference_jobs(self, info: SceneInfo | None = None, depth: Depth | None = None,
                       resolution=None, spp: int | None = None,
                       method: Method | None = None,
                       typical_spp: int | None = None) -> list[Job]:
        """The chunks of a reference in the shared reference store
        (:mod:`.references`: keyed by the scene's content, not by the study, and extended in
        place for more samples): ``spp`` (default ``--reference-spp``) of ``method``
        (default ``--reference-method``) at ``resolution`` (default the study's), in chunks
        of :func:`.references.chunk_spp_for` the film and ``typical_spp`` (default: the
        study's own default ``--reference-spp``, whatever this run asks for)."""
        width, height = resolution or (self.width, self.height)
        spp = spp or self.settings.reference_spp
        typical = typical_spp or self.settings.reference_spp_default or spp
        spec = RefSpec(info or self.info, width, height, depth or self.depth,
                       method or self.settings.reference_method, self.variant,
                       chunk_spp_for(width, height, typical))
        jobs = self.references.plan(spec, spp)
        self._reference_of.update((j.key, spec) for j in jobs)
        return jobs

    def results(self, jobs: list[Job]) -> list:
        """The stored results of ``jobs``, from the store that holds each (job store or
        reference store)."""
        return [self._store_of(j).get(j.key) for j in jobs]

    def accumulate(self, jobs: list[Job]) -> list[Accumulator]:
        """The cumulative image after each of ``jobs`` (a ladder, in order)."""
        return accumulate_results(self.results(jobs))

    def reference(self, jobs: list[Job], every_cached: bool = False) -> tuple[np.ndarray, dict]:
        """The reference image of ``jobs`` (:meth:`reference_jobs`) and its metadata (render
        seconds, passes, and the expected error of the reference itself, the floor under
        every measured error: ``mse_floor``, ``relmse_floor``, ``relmse_floor_map``);
        ``every_cached``: of every chunk the store holds of that reference (an earlier run
        may have extended it), at least ``jobs``."""
        if every_cached:
            ref = self.references.read(self._reference_of[jobs[0].key], None)
        else:
            ref = self.references.read_jobs(jobs)
        return ref.image, ref.meta()

    def timed_on(self, jobs: list[Job]) -> str:
        """Which machine (host, CPU) measured the render times that each comparison of
        ``jobs`` divides (their ``timing_group``), read from the store."""
        groups: dict[str, set] = {}
        for j in jobs:
            if j.timing_group is not None:
                r = self.store.get(j.key)
                groups.setdefault(j.timing_group, set()).add(f"{r.host}, {r.cpu}")
        machines = set().union(*groups.values())
        if not machines:
            return "(no timed comparison)"
        if len(machines) == 1:
            return machines.pop()
        return "; ".join(f"{g}: {' + '.join(sorted(m))}" for g, m in sorted(groups.items()))

    def describe_reference(self, meta: dict) -> str:
        return (f"{meta['spp']} spp of {meta['method']} (NEE + MIS), {meta['passes']} chunks, "
                f"{meta['seconds']:.1f} s; its own expected MSE about {meta['mse_floor']:.1e} "
                f"(relMSE {meta['relmse_floor']:.1e}), estimated from the spread of its "
                f"passes and subtracted from every expected MSE and relMSE")
