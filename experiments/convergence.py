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

from experiments.lib import cli, figures, metrics, report, store
from experiments.lib import plan as P
from experiments.lib.study import Study

NAME = "convergence"


def build_parser() -> cli.Parser:
    return cli.common_parser("python -m experiments.convergence", __doc__.split("\n")[0],
                             spp=256, time_budget=2.0)


def fmt(x: float) -> str:
    return f"{x:.3g}"


def plan_sequences(st: Study) -> dict[str, list[P.Job]]:
    targets = P.doubling_targets(st.args.spp)
    return {m: st.ladder(f"{NAME}/{m}", m, targets, timing_group=NAME)
            for m in st.args.methods}


def plan_equal_time(st: Study, ladders: dict[str, list[P.Job]]) -> dict[str, P.Job]:
    """One job per method with as many spp as fit in the budget at its measured speed."""
    jobs = {}
    for m, ladder in ladders.items():
        results = [st.store.get(j.key) for j in ladder]
        per_spp = sum(r.seconds for r in results) / sum(r.spp for r in results)
        spp = max(1, int(st.args.time_budget / per_spp))
        jobs[m] = st.job(f"equal_time/{m}", m, spp, timing_group=NAME)
    return jobs


def sequences(st: Study, ladders, ref) -> tuple[dict, list[dict]]:
    """Errors of every ladder image; returns ({metric: {method: (spp, seconds, errors)}},
    report blocks)."""
    out = st.out
    table, series, grid, captions = [], {"MSE": {}, "relMSE": {}, "FLIP": {}}, [], []
    viewers, notes = [], []
    for m, jobs in ladders.items():
        points = []
        grid.append([]), captions.append([]), notes.append([])
        for acc in P.accumulate(st.store, jobs):
            stem = os.path.join(out, NAME, m, f"spp{acc.spp:05d}")
            store.write_image(stem, acc.mean)
            err = metrics.errors(acc.mean, ref)
            points.append((acc.spp, acc.seconds, err["mse"], err["relmse"], err["flip"]))
            table.append([m, acc.spp, round(acc.seconds, 4), fmt(err["mse"]),
                          fmt(err["relmse"]), fmt(err["flip"]), fmt(err["rmse"]),
                          f"{NAME}/{m}/spp{acc.spp:05d}.exr"])
            grid[-1].append(acc.mean)
            captions[-1].append(f"MSE {err['mse']:.2e}\nrelMSE {err['relmse']:.2e}\n"
                                f"{acc.seconds:.2f} s")
            notes[-1].append(f"{acc.seconds:.2f} s · relMSE {err['relmse']:.3g} · "
                             f"FLIP {err['flip']:.3f}")
        spp, secs, mse, rel, flip = (list(v) for v in zip(*points))
        series["MSE"][m] = (spp, secs, mse)
        series["relMSE"][m] = (spp, secs, rel)
        series["FLIP"][m] = (spp, secs, flip)
        viewers.append(report.viewer(
            out, f"{m}: 1 to {spp[-1]} spp", [(f"{n} spp", im) for n, im in zip(spp, grid[-1])],
            ref, f"The convergence sequence of {m} against the reference.", notes[-1]))
    viewers.insert(0, report.viewer(
        out, f"Every method at {st.args.spp} spp", [(m, g[-1]) for m, g in zip(ladders, grid)],
        ref, "The last image of each sequence.", [n[-1] for n in notes]))
    targets = P.doubling_targets(st.args.spp)
    figures.image_grid(os.path.join(out, NAME, "sequences.png"), grid, list(ladders),
                       [f"{t} spp" for t in targets], captions)
    for metric in series:
        figures.error_plots(os.path.join(out, NAME, f"error_{metric.lower()}.png"),
                            series[metric], metric)
    return series, viewers + [
        report.image(f"{NAME}/sequences.png", "Convergence sequences: rows = methods, columns = "
                     "spp; MSE, relMSE and cumulative render time under each tile."),
        report.image(f"{NAME}/error_mse.png", "MSE against spp and against render time "
                     "(log-log); fitted slopes in the legend (-1 is the Monte Carlo rate)."),
        report.image(f"{NAME}/error_relmse.png", f"relMSE = mean((x - ref)^2 / (ref^2 + "
                     f"{metrics.RELMSE_EPS})) against spp and time."),
        report.image(f"{NAME}/error_flip.png", "Mean FLIP (NVIDIA's perceptual error in "
                     "[0, 1], flip-evaluator, HDR) against spp and time; not a squared error, "
                     "so its slope is not the Monte Carlo -1."),
        report.write_table(out, f"{NAME}/errors", ["method", "spp", "seconds", "MSE", "relMSE",
                                                   "FLIP", "RMSE", "image"], table,
                           "Every intermediate image with its error and cumulative time",
                           collapsed=True),
        report.write_table(out, f"{NAME}/slopes", ["method", "MSE vs spp", "MSE vs time",
                                                   "relMSE vs spp", "relMSE vs time"],
                           slope_rows(series), "Fitted convergence slopes (least squares in "
                           "log-log; -1 is the Monte Carlo rate)"),
    ]


def slope_rows(series: dict) -> list[list]:
    """Per method: slopes of MSE and relMSE against spp and against time."""
    rows = []
    for name in series["MSE"]:
        row = [name]
        for metric in ("MSE", "relMSE"):
            spp, seconds, err = series[metric][name]
            row += [fmt(metrics.loglog_slope(spp, err)), fmt(metrics.loglog_slope(seconds, err))]
        rows.append(row)
    return rows


def equal_time(st: Study, jobs: dict[str, P.Job], ref) -> tuple[dict, list[dict]]:
    """The equal-time panel; returns ({method: (spp, seconds, MSE)}, report blocks)."""
    images, captions, result, notes = [], [], {}, []
    for m, job in jobs.items():
        r = st.store.get(job.key)
        image = r.image.astype(float)
        store.write_image(os.path.join(st.out, "equal_time", m), image)
        mse = metrics.mse(image, ref)
        result[m] = (r.spp, r.seconds, mse)
        images.append(image)
        captions.append(f"{r.spp} spp, {r.seconds:.2f} s\nMSE {mse:.2e}")
        notes.append(f"{r.spp} spp, {r.seconds:.2f} s · relMSE {metrics.relmse(image, ref):.3g}"
                     f" · FLIP {metrics.flip_mean(image, ref):.3f}")
    figures.image_grid(os.path.join(st.out, NAME, "equal_time.png"), [images], ["equal time"],
                       list(jobs), [captions])
    return result, [report.viewer(
        st.out, f"Equal time ({st.args.time_budget:g} s)", list(zip(jobs, images)), ref,
        f"Equal time: each method renders the samples that fit in {st.args.time_budget:g} s "
        f"at the speed measured on its convergence sequence (spp and actual render time "
        f"on each label).", notes, figure=f"{NAME}/equal_time.png")]


def efficiency(st: Study, series: dict, equal: dict) -> list[dict]:
    final = {n: (spp[-1], secs[-1], mse[-1], series["relMSE"][n][2][-1])
             for n, (spp, secs, mse) in series["MSE"].items()}
    base = "uniform" if "uniform" in final else next(iter(final))
    eff = {n: metrics.efficiency(v[2], v[1]) for n, v in final.items()}
    eff_eq = {n: metrics.efficiency(v[2], v[1]) for n, v in equal.items()}
    rows = [[n, final[n][0], round(final[n][1], 3), fmt(final[n][2]), fmt(final[n][3]),
             fmt(eff[n]), f"{eff[n] / eff[base]:.2f}", equal[n][0], fmt(equal[n][2]),
             f"{eff_eq[n] / eff_eq[base]:.2f}"] for n in final]
    best = max(eff, key=eff.get)
    return [
        report.write_table(
            st.out, f"{NAME}/efficiency",
            ["method", "spp", "seconds", "MSE", "relMSE", "1/(MSE x time)",
             f"relative to {base}", "equal-time spp", "equal-time MSE",
             f"equal-time relative to {base}"], rows,
            f"Veach efficiency 1/(MSE x time) after {st.args.spp} spp and at equal time, "
            f"relative to {base}"),
        report.text(
            f"Most efficient after {st.args.spp} spp: {best}, {eff[best] / eff[base]:.1f} times "
            f"{base}. Timings are warm render times on this machine and vary with its load "
            f"(other processes sharing the cores slow every method); MSE does not."),
    ]


def run(args) -> None:
    start = time.perf_counter()
    st = Study(args)
    ref_jobs = st.reference_jobs()
    ladders = plan_sequences(st)
    st.run(ref_jobs + [j for jobs in ladders.values() for j in jobs], f"{NAME}: sequences")
    equal_jobs = plan_equal_time(st, ladders)
    st.run(list(equal_jobs.values()), f"{NAME}: equal time")

    ref, ref_meta = st.reference(ref_jobs)
    blocks = [report.text(
        f"Progressive renders of {os.path.basename(args.scene)} at {st.width}x{st.height} "
        f"({args.depth.describe()}): each method accumulates jobs (a new seed each; Halton "
        f"continues its sequence) to 1, 2, 4, ... {args.spp} spp (Mitsuba's stratified, "
        f"orthogonal and ldsampler round counts up; the spp shown are those rendered). Errors "
        f"are against the reference: {st.describe_reference(ref_meta)}, a floor under every "
        f"MSE below. Times are warm render times (JIT compilation excluded), cumulative over "
        f"passes.")]
    series, part = sequences(st, ladders, ref)
    blocks += part
    equal, part = equal_time(st, equal_jobs, ref)
    blocks += part + efficiency(st, series, equal)
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "methods": ", ".join(args.methods), "variant": args.variant,
                "seed": args.seed, "time budget (s)": args.time_budget,
                "path settings": args.depth.describe(),
                "reference": st.describe_reference(ref_meta), "max lanes per pass": P.MAX_LANES,
                "render times measured on": st.timed_on(
                    [j for jobs in ladders.values() for j in jobs] + list(equal_jobs.values()))}
    report.write_section(args.out, NAME, "Convergence, error against time, efficiency", 10,
                         settings, blocks, args.variant, time.perf_counter() - start)


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    run(args)
    print(f"report: {report.build_report(args.out, args.variant)}")


if __name__ == "__main__":
    cli.main_wrapper(main)
