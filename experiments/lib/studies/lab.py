"""Sampling lab: every vr_path strategy as a warp, and every sampler's point sets, measured.

Warps (:mod:`experiments.lib.lab_warps`): each registered strategy of ``vr_path`` on
``phong`` (exponents 1, 10, 100, 1000), ``roughconductor`` (alpha 0.1) and
``roughdielectric`` (alpha 0.3, both sides) at incidence 0, 60 and 85 degrees,
drawn by the plugin's own ``integrators.path.sample_direction`` and checked
against its ``direction_pdf`` by a chi-square test; the integrand f cos and
the relative variance of the weight f cos / pdf beside it. Point sets
(:mod:`experiments.lib.lab_points`): the points one pixel receives from every
sampler label of the sampler table (the sampler study's list, a ``--plugin``
sampler included) at 64 and 256 spp, driven as a render drives them; 2-D
projections, centered L2 discrepancy and radially averaged power spectra. Each
part is plan -> measure -> pure analysis (a conclusion table and at most three
sentences computed from it) -> report. Finished panels are cached under
OUT/lab/cache, so a rerun (or an interrupted run, rerun) only computes what is
missing.

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
from experiments.lib import sampler_study as SS
from experiments.lib.methods import strategies as registered_strategies

NAME = "lab"
ORDER = 35
SAMPLES = 1_000_000
QUICK_SAMPLES = 10_000


@dataclasses.dataclass(frozen=True)
class Config:
    """What one run of the lab computes."""
    bsdfs: tuple = LW.BSDFS
    incidences: tuple = LW.INCIDENCES
    samplers: tuple | None = None        # None: every label of the sampler table
    counts: tuple = LP.COUNTS
    pixels: tuple = (8, 8)               # width, height of the point-set "render"
    strategies: tuple | None = None      # None: every registered strategy
    samples: int = SAMPLES               # directions per warp panel
    seed: int = 0

    def sampler_labels(self) -> list[str]:
        return list(self.samplers or LP.samplers())

    def strategy_names(self) -> list[str]:
        return list(self.strategies or registered_strategies())


FULL = Config()
QUICK = Config(bsdfs=(LW.BSDFS[1], LW.BSDFS[-1]), incidences=(60.0,), counts=(64,),
               pixels=(4, 4), samples=QUICK_SAMPLES)


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.lab", __doc__.split("\n")[0],
                          default_resolution="64x32")
    p.add_argument("--samples", type=cli.positive_int, default=None,
                   help=f"directions per warp panel (default {SAMPLES}; {QUICK_SAMPLES} "
                        f"with --quick)")
    p.add_argument("--quick", action="store_true",
                   help="tiny run (for tests): two BSDFs at 60 degrees, every sampler at 64 "
                        "spp on 4x4 pixels")
    return p


def parse(argv=None):
    args = cli.parse_args(build_parser(), argv)
    base = QUICK if args.quick else FULL
    if args.samples is None:
        args.samples = base.samples
    args.config = dataclasses.replace(base, samples=args.samples, seed=args.seed)
    return args


def slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label)


# ------------------------------------------------------------------ warps

@dataclasses.dataclass(frozen=True)
class WarpsMeasured:
    specs: list                  # LW.PanelSpec, in plan order
    panels: dict                 # {spec key: panel}
    rows: list                   # one dict per panel (the warps table)


def plan_warps(cfg: Config) -> list:
    return LW.plan(cfg.strategy_names(), cfg.samples, cfg.seed, cfg.bsdfs, cfg.incidences)


def measure_warps(specs: list, cache: str) -> WarpsMeasured:
    panels = {spec.key(): LW.cached(spec, cache) for spec in specs}
    rows = [{"bsdf": spec.bsdf_label, "incidence_deg": spec.incidence_deg,
             "strategy": spec.strategy, "samples": spec.samples, "seed": spec.seed,
             "grid": LW.domain_for(spec).describe(),
             **{k: panels[spec.key()][k] for k in LW.SCALARS}} for spec in specs]
    return WarpsMeasured(specs, panels, rows)


WARP_HEADER = ["bsdf", "incidence_deg", "strategy", "samples", "seed", "grid", "p_value",
               "chi2", "dof", "rel_variance", "albedo", "drawn", "in_grid", "max_weight",
               "max_z"]


def report_warps(out: str, cfg: Config, m: WarpsMeasured, found: LW.Findings) -> list:
    out_dir = os.path.join(out, NAME)
    strategies = list(dict.fromkeys(s.strategy for s in m.specs))
    blocks = []
    for label, _ in cfg.bsdfs:
        mine = [s for s in m.specs if s.bsdf_label == label]
        stem = "warps_" + slug(label)
        tiles = [(f"{s.strategy:8s} {s.incidence_deg:4g}°  p={m.panels[s.key()]['p_value']:.2g}"
                  f"\nVar/E²={m.panels[s.key()]['rel_variance']:.3g}", m.panels[s.key()])
                 for s in mine]
        LF.warp_mosaic(os.path.join(out_dir, stem + ".png"), f"{label}: vr_path strategies",
                       tiles)
        blocks.append(report.image(
            f"{NAME}/{stem}.png",
            f"{label}, {LW.domain_for(mine[0]).describe()} (x: azimuth, the whole sphere with "
            f"the mirror direction's azimuth in the middle; y: cosine, the normal or the "
            f"lobe axis at the top): per row one strategy at one incidence; left to right the "
            f"first {mine[0].scatter} drawn directions, the histogram of {cfg.samples} "
            f"directions, the strategy's density integrated over the same cells (both as "
            f"(value/max)^{LF.GAMMA:g}), their difference as a z-score (blue: too few "
            f"samples, red: too many; ±{LF.Z_RANGE:g} at full colour) and the integrand "
            f"f·cos."))
    rows = m.rows
    configs = list(dict.fromkeys((r["bsdf"], r["incidence_deg"]) for r in rows))
    values = np.array([[next(r["rel_variance"] for r in rows if (r["bsdf"], r["incidence_deg"])
                             == c and r["strategy"] == s) for s in strategies] for c in configs])
    LF.rel_variance_chart(os.path.join(out_dir, "rel_variance.png"),
                          [f"{b} {i:g}°" for b, i in configs], strategies, values)
    blocks.append(report.image(f"{NAME}/rel_variance.png",
                               "Var[w]/E[w]^2 of the weight w = f·cos/pdf per configuration "
                               "and strategy (0: w constant, the strategy matches f·cos)."))
    blocks.append(report.write_table(
        out, f"{NAME}/warps", WARP_HEADER,
        [[r[h] if not isinstance(r[h], float) else float(f"{r[h]:.6g}") for h in WARP_HEADER]
         for r in rows], "Every warp panel (p_value: chi-square test of the histogram "
                         "against the strategy's density)", collapsed=True))
    wide = []
    for b, i in configs:
        cells = {r["strategy"]: r for r in rows if (r["bsdf"], r["incidence_deg"]) == (b, i)}
        wide.append([b, f"{i:g}"] + [f"{cells[s]['p_value']:.3g}" for s in strategies]
                    + [f"{cells[s]['rel_variance']:.3g}" for s in strategies])
    blocks.append(report.write_table(
        out, f"{NAME}/p_values", ["bsdf", "incidence_deg"]
        + [f"p_value {s}" for s in strategies] + [f"rel_variance {s}" for s in strategies],
        wide, "Chi-square p-value and Var[w]/E[w]^2 per configuration and strategy"))
    blocks += [report.write_table(
        out, f"{NAME}/warps_conclusion", LW.HEADER, [r.cells() for r in found.rows],
        f"Warps, per strategy over {found.configurations} configurations: chi-square "
        f"rejections at 1% (Sidak over the panels: p < {found.alpha:.1e}), the lowest "
        f"p-value, where Var[w]/E[w]^2 exceeds {LW.EXPLODES:g}, and in how many "
        f"configurations the strategy's Var[w]/E[w]^2 is the lowest"),
        report.text("\n\n".join(found.sentences))]
    return blocks


# ------------------------------------------------------------- point sets

@dataclasses.dataclass(frozen=True)
class PointsMeasured:
    names: list                  # sampler labels, in order
    results: dict                # {(spp, label): LP.compute's dict}
    cd: dict                     # {(spp, label, pair): mean squared CD over pixels}
    joint: dict                  # {(spp, label, pair): joint low-frequency power}
    counts: dict                 # {spp: {label: points drawn}}


def plan_points(cfg: Config) -> list:
    width, height = cfg.pixels
    return [LP.PointSpec(name, spp, seeds=(cfg.seed,), width=width, height=height)
            for spp in cfg.counts for name in cfg.sampler_labels()]


def measure_points(specs: list, cache: str) -> PointsMeasured:
    results, cd, joint, counts = {}, {}, {}, {}
    for spec in specs:
        res = results[(spec.spp, spec.sampler)] = LP.cached(spec, cache)
        counts.setdefault(spec.spp, {})[spec.sampler] = int(res["count"])
        for a, b in LP.PAIRS:
            cd[(spec.spp, spec.sampler, (a, b))] = float(np.mean(res[f"cd_{a}_{b}"]))
            joint[(spec.spp, spec.sampler, (a, b))] = float(res[f"joint_{a}_{b}"])
    names = list(dict.fromkeys(s.sampler for s in specs))
    return PointsMeasured(names, results, cd, joint, counts)


def analyse_points(m: PointsMeasured, spp: int) -> LP.Findings:
    """The conclusion at ``spp`` requested (pure, from the measured numbers)."""
    at = {(n, p): v for (s, n, p), v in m.cd.items() if s == spp}
    joint = {(n, p): v for (s, n, p), v in m.joint.items() if s == spp}
    return LP.analyse(at, joint, m.counts[spp], spp, SS.families(m.names))


def report_points(out: str, cfg: Config, m: PointsMeasured, found: LP.Findings) -> list:
    out_dir = os.path.join(out, NAME)
    width, height = cfg.pixels
    names, rows, blocks = m.names, [], []
    for spp in cfg.counts:
        points, power, counts = {}, {}, m.counts[spp]
        for name in names:
            res = m.results[(spp, name)]
            for a, b in LP.PAIRS:
                tag = f"{a}_{b}"
                points[(name, (a, b))] = res[f"scatter_{tag}"]
                power[(name, (a, b))] = (res["freqs"], res[f"power_{tag}"])
                cd = res[f"cd_{tag}"]
                rows.append([name, spp, counts[name], f"({a},{b})", LP.describe_pair(a, b),
                             float(f"{np.mean(cd):.6g}"), float(f"{np.std(cd):.3g}"),
                             float(f"{np.mean(cd) / LP.random_expectation(counts[name]):.4g}"),
                             float(f"{float(res[f'joint_{tag}']):.4g}"), len(cd)])
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
                                f"at low frequencies = stratified).")]
    blocks.append(report.write_table(
        out, f"{NAME}/discrepancy",
        ["sampler", "spp", "count", "pair", "dimensions", "discrepancy_cd", "discrepancy_cd_std",
         "ratio_to_independent_expectation", "joint_power", "pixels"], rows,
        "Squared centered L2 discrepancy per sampler, count and pair (mean over pixels)",
        collapsed=True))
    spp = found.spp
    header = ["sampler", "count"] + [f"({a},{b})" for a, b in LP.PAIRS]
    wide = [[n, m.counts[spp][n]] + [f"{m.cd[(spp, n, p)]:.3g}" for p in LP.PAIRS]
            for n in names]
    wide.append(["(independent points, expected)", ""] + [
        f"{LP.random_expectation(spp):.3g}" for _ in LP.PAIRS])
    blocks += [
        report.write_table(out, f"{NAME}/discrepancy_{spp}", header, wide,
                           f"discrepancy_cd (squared centered L2) at {spp} spp requested, "
                           f"mean over pixels; columns: dimension pairs"),
        report.write_table(
            out, f"{NAME}/points_conclusion", LP.HEADER, [r.cells() for r in found.rows],
            f"Point sets at {spp} spp requested: the pairs each sampler stratifies jointly "
            f"(discrepancy below {LP.LOST} of independent points' and joint low-frequency "
            f"power below {LP.JOINT}), only per coordinate, or not at all"),
        report.text("\n\n".join(found.sentences))]
    return blocks


GUIDE = (
    "How to read this section. Each warp row is one way vr_path picks the next direction. "
    "The picture is the whole sphere of directions (or, for narrow Phong lobes, a cap about "
    "the mirror direction) in an equal-area projection: left-right is the azimuth phi, "
    "up-down the cosine to the normal (top: the normal, bottom: straight through the "
    "surface), so every cell covers the same solid angle.\n\n"
    "A correct strategy's histogram (2nd tile) looks like its density (3rd) up to noise, "
    "the difference tile (4th) is unstructured speckle, and the chi-square p-value is not "
    "tiny. The last tile is what the strategy should follow: f·cos. The closer the density "
    "is to the shape of f·cos, the smaller Var[w]/E[w]^2, the relative variance of the "
    "weight the path is multiplied by; 0 means every sample gives the exact answer.\n\n"
    "The point-set plots show the numbers a sampler hands one pixel, pair by pair of "
    "dimensions, in the order vr_path (bsdf + next-event estimation) consumes them. "
    "Evenly spread points (low discrepancy, a power spectrum below 1 at low frequencies) "
    "integrate smooth functions of those two dimensions better than independent points; "
    "a pair that looks like independent points gains nothing.\n\n"
    "Dimension k is the k-th float drawn per sample: 0-1 the film position in the pixel "
    "(the camera's next_2d), then per bounce 6: the emitter sample (2), the BSDF lobe "
    "choice (1), the direction (2) and Russian roulette (1).\n\n"
    "A sampler that stratifies only "
    "the two values of one next_2d call together shows it in the pairs within one call; "
    "one that stratifies across calls (an orthogonal array, a sequence over all its "
    "dimensions) shows it in the pairs across calls too.")


def run(args) -> None:
    start = time.perf_counter()
    cfg: Config = args.config
    out_dir = os.path.join(args.out, NAME)
    warps = measure_warps(plan_warps(cfg), os.path.join(out_dir, "cache", "warps"))
    warp_found = LW.analyse(warps.rows)
    warp_seconds = time.perf_counter() - start
    points = measure_points(plan_points(cfg), os.path.join(out_dir, "cache", "points"))
    point_found = analyse_points(points, cfg.counts[0])
    point_seconds = time.perf_counter() - start - warp_seconds
    blocks = ([report.text(GUIDE)] + report_warps(args.out, cfg, warps, warp_found)
              + report_points(args.out, cfg, points, point_found))
    settings = {"samples per warp panel": cfg.samples, "seed": cfg.seed,
                "warp grid": f"{LW.PanelSpec.res} x {LW.PanelSpec.res} cells, "
                             f"{LW.PanelSpec.ires} x {LW.PanelSpec.ires} trapezoid points "
                             f"per cell",
                "BSDFs": "; ".join(label for label, _ in cfg.bsdfs),
                "incidences (deg)": ", ".join(f"{i:g}" for i in cfg.incidences),
                "point sets": f"{cfg.pixels[0]}x{cfg.pixels[1]} pixels, "
                              f"counts {', '.join(map(str, cfg.counts))} requested",
                "variant": args.variant, "quick": args.quick,
                "wall time (s)": f"warps {warp_seconds:.1f}, point sets {point_seconds:.1f} "
                                 f"(panels and point sets cached under {NAME}/cache/ are "
                                 f"not recomputed)"}
    report.write_section(args.out, NAME, "Sampling lab: strategies as warps, samplers as "
                         "point sets", ORDER, settings, blocks, args.variant,
                         time.perf_counter() - start)
    files.write_json(os.path.join(out_dir, "summary.json"), {
        "warps": warps.rows, "warp_conclusion": warp_found.sentences,
        "warp_table": [dataclasses.asdict(r) for r in warp_found.rows],
        "point_conclusion": point_found.sentences,
        "point_table": [dataclasses.asdict(r) for r in point_found.rows],
        "discrepancy": [{"spp": spp, "sampler": n, "pair": list(p), "discrepancy_cd": v}
                        for (spp, n, p), v in points.cd.items()]})


STUDY = register_study(StudySpec(
    NAME, 'Sampling lab: strategies as warps, samplers as point sets', ORDER, build_parser, run,
    parse=parse, quick=("--quick",)))
