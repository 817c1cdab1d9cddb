"""The experiment engine: a study declares what it compares, the engine does the rest.

A :class:`Declaration` names the methods, the scenes (each with its film and path
settings), the budgets (equal spp, equal time, a ladder of counts), a swept parameter if
any, and the repeats. :class:`Engine` then

1. plans the jobs (:mod:`.plan`: keys and seeds from the plan, a deterministic method
   rendered once for every repeat, the references in the shared reference store);
2. renders what the stores lack through the study's executor (local or Dask; a rerun
   resumes), the equal-time budgets after the budgets that measure their cost per sample
   (or at the counts of an earlier run: ``--replay-counts``, :meth:`Engine.replayed`), each
   job in the passes the declaration asks for (``pass_spp``: per-pixel variances from
   their spread) or with its samples' second moments (``sample_moments``);
3. costs every image with the one clock (:mod:`.clock`) and measures its errors against
   the reference (whose own expected error, the floor, comes with it);
4. gives errors, ratios and efficiencies with their intervals from one implementation
   (:mod:`.stats`), in :class:`Measurements`.

A study adds its own analysis and figures over :class:`Measurements`.
``examples/roulette_study.py`` is a whole study in this form. Models: SeeSharp's
``Experiment`` and ``Benchmark`` (a list of methods over a list of scenes against cached
references), Mitsuba's ``ADIntegrator`` (the shared work in one base).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from . import clock, metrics, stats
from .jobs import accumulate
from .methods import Depth, Method
from .plan import job_name
from .scenes import SceneInfo
from .store import STORE_DIR, JobStore, ReplayError
from .study import Study, repeat_prefix


@dataclass(frozen=True)
class SceneSetup:
    """A scene as a study renders it: its file, film and path settings, and a short name
    (its part of the job keys and of the report)."""
    name: str
    info: SceneInfo
    resolution: tuple            # (width, height)
    depth: Depth = Depth()


@dataclass(frozen=True)
class Budget:
    """How much every method renders in a cell. Make one with :meth:`equal_spp`,
    :meth:`equal_time` or :meth:`progressive`."""
    name: str
    spp: int = 0                 # equal spp: the count
    seconds: float = 0.0         # equal time: seconds of cost (the clock) per image ...
    after: str = ""              # ... at the cost per sample measured by this budget's renders
    power_of_two: bool = False   # equal time: the count rounded to the nearest power of two
    max_spp: int = 0             # equal time: at most this count (0: no cap)
    ladder: tuple = ()           # progressive: the counts, each image all samples up to it

    @classmethod
    def equal_spp(cls, spp: int, name: str = "equal-spp") -> "Budget":
        return cls(name, spp=int(spp))

    @classmethod
    def equal_time(cls, seconds: float, after: str = "equal-spp", name: str = "equal-time",
                   power_of_two: bool = False, max_spp: int = 0) -> "Budget":
        return cls(name, seconds=float(seconds), after=after, power_of_two=power_of_two,
                   max_spp=int(max_spp))

    @classmethod
    def progressive(cls, targets, name: str = "ladder") -> "Budget":
        return cls(name, ladder=tuple(sorted({int(t) for t in targets})))

    @property
    def timed(self) -> bool:
        return self.seconds > 0


@dataclass(frozen=True)
class Sweep:
    """A swept parameter: ``apply(value, scene)`` gives the scene set up at ``value`` (its
    depth, film or file). ``shared_reference``: the parameter changes the estimator, not
    the image it converges to (rr_depth), so every value is measured against the reference
    of the scene as declared."""
    name: str
    values: tuple
    apply: Callable[[object, SceneSetup], SceneSetup]
    shared_reference: bool = False


@dataclass(frozen=True)
class Cell:
    """One comparison point: a scene, a method, a budget and (in a sweep) a value."""
    scene: str
    method: str
    budget: str
    point: object = None


def default_key(declaration: "Declaration", cell: Cell) -> str:
    """``NAME/scene/method/budget[/sweep=value]``: the prefix of a cell's jobs."""
    point = "" if cell.point is None else f"/{declaration.sweep.name}={cell.point}"
    return f"{declaration.name}/{cell.scene}/{cell.method}/{cell.budget}{point}"


@dataclass(frozen=True)
class Declaration:
    """What a study compares. ``key(declaration, cell)`` names a cell's jobs (their seeds
    derive from it; default :func:`default_key`), the repeat and ladder parts appended."""
    name: str
    methods: tuple               # Method values
    scenes: tuple                # SceneSetup values
    budgets: tuple               # Budget values, in the order they render
    repeats: int = 1
    sweep: Sweep | None = None
    reference_spp: int | None = None        # None: the study's --reference-spp
    reference_method: Method | None = None  # None: the study's --reference-method
    reference_typical_spp: int | None = None  # sizes the reference's chunks (None: the study's)
    key: Callable = default_key
    #: (method, spp, repeat) -> the samples per pass of a cell's jobs (0: as many as memory
    #: allows): passes give per-pixel variances from their spread (a job key field)
    pass_spp: Callable | None = None
    #: method -> whether a cell's jobs (of budgets without a ladder) keep their samples'
    #: per-pixel second moments (``vr_moments``: every sample its own pass; for independent
    #: samples under a box filter only; a job key field)
    sample_moments: Callable | None = None

    def __post_init__(self):
        names = [b.name for b in self.budgets]
        for b in self.budgets:
            if b.timed and b.after not in names[:names.index(b.name)]:
                raise ValueError(f"budget '{b.name}' measures its cost per sample on budget "
                                 f"'{b.after}', which must come before it among "
                                 f"{', '.join(names)}")
        if not self.methods or not self.scenes or not self.budgets or self.repeats < 1:
            raise ValueError(f"declaration '{self.name}': give at least one method, scene "
                             f"and budget, and repeats >= 1 (got {self.repeats})")

    def points(self) -> tuple:
        return self.sweep.values if self.sweep else (None,)

    def setup(self, scene: SceneSetup, point) -> SceneSetup:
        return scene if point is None else self.sweep.apply(point, scene)

    def cells(self, budget: Budget) -> list[tuple[Cell, SceneSetup, Method]]:
        return [(Cell(s.name, m.name, budget.name, p), self.setup(s, p), m)
                for s in self.scenes for p in self.points() for m in self.methods]


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
                                         # None with fewer than two passes)


@dataclass
class Measurements:
    """Every run of every cell, and the references they were measured against."""
    declaration: Declaration
    runs: dict                   # Cell -> [per repeat: [Run per rung (one without a ladder)]]
    references: dict             # (scene, point) -> (image, metadata with the floors)
    jobs: dict = field(default_factory=dict)   # Cell -> [per repeat rendered: [jobs]]

    def all_jobs(self) -> list:
        """Every job the cells were made of (e.g. for :meth:`.study.Study.timed_on`)."""
        return [j for reps in self.jobs.values() for jobs in reps for j in jobs]

    def reference_of(self, cell: Cell) -> tuple:
        return self.references[self._reference_key(cell)]

    def _reference_key(self, cell: Cell):
        sweep = self.declaration.sweep
        return (cell.scene, None if sweep is None or sweep.shared_reference else cell.point)

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


class Engine:
    """Plans, renders and measures a :class:`Declaration` with a :class:`.study.Study`'s
    stores and executor."""

    def __init__(self, study: Study):
        self.study = study
        self._replay: dict | None = None       # {job name: spp} of --replay-counts

    # ---------------------------------------------------------------- plan
    def jobs(self, declaration: Declaration, budget: Budget, spp: dict | None = None) -> dict:
        """{cell: [per repeat: [jobs]]} of one budget (``spp``: an equal-time budget's count
        per cell). A deterministic method renders one run, which stands for every repeat."""
        st, out = self.study, {}
        for cell, setup, method in declaration.cells(budget):
            prefix = declaration.key(declaration, cell)
            options = self._options(declaration, cell, setup)
            repeats = 1 if method.deterministic else declaration.repeats
            count = (budget.ladder[-1] if budget.ladder else
                     spp[cell] if budget.timed else budget.spp)
            moments = bool(declaration.sample_moments and declaration.sample_moments(method))
            runs = []
            for r in range(repeats):
                passes = declaration.pass_spp(method, count, r) if declaration.pass_spp else 0
                runs.append(st.ladder(repeat_prefix(prefix, r), method, budget.ladder,
                                      pass_spp=passes, **options) if budget.ladder else
                            [st.job(repeat_prefix(prefix, r), method, count,
                                    pass_spp=passes, sample_moments=moments, **options)])
            out[cell] = runs
        return out

    @staticmethod
    def _options(declaration: Declaration, cell: Cell, setup: SceneSetup) -> dict:
        """The job options of a cell's renders (scene, depth, film, timing group)."""
        return dict(info=setup.info, depth=setup.depth, resolution=setup.resolution,
                    timing_group=f"{declaration.name}/{cell.scene}")

    def piloted_spp(self, declaration: Declaration, cell: Cell, budget: Budget,
                    count: int) -> int:
        """A learning method's equal-time count (:attr:`.methods.Method.learns`): ``count``
        (what its equal-spp renders' cost per sample gives) is rendered once as a pilot,
        kept in the store and in no comparison, and the count comes from the pilot's cost
        per sample. Equal-spp renders too short to train cost what plain BSDF sampling
        costs, while a render that trains records, refines and guides: at their cost per
        sample its equal-time render would take about twice the budget, and the efficiency
        of a method whose training pays more the longer it runs would be measured with more
        time than the others had. For the same reason the count is the budget's own, never
        rounded to a power of two (:attr:`Budget.power_of_two`, which could give it from
        0.71 to 1.41 times the budget: a learning method's efficiency would then follow the
        rounding, and two runs whose pilots cost a few percent apart could measure it at
        counts a factor of two apart). The pilot renders once (:attr:`.jobs.Job.pilot`),
        not again warm: the view its equal-spp renders warmed did not train, so its
        kernels compile in it."""
        setup, method = next((s, m) for c, s, m in declaration.cells(budget) if c == cell)
        moments = bool(declaration.sample_moments and declaration.sample_moments(method))
        job = self.study.job(f"{declaration.key(declaration, cell)}/pilot", method, count,
                             sample_moments=moments, pilot=True,
                             **self._options(declaration, cell, setup))
        self.study.run([job], f"{declaration.name}: pilot")
        return self.equal_time_spp(budget, [self.study.results([job])], exact=True)

    def reference_jobs(self, declaration: Declaration) -> dict:
        """{(scene, point): the chunks of its reference} in the shared reference store."""
        out = {}
        for scene in declaration.scenes:
            for point in declaration.points():
                shared = declaration.sweep is None or declaration.sweep.shared_reference
                key = (scene.name, None if shared else point)
                if key in out:
                    continue
                setup = scene if shared else declaration.setup(scene, point)
                out[key] = self.study.reference_jobs(
                    setup.info, setup.depth, setup.resolution, declaration.reference_spp,
                    declaration.reference_method, declaration.reference_typical_spp)
        return out

    def equal_time_spp(self, budget: Budget, measured: list, exact: bool = False) -> int:
        """Samples per pixel that cost ``budget.seconds`` at the cost per sample of the
        ``measured`` renders (each repeat's, averaged), their fixed cost per job
        (:func:`.clock.fixed`: a learning method's host work between passes, which a short
        render would otherwise spread over its few samples) taken off the budget first;
        rounded to a power of two where the budget says so, unless ``exact``."""
        fixed = np.mean([sum(clock.fixed(r) for r in rs) / len(rs) for rs in measured])
        per_sample = np.mean([(clock.total(rs) - sum(clock.fixed(r) for r in rs)) /
                              sum(r.spp for r in rs) for rs in measured])
        spp = (budget.seconds - float(fixed)) / max(float(per_sample), 1e-12)
        if budget.power_of_two and not exact:
            spp = 2 ** max(0, round(math.log2(max(spp, 1.0))))
        spp = max(1, int(spp))
        return min(spp, budget.max_spp) if budget.max_spp else spp

    def replayed(self, declaration: Declaration, cell: Cell) -> int | None:
        """The count an earlier run (``--replay-counts``) gave ``cell``'s first repeat, or
        None without one; an earlier run that lacks the job is an error."""
        if self.study.replay_counts is None:
            return None
        if self._replay is None:
            self._replay = JobStore(os.path.join(self.study.replay_counts, STORE_DIR)).counts()
        name = job_name(repeat_prefix(declaration.key(declaration, cell), 0))
        if name not in self._replay:
            raise ReplayError(f"--replay-counts {self.study.replay_counts}: no job '{name}' in "
                              f"its store, so its equal-time count cannot be replayed (that run "
                              f"did not render this method or budget)")
        return self._replay[name]

    # ---------------------------------------------------------------- run
    def references(self, declaration: Declaration) -> dict:
        """{(scene, point): (reference image, its metadata with the floors)}, rendered where
        the reference store lacks them."""
        jobs = self.reference_jobs(declaration)
        self.study.run([j for chunks in jobs.values() for j in chunks],
                       f"{declaration.name}: references")
        return {key: self.study.reference(chunks) for key, chunks in jobs.items()}

    def run(self, declaration: Declaration, references: dict | None = None) -> Measurements:
        """Plan, render (resuming) and measure every cell of ``declaration``, against
        ``references`` ({(scene, point): (image, metadata)}; default :meth:`references`)."""
        st = self.study
        refs = self.references(declaration) if references is None else references
        planned = {}
        for budget in declaration.budgets:
            spp = None
            if budget.timed:
                spp = {}
                for cell, reps in planned[budget.after].items():
                    cell = replace(cell, budget=budget.name)
                    spp[cell] = self.replayed(declaration, cell) or self.equal_time_spp(
                        budget, [st.results(jobs) for jobs in reps])
            planned[budget.name] = self.jobs(declaration, budget, spp)
            st.run([j for reps in planned[budget.name].values() for jobs in reps
                    for j in jobs], f"{declaration.name}: {budget.name}")
        return self.measure(declaration, planned, refs)

    def measure(self, declaration: Declaration, planned: dict, refs: dict) -> Measurements:
        """The :class:`Measurements` of rendered ``planned`` jobs against ``refs``."""
        out = Measurements(declaration, {}, refs)
        for cells in planned.values():
            for cell, reps in cells.items():
                ref = out.reference_of(cell)[0]
                runs = [self._rungs(jobs, ref) for jobs in reps]
                out.runs[cell] = runs * (declaration.repeats if len(runs) == 1 else 1)
                out.jobs[cell] = reps
        return out

    def _rungs(self, jobs: list, ref: np.ndarray) -> list[Run]:
        """A run's :class:`Run` per rung: the images accumulated over its jobs."""
        results = self.study.results(jobs)
        overheads = np.cumsum([clock.overhead(r) for r in results])
        return [Run(acc.spp, acc.cost, metrics.mse(acc.mean, ref), metrics.relmse(acc.mean, ref),
                    acc.mean, float(overhead),
                    acc.variance_of_mean() if acc.passes > 1 else None)
                for acc, overhead in zip(accumulate(results), overheads)]
