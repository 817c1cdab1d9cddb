"""Convergence sequences, error against spp and time, equal-time panel, efficiency table.

For each method: render 1, 2, 4, ... --spp samples per pixel as a ladder of
jobs (each image is the sum of the jobs before it), keep every intermediate
image (EXR + PNG) with its cumulative render time, measure MSE / relMSE
against a high-spp reference, then plot and tabulate. Then an equal-time
comparison: each method renders as many samples as fit in --time-budget
seconds at the speed measured on its ladder. The default methods include
``bsdf+nee`` and Mitsuba's ``path`` as what a user would run instead.

The study runs in four steps, data flowing one way: :func:`plan` (jobs as data),
:func:`measure` (plain numbers from the store), :func:`.convergence_analysis.analyse`
(pure: every ratio, interval, ranking, verdict and sentence) and
:func:`.convergence_report.report` (blocks, CSVs, figures, summary.json).
:class:`ConvergenceSettings` is made from the command line in one place
(:func:`settings_from`); the library never sees the Namespace.

    python -m experiments.convergence --help
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass

from experiments.lib import cli, clock, files, metrics
from experiments.lib.jobs import Job
from experiments.lib.plan import doubling_targets
from experiments.lib.methods import Method
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies import convergence_analysis
from experiments.lib.studies import convergence_report
from experiments.lib.studies.settings import StudySettings, common_fields
from experiments.lib.study import Study, repeat_prefix

NAME = convergence_analysis.NAME
ORDER = 20
TITLE = "Convergence, error against time, efficiency"


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.convergence", __doc__.split("\n")[0],
                          spp=128, time_budget=0.1, default_resolution="64x32")
    p.set_defaults(reference_spp=1024)
    add_arguments(p)
    return p


def add_arguments(p: cli.Parser) -> None:
    """The options of this experiment (also taken by run_all)."""
    p.add_argument("--best-sampler", default="auto", metavar="SAMPLER|auto|none",
                   help="add bsdf+nee with this sampler to the default methods (the best "
                        "combination the suite offers); auto: the sampler study's most "
                        "efficient one at the nearest depth, read from OUT/samplers/"
                        "summary.json when that study has run (run_all runs it first)")


# ------------------------------------------------------------------ settings

@dataclass(frozen=True)
class Best:
    """The best combination the suite offers: bsdf+nee with the sampler study's winner,
    and where that study chose it (None where it was given by --best-sampler)."""
    method: Method
    sampler: str
    depth: int | None = None          # the sampler study's max_depth it won at
    spp: int | None = None            # ... its sample count there
    resolution: str | None = None     # ... and its resolution


@dataclass(frozen=True)
class ConvergenceSettings(StudySettings):
    spp: int                          # the longest render (the ladder's top)
    time_budget: float                # seconds per method of the equal-time comparison
    best: Best | None                 # the best combination, among ``methods``


def best_combination(choice: str, out: str, max_depth: int | None) -> Best | None:
    """``bsdf+nee+SAMPLER`` for ``--best-sampler`` ``choice`` (None: none, or no sampler
    study in ``out`` yet); auto: the sampler study's winner at the depth nearest
    ``max_depth``, with the count and resolution it was chosen at."""
    if choice == "none":
        return None
    depth = spp = resolution = None
    if choice == "auto":
        summary = files.read_json(os.path.join(out, "samplers", "summary.json"), {})
        best = summary.get("best") or {}
        if not best:
            return None
        wanted = max_depth if max_depth is not None else convergence_analysis.DEFAULT_DEPTH
        key = min(best, key=lambda d: (abs(int(d) - wanted), int(d)))
        choice, depth = best[key], int(key)
        at = (summary.get("best_at") or {}).get(key) or {}
        spp = at.get("requested_spp") or at.get("spp") or max(
            (r.get("requested_spp") or r.get("spp", 0) for r in summary.get("rows", [])
             if int(r.get("depth", -1)) == depth and r.get("sampler") == choice),
            default=None)
        section = files.read_json(os.path.join(out, "samplers", "section.json"), {})
        resolution = section.get("settings", {}).get("resolution")
    name = "bsdf+nee" if choice == "independent" else f"bsdf+nee+{choice}"
    return Best(cli.one_method(name), choice, depth, spp, resolution)


def settings_from(args) -> ConvergenceSettings:
    """The settings of a parsed command line: --methods, with the best combination added
    to the default methods (see --best-sampler)."""
    best = (None if "methods" in args.explicit else
            best_combination(args.best_sampler, args.out, args.depth.max_depth))
    fields = common_fields(args)
    # issue 29: its references' chunks stay sized by this run's --reference-spp, as before
    # typed settings (by the study's default, as the other studies do, changes the chunks of
    # a run given --reference-spp: a decision apart from this refactoring)
    fields["reference_spp_default"] = None
    methods = list(fields["methods"])
    if best is not None and best.method.name not in {m.name for m in methods}:
        methods.append(best.method)
    fields["methods"] = tuple(methods)
    return ConvergenceSettings(**fields, spp=args.spp, time_budget=args.time_budget,
                               best=best)


# ------------------------------------------------------------------ plan

@dataclass(frozen=True)
class Plan:
    """The jobs: the reference, and per method one ladder per repeat (a deterministic
    method: one, every run gives the same image)."""
    targets: tuple
    reference: list
    ladders: dict                     # method name -> [ladder (list of Job) per repeat]

    def jobs(self) -> list[Job]:
        return self.reference + [j for reps in self.ladders.values() for jobs in reps
                                 for j in jobs]


def plan(st: Study, settings: ConvergenceSettings) -> Plan:
    targets = doubling_targets(settings.spp)
    ladders = {m.name: [st.ladder(repeat_prefix(f"{NAME}/{m.name}", r), m, targets,
                                  timing_group=NAME)
                        for r in range(st.repeats_of(m))] for m in settings.methods}
    return Plan(tuple(targets), st.reference_jobs(), ladders)


def plan_equal_time(st: Study, settings: ConvergenceSettings, plan: Plan) -> dict:
    """Per method, repeats of one job with as many spp as fit in the budget at the speed
    measured on its ladders (read from the store: plan the ladders' run first)."""
    jobs = {}
    for name, reps in plan.ladders.items():
        results = [st.store.get(j.key) for ladder in reps for j in ladder]
        spp = convergence_analysis.equal_time_spp([clock.cost(r) for r in results],
                                                  [r.spp for r in results],
                                                  settings.time_budget)
        method = reps[0][0].method
        jobs[name] = [st.job(repeat_prefix(f"equal_time/{name}", r), method, spp,
                             timing_group=NAME) for r in range(st.repeats_of(method))]
    return jobs


# ------------------------------------------------------------------ measure

def measure(st: Study, plan: Plan, equal_jobs: dict) -> convergence_analysis.Measured:
    """Errors (against the reference, its own expected error not subtracted), seconds and
    spp per method, count and repeat; the first repeat's images for the report."""
    ref, meta = st.reference(plan.reference)
    ladders, equal, images, equal_images = {}, {}, {}, {}
    for name, reps in plan.ladders.items():
        runs = [st.accumulate(jobs) for jobs in reps]
        ladders[name], images[name] = [], []
        for accs in zip(*runs):
            first = accs[0]
            ladders[name].append(convergence_analysis.Rung(
                first.spp, len(accs), st.per_repeat(a.cost for a in accs),
                st.per_repeat(metrics.mse(a.mean, ref) for a in accs),
                st.per_repeat(metrics.relmse(a.mean, ref) for a in accs),
                metrics.flip_mean(first.mean, ref)))
            images[name].append(first.mean)
    for name, reps in equal_jobs.items():
        results = [st.store.get(j.key) for j in reps]
        shown = results[0].image.astype(float)
        equal[name] = convergence_analysis.Rung(
            results[0].spp, len(results), st.per_repeat(clock.cost(r) for r in results),
            st.per_repeat(metrics.mse(r.image.astype(float), ref) for r in results),
            st.per_repeat(metrics.relmse(r.image.astype(float), ref) for r in results),
            metrics.flip_mean(shown, ref))
        equal_images[name] = shown
    floor = convergence_analysis.Floor(meta["mse_floor"], meta["relmse_floor"])
    return convergence_analysis.Measured(ladders, equal, floor, st.repeats, plan.targets,
                      convergence_analysis.Images(ref, images, equal_images),
                      {k: v for k, v in meta.items() if k != "relmse_floor_map"})


# ------------------------------------------------------------------ run

def run_settings(settings: ConvergenceSettings) -> convergence_analysis.Result:
    """The whole study from typed settings; returns the analysis."""
    start = time.perf_counter()
    st = Study(settings)
    the_plan = plan(st, settings)
    st.run(the_plan.jobs(), f"{NAME}: sequences")
    equal_jobs = plan_equal_time(st, settings, the_plan)
    st.run([j for reps in equal_jobs.values() for j in reps], f"{NAME}: equal time")
    measured = measure(st, the_plan, equal_jobs)
    result = convergence_analysis.analyse(measured, settings)
    timed = st.timed_on([j for reps in the_plan.ladders.values() for jobs in reps
                         for j in jobs] + [j for reps in equal_jobs.values() for j in reps])
    convergence_report.report(convergence_report.Context(settings, st, measured, the_plan.targets,
                                                         timed, TITLE, ORDER, start),
                              result)
    return result


def run(args) -> None:
    run_settings(settings_from(args))


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run, shared=add_arguments,
    forwarded={"time_budget": "--time-budget", "best_sampler": "--best-sampler"}))
