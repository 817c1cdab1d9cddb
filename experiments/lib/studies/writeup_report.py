"""The writeup study's report: figures, viewers, tables and prose of a
:class:`~.writeup_analysis.Result` (numbers and sentences come from the analysis)."""
from __future__ import annotations

import os
from dataclasses import dataclass

from .. import clock, figures, stats
from .. import report as rep
from . import conclusion
from .writeup_analysis import NAME, Result


@dataclass(frozen=True)
class Context:
    settings: object              # WriteupSettings
    st: object                    # Study
    measured: object              # Measured
    title: str
    order: int
    timer: clock.Timer            # started when the study began


BOUNDS = conclusion.BOUNDS
RMSE_HEADER = ["pair A vs B", "spp", "repeats", "RMSE B", "RMSE A", "RMSE ratio B/A",
               "RMSE ratio B/A_lo", "RMSE ratio B/A_hi", "variance ratio B/A",
               "variance ratio B/A_lo", "variance ratio B/A_hi", BOUNDS]
BIAS_HEADER = ["pair", "mean difference A − B per channel (R, G, B) ± 99% CI",
               "CI contains 0", "pixel values passing z-test", "per channel"]
DETERMINISTIC_HEADER = ["method", "spp", "MSE against the reference",
                        "image-mean difference to the reference (R, G, B)",
                        "MSE slope vs spp", "converges"]
DETERMINISTIC_TEXT = (
    "Plain Halton (uniform+halton) is deterministic: the same points in every pixel and every "
    "run, so its 1-spp passes are not independent samples and a z-test from their spread "
    "does not apply.\n\nIt is checked the way a deterministic sequence can be: its error "
    "against the reference must fall as the sequence continues (MSE at 1/4, 1/2 and all of "
    "the samples; 'converges' when the last is below the first and the fitted slope of MSE "
    "against spp is -0.5 or steeper; with the image-mean difference per channel).")


def _stem(a: str, b: str, suffix: str) -> str:
    return f"{a}_vs_{b}_{suffix}".replace("+", "_")


def short_figures(ctx: Context, result: Result) -> list[dict]:
    s, st, images = ctx.settings, ctx.st, ctx.measured.images
    if not result.pairs:
        return []
    width, height = s.resolution
    ref = images.reference
    blocks, rows = [], []
    for p in result.pairs:
        rows.append([f"{p.a} vs {p.b}", p.spp, st.repeats, f"{p.rmse_b:.4f}",
                     f"{p.rmse_a:.4f}",
                     *conclusion.ratio_cells(p.rmse_ratio),
                     *conclusion.ratio_cells(p.variance_ratio),
                     ", ".join(p.bounds())])
        img_a, img_b = images.shown[(p.a, p.spp)], images.shown[(p.b, p.spp)]
        stem = _stem(p.a, p.b, f"{p.spp}spp")
        figures.image_grid(os.path.join(s.out, NAME, stem + ".png"), [[img_b, img_a, ref]],
                           [f"{p.spp} spp"], [p.b, p.a, "reference"],
                           [[f"RMSE {p.rmse_shown_b:.4f}", f"RMSE {p.rmse_shown_a:.4f}",
                             f"{s.reference_spp} spp"]])
        blocks.append(rep.viewer(
            s.out, f"{p.a} vs {p.b}, {p.spp} spp", [(p.b, img_b), (p.a, img_a)], ref,
            f"{p.a} vs {p.b} at {width}x{height} after {p.spp} spp: RMSE "
            f"{p.rmse_shown_a:.4f} vs {p.rmse_shown_b:.4f}, ratio {p.b}/{p.a} = "
            f"{p.shown_ratio:.2f}", figure=f"{NAME}/{stem}.png"))
    floor = ctx.measured.floor
    blocks[0:0] = [rep.write_table(
        s.out, f"{NAME}/rmse", RMSE_HEADER, rows,
        f"Expected RMSE against the reference at {width}x{height} over {st.repeats} "
        f"independent runs, the reference's own expected MSE ({floor:.1e}) subtracted "
        f"(ratio > 1: A has less error; {stats.LEVEL:.0%} intervals, {stats.METHOD}; plain "
        f"Halton is deterministic: one run, no spread of its own). The images below are the "
        f"first run."), rep.write_table(
        s.out, f"{NAME}/conclusion", conclusion.HEADER, conclusion.rows(result.conclusion),
        f"Conclusion: each pair by its RMSE ratio B/A at equal spp (above 1: A has less "
        f"error) with its {stats.LEVEL:.0%} interval"), rep.text(" ".join(result.sentences))]
    if result.bias_rows:
        blocks.append(rep.write_table(
            s.out, f"{NAME}/bias_short", BIAS_HEADER, result.bias_rows,
            f"Bias check of the random pairs at {width}x{height} (variances from 1-spp "
            f"passes)"))
    if result.deterministic_rows:
        blocks += [rep.text(DETERMINISTIC_TEXT), rep.write_table(
            s.out, f"{NAME}/deterministic_short", DETERMINISTIC_HEADER,
            result.deterministic_rows, f"Convergence check of plain Halton at "
            f"{width}x{height}")]
    return blocks


def full_checks(ctx: Context, result: Result) -> list[dict]:
    s, images = ctx.settings, ctx.measured.images
    if not ctx.measured.full:
        return []
    width, height = s.full_resolution
    blocks = []
    for f in ctx.measured.full:
        img_a, img_b, var = images.full[(f.a, f.b)]
        stem = f"bias_{f.a}_vs_{f.b}".replace("+", "_")
        figures.image_grid(os.path.join(s.out, NAME, stem + ".png"), [[img_b, img_a]],
                           [f"{f.spp} spp"], [f.b, f.a],
                           [[f"{f.seconds_b:.1f} s", f"{f.seconds_a:.1f} s"]])
        blocks.append(rep.viewer(s.out, f"{f.b} and {f.a}, {f.spp} spp",
                                 [(f.b, img_b), (f.a, img_a)], images.full_reference,
                                 f"{f.b} and {f.a} at {width}x{height} after {f.spp} spp",
                                 figure=f"{NAME}/{stem}.png"))
        if f.deterministic:
            continue
        share = result.full_pass_fractions[(f.a, f.b)]
        figures.zscore_map(os.path.join(s.out, NAME, stem + "_z.png"), img_a - img_b, var,
                           f"|z| of {f.a} − {f.b}; {share:.2%} of pixel values below 2.576")
        blocks.append(rep.image(f"{NAME}/{stem}_z.png", f"Per-pixel z-score of {f.a} − {f.b}"))
    if result.full_rows:
        blocks.insert(0, rep.write_table(
            s.out, f"{NAME}/bias_full", BIAS_HEADER + ["passes", "seconds A", "seconds B"],
            result.full_rows, f"No bias at {width}x{height} after {s.full_spp} spp: A − B "
            f"per channel with its 99% confidence interval, and the fraction of pixel values "
            f"with |z| < 2.576"))
        blocks.insert(0, rep.text(
            "Each random image is rendered in independent passes; the per-pixel variance of "
            "each mean comes from the spread of its passes. Without bias, the confidence "
            "intervals contain 0 and about 99% of pixel values pass the z-test."))
    if result.full_deterministic_rows:
        blocks += [rep.text(DETERMINISTIC_TEXT), rep.write_table(
            s.out, f"{NAME}/deterministic_full", DETERMINISTIC_HEADER,
            result.full_deterministic_rows, f"Convergence check of plain Halton at "
            f"{width}x{height} against a {s.reference_spp}-spp reference")]
    return blocks


def settings_table(ctx: Context) -> dict:
    s, st = ctx.settings, ctx.st
    width, height = s.resolution
    return {"scene": s.scene, "resolution": f"{width}x{height}",
            "short spp": s.short_spp, "halton spp": s.halton_spp, "full": s.full,
            "full resolution": "{}x{}".format(*s.full_resolution),
            "full spp": s.full_spp, "methods": ", ".join(m.name for m in s.methods),
            "variant": s.variant, "seed": s.seed, "path settings": s.depth.describe(),
            "reference": st.describe_reference(ctx.measured.reference)}


def report(ctx: Context, result: Result) -> None:
    s = ctx.settings
    blocks = [rep.text(
        "The writeup's comparisons, measured. Methods: uniform hemisphere, cosine-weighted "
        "hemisphere and Phong-lobe (bsdf) direction sampling, and uniform sampling driven by "
        "the plain Halton sequence (uniform+halton), all without emitter sampling, as in the "
        f"writeup ({s.depth.describe()}).")]
    blocks += short_figures(ctx, result)
    if s.full:
        blocks += full_checks(ctx, result)
    else:
        blocks.append(rep.text(
            f"The {s.full_resolution[0]}x{s.full_resolution[1]}, {s.full_spp}-spp "
            f"no-bias checks run with --full (make full)."))
    rep.write_section(s.out, NAME, ctx.title, ctx.order, settings_table(ctx), blocks,
                      s.variant, ctx.timer.elapsed())
