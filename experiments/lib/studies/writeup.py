"""The writeup's figures, with numbers.

* cosine vs uniform and Phong lobe (bsdf) vs uniform after --short-spp (20) spp,
  Halton (plain, uniform+halton) vs uniform after --halton-spp (50) spp, at
  --resolution (256x128): images side by side with their RMSE and the RMSE ratio;
* with --full: cosine vs uniform and Halton vs uniform at --full-resolution
  (1024x512) after --full-spp (1000) spp: no bias, i.e. the per-channel mean
  difference with a 99% confidence interval and the fraction of pixel values
  passing a per-pixel z-test (expected about 99%).

    python -m experiments.writeup --help
"""
from __future__ import annotations

import math
import os
import time

import numpy as np

from experiments.lib import jobs as J
from experiments.lib.studies import StudySpec, register_study
from experiments.lib import cli, figures, metrics, report, stats
from experiments.lib import plan as P
from experiments.lib.methods import parse_method
from experiments.lib.study import Study, repeat_prefix

NAME = "writeup"
ORDER = 30
#: (method, compared against, which spp option) of the 256x128 figures.
SHORT_PAIRS = (("cosine", "uniform", "short_spp"), ("bsdf", "uniform", "short_spp"),
               ("uniform+halton", "uniform", "halton_spp"))
#: (method, compared against) of the --full bias checks.
FULL_PAIRS = (("cosine", "uniform"), ("uniform+halton", "uniform"))
#: Passes of a --full render (for the per-pixel variances of the z-test).
FULL_PASSES = 100


def add_arguments(p: cli.Parser) -> None:
    """The options of this experiment (also taken by run_all)."""
    p.add_argument("--short-spp", type=cli.positive_int, default=20,
                   help="spp of the cosine/Phong-lobe vs uniform figures")
    p.add_argument("--halton-spp", type=cli.positive_int, default=50,
                   help="spp of the Halton vs uniform figure")
    p.add_argument("--full", action="store_true",
                   help="also the long no-bias checks at --full-resolution, --full-spp")
    p.add_argument("--full-resolution", type=cli.resolution, default="1024x512", metavar="WxH",
                   help="resolution of the --full bias checks")
    p.add_argument("--full-spp", type=cli.positive_int, default=1000,
                   help="spp of the --full bias checks")


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.writeup", __doc__.split("\n")[0])
    p.set_defaults(reference_spp=512)      # its own expected error is subtracted
    add_arguments(p)
    return p


def _selected(args, pairs):
    names = set(args.methods)
    return [p for p in pairs if p[0] in names and p[1] in names]


def _plan(st: Study, experiment: str, name: str, targets, resolution, pass_spp: int,
          repeat: int = 0):
    """The ladder of ``name`` to ``targets`` (plain Halton also to 1/4 and 1/2 of the last,
    for its convergence check); ``repeat``: an independent randomization of it."""
    targets = set(targets)
    method = parse_method(name)
    if method.deterministic:
        targets |= {max(1, max(targets) // 4), max(1, max(targets) // 2)}
    return st.ladder(repeat_prefix(f"{experiment}/{name}", repeat), method, sorted(targets),
                     resolution=resolution, pass_spp=pass_spp)


def _images(st: Study, jobs) -> dict[int, J.Accumulator]:
    """{requested spp: cumulative image} of a ladder."""
    return dict(zip(_targets(jobs), st.accumulate(jobs)))


def _targets(jobs) -> list[int]:
    out, total = [], 0
    for j in jobs:
        total += j.spp
        out.append(total)
    return out


def _bias_row(label, check):
    ci = ", ".join(f"{d:+.2e} ± {h:.1e}" for d, h in zip(check["mean_diff"],
                                                       check["ci_half_width"]))
    inside = "yes" if all(check["ci_contains_zero"]) else "no"
    per_channel = " / ".join(f"{f:.2%}" for f in check["pass_fraction_per_channel"])
    return [label, ci, inside, f"{check['pass_fraction']:.2%}", per_channel]


BIAS_HEADER = ["pair", "mean difference A − B per channel (R, G, B) ± 99% CI",
               "CI contains 0", "pixel values passing z-test", "per channel"]
DETERMINISTIC_HEADER = ["method", "spp", "MSE against the reference",
                        "image-mean difference to the reference (R, G, B)",
                        "MSE slope vs spp", "converges"]
DETERMINISTIC_TEXT = (
    "Plain Halton (uniform+halton) is deterministic: the same points in every pixel and every "
    "run, so its 1-spp passes are not independent samples and a z-test from their spread "
    "does not apply. It is checked the way a deterministic sequence can be: its error "
    "against the reference must fall as the sequence continues (MSE at 1/4, 1/2 and all of "
    "the samples; 'converges' when the last is below the first and the fitted slope of MSE "
    "against spp is -0.5 or steeper; with the image-mean difference per channel).")


def _deterministic_rows(name, images, ref, ref_var):
    spps = sorted(images)
    check = metrics.deterministic_check(spps, [images[s].mean for s in spps], ref, ref_var)
    rows = [[name, s, f"{e:.3e}", ", ".join(f"{d:+.2e}" for d in diff),
             f"{check['slope']:.2f}", "yes" if check["converges"] else "no"]
            for s, e, diff in zip(check["spp"], check["mse"], check["mean_diff"])]
    return rows, check


def short_figures(st: Study, ref, ref_var) -> list[dict]:
    args = st.args
    ref_floor = float(np.mean(ref_var))
    width, height = args.resolution
    pairs = _selected(args, SHORT_PAIRS)
    if not pairs:
        return []
    wanted: dict[str, set] = {}
    for a, b, opt in pairs:
        for name in (a, b):
            wanted.setdefault(name, set()).add(getattr(args, opt))
    # 1-spp passes in the first repeat: the spread of its passes gives the per-pixel
    # variances of the bias check; the other repeats only enter the expected errors
    ladders = {n: [_plan(st, NAME, n, t, args.resolution, 1 if r == 0 else 0, r)
                   for r in range(st.repeats_of(parse_method(n)))] for n, t in wanted.items()}
    st.run([j for reps in ladders.values() for jobs in reps for j in jobs], f"{NAME}: figures")
    repeats = {n: [_images(st, jobs) for jobs in reps] for n, reps in ladders.items()}
    renders = {n: reps[0] for n, reps in repeats.items()}
    blocks, rows, bias_rows, det_rows, verdicts = [], [], [], [], []
    for a, b, opt in pairs:
        spp = getattr(args, opt)
        # expected MSE over the repeats, the reference's own subtracted (a deterministic
        # method's one run stands for every repeat)
        mse = {n: st.per_repeat(metrics.mse(r[spp].mean, ref) - ref_floor for r in repeats[n])
               for n in (a, b)}
        var_ratio = stats.ratio_interval([mse[b]], [mse[a]])
        rmse_ratio = stats.Estimate(*(math.sqrt(x) if x > 0 else float("nan") for x in
                                      (var_ratio.value, var_ratio.lo, var_ratio.hi)),
                                    var_ratio.n)
        expected = {n: stats.mean_interval(v) for n, v in mse.items()}
        rows.append([f"{a} vs {b}", spp, st.repeats,
                     *(f"{math.sqrt(max(expected[n].value, 0)):.4f}" for n in (b, a)),
                     *(f"{x:.3g}" for x in (rmse_ratio.value, rmse_ratio.lo, rmse_ratio.hi,
                                            var_ratio.value, var_ratio.lo, var_ratio.hi))])
        verdicts.append(f"After {spp} spp, " + stats.verdict(a, b, var_ratio, "accurate")
                        + " (ratio of expected MSEs at equal spp).")
        acc_a, acc_b = renders[a][spp], renders[b][spp]
        img_a, img_b = acc_a.mean, acc_b.mean
        rmse_a, rmse_b = metrics.rmse(img_a, ref), metrics.rmse(img_b, ref)
        stem = f"{a}_vs_{b}_{spp}spp".replace("+", "_")
        figures.image_grid(os.path.join(args.out, NAME, stem + ".png"), [[img_b, img_a, ref]],
                           [f"{spp} spp"], [b, a, "reference"],
                           [[f"RMSE {rmse_b:.4f}", f"RMSE {rmse_a:.4f}",
                             f"{args.reference_spp} spp"]])
        blocks.append(report.viewer(args.out, f"{a} vs {b}, {spp} spp",
                                    [(b, img_b), (a, img_a)], ref,
                                    f"{a} vs {b} at {width}x{height} after {spp} spp: RMSE "
                                    f"{rmse_a:.4f} vs {rmse_b:.4f}, ratio {b}/{a} = "
                                    f"{rmse_b / rmse_a:.2f}", figure=f"{NAME}/{stem}.png"))
        if parse_method(a).deterministic:
            det_rows += _deterministic_rows(a, renders[a], ref, ref_var)[0]
        else:
            bias_rows.append(_bias_row(f"{a} − {b} ({spp} spp)", metrics.bias_check(
                img_a, acc_a.variance_of_mean(), img_b, acc_b.variance_of_mean())))
    blocks[0:0] = [report.write_table(
        args.out, f"{NAME}/rmse", ["pair A vs B", "spp", "repeats", "RMSE B", "RMSE A",
                                   "RMSE ratio B/A", "RMSE ratio B/A_lo", "RMSE ratio B/A_hi",
                                   "variance ratio B/A", "variance ratio B/A_lo",
                                   "variance ratio B/A_hi"], rows,
        f"Expected RMSE against the reference at {width}x{height} over {st.repeats} "
        f"independent runs, the reference's own expected MSE ({ref_floor:.1e}) subtracted "
        f"(ratio > 1: A has less error; {stats.LEVEL:.0%} intervals, {stats.METHOD}; plain "
        f"Halton is deterministic: one run, no spread of its own). The images below are the "
        f"first run."), report.text(" ".join(verdicts))]
    if bias_rows:
        blocks.append(report.write_table(
            args.out, f"{NAME}/bias_short", BIAS_HEADER, bias_rows,
            f"Bias check of the random pairs at {width}x{height} (variances from 1-spp "
            f"passes)"))
    if det_rows:
        blocks += [report.text(DETERMINISTIC_TEXT), report.write_table(
            args.out, f"{NAME}/deterministic_short", DETERMINISTIC_HEADER, det_rows,
            f"Convergence check of plain Halton at {width}x{height}")]
    return blocks


def full_checks(st: Study) -> list[dict]:
    args = st.args
    width, height = args.full_resolution
    pairs = _selected(args, FULL_PAIRS)
    if not pairs:
        return []
    pass_spp = max(1, args.full_spp // FULL_PASSES)
    chunk = pass_spp * 10                     # 10 passes per job: an interruption loses little
    targets = list(range(chunk, args.full_spp, chunk)) + [args.full_spp]
    ref_jobs = st.reference_jobs(resolution=args.full_resolution)
    ladders = {n: _plan(st, NAME + "_full", n, targets, args.full_resolution, pass_spp)
               for n in dict.fromkeys(x for p in pairs for x in p)}
    st.run(ref_jobs + [j for jobs in ladders.values() for j in jobs], f"{NAME}: --full")
    renders = {n: _images(st, jobs) for n, jobs in ladders.items()}
    ref = st.accumulate(ref_jobs)[-1]
    blocks, rows, det_rows = [], [], []
    for a, b in pairs:
        acc_a, acc_b = renders[a][args.full_spp], renders[b][args.full_spp]
        img_a, img_b = acc_a.mean, acc_b.mean
        stem = f"bias_{a}_vs_{b}".replace("+", "_")
        figures.image_grid(os.path.join(args.out, NAME, stem + ".png"), [[img_b, img_a]],
                           [f"{args.full_spp} spp"], [b, a],
                           [[f"{acc_b.seconds:.1f} s", f"{acc_a.seconds:.1f} s"]])
        blocks.append(report.viewer(args.out, f"{b} and {a}, {args.full_spp} spp",
                                    [(b, img_b), (a, img_a)], ref.mean,
                                    f"{b} and {a} at {width}x{height} after {args.full_spp} spp",
                                    figure=f"{NAME}/{stem}.png"))
        if parse_method(a).deterministic:
            det_rows += _deterministic_rows(a, renders[a], ref.mean, ref.variance_of_mean())[0]
            continue
        var_a, var_b = acc_a.variance_of_mean(), acc_b.variance_of_mean()
        check = metrics.bias_check(img_a, var_a, img_b, var_b)
        rows.append(_bias_row(f"{a} − {b}", check) + [acc_a.passes, f"{acc_a.seconds:.1f}",
                                                        f"{acc_b.seconds:.1f}"])
        figures.zscore_map(os.path.join(args.out, NAME, stem + "_z.png"), img_a - img_b,
                           var_a + var_b, f"|z| of {a} − {b}; {check['pass_fraction']:.2%} "
                           f"of pixel values below 2.576")
        blocks.append(report.image(f"{NAME}/{stem}_z.png", f"Per-pixel z-score of {a} − {b}"))
    if rows:
        blocks.insert(0, report.write_table(
            args.out, f"{NAME}/bias_full", BIAS_HEADER + ["passes", "seconds A", "seconds B"],
            rows, f"No bias at {width}x{height} after {args.full_spp} spp: A − B per channel "
            f"with its 99% confidence interval, and the fraction of pixel values with "
            f"|z| < 2.576"))
        blocks.insert(0, report.text(
            "Each random image is rendered in independent passes; the per-pixel variance of "
            "each mean comes from the spread of its passes. Without bias, the confidence "
            "intervals contain 0 and about 99% of pixel values pass the z-test."))
    if det_rows:
        blocks += [report.text(DETERMINISTIC_TEXT), report.write_table(
            args.out, f"{NAME}/deterministic_full", DETERMINISTIC_HEADER, det_rows,
            f"Convergence check of plain Halton at {width}x{height} against a "
            f"{args.reference_spp}-spp reference")]
    return blocks


def run(args) -> None:
    start = time.perf_counter()
    st = Study(args)
    width, height = args.resolution
    ref_jobs = st.reference_jobs()
    st.run(ref_jobs, f"{NAME}: reference")
    ref, ref_meta = st.reference(ref_jobs)
    ref_var = st.accumulate(ref_jobs)[-1].variance_of_mean()
    blocks = [report.text(
        "The writeup's comparisons, measured. Methods: uniform hemisphere, cosine-weighted "
        "hemisphere and Phong-lobe (bsdf) direction sampling, and uniform sampling driven by "
        "the plain Halton sequence (uniform+halton), all without emitter sampling, as in the "
        f"writeup ({args.depth.describe()}).")]
    blocks += short_figures(st, ref, ref_var)
    if args.full:
        blocks += full_checks(st)
    else:
        blocks.append(report.text(
            f"The {args.full_resolution[0]}x{args.full_resolution[1]}, {args.full_spp}-spp "
            f"no-bias checks run with --full (make full)."))
    settings = {"scene": args.scene, "resolution": f"{width}x{height}",
                "short spp": args.short_spp, "halton spp": args.halton_spp, "full": args.full,
                "full resolution": "{}x{}".format(*args.full_resolution),
                "full spp": args.full_spp, "methods": ", ".join(args.methods),
                "variant": args.variant, "seed": args.seed,
                "path settings": args.depth.describe(),
                "reference": st.describe_reference(ref_meta)}
    report.write_section(args.out, NAME, "The writeup's figures, with numbers", ORDER, settings,
                         blocks, args.variant, time.perf_counter() - start)


STUDY = register_study(StudySpec(
    NAME, "The writeup's figures, with numbers", ORDER, build_parser, run,
    shared=add_arguments,
    forwarded={"short_spp": "--short-spp", "halton_spp": "--halton-spp", "full": "--full",
               "full_resolution": "--full-resolution", "full_spp": "--full-spp"}))
