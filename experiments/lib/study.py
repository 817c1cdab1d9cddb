"""What every experiment script shares: the job store, the executor, the reference image.

A :class:`Study` is built from the parsed arguments. Scripts plan jobs
(:mod:`.plan`), hand them to :meth:`Study.run` (which executes what the store
lacks, :func:`.execute.execute`), then read the results back from the store
(:meth:`Study.accumulate`: the cumulative images of a ladder).
The store lives in ``<out>/store``; jobs that several experiments share (a
reference at the same settings) are rendered once.
"""
from __future__ import annotations

import os

import numpy as np

from . import plan as P
from .execute import execute
from .jobs import Accumulator, Job, accumulate as accumulate_results, derive_seed
from .methods import Depth, Method
from .scenes import SceneInfo
from .metrics import RELMSE_EPS
from .store import STORE_DIR, JobStore


def repeat_prefix(prefix: str, repeat: int) -> str:
    """Job prefix of repeat ``repeat`` (0: the prefix itself, so earlier single runs are
    reused as the first repeat; others: ``prefix/rN``, hence another seed)."""
    return prefix if repeat == 0 else f"{prefix}/r{repeat}"


class Study:
    def __init__(self, args, executor=None):
        self.args = args
        self.out = args.out
        self.variant = args.variant
        self.info: SceneInfo = args.info
        self.depth: Depth = args.depth
        self.seed = args.seed
        self.width, self.height = args.resolution
        self.store = JobStore(os.path.join(args.out, STORE_DIR))
        self.executor = executor if executor is not None else getattr(args, "executor", None)
        self.repeats: int = getattr(args, "repeats", 1)

    def run(self, jobs: list, label: str = "render jobs") -> int:
        """Execute the jobs the store lacks; return how many were rendered."""
        return execute(jobs, self.store, self.executor, progress=label, variant=self.variant)

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
        return P.make_job(prefix, info or self.info, method, width, height, spp,
                          derive_seed(self.seed, prefix), depth or self.depth, self.variant,
                          **options)

    def ladder(self, prefix: str, method: Method, targets, info: SceneInfo | None = None,
               depth: Depth | None = None, **options) -> list[Job]:
        width, height = options.pop("resolution", (self.width, self.height))
        return P.ladder(prefix, info or self.info, method, width, height, targets, self.seed,
                        depth or self.depth, self.variant, **options)

    def reference_jobs(self, info: SceneInfo | None = None, depth: Depth | None = None,
                       resolution=None) -> list[Job]:
        width, height = resolution or (self.width, self.height)
        return P.reference_jobs(info or self.info, width, height, self.args.reference_spp,
                                self.args.reference_method, depth or self.depth, self.variant,
                                self.seed)

    def accumulate(self, jobs: list[Job]) -> list[Accumulator]:
        """The cumulative image after each of ``jobs`` (a ladder, in order), from the store."""
        return accumulate_results(self.store.results(jobs))

    def reference(self, jobs: list[Job]) -> tuple[np.ndarray, dict]:
        """The reference image of ``jobs`` and its metadata (render seconds, passes, and the
        expected MSE of the reference itself, the floor under every measured MSE)."""
        acc = self.accumulate(jobs)[-1]
        var = acc.variance_of_mean()
        rel = var / (acc.mean ** 2 + RELMSE_EPS)     # per pixel and channel, for masked errors
        return acc.mean, {"seconds": acc.seconds, "passes": acc.passes, "spp": acc.spp,
                          "method": jobs[0].method.name, "mse_floor": float(np.mean(var)),
                          "relmse_floor": float(np.mean(rel)), "relmse_floor_map": rel}

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
        return (f"{meta['spp']} spp of {meta['method']} (NEE + MIS), {meta['passes']} passes, "
                f"{meta['seconds']:.1f} s; its own expected MSE about {meta['mse_floor']:.1e} "
                f"(relMSE {meta['relmse_floor']:.1e}), estimated from the spread of its "
                f"passes and subtracted from every expected MSE and relMSE")
