"""Sampler study: halton (each randomization) against Mitsuba's own samplers, by efficiency.

For the base method (default ``bsdf+nee``) with every sampler (independent,
stratified, multijitter, orthogonal, ldsampler, and halton with each
randomization), at max_depth 2 and 8 (or --max-depth), each sample count of
the ladder 1, 4, 16, ... --spp is a fresh render (so every sampler stratifies
the whole count; Mitsuba's samplers round some counts up, e.g. orthogonal
to a prime squared, and the rendered count is used). Measured: MSE and
relMSE against a high-spp reference, time per sample, Veach efficiency
1/(MSE x time) relative to ``independent``, fitted slope of MSE against spp;
a chart of error against time per sampler; the conclusion computed from the
numbers. Renders of one depth are interleaved (every sampler at one spp,
then the next spp) so that changing machine load affects them alike.

    python -m experiments.samplers --help
"""
from __future__ import annotations

import os
import time

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
ORDER = 10
DEPTHS = (2, 8)
#: Independent runs of every count of the ladder: samplers close in efficiency (halton's best
#: and the best native one are within about 10%) need more than the other studies' 3.
REPEATS = 4
CPU_TIME = ("the CPU time of the rendering process (all its threads), which load from other "
            "processes perturbs far less than wall-clock time")


def samplers() -> list[str]:
    """Every sampler of the study: each registered sampler with each of its randomizations
    (:func:`experiments.lib.samplers.labels`)."""
    return S.labels()


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
    # 7-12% low, halton's not), which biases the comparison. Its own expected error is
    # subtracted, so it need not be far below the samplers' errors.
    p.set_defaults(reference_spp=2048, reference_method="path")
    add_arguments(p)
    return p


def method(base: Method, sampler: str) -> Method:
    """``base`` driven by the sampler label ``sampler``."""
    return parse_method(_method_name(base, sampler))


def depths(args) -> list[int]:
    return [args.max_depth] if args.max_depth is not None else list(args.depths)


def plan(st: Study) -> tuple[dict, dict]:
    """(reference jobs per depth, {depth: {sampler: [repeat: [jobs of the ladder]]}})."""
    a = st.args
    targets = P.doubling_targets(a.spp, a.ladder_factor)
    refs, ladders = {}, {}
    for d in depths(a):
        depth = Depth(d, a.depth.rr_depth, a.depth.hide_emitters)
        refs[d] = st.reference_jobs(depth=depth)
        ladders[d] = {s: [[st.job(repeat_prefix(f"{NAME}/depth{d}/{s}/spp{t:05d}", r),
                                  method(a.base, s), t, depth=depth,
                                  timing_group=f"{NAME}/depth{d}") for t in targets]
                          for r in range(st.repeats_of(method(a.base, s)))]
                      for s in samplers()}
    return refs, ladders


def ordered(refs: dict, ladders: dict) -> list[J.Job]:
    """References first, then per depth and repeat every sampler at one spp before the
    next spp (so that drifting machine load affects every sampler alike)."""
    jobs = [j for r in refs.values() for j in r]
    for by_sampler in ladders.values():
        for r in range(max(len(reps) for reps in by_sampler.values())):
            for i in range(len(next(iter(by_sampler.values()))[0])):
                jobs += [reps[r][i] for reps in by_sampler.values() if r < len(reps)]
    return jobs


def timing(st: Study, result) -> float:
    """Render time compared: process CPU time on the CPU (LLVM) backend, where other
    processes sharing the machine perturb wall-clock time, else wall-clock time."""
    if st.variant.startswith("llvm") and result.cpu_seconds > 0:
        return result.cpu_seconds
    return result.seconds


def analyse(st: Study, refs: dict, ladders: dict) -> tuple[list[SS.Row], dict, dict]:
    """Rows, ``{depth: {sampler: [Point per count]}}`` and the references' metadata.

    Errors are expected values over the repeats with the reference's own expected
    error subtracted; plain Halton (``halton:none``) is deterministic, so its one run
    stands for every repeat (its error has no spread).
    """
    points, floors = {}, {}
    for d, by_sampler in ladders.items():
        ref, meta = st.reference(refs[d])
        floors[d] = meta
        points[d] = {}
        for s, reps in by_sampler.items():
            pts = []
            for i, target in enumerate(reps[0]):
                results = [st.store.get(rep[i].key) for rep in reps]
                images = [r.image.astype(float) for r in results]
                pts.append(SS.Point(
                    results[0].spp, st.per_repeat(timing(st, r) for r in results),
                    st.per_repeat(metrics.mse(im, ref) - meta["mse_floor"] for im in images),
                    st.per_repeat(metrics.relmse(im, ref) - meta["relmse_floor"]
                                  for im in images), target.spp))
            points[d][s] = pts
    return SS.table(points, st.width * st.height), points, floors


def comparison(st: Study, refs: dict, ladders: dict, d: int) -> dict:
    """Viewer block: every sampler's image at the largest count of the ladder, at max_depth d
    (the first repeat)."""
    ref, _ = st.reference(refs[d])
    images = [(s, st.store.get(reps[0][-1].key).image.astype(float))
              for s, reps in ladders[d].items()]
    return report.viewer(st.out, f"Samplers at max_depth {d}, {st.args.spp} spp", images, ref,
                         f"{st.args.base} with each sampler at max_depth {d} after the largest "
                         f"sample count (first repeat), against the reference.")


TABLE_HEADER = ["max_depth", "sampler", "spp rendered", "spp requested", "repeats",
                "MSE", "MSE_lo", "MSE_hi", "relMSE", "relMSE_lo", "relMSE_hi", "µs / sample",
                "MSE / independent", "MSE / independent_lo", "MSE / independent_hi",
                "efficiency / independent", "efficiency / independent_lo",
                "efficiency / independent_hi", "MSE slope"]


def table_rows(rows: list[SS.Row]) -> list[list]:
    return [[r.depth, r.sampler, r.spp, r.requested, r.repeats, *r.mse.cells(),
             *r.relmse.cells(), f"{r.us_per_sample:.3f}",
             *r.relative_mse.cells(), *r.relative_efficiency.cells(),
             f"{r.slope:.2f}"] for r in rows]


def curve_rows(curves: dict) -> list[list]:
    return [[d, s, i, spp, *e.cells()]
            for d, by_sampler in curves.items() for s, pts in by_sampler.items()
            for i, (spp, e) in enumerate(pts)]


def best_sampler(rows: list[SS.Row], depth: int) -> str:
    """The sampler of the highest efficiency at ``depth`` (the nearest depth studied)."""
    studied = sorted({r.depth for r in rows}, key=lambda d: (abs(d - depth), d))
    at = [r for r in rows if r.depth == studied[0]]
    return max(at, key=lambda r: r.relative_efficiency.value).sampler


def run(args) -> None:
    start = time.perf_counter()
    st = Study(args)
    refs, ladders = plan(st)
    st.run(ordered(refs, ladders), f"{NAME}: renders")
    rows, points, floors = analyse(st, refs, ladders)
    curves = SS.curves(points)
    sentences = SS.conclude(rows, points)
    targets = P.doubling_targets(args.spp, args.ladder_factor)
    blocks = [report.text(
        f"Which sampler to use with {args.base} on {os.path.basename(args.scene)} at "
        f"{st.width}x{st.height}: Mitsuba's independent, stratified, multijitter, orthogonal "
        f"and ldsampler against the bundled halton with each randomization, at max_depth "
        f"{', '.join(map(str, depths(args)))}. Every count of the ladder "
        f"{', '.join(map(str, targets))} spp is its own render, {st.repeats} times with "
        f"independent randomizations (plain halton:none is deterministic: one run); samplers "
        f"that round the count up (orthogonal to a prime squared, stratified to a square) "
        f"are compared at the count they rendered, which the table gives beside the "
        f"requested one. Errors are expected values over the repeats, with the reference's "
        f"own expected error subtracted. Efficiency is Veach's 1/(MSE x render time) "
        f"relative to independent: above 1, a sampler reaches a given error sooner. Render "
        f"time is {CPU_TIME if st.variant.startswith('llvm') else 'wall-clock time'}, warm "
        f"in exactly the timed configuration (a render during which a kernel compiled is "
        f"rendered again). Intervals: {stats.LEVEL:.0%}, {stats.METHOD}.")]
    for d in points:
        bands = {s: ([p.spp for p in pts], [sum(p.seconds) / len(p.seconds) for p in pts],
                     [stats.mean_interval(p.mse) for p in pts]) for s, pts in points[d].items()}
        figures.error_bands(os.path.join(args.out, NAME, f"error_depth{d}.png"), bands, "MSE")
        figures.ratio_bands(os.path.join(args.out, NAME, f"efficiency_depth{d}.png"),
                            curves[d], "efficiency / independent",
                            f"max_depth {d}: efficiency relative to independent")
        blocks.append(report.image(
            f"{NAME}/error_depth{d}.png", f"max_depth {d}: expected MSE against spp and "
            f"against render (CPU) time per sampler, with {stats.LEVEL:.0%} bands over the "
            f"repeats (log-log, fitted slopes in the legend); reference: "
            f"{st.describe_reference(floors[d])}."))
        blocks.append(report.image(
            f"{NAME}/efficiency_depth{d}.png", f"max_depth {d}: efficiency relative to "
            f"independent at every count of the ladder, with {stats.LEVEL:.0%} bands: where "
            f"the curves cross, the order of the samplers changes with the sample count."))
        blocks.append(comparison(st, refs, ladders, d))
    blocks += [
        report.write_table(args.out, f"{NAME}/samplers", TABLE_HEADER, table_rows(rows),
                           f"Samplers with {args.base} at the largest sample count "
                           f"(expected values over {st.repeats} runs, {stats.LEVEL:.0%} "
                           f"intervals as _lo/_hi)"),
        report.write_table(args.out, f"{NAME}/efficiency_ladder",
                           ["max_depth", "sampler", "ladder index", "spp rendered",
                            "efficiency / independent", "efficiency / independent_lo",
                            "efficiency / independent_hi"], curve_rows(curves),
                           "Efficiency relative to independent at every count of the ladder",
                           collapsed=True),
        report.text("Conclusion: " + " ".join(sentences))]
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "base method": str(args.base), "max_depth": ", ".join(map(str, depths(args))),
                "repeats": st.repeats, "path settings": args.depth.describe(),
                "variant": args.variant, "seed": args.seed,
                "reference": f"{args.reference_spp} spp of {args.reference_method}",
                "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
                "render times measured on": st.timed_on(ordered(refs, ladders))}
    report.write_section(args.out, NAME, "Samplers: halton against Mitsuba's own", ORDER,
                         settings, blocks, args.variant, time.perf_counter() - start)
    files.write_json(os.path.join(args.out, NAME, "summary.json"),
                     {"rows": [r.record() for r in rows], "conclusion": sentences,
                      "best": {d: best_sampler(rows, d) for d in points},
                      "halton_vs_best_native": {
                          d: {"halton": h, "native": n, **e.fields("efficiency_ratio")}
                          for d, (h, n, e) in SS.halton_vs_native(rows, points).items()},
                      "curves": {d: {s: [dict(spp=spp, **e.fields("relative_efficiency"))
                                         for spp, e in pts] for s, pts in by.items()}
                                 for d, by in curves.items()}})


STUDY = register_study(StudySpec(
    NAME, "Samplers: halton against Mitsuba's own", ORDER, build_parser, run,
    quick=("--resolution", "16x8", "--spp", "4", "--reference-spp", "16")))
