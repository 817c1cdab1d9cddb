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

The screen-space pass (:class:`ScreenSpace`, options --screen-*) renders a short ladder
(1, 4, 16 spp) on a larger image (128x128; a spectrum needs it) at max_depth 2, for a
subset of labels by default (the baseline, multijitter, ldsampler and each bundled sampler
at its last randomization: every FLIP of a 128x128 image costs a few tenths of a CPU
second; --screen-samplers all for every label). Per count: mean FLIP against the
reference, the radially averaged power spectrum of the error image and its low-frequency
share (:mod:`experiments.lib.screen_space`: power below a quarter of Nyquist over the
total, the reference's own white noise subtracted), and MSE efficiency; a conclusion table
per depth (each bundled sampler's best against every native one and the other bundled
ones, per count) and three sentences computed from it.

The study is a list of measurement passes (:data:`PASSES`), each plan -> measure -> pure
analysis -> report.

    python -m experiments.samplers --help
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from experiments.lib import execute as E
from experiments.lib import jobs as J
from experiments.lib import files
from experiments.lib.studies import StudySpec, register_study
from experiments.lib import cli, clock, figures, metrics, report, stats
from experiments.lib import plan as P
from experiments.lib import sampler_study as SS
from experiments.lib import samplers as S
from experiments.lib import screen_space as SP
from experiments.lib.methods import Depth, Method, parse_method
from experiments.lib.methods import method_name as _method_name
from experiments.lib.study import Study, repeat_prefix

NAME = "samplers"
TITLE = "Samplers: the bundled samplers against Mitsuba's own"
ORDER = 10
#: One short depth by default (make run's time budget); --depths 2,8 adds a long one.
DEPTHS = (2,)
#: The method every sampler drives, by default.
BASE = "bsdf+nee"
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


#: The screen-space pass's defaults: small enough for ``make run`` (every FLIP of a
#: 128x128 image costs a few tenths of a CPU second, each native sampler compiles a kernel
#: per count); larger settings through the --screen-* options.
SCREEN_RESOLUTION = "128x128"
SCREEN_COUNTS = (1, 4, 16)
SCREEN_DEPTHS = (2,)
SCREEN_REPEATS = 2
SCREEN_REFERENCE_SPP = 512
#: Native samplers of the default pass besides the baseline: the two with the lowest FLIP
#: in the zsobol sampler's calibration (issue 25); --screen-samplers all adds the others.
SCREEN_NATIVES = ("multijitter", "ldsampler")


def default_screen_labels() -> list[str]:
    """The default pass's labels, from the sampler table: the baseline, the natives of
    :data:`SCREEN_NATIVES`, and every sampler that is not native (bundled, or a
    ``--plugin`` file's) at its last randomization (the table lists them weakest first)."""
    out = [S.DEFAULT] + [n for n in SCREEN_NATIVES if n in S.names()]
    out += [S.get(n).labels()[-1] for n in S.names() if not S.get(n).native]
    return list(dict.fromkeys(out))


def screen_samplers(text: str) -> tuple:
    """--screen-samplers: 'default', 'all' or labels of the sampler table (checked)."""
    if text in ("default", "all"):
        return tuple(default_screen_labels() if text == "default" else S.labels())
    labels = [x.strip() for x in text.split(",") if x.strip()]
    for label in labels:
        try:
            S.split_label(label)
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


@dataclass(frozen=True)
class ScreenSettings:
    """What the screen-space pass measures."""
    resolution: tuple             # (width, height)
    counts: tuple                 # sample counts, each a fresh render
    depths: tuple                 # max_depth values
    samplers: tuple               # sampler labels
    repeats: int                  # independent randomizations (1 for a deterministic label)
    reference_spp: int
    reference: Method             # the reference's method (independent sampler)


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
    screen: ScreenSettings | None = None     # None: no screen-space pass

    def at(self, max_depth: int) -> Depth:
        return Depth(max_depth, self.depth.rr_depth, self.depth.hide_emitters)


def settings_of(args) -> Settings:
    one = [args.max_depth] if args.max_depth is not None else None
    screen = None if args.screen_space == "off" else ScreenSettings(
        tuple(args.screen_resolution), tuple(args.screen_counts),
        tuple(one or args.screen_depths), tuple(args.screen_samplers), args.screen_repeats,
        args.screen_reference_spp, args.reference_method)
    return Settings(args.base, tuple(one or args.depths),
                    tuple(P.doubling_targets(args.spp, args.ladder_factor)),
                    tuple(S.labels()), args.depth, args.scene, tuple(args.resolution),
                    screen)


def method(base: Method, sampler: str) -> Method:
    """``base`` driven by the sampler label ``sampler``."""
    return parse_method(_method_name(base, sampler))


def ladder_job(st: Study, cfg: Settings, root: str, d: int, label: str, count: int,
               repeat: int, resolution: tuple, group: str) -> J.Job:
    """Repeat ``repeat`` of ``label`` at ``count`` spp and max_depth ``d``, a fresh render,
    named ``root/label/sppNNNNN[/rR]`` (its seed derives from the name)."""
    return st.job(repeat_prefix(f"{root}/{label}/spp{count:05d}", repeat),
                  method(cfg.base, label), count, depth=cfg.at(d), resolution=resolution,
                  timing_group=group)


def timing(st: Study, result) -> float:
    """Render time compared: the one clock (:func:`.clock.cost`)."""
    return clock.cost(result)


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
            ladders[d] = {s: [[ladder_job(st, cfg, f"{NAME}/depth{d}", d, s, t, r,
                                          (st.width, st.height), f"{NAME}/depth{d}")
                               for t in cfg.targets]
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
                for target, results, images in rungs(st, reps):
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


# ------------------------------------------------------------------ screen space

@dataclass(frozen=True)
class ScreenPlan:
    refs: dict                    # {depth: reference jobs at the pass's resolution}
    ladders: dict                 # {depth: {label: [repeat: [job per count]]}}


@dataclass(frozen=True)
class ScreenMeasured:
    points: dict                  # {depth: {label: [SS.ScreenPoint per count]}}
    floors: dict                  # {depth: the reference's metadata, spectrum floor included}
    pixels: int
    kinds: dict                   # {label: SS.Family}
    white: float                  # the low-frequency share of white noise on the grid


def rungs(st: Study, reps: list):
    """Per rung of a label's ladders (``reps``: one ladder per repeat): its job in the first
    repeat, the stored results of every repeat and their images (float64)."""
    for i, target in enumerate(reps[0]):
        results = [st.store.get(rep[i].key) for rep in reps]
        yield target, results, [r.image.astype(float) for r in results]


def screen_reference_jobs(st: Study, sc: ScreenSettings, depth: Depth) -> list[J.Job]:
    """The pass's reference: ``sc.reference_spp`` of ``sc.reference`` at its resolution."""
    return st.reference_jobs(st.info, depth, resolution=sc.resolution, spp=sc.reference_spp,
                             method=sc.reference, typical_spp=SCREEN_REFERENCE_SPP)


def screen_ladders(st: Study, cfg: Settings, sc: ScreenSettings, d: int, labels,
                   counts, repeats: int) -> dict:
    """``{label: [repeat: [job per count]]}`` (one repeat for a deterministic label), named
    by the pass's resolution (``samplers/screen-128x128-depth2/...``), so that the lab,
    planning the same jobs, finds them in the store."""
    root = "{}/screen-{}x{}-depth{}".format(NAME, *sc.resolution, d)
    return {s: [[ladder_job(st, cfg, root, d, s, t, r, sc.resolution, f"{NAME}/screen/depth{d}")
                 for t in counts]
                for r in range(1 if method(cfg.base, s).deterministic else repeats)]
            for s in labels}


def screen_floor(st: Study, refs: list[J.Job]) -> float:
    """The white power the reference's own noise adds to an error spectrum
    (:func:`.screen_space.reference_floor` of its chunks)."""
    chunks = st.results(refs)
    return SP.reference_floor([r.image for r in chunks], [r.spp for r in chunks])


def _replicate(values, n: int) -> tuple:
    """A deterministic label's one value stands for every repeat."""
    values = tuple(values)
    return values * n if len(values) == 1 else values


class ScreenSpace:
    """FLIP, the error's power spectrum and MSE efficiency on a larger image
    (:class:`ScreenSettings`), at every count of a short ladder."""
    name = "screen"

    def plan(self, st: Study, cfg: Settings) -> ScreenPlan | None:
        sc = cfg.screen
        if sc is None:
            return None
        return ScreenPlan({d: screen_reference_jobs(st, sc, cfg.at(d)) for d in sc.depths},
                          {d: screen_ladders(st, cfg, sc, d, sc.samplers, sc.counts,
                                             sc.repeats) for d in sc.depths})

    def jobs(self, planned: ScreenPlan | None) -> list[J.Job]:
        """References first; then per depth, in groups of labels no larger than the methods
        a process keeps warm (:data:`.execute.VIEW_CACHE`), per repeat every label of
        the group at one count before the next count."""
        if planned is None:
            return []
        jobs = [j for r in planned.refs.values() for j in r]
        for by_sampler in planned.ladders.values():
            labels = list(by_sampler)
            for g in range(0, len(labels), E.VIEW_CACHE):
                group = {s: by_sampler[s] for s in labels[g:g + E.VIEW_CACHE]}
                for r in range(max(len(reps) for reps in group.values())):
                    for i in range(len(next(iter(group.values()))[0])):
                        jobs += [reps[r][i] for reps in group.values() if r < len(reps)]
        return jobs

    def measure(self, st: Study, cfg: Settings, planned: ScreenPlan) -> ScreenMeasured:
        """Per repeat: FLIP, the error's periodogram (its low-frequency share, the
        reference's floor subtracted), MSE, relMSE and render time; spectra averaged over
        the repeats."""
        sc = cfg.screen
        points, floors = {}, {}
        for d, by_sampler in planned.ladders.items():
            ref, meta = st.reference(planned.refs[d])
            floor = screen_floor(st, planned.refs[d])
            floors[d] = dict(meta, spectrum_floor=floor)
            points[d] = {}
            for s, reps in by_sampler.items():
                pts = []
                for target, results, images in rungs(st, reps):
                    powers = [SP.periodogram(SP.error_field(im, ref)) for im in images]
                    freqs, power = SP.spectrum(SP.normalized(np.mean(powers, axis=0), floor))
                    error = SS.Point(
                        results[0].spp, _replicate((timing(st, r) for r in results), sc.repeats),
                        _replicate((metrics.mse(im, ref) for im in images), sc.repeats),
                        _replicate((metrics.relmse(im, ref) for im in images), sc.repeats),
                        target.spp, meta["mse_floor"], meta["relmse_floor"])
                    pts.append(SS.ScreenPoint(
                        results[0].spp,
                        _replicate((metrics.flip_mean(im, ref) for im in images), sc.repeats),
                        _replicate((SP.low_share(p, floor) for p in powers), sc.repeats),
                        error, tuple(float(f) for f in freqs), tuple(float(v) for v in power),
                        target.spp))
                points[d][s] = pts
        width, height = sc.resolution
        return ScreenMeasured(points, floors, width * height, SS.families(sc.samplers),
                              SP.white_share((height, width)))

    def analyse(self, measured: ScreenMeasured) -> SS.ScreenAnalysis:
        return SS.analyse_screen(measured.points, measured.pixels, measured.kinds,
                                 measured.white)

    def report(self, st: Study, cfg: Settings, planned: ScreenPlan, measured: ScreenMeasured,
               result: SS.ScreenAnalysis) -> PassReport:
        sc, out = cfg.screen, st.out
        width, height = sc.resolution
        blocks = [report.text(screen_introduction(cfg, measured))]
        for d, by_sampler in measured.points.items():
            curves = {s: [(p.spp, p.mean_flip()) for p in pts] for s, pts in by_sampler.items()}
            figures.estimate_lines(os.path.join(out, NAME, f"screen_flip_depth{d}.png"),
                                   curves, "samples per pixel (rendered)", "mean FLIP",
                                   f"max_depth {d}, {width}x{height}: mean FLIP against the "
                                   f"reference")
            shown = spectrum_counts(sc.counts)
            panels = {f"{n} spp requested": {s: (pts[sc.counts.index(n)].frequencies,
                                                 pts[sc.counts.index(n)].power)
                                             for s, pts in by_sampler.items()} for n in shown}
            figures.spectrum_panels(os.path.join(out, NAME, f"screen_spectra_depth{d}.png"),
                                    panels, SP.LOW, f"max_depth {d}: radially averaged power "
                                    f"spectrum of the luminance error, mean over the repeats")
            blocks += [
                report.image(f"{NAME}/screen_flip_depth{d}.png",
                             f"max_depth {d}: mean FLIP against spp per sampler at "
                             f"{width}x{height}, with {stats.LEVEL:.0%} bands over the "
                             f"repeats (lower is better); reference: "
                             f"{st.describe_reference(measured.floors[d])}."),
                report.image(f"{NAME}/screen_spectra_depth{d}.png",
                             f"max_depth {d}: power spectrum of the error (render minus "
                             f"reference, luminance, mean subtracted; the reference's white "
                             f"noise subtracted), relative to its mean (white noise: 1), at "
                             f"{' and '.join(map(str, shown))} spp. Dashed: "
                             f"{SP.LOW} cycles per pixel, below which the low-frequency share "
                             f"is taken."),
                report.write_table(out, f"{NAME}/screen_conclusion_depth{d}",
                                   SS.SCREEN_HEADER,
                                   [c.cells() for c in result.comparisons if c.depth == d],
                                   f"Screen-space conclusion at max_depth {d}: each bundled "
                                   f"sampler's best (lowest FLIP) against every native "
                                   f"sampler and the other bundled ones, at every count; "
                                   f"ratios A / B with {stats.LEVEL:.0%} intervals; a verdict "
                                   f"only where the interval excludes 1, in FLIP only "
                                   f"between equal counts rendered"),
                report.text("\n\n".join(result.conclusions[d]))]
        header = (["max_depth", "sampler", "spp rendered", "spp requested", "repeats"]
                  + _interval("mean FLIP") + _interval("low-frequency share")
                  + _interval("MSE") + ["µs / sample"])
        blocks += [
            report.write_table(out, f"{NAME}/screen_space", header, screen_table_rows(
                result.rows), f"Every sampler and count of the screen-space pass at "
                f"{width}x{height} (means over the repeats, {stats.LEVEL:.0%} intervals; "
                f"low-frequency share of white noise on this grid: {result.white:.4f})"),
            report.write_table(out, f"{NAME}/screen_spectra",
                               ["max_depth", "sampler", "spp rendered", "frequency (cycles "
                                "per pixel)", "power / mean"],
                               [[d, s, p.spp, f"{f:.5g}", f"{v:.4g}"]
                                for d, by in measured.points.items() for s, pts in by.items()
                                for p in pts for f, v in zip(p.frequencies, p.power)],
                               "Radially averaged error spectra (white noise: 1)",
                               collapsed=True)]
        summary = {"screen": {
            "resolution": f"{width}x{height}", "counts": list(sc.counts),
            "depths": list(sc.depths), "samplers": list(sc.samplers),
            "repeats": sc.repeats, "reference_spp": sc.reference_spp,
            "white_share": result.white, "low_frequency_cutoff": SP.LOW,
            "spectrum_floor": {d: f["spectrum_floor"] for d, f in measured.floors.items()},
            "rows": [r.record() for r in result.rows],
            "comparisons": [c.record() for c in result.comparisons],
            "conclusion": result.conclusions}}
        return PassReport(blocks, summary, self.jobs(planned)[sum(
            len(r) for r in planned.refs.values()):])


def spectrum_counts(counts) -> list[int]:
    """The counts whose spectra are drawn: 4 and 16 where rendered, else the last two."""
    shown = [n for n in (4, 16) if n in counts]
    return shown or list(counts[-2:])


def screen_table_rows(rows: list[SS.ScreenRow]) -> list[list]:
    def cells(e):
        return [f"< {stats.g(e.hi)}", "0", stats.g(e.hi)] if e.bound else e.cells()
    return [[r.depth, r.sampler, r.spp, r.requested, r.repeats, *r.flip.cells(),
             *r.share.cells(), *cells(r.mse), f"{r.us_per_sample:.3f}"] for r in rows]


def screen_introduction(cfg: Settings, m: ScreenMeasured) -> str:
    """Two paragraphs of at most 80 words: what the pass renders, what it measures."""
    sc = cfg.screen
    width, height = sc.resolution
    subset = (" (the default subset: the baseline, the native samplers with the lowest FLIP "
              "in the zsobol calibration, each other sampler's last randomization; FLIP "
              "at this size is costly)" if sc.samplers == tuple(default_screen_labels())
              else "")
    return (f"Screen-space pass: {', '.join(sc.samplers)}{subset} at {width}x{height}, "
            f"max_depth {', '.join(map(str, sc.depths))}, {', '.join(map(str, sc.counts))} "
            f"spp, {sc.repeats} repeats, against {sc.reference_spp} spp of {sc.reference}."
            f"\n\nPer count: mean FLIP, the low-frequency share of the error's power (below "
            f"{SP.LOW} cycles per pixel; white noise {m.white:.3f}) with the reference's own "
            f"white noise subtracted, and MSE efficiency. FLIP is not corrected for the "
            f"reference's noise, which pulls every FLIP ratio towards 1.")


#: The measurement passes, in order (rendered together, then measured and reported).
PASSES: tuple = (Efficiency(), ScreenSpace())


# ------------------------------------------------------------------ the study

def introduction(st: Study, cfg: Settings) -> str:
    """What the study compares, from the sampler table (no sampler named by hand), in
    paragraphs of at most 80 words."""
    natives = [s for s in cfg.samplers if S.split_label(s)[0].native]
    bundled = [s for s in cfg.samplers if s not in natives]
    fixed = [s for s in cfg.samplers if S.split_label(s)[0].is_deterministic(
        S.split_label(s)[1])]
    time_is = clock.DESCRIPTION
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


def screen_settings_text(sc: ScreenSettings | None) -> str:
    if sc is None:
        return "off"
    return (f"{sc.resolution[0]}x{sc.resolution[1]}, max_depth "
            f"{', '.join(map(str, sc.depths))}, {', '.join(map(str, sc.counts))} spp, "
            f"{sc.repeats} repeats, reference {sc.reference_spp} spp of {sc.reference}; "
            f"samplers {', '.join(sc.samplers)}; verdicts by mean FLIP, low-frequency share "
            f"and efficiency 1/(MSE x time)")


def run(args) -> None:
    start = time.perf_counter()
    st, cfg = Study(args), settings_of(args)
    planned = [(p, p.plan(st, cfg)) for p in PASSES]
    planned = [(p, pl) for p, pl in planned if pl is not None]      # passes switched off
    st.run([j for p, pl in planned for j in p.jobs(pl)], f"{NAME}: renders")
    blocks, summary, timed = [report.text(introduction(st, cfg))], {}, []
    for p, pl in planned:
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
                "screen-space pass": screen_settings_text(cfg.screen),
                "render times measured on": st.timed_on(timed)}
    report.write_section(args.out, NAME, TITLE, ORDER, settings, blocks, args.variant,
                         time.perf_counter() - start)
    files.write_json(os.path.join(args.out, NAME, "summary.json"), summary)


STUDY = register_study(StudySpec(
    NAME, TITLE, ORDER, build_parser, run,
    quick=("--resolution", "16x8", "--spp", "4", "--reference-spp", "16",
           "--screen-resolution", "16x8", "--screen-counts", "1,4", "--screen-repeats", "2",
           "--screen-reference-spp", "16")))
