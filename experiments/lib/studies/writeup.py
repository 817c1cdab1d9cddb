"""The writeup's figures, with numbers.

* cosine vs uniform and Phong lobe (bsdf) vs uniform after --short-spp (20) spp,
  Halton (plain, uniform+halton) vs uniform after --halton-spp (50) spp, at
  --resolution (256x128): images side by side with their RMSE and the RMSE ratio;
* with --full: cosine vs uniform and Halton vs uniform at --full-resolution
  (1024x512) after --full-spp (1000) spp: no bias, i.e. the per-channel mean
  difference with a 99% confidence interval and the fraction of pixel values
  passing a per-pixel z-test (expected about 99%).

The study runs in four steps, data flowing one way: :func:`plan` (jobs as data),
:func:`measure` (plain numbers from the store), :func:`.writeup_analysis.analyse` (pure:
every ratio, interval, verdict and sentence) and :func:`.writeup_report.report`.
:class:`WriteupSettings` is made from the command line in one place (:func:`settings_from`).

    python -m experiments.writeup --help
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from experiments.lib import cli, metrics
from experiments.lib.jobs import Job
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies import writeup_analysis
from experiments.lib.studies import writeup_report
from experiments.lib.studies.settings import StudySettings, common_fields
from experiments.lib.study import Study, repeat_prefix

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
    fields = common_fields(args)
    # issue 29: its references' chunks stay sized by this run's --reference-spp, as before
    # typed settings (by the study's default, as the other studies do, changes the chunks of
    # a run given --reference-spp: a decision apart from this refactoring)
    fields["reference_spp_default"] = None
    return WriteupSettings(**fields, short_spp=args.short_spp,
                           halton_spp=args.halton_spp, full=bool(args.full),
                           full_resolution=tuple(args.full_resolution),
                           full_spp=args.full_spp)


# ------------------------------------------------------------------ plan

@dataclass(frozen=True)
class Plan:
    reference: list
    pairs: tuple                # (a, b, spp) of the short figures
    ladders: dict               # method name -> [ladder per repeat] (short figures)
    methods: dict               # method name -> Method
    full_pairs: tuple = ()      # (a, b) of the --full checks
    full_reference: list = ()
    full_ladders: dict = None   # method name -> ladder (one run)
    full_spp: int = 0

    def short_jobs(self) -> list[Job]:
        return [j for reps in self.ladders.values() for jobs in reps for j in jobs]

    def full_jobs(self) -> list[Job]:
        return list(self.full_reference) + [j for jobs in (self.full_ladders or {}).values()
                                            for j in jobs]


def _ladder(st: Study, experiment: str, method, targets, resolution, pass_spp: int,
            repeat: int = 0) -> list[Job]:
    """The ladder of ``method`` to ``targets`` (a deterministic method also to 1/4 and 1/2
    of the last, for its convergence check); ``repeat``: an independent randomization."""
    targets = set(targets)
    if method.deterministic:
        targets |= {max(1, max(targets) // 4), max(1, max(targets) // 2)}
    return st.ladder(repeat_prefix(f"{experiment}/{method.name}", repeat), method,
                     sorted(targets), resolution=resolution, pass_spp=pass_spp)


def plan(st: Study, settings: WriteupSettings) -> Plan:
    methods = {m.name: m for m in settings.methods}
    pairs = tuple((a, b, getattr(settings, opt)) for a, b, opt in SHORT_PAIRS
                  if a in methods and b in methods)
    wanted: dict[str, set] = {}
    for a, b, spp in pairs:
        for name in (a, b):
            wanted.setdefault(name, set()).add(spp)
    # 1-spp passes in the first repeat: the spread of its passes gives the per-pixel
    # variances of the bias check; the other repeats only enter the expected errors
    ladders = {n: [_ladder(st, NAME, methods[n], t, settings.resolution, 1 if r == 0 else 0, r)
                   for r in range(st.repeats_of(methods[n]))] for n, t in wanted.items()}
    result = Plan(st.reference_jobs(), pairs, ladders, methods)
    full_pairs = tuple((a, b) for a, b in FULL_PAIRS if a in methods and b in methods)
    if not settings.full or not full_pairs:
        return result
    pass_spp = max(1, settings.full_spp // FULL_PASSES)
    chunk = pass_spp * 10                     # 10 passes per job: an interruption loses little
    targets = list(range(chunk, settings.full_spp, chunk)) + [settings.full_spp]
    full = {n: _ladder(st, NAME + "_full", methods[n], targets, settings.full_resolution,
                       pass_spp) for n in dict.fromkeys(x for p in full_pairs for x in p)}
    return Plan(result.reference, pairs, ladders, methods, full_pairs,
                st.reference_jobs(resolution=settings.full_resolution), full,
                settings.full_spp)


# ------------------------------------------------------------------ measure

def _images(st: Study, jobs) -> dict:
    """{requested spp: cumulative image (Accumulator)} of a ladder."""
    targets, total = [], 0
    for j in jobs:
        total += j.spp
        targets.append(total)
    return dict(zip(targets, st.accumulate(jobs)))


def measure_short(st: Study, plan: Plan) -> tuple:
    """The short pairs as numbers, and the images the report shows."""
    accs = st.accumulate(plan.reference)
    ref, ref_var = accs[-1].mean, accs[-1].variance_of_mean()
    repeats = {n: [_images(st, jobs) for jobs in reps] for n, reps in plan.ladders.items()}
    renders = {n: reps[0] for n, reps in repeats.items()}
    pairs, shown = [], {}
    for a, b, spp in plan.pairs:
        sides = []
        for n in (a, b):
            image = renders[n][spp].mean
            shown[(n, spp)] = image
            sides.append(writeup_analysis.Side(n, st.per_repeat(metrics.mse(r[spp].mean, ref)
                                                 for r in repeats[n]),
                                metrics.rmse(image, ref), plan.methods[n].deterministic))
        if sides[0].deterministic:
            spps = sorted(renders[a])
            check = metrics.deterministic_check(spps, [renders[a][s].mean for s in spps],
                                                ref, ref_var)
        else:
            acc_a, acc_b = renders[a][spp], renders[b][spp]
            check = metrics.bias_check(acc_a.mean, acc_a.variance_of_mean(), acc_b.mean,
                                       acc_b.variance_of_mean())
        pairs.append(writeup_analysis.PairMeasured(sides[0], sides[1], spp, check))
    return pairs, ref, ref_var, shown


def measure_full(st: Study, plan: Plan) -> tuple:
    """The --full checks as numbers, and their images (with the z-maps' inputs)."""
    renders = {n: _images(st, jobs) for n, jobs in plan.full_ladders.items()}
    ref = st.accumulate(list(plan.full_reference))[-1]
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
    pairs, ref, ref_var, shown = measure_short(st, plan)
    full, full_ref, full_shown = measure_full(st, plan) if plan.full_pairs else ([], None, {})
    _, meta = st.reference(plan.reference)
    return writeup_analysis.Measured(pairs, full, float(ref_var.mean()), st.repeats,
                      Images(ref, shown, full_ref, full_shown),
                      {k: v for k, v in meta.items() if k != "relmse_floor_map"})


# ------------------------------------------------------------------ run

def run_settings(settings: WriteupSettings) -> writeup_analysis.Result:
    """The whole study from typed settings; returns the analysis."""
    start = time.perf_counter()
    st = Study(settings)
    the_plan = plan(st, settings)
    st.run(the_plan.reference, f"{NAME}: reference")
    if the_plan.pairs:
        st.run(the_plan.short_jobs(), f"{NAME}: figures")
    if the_plan.full_pairs:
        st.run(the_plan.full_jobs(), f"{NAME}: --full")
    measured = measure(st, the_plan)
    result = writeup_analysis.analyse(measured, settings)
    writeup_report.report(writeup_report.Context(settings, st, measured, TITLE, ORDER, start),
                          result)
    return result


def run(args) -> None:
    run_settings(settings_from(args))


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run, shared=add_arguments,
    forwarded={"short_spp": "--short-spp", "halton_spp": "--halton-spp", "full": "--full",
               "full_resolution": "--full-resolution", "full_spp": "--full-spp"}))
