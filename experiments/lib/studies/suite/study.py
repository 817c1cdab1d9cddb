"""Scene suite: every method on a set of scenes, each isolating one phenomenon, against a
cached reference per scene; a scene x method matrix with intervals and the winner per scene.

``--scenes DIR|FILE,...`` takes any folder (its ``*.xml``) or list of Mitsuba 3 scene files
(read through Mitsuba's own parser: ``<include>``, ``<path>``, ``$`` defaults, ``<ref>``);
default: the bundled suite, ``scenes/suite/``. Each scene's integrator and sampler are
replaced per method, its own max_depth (and rr_depth, hide_emitters) kept unless
``--max-depth`` etc. say otherwise. Resolution: the scene's own film, scaled so that its long
side is at most ``--max-size`` pixels (aspect kept; and scaled up to ``--min-size`` where
it is shorter), unless ``--resolution`` gives one. ``--preset paper`` sets publication-size
values (PRESETS; an option given explicitly wins); ``--preset default`` changes nothing.

Per scene and method (a cell), ``--repeats`` independent runs at equal spp (``--spp``) and at
equal time: each equal-time render gets about ``--time-budget`` seconds of sample work at the
cell's measured time per sample (its spp rounded to a power of two: Mitsuba renders powers of
two with another kernel than other counts, and one kernel per cell keeps compilation down); a
learning method's (guided) from one pilot render at that count, in no comparison (its
equal-spp renders are too short to train, and cost what plain BSDF sampling costs), and not
rounded (its efficiency grows with its count: rounded, it would follow the rounding).
Time per sample: the execution time of each render's kernels (Dr.Jit's kernel history:
the sample work, without tracing the integrator or launching kernels, a fixed cost per
render call that can swamp the samples of a small render), over its samples, per repeat
summed over both budgets' renders. The suite is one declaration (:mod:`.declare`) over the
experiment engine, which decides every count and renders: a scene's cells in groups of at
most the methods a process keeps warm (the baseline and vr_path bsdf+nee lead the first),
their renders taking turns. Errors against the reference (from
:mod:`experiments.lib.references`: rendered once per scene, cached, extended when too noisy;
the best sampler's method's where it is proven against ``--reference-method``'s on the
scene, :mod:`.reference_choice`) with its own expected error subtracted; efficiency over
``--baseline`` (Mitsuba's ``path``: what a user would run instead) from relMSE and time per
sample.

    python -m experiments.suite --help
"""
from __future__ import annotations

import os

import numpy as np

import scenes as bundled
from experiments.lib import cli, clock, references, samplers, scenes
from experiments.lib.engine import Engine
from experiments.lib.methods import parse_method, strategies
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies.sampler_comparison import efficiency as sampler_efficiency
from experiments.lib.studies.suite import (analysis, bias_renders, bias_test, declare,
                                           measure, reference_choice, report)
from experiments.lib.study import Study
from integrators.strategies import integrator_type

NAME, ORDER, TITLE = declare.NAME, declare.ORDER, declare.TITLE
#: Long side of the film when --resolution is not given (the scene's film scaled down to it).
MAX_SIZE = 48
#: The reference's automatic extension stops at this many times --reference-spp.
REFERENCE_GROWTH = 16
#: Without --reference-max-spp (and --quick), a reference whose extension costs little goes
#: past that cap as far as this many seconds of rendering go
#: (:func:`experiments.lib.counts.reference_cap`: veach_mis' and rough_glass' references
#: at 48x36, whose heavy tails need 32768-65536 spp, a few seconds each).
REFERENCE_SECONDS = 6.0
QUICK_DEFAULTS = {"spp": 4, "time_budget": 0.02, "reference_spp": 32, "max_size": 12,
                  "scenes": "furnace,veach_mis", "methods": "bsdf,bsdf+nee,path"}
FLIP_MODES = ("first", "all")
#: ``--preset NAME``: option values set where the command line does not give them (an
#: explicit option wins; ``--quick`` wins over a preset). ``default`` changes nothing;
#: ``paper`` is the publication run (docs/methodology.md, "The paper preset", says why
#: each value and what it costs): every film's long side 256 pixels (the writeup's Cornell
#: box film, 256 x 128; the bundled films are 64 wide, so they are scaled up), 256 spp at
#: equal spp, 0.5 s of sample work at equal time, 8 repeats (a Student t of 2.36 at 7
#: degrees of freedom, against 4.30 at the default 3), references of 4096 spp extended to
#: their floor (FLOOR_SHARE of the smallest error) up to 65536 spp.
PRESETS = {
    "default": {},
    "paper": {"max_size": 256, "min_size": 256, "spp": 256, "time_budget": 0.5,
              "repeats": 8, "reference_spp": 4096, "reference_max_spp": 65536},
}


# ------------------------------------------------------------------ options

#: The adaptive modifier's method among the default methods: :data:`.analysis.TIMED_PAIR`'s
#: first method with its samples where the relative error is (docs/methodology.md,
#: "Adaptive sampling").
ADAPTIVE_METHOD = f"{analysis.TIMED_PAIR[0]}+adaptive"


def default_methods() -> list[str]:
    """Every vr_path strategy with and without NEE, every strategy that learns (its own
    integrator, e.g. ``guided``) with NEE only, ``bsdf+nee`` made adaptive
    (:data:`ADAPTIVE_METHOD`), then Mitsuba's path."""
    return [n for s in strategies() for n in
            ((s, f"{s}+nee") if integrator_type(s) == "vr_path" else (f"{s}+nee",))] + \
        [ADAPTIVE_METHOD, "path"]


def scene_files(text: str) -> list[str]:
    """The scene files of ``--scenes DIR|FILE,...`` (a folder: its ``*.xml``, sorted)."""
    out = []
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        if os.path.isdir(item):
            found = sorted(os.path.join(item, n) for n in os.listdir(item)
                           if n.endswith(".xml") and os.path.isfile(os.path.join(item, n)))
            if not found:
                raise cli.argparse.ArgumentTypeError(f"--scenes folder '{item}' holds no "
                                                     f"*.xml scene file")
            out += found
        elif os.path.isfile(item):
            out.append(item)
        elif item in bundled.suite_names() or f"suite/{item}.xml" in bundled.suite_names():
            out.append(bundled.path(item if item.endswith(".xml") else f"suite/{item}.xml"))
        else:
            raise cli.argparse.ArgumentTypeError(
                f"--scenes '{item}' is neither a folder nor a scene file (nor a bundled suite "
                f"scene: {', '.join(n[6:-4] for n in bundled.suite_names())})")
    if not out:
        raise cli.argparse.ArgumentTypeError("--scenes names no scene")
    return [os.path.abspath(p) for p in dict.fromkeys(out)]


def non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise cli.argparse.ArgumentTypeError(f"'{text}' is not a whole number >= 0")
    return value


def flip_mode(text: str) -> str:
    if text not in FLIP_MODES:
        raise cli.argparse.ArgumentTypeError(f"invalid --flip '{text}': choose "
                                             f"{' or '.join(FLIP_MODES)}")
    return text


def add_shared(p: cli.Parser) -> None:
    """The suite's options that run_all also takes (and passes on)."""
    p.add_argument("--scenes", type=scene_files, default=None, metavar="DIR|FILE,...",
                   help="the suite's scenes: folders (their *.xml) and scene files, "
                        "comma-separated; default: the bundled suite (scenes/suite)")
    p.add_argument("--references", default=None, metavar="DIR",
                   help="use your own reference images: DIR/<scene name>.exr (their own "
                        "error is unknown, nothing is subtracted)")
    p.add_argument("--preset", choices=tuple(PRESETS), default="default",
                   help="default: every option at its own default; paper: publication size (" +
                        ", ".join(f"{k.replace('_', '-')} {v}" for k, v in
                                  PRESETS["paper"].items()) +
                        "); options given explicitly win")


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.suite", __doc__.split("\n")[0], spp=16,
                          time_budget=0.02, default_resolution="48x36",
                          methods=default_methods(), repeats=3)
    p.set_defaults(reference_spp=256)
    p._option_string_actions["--resolution"].help = (
        f"film resolution of every scene; default: each scene's own film scaled so that its "
        f"long side is at most --max-size pixels")
    p._option_string_actions["--time-budget"].help = (
        "seconds of sample work (kernel execution time) of each equal-time render; the "
        "per-call cost is left out, see the module help")
    p._option_string_actions["--scene"].help = "not used by the suite (see --scenes)"
    add_shared(p)
    p.add_argument("--max-size", type=cli.positive_int, default=MAX_SIZE,
                   help="longest film side when --resolution is not given")
    p.add_argument("--min-size", type=non_negative_int, default=0,
                   help="scale a film whose long side is shorter up to this many pixels "
                        "(aspect kept; at most --max-size); 0: never scale up")
    p.add_argument("--baseline", type=cli.one_method, default="path",
                   help="method every efficiency is relative to (one of --methods)")
    p.add_argument("--best-sampler", default="auto", metavar="SAMPLER|auto|none",
                   help="add bsdf+nee with this sampler to the default methods; auto: the "
                        "sampler study's pick (OUT/samplers/summary.json: its most efficient "
                        "randomized sampler, or of those it cannot tell apart the last in its "
                        "table) at the depth nearest the scenes' median max_depth")
    p.add_argument("--reference-max-spp", type=cli.positive_int, default=None,
                   help=f"cap of the automatic extension of a reference too noisy for the "
                        f"comparison (default {REFERENCE_GROWTH} x --reference-spp, or "
                        f"more where it costs at most {REFERENCE_SECONDS} s)")
    p.add_argument("--flip", type=flip_mode, default="first",
                   help="FLIP of the first repeat at equal time only (the images shown), or "
                        "of every repeat at both budgets (an interval; HDR-FLIP costs 0.1-1 s "
                        "of CPU per 64x48 image)")
    p.add_argument("--quick", action="store_true",
                   help="tiny run for tests: " + ", ".join(f"{k} {v}" for k, v in
                                                          QUICK_DEFAULTS.items()))
    return p


def _best_sampler(choice: str, out: str, files_list) -> tuple[str | None, str]:
    """(bsdf+nee+SAMPLER or None, where it was chosen) for ``--best-sampler`` ``choice``,
    read from the sampler study's summary in ``out`` (auto)."""
    if choice == "none":
        return None, "no best sampler (--best-sampler none)"
    if choice != "auto":
        m = "bsdf+nee" if choice == samplers.DEFAULT else f"bsdf+nee+{choice}"
        cli.one_method(m)
        return m, f"{m} as given (--best-sampler)"
    depths = [scenes.read_scene(f).depth.max_depth for f in files_list if _reads(f)]
    depths = [d if d is not None and d >= 0 else 8 for d in depths] or [8]
    found = sampler_efficiency.pick_near(out, float(np.median(depths)))
    if found is None:
        return None, ("no best sampler: the sampler study has not run or picked none (run_all "
                      "runs it first)")
    d, record = found
    sampler = record["sampler"]
    m = "bsdf+nee" if sampler == samplers.DEFAULT else f"bsdf+nee+{sampler}"
    try:
        cli.one_method(m)
    except cli.argparse.ArgumentTypeError:
        return None, f"no best sampler: the sampler study's '{sampler}' is not known here"
    return m, (f"bsdf+nee with {sampler}: {sampler_efficiency.pick_text(d, record)} (chosen "
               f"there, on its own scene and counts, not here)")


def _reads(path: str) -> bool:
    try:
        scenes.read_scene(path)
        return True
    except (ValueError, OSError):
        return False


def parse(argv=None):
    args = cli.parse_args(build_parser(), argv)
    for key, value in PRESETS[args.preset].items():
        if key not in args.explicit:
            setattr(args, key, value)
    if args.quick:
        for key, value in QUICK_DEFAULTS.items():
            if key not in args.explicit:
                if key == "scenes":
                    value = scene_files(value)
                elif key == "methods":
                    value = cli.method_list(value)
                setattr(args, key, value)
    files_list = args.scenes or bundled.suite()
    methods = list(args.methods)
    args.best_note = "methods as given (--methods)"
    args.precise_reference = None
    if "methods" not in args.explicit and not args.quick:
        best, args.best_note = _best_sampler(args.best_sampler, args.out, files_list)
        if best is not None and best not in methods:
            methods.insert(methods.index("path") if "path" in methods else len(methods), best)
        chosen = parse_method(best) if best is not None else None
        if chosen is not None and "reference_method" not in args.explicit \
                and not chosen.deterministic:
            args.precise_reference = chosen
    args.methods = methods
    args.method_objs = [parse_method(m) for m in methods]
    fixed = [m.name for m in args.method_objs if m.deterministic]
    if fixed:
        build_parser().error(
            f"method '{fixed[0]}' is deterministic (the same image every run): the suite "
            f"judges every cell over independent repeats, and the bundled scenes include "
            f"unbounded depths where such a sampler's all-zero first sample never ends its "
            f"path; use a randomized sampler (e.g. {parse_method(fixed[0]).sampler}:owen)")
    if args.baseline.name not in methods:
        build_parser().error(f"--baseline '{args.baseline}' is not one of the methods "
                             f"({', '.join(methods)})")
    args.user_references = {}
    if args.references:
        try:
            args.user_references = references.user_references(args.references)
        except ValueError as e:
            build_parser().error(str(e))
    args.scene_files = files_list
    return args


def settings(args) -> declare.Settings:
    """The typed settings of a parsed command line (:func:`parse`)."""
    ref_spp = args.reference_spp
    return declare.Settings(
        out=args.out, variant=args.variant, seed=args.seed, repeats=args.repeats,
        executor=args.executor, info=args.info, depth=args.depth,
        scenes=tuple(args.scene_files), methods=tuple(args.method_objs),
        baseline=args.baseline, spp=args.spp, time_budget=args.time_budget,
        forced_resolution=tuple(args.resolution) if "resolution" in args.explicit else None,
        max_size=args.max_size, min_size=args.min_size, max_depth=args.max_depth, rr_depth=args.rr_depth,
        reference_spp=ref_spp, reference_max_spp=max(ref_spp, args.reference_max_spp or
                                                     REFERENCE_GROWTH * ref_spp),
        reference_typical_spp=REFERENCE_GROWTH * (args.reference_spp_default or ref_spp),
        reference_spp_default=args.reference_spp_default,
        reference_cache=args.reference_cache, replay_counts=args.replay_counts,
        reference_method=args.reference_method,
        reference_root=args.reference_cache or os.path.join(args.out, references.REFERENCES_DIR),
        user_references=dict(args.user_references), flip=args.flip, best_note=args.best_note,
        precise_reference=args.precise_reference,
        reference_max_seconds=0.0 if args.reference_max_spp or args.quick else
        REFERENCE_SECONDS)


# ------------------------------------------------------------------ the study

def run_suite(cfg: declare.Settings) -> dict:
    """Declare, render (the engine), measure, analyse and report the suite; returns
    summary.json's data."""
    timer = clock.Timer()
    engine = Engine(Study(cfg))
    refs = references.ReferenceStore(cfg.reference_root)
    plans = declare.plan_scenes(cfg)
    live = [sp for sp in plans if not sp.error]
    measured = None
    if live:
        timer.time("references", reference_choice.choose, engine.study, cfg, live, refs)
        own = {(sp.name, None): (lambda r: (r.image, r.meta()))(declare.reference_of(refs, sp))
               for sp in live if sp.user_ref is not None}
        measured = timer.time("renders", engine.run, declare.declaration(cfg, live), own)
        for sp in live:
            sp.error = (measured.scene_errors.get((sp.name, None)) or
                        measure.comparable(cfg, sp, measured.failed_on(sp.name)))
    guides = timer.time("guide figures", report.guide_blocks, cfg, plans, measured)
    compared = [sp for sp in plans if not sp.error]
    cells = sum(1 for sp in compared for m in cfg.methods
                if m.name not in sp.left_out and m.name not in measured.failed_on(sp.name))
    level = bias_test.cell_level(cells)
    with timer.part("analysis"):
        chunks = {sp.name: bias_test.reference_chunks(refs, sp.bias_ref) for sp in compared}
        tests = {sp.name: measure.bias_tests(cfg, sp, measured, chunks[sp.name], level)
                 for sp in compared}
    # a cell whose tails void its test, a flagged cell, and the A/A pair where its error is
    # unsure, render on, once (bias_renders); the pair's round joins its errors
    unsure = bias_renders.imprecise(cfg, compared, measured,
                                    lambda sp: declare.reference_of(refs, sp, True))
    void, flagged = bias_renders.void(tests), bias_renders.flagged(tests)
    more = timer.time("more renders", bias_renders.render, engine, cfg, compared, measured,
                      bias_renders.union(void, flagged, unsure))
    with timer.part("analysis"):
        for sp in [sp for sp in compared if sp.name in more]:
            tests[sp.name] = retested(cfg, sp, measured, chunks[sp.name], level,
                                      tests[sp.name], more[sp.name], void, flagged)
        outcomes = [outcome(cfg, sp, measured, refs, tests[sp.name],
                            bias_renders.only(more.get(sp.name, {}), unsure.get(sp.name, ())))
                    for sp in compared]
    allocations = timer.time("allocation figures", report.adaptive_blocks, cfg, compared,
                             measured, {o.plan.name: o.reference.image for o in outcomes})
    return report.write(cfg, engine.study, plans, outcomes, measured, timer, guides,
                        allocations)


def retested(cfg: declare.Settings, sp: declare.ScenePlan, measured, chunks, level: float,
             tests: dict, more: dict, void: dict, flagged: dict) -> dict:
    """One scene's bias ``tests`` after the round's renders ``more`` ({method: [Run]}): a
    void cell's test with them beside its own renders, a flagged cell's flag tested again
    on them alone (:func:`.bias_renders.confirmed`)."""
    if sp.name in void:
        tests = measure.bias_tests(cfg, sp, measured, chunks, level,
                                   bias_renders.only(more, void[sp.name]))
    fresh = bias_renders.only(more, flagged.get(sp.name, ()))
    if fresh:
        again = measure.bias_tests(cfg, sp, measured, chunks, level, fresh, alone=True)
        tests = {**tests, **{m: bias_renders.confirmed(tests[m], again[m])
                             for m in fresh if m in again}}
    return tests


def outcome(cfg: declare.Settings, sp: declare.ScenePlan, measured, refs,
            tests: dict, extra: dict | None = None) -> report.SceneOutcome:
    """One scene's numbers (FLIP, its cells' bias ``tests`` and the ``extra`` renders that
    join their errors included), analysis and viewer."""
    ref = declare.reference_of(refs, sp)
    numbers = measure.measure_scene(cfg, sp, measured, ref, True, tests, extra)
    result = analysis.analyse_scene(numbers)
    return report.SceneOutcome(sp, numbers, result, ref,
                               report.viewer_block(cfg, sp, measured, result, ref))


def run(args) -> None:
    run_suite(settings(args))


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run, parse=parse, quick=("--quick",), shared=add_shared,
    forwarded={"scenes": "--scenes", "references": "--references",
               "best_sampler": "--best-sampler", "preset": "--preset", "full": "--full"}))
