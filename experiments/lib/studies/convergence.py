"""Convergence sequences, error against spp and time, equal-time panel, efficiency table.

For each method: render 1, 2, 4, ... --spp samples per pixel as a ladder of
jobs (each image is the sum of the jobs before it), keep every intermediate
image (EXR + PNG) with its cumulative render time, measure MSE / relMSE
against a high-spp reference, then plot and tabulate. Then an equal-time
comparison: each method renders as many samples as fit in --time-budget
seconds at the speed measured on its ladder. The default methods include
``bsdf+nee`` and Mitsuba's ``path`` as what a user would run instead.

    python -m experiments.convergence --help
"""
from __future__ import annotations

import os
import time

import numpy as np

from experiments.lib import jobs as J
from experiments.lib import files
from experiments.lib.studies import StudySpec, register_study
from experiments.lib import cli, figures, metrics, report, stats
from experiments.lib import plan as P
from experiments.lib.methods import parse_method
from experiments.lib.study import Study, repeat_prefix

NAME = "convergence"
ORDER = 20


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.convergence", __doc__.split("\n")[0],
                          spp=256, time_budget=0.25, default_resolution="128x64")
    p.set_defaults(reference_spp=2048)
    add_arguments(p)
    return p


def add_arguments(p: cli.Parser) -> None:
    """The options of this experiment (also taken by run_all)."""
    p.add_argument("--best-sampler", default="auto", metavar="SAMPLER|auto|none",
                   help="add bsdf+nee with this sampler to the default methods (the best "
                        "combination the suite offers); auto: the sampler study's most "
                        "efficient one at the nearest depth, read from OUT/samplers/"
                        "summary.json when that study has run (run_all runs it first)")


def best_method(args) -> str | None:
    """``bsdf+nee+SAMPLER`` for ``--best-sampler`` (None: none, or no sampler study yet)."""
    choice = getattr(args, "best_sampler", "none")
    if choice == "none":
        return None
    if choice == "auto":
        summary = files.read_json(os.path.join(args.out, "samplers", "summary.json"), {})
        best = summary.get("best") or {}
        if not best:
            return None
        depth = args.depth.max_depth if args.depth.max_depth is not None else 8
        choice = best[min(best, key=lambda d: (abs(int(d) - depth), int(d)))]
    method = "bsdf+nee" if choice == "independent" else f"bsdf+nee+{choice}"
    cli.one_method(method)        # a clear error for a sampler that does not exist
    return method


def methods_of(args) -> list[str]:
    """--methods, with the best combination added to the defaults (see --best-sampler)."""
    methods = list(args.methods)
    best = None if "methods" in args.explicit else best_method(args)
    if best is not None and best not in methods:
        methods.append(best)
    return methods


def plan_sequences(st: Study, methods: list[str]) -> dict[str, list[list[J.Job]]]:
    """Per method, one ladder per repeat (plain Halton: one, it is deterministic)."""
    targets = P.doubling_targets(st.args.spp)
    parsed = {m: parse_method(m) for m in methods}
    return {m: [st.ladder(repeat_prefix(f"{NAME}/{m}", r), parsed[m], targets,
                          timing_group=NAME)
                for r in range(st.repeats_of(parsed[m]))] for m in methods}


def plan_equal_time(st: Study, ladders: dict[str, list[list[J.Job]]]) -> dict[str, list]:
    """Per method, repeats of one job with as many spp as fit in the budget at the speed
    measured on its ladders."""
    jobs = {}
    for m, reps in ladders.items():
        results = [st.store.get(j.key) for ladder in reps for j in ladder]
        per_spp = sum(r.seconds for r in results) / sum(r.spp for r in results)
        spp = max(1, int(st.args.time_budget / per_spp))
        method = reps[0][0].method
        jobs[m] = [st.job(repeat_prefix(f"equal_time/{m}", r), method, spp, timing_group=NAME)
                   for r in range(st.repeats_of(method))]
    return jobs


def sequences(st: Study, ladders, ref, floor) -> tuple[dict, list[dict]]:
    """Expected errors along every ladder; returns ({metric: {method: (spp, [seconds per
    repeat], [errors per repeat])}}, report blocks). Images: the first repeat."""
    out = st.out
    table, series, grid, captions = [], {"MSE": {}, "relMSE": {}, "FLIP": {}}, [], []
    viewers, notes = [], []
    for m, reps in ladders.items():
        runs = [st.accumulate(jobs) for jobs in reps]
        grid.append([]), captions.append([]), notes.append([])
        spp, secs, mse, rel, flip = [], [], [], [], []
        for i, accs in enumerate(zip(*runs)):
            first = accs[0]
            stem = os.path.join(out, NAME, m, f"spp{first.spp:05d}")
            files.write_image(stem, first.mean)
            spp.append(first.spp)
            secs.append(st.per_repeat([a.seconds for a in accs]))
            mse.append(st.per_repeat([metrics.mse(a.mean, ref) - floor["mse_floor"]
                                        for a in accs]))
            rel.append(st.per_repeat([metrics.relmse(a.mean, ref) - floor["relmse_floor"]
                                        for a in accs]))
            flip.append((metrics.flip_mean(first.mean, ref),))     # the image shown
            e_mse, e_rel = (stats.mean_interval(v[-1]) for v in (mse, rel))
            e_flip = flip[-1][0]
            table.append([m, first.spp, len(accs), round(float(np.mean(secs[-1])), 4),
                          *e_mse.cells(), *e_rel.cells(), stats.g(e_flip),
                          f"{NAME}/{m}/spp{first.spp:05d}.exr"])
            grid[-1].append(first.mean)
            captions[-1].append(f"MSE {e_mse.value:.2e}\nrelMSE {e_rel.value:.2e}\n"
                                f"{np.mean(secs[-1]):.2f} s")
            notes[-1].append(f"{first.seconds:.2f} s · expected relMSE {e_rel.value:.3g} · "
                             f"FLIP {e_flip:.3f}")
        series["MSE"][m] = (spp, secs, mse)
        series["relMSE"][m] = (spp, secs, rel)
        series["FLIP"][m] = (spp, secs, flip)
        viewers.append(report.viewer(
            out, f"{m}: 1 to {spp[-1]} spp", [(f"{n} spp", im) for n, im in zip(spp, grid[-1])],
            ref, f"The convergence sequence of {m} against the reference (first repeat; the "
                 f"notes give expected errors over the repeats).", notes[-1]))
    viewers.insert(0, report.viewer(
        out, f"Every method at {st.args.spp} spp", [(m, g[-1]) for m, g in zip(ladders, grid)],
        ref, "The last image of each sequence.", [n[-1] for n in notes]))
    targets = P.doubling_targets(st.args.spp)
    figures.image_grid(os.path.join(out, NAME, "sequences.png"), grid, list(ladders),
                       [f"{t} spp" for t in targets], captions)
    for metric in series:
        figures.error_bands(os.path.join(out, NAME, f"error_{metric.lower()}.png"),
                            {m: (spp, _means(secs), [stats.mean_interval(e) for e in err])
                             for m, (spp, secs, err) in series[metric].items()}, metric)
    band = (f"expected over {st.repeats} repeats with {stats.LEVEL:.0%} bands; the reference's "
            f"own expected error is subtracted")
    return series, viewers + [
        report.image(f"{NAME}/sequences.png", "Convergence sequences (first repeat): rows = "
                     "methods, columns = spp; expected MSE, relMSE and cumulative render time "
                     "under each tile."),
        report.image(f"{NAME}/error_mse.png", f"MSE against spp and against render time "
                     f"(log-log), {band}; fitted slopes in the legend (-1 is the Monte Carlo "
                     f"rate)."),
        report.image(f"{NAME}/error_relmse.png", f"relMSE = mean((x - ref)^2 / (ref^2 + "
                     f"{metrics.RELMSE_EPS})) against spp and time, {band}."),
        report.image(f"{NAME}/error_flip.png", "Mean FLIP (NVIDIA's perceptual error in "
                     "[0, 1], flip-evaluator, HDR) of the images shown (the first repeat) "
                     "against spp and time; a perceptual measure of one image, not an "
                     "expected error (no band), and not a squared error, so its slope is not "
                     "the Monte Carlo -1."),
        report.write_table(out, f"{NAME}/errors", ERRORS_HEADER, table,
                           f"Every intermediate image with its expected error ({band}) and "
                           f"mean cumulative time", collapsed=True),
        report.write_table(out, f"{NAME}/slopes", ["method", "MSE vs spp", "MSE vs time",
                                                   "relMSE vs spp", "relMSE vs time"],
                           slope_rows(series), "Fitted convergence slopes of the expected "
                           "errors (least squares in log-log; -1 is the Monte Carlo rate)"),
    ]


ERRORS_HEADER = ["method", "spp", "repeats", "seconds", "MSE", "MSE_lo", "MSE_hi", "relMSE",
                 "relMSE_lo", "relMSE_hi", "FLIP (first repeat)", "image"]


def _means(values: list) -> list[float]:
    return [float(np.mean(v)) for v in values]


def slope_rows(series: dict) -> list[list]:
    """Per method: slopes of expected MSE and relMSE against spp and against time."""
    rows = []
    for name in series["MSE"]:
        row = [name]
        for metric in ("MSE", "relMSE"):
            spp, seconds, err = series[metric][name]
            err, seconds = _means(err), _means(seconds)
            row += [stats.g(metrics.loglog_slope(spp, err)),
                    stats.g(metrics.loglog_slope(seconds, err))]
        rows.append(row)
    return rows


def equal_time(st: Study, jobs: dict[str, list], ref, floor) -> tuple[dict, list[dict]]:
    """The equal-time panel; returns ({method: (spp, [seconds], [MSE])}, report blocks)."""
    images, captions, result, notes = [], [], {}, []
    for m, reps in jobs.items():
        results = [st.store.get(j.key) for j in reps]
        image = results[0].image.astype(float)
        files.write_image(os.path.join(st.out, "equal_time", m), image)
        mse = st.per_repeat([metrics.mse(r.image.astype(float), ref) - floor["mse_floor"]
                               for r in results])
        secs = st.per_repeat([r.seconds for r in results])
        result[m] = (results[0].spp, secs, mse)
        e = stats.mean_interval(mse)
        images.append(image)
        captions.append(f"{results[0].spp} spp, {np.mean(secs):.2f} s\nMSE {e.value:.2e}")
        notes.append(f"{results[0].spp} spp, {np.mean(secs):.2f} s · expected MSE "
                     f"{e.text()} · FLIP {metrics.flip_mean(image, ref):.3f}")
    figures.image_grid(os.path.join(st.out, NAME, "equal_time.png"), [images], ["equal time"],
                       list(jobs), [captions])
    return result, [report.viewer(
        st.out, f"Equal time ({st.args.time_budget:g} s)", list(zip(jobs, images)), ref,
        f"Equal time: each method renders the samples that fit in {st.args.time_budget:g} s "
        f"at the speed measured on its convergence sequences, {st.repeats} times (the first "
        f"repeat is shown; the notes give the expected MSE over the repeats with its "
        f"{stats.LEVEL:.0%} interval).", notes, figure=f"{NAME}/equal_time.png")]


EFFICIENCY_HEADER = ["method", "spp", "repeats", "seconds", "MSE", "MSE_lo", "MSE_hi",
                     "relMSE", "relMSE_lo", "relMSE_hi", "relative efficiency",
                     "relative efficiency_lo", "relative efficiency_hi", "equal-time spp",
                     "equal-time MSE", "equal-time MSE_lo", "equal-time MSE_hi",
                     "equal-time relative efficiency", "equal-time relative efficiency_lo",
                     "equal-time relative efficiency_hi"]


def efficiency(st: Study, series: dict, equal: dict) -> tuple[list[dict], list[dict]]:
    """The efficiency table (relative to uniform, with intervals) and its verdicts; returns
    (report blocks, rows for summary.json)."""
    final = {n: (spp[-1], secs[-1], mse[-1], series["relMSE"][n][2][-1])
             for n, (spp, secs, mse) in series["MSE"].items()}
    base = "uniform" if "uniform" in final else next(iter(final))
    one = stats.Estimate(1.0, 1.0, 1.0, len(final[base][2]))    # the baseline against itself
    rel = {n: one if n == base else
           stats.efficiency_ratio(v[2], v[1], final[base][2], final[base][1])
           for n, v in final.items()}
    rel_eq = {n: one if n == base else
              stats.efficiency_ratio(v[2], v[1], equal[base][2], equal[base][1])
              for n, v in equal.items()}
    rows, records = [], []
    for n, (spp, secs, mse, relmse) in final.items():
        e_mse, e_rel, e_eq = (stats.mean_interval(x) for x in (mse, relmse, equal[n][2]))
        rows.append([n, spp, len(mse), round(float(np.mean(secs)), 3), *e_mse.cells(),
                     *e_rel.cells(), *rel[n].cells(), equal[n][0], *e_eq.cells(),
                     *rel_eq[n].cells()])
        records.append({"method": n, "spp": spp, "repeats": len(mse),
                        "seconds": float(np.mean(secs)), **e_mse.fields("mse"),
                        **e_rel.fields("relmse"), **rel[n].fields("relative_efficiency"),
                        "equal_time_spp": equal[n][0], **e_eq.fields("equal_time_mse"),
                        **rel_eq[n].fields("equal_time_relative_efficiency")})
    ranked = sorted(rel, key=lambda n: rel[n].value, reverse=True)
    best = ranked[0]
    sentences = [f"Most efficient after {st.args.spp} spp: {best}; "
                 + stats.verdict(best, base, rel[best]) + "."]
    if len(ranked) > 2 or (len(ranked) == 2 and ranked[1] != base):
        second = next(n for n in ranked[1:])
        sentences.append("Against the next best, " + stats.verdict(
            best, second, stats.efficiency_ratio(final[best][2], final[best][1],
                                                 final[second][2], final[second][1])) + ".")
    best_eq = max(rel_eq, key=lambda n: rel_eq[n].value)
    sentences.append(f"At equal time ({st.args.time_budget:g} s) the most efficient is "
                     f"{best_eq}: " + stats.verdict(best_eq, base, rel_eq[best_eq]) + ".")
    return [
        report.write_table(
            st.out, f"{NAME}/efficiency", EFFICIENCY_HEADER, rows,
            f"Veach efficiency 1/(MSE x time) after {st.args.spp} spp and at equal time, "
            f"relative to {base}: expected values over {st.repeats} repeats with "
            f"{stats.LEVEL:.0%} intervals ({stats.METHOD})"),
        report.text(" ".join(sentences) + " Timings are warm render times on this machine "
                    "and vary with its load (other processes sharing the cores slow every "
                    "method); MSE does not."),
    ], records


def run(args) -> None:
    start = time.perf_counter()
    st = Study(args)
    methods = methods_of(args)
    ref_jobs = st.reference_jobs()
    ladders = plan_sequences(st, methods)
    st.run(ref_jobs + [j for reps in ladders.values() for jobs in reps for j in jobs],
           f"{NAME}: sequences")
    equal_jobs = plan_equal_time(st, ladders)
    st.run([j for reps in equal_jobs.values() for j in reps], f"{NAME}: equal time")

    ref, ref_meta = st.reference(ref_jobs)
    best = None if "methods" in args.explicit else best_method(args)
    blocks = [report.text(
        f"Progressive renders of {os.path.basename(args.scene)} at {st.width}x{st.height} "
        f"({args.depth.describe()}): each method accumulates jobs (a new seed each; Halton "
        f"continues its sequence) to 1, 2, 4, ... {args.spp} spp (Mitsuba's stratified, "
        f"orthogonal and ldsampler round counts up; the spp shown are those rendered), "
        f"{st.repeats} times with independent randomizations (plain Halton, deterministic, "
        f"once). Errors are expected values over the repeats against the reference: "
        f"{st.describe_reference(ref_meta)}. Times are warm render times in the timed "
        f"configuration (JIT compilation excluded), cumulative over passes. "
        + (f"{best} is the best combination the sampler study found (its most efficient "
           f"sampler with bsdf+nee)." if best else
           "The sampler study's winner is not among the methods (run the sampler study "
           "first, as run_all does, or give --best-sampler).")
        + f" Intervals: {stats.LEVEL:.0%}, {stats.METHOD}.")]
    series, part = sequences(st, ladders, ref, ref_meta)
    blocks += part
    equal, part = equal_time(st, equal_jobs, ref, ref_meta)
    blocks += part
    part, records = efficiency(st, series, equal)
    blocks += part
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "methods": ", ".join(methods), "repeats": st.repeats, "variant": args.variant,
                "seed": args.seed, "time budget (s)": args.time_budget,
                "path settings": args.depth.describe(),
                "reference": st.describe_reference(ref_meta), "max lanes per pass": J.MAX_LANES,
                "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
                "render times measured on": st.timed_on(
                    [j for reps in ladders.values() for jobs in reps for j in jobs]
                    + [j for reps in equal_jobs.values() for j in reps])}
    report.write_section(args.out, NAME, "Convergence, error against time, efficiency", ORDER,
                         settings, blocks, args.variant, time.perf_counter() - start)
    files.write_json(os.path.join(args.out, NAME, "summary.json"), {"efficiency": records})


STUDY = register_study(StudySpec(
    NAME, 'Convergence, error against time, efficiency', ORDER, build_parser, run,
    shared=add_arguments,
    forwarded={"time_budget": "--time-budget", "best_sampler": "--best-sampler"}))
