"""The experiment engine: a study declares what it compares, the engine does the rest.

A study hands a :class:`~.declaration.Declaration` (methods, scenes, budgets, a sweep,
repeats, policies) to :meth:`Engine.run`, the only budget loop of the project. For each
scene (locally one after another, so that each stays loaded; on a cluster all at once, so
that they fan out) the engine

1. renders the scene's reference where the shared reference store lacks it (or takes the
   study's own image);
2. renders every budget in order, its methods in groups a process keeps warm (the
   declaration's ``lead`` methods first), the budgets whose counts are known up front
   together and each group's renders interleaved (repeat by repeat, every method at one
   count before the next), so that a drifting machine load affects every method alike;
3. decides every count: equal spp as declared; a ladder as stretches that accumulate, or
   for a method that learns one job per rung that trains at that count; equal time from
   the cost per sample an earlier budget measured (:mod:`.counts`), times the scene's
   factor (its own, or a :class:`~.declaration.TimeScale` policy's, decided once after the
   earlier budgets), and for a method that learns or samples adaptively from a pilot render
   at that count (:meth:`Engine.pilot`, :func:`.engine_pilots.adaptive_count`), exact; or the counts
   of an earlier run (``--replay-counts``);
4. where the declaration says so, records a failing cell and goes on
   (``isolate_failures``), and extends a reference too noisy for the comparison
   (``reference_floor``);
5. costs every image with the one clock (:mod:`.clock`) and measures its errors against
   the reference, in :class:`~.measurements.Measurements`.

Every study (convergence, samplers, the writeup's figures, the lab's screen pass, the
stability sweeps, the scene suite) is a declaration over this loop, so a method is the
same method in all of them. ``examples/roulette_study.py`` is a whole study in this form.
Models: SeeSharp's ``Experiment`` and ``Benchmark`` (a list of methods over a list of
scenes against cached references), Mitsuba's ``ADIntegrator`` (the shared work in one base).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

from . import counts, engine_pilots, engine_references
from .declaration import (Budget, Cell, Declaration, ReferenceFloor, SceneSetup,  # noqa: F401
                          Sweep, TimeScale, default_key)
from .execute import VIEW_CACHE
from .measurements import Measurements, Run, rungs  # noqa: F401  (the engine's results)
from .names import one_line
from .plan import job_name
from .references import MIN_CHUNKS
from .store import STORE_DIR, JobStore, ReplayError
from .study import Study, repeat_prefix

#: About how many times plain BSDF sampling's cost per sample a learning method's render
#: that trains costs (the guide: 1.6 to 2.4 on the suite's guiding scenes, training
#: included): its pilot's count is the plain count over this (:meth:`Engine.pilot`).
LEARNER_COST = 2.0


@dataclass
class Planned:
    """A declaration's jobs as the engine planned and rendered them."""
    jobs: dict = field(default_factory=dict)      # {budget: {Cell: [per repeat: [Job]]}}
    failed: dict = field(default_factory=dict)    # (scene, point, method) -> error
    scales: dict = field(default_factory=dict)    # (scene, point, budget) -> (factor, note)
    scene_errors: dict = field(default_factory=dict)   # (scene, point) -> error

    def runs(self, cell: Cell) -> list:
        """[per repeat: [Job]] of ``cell`` ([] where it was not planned)."""
        return self.jobs.get(cell.budget, {}).get(cell, [])

    def add(self, budget: str, cells: dict) -> None:
        self.jobs.setdefault(budget, {}).update(cells)


@dataclass(frozen=True)
class Slot:
    """A method on a scene at a sweep point: a cell without its budget."""
    scene: SceneSetup            # as declared (its name keys the cells)
    setup: SceneSetup            # as rendered at ``point``
    point: object
    method: object               # a Method

    def cell(self, budget: str) -> Cell:
        return Cell(self.scene.name, self.method.name, budget, self.point)

    @property
    def failure_key(self) -> tuple:
        return (self.scene.name, self.point, self.method.name)


class Engine:
    """Plans, renders and measures a :class:`~.declaration.Declaration` with a
    :class:`.study.Study`'s stores and executor."""

    def __init__(self, study: Study):
        self.study = study
        self._replay: dict | None = None       # {job name: spp} of --replay-counts

    # ---------------------------------------------------------------- plan
    def jobs(self, declaration: Declaration, budget: Budget, spp: dict | None = None,
             slots: list | None = None) -> dict:
        """{cell: [per repeat: [jobs]]} of one budget over ``slots`` (default: every cell;
        ``spp``: an equal-time budget's count per cell). A deterministic method renders one
        run, which stands for every repeat. A ladder is stretches that accumulate, but for a
        method that learns: one job per rung, each its own training run."""
        out = {}
        for slot in slots if slots is not None else self.slots(declaration):
            cell, method = slot.cell(budget.name), slot.method
            prefix = declaration.key(declaration, cell)
            options = self._options(declaration, cell, slot.setup)
            count = (budget.ladder[-1] if budget.ladder else
                     spp[cell] if budget.timed else budget.spp)
            moments = declaration.moments(method, slot.setup) and not budget.ladder
            runs = []
            for r in range(1 if method.deterministic else declaration.repeats):
                passes = declaration.pass_spp(method, count, r) if declaration.pass_spp else 0
                name = repeat_prefix(prefix, r)
                if budget.ladder and method.learns:
                    runs.append([self.study.job(f"{name}/spp{t:05d}", method, t,
                                                pass_spp=passes, **options)
                                 for t in budget.ladder])
                elif budget.ladder:
                    runs.append(self.study.ladder(name, method, budget.ladder,
                                                  pass_spp=passes, **options))
                else:
                    runs.append([self.study.job(name, method, count, pass_spp=passes,
                                                sample_moments=moments, **options)])
            out[cell] = runs
        return out

    def slots(self, declaration: Declaration, scenes=None) -> list[Slot]:
        """Every (scene, point, method) of ``declaration`` (of ``scenes``: [(scene,
        point)]), the declaration's ``lead`` methods first on each scene."""
        scenes = scenes or [(s, p) for s in declaration.scenes for p in declaration.points()]
        return [Slot(s, declaration.setup(s, p), p, m)
                for s, p in scenes for m in declaration.methods_on(s)]

    @staticmethod
    def _options(declaration: Declaration, cell: Cell, setup: SceneSetup) -> dict:
        """The job options of a cell's renders (scene, depth, film, timing group)."""
        return dict(info=setup.info, depth=setup.depth, resolution=setup.resolution,
                    timing_group=f"{declaration.name}/{cell.scene}")

    # ---------------------------------------------------------------- counts
    def count(self, declaration: Declaration, budget: Budget, slot: Slot, planned: Planned
              ) -> int:
        """The equal-time count of ``slot`` at ``budget``: an earlier run's
        (``--replay-counts``), else the budget's seconds times the scene's factor at the
        cost per sample its ``after`` budget measured (:func:`.counts.equal_time_spp`), and
        for a method that learns the count of a pilot render (:meth:`pilot`)."""
        cell = slot.cell(budget.name)
        replayed = self.replayed(declaration, cell)
        if replayed is not None:
            return replayed
        factor = planned.scales.get((slot.scene.name, slot.point, budget.name),
                                    (slot.scene.time_scale, ""))[0]
        seconds = budget.seconds * factor
        measured = [self.study.results(jobs) for jobs in planned.runs(slot.cell(budget.after))]
        if slot.method.learns:
            return self.pilot(declaration, budget, slot, measured, seconds)
        if slot.method.adaptive:
            return engine_pilots.adaptive_count(self, declaration, budget, slot, measured,
                                                seconds)
        return counts.equal_time_spp(seconds, measured, budget.power_of_two, budget.max_spp)

    def pilot(self, declaration: Declaration, budget: Budget, slot: Slot, measured: list,
              seconds: float) -> int:
        """A learning method's equal-time count (:attr:`.methods.Method.learns`): a pilot
        render, kept in the store and in no comparison, and the count that costs
        ``seconds`` at the pilot's cost per sample, exact (:func:`.counts.learner_spp`,
        which also decides a budget between its training regimes). Where even the count
        the ``measured`` renders give does not train, the method is its plain counterpart
        at that count, and that count (from every repeat's renders, not one pilot's,
        rounded as a plain method's is where that count does not train either) is its
        count: no pilot. Elsewhere their cost per sample gives too many samples: they were
        too short to train and cost what plain BSDF sampling costs, while a render that
        trains records, refines and guides, at about :data:`LEARNER_COST` times the cost
        per sample. So the pilot renders their count over :data:`LEARNER_COST` (nearer the
        count it finds, at half the time) where that count trains as theirs would
        (:meth:`.methods.Method.trains`), else theirs. It renders once
        (:attr:`.jobs.Job.pilot`), not again warm: the view its short renders warmed did
        not train, so its kernels compile in it."""
        pixels = slot.setup.resolution[0] * slot.setup.resolution[1]

        def trains(spp: int) -> bool:
            return slot.method.trains(spp, pixels)
        plain = counts.equal_time_spp(seconds, measured, False, budget.max_spp)
        if not trains(plain):       # it does not train at its budget: their cost is its cost
            # and it is a plain method, counted as one (rounded where the budget rounds)
            rounded = counts.equal_time_spp(seconds, measured, budget.power_of_two,
                                            budget.max_spp)
            return plain if trains(rounded) else rounded
        fewer = max(1, int(plain / LEARNER_COST))
        spp = fewer if trains(fewer) == trains(plain) else plain
        piloted = [engine_pilots.render(self, declaration, budget, slot, spp)]
        count = counts.equal_time_spp(seconds, piloted, False, budget.max_spp)
        return counts.learner_spp(seconds, spp, count, trains, piloted, measured)

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
    def reference_jobs(self, declaration: Declaration) -> dict:
        """{(scene, point): the chunks of its reference} in the shared reference store."""
        return engine_references.jobs(self.study, declaration)

    def references(self, declaration: Declaration) -> dict:
        """{(scene, point): (reference image, its metadata with the floors)}, rendered where
        the reference store lacks them."""
        jobs = self.reference_jobs(declaration)
        self.study.run([j for chunks in jobs.values() for j in chunks],
                       f"{declaration.name}: references")
        return {key: self.study.reference(chunks) for key, chunks in jobs.items()}

    def run(self, declaration: Declaration, references: dict | None = None) -> Measurements:
        """Plan, render (resuming) and measure every cell of ``declaration``, against
        ``references`` ({(scene, point): (image, metadata)} the study brings; the others
        from the shared reference store)."""
        planned, refs = Planned(), {}
        scenes = [(s, p) for s in declaration.scenes for p in declaration.points()]
        units = [scenes] if self.study.executor is not None else [[x] for x in scenes]
        for unit in units:
            chunks = engine_references.render(self.study, declaration, unit, references or {},
                                              planned.scene_errors, refs)
            slots = [s for s in self.slots(declaration, unit)
                     if declaration.reference_key(s.scene.name, s.point) in refs]
            groups = [slots[i:i + VIEW_CACHE] for i in range(0, len(slots), VIEW_CACHE)]
            for batch in [groups] if self.study.executor is not None else [[g] for g in groups]:
                for stage in self.stages(declaration):
                    self._render_stage(declaration, stage, batch, planned, refs, chunks)
            if declaration.reference_floor is not None:
                engine_references.extend(self.study, declaration, chunks, refs,
                                         self.measure(declaration, planned, refs, set(chunks)))
        return self.measure(declaration, planned, refs)

    @staticmethod
    def stages(declaration: Declaration) -> list[list[Budget]]:
        """The budgets in the order they render: those whose counts are known up front
        together, an equal-time budget (which needs the costs before it) alone."""
        out = []
        for budget in declaration.budgets:
            if budget.timed or not out or out[-1][-1].timed:
                out.append([budget])
            else:
                out[-1].append(budget)
        return out

    def _render_stage(self, declaration, stage, groups, planned, refs, chunks) -> None:
        """Plan and render the budgets of ``stage`` over ``groups`` of slots: each group's
        renders interleaved (per repeat, per budget, every method), in one executor call;
        where that fails and failures are isolated, cell by cell."""
        order = []
        for group in groups:
            live = [s for s in group if s.failure_key not in planned.failed]
            for budget in stage:
                if budget.timed:
                    self._decide_scales(declaration, budget, live, planned, refs, chunks)
                counted = {}
                for slot in list(live):
                    try:
                        counted[slot.cell(budget.name)] = (self.count(
                            declaration, budget, slot, planned) if budget.timed else None)
                    except Exception as e:  # noqa: BLE001
                        if not declaration.isolate_failures or isinstance(e, ReplayError):
                            raise
                        planned.failed[slot.failure_key] = one_line(e)
                        live.remove(slot)
                planned.add(budget.name, self.jobs(declaration, budget, counted, live))
            order += [(slot, reps[r]) for r in range(declaration.repeats) for budget in stage
                      for slot in live
                      for reps in [planned.runs(slot.cell(budget.name))] if r < len(reps)]
        label = f"{declaration.name}: {', '.join(b.name for b in stage)}"
        try:
            self.study.run([j for _, jobs in order for j in jobs], label)
            return
        except Exception:  # noqa: BLE001  (cell by cell below, or the run ends)
            if not declaration.isolate_failures:
                raise
        for slot in dict.fromkeys(s for s, _ in order):
            try:
                self.study.run([j for s, jobs in order if s == slot for j in jobs],
                               f"{label} ({slot.scene.name}, {slot.method.name})")
            except Exception as e:  # noqa: BLE001  (recorded, the others go on)
                planned.failed[slot.failure_key] = one_line(e)

    def _decide_scales(self, declaration, budget, slots, planned, refs, chunks) -> None:
        """The factor of ``budget`` on each scene of ``slots`` not decided yet: its policy's
        (``budget.scale``), else the scene's own."""
        for slot in slots:
            key = (slot.scene.name, slot.point, budget.name)
            if key in planned.scales:
                continue
            if budget.scale is None:
                planned.scales[key] = (slot.scene.time_scale, "")
                continue
            ref_key = declaration.reference_key(slot.scene.name, slot.point)
            first = (self.study.reference(chunks[ref_key][:MIN_CHUNKS])[0]
                     if ref_key in chunks else refs[ref_key][0])
            planned.scales[key] = budget.scale(self, declaration, slot.scene, planned, first)

    # ---------------------------------------------------------------- measure
    def measure(self, declaration: Declaration, planned: Planned | dict, refs: dict,
                keys: set | None = None) -> Measurements:
        """The :class:`~.measurements.Measurements` of rendered ``planned`` jobs (a
        :class:`Planned`, or its ``jobs`` dict) against ``refs`` (of the reference ``keys``
        only, where given)."""
        planned = planned if isinstance(planned, Planned) else Planned(dict(planned))
        out = Measurements(declaration, {}, refs, failed=dict(planned.failed),
                           scales=dict(planned.scales),
                           scene_errors=dict(planned.scene_errors))
        budgets = {b.name: b for b in declaration.budgets}
        for name, cells in planned.jobs.items():
            for cell, reps in cells.items():
                if (cell.scene, cell.point, cell.method) in planned.failed or \
                        (keys is not None and out.reference_key(cell) not in keys):
                    continue
                ref = out.reference_of(cell)[0]
                independent = bool(budgets[name].ladder) and \
                    declaration.method(cell.method).learns
                spread = not declaration.method(cell.method).continues_sequence
                runs = [rungs(self.study.results(jobs), ref, independent, spread)
                        for jobs in reps]
                out.runs[cell] = runs * (declaration.repeats if len(runs) == 1 else 1)
                out.jobs[cell] = reps
        return out
