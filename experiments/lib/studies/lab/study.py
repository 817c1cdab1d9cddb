"""Sampling lab: every vr_path strategy as a warp, and every sampler's point sets, measured.

Warps (:mod:`experiments.lib.studies.lab.warps`): each registered strategy of ``vr_path`` on
``phong`` (exponents 1, 10, 100, 1000), ``roughconductor`` (alpha 0.1) and
``roughdielectric`` (alpha 0.3, both sides) at incidence 0, 60 and 85 degrees,
drawn by the plugin's own ``integrators.path.sample_direction`` and checked
against its ``direction_pdf`` by a chi-square test; the integrand f cos and
the relative variance of the weight f cos / pdf beside it. Point sets
(:mod:`experiments.lib.studies.lab.points`): the points one pixel receives from every
sampler label of the sampler table (the sampler study's list, a ``--plugin``
sampler included) at 64 and 256 spp, driven as a render drives them; 2-D
projections, centered L2 discrepancy and radially averaged power spectra. Each
part is plan -> measure -> pure analysis (a conclusion table and at most three
sentences computed from it) -> report. Finished panels are cached under
OUT/lab/cache, so a rerun (or an interrupted run, rerun) only computes what is
missing. Screen-space error (:mod:`experiments.lib.screen_space`): each sampler's error
image (render minus reference, luminance) and its power spectrum at 4 and 16 spp side by
side, from the sampler study's screen-space renders (the first repeat): the lab declares the
same screen-space pass on the experiment engine (one repeat), so it reads them from the
job store where the sampler study made them and renders (and stores) only the missing ones.

    python -m experiments.lab --help
"""
from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from experiments.lib import cli, files, report, screen_space
from experiments.lib.figures import spectrum_panels
from experiments.lib.engine import Cell, Engine
from experiments.lib.methods import Method, parse_method, strategies as registered_strategies
from experiments.lib.study import Study, StudySettings
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies.lab import checks_report, figures, guide, mass, points, warps
from experiments.lib.studies.sampler_comparison import plan
from experiments.lib.studies.sampler_comparison.study import screen_samplers
from experiments.lib.studies.sampler_comparison.analysis import families
from experiments.lib.studies.sampler_comparison.screen import screen_floor

NAME = "lab"
ORDER = 35
SAMPLES = 250_000
QUICK_SAMPLES = 10_000


@dataclasses.dataclass(frozen=True)
class Config:
    """What one run of the lab computes."""
    bsdfs: tuple = warps.BSDFS
    incidences: tuple = warps.INCIDENCES
    samplers: tuple | None = None        # None: every label of the sampler table
    counts: tuple = points.COUNTS
    pixels: tuple = (8, 8)               # width, height of the point-set "render"
    strategies: tuple | None = None      # None: every registered strategy
    samples: int = SAMPLES               # directions per warp panel
    seed: int = 0
    #: screen-space error: the sampler study's renders (first repeat) at these settings
    screen_resolution: tuple = (128, 128)
    screen_counts: tuple = (4, 16)
    screen_depth: int = 2
    screen_samplers: tuple | None = None     # None: the sampler study's default labels
    screen_reference_spp: int = plan.SCREEN_REFERENCE_SPP
    #: the frozen guide's panels (:mod:`.lab.guide`): the scene it trains on (None: none), film,
    #: training spp, surface points
    guide_scene: str | None = guide.SCENE
    guide_film: tuple = guide.FILM
    guide_spp: int = guide.SPP
    guide_sites: int = guide.SITES

    def sampler_labels(self) -> list[str]:
        return list(self.samplers or points.samplers())

    def strategy_names(self) -> list[str]:
        return list(self.strategies or registered_strategies())

    def screen_labels(self) -> list[str]:
        return list(self.screen_samplers
                    or plan.default_screen_labels())


FULL = Config()
#: The screen-space part of --quick matches the sampler study's quick screen-space pass,
#: so that run_all's quick run renders it once.
QUICK = Config(bsdfs=(warps.BSDFS[1], warps.BSDFS[-1]), incidences=(60.0,),
               counts=(64,), pixels=(4, 4), samples=QUICK_SAMPLES, screen_resolution=(16, 8),
               screen_counts=(4,), screen_reference_spp=16, guide_film=(24, 18),
               guide_spp=64, guide_sites=1)


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.lab", __doc__.split("\n")[0],
                          default_resolution="64x32")
    p.add_argument("--samples", type=cli.positive_int, default=None,
                   help=f"directions per warp panel (default {SAMPLES}; {QUICK_SAMPLES} "
                        f"with --quick)")
    p.add_argument("--quick", action="store_true",
                   help="tiny run (for tests): two BSDFs at 60 degrees, every sampler at 64 "
                        "spp on 4x4 pixels, screen-space error at 16x8 and 4 spp")
    p.add_argument("--screen-samplers", type=screen_samplers,
                   default=None,
                   help="samplers of the screen-space error images: 'default' (the sampler "
                        "study's default screen-space labels), 'all' or comma-separated "
                        "labels")
    return p


@dataclasses.dataclass(frozen=True)
class Settings:
    """What one run of the lab does (typed; the Namespace stays in :func:`run`)."""
    config: Config                # what it computes
    out: str                      # the results folder
    reference: Method             # the screen-space reference's method
    variant: str
    quick: bool


def settings_of(args) -> Settings:
    base = QUICK if args.quick else FULL
    samples = base.samples if args.samples is None else args.samples
    config = dataclasses.replace(base, samples=samples, seed=args.seed,
                                 screen_samplers=args.screen_samplers)
    return Settings(config, args.out, args.reference_method, args.variant, args.quick)


def slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label)


# ------------------------------------------------------------------ warps

@dataclasses.dataclass(frozen=True)
class WarpsMeasured:
    specs: list                  # warps.PanelSpec, in plan order
    panels: dict                 # {spec key: panel}
    rows: list                   # one dict per panel (the warps table)


def plan_warps(cfg: Config) -> list:
    return warps.plan(cfg.strategy_names(), cfg.samples, cfg.seed, cfg.bsdfs,
                          cfg.incidences)


def measure_warps(specs: list, cache: str) -> WarpsMeasured:
    panels = {spec.key(): warps.cached(spec, cache) for spec in specs}
    rows = [{"bsdf": spec.bsdf_label, "incidence_deg": spec.incidence_deg,
             "strategy": spec.strategy, "samples": spec.samples, "seed": spec.seed,
             "grid": warps.domain_for(spec).describe(),
             **{k: panels[spec.key()][k] for k in warps.SCALARS}} for spec in specs]
    return WarpsMeasured(specs, panels, rows)


WARP_HEADER = ["bsdf", "incidence_deg", "strategy", "samples", "seed", "grid", "p_value",
               "chi2", "dof", "rel_variance", "albedo", "drawn", "in_grid", "max_weight",
               "max_z"]


def report_warps(out: str, cfg: Config, m: WarpsMeasured, found: warps.Findings) -> list:
    out_dir = os.path.join(out, NAME)
    strategies = list(dict.fromkeys(s.strategy for s in m.specs))
    blocks = []
    for label, _ in cfg.bsdfs:
        mine = [s for s in m.specs if s.bsdf_label == label]
        stem = "warps_" + slug(label)
        tiles = [(f"{s.strategy:8s} {s.incidence_deg:4g}°  p={m.panels[s.key()]['p_value']:.2g}"
                  f"\nVar/E²={m.panels[s.key()]['rel_variance']:.3g}", m.panels[s.key()])
                 for s in mine]
        figures.warp_mosaic(os.path.join(out_dir, stem + ".png"),
                                f"{label}: vr_path strategies", tiles)
        blocks.append(report.image(
            f"{NAME}/{stem}.png",
            f"{label}, {warps.domain_for(mine[0]).describe()} (x: azimuth, the whole "
            f"sphere with the mirror direction's azimuth in the middle; y: cosine, the normal "
            f"or the lobe axis at the top): per row one strategy at one incidence; left to "
            f"right the first {mine[0].scatter} drawn directions, the histogram of {cfg.samples} "
            f"directions, the strategy's density integrated over the same cells (both as "
            f"(value/max)^{figures.GAMMA:g}), their difference as a z-score (blue: too "
            f"few samples, red: too many; ±{figures.Z_RANGE:g} at full colour) and the "
            f"integrand f·cos."))
    rows = m.rows
    configs = list(dict.fromkeys((r["bsdf"], r["incidence_deg"]) for r in rows))
    values = np.array([[next(r["rel_variance"] for r in rows if (r["bsdf"], r["incidence_deg"])
                             == c and r["strategy"] == s) for s in strategies] for c in configs])
    figures.rel_variance_chart(os.path.join(out_dir, "rel_variance.png"),
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
        out, f"{NAME}/warps_conclusion", warps.HEADER, [r.cells() for r in found.rows],
        f"Warps, per strategy over {found.configurations} configurations: chi-square "
        f"rejections at 1% (Sidak over the panels: p < {found.alpha:.1e}), the lowest "
        f"p-value, where Var[w]/E[w]^2 exceeds {warps.EXPLODES:g}, and in how many "
        f"configurations the strategy's Var[w]/E[w]^2 is the lowest"),
        report.text("\n\n".join(found.sentences))]
    return blocks


def guide_config(cfg: Config) -> guide.GuideConfig | None:
    """The frozen guide's settings (the lab's samples per panel and seed), or None."""
    if not cfg.guide_scene:
        return None
    scene = cfg.guide_scene
    if not os.path.isabs(scene):
        scene = os.path.join(os.path.dirname(os.path.abspath(guide.__file__)), "..", "..", "..",
                             "..", scene)
    return guide.GuideConfig(os.path.normpath(scene), cfg.guide_film[0], cfg.guide_film[1],
                                 cfg.guide_spp, cfg.seed, cfg.guide_sites, cfg.samples)


def report_guide(out: str, gcfg: guide.GuideConfig, m: guide.Measured) -> list:
    """The frozen guide's mosaic (the warp panels' five tiles per surface point)."""
    out_dir = os.path.join(out, NAME)
    if not m.specs:
        return [report.text(f"{gcfg.label()}: no surface point to check (no camera ray "
                            f"hit a BSDF without a Dirac lobe).")]
    tiles = [(f"{s.bsdf_label}\n{s.incidence_deg:g}°  p={m.panels[s.key()]['p_value']:.2g}  "
              f"Var/E²={m.panels[s.key()]['rel_variance']:.3g}", m.panels[s.key()])
             for s in m.specs]
    figures.warp_mosaic(os.path.join(out_dir, "warps_frozen_guide.png"),
                            f"{gcfg.label()}: the trained strategy at scene points", tiles)
    how = ("read from the lab's cache" if m.cached else
           f"trained in {m.train_seconds:.1f} s, panels computed in "
           f"{m.seconds - m.train_seconds:.1f} s")
    return [report.image(
        f"{NAME}/warps_frozen_guide.png",
        f"{gcfg.label()}: a guide trained by vr_guided_path ({gcfg.method}, {gcfg.spp} spp at "
        f"{gcfg.width}x{gcfg.height}; {how}), frozen, and its strategy (the learned "
        f"histograms and BSDF shares) checked as a warp at the first hits of the camera rays "
        f"of {len(m.specs)} pixels (the learned units the guide is used most in), with the "
        f"scene's BSDF there and the camera direction as the incident one: the same tiles, "
        f"chi-square, mass and albedo checks as the other panels (the whole local sphere, "
        f"the shading normal up). Its rows join the warps' conclusion and the mass and "
        f"albedo checks below, each point a configuration of its own."),
        report.write_table(
            out, f"{NAME}/frozen_guide", WARP_HEADER,
            [[r[h] if not isinstance(r[h], float) else float(f"{r[h]:.6g}") for h in WARP_HEADER]
             for r in m.rows], f"The frozen guide's panels (p_value: chi-square test of the "
                               f"histogram against the strategy's density; grid "
                               f"{warps.PanelSpec.res} x {warps.PanelSpec.res} cells, "
                               f"{gcfg.ires} x {gcfg.ires} points per cell)")]


# ------------------------------------------------------------- point sets

@dataclasses.dataclass(frozen=True)
class PointsMeasured:
    names: list                  # sampler labels, in order
    results: dict                # {(spp, label): points.compute's dict}
    cd: dict                     # {(spp, label, pair): mean squared CD over pixels}
    joint: dict                  # {(spp, label, pair): joint low-frequency power}
    counts: dict                 # {spp: {label: points drawn}}


def plan_points(cfg: Config) -> list:
    width, height = cfg.pixels
    return [points.PointSpec(name, spp, seeds=(cfg.seed,), width=width, height=height)
            for spp in cfg.counts for name in cfg.sampler_labels()]


def measure_points(specs: list, cache: str) -> PointsMeasured:
    results, cd, joint, counts = {}, {}, {}, {}
    for spec in specs:
        res = results[(spec.spp, spec.sampler)] = points.cached(spec, cache)
        counts.setdefault(spec.spp, {})[spec.sampler] = int(res["count"])
        for a, b in points.PAIRS:
            cd[(spec.spp, spec.sampler, (a, b))] = float(np.mean(res[f"cd_{a}_{b}"]))
            joint[(spec.spp, spec.sampler, (a, b))] = float(res[f"joint_{a}_{b}"])
    names = list(dict.fromkeys(s.sampler for s in specs))
    return PointsMeasured(names, results, cd, joint, counts)


def analyse_points(m: PointsMeasured, spp: int) -> points.Findings:
    """The conclusion at ``spp`` requested (pure, from the measured numbers)."""
    at = {(n, p): v for (s, n, p), v in m.cd.items() if s == spp}
    joint = {(n, p): v for (s, n, p), v in m.joint.items() if s == spp}
    return points.analyse(at, joint, m.counts[spp], spp, families(m.names))


def report_points(out: str, cfg: Config, m: PointsMeasured,
                  found: points.Findings) -> list:
    out_dir = os.path.join(out, NAME)
    width, height = cfg.pixels
    names, rows, blocks = m.names, [], []
    for spp in cfg.counts:
        scatter, power, counts = {}, {}, m.counts[spp]
        for name in names:
            res = m.results[(spp, name)]
            for a, b in points.PAIRS:
                tag = f"{a}_{b}"
                scatter[(name, (a, b))] = res[f"scatter_{tag}"]
                power[(name, (a, b))] = (res["freqs"], res[f"power_{tag}"])
                cd = res[f"cd_{tag}"]
                expected = points.random_expectation(counts[name])
                rows.append([name, spp, counts[name], f"({a},{b})",
                             points.describe_pair(a, b),
                             float(f"{np.mean(cd):.6g}"), float(f"{np.std(cd):.3g}"),
                             float(f"{np.mean(cd) / expected:.4g}"),
                             float(f"{float(res[f'joint_{tag}']):.4g}"), len(cd)])
        figures.point_grid(os.path.join(out_dir, f"points_{spp}.png"),
                               f"One pixel's points at {spp} spp requested (vr_path bsdf+nee "
                               f"order)", names, list(points.PAIRS), scatter, counts)
        spectrum_points = points.PointSpec('', 0).spectrum_points
        figures.spectra(os.path.join(out_dir, f"spectrum_{spp}.png"),
                            f"Radially averaged power spectrum at {spp} spp, mean over "
                            f"{min(width * height, max(8, spectrum_points // spp))} pixels",
                            names, list(points.PAIRS), power, counts)
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
    header = ["sampler", "count"] + [f"({a},{b})" for a, b in points.PAIRS]
    wide = [[n, m.counts[spp][n]] + [f"{m.cd[(spp, n, p)]:.3g}" for p in points.PAIRS]
            for n in names]
    wide.append(["(independent points, expected)", ""] + [
        f"{points.random_expectation(spp):.3g}" for _ in points.PAIRS])
    blocks += [
        report.write_table(out, f"{NAME}/discrepancy_{spp}", header, wide,
                           f"discrepancy_cd (squared centered L2) at {spp} spp requested, "
                           f"mean over pixels; columns: dimension pairs"),
        report.write_table(
            out, f"{NAME}/points_conclusion", points.HEADER,
            [r.cells() for r in found.rows],
            f"Point sets at {spp} spp requested: the pairs each sampler stratifies jointly "
            f"(discrepancy below {points.LOST} of independent points' and joint "
            f"low-frequency power below {points.JOINT}), only per coordinate, or not at "
            f"all"),
        report.text("\n\n".join(found.sentences))]
    return blocks


# ------------------------------------------------------------- screen space

@dataclasses.dataclass(frozen=True)
class ScreenMeasured:
    labels: list
    counts: tuple
    fields: dict                 # {(label, count): (H, W) luminance error, mean subtracted}
    spectra: dict                # {(label, count): periodogram / its mean (white noise 1)}
    radial: dict                 # {(label, count): (frequencies, radially averaged power)}
    shares: dict                 # {(label, count): low-frequency share}
    rendered: dict               # {(label, count): spp rendered}
    found: int                   # of the renders, found in the store before the lab ran
    total: int


def plan_screen(engine: Engine, cfg: Config, reference) -> plan.Planned:
    """The sampler study's screen-space declaration at ``cfg``'s settings, one repeat (the
    same jobs as the study's first repeat: :func:`.sampler_comparison.plan.declare_screen`)."""
    st, labels, depth = engine.study, cfg.screen_labels(), cfg.screen_depth
    screen = plan.ScreenSettings(
        tuple(cfg.screen_resolution), tuple(cfg.screen_counts), (depth,), tuple(labels), 1,
        cfg.screen_reference_spp, reference)
    study = plan.Settings(
        parse_method(plan.BASE), (depth,), (), tuple(labels), st.depth,
        st.info.path, (st.width, st.height), screen)
    return plan.plan(
        engine, plan.declare_screen(study, screen, st.info))


def measure_screen(engine: Engine, cfg: Config,
                   planned: plan.Planned) -> ScreenMeasured:
    """Render what the stores lack (the engine), then each render's error field and
    spectrum."""
    st, decl = engine.study, planned.declaration
    refs, renders = [j for chunks in planned.refs.values() for j in chunks], planned.renders()
    found = sum(st.store.has(j.key) for j in refs + renders)
    references = engine.references(decl)
    st.run(renders, f"{NAME}: screen-space renders")
    measured = engine.measure(decl, planned.cells, references)
    (scene, ref_jobs), = planned.refs.items()
    ref = references[scene][0]
    floor = screen_floor(st, ref_jobs)
    fields, spectra, radial, shares, rendered = {}, {}, {}, {}, {}
    labels = cfg.screen_labels()
    for label, method in zip(labels, decl.methods):
        for budget, count in zip(decl.budgets, cfg.screen_counts):
            run = measured.runs[Cell(scene[0], method.name, budget.name)][0][-1]
            field = screen_space.error_field(run.image, ref)
            power = screen_space.periodogram(field)
            key = (label, count)
            fields[key] = field
            spectra[key] = screen_space.normalized(power, floor)
            radial[key] = screen_space.spectrum(spectra[key])
            shares[key] = screen_space.low_share(power, floor)
            rendered[key] = run.spp
    return ScreenMeasured(labels, tuple(cfg.screen_counts), fields, spectra, radial, shares,
                          rendered, found, len(refs) + len(renders))


def screen_source(m: ScreenMeasured) -> str:
    """Where the renders came from."""
    if m.found == m.total:
        return (f"all {m.total} renders found in the job store (the sampler study's "
                f"screen-space jobs)")
    if m.found == 0:
        return (f"all {m.total} renders made by the lab (the sampler study's screen-space "
                f"jobs, stored for it to reuse)")
    return (f"{m.found} of {m.total} renders found in the job store (the sampler study's "
            f"screen-space jobs), {m.total - m.found} made by the lab")


def report_screen(out: str, cfg: Config, m: ScreenMeasured) -> list:
    out_dir = os.path.join(out, NAME)
    width, height = cfg.screen_resolution
    by_count = {c: figures.error_tiles([m.fields[(s, c)] for s in m.labels],
                                           [m.spectra[(s, c)] for s in m.labels])
                for c in m.counts}
    tiles = [[t for c in m.counts for t in by_count[c][r]] for r in range(len(m.labels))]
    columns = [f"{what}, {c} spp" for c in m.counts for what in ("error", "spectrum")]
    figures.error_mosaic(os.path.join(out_dir, "screen_errors.png"),
                             f"Error images and their power spectra, {width}x{height}, "
                             f"max_depth {cfg.screen_depth}", m.labels, columns, tiles)
    spectrum_panels(os.path.join(out_dir, "screen_spectra.png"),
                            {f"{c} spp requested": {s: m.radial[(s, c)] for s in m.labels}
                             for c in m.counts}, screen_space.LOW,
                            "Radially averaged power spectra of the error images above")
    rows = [[s, c, m.rendered[(s, c)], f"{m.shares[(s, c)]:.4g}"] for s in m.labels
            for c in m.counts]
    white = screen_space.white_share((height, width))
    return [
        report.image(f"{NAME}/screen_errors.png",
                     f"Per sampler: the error (render minus reference, luminance; red too "
                     f"bright, blue too dark, one scale per count) and its power spectrum "
                     f"(frequency 0 in the middle, the Nyquist frequency at the edges; log "
                     f"of the power over white noise's, smoothed over {figures.SMOOTH}x"
                     f"{figures.SMOOTH} bins; dark centre: blue noise) at "
                     f"{' and '.join(map(str, m.counts))} spp; {screen_source(m)}."),
        report.image(f"{NAME}/screen_spectra.png",
                     f"The same spectra radially averaged (white noise: 1); the low-"
                     f"frequency share is the power left of the dashed line. One render "
                     f"each: the sampler study gives intervals over repeats."),
        report.write_table(out, f"{NAME}/screen", ["sampler", "spp requested",
                                                   "spp rendered", "low-frequency share"],
                           rows, f"Low-frequency share of each error image above (one "
                                 f"render; white noise {white:.4f})")]


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
    settings = settings_of(args)
    cfg, out = settings.config, settings.out
    out_dir = os.path.join(out, NAME)
    warp_panels = measure_warps(plan_warps(cfg), os.path.join(out_dir, "cache", "warps"))
    gcfg = guide_config(cfg)
    frozen = (guide.measure(gcfg, os.path.join(out_dir, "cache", "warps"))
             if gcfg else None)
    rows = warp_panels.rows + (frozen.rows if frozen else [])
    warp_found, checks = warps.analyse(rows), mass.analyse(rows)
    warp_seconds = time.perf_counter() - start
    point_sets = measure_points(plan_points(cfg), os.path.join(out_dir, "cache", "points"))
    point_found = analyse_points(point_sets, cfg.counts[0])
    point_seconds = time.perf_counter() - start - warp_seconds
    engine = Engine(Study(StudySettings(**cli.common_fields(args))))
    screen = measure_screen(engine, cfg, plan_screen(engine, cfg, settings.reference))
    screen_seconds = time.perf_counter() - start - warp_seconds - point_seconds
    blocks = ([report.text(GUIDE)] + report_warps(out, cfg, warp_panels, warp_found)
              + (report_guide(out, gcfg, frozen) if frozen else [])
              + checks_report.report_checks(out, checks, [r["p_value"] for r in rows],
                                                warp_found.alpha)
              + report_points(out, cfg, point_sets, point_found)
              + report_screen(out, cfg, screen))
    described = {"samples per warp panel": cfg.samples, "seed": cfg.seed,
                "warp grid": f"{warps.PanelSpec.res} x {warps.PanelSpec.res} cells, "
                             f"{warps.PanelSpec.ires} x {warps.PanelSpec.ires} "
                             f"trapezoid points per cell",
                "BSDFs": "; ".join(label for label, _ in cfg.bsdfs),
                "incidences (deg)": ", ".join(f"{i:g}" for i in cfg.incidences),
                "point sets": f"{cfg.pixels[0]}x{cfg.pixels[1]} pixels, "
                              f"counts {', '.join(map(str, cfg.counts))} requested",
                "screen-space error": f"{cfg.screen_resolution[0]}x"
                                      f"{cfg.screen_resolution[1]}, max_depth "
                                      f"{cfg.screen_depth}, "
                                      f"{', '.join(map(str, cfg.screen_counts))} spp, "
                                      f"reference {cfg.screen_reference_spp} spp of "
                                      f"{settings.reference}; {screen_source(screen)}",
                "frozen guide": (f"{gcfg.label()}: {gcfg.method}, {gcfg.spp} spp at "
                                 f"{gcfg.width}x{gcfg.height}, {len(frozen.specs)} surface "
                                 f"points, training {frozen.train_seconds:.1f} s"
                                 + (" (panels cached)" if frozen.cached else "")
                                 if frozen else "none"),
                "variant": settings.variant, "quick": settings.quick,
                "wall time (s)": f"warps {warp_seconds:.1f}, point sets {point_seconds:.1f}, "
                                 f"screen space {screen_seconds:.1f} (panels and point sets "
                                 f"cached under {NAME}/cache/ are not recomputed; renders "
                                 f"come from the job store)"}
    report.write_section(out, NAME, "Sampling lab: strategies as warps, samplers as "
                         "point sets", ORDER, described, blocks, settings.variant,
                         time.perf_counter() - start)
    files.write_json(os.path.join(out_dir, "summary.json"), {
        "warps": warp_panels.rows, "frozen_guide": frozen.rows if frozen else [],
        "warp_conclusion": warp_found.sentences,
        "warp_table": [dataclasses.asdict(r) for r in warp_found.rows],
        "mass_albedo": {"z": checks.z, "tests": checks.tests, "sentences": checks_report
                        .sentences(checks), "panels": [dataclasses.asdict(r) for r in checks.rows]},
        "point_conclusion": point_found.sentences,
        "point_table": [dataclasses.asdict(r) for r in point_found.rows],
        "discrepancy": [{"spp": spp, "sampler": n, "pair": list(p), "discrepancy_cd": v}
                        for (spp, n, p), v in point_sets.cd.items()],
        "screen": {"source": screen_source(screen), "shares": [
            {"sampler": s, "spp": c, "spp_rendered": screen.rendered[(s, c)],
             "low_frequency_share": screen.shares[(s, c)]}
            for s in screen.labels for c in screen.counts]}})


STUDY = register_study(StudySpec(
    NAME, 'Sampling lab: strategies as warps, samplers as point sets', ORDER, build_parser, run,
    quick=("--quick",)))
