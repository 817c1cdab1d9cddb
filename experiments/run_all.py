"""The default experiment suite on the bundled scene, and the report (``make run``).

Runs :mod:`experiments.samplers` first (halton against Mitsuba's samplers;
its most efficient sampler joins the convergence study as ``bsdf+nee+SAMPLER``),
then :mod:`experiments.convergence` (sequences, error against spp and time,
equal-time panel, efficiency table; with ``bsdf+nee`` and ``path`` as
reference rows), :mod:`experiments.writeup` (the writeup's figures; with
--full also the 1024x512, 1000-spp no-bias checks) and
:mod:`experiments.stability` (where each method breaks down), then writes
OUT/index.html. Every study runs at its own default sizes and repeats; the
options given here (--resolution, --spp, --repeats, --methods, --max-depth,
...) are passed on to each study that takes them. Rerunning resumes: finished
render jobs are not redone.

    python -m experiments.run_all --help
"""
from __future__ import annotations

import sys
import time

from experiments import convergence, lab, samplers, stability, writeup
from experiments.lib import cli, report

#: Options passed on to every study: always (SHARED), or when given here (FORWARDED).
SHARED = {"scene": "--scene", "variant": "--variant", "seed": "--seed", "out": "--out"}
FORWARDED = {"resolution": "--resolution", "spp": "--spp", "max_depth": "--max-depth",
             "rr_depth": "--rr-depth", "reference_spp": "--reference-spp",
             "repeats": "--repeats", "methods": "--methods"}
#: Options of the convergence study and of the writeup's, passed on when given here.
CONVERGENCE = {"time_budget": "--time-budget", "best_sampler": "--best-sampler"}
WRITEUP = {"short_spp": "--short-spp", "halton_spp": "--halton-spp", "full": "--full",
           "full_resolution": "--full-resolution", "full_spp": "--full-spp"}


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.run_all", __doc__.split("\n")[0],
                          spp=256, time_budget=0.25)
    convergence.add_arguments(p)
    writeup.add_arguments(p)
    p.add_argument("--stability", choices=("default", "quick", "off"), default="default",
                   help="the stability study at its own default settings, tiny (quick), "
                        "or not at all")
    p.add_argument("--samplers", choices=("default", "quick", "off"), default="default",
                   help="the sampler study at its own default settings, tiny (quick), "
                        "or not at all")
    p.add_argument("--lab", choices=("default", "quick", "off"), default="default",
                   help="the sampling lab (warps and point sets) at its own default "
                        "settings, tiny (quick), or not at all")
    return p


def _value(key, value) -> str:
    if key in ("resolution", "full_resolution"):
        return "{}x{}".format(*value)
    return ",".join(value) if isinstance(value, list) else str(value)


def sub_argv(args, module, extra: dict | None = None) -> list[str]:
    """Arguments for ``module``'s study: the shared ones, and those given explicitly here
    that its parser takes."""
    known = module.build_parser()._option_string_actions
    argv = []
    for key, option in SHARED.items():
        argv += [option, _value(key, getattr(args, key))]
    for key, option in dict(FORWARDED, **(extra or {})).items():
        if key in args.explicit and option in known:
            value = getattr(args, key)
            if isinstance(value, bool):
                argv += [option] if value else []
            else:
                argv += [option, _value(key, value)]
    return argv


def study_args(module, args, argv: list[str]):
    """``module``'s own parser over ``argv``, sharing this run's cluster, if any."""
    parse = getattr(module, "parse", None) or (lambda a: cli.parse_args(module.build_parser(), a))
    sub = parse(argv)
    sub.executor = args.executor
    return sub


#: Tiny sizes of --samplers quick (for tests).
SAMPLERS_QUICK = ["--resolution", "16x8", "--spp", "4", "--reference-spp", "16"]


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    start = time.perf_counter()
    if args.samplers != "off":       # first: the convergence study adds its winner
        quick = SAMPLERS_QUICK if args.samplers == "quick" else []
        samplers.run(study_args(samplers, args, quick + sub_argv(args, samplers)))
    convergence.run(study_args(convergence, args, sub_argv(args, convergence, CONVERGENCE)))
    writeup.run(study_args(writeup, args, sub_argv(args, writeup, WRITEUP)))
    if args.lab != "off":            # its own BSDFs and samplers: only where, how and seed
        lab.run(lab.parse([a for k in ("variant", "seed", "out")
                           for a in (f"--{k}", str(getattr(args, k)))]
                          + (["--quick"] if args.lab == "quick" else [])))
    if args.stability != "off":
        stability.run(study_args(stability, args, sub_argv(args, stability) + (
            ["--quick"] if args.stability == "quick" else [])))
    seconds = time.perf_counter() - start
    report.write_section(args.out, "run_all", "This run", 90, {
        "command": "python -m experiments.run_all " + " ".join(sys.argv[1:] if argv is None
                                                               else argv),
        "full": args.full}, [report.text(
            f"The whole suite took {seconds:.1f} s of wall time (renders already in the store "
            f"are not redone, so a resumed run is faster) with a peak resident memory of "
            f"{report.peak_rss_mb():.0f} MiB.")], args.variant, seconds)
    path = report.build_report(args.out, args.variant)
    print(f"done in {seconds:.1f} s, peak RSS {report.peak_rss_mb():.0f} MiB; report: {path}")


if __name__ == "__main__":
    cli.main_wrapper(main)
