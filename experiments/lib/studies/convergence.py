"""Convergence sequences, error against spp and time, equal-time panel, efficiency table.

For each method: render 1, 2, 4, ... --spp samples per pixel as a ladder of
jobs (each image is the sum of the jobs before it), keep every intermediate
image (EXR + PNG) with its cumulative render time, measure MSE / relMSE
against a high-spp reference, then plot and tabulate. Then an equal-time
comparison: each method renders as many samples as fit in --time-budget
seconds at the speed measured on its ladder. The default methods include
``bsdf+nee`` and Mitsuba's ``path`` as what a user would run instead.

The study is a declaration on the experiment engine (:func:`declare`: the methods, one
scene, a ladder and an equal-time budget measured on it, the repeats): the engine plans,
renders (resuming), costs with the one clock and measures against the reference;
:func:`measured_of` gives its numbers to :func:`.convergence_analysis.analyse` (pure:
every ratio, interval, ranking and verdict) and :func:`.convergence_report.report`
(blocks, CSVs, figures, summary.json).
:class:`ConvergenceSettings` is made from the command line in one place
(:func:`settings_from`); the library never sees the Namespace.

    python -m experiments.convergence --help
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from experiments.lib import cli, clock, files, metrics
from experiments.lib.engine import Budget, Cell, Declaration, Engine, Measurements, SceneSetup
from experiments.lib.plan import doubling_targets
from experiments.lib.methods import Method
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies.sampler_comparison import efficiency as sampler_efficiency
from experiments.lib.studies import convergence_analysis
from experiments.lib.studies import convergence_report
from experiments.lib.study import Study, StudySettings

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
                        "combination the suite offers); auto: the sampler study's pick (its "
                        "most efficient randomized sampler, or of those it cannot tell apart "
                        "the last in its table) at the nearest depth, read from OUT/samplers/"
                        "summary.json when that study has run (run_all runs it first)")


# ------------------------------------------------------------------ settings

@dataclass(frozen=True)
class Best:
    """The best combination the suite offers: bsdf+nee with the sampler study's pick
    (:func:`.sampler_comparison.analysis.picks`), and where that study chose it (None where
    it was given by --best-sampler)."""
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
    study in ``out`` yet); auto: the sampler study's pick at the depth nearest
    ``max_depth``, with the count and resolution it was chosen at."""
    if choice == "none":
        return None
    depth = spp = resolution = None
    if choice == "auto":
        wanted = max_depth if max_depth is not None else convergence_analysis.DEFAULT_DEPTH
        found = sampler_efficiency.pick_near(out, wanted)
        if found is None:
            return None
        depth, record = found
        choice = record["sampler"]
        spp = record.get("requested_spp") or record.get("spp")
        section = files.read_json(os.path.join(out, "samplers", "section.json"), {})
        resolution = section.get("settings", {}).get("resolution")
    name = "bsdf+nee" if choice == "independent" else f"bsdf+nee+{choice}"
    return Best(cli.one_method(name), choice, depth, spp, resolution)


def settings_from(args) -> ConvergenceSettings:
    """The settings of a parsed command line: --methods, with the best combination added
    to the default methods (see --best-sampler)."""
    best = (None if "methods" in args.explicit else
            best_combination(args.best_sampler, args.out, args.depth.max_depth))
    fields = cli.common_fields(args)
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


# ------------------------------------------------------------------ declaration

#: The budgets: each method's ladder (the progress label "sequences"), then equal time.
SEQUENCES, EQUAL_TIME = "sequences", "equal time"


def job_key(declaration: Declaration, cell: Cell) -> str:
    """The prefix of a cell's jobs, as the study always named them (so their seeds too)."""
    return f"{NAME}/{cell.method}" if cell.budget == SEQUENCES else f"equal_time/{cell.method}"


def declare(settings: ConvergenceSettings) -> Declaration:
    """Every method's ladder 1, 2, 4, ... --spp, then as many samples as fit in
    --time-budget at the cost per sample measured on its ladders; --repeats of each."""
    scene = SceneSetup("scene", settings.info, tuple(settings.resolution), settings.depth)
    return Declaration(NAME, tuple(settings.methods), (scene,), (
        Budget.progressive(doubling_targets(settings.spp), name=SEQUENCES),
        Budget.equal_time(settings.time_budget, after=SEQUENCES, name=EQUAL_TIME)),
        settings.repeats, key=job_key)


# ------------------------------------------------------------------ measure

def _rung(runs: list, count: int, reference) -> convergence_analysis.Rung:
    """One rung over the repeats (``runs``: the engine's Run per repeat, ``count`` of them
    distinct renders); FLIP of the first repeat's image, the one shown."""
    return convergence_analysis.Rung(
        runs[0].spp, count, tuple(r.cost for r in runs), tuple(r.mse for r in runs),
        tuple(r.relmse for r in runs), metrics.flip_mean(runs[0].image, reference))


def measured_of(measurements: Measurements) -> convergence_analysis.Measured:
    """The analysis's numbers from the engine's: per method and rung the cost, the errors
    (the reference's floor not subtracted) per repeat; the first repeat's images."""
    decl = measurements.declaration
    ref, meta = measurements.references[("scene", None)]
    distinct = {m.name: 1 if m.deterministic else decl.repeats for m in decl.methods}
    ladders, equal, images, equal_images = {}, {}, {}, {}
    for cell, reps in measurements.runs.items():
        if cell.budget == SEQUENCES:
            ladders[cell.method] = [_rung(list(rung), distinct[cell.method], ref)
                                    for rung in zip(*reps)]
            images[cell.method] = [r.image for r in reps[0]]
        else:
            equal[cell.method] = _rung([r[-1] for r in reps], distinct[cell.method], ref)
            equal_images[cell.method] = reps[0][-1].image
    floor = convergence_analysis.Floor(meta["mse_floor"], meta["relmse_floor"])
    return convergence_analysis.Measured(
        ladders, equal, floor, decl.repeats, decl.budgets[0].ladder,
        convergence_analysis.Images(ref, images, equal_images),
        {k: v for k, v in meta.items() if k != "relmse_floor_map"})


# ------------------------------------------------------------------ run

def run_settings(settings: ConvergenceSettings) -> convergence_analysis.Result:
    """The whole study from typed settings; returns the analysis."""
    timer = clock.Timer()
    st = Study(settings)
    declaration = declare(settings)
    measurements = Engine(st).run(declaration)
    measured = measured_of(measurements)
    result = convergence_analysis.analyse(measured, settings)
    convergence_report.report(convergence_report.Context(
        settings, st, measured, measured.targets, st.timed_on(measurements.all_jobs()),
        TITLE, ORDER, timer),
        result)
    return result


def run(args) -> None:
    run_settings(settings_from(args))


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run, shared=add_arguments,
    forwarded={"time_budget": "--time-budget", "best_sampler": "--best-sampler"}))
