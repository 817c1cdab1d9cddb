"""The writeup's figures, with numbers.

* cosine vs uniform and Phong lobe (bsdf) vs uniform after --short-spp (20) spp,
  Halton (plain, uniform+halton) vs uniform after --halton-spp (50) spp, at
  --resolution (256x128): images side by side with their RMSE and the RMSE ratio;
* with --full: cosine vs uniform and Halton vs uniform at --full-resolution
  (1024x512) after --full-spp (1000) spp: no bias, i.e. the per-channel mean
  difference with a 99% confidence interval and the fraction of pixel values
  passing a per-pixel z-test (expected about 99%).

The study is declared on the experiment engine (:func:`declare`: one declaration per
method and pass, each method's ladder to the counts of its pairs, its jobs in the passes
the bias checks need); :func:`measure` has the engine render them (resuming) and measure
them (the engine's errors per repeat, the first repeat's passes for the variances), then
:func:`.writeup_analysis.analyse` (pure: every ratio, interval, verdict and sentence) and
:func:`.writeup_report.report`.
:class:`WriteupSettings` is made from the command line in one place (:func:`settings_from`).

    python -m experiments.writeup --help
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from experiments.lib import cli, clock, metrics
from experiments.lib.engine import Budget, Declaration, Engine, SceneSetup
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies import writeup_analysis
from experiments.lib.studies import writeup_report
from experiments.lib.study import Study, StudySettings, repeat_prefix

NAME = writeup_analysis.NAME
ORDER = 30
TITLE = "The writeup's figures, with numbers"
#: (method, compared against, which spp setting) of the short figures.
SHORT_PAIRS = (("cosine", "uniform", "short_spp"), ("bsdf", "uniform", "short_spp"),
               ("uniform+halton", "uniform", "halton_spp"))
#: (method, compared against) of the --full bias checks.
FULL_PAIRS = (("cosine", "uniform"), ("uniform+halton", "uniform"))
#: Passes of a --full render (for the per-pixel variances of the z-test).
FULL_PASSES = 100


def add_arguments(p: cli.Parser) -> None:
    """The options of this experiment (also taken by run_all)."""
    p.add_argument("--short-spp", type=cli.positive_int, default=20,
                   help="spp of the cosine/Phong-lobe vs uniform figures")
    p.add_argument("--halton-spp", type=cli.positive_int, default=50,
                   help="spp of the Halton vs uniform figure")
    p.add_argument("--full", action="store_true",
                   help="also the long no-bias checks at --full-resolution, --full-spp")
    p.add_argument("--full-resolution", type=cli.resolution, default="1024x512", metavar="WxH",
                   help="resolution of the --full bias checks")
    p.add_argument("--full-spp", type=cli.positive_int, default=1000,
                   help="spp of the --full bias checks")


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.writeup", __doc__.split("\n")[0])
    p.set_defaults(reference_spp=256)      # its own expected error is subtracted
    add_arguments(p)
    return p


@dataclass(frozen=True)
class WriteupSettings(StudySettings):
    short_spp: int
    halton_spp: int
    full: bool
    full_resolution: tuple
    full_spp: int


def settings_from(args) -> WriteupSettings:
    fields = cli.common_fields(args)
    # issue 29: its references' chunks stay sized by this run's --reference-spp, as before
    # typed settings (by the study's default, as the other studies do, changes the chunks of
    # a run given --reference-spp: a decision apart from this refactoring)
    fields["reference_spp_default"] = None
    return WriteupSettings(**fields, short_spp=args.short_spp,
                           halton_spp=args.halton_spp, full=bool(args.full),
                           full_resolution=tuple(args.full_resolution),
                           full_spp=args.full_spp)


# ------------------------------------------------------------------ declarations

@dataclass(frozen=True)
class Plan:
    """The declarations (one per method and pass: each method renders its own ladder) and
    their jobs, as the engine plans them (with the writeup's passes)."""
    pairs: tuple                # (a, b, spp) of the short figures
    methods: dict               # method name -> Method
    resolution: tuple
    short: tuple                # Declarations of the short figures
    full: tuple = ()            # ... and of the --full checks
    full_pairs: tuple = ()      # (a, b) of the --full checks
    full_spp: int = 0
    full_resolution: tuple = ()


def _targets(method, targets) -> tuple:
    """``targets``, and for a deterministic method also 1/4 and 1/2 of the last (for its
    convergence check)."""
    targets = set(targets)
    if method.deterministic:
        targets |= {max(1, max(targets) // 4), max(1, max(targets) // 2)}
    return tuple(sorted(targets))


def _declaration(name: str, method, scene: SceneSetup, targets, repeats: int,
                 pass_spp) -> Declaration:
    """One method's ladder; ``pass_spp(method, spp, repeat)``: its jobs' passes."""
    return Declaration(name, (method,), (scene,), (Budget.progressive(_targets(
        method, targets)),), repeats, key=lambda decl, cell: f"{decl.name}/{cell.method}",
        pass_spp=pass_spp)


def short_passes(method, spp: int, repeat: int) -> int:
    """The short pairs' first repeat in passes of one sample: the spread of its passes gives
    the per-pixel variances of the bias check; the other repeats as memory allows."""
    return 1 if repeat == 0 else 0


def declare(settings: WriteupSettings) -> Plan:
    """Each method of the short pairs renders a ladder to the counts of the pairs it is
    in, --repeats times; with --full, those of the full pairs render one ladder to
    --full-spp at --full-resolution in jobs of 10 passes."""
    methods = {m.name: m for m in settings.methods}
    pairs = tuple((a, b, getattr(settings, opt)) for a, b, opt in SHORT_PAIRS
                  if a in methods and b in methods)
    wanted: dict[str, set] = {}
    for a, b, spp in pairs:
        for name in (a, b):
            wanted.setdefault(name, set()).add(spp)
    scene = SceneSetup("short", settings.info, tuple(settings.resolution), settings.depth)
    short = tuple(_declaration(NAME, methods[n], scene, t, settings.repeats, short_passes)
                  for n, t in wanted.items())
    full_pairs = tuple((a, b) for a, b in FULL_PAIRS if a in methods and b in methods)
    if not settings.full or not full_pairs:
        return Plan(pairs, methods, scene.resolution, short)
    # 10 passes per job: an interruption loses little
    chunk = max(1, settings.full_spp // FULL_PASSES) * 10
    targets = list(range(chunk, settings.full_spp, chunk)) + [settings.full_spp]
    full_scene = replace(scene, name="full", resolution=tuple(settings.full_resolution))
    full_pass = max(1, settings.full_spp // FULL_PASSES)
    full = tuple(_declaration(NAME + "_full", methods[n], full_scene, targets, 1,
                              lambda method, spp, repeat: full_pass)
                 for n in dict.fromkeys(x for p in full_pairs for x in p))
    return Plan(pairs, methods, scene.resolution, short, full, full_pairs, settings.full_spp,
                full_scene.resolution)


# ------------------------------------------------------------------ measure

def _images(st: Study, jobs) -> dict:
    """{requested spp: cumulative image (Accumulator)} of a ladder."""
    targets, total = [], 0
    for j in jobs:
        total += j.spp
        targets.append(total)
    return dict(zip(targets, st.accumulate(jobs)))


def _reference(st: Study, resolution: tuple, label: str):
    """The reference at ``resolution`` (rendered where the reference store lacks it) as
    accumulated chunks (its mean, and the per-pixel variance of its mean that the checks
    need), and its metadata."""
    chunks = st.reference_jobs(resolution=resolution)
    st.run(chunks, f"{NAME}: {label}")
    return st.accumulate(chunks)[-1], st.reference(chunks)[1]


def measure_short(st: Study, plan: Plan) -> tuple:
    """The short pairs as numbers, and the images the report shows."""
    reference, meta = _reference(st, plan.resolution, "reference")
    ref, ref_var = reference.mean, reference.variance_of_mean()
    refs = {("short", None): (ref, meta)}
    engine = Engine(st)
    errors, renders = {}, {}
    for d in plan.short:
        name, budget = d.methods[0].name, d.budgets[0]
        measured = engine.run(d, refs)
        (cell, runs), = measured.runs.items()
        rungs = dict(zip(budget.ladder, zip(*runs)))
        errors[name] = {spp: tuple(run.mse for run in runs) for spp, runs in rungs.items()}
        renders[name] = _images(st, measured.jobs[cell][0])     # the first repeat's
    pairs, shown = [], {}
    for a, b, spp in plan.pairs:
        sides = []
        for n in (a, b):
            image = renders[n][spp].mean
            shown[(n, spp)] = image
            sides.append(writeup_analysis.Side(n, errors[n][spp], metrics.rmse(image, ref),
                                               plan.methods[n].deterministic))
        if sides[0].deterministic:
            spps = sorted(renders[a])
            check = metrics.deterministic_check(spps, [renders[a][s].mean for s in spps],
                                                ref, ref_var)
        else:
            acc_a, acc_b = renders[a][spp], renders[b][spp]
            check = metrics.bias_check(acc_a.mean, acc_a.variance_of_mean(), acc_b.mean,
                                       acc_b.variance_of_mean())
        pairs.append(writeup_analysis.PairMeasured(sides[0], sides[1], spp, check))
    return pairs, ref, ref_var, shown, meta


def measure_full(st: Study, plan: Plan) -> tuple:
    """The --full checks as numbers, and their images (with the z-maps' inputs)."""
    ref, meta = _reference(st, plan.full_resolution, "--full reference")
    engine = Engine(st)
    renders = {}
    for d in plan.full:
        measured = engine.run(d, {("full", None): (ref.mean, meta)})
        (cell, jobs), = measured.jobs.items()
        renders[d.methods[0].name] = _images(st, jobs[0])
    out, shown = [], {}
    for a, b in plan.full_pairs:
        acc_a, acc_b = renders[a][plan.full_spp], renders[b][plan.full_spp]
        deterministic = plan.methods[a].deterministic
        if deterministic:
            spps = sorted(renders[a])
            check = metrics.deterministic_check(spps, [renders[a][s].mean for s in spps],
                                                ref.mean, ref.variance_of_mean())
            var = None
        else:
            var = acc_a.variance_of_mean() + acc_b.variance_of_mean()
            check = metrics.bias_check(acc_a.mean, acc_a.variance_of_mean(), acc_b.mean,
                                       acc_b.variance_of_mean())
        shown[(a, b)] = (acc_a.mean, acc_b.mean, var)
        out.append(writeup_analysis.FullMeasured(a, b, plan.full_spp, acc_a.passes, acc_a.cost,
                                  acc_b.cost, deterministic, check))
    return out, ref.mean, shown


@dataclass(frozen=True)
class Images:
    reference: object
    shown: dict                 # (method, spp) -> the first run's image
    full_reference: object = None
    full: dict = None           # (a, b) -> (image A, image B, var A + var B or None)


def measure(st: Study, plan: Plan) -> writeup_analysis.Measured:
    """Render (resuming) what the stores lack and measure it."""
    pairs, ref, ref_var, shown, meta = measure_short(st, plan)
    full, full_ref, full_shown = measure_full(st, plan) if plan.full_pairs else ([], None, {})
    return writeup_analysis.Measured(pairs, full, float(ref_var.mean()), st.repeats,
                      Images(ref, shown, full_ref, full_shown),
                      {k: v for k, v in meta.items() if k != "relmse_floor_map"})


# ------------------------------------------------------------------ run

def run_settings(settings: WriteupSettings) -> writeup_analysis.Result:
    """The whole study from typed settings; returns the analysis."""
    timer = clock.Timer()
    st = Study(settings)
    measured = measure(st, declare(settings))
    result = writeup_analysis.analyse(measured, settings)
    writeup_report.report(writeup_report.Context(settings, st, measured, TITLE, ORDER, timer),
                          result)
    return result


def run(args) -> None:
    run_settings(settings_from(args))


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run, shared=add_arguments,
    forwarded={"short_spp": "--short-spp", "halton_spp": "--halton-spp", "full": "--full",
               "full_resolution": "--full-resolution", "full_spp": "--full-spp"}))
