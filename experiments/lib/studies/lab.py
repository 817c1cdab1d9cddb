"""Sampling lab: every vr_path strategy as a warp, and every sampler's point sets, measured.

Warps (:mod:`experiments.lib.lab_warps`): each strategy of ``vr_path`` on
``phong`` (exponents 1, 10, 100, 1000), ``roughconductor`` (alpha 0.1) and
``roughdielectric`` (alpha 0.3, both sides) at incidence 0, 60 and 85 degrees,
drawn by the plugin's own ``integrators.path.sample_direction`` and checked
against its ``direction_pdf`` by a chi-square test; the integrand f cos and
the relative variance of the weight f cos / pdf beside it. Point sets
(:mod:`experiments.lib.lab_points`): the points one pixel receives from every
sampler of the sampler study at 64 and 256 spp, driven as a render drives
them; 2-D projections, centered L2 discrepancy and radially averaged power
spectra. Finished panels are cached under OUT/lab/cache, so a rerun (or an
interrupted run, rerun) only computes what is missing.

    python -m experiments.lab --help
"""
from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from experiments.lib import files
from experiments.lib.studies import StudySpec, register_study
from experiments.lib import cli, report
from experiments.lib import lab_figures as LF
from experiments.lib import lab_points as LP
from experiments.lib import lab_warps as LW

NAME = "lab"
ORDER = 35
SAMPLES = 1_000_000
QUICK_SAMPLES = 10_000


@dataclasses.dataclass(frozen=True)
class Config:
    """What one run of the lab computes."""
    bsdfs: tuple = LW.BSDFS
    incidences: tuple = LW.INCIDENCES
    samplers: tuple | None = None        # None: every sampler of the sampler study
    counts: tuple = LP.COUNTS
    pixels: tuple = (8, 8)               # width, height of the point-set "render"


FULL = Config()
QUICK = Config(bsdfs=(LW.BSDFS[1], LW.BSDFS[-1]), incidences=(60.0,),
               samplers=("independent", "stratified", "orthogonal", "halton:owen"),
               counts=(64,), pixels=(4, 4))


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.lab", __doc__.split("\n")[0],
                          default_resolution="64x32")
    p.add_argument("--samples", type=cli.positive_int, default=None,
                   help=f"directions per warp panel (default {SAMPLES}; {QUICK_SAMPLES} "
                        f"with --quick)")
    p.add_argument("--quick", action="store_true",
                   help="tiny run (for tests): two BSDFs at 60 degrees, four samplers at 64 spp")
    return p


def parse(argv=None):
    args = cli.parse_args(build_parser(), argv)
    args.config = QUICK if args.quick else FULL
    if args.samples is None:
        args.samples = QUICK_SAMPLES if args.quick else SAMPLES
    return args


# ------------------------------------------------------------------ warps

def run_warps(args, out_dir: str) -> tuple[list[dict], list[dict]]:
    from integrators.choices import STRATEGIES
    cfg = args.config
    specs = LW.plan(STRATEGIES, args.samples, args.seed, cfg.bsdfs, cfg.incidences)
    cache = os.path.join(out_dir, "cache", "warps")
    rows, blocks = [], []
    panels = {}
    for spec in specs:
        panel = LW.cached(spec, cache)
        panels[spec.key()] = panel
        rows.append({"bsdf": spec.bsdf_label, "incidence_deg": spec.incidence_deg,
                     "strategy": spec.strategy, "samples": spec.samples, "seed": spec.seed,
                     "grid": LW.domain_for(spec).describe(),
                     **{k: panel[k] for k in LW.SCALARS}})
    for label, _ in cfg.bsdfs:
        mine = [s for s in specs if s.bsdf_label == label]
        stem = "warps_" + "".join(c if c.isalnum() else "_" for c in label)
        tiles = []
        for spec in mine:
            panel = panels[spec.key()]
            tiles.append((f"{spec.strategy:8s} {spec.incidence_deg:4g}°  p={panel['p_value']:.2g}"
                         f"\nVar/E²={panel['rel_variance']:.3g}", panel))
        LF.warp_mosaic(os.path.join(out_dir, stem + ".png"), f"{label}: vr_path strategies",
                       tiles)
        blocks.append(report.image(
            f"{NAME}/{stem}.png",
            f"{label}, {LW.domain_for(mine[0]).describe()} (x: azimuth, the whole sphere with "
            f"the mirror direction's azimuth in the middle; y: cosine, the normal or the "
            f"lobe axis at the top): per row one strategy at one incidence; left to right the "
            f"first {mine[0].scatter} drawn directions, the histogram of {args.samples} "
            f"directions, the strategy's density integrated over the same cells (both as "
            f"(value/max)^{LF.GAMMA:g}), their difference as a z-score (blue: too few "
            f"samples, red: too many; ±{LF.Z_RANGE:g} at full colour) and the integrand "
            f"f·cos."))
    configs = list(dict.fromkeys((r["bsdf"], r["incidence_deg"]) for r in rows))
    values = np.array([[next(r["rel_variance"] for r in rows if (r["bsdf"], r["incidence_deg"])
                             == c and r["strategy"] == s) for s in STRATEGIES] for c in configs])
    LF.rel_variance_chart(os.path.join(out_dir, "rel_variance.png"),
                          [f"{b} {i:g}°" for b, i in configs], list(STRATEGIES), values)
    blocks.append(report.image(f"{NAME}/rel_variance.png",
                               "Var[w]/E[w]^2 of the weight w = f·cos/pdf per configuration "
                               "and strategy (0: w constant, the strategy matches f·cos)."))
    header = ["bsdf", "incidence_deg", "strategy", "samples", "seed", "grid", "p_value", "chi2",
              "dof", "rel_variance", "albedo", "drawn", "in_grid", "max_weight", "max_z"]
    blocks.append(report.write_table(
        args.out, f"{NAME}/warps", header,
        [[r[h] if not isinstance(r[h], float) else float(f"{r[h]:.6g}") for h in header]
         for r in rows], "Every warp panel (p_value: chi-square test of the histogram "
                         "against the strategy's density)", collapsed=True))
    wide = []
    for b, i in configs:
        cells = {r["strategy"]: r for r in rows if (r["bsdf"], r["incidence_deg"]) == (b, i)}
        wide.append([b, f"{i:g}"] + [f"{cells[s]['p_value']:.3g}" for s in STRATEGIES]
                    + [f"{cells[s]['rel_variance']:.3g}" for s in STRATEGIES])
    blocks.append(report.write_table(
        args.out, f"{NAME}/p_values", ["bsdf", "incidence_deg"]
        + [f"p_value {s}" for s in STRATEGIES] + [f"rel_variance {s}" for s in STRATEGIES],
        wide, "Chi-square p-value and Var[w]/E[w]^2 per configuration and strategy"))
    return rows, blocks


# ------------------------------------------------------------- point sets

def run_points(args, out_dir: str) -> tuple[dict, dict, list[dict]]:
    cfg = args.config
    names = list(cfg.samplers or LP.samplers())
    cache = os.path.join(out_dir, "cache", "points")
    width, height = cfg.pixels
    table, joint, counts_by, rows, blocks = {}, {}, {}, [], []
    for spp in cfg.counts:
        points, power, counts = {}, {}, {}
        for name in names:
            spec = LP.PointSpec(name, spp, seeds=(args.seed,), width=width, height=height)
            res = LP.cached(spec, cache)
            counts[name] = int(res["count"])
            for a, b in LP.PAIRS:
                tag = f"{a}_{b}"
                points[(name, (a, b))] = res[f"scatter_{tag}"]
                power[(name, (a, b))] = (res["freqs"], res[f"power_{tag}"])
                cd = res[f"cd_{tag}"]
                table[(spp, name, (a, b))] = float(np.mean(cd))
                joint[(spp, name, (a, b))] = float(res[f"joint_{tag}"])
                rows.append([name, spp, counts[name], f"({a},{b})", LP.describe_pair(a, b),
                             float(f"{np.mean(cd):.6g}"), float(f"{np.std(cd):.3g}"),
                             float(f"{np.mean(cd) / LP.random_expectation(counts[name]):.4g}"),
                             float(f"{float(res[f'joint_{tag}']):.4g}"), len(cd)])
        counts_by[spp] = counts
        LF.point_grid(os.path.join(out_dir, f"points_{spp}.png"),
                      f"One pixel's points at {spp} spp requested (vr_path bsdf+nee order)",
                      names, list(LP.PAIRS), points, counts)
        LF.spectra(os.path.join(out_dir, f"spectrum_{spp}.png"),
                   f"Radially averaged power spectrum at {spp} spp, mean over "
                   f"{min(width * height, max(8, LP.PointSpec('', 0).spectrum_points // spp))}"
                   f" pixels", names, list(LP.PAIRS), power, counts)
        blocks += [report.image(f"{NAME}/points_{spp}.png",
                                f"The points pixel 0 receives at {spp} spp requested (count "
                                f"drawn in brackets), per pair of dimensions."),
                   report.image(f"{NAME}/spectrum_{spp}.png",
                                f"Power spectra at {spp} spp (1 = independent points; below 1 "
                                f"at low frequencies = stratified)."),
                   ]
    blocks.append(report.write_table(
        args.out, f"{NAME}/discrepancy",
        ["sampler", "spp", "count", "pair", "dimensions", "discrepancy_cd", "discrepancy_cd_std",
         "ratio_to_independent_expectation", "joint_power", "pixels"], rows,
        "Squared centered L2 discrepancy per sampler, count and pair (mean over pixels)",
        collapsed=True))
    return table, joint, counts_by, blocks


def discrepancy_wide(args, table: dict, counts: dict, spp: int) -> dict:
    names = list(args.config.samplers or LP.samplers())
    header = ["sampler", "count"] + [f"({a},{b})" for a, b in LP.PAIRS]
    rows = [[n, counts[n]] + [f"{table[(spp, n, p)]:.3g}" for p in LP.PAIRS] for n in names]
    rows.append(["(independent points, expected)", ""] + [
        f"{LP.random_expectation(spp):.3g}" for _ in LP.PAIRS])
    return report.write_table(args.out, f"{NAME}/discrepancy_{spp}", header, rows,
                              f"discrepancy_cd (squared centered L2) at {spp} spp requested, "
                              f"mean over pixels; columns: dimension pairs")


GUIDE = (
    "How to read this section. Each warp row is one way vr_path picks the next direction. "
    "The picture is the whole sphere of directions (or, for narrow Phong lobes, a cap about "
    "the mirror direction) in an equal-area projection: left-right is the azimuth phi, "
    "up-down the cosine to the normal (top: the normal, bottom: straight through the "
    "surface), so every cell covers the same solid angle. A correct strategy's histogram "
    "(2nd tile) looks like its density (3rd) up to noise, the difference tile (4th) is "
    "unstructured speckle, and the chi-square p-value is not tiny. The last tile is what "
    "the strategy should follow: f·cos. The closer the density is to the shape of f·cos, "
    "the smaller Var[w]/E[w]^2, the relative variance of the weight the path is multiplied "
    "by; 0 means every sample gives the exact answer, above 10 one bounce needs more than "
    "10 times the samples of a matched strategy.\n\n"
    "The point-set plots show the numbers a sampler hands one pixel, pair by pair of "
    "dimensions, in the order vr_path (bsdf + next-event estimation) consumes them. "
    "Evenly spread points (low discrepancy, a power spectrum below 1 at low frequencies) "
    "integrate smooth functions of those two dimensions better than independent points; "
    "a pair that looks like independent points gains nothing. Dimension k is the k-th "
    "float drawn per sample: 0-1 the film position in the pixel (the camera's next_2d), "
    "then per bounce 6: the emitter sample (2), the BSDF lobe choice (1), the direction "
    "(2) and Russian roulette (1). Mitsuba's samplers stratify the two values of one "
    "next_2d call together; halton stratifies every pair of its prime bases, well only "
    "while the bases are small compared with the sample count.")


def run(args) -> None:
    start = time.perf_counter()
    out_dir = os.path.join(args.out, NAME)
    warp_rows, warp_blocks = run_warps(args, out_dir)
    warp_seconds = time.perf_counter() - start
    table, joint, counts, point_blocks = run_points(args, out_dir)
    point_seconds = time.perf_counter() - start - warp_seconds
    first = args.config.counts[0]
    wide = discrepancy_wide(args, table, counts[first], first)
    at = lambda d: {(n, p): v for (spp, n, p), v in d.items() if spp == first}  # noqa: E731
    point_sentences = LP.conclude(at(table), at(joint), counts[first], first)
    warp_sentences = LW.conclude(warp_rows)
    blocks = [report.text(GUIDE)] + warp_blocks + [
        report.text("Warps: " + " ".join(warp_sentences))] + point_blocks + [
        wide, report.text("Point sets: " + " ".join(point_sentences))]
    settings = {"samples per warp panel": args.samples, "seed": args.seed,
                "warp grid": f"{LW.PanelSpec.res} x {LW.PanelSpec.res} cells, "
                             f"{LW.PanelSpec.ires} x {LW.PanelSpec.ires} trapezoid points "
                             f"per cell",
                "BSDFs": "; ".join(label for label, _ in args.config.bsdfs),
                "incidences (deg)": ", ".join(f"{i:g}" for i in args.config.incidences),
                "point sets": f"{args.config.pixels[0]}x{args.config.pixels[1]} pixels, "
                              f"counts {', '.join(map(str, args.config.counts))} requested",
                "variant": args.variant, "quick": args.quick,
                "wall time (s)": f"warps {warp_seconds:.1f}, point sets {point_seconds:.1f} "
                                 f"(panels and point sets cached under {NAME}/cache/ are "
                                 f"not recomputed)"}
    report.write_section(args.out, NAME, "Sampling lab: strategies as warps, samplers as "
                         "point sets", ORDER, settings, blocks, args.variant,
                         time.perf_counter() - start)
    files.write_json(os.path.join(out_dir, "summary.json"),
                     {"warps": warp_rows, "warp_conclusion": warp_sentences,
                      "point_conclusion": point_sentences,
                      "discrepancy": [{"spp": spp, "sampler": n, "pair": list(p),
                                       "discrepancy_cd": v}
                                      for (spp, n, p), v in table.items()]})


STUDY = register_study(StudySpec(
    NAME, 'Sampling lab: strategies as warps, samplers as point sets', ORDER, build_parser, run,
    parse=parse, quick=("--quick",)))
