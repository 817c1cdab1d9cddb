"""Sampler study: every sampler of the sampler table, the bundled ones against Mitsuba's own.

For the base method (default ``bsdf+nee``) with every sampler label of the sampler table
(:func:`experiments.lib.samplers.labels`: Mitsuba's independent, stratified, multijitter,
orthogonal and ldsampler, the bundled samplers with each randomization, and any sampler a
``--plugin`` file registers), at max_depth 2 and 8 (or --max-depth), each sample count of
the ladder 1, 4, 16, ... --spp is a fresh render (so every sampler stratifies the whole
count; samplers that round a count up are compared at the count they rendered). Measured:
MSE and relMSE against a high-spp reference (its own expected error subtracted), time per
sample, Veach efficiency 1/(error x time) relative to ``independent``, the fitted slope of
MSE against spp; a chart of error against time per sampler; per depth a conclusion table
(the most efficient sampler against the runner-up, each bundled sampler family's best
against the best native sampler and the others, with the counts where the order changes)
and three sentences computed from it. Renders of one depth are interleaved (every sampler at
one spp, then the next spp) so that changing machine load affects them alike.

The screen-space pass (:class:`.sampler_comparison.screen.ScreenSpace`, options --screen-*)
renders a short ladder (1, 4, 16 spp) on a larger image (128x128; a spectrum needs it) at
max_depth 2, for a subset of labels by default (the baseline, multijitter, ldsampler and
each bundled sampler at its last randomization: every FLIP of a 128x128 image costs a few
tenths of a CPU second; --screen-samplers all for every label). Per count: mean FLIP against
the reference, the radially averaged power spectrum of the error image and its low-frequency
share (:mod:`experiments.lib.screen_space`: power below a quarter of Nyquist over the total,
the reference's own white noise subtracted), and MSE efficiency; a conclusion table per
depth (each bundled sampler's best against every native one and the other bundled ones, per
count) and three sentences computed from it.

The study is a list of measurement passes (:data:`PASSES`), each a declaration on the
experiment engine (:mod:`experiments.lib.engine`, which plans, renders, costs and measures)
-> pure analysis -> report: its settings and declarations (:mod:`.plan`), the efficiency
pass (:mod:`.efficiency`, analysed by :mod:`.analysis`) and the screen-space pass
(:mod:`.screen`, analysed by :mod:`.screen_analysis`), modules of this package
(:mod:`experiments.lib.studies.sampler_comparison`). This module is the entry point: the
command line, :func:`settings_of` (the one place that reads it), the report's introduction
and settings, and the registration of the study as ``samplers``.

    python -m experiments.samplers --help
"""
from __future__ import annotations

import os

from experiments.lib import cli, clock, files, report, samplers, stats
from experiments.lib.engine import Engine
from experiments.lib.methods import Method
from experiments.lib.plan import doubling_targets
from experiments.lib.study import Study, StudySettings
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies.sampler_comparison.analysis import BASELINE, METRIC, METRIC_NAMES
from experiments.lib.studies.sampler_comparison.efficiency import Efficiency
from experiments.lib.studies.sampler_comparison.plan import (
    BASE, NAME, SCREEN_COUNTS, SCREEN_DEPTHS, SCREEN_NATIVES, SCREEN_REFERENCE_SPP,
    SCREEN_REPEATS, SCREEN_RESOLUTION, ScreenSettings, Settings, default_screen_labels, plan)
from experiments.lib.studies.sampler_comparison.screen import ScreenSpace

TITLE = "Samplers: the bundled samplers against Mitsuba's own"
ORDER = 10
#: One short depth by default (make run's time budget); --depths 2,8 adds a long one.
DEPTHS = (2,)
#: Independent runs of every count of the ladder, as in the other studies (samplers close
#: in efficiency, within about 10%, come out as ties at 3: --repeats 8 tells more of them
#: apart; make run keeps to its time budget).
REPEATS = 3


# ------------------------------------------------------------------ settings

def base_method(text: str) -> Method:
    m = cli.one_method(text)
    if "+" in m.name.replace("+nee", ""):
        raise cli.argparse.ArgumentTypeError(
            f"invalid base method '{text}': give it without a sampler (e.g. bsdf+nee or path); "
            f"the study adds every sampler")
    return m


def screen_samplers(text: str) -> tuple:
    """--screen-samplers: 'default', 'all' or labels of the sampler table (checked)."""
    if text in ("default", "all"):
        return tuple(default_screen_labels() if text == "default" else samplers.labels())
    labels = [x.strip() for x in text.split(",") if x.strip()]
    for label in labels:
        try:
            samplers.split_label(label)
        except ValueError as e:
            raise cli.argparse.ArgumentTypeError(
                f"invalid --screen-samplers '{text}': {e} (or 'default', 'all')") from None
    if not labels:
        raise cli.argparse.ArgumentTypeError("--screen-samplers names no sampler")
    return tuple(dict.fromkeys(labels))


def count_list(text: str) -> list[int]:
    try:
        counts = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        counts = []
    if not counts or any(c < 1 for c in counts):
        raise cli.argparse.ArgumentTypeError(
            f"invalid counts '{text}': expected comma-separated positive integers, e.g. "
            f"1,4,16")
    return sorted(set(counts))


def depth_list(text: str) -> list[int]:
    try:
        depths = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        depths = []
    if not depths or any(d < -1 for d in depths):
        raise cli.argparse.ArgumentTypeError(
            f"invalid depths '{text}': expected comma-separated integers >= -1, e.g. 2,8")
    return list(dict.fromkeys(depths))


def add_arguments(p: cli.Parser) -> None:
    p.add_argument("--base", type=base_method, default=BASE,
                   help="method the samplers drive (STRATEGY[+nee] or path)")
    p.add_argument("--depths", type=depth_list, default=",".join(map(str, DEPTHS)),
                   help="max_depth values of the study (--max-depth replaces them by one)")
    p.add_argument("--ladder-factor", type=cli.positive_int, default=4,
                   help="ratio of consecutive sample counts of the ladder")
    g = p.add_argument_group(
        "screen-space pass", "FLIP and the error's power spectrum on a larger image: its own "
        "resolution, counts, depths, samplers, repeats and reference (--max-depth replaces "
        "its depths too)")
    g.add_argument("--screen-space", choices=("on", "off"), default="on",
                   help="run the screen-space pass")
    g.add_argument("--screen-resolution", type=cli.resolution, default=SCREEN_RESOLUTION,
                   metavar="WxH", help="film resolution of the pass (a spectrum needs at "
                                       "least 128x128)")
    g.add_argument("--screen-counts", type=count_list, default=",".join(map(str, SCREEN_COUNTS)),
                   help="sample counts of the pass, each a fresh render")
    g.add_argument("--screen-depths", type=depth_list, default=",".join(map(str, SCREEN_DEPTHS)),
                   help="max_depth values of the pass")
    g.add_argument("--screen-samplers", type=screen_samplers, default="default",
                   help="'default' (the baseline, " + ", ".join(SCREEN_NATIVES) + " and each "
                        "other sampler at its last randomization), 'all' (every label) or "
                        "comma-separated labels")
    g.add_argument("--screen-repeats", type=cli.positive_int, default=SCREEN_REPEATS,
                   metavar="R", help="independent randomizations of every render of the pass")
    g.add_argument("--screen-reference-spp", type=cli.positive_int,
                   default=SCREEN_REFERENCE_SPP,
                   help="samples per pixel of the pass's reference (--reference-method)")


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.samplers", __doc__.split("\n")[0], spp=64,
                          default_resolution="64x32", methods=("bsdf+nee",), repeats=REPEATS)
    # The reference uses the independent sampler: a QMC reference shares structure with the
    # QMC renders it judges (ldsampler against a path+ldsampler reference: its MSE came out
    # 7-12% low), which biases the comparison. Its own expected error is subtracted, so it
    # need not be far below the samplers' errors.
    p.set_defaults(reference_spp=1024, reference_method="path")
    add_arguments(p)
    return p


def settings_of(args) -> Settings:
    one = [args.max_depth] if args.max_depth is not None else None
    screen = None if args.screen_space == "off" else ScreenSettings(
        tuple(args.screen_resolution), tuple(args.screen_counts),
        tuple(one or args.screen_depths), tuple(args.screen_samplers), args.screen_repeats,
        args.screen_reference_spp, args.reference_method)
    return Settings(args.base, tuple(one or args.depths),
                    tuple(doubling_targets(args.spp, args.ladder_factor)),
                    tuple(samplers.labels()), args.depth, args.scene, tuple(args.resolution),
                    screen)


#: The measurement passes, in order (rendered together, then measured and reported).
PASSES: tuple = (Efficiency(), ScreenSpace())


# ------------------------------------------------------------------ the study

def introduction(st: Study, cfg: Settings) -> str:
    """What the study compares, from the sampler table (no sampler named by hand), in
    paragraphs of at most 80 words."""
    natives = [s for s in cfg.samplers if samplers.split_label(s)[0].native]
    bundled = [s for s in cfg.samplers if s not in natives]
    fixed = [s for s in cfg.samplers if samplers.split_label(s)[0].is_deterministic(
        samplers.split_label(s)[1])]
    time_is = clock.DESCRIPTION
    metric = METRIC_NAMES[METRIC]
    return "\n\n".join([
        f"Which sampler to use with {cfg.base} on {os.path.basename(cfg.scene)} at "
        f"{st.width}x{st.height}: Mitsuba's own samplers ({', '.join(natives)}) against the "
        f"bundled ones ({', '.join(bundled) or 'none'}), at max_depth "
        f"{', '.join(map(str, cfg.depths))}.",
        f"Every count of the ladder {', '.join(map(str, cfg.targets))} spp is its own "
        f"render, {st.repeats} times with independent randomizations"
        + (f" ({', '.join(fixed)}: deterministic, one run)" if fixed else "")
        + ". Samplers that round the count up are compared at the count they rendered, "
          "which the table gives beside the requested one.",
        f"Errors are expected values over the repeats, with the reference's own expected "
        f"error subtracted. Efficiency is Veach's 1/(error x render time) relative to "
        f"{BASELINE}: above 1, a sampler reaches a given error sooner. Every verdict "
        f"uses {metric} as the error (the tables give MSE too). Intervals: "
        f"{stats.LEVEL:.0%}, {stats.METHOD}.",
        f"Render time is {time_is}, warm in exactly the timed configuration (a render "
        f"during which a kernel compiled is rendered again)."])


def screen_settings_text(sc: ScreenSettings | None) -> str:
    if sc is None:
        return "off"
    return (f"{sc.resolution[0]}x{sc.resolution[1]}, max_depth "
            f"{', '.join(map(str, sc.depths))}, {', '.join(map(str, sc.counts))} spp, "
            f"{sc.repeats} repeats, reference {sc.reference_spp} spp of {sc.reference}; "
            f"samplers {', '.join(sc.samplers)}; verdicts by mean FLIP, low-frequency share "
            f"and efficiency 1/(MSE x time)")


def run(args) -> None:
    timer = clock.Timer()
    st, cfg = Study(StudySettings(**cli.common_fields(args))), settings_of(args)
    engine = Engine(st)
    blocks, summary, timed = [report.text(introduction(st, cfg))], {}, []
    for p in PASSES:
        declared = p.declare(st, cfg)
        if declared is None:                # the pass is switched off
            continue
        planned = plan(engine, declared)
        measured = p.measure(st, cfg, planned, engine.run(declared))
        reported = p.report(st, cfg, planned, measured, p.analyse(measured))
        blocks += reported.blocks
        summary.update(reported.summary)
        timed += reported.jobs
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "base method": str(cfg.base), "max_depth": ", ".join(map(str, cfg.depths)),
                "repeats": st.repeats, "path settings": args.depth.describe(),
                "variant": args.variant, "seed": args.seed,
                "reference": f"{args.reference_spp} spp of {args.reference_method}",
                "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
                "verdicts": f"efficiency 1/({METRIC_NAMES[METRIC]} x time)",
                "screen-space pass": screen_settings_text(cfg.screen),
                "render times measured on": st.timed_on(timed)}
    report.write_section(args.out, NAME, TITLE, ORDER, settings, blocks, args.variant,
                         timer.elapsed())
    files.write_json(os.path.join(args.out, NAME, "summary.json"), summary)


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run,
    quick=("--resolution", "16x8", "--spp", "4", "--reference-spp", "16",
           "--screen-resolution", "16x8", "--screen-counts", "1,4", "--screen-repeats", "2",
           "--screen-reference-spp", "16")))
