"""Convergence sequences, error against spp and time, equal-time panel, efficiency table.

For each method: render 1, 2, 4, ... --spp samples per pixel by accumulating
passes, keep every intermediate image (EXR + PNG) with its cumulative render
time, measure MSE / relMSE against a cached high-spp reference, then plot and
tabulate. Also an equal-time comparison (--time-budget seconds per method).

    python -m experiments.convergence --help
"""
from __future__ import annotations

import os
import time

from experiments.lib import cli, figures, metrics, report
from experiments.lib import render as R

NAME = "convergence"


def build_parser() -> cli.Parser:
    return cli.common_parser("python -m experiments.convergence", __doc__.split("\n")[0],
                          spp=256, time_budget=2.0)


def fmt(x: float) -> str:
    return f"{x:.3g}"


def sequences(args, ref) -> tuple[dict, list[dict]]:
    """Part 1: progressive renders of every method to 1, 2, 4, ... --spp, their errors.

    Returns ({metric: {method: (spp, seconds, errors)}}, report blocks).
    """
    out, (width, height) = args.out, args.resolution
    targets = R.doubling_targets(args.spp)
    table, series, grid, captions = [], {"MSE": {}, "relMSE": {}}, [], []
    for method in args.method_objs:
        job = R.method_job(out, NAME, args.info, method, width, height, args.variant, args.seed)
        R.run_progressive(job, targets)
        points = []
        grid.append([]), captions.append([])
        for cp in (c for c in job.checkpoints if c["spp"] in targets):
            image = R.read_checkpoint(job, cp)
            err = metrics.errors(image, ref)
            points.append((cp["spp"], cp["seconds"], err["mse"], err["relmse"]))
            table.append([method.name, cp["spp"], round(cp["seconds"], 4), fmt(err["mse"]),
                          fmt(err["relmse"]), fmt(err["rmse"]),
                          f"{NAME}/{method.name}/{cp['exr']}"])
            grid[-1].append(image)
            captions[-1].append(f"MSE {err['mse']:.2e}\nrelMSE {err['relmse']:.2e}\n"
                                f"{cp['seconds']:.2f} s")
        spp, secs, mse, rel = (list(v) for v in zip(*points))
        series["MSE"][method.name] = (spp, secs, mse)
        series["relMSE"][method.name] = (spp, secs, rel)

    figures.image_grid(os.path.join(out, NAME, "sequences.png"), grid,
                       [m.name for m in args.method_objs], [f"{t} spp" for t in targets], captions)
    for metric in series:
        figures.error_plots(os.path.join(out, NAME, f"error_{metric.lower()}.png"),
                            series[metric], metric)
    return series, [
        report.image(f"{NAME}/sequences.png", "Convergence sequences: rows = methods, columns = "
                     "spp; MSE, relMSE and cumulative render time under each tile."),
        report.image(f"{NAME}/error_mse.png", "MSE against spp and against render time "
                     "(log-log); fitted slopes in the legend (-1 is the Monte Carlo rate)."),
        report.image(f"{NAME}/error_relmse.png", "relMSE = mean((x - ref)^2 / (ref^2 + 0.01)) "
                     "against spp and time."),
        report.write_table(out, f"{NAME}/errors", ["method", "spp", "seconds", "MSE", "relMSE",
                                                   "RMSE", "image"], table,
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


def equal_time(args, ref) -> tuple[dict, list[dict]]:
    """Part 2: every method renders for --time-budget seconds; returns ({method: (spp,
    seconds, MSE)}, report blocks)."""
    out, (width, height) = args.out, args.resolution
    images, captions, result = [], [], {}
    for method in args.method_objs:
        job = R.method_job(out, "equal_time", args.info, method, width, height, args.variant,
                           args.seed, extra_settings={"time_budget": args.time_budget})
        R.run_progressive(job, time_budget=args.time_budget)
        cp = job.checkpoints[-1]
        image = R.read_checkpoint(job, cp)
        err = metrics.errors(image, ref)
        result[method.name] = (cp["spp"], cp["seconds"], err["mse"])
        images.append(image)
        captions.append(f"{cp['spp']} spp in {cp['seconds']:.2f} s\nMSE {err['mse']:.2e}\n"
                        f"relMSE {err['relmse']:.2e}")
    figures.image_grid(os.path.join(out, NAME, "equal_time.png"), [images + [ref]],
                       [f"{args.time_budget:g} s each"],
                       [m.name for m in args.method_objs] + ["reference"],
                       [captions + [f"{args.reference_spp} spp"]])
    return result, [report.image(f"{NAME}/equal_time.png",
                                 f"Equal time: every method renders for {args.time_budget:g} s "
                                 f"(in passes of 4 spp); errors under each image.")]


def efficiency(args, series: dict, equal: dict) -> list[dict]:
    """Part 3: Veach efficiency 1/(MSE x time) relative to uniform, as CSV and markdown."""
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
            args.out, f"{NAME}/efficiency",
            ["method", "spp", "seconds", "MSE", "relMSE", "1/(MSE x time)",
             f"relative to {base}", "equal-time spp", "equal-time MSE",
             f"equal-time relative to {base}"], rows,
            f"Veach efficiency 1/(MSE x time) after {args.spp} spp and at equal time, "
            f"relative to {base}"),
        report.text(
            f"Most efficient after {args.spp} spp: {best}, {eff[best] / eff[base]:.1f} times "
            f"{base}. Timings are wall-clock render times on this machine and vary with its "
            f"load (other processes sharing the cores slow every method); MSE does not."),
    ]


def run(args) -> None:
    start = time.perf_counter()
    width, height = args.resolution
    ref, ref_meta = R.reference(args.out, args.info, width, height, args.reference_spp,
                                args.reference_integrator, args.variant, args.seed)
    blocks = [report.text(
        f"Progressive renders of {os.path.basename(args.scene)} at {width}x{height}: each "
        f"method accumulates passes (a new seed each; Halton continues its sequence) to 1, 2, "
        f"4, ... {args.spp} spp. Errors are against a {args.reference_spp}-spp reference "
        f"({args.reference_integrator} with emitter sampling, max_depth {args.info.max_depth}; "
        f"its own expected MSE, from the spread of its passes, is about "
        f"{ref_meta.get('mse_floor', float('nan')):.1e}, a floor under every MSE below). "
        f"Times are warm render times (JIT compilation excluded), cumulative over passes.")]
    series, part = sequences(args, ref)
    blocks += part
    equal, part = equal_time(args, ref)
    blocks += part + efficiency(args, series, equal)
    settings = {"scene": args.scene, "resolution": f"{width}x{height}", "spp": args.spp,
                "methods": ", ".join(m.name for m in args.method_objs),
                "variant": args.variant, "seed": args.seed,
                "time budget (s)": args.time_budget, "max_depth": args.info.max_depth,
                "reference": f"{args.reference_spp} spp, {args.reference_integrator} + NEE, "
                             f"cache/{ref_meta['exr']} ({ref_meta['seconds']:.1f} s)",
                "max lanes per pass": R.MAX_LANES}
    report.write_section(args.out, NAME, "Convergence, error against time, efficiency", 10,
                         settings, blocks, args.variant, time.perf_counter() - start)


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    run(args)
    print(f"report: {report.build_report(args.out, args.variant)}")


if __name__ == "__main__":
    cli.main_wrapper(main)
