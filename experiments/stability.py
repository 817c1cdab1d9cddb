"""Stability sweeps: where each sampling method breaks down, measured and charted.

Four sweeps on the scene's parameters (see :mod:`experiments.lib.sweeps`):
the Phong exponent (every vr_path strategy), the light size at constant
power (with and without next-event estimation), grazing incidence, and
Halton without and with randomization at max_depth 2 and --max-depth (8 when
the scene and the command line give none above 2). Outliers are counted over
every render. --methods picks the strategies of the light and Halton sweeps.

    python -m experiments.stability --help
"""
from __future__ import annotations

import os
import time

from experiments.lib import cli, report, store
from experiments.lib.sweeps import BREAK_FACTOR, NAME, NORMAL, QUICK, SWEEPS, Sweeps
from experiments.lib.metrics import FIREFLY_MADS

ORDER = 40
QUICK_DEFAULTS = {"resolution": (32, 16), "spp": 4, "reference_spp": 16}


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.stability", __doc__.split("\n")[0], spp=32,
                          default_resolution="128x64", methods=("uniform", "cosine", "bsdf"))
    p.set_defaults(reference_spp=128)
    p.add_argument("--quick", action="store_true",
                   help=f"tiny run (for tests): fewer sweep points; resolution, --spp and "
                        f"--reference-spp default to {QUICK_DEFAULTS['resolution'][0]}x"
                        f"{QUICK_DEFAULTS['resolution'][1]}, {QUICK_DEFAULTS['spp']} and "
                        f"{QUICK_DEFAULTS['reference_spp']}")
    p.add_argument("--sweeps", type=sweep_list, default=",".join(SWEEPS),
                   help=f"comma-separated sweeps to run: {', '.join(SWEEPS)}")
    return p


def sweep_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in SWEEPS]
    if bad or not names:
        raise cli.argparse.ArgumentTypeError(
            f"unknown sweep '{bad[0] if bad else text}': choose from {', '.join(SWEEPS)}")
    return list(dict.fromkeys(names))


def parse(argv=None):
    args = cli.parse_args(build_parser(), argv)
    if args.quick:       # quick values for every option not given on the command line
        for key, value in QUICK_DEFAULTS.items():
            if key not in args.explicit:
                setattr(args, key, value)
    args.config = QUICK if args.quick else NORMAL
    return args


def run(args) -> None:
    start = time.perf_counter()
    sw = Sweeps(args, args.config)
    jobs = sw.plan(args.sweeps)
    sw.st.run(jobs, f"{NAME}: sweeps")
    blocks = [report.text(
        f"Where each sampling method breaks down, on {os.path.basename(args.scene)} at "
        f"{sw.width}x{sw.height} ({args.depth.describe()}). Each sweep point is the scene with "
        f"one parameter changed (the scene files are in {NAME}/scenes/); errors are relMSE "
        f"against a {args.reference_spp}-spp reference ({args.reference_method}) of the same "
        f"point. Times are warm render times on this (shared) machine. Breakdown points below "
        f"are computed from the measurements.")]
    parts = {"exponent": sw.exponent_sweep, "light": sw.light_sweep,
             "grazing": sw.grazing_sweep, "halton": sw.halton_sweep}
    for name in args.sweeps:
        if name in sw.skipped:
            blocks.append(report.text(f"Sweep '{name}' skipped: the scene has no <default> "
                                      f"parameter {sw.skipped[name]}."))
        else:
            blocks += parts[name]()
    blocks += sw.outlier_blocks()
    blocks.append(report.text("Closing note, per sweep: " + " ".join(sw.notes)))
    settings = {"scene": args.scene, "resolution": f"{sw.width}x{sw.height}", "spp": args.spp,
                "sweeps": ", ".join(args.sweeps), "quick": args.quick,
                "strategies (light, halton sweeps)": ", ".join(sw.strategies),
                "path settings": args.depth.describe(),
                "halton sweep max_depth": ", ".join(map(str, sw.halton_depths)),
                "variant": args.variant, "seed": args.seed,
                "reference": f"{args.reference_spp} spp, {args.reference_method}",
                "breakdown factor": BREAK_FACTOR, "firefly threshold (MADs)": FIREFLY_MADS,
                "render times measured on": sw.st.timed_on(jobs)}
    report.write_section(args.out, NAME, "Stability: where each method breaks down", ORDER,
                         settings, blocks, args.variant, time.perf_counter() - start)
    # machine-readable results (breakdown sentences, outliers) for tests and other tools
    store.write_json(os.path.join(args.out, NAME, "summary.json"),
                     {"notes": sw.notes, "outliers": sw.outliers.rows})


def main(argv=None) -> None:
    args = parse(argv)
    run(args)
    print(f"report: {report.build_report(args.out, args.variant)}")


if __name__ == "__main__":
    cli.main_wrapper(main)
