"""The default experiment suite on the bundled scene, and the report (``make run``).

Runs :mod:`experiments.convergence` (sequences, error against spp and time,
equal-time panel, efficiency table; with ``bsdf+nee`` and ``path`` as
reference rows), :mod:`experiments.writeup` (the writeup's figures; with
--full also the 1024x512, 1000-spp no-bias checks), :mod:`experiments.samplers`
(halton against Mitsuba's samplers) and :mod:`experiments.stability` (where
each method breaks down), then writes OUT/index.html. The sampler and
stability studies run at their own default sizes unless --resolution, --spp,
--methods (stability), --max-depth or --rr-depth are given here. Rerunning
resumes: finished render jobs are not redone.

    python -m experiments.run_all --help
"""
from __future__ import annotations

import sys
import time

from experiments import convergence, lab, samplers, stability, writeup
from experiments.lib import cli, report

#: Options passed on to the sampler and stability studies when given here.
SHARED = {"scene": "--scene", "variant": "--variant", "seed": "--seed", "out": "--out"}
FORWARDED = {"resolution": "--resolution", "spp": "--spp", "max_depth": "--max-depth",
             "rr_depth": "--rr-depth", "reference_spp": "--reference-spp"}


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.run_all", __doc__.split("\n")[0],
                          spp=256, time_budget=2.0)
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
    return "{}x{}".format(*value) if key == "resolution" else str(value)


def sub_argv(args, extra: tuple = ()) -> list[str]:
    """Arguments for a sub-study: the shared ones, and those given explicitly here."""
    argv = []
    for key, option in SHARED.items():
        argv += [option, _value(key, getattr(args, key))]
    for key, option in dict(FORWARDED, **dict(extra)).items():
        if key in args.explicit:
            value = getattr(args, key)
            argv += [option, ",".join(value) if isinstance(value, list) else _value(key, value)]
    return argv


#: Tiny sizes of --samplers quick (for tests).
SAMPLERS_QUICK = ["--resolution", "16x8", "--spp", "4", "--reference-spp", "16"]


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    start = time.perf_counter()
    convergence.run(args)
    writeup.run(args)
    if args.samplers != "off":
        quick = SAMPLERS_QUICK if args.samplers == "quick" else []
        sub = cli.parse_args(samplers.build_parser(), quick + sub_argv(args))
        sub.executor = args.executor                  # the same cluster, if any
        samplers.run(sub)
    if args.lab != "off":
        lab.run(lab.parse([a for k in ("variant", "seed", "out")
                           for a in (f"--{k}", str(getattr(args, k)))]
                          + (["--quick"] if args.lab == "quick" else [])))
    if args.stability != "off":
        sub = stability.parse(sub_argv(args, (("methods", "--methods"),))
                              + (["--quick"] if args.stability == "quick" else []))
        sub.executor = args.executor
        stability.run(sub)
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
