"""The default experiments and the report (``make run``): every registered study, in order.

Runs each study of :func:`experiments.lib.studies.ordered` (built-in: the sampler study,
the convergence study, the writeup's figures, the sampling lab, the stability sweeps and the
scene suite; and any study a ``--plugin FILE`` registers) at its own default sizes and
repeats, then writes OUT/index.html. ``--NAME default|quick|off`` runs a study at its
defaults, at tiny settings, or not at all. The options given here (--resolution, --spp,
--repeats, --methods, --max-depth, ...) are passed on to each study that takes them.
Rerunning resumes: finished render jobs are not redone.

    python -m experiments.run_all --help
"""
from __future__ import annotations

import sys

from experiments.lib import cli, clock, figure_pool, report, studies

#: Options passed on to every study that takes them: always (SHARED), or when given here
#: (FORWARDED; a study's own ``forwarded`` adds to these).
SHARED = {"scene": "--scene", "variant": "--variant", "seed": "--seed", "out": "--out"}
FORWARDED = {"resolution": "--resolution", "spp": "--spp", "max_depth": "--max-depth",
             "rr_depth": "--rr-depth", "reference_spp": "--reference-spp",
             "repeats": "--repeats", "methods": "--methods",
             "reference_cache": "--reference-cache", "replay_counts": "--replay-counts"}


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.run_all", __doc__.split("\n")[0],
                          spp=256, time_budget=0.25)
    for study in studies.ordered():
        if study.shared is not None:
            study.shared(p)
        p.add_argument(f"--{study.name}", choices=studies.MODES, default="default",
                       dest=mode_dest(study),
                       help=f"{study.title}: at its own default settings, tiny (quick), or "
                            f"not at all")
    return p


def mode_dest(study: studies.StudySpec) -> str:
    """Where ``--NAME default|quick|off`` is kept (apart from every other option's dest: a
    study may be named like one, e.g. ``rr_depth``)."""
    return f"study_mode_{study.name}"


def _value(key, value) -> str:
    if key in ("resolution", "full_resolution"):
        return "{}x{}".format(*value)
    return ",".join(map(str, value)) if isinstance(value, list) else str(value)


def sub_argv(args, study: studies.StudySpec) -> list[str]:
    """Arguments for ``study``: the shared ones, and those given explicitly here that its
    parser takes."""
    known = study.build_parser()._option_string_actions
    argv = []
    for key, option in SHARED.items():
        if option in known:
            argv += [option, _value(key, getattr(args, key))]
    for key, option in dict(FORWARDED, **study.forwarded).items():
        if key in args.explicit and option in known:
            value = getattr(args, key)
            if isinstance(value, bool):
                argv += [option] if value else []
            else:
                argv += [option, _value(key, value)]
    return argv


def study_args(study: studies.StudySpec, args, argv: list[str]):
    """``study``'s own parser over ``argv``, sharing this run's cluster, if any."""
    sub = study.parse_args(argv)
    sub.executor = args.executor
    return sub


def main(argv=None) -> None:
    cli.load_extensions(argv)
    args = cli.parse_args(build_parser(), argv)
    timer = clock.Timer()
    with figure_pool.parallel():        # figures written beside the run, never during renders
        for study in studies.ordered():
            mode = getattr(args, mode_dest(study))
            if mode == "off":
                continue
            quick = list(study.quick) if mode == "quick" else []
            study.run(study_args(study, args, quick + sub_argv(args, study)))
            figure_pool.drain()         # a study's figures are on disk when it is done
    seconds = timer.elapsed()
    report.write_section(args.out, "run_all", "This run", 90, {
        "command": "python -m experiments.run_all " + " ".join(sys.argv[1:] if argv is None
                                                               else argv),
        "full": getattr(args, "full", False)}, [report.text(
            f"The whole suite took {seconds:.1f} s of wall time (renders already in the store "
            f"are not redone, so a resumed run is faster) with a peak resident memory of "
            f"{report.peak_rss_mb():.0f} MiB.")], args.variant, seconds)
    path = report.build_report(args.out, args.variant)
    print(f"done in {seconds:.1f} s, peak RSS {report.peak_rss_mb():.0f} MiB; report: {path}")


if __name__ == "__main__":
    cli.main_wrapper(main)
