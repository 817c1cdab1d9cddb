"""What the engine measured: every run of every cell, against its reference.

* :class:`Run`: one repeat of a cell (one rung of a ladder): its count, its cost by the one
  clock (:mod:`.clock`), its errors against the reference, its image;
* :class:`Measurements`: the runs of every cell, the references, the jobs each cell was
  made of, the cells that failed and each scene's equal-time factor; errors and
  efficiencies with their intervals from :mod:`.stats`;
* :func:`rungs`: a run's rungs from its stored results: a ladder of stretches accumulates
  (every rung all samples up to its count, costed cumulatively); a learning method's
  ladder is one job per rung (each trained at its own count, costed alone).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import clock, metrics, stats
from .declaration import Cell, Declaration
from .jobs import Accumulator, accumulate


@dataclass
class Run:
    """One repeat of a cell (one rung of a ladder): what it rendered and cost, its errors
    against the reference (the reference's own floor not subtracted)."""
    spp: int
    cost: float
    mse: float
    relmse: float
    image: np.ndarray
    overhead: float = 0.0        # seconds the clock does not count (tracing, launching)
    variance: np.ndarray | None = None   # per pixel, of the image (from its passes' spread;
                                         # None with fewer than two passes, or passes
                                         # of one sequence)
    variance_var: np.ndarray | None = None   # per pixel, the variance of ``variance`` as an
                                             # estimate (from the samples' fourth moments;
                                             # None where they are unknown)
    third: np.ndarray | None = None     # per pixel, the third cumulant of the image (from
                                        # the samples' third moments; None where unknown)


def rungs(results: list, ref: np.ndarray, independent: bool = False,
          spread: bool = True) -> list[Run]:
    """A run's :class:`Run` per rung from its jobs' ``results``: the images accumulated over
    the jobs (a ladder of stretches), or each job alone where ``independent`` (a learning
    method's ladder: one job per rung, each its own training run). ``spread``: whether the
    passes are independent estimates, so that their spread is the image's variance (not
    for a sampler whose passes continue one sequence: the parts of one Owen-scrambled
    Sobol' sequence are not independent, their spread is no variance)."""
    if independent:
        accs = []
        for r in results:
            acc = Accumulator.empty(*r.image.shape[:2])
            acc.add_result(r)
            accs.append(acc)
        overheads = [clock.overhead(r) for r in results]
    else:
        accs = accumulate(results)
        overheads = np.cumsum([clock.overhead(r) for r in results])
    return [Run(acc.spp, acc.cost, metrics.mse(acc.mean, ref), metrics.relmse(acc.mean, ref),
                acc.mean, float(overhead),
                acc.variance_of_mean() if spread and acc.passes > 1 else None,
                acc.variance_of_variance() if spread else None,
                acc.third_of_mean() if spread else None)
            for acc, overhead in zip(accs, overheads)]


@dataclass
class Measurements:
    """Every run of every cell, and the references they were measured against."""
    declaration: Declaration
    runs: dict                   # Cell -> [per repeat: [Run per rung (one without a ladder)]]
    references: dict             # (scene, point) -> (image, metadata with the floors)
    jobs: dict = field(default_factory=dict)   # Cell -> [per repeat rendered: [jobs]]
    #: (scene, point, method) -> the error of a cell whose renders failed (the declaration's
    #: ``isolate_failures``); its cells have no runs
    failed: dict = field(default_factory=dict)
    #: (scene, point, budget) -> (the factor of an equal-time budget's seconds there, the
    #: note of the policy that decided it)
    scales: dict = field(default_factory=dict)
    #: (scene, point) -> why a scene has no cells (its reference failed to render)
    scene_errors: dict = field(default_factory=dict)

    def all_jobs(self) -> list:
        """Every job the cells were made of (e.g. for :meth:`.study.Study.timed_on`)."""
        return [j for reps in self.jobs.values() for jobs in reps for j in jobs]

    def failed_on(self, scene: str, point=None) -> dict:
        """{method: error} of the cells of ``scene`` (at ``point``) that failed."""
        return {m: e for (s, p, m), e in self.failed.items() if s == scene and p == point}

    def reference_of(self, cell: Cell) -> tuple:
        return self.references[self.reference_key(cell)]

    def reference_key(self, cell: Cell) -> tuple:
        """The (scene, point) of ``cell``'s reference (point None where the sweep shares it)."""
        return self.declaration.reference_key(cell.scene, cell.point)

    def floor(self, cell: Cell, metric: str = "relmse") -> float:
        return float(self.reference_of(cell)[1][f"{metric}_floor"])

    def final(self, cell: Cell) -> list[Run]:
        """The last rung of each repeat (the cell's image)."""
        return [rungs[-1] for rungs in self.runs[cell]]

    def error(self, cell: Cell, metric: str = "relmse", rung: int = -1) -> stats.Estimate:
        """The cell's expected error (floor subtracted) with its interval."""
        values = [getattr(rungs[rung], metric) for rungs in self.runs[cell]]
        return stats.excess_interval(values, self.floor(cell, metric))

    def efficiency(self, a: Cell, b: Cell, metric: str = "relmse",
                   rung: int = -1) -> stats.Estimate:
        """Efficiency 1/(error x cost) of ``a`` over ``b`` with its interval (errors less
        their floors, costs from the clock, per repeat); exactly 1 for a cell against itself."""
        if a == b:
            return stats.Estimate(1.0, 1.0, 1.0, len(self.runs[a]))
        ea, eb = ([getattr(r[rung], metric) - self.floor(c, metric) for r in self.runs[c]]
                  for c in (a, b))
        ca, cb = ([r[rung].cost for r in self.runs[c]] for c in (a, b))
        return stats.efficiency_ratio(ea, ca, eb, cb)
