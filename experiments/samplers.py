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

from experiments.lib import cli, figures, metrics, report
from experiments.lib import plan as P
from experiments.lib import sampler_study as SS
from experiments.lib.methods import NATIVE_SAMPLERS, RANDOMIZATIONS, Depth
from experiments.lib.study import Study

NAME = "samplers"
ORDER = 30
DEPTHS = (2, 8)
CPU_TIME = ("the CPU time of the rendering process (all its threads), which load from other "
            "processes perturbs far less than wall-clock time")


def samplers() -> list[str]:
    """Every sampler of the study: Mitsuba's, then halton with each randomization."""
    return list(NATIVE_SAMPLERS) + [f"halton:{r}" for r in RANDOMIZATIONS]


def base_method(text: str) -> str:
    m = cli.one_method(text)
    if "+" in m.replace("+nee", ""):
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
                          default_resolution="64x32", methods=("bsdf+nee",))
    p.set_defaults(reference_spp=4096, reference_method="path+ldsampler")
    add_arguments(p)
    return p


def method_name(base: str, sampler: str) -> str:
    return base if sampler == "independent" else f"{base}+{sampler}"


def depths(args) -> list[int]:
    return [args.max_depth] if args.max_depth is not None else list(args.depths)


def plan(st: Study) -> tuple[dict, dict]:
    """(reference jobs per depth, {depth: {sampler: [jobs of the ladder]}}), interleaved."""
    a = st.args
    targets = P.doubling_targets(a.spp, a.ladder_factor)
    refs, ladders = {}, {}
    for d in depths(a):
        depth = Depth(d, a.depth.rr_depth, a.depth.hide_emitters)
        refs[d] = st.reference_jobs(depth=depth)
        ladders[d] = {s: [st.job(f"{NAME}/depth{d}/{s}/spp{t:05d}", method_name(a.base, s), t,
                                 depth=depth, timing_group=f"{NAME}/depth{d}")
                          for t in targets] for s in samplers()}
    return refs, ladders


def ordered(refs: dict, ladders: dict) -> list[P.Job]:
    """References first, then per depth every sampler at one spp before the next spp."""
    jobs = [j for r in refs.values() for j in r]
    for by_sampler in ladders.values():
        for i in range(len(next(iter(by_sampler.values())))):
            jobs += [ladder[i] for ladder in by_sampler.values()]
    return jobs


def timing(st: Study, result) -> float:
    """Render time compared: process CPU time on the CPU (LLVM) backend, where other
    processes sharing the machine perturb wall-clock time, else wall-clock time."""
    if st.variant.startswith("llvm") and result.cpu_seconds > 0:
        return result.cpu_seconds
    return result.seconds


def analyse(st: Study, refs: dict, ladders: dict) -> tuple[list[SS.Row], dict, dict]:
    points, floors = {}, {}
    for d, by_sampler in ladders.items():
        ref, meta = st.reference(refs[d])
        floors[d] = meta
        points[d] = {}
        for s, jobs in by_sampler.items():
            pts = []
            for j in jobs:
                r = st.store.get(j.key)
                image = r.image.astype(float)
                pts.append(SS.Point(r.spp, timing(st, r), metrics.mse(image, ref),
                                    metrics.relmse(image, ref)))
            points[d][s] = pts
    return SS.table(points, st.width * st.height), points, floors


def comparison(st: Study, refs: dict, ladders: dict, d: int) -> dict:
    """Viewer block: every sampler's image at the largest count of the ladder, at max_depth d."""
    ref, _ = st.reference(refs[d])
    images = [(s, st.store.get(jobs[-1].key).image.astype(float))
              for s, jobs in ladders[d].items()]
    return report.viewer(st.out, f"Samplers at max_depth {d}, {st.args.spp} spp", images, ref,
                         f"{st.args.base} with each sampler at max_depth {d} after the largest "
                         f"sample count, against the reference.")


def g(x: float) -> str:
    return f"{x:.3g}"


def run(args) -> None:
    start = time.perf_counter()
    st = Study(args)
    refs, ladders = plan(st)
    st.run(ordered(refs, ladders), f"{NAME}: renders")
    rows, points, floors = analyse(st, refs, ladders)
    sentences = SS.conclude(rows)
    blocks = [report.text(
        f"Which sampler to use with {args.base} on {os.path.basename(args.scene)} at "
        f"{st.width}x{st.height}: Mitsuba's independent, stratified, multijitter, orthogonal "
        f"and ldsampler against the bundled halton with each randomization, at max_depth "
        f"{', '.join(map(str, depths(args)))}. Every point of the ladder "
        f"{', '.join(map(str, P.doubling_targets(args.spp, args.ladder_factor)))} spp is its "
        f"own render (samplers that round the count up are shown at the count they rendered). "
        f"Efficiency is Veach's 1/(MSE x render time) at the largest count, relative to "
        f"independent: above 1, a sampler reaches a given error sooner. Render time is "
        f"{CPU_TIME if st.variant.startswith('llvm') else 'wall-clock time'}.")]
    for d in points:
        figures.error_plots(os.path.join(args.out, NAME, f"error_depth{d}.png"),
                            {s: ([p.spp for p in pts], [p.seconds for p in pts],
                                 [p.mse for p in pts]) for s, pts in points[d].items()}, "MSE")
        blocks.append(report.image(
            f"{NAME}/error_depth{d}.png", f"max_depth {d}: MSE against spp and against render "
            f"(CPU) time per sampler (log-log, fitted slopes in the legend); reference: "
            f"{st.describe_reference(floors[d])}."))
        blocks.append(comparison(st, refs, ladders, d))
    table_rows = [[r.depth, r.sampler, r.spp, g(r.mse), g(r.relmse), f"{r.us_per_sample:.3f}",
                   f"{r.relative_mse:.2f}", f"{r.relative_efficiency:.2f}", f"{r.slope:.2f}"]
                  for r in rows]
    blocks += [
        report.write_table(args.out, f"{NAME}/samplers",
                           ["max_depth", "sampler", "spp", "MSE", "relMSE", "µs / sample",
                            "MSE / independent", "efficiency / independent", "MSE slope"],
                           table_rows, f"Samplers with {args.base} at the largest sample count"),
        report.text("Conclusion: " + " ".join(sentences))]
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "base method": args.base, "max_depth": ", ".join(map(str, depths(args))),
                "path settings": args.depth.describe(), "variant": args.variant,
                "seed": args.seed, "reference": f"{args.reference_spp} spp of "
                f"{args.reference_method}",
                "render times measured on": st.timed_on(ordered(refs, ladders))}
    report.write_section(args.out, NAME, "Samplers: halton against Mitsuba's own", ORDER,
                         settings, blocks, args.variant, time.perf_counter() - start)
    from experiments.lib import store
    store.write_json(os.path.join(args.out, NAME, "summary.json"),
                     {"rows": [r.__dict__ for r in rows], "conclusion": sentences})


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    run(args)
    print(f"report: {report.build_report(args.out, args.variant)}")


if __name__ == "__main__":
    cli.main_wrapper(main)
