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

The study is a list of measurement passes (:data:`PASSES`), each plan -> measure -> pure
analysis -> report; a further pass (e.g. screen-space error at another resolution) is one
more entry.

    python -m experiments.samplers --help
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Protocol

from experiments.lib import jobs as J
from experiments.lib import files
from experiments.lib.studies import StudySpec, register_study
from experiments.lib import cli, figures, metrics, report, stats
from experiments.lib import plan as P
from experiments.lib import sampler_study as SS
from experiments.lib import samplers as S
from experiments.lib.methods import Depth, Method, parse_method
from experiments.lib.methods import method_name as _method_name
from experiments.lib.study import Study, repeat_prefix

NAME = "samplers"
TITLE = "Samplers: the bundled samplers against Mitsuba's own"
ORDER = 10
DEPTHS = (2, 8)
#: Independent runs of every count of the ladder: samplers close in efficiency (the best
#: bundled and the best native one can be within about 10%) need more than the other
#: studies' 3.
REPEATS = 4
CPU_TIME = ("the CPU time of the rendering process (all its threads), which load from other "
            "processes perturbs far less than wall-clock time")


# ------------------------------------------------------------------ settings

def base_method(text: str) -> Method:
    m = cli.one_method(text)
    if "+" in m.name.replace("+nee", ""):
        raise cli.argparse.ArgumentTypeError(
            f"invalid base method '{text}': give it without a sampler (e.g. bsdf+nee or path); "
            f"the study adds every sampler")
    return m


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
    p.add_argument("--base", type=base_method, default="bsdf+nee",
                   help="method the samplers drive (STRATEGY[+nee] or path)")
    p.add_argument("--depths", type=depth_list, default=",".join(map(str, DEPTHS)),
                   help="max_depth values of the study (--max-depth replaces them by one)")
    p.add_argument("--ladder-factor", type=cli.positive_int, default=4,
                   help="ratio of consecutive sample counts of the ladder")


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.samplers", __doc__.split("\n")[0], spp=256,
                          default_resolution="64x32", methods=("bsdf+nee",), repeats=REPEATS)
    # The reference uses the independent sampler: a QMC reference shares structure with the
    # QMC renders it judges (ldsampler against a path+ldsampler reference: its MSE came out
    # 7-12% low), which biases the comparison. Its own expected error is subtracted, so it
    # need not be far below the samplers' errors.
    p.set_defaults(reference_spp=2048, reference_method="path")
    add_arguments(p)
    return p


@dataclass(frozen=True)
class Settings:
    """What one run of the study measures (typed; the Namespace stays in :func:`run`)."""
    base: Method                  # the method every sampler drives
    depths: tuple                 # max_depth values
    targets: tuple                # the ladder's requested counts
    samplers: tuple               # sampler labels, from the sampler table
    depth: Depth                  # the scene's path settings (max_depth set per depth)
    scene: str
    resolution: tuple             # (width, height)

    def at(self, max_depth: int) -> Depth:
        return Depth(max_depth, self.depth.rr_depth, self.depth.hide_emitters)


def settings_of(args) -> Settings:
    depths = [args.max_depth] if args.max_depth is not None else list(args.depths)
    return Settings(args.base, tuple(depths),
                    tuple(P.doubling_targets(args.spp, args.ladder_factor)),
                    tuple(S.labels()), args.depth, args.scene, tuple(args.resolution))


def method(base: Method, sampler: str) -> Method:
    """``base`` driven by the sampler label ``sampler``."""
    return parse_method(_method_name(base, sampler))


def timing(st: Study, result) -> float:
    """Render time compared: process CPU time on the CPU (LLVM) backend, where other
    processes sharing the machine perturb wall-clock time, else wall-clock time."""
    if st.variant.startswith("llvm") and result.cpu_seconds > 0:
        return result.cpu_seconds
    return result.seconds


# ------------------------------------------------------------------ passes

@dataclass
class PassReport:
    blocks: list                  # report blocks, in order
    summary: dict                 # entries of summary.json
    jobs: list                    # the timed jobs (for "render times measured on")


class Pass(Protocol):
    """One measurement pass: plan -> measure -> analyse (pure) -> report."""
    name: str

    def plan(self, st: Study, cfg: Settings): ...

    def jobs(self, planned) -> list[J.Job]: ...

    def measure(self, st: Study, cfg: Settings, planned): ...

    def analyse(self, measured): ...

    def report(self, st: Study, cfg: Settings, planned, measured, result) -> PassReport: ...


@dataclass(frozen=True)
class LadderPlan:
    refs: dict                    # {depth: reference jobs}
    ladders: dict                 # {depth: {label: [repeat: [jobs of the ladder]]}}


@dataclass(frozen=True)
class Measured:
    points: dict                  # {depth: {label: [SS.Point per count]}}
    floors: dict                  # {depth: the reference's metadata}
    pixels: int
    kinds: dict                   # {label: SS.Family}


def _interval(name: str) -> list[str]:
    return [name, f"{name}_lo", f"{name}_hi"]


#: The error every efficiency (and so every verdict) uses, as the tables name it.
EFFICIENCY = f"efficiency 1/({SS.METRIC_NAMES[SS.METRIC]} x time) / {SS.BASELINE}"
TABLE_HEADER = (["max_depth", "sampler", "spp rendered", "spp requested", "repeats"]
                + _interval("MSE") + _interval("relMSE") + ["µs / sample"]
                + _interval(f"MSE / {SS.BASELINE}") + _interval(f"relMSE / {SS.BASELINE}")
                + _interval(EFFICIENCY) + ["MSE slope"])


def table_rows(rows: list[SS.Row]) -> list[list]:
    """Errors below the reference's own noise are bounds: their cells read '< x'."""
    def cells(e):
        return [f"< {stats.g(e.hi)}", "0", stats.g(e.hi)] if e.bound else e.cells()
    return [[r.depth, r.sampler, r.spp, r.requested, r.repeats, *cells(r.mse),
             *cells(r.relmse), f"{r.us_per_sample:.3f}", *cells(r.relative_mse),
             *cells(r.relative_relmse), *r.relative_efficiency.cells(),
             f"{r.slope:.2f}"] for r in rows]


def curve_rows(curves: dict) -> list[list]:
    return [[d, s, i, spp, *e.cells()]
            for d, by_sampler in curves.items() for s, pts in by_sampler.items()
            for i, (spp, e) in enumerate(pts)]


class Efficiency:
    """Errors and render times of every label over the ladder, at every depth."""
    name = "efficiency"

    def plan(self, st: Study, cfg: Settings) -> LadderPlan:
        refs, ladders = {}, {}
        for d in cfg.depths:
            depth = cfg.at(d)
            refs[d] = st.reference_jobs(depth=depth)
            ladders[d] = {s: [[st.job(repeat_prefix(f"{NAME}/depth{d}/{s}/spp{t:05d}", r),
                                      method(cfg.base, s), t, depth=depth,
                                      timing_group=f"{NAME}/depth{d}") for t in cfg.targets]
                              for r in range(st.repeats_of(method(cfg.base, s)))]
                          for s in cfg.samplers}
        return LadderPlan(refs, ladders)

    def jobs(self, planned: LadderPlan) -> list[J.Job]:
        """References first, then per depth and repeat every label at one spp before the
        next spp (so that drifting machine load affects every sampler alike)."""
        jobs = [j for r in planned.refs.values() for j in r]
        for by_sampler in planned.ladders.values():
            for r in range(max(len(reps) for reps in by_sampler.values())):
                for i in range(len(next(iter(by_sampler.values()))[0])):
                    jobs += [reps[r][i] for reps in by_sampler.values() if r < len(reps)]
        return jobs

    def measure(self, st: Study, cfg: Settings, planned: LadderPlan) -> Measured:
        """Per-repeat times and errors against each depth's reference; a deterministic
        label's one run stands for every repeat (:meth:`Study.per_repeat`)."""
        points, floors = {}, {}
        for d, by_sampler in planned.ladders.items():
            ref, meta = st.reference(planned.refs[d])
            floors[d] = meta
            points[d] = {}
            for s, reps in by_sampler.items():
                pts = []
                for i, target in enumerate(reps[0]):
                    results = [st.store.get(rep[i].key) for rep in reps]
                    images = [r.image.astype(float) for r in results]
                    pts.append(SS.Point(
                        results[0].spp, st.per_repeat(timing(st, r) for r in results),
                        st.per_repeat(metrics.mse(im, ref) for im in images),
                        st.per_repeat(metrics.relmse(im, ref) for im in images), target.spp,
                        meta["mse_floor"], meta["relmse_floor"]))
                points[d][s] = pts
        return Measured(points, floors, st.width * st.height, SS.families(cfg.samplers))

    def analyse(self, measured: Measured) -> SS.Analysis:
        return SS.analyse(measured.points, measured.pixels, measured.kinds)

    def report(self, st: Study, cfg: Settings, planned: LadderPlan, measured: Measured,
               result: SS.Analysis) -> PassReport:
        out, blocks, metric = st.out, [], SS.METRIC_NAMES[SS.METRIC]
        for d, by_sampler in measured.points.items():
            bands = {s: ([p.spp for p in pts], [sum(p.seconds) / len(p.seconds) for p in pts],
                         [p.expected(SS.METRIC) for p in pts])
                     for s, pts in by_sampler.items()}
            figures.error_bands(os.path.join(out, NAME, f"error_depth{d}.png"), bands, metric)
            blocks.append(report.image(
                f"{NAME}/error_depth{d}.png", f"max_depth {d}: expected {metric} against "
                f"spp and against render (CPU) time per sampler, with {stats.LEVEL:.0%} "
                f"bands over the repeats (log-log, fitted slopes in the legend); "
                f"reference: {st.describe_reference(measured.floors[d])}."))
            if any(math.isfinite(e.value) for pts in result.curves[d].values() for _, e in pts):
                figures.ratio_bands(os.path.join(out, NAME, f"efficiency_depth{d}.png"),
                                    result.curves[d], EFFICIENCY,
                                    f"max_depth {d}: efficiency relative to {SS.BASELINE}")
                blocks.append(report.image(
                    f"{NAME}/efficiency_depth{d}.png", f"max_depth {d}: {EFFICIENCY} at "
                    f"every count of the ladder, with {stats.LEVEL:.0%} bands: where the "
                    f"curves cross, the order of the samplers changes with the sample "
                    f"count."))
            else:
                blocks.append(report.text(
                    f"max_depth {d}: no efficiency relative to {SS.BASELINE} is known at "
                    f"this budget (at every count an error is below the reference's own "
                    f"noise, only a bound), so no chart of them is drawn; a better reference "
                    f"(--reference-spp) or more repeats cure it."))
            blocks.append(comparison_viewer(st, cfg, planned, d))
        blocks += [
            report.write_table(out, f"{NAME}/samplers", TABLE_HEADER, table_rows(result.rows),
                               f"Samplers with {cfg.base} at the largest sample count "
                               f"(expected values over {st.repeats} runs with the "
                               f"reference's own expected error subtracted, '< x' where an "
                               f"error is below the reference's noise; {stats.LEVEL:.0%} "
                               f"intervals as _lo/_hi; the efficiency uses {metric})"),
            report.write_table(out, f"{NAME}/efficiency_ladder",
                               ["max_depth", "sampler", "ladder index", "spp rendered"]
                               + _interval(EFFICIENCY), curve_rows(result.curves),
                               f"{EFFICIENCY} at every count of the ladder", collapsed=True)]
        for d in measured.points:
            mine = [c for c in result.comparisons if c.depth == d]
            blocks += [report.write_table(
                out, f"{NAME}/conclusion_depth{d}", SS.COMPARISON_HEADER,
                [c.cells() for c in mine],
                f"Conclusion at max_depth {d}: efficiency 1/({metric} x time) of A over B at "
                f"the largest count, its {stats.LEVEL:.0%} interval, "
                f"the verdict (only where the interval excludes 1) and the counts where the "
                f"order changes along the ladder"),
                report.text("\n\n".join(result.conclusions[d]))]
        summary = {
            "rows": [r.record() for r in result.rows],
            "conclusion": {d: s for d, s in result.conclusions.items()},
            "comparisons": [c.record() for c in result.comparisons],
            "best": {d: r.sampler for d, r in result.best.items()},
            "best_at": {d: {"sampler": r.sampler, "spp": r.spp, "requested_spp": r.requested}
                        for d, r in result.best.items()},
            "curves": {d: {s: [dict(spp=spp, **e.fields("relative_efficiency"))
                               for spp, e in pts] for s, pts in by.items()}
                       for d, by in result.curves.items()}}
        return PassReport(blocks, summary, self.jobs(planned))


def comparison_viewer(st: Study, cfg: Settings, planned: LadderPlan, d: int) -> dict:
    """Viewer block: every label's image at the largest count of the ladder, at max_depth d
    (the first repeat)."""
    ref, _ = st.reference(planned.refs[d])
    images = [(s, st.store.get(reps[0][-1].key).image.astype(float))
              for s, reps in planned.ladders[d].items()]
    return report.viewer(st.out, f"Samplers at max_depth {d}, {cfg.targets[-1]} spp", images,
                         ref, f"{cfg.base} with each sampler at max_depth {d} after the "
                         f"largest sample count (first repeat), against the reference.")


#: The measurement passes, in order (rendered together, then measured and reported).
PASSES: tuple = (Efficiency(),)


# ------------------------------------------------------------------ the study

def introduction(st: Study, cfg: Settings) -> str:
    """What the study compares, from the sampler table (no sampler named by hand), in
    paragraphs of at most 80 words."""
    natives = [s for s in cfg.samplers if S.split_label(s)[0].native]
    bundled = [s for s in cfg.samplers if s not in natives]
    fixed = [s for s in cfg.samplers if S.split_label(s)[0].is_deterministic(
        S.split_label(s)[1])]
    time_is = CPU_TIME if st.variant.startswith("llvm") else "wall-clock time"
    metric = SS.METRIC_NAMES[SS.METRIC]
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
        f"{SS.BASELINE}: above 1, a sampler reaches a given error sooner. Every verdict "
        f"uses {metric} as the error (the tables give MSE too). Intervals: "
        f"{stats.LEVEL:.0%}, {stats.METHOD}.",
        f"Render time is {time_is}, warm in exactly the timed configuration (a render "
        f"during which a kernel compiled is rendered again)."])


def run(args) -> None:
    start = time.perf_counter()
    st, cfg = Study(args), settings_of(args)
    planned = [p.plan(st, cfg) for p in PASSES]
    st.run([j for p, pl in zip(PASSES, planned) for j in p.jobs(pl)], f"{NAME}: renders")
    blocks, summary, timed = [report.text(introduction(st, cfg))], {}, []
    for p, pl in zip(PASSES, planned):
        measured = p.measure(st, cfg, pl)
        reported = p.report(st, cfg, pl, measured, p.analyse(measured))
        blocks += reported.blocks
        summary.update(reported.summary)
        timed += reported.jobs
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "base method": str(cfg.base), "max_depth": ", ".join(map(str, cfg.depths)),
                "repeats": st.repeats, "path settings": args.depth.describe(),
                "variant": args.variant, "seed": args.seed,
                "reference": f"{args.reference_spp} spp of {args.reference_method}",
                "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
                "verdicts": f"efficiency 1/({SS.METRIC_NAMES[SS.METRIC]} x time)",
                "render times measured on": st.timed_on(timed)}
    report.write_section(args.out, NAME, TITLE, ORDER, settings, blocks, args.variant,
                         time.perf_counter() - start)
    files.write_json(os.path.join(args.out, NAME, "summary.json"), summary)


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run,
    quick=("--resolution", "16x8", "--spp", "4", "--reference-spp", "16")))
