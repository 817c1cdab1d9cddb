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

import os
import time

from experiments.lib import cli, figures, metrics, report
from experiments.lib import methods as M
from experiments.lib import render as R

NAME = "writeup"
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
    add_arguments(p)
    return p


def _selected(args, pairs):
    names = {m.name for m in args.method_objs}
    return [p for p in pairs if p[0] in names and p[1] in names]


def _render(args, experiment, method_name, width, height, targets, **options):
    """Render one method to ``targets`` spp; return {spp: (mean, variance of mean, entry)}."""
    job = R.method_job(args.out, experiment, args.info, M.parse_method(method_name), width,
                       height, args.variant, args.seed, save_variance=True, **options)
    R.run_progressive(job, targets)
    return {cp["spp"]: (R.read_checkpoint(job, cp), R.read_checkpoint(job, cp, "var_exr"),
                        dict(cp, path=f"{experiment}/{method_name}/{cp['png']}"))
            for cp in job.checkpoints if cp["spp"] in targets}


def _bias_row(label, check):
    ci = ", ".join(f"{d:+.2e} ± {h:.1e}" for d, h in zip(check["mean_diff"],
                                                       check["ci_half_width"]))
    inside = "yes" if all(check["ci_contains_zero"]) else "no"
    per_channel = " / ".join(f"{f:.2%}" for f in check["pass_fraction_per_channel"])
    return [label, ci, inside, f"{check['pass_fraction']:.2%}", per_channel]


BIAS_HEADER = ["pair", "mean difference A − B per channel (R, G, B) ± 99% CI",
               "CI contains 0", "pixel values passing z-test", "per channel"]


def short_figures(args, ref) -> list[dict]:
    width, height = args.resolution
    pairs = _selected(args, SHORT_PAIRS)
    if not pairs:
        return []
    wanted: dict[str, set] = {}
    for a, b, opt in pairs:
        for name in (a, b):
            wanted.setdefault(name, set()).add(getattr(args, opt))
    renders = {n: _render(args, NAME, n, width, height, sorted(t), max_pass_spp=1)
               for n, t in wanted.items()}
    blocks, rows, bias_rows = [], [], []
    for a, b, opt in pairs:
        spp = getattr(args, opt)
        (img_a, var_a, _), (img_b, var_b, _) = renders[a][spp], renders[b][spp]
        rmse_a, rmse_b = metrics.rmse(img_a, ref), metrics.rmse(img_b, ref)
        stem = f"{a}_vs_{b}_{spp}spp".replace("+", "_")
        figures.image_grid(os.path.join(args.out, NAME, stem + ".png"), [[img_b, img_a, ref]],
                           [f"{spp} spp"], [b, a, "reference"],
                           [[f"RMSE {rmse_b:.4f}", f"RMSE {rmse_a:.4f}",
                             f"{args.reference_spp} spp"]])
        blocks.append(report.image(f"{NAME}/{stem}.png",
                                   f"{a} vs {b} at {width}x{height} after {spp} spp: RMSE "
                                   f"{rmse_a:.4f} vs {rmse_b:.4f}, ratio {b}/{a} = "
                                   f"{rmse_b / rmse_a:.2f}"))
        rows.append([f"{a} vs {b}", spp, f"{rmse_b:.4f}", f"{rmse_a:.4f}",
                     f"{rmse_b / rmse_a:.2f}", f"{(rmse_b / rmse_a) ** 2:.2f}"])
        bias_rows.append(_bias_row(f"{a} − {b} ({spp} spp)",
                                   metrics.bias_check(img_a, var_a, img_b, var_b)))
    blocks.insert(0, report.write_table(
        args.out, f"{NAME}/rmse", ["pair A vs B", "spp", "RMSE B", "RMSE A", "RMSE ratio B/A",
                                   "variance ratio B/A"], rows,
        f"RMSE against the reference at {width}x{height} (ratio > 1: A has less error)"))
    blocks.append(report.write_table(
        args.out, f"{NAME}/bias_short", BIAS_HEADER, bias_rows,
        f"Bias check of the same pairs at {width}x{height} (variances from 1-spp passes)"))
    return blocks


def full_checks(args) -> list[dict]:
    width, height = args.full_resolution
    pairs = _selected(args, FULL_PAIRS)
    if not pairs:
        return []
    pass_spp = max(1, args.full_spp // FULL_PASSES)
    renders = {n: _render(args, NAME + "_full", n, width, height, [args.full_spp],
                          max_pass_spp=pass_spp)[args.full_spp]
               for n in dict.fromkeys(x for p in pairs for x in p)}
    blocks, rows = [], []
    for a, b in pairs:
        (img_a, var_a, cp_a), (img_b, var_b, cp_b) = renders[a], renders[b]
        check = metrics.bias_check(img_a, var_a, img_b, var_b)
        rows.append(_bias_row(f"{a} − {b}", check) + [cp_a["passes"], f"{cp_a['seconds']:.1f}",
                                                        f"{cp_b['seconds']:.1f}"])
        stem = f"bias_{a}_vs_{b}".replace("+", "_")
        figures.image_grid(os.path.join(args.out, NAME, stem + ".png"), [[img_b, img_a]],
                           [f"{args.full_spp} spp"], [b, a],
                           [[f"{cp_b['seconds']:.1f} s", f"{cp_a['seconds']:.1f} s"]])
        figures.zscore_map(os.path.join(args.out, NAME, stem + "_z.png"), img_a - img_b,
                           var_a + var_b, f"|z| of {a} − {b}; {check['pass_fraction']:.2%} "
                           f"of pixel values below 2.576")
        blocks += [report.image(f"{NAME}/{stem}.png", f"{b} and {a} at {width}x{height} after "
                                f"{args.full_spp} spp"),
                   report.image(f"{NAME}/{stem}_z.png", f"Per-pixel z-score of {a} − {b}")]
    blocks.insert(0, report.write_table(
        args.out, f"{NAME}/bias_full", BIAS_HEADER + ["passes", "seconds A", "seconds B"], rows,
        f"No bias at {width}x{height} after {args.full_spp} spp: A − B per channel with its "
        f"99% confidence interval, and the fraction of pixel values with |z| < 2.576"))
    blocks.insert(0, report.text(
        "Each image is rendered in independent passes (Halton: one sequence continued over "
        "the passes); the per-pixel variance of each mean comes from the spread of its "
        "passes. Without bias, the confidence intervals contain 0 and about 99% of pixel "
        "values pass the z-test. For plain Halton (no randomization, the same points in "
        "every pixel) the pass spread is only a proxy for the error and pixel errors are "
        "correlated, so its interval is approximate."))
    return blocks


def run(args) -> None:
    start = time.perf_counter()
    width, height = args.resolution
    ref, ref_meta = R.reference(args.out, args.info, width, height, args.reference_spp,
                                args.reference_integrator, args.variant, args.seed)
    blocks = [report.text(
        "The writeup's comparisons, measured. Methods: uniform hemisphere, cosine-weighted "
        "hemisphere and Phong-lobe (bsdf) direction sampling, and uniform sampling driven by "
        "the plain Halton sequence (uniform+halton), all without emitter sampling, as in the "
        "writeup.")]
    blocks += short_figures(args, ref)
    if args.full:
        blocks += full_checks(args)
    else:
        blocks.append(report.text(
            f"The {args.full_resolution[0]}x{args.full_resolution[1]}, {args.full_spp}-spp "
            f"no-bias checks run with --full (make full)."))
    settings = {"scene": args.scene, "resolution": f"{width}x{height}",
                "short spp": args.short_spp, "halton spp": args.halton_spp, "full": args.full,
                "full resolution": "{}x{}".format(*args.full_resolution),
                "full spp": args.full_spp, "methods": ", ".join(m.name for m in args.method_objs),
                "variant": args.variant, "seed": args.seed, "max_depth": args.info.max_depth,
                "reference": f"{args.reference_spp} spp, {args.reference_integrator} + NEE, "
                             f"cache/{ref_meta['exr']}"}
    report.write_section(args.out, NAME, "The writeup's figures, with numbers", 20, settings,
                         blocks, args.variant, time.perf_counter() - start)


def main(argv=None) -> None:
    args = cli.parse_args(build_parser(), argv)
    run(args)
    print(f"report: {report.build_report(args.out, args.variant)}")


if __name__ == "__main__":
    cli.main_wrapper(main)
