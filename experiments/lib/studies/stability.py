"""Stability sweeps: where each sampling method breaks down, measured and charted.

Four sweeps on the scene's parameters (see :mod:`experiments.lib.sweeps`):
the Phong exponent (every vr_path strategy), the light size at constant
power (with and without next-event estimation), grazing incidence, and
Halton without and with randomization at max_depth 2 and --max-depth (8 when
the scene and the command line give none above 2, or an unbounded one, where
plain Halton's all-zero first sample would never end its path); with --full (make full)
a fifth, adaptive sampling against its plain twin on the light sweep's scenes, where
its pilot can mislead it (fireflies, dark pixels). Every comparison is
measured over --repeats independent randomizations and reported with 95%
intervals. Outliers are counted over every render. --methods picks the
strategies of the light and Halton sweeps.

    python -m experiments.stability --help
"""
from __future__ import annotations

import math
import os

from experiments.lib import files
from experiments.lib.studies import StudySpec, check_scene, register_study
from experiments.lib import cli, clock, report, stats
from experiments.lib.metrics import FIREFLY_MADS
from experiments.lib.sweeps import BREAK_FACTOR, NAME, NORMAL, QUICK, REGISTRY, Context, Skip
from experiments.lib.sweeps.base import StabilitySettings

ORDER = 40
#: Sweeps that only ``--full`` (``make full``) adds to the default ones: the adaptive
#: method is not among the default run's methods either (the 5-minute make run).
FULL_ONLY = ("adaptive",)
DEFAULT_SWEEPS = tuple(n for n in REGISTRY if n not in FULL_ONLY)
QUICK_DEFAULTS = {"resolution": (32, 16), "spp": 4, "reference_spp": 16}
#: Independent repeats of every sweep render, for the intervals (--spp, and the Halton
#: ladder's 64, are split over them: each repeat renders spp // R).
REPEATS = 3


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.stability", __doc__.split("\n")[0], spp=32,
                          default_resolution="64x32", methods=("uniform", "cosine", "bsdf"),
                          repeats=REPEATS)
    p.set_defaults(reference_spp=128)
    p.add_argument("--quick", action="store_true",
                   help=f"tiny run (for tests): fewer sweep points; resolution, --spp and "
                        f"--reference-spp default to {QUICK_DEFAULTS['resolution'][0]}x"
                        f"{QUICK_DEFAULTS['resolution'][1]}, {QUICK_DEFAULTS['spp']} and "
                        f"{QUICK_DEFAULTS['reference_spp']}")
    p.add_argument("--sweeps", type=sweep_list, default=",".join(DEFAULT_SWEEPS),
                   help=f"comma-separated sweeps to run: {', '.join(REGISTRY)} (default: "
                        f"{', '.join(DEFAULT_SWEEPS)}; --full adds the rest)")
    p.add_argument("--full", action="store_true",
                   help=f"also the sweeps {', '.join(FULL_ONLY)} when --sweeps is not given "
                        f"(make full)")
    return p


def sweep_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in REGISTRY]
    if bad or not names:
        raise cli.argparse.ArgumentTypeError(
            f"unknown sweep '{bad[0] if bad else text}': choose from {', '.join(REGISTRY)}")
    return list(dict.fromkeys(names))


def parse(argv=None):
    args = cli.parse_args(build_parser(), argv)
    if args.full and "sweeps" not in args.explicit:
        args.sweeps = list(REGISTRY)
    if args.quick:       # quick values for every option not given on the command line
        for key, value in QUICK_DEFAULTS.items():
            if key not in args.explicit:
                setattr(args, key, value)
    return args


def settings_from(args) -> StabilitySettings:
    """The typed settings of a parsed command line (:func:`parse`); the library below
    never sees the Namespace."""
    return StabilitySettings(**cli.common_fields(args), spp=args.spp, sweeps=tuple(args.sweeps),
                             quick=bool(args.quick), config=QUICK if args.quick else NORMAL)


def declare(ctx: Context, names) -> tuple[dict, dict]:
    """The declaration of every sweep in ``names`` (None: nothing to render), and the
    skipped ones with the reason."""
    declarations, skipped = {}, {}
    for name in names:
        sweep = REGISTRY[name]
        reason = check_scene(NAME, ctx.settings.info, sweep.needs, f"sweep '{name}'")
        if reason is not None:
            skipped[name] = reason
            continue
        try:
            declarations[name] = sweep.declare(ctx)
        except Skip as e:
            skipped[name] = str(e)
    return declarations, skipped


def _json_safe(rows: list[dict]) -> list[dict]:
    """NaN/inf (no interval from one repeat) as null in summary.json."""
    return [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
             for k, v in r.items()} for r in rows]


def run(args) -> None:
    run_settings(settings_from(args))


def run_settings(settings: StabilitySettings) -> None:
    """Declare, render and measure (the engine), analyse and report every sweep of
    ``settings``."""
    timer = clock.Timer()
    ctx = Context(settings)
    declarations, skipped = declare(ctx, settings.sweeps)
    measured = {name: None if decl is None else ctx.measure(decl)
                for name, decl in declarations.items()}
    blocks = [report.text(
        f"Where each sampling method breaks down, on {os.path.basename(settings.scene)} at "
        f"{ctx.width}x{ctx.height} ({settings.depth.describe()}). Each sweep point is the "
        f"scene with one parameter changed (the scene files are in {NAME}/scenes/); errors are "
        f"relMSE "
        f"against a {settings.reference_spp}-spp reference ({settings.reference_method}) of "
        f"the same point, the reference's own expected relMSE (from the spread of its passes) "
        f"subtracted, means over {ctx.repeats} independent repeats with {stats.LEVEL:.0%} "
        f"intervals "
        f"({stats.METHOD}). Times are warm render times on this (shared) machine. Breakdown "
        f"points and verdicts below are computed from the measurements; a difference is "
        f"claimed only where its interval excludes no difference.")]
    notes, rows = [], []
    for name in settings.sweeps:
        if name in skipped:
            blocks.append(report.text(f"Sweep '{name}' skipped: {skipped[name]}."))
            continue
        sweep = REGISTRY[name]
        part = sweep.report(ctx, sweep.analyse(sweep.measure(ctx, measured[name])))
        blocks += part.blocks
        notes += part.notes
        rows += part.rows
    outliers = ctx.outliers.report(settings.out)
    blocks += outliers.blocks
    notes += outliers.notes
    blocks.append(report.text("Closing note, per sweep: " + " ".join(notes)))
    table = {"scene": settings.scene, "resolution": f"{ctx.width}x{ctx.height}",
             "spp": settings.spp,
             "repeats": ctx.repeats, "spp per repeat": ctx.spp,
             "halton spp per repeat": ctx.halton_spp, "sweeps": ", ".join(settings.sweeps),
             "quick": settings.quick,
             "strategies (light, halton sweeps)": ", ".join(ctx.strategies),
             "path settings": settings.depth.describe(),
             "halton sweep max_depth": ", ".join(map(str, ctx.halton_depths)),
             "variant": settings.variant, "seed": settings.seed,
             "reference": f"{settings.reference_spp} spp, {settings.reference_method}",
             "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
             "breakdown factor": BREAK_FACTOR, "firefly threshold (MADs)": FIREFLY_MADS,
             "render times measured on": ctx.timed_on()}
    report.write_section(settings.out, NAME, "Stability: where each method breaks down", ORDER,
                         table, blocks, settings.variant, timer.elapsed())
    # machine-readable results (breakdown sentences, rows with intervals, outliers)
    files.write_json(os.path.join(settings.out, NAME, "summary.json"),
                     {"notes": notes, "repeats": ctx.repeats, "rows": _json_safe(rows),
                      "outliers": ctx.outliers.rows})


STUDY = register_study(StudySpec(
    NAME, 'Stability: where each method breaks down', ORDER, build_parser, run,
    parse=parse, quick=("--quick",), forwarded={"full": "--full"}))
