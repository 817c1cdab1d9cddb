"""The default experiment suite on the bundled scene, and the report (``make run``).

Runs :mod:`experiments.convergence` (sequences, error against spp and time,
equal-time panel, efficiency table), :mod:`experiments.writeup` (the
writeup's figures; with --full also the 1024x512, 1000-spp no-bias checks)
and :mod:`experiments.stability` (where each method breaks down, at its own
default settings), then writes OUT/index.html. Rerunning resumes: finished renders are not redone.

    python -m experiments.run_all --help
"""
from __future__ import annotations

import sys
import time

from experiments import convergence, stability, writeup
from experiments.lib import cli, report


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.run_all", __doc__.split("\n")[0],
                          spp=256, time_budget=2.0)
    writeup.add_arguments(p)
    p.add_argument("--stability", choices=("default", "quick", "off"), default="default",
                   help="the stability study at its own default settings, tiny (quick), "
                        "or not at all (default: default)")
    return p


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    start = time.perf_counter()
    convergence.run(args)
    writeup.run(args)
    if args.stability != "off":
        stability.run(stability.parse(
            ["--out", args.out, "--variant", args.variant, "--seed", str(args.seed),
             "--scene", args.scene] + (["--quick"] if args.stability == "quick" else [])))
    seconds = time.perf_counter() - start
    report.write_section(args.out, "run_all", "This run", 90, {
        "command": "python -m experiments.run_all " + " ".join(sys.argv[1:] if argv is None
                                                               else argv),
        "full": args.full}, [report.text(
            f"The whole suite took {seconds:.1f} s of wall time (renders already on disk are "
            f"not redone, so a resumed run is faster) with a peak resident memory of "
            f"{report.peak_rss_mb():.0f} MiB.")], args.variant, seconds)
    path = report.build_report(args.out, args.variant)
    print(f"done in {seconds:.1f} s, peak RSS {report.peak_rss_mb():.0f} MiB; report: {path}")


if __name__ == "__main__":
    cli.main_wrapper(main)
