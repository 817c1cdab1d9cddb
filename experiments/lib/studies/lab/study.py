"""Sampling lab: every vr_path strategy as a warp, and every sampler's point sets, measured.

Warps (:mod:`.lab.warps`, :mod:`.lab.warp_part`): each registered strategy of ``vr_path``
on ``phong`` (exponents 1, 10, 100, 1000), ``roughconductor`` (alpha 0.1) and
``roughdielectric`` (alpha 0.3, both sides) at incidence 0, 60 and 85 degrees,
drawn by the plugin's own ``integrators.path.sample_direction`` and checked
against its ``direction_pdf`` by a chi-square test; the integrand f cos and
the relative variance of the weight f cos / pdf beside it. Point sets
(:mod:`.lab.points`, :mod:`.lab.point_part`): the points one pixel receives from every
sampler label of the sampler table (the sampler study's list, a ``--plugin``
sampler included) at 64 and 256 spp, driven as a render drives them; 2-D
projections, centered L2 discrepancy and radially averaged power spectra. Each
part is plan -> measure -> pure analysis (a conclusion table and at most three
sentences computed from it) -> report. Finished panels are cached under
OUT/lab/cache, so a rerun (or an interrupted run, rerun) only computes what is
missing. Screen-space error (:mod:`.lab.screen_part`, :mod:`experiments.lib.screen_space`):
each sampler's error image (render minus reference, luminance) and its power spectrum at 4
and 16 spp side by side, from the sampler study's screen-space renders (the first repeat):
the lab declares the same screen-space pass on the experiment engine (one repeat), so it
reads them from the job store where the sampler study made them and renders (and stores)
only the missing ones.

This module is the entry point: the command line, :func:`settings_of` (the one place that
reads it), the three parts in turn (:func:`measure`), the report section and summary.json
made from what they measured, and the registration of the study as ``lab``.

    python -m experiments.lab --help
"""
from __future__ import annotations

import dataclasses
import os

from experiments.lib import cli, clock, files, report
from experiments.lib.engine import Engine
from experiments.lib.methods import Method
from experiments.lib.study import Study, StudySettings
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies.lab import (
    checks_report, guide, mass, point_part, points, screen_part, warp_part, warps)
from experiments.lib.studies.lab.config import FULL, NAME, QUICK, QUICK_SAMPLES, SAMPLES, Config
from experiments.lib.studies.sampler_comparison.study import screen_samplers

TITLE = "Sampling lab: strategies as warps, samplers as point sets"
ORDER = 35


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.lab", __doc__.split("\n")[0],
                          default_resolution="64x32")
    p.add_argument("--samples", type=cli.positive_int, default=None,
                   help=f"directions per warp panel (default {SAMPLES}; {QUICK_SAMPLES} "
                        f"with --quick)")
    p.add_argument("--quick", action="store_true",
                   help="tiny run (for tests): two BSDFs at 60 degrees, every sampler at 64 "
                        "spp on 4x4 pixels, screen-space error at 16x8 and 4 spp")
    p.add_argument("--screen-samplers", type=screen_samplers, default=None,
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

@dataclasses.dataclass(frozen=True)
class Measured:
    """What one run measured and concluded, part by part."""
    warp_panels: warp_part.WarpsMeasured
    guide_config: guide.GuideConfig | None     # None: no frozen guide
    frozen: guide.Measured | None              # the frozen guide's panels
    rows: list                                 # every warp panel's row, the guide's included
    warp_found: warps.Findings
    checks: mass.Findings
    point_sets: point_part.PointsMeasured
    point_found: points.Findings
    screen: screen_part.ScreenMeasured
    seconds: dict                              # wall time of each part: warps, points, screen


def measure(settings: Settings, common: StudySettings) -> Measured:
    """The three parts in turn, each planned, measured (or read from the lab's cache and
    the job store) and analysed: the warps with the frozen guide (one chi-square family,
    one family of mass and albedo checks), the point sets, the screen-space error."""
    cfg = settings.config
    cache = os.path.join(settings.out, NAME, "cache")
    timer = clock.Timer()
    with timer.part("warps"):
        warp_panels = warp_part.measure_warps(warp_part.plan_warps(cfg),
                                              os.path.join(cache, "warps"))
        gcfg = warp_part.guide_config(cfg)
        frozen = guide.measure(gcfg, os.path.join(cache, "warps")) if gcfg else None
        rows = warp_panels.rows + (frozen.rows if frozen else [])
        warp_found, checks = warps.analyse(rows), mass.analyse(rows)
    with timer.part("points"):
        point_sets = point_part.measure_points(point_part.plan_points(cfg),
                                               os.path.join(cache, "points"))
        point_found = point_part.analyse_points(point_sets, cfg.counts[0])
    with timer.part("screen"):
        engine = Engine(Study(common))
        screen = screen_part.measure_screen(
            engine, cfg, screen_part.plan_screen(engine, cfg, settings.reference))
    seconds = {part: timer.seconds(part) for part in ("warps", "points", "screen")}
    return Measured(warp_panels, gcfg, frozen, rows, warp_found, checks, point_sets,
                    point_found, screen, seconds)


def blocks_of(settings: Settings, m: Measured) -> list:
    """The section's blocks: the reading guide, then each part's figures, tables and
    sentences (writing their files)."""
    cfg, out = settings.config, settings.out
    return ([report.text(GUIDE)]
            + warp_part.report_warps(out, cfg, m.warp_panels, m.warp_found, m.checks)
            + (warp_part.report_guide(out, m.guide_config, m.frozen) if m.frozen else [])
            + checks_report.report_checks(out, m.checks, [r["p_value"] for r in m.rows],
                                          m.warp_found.alpha)
            + point_part.report_points(out, cfg, m.point_sets, m.point_found)
            + screen_part.report_screen(out, cfg, m.screen))


def described(settings: Settings, m: Measured) -> dict:
    """The section's settings table."""
    cfg, gcfg, frozen = settings.config, m.guide_config, m.frozen
    return {"samples per warp panel": cfg.samples, "seed": cfg.seed,
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
                                  f"{settings.reference}; "
                                  f"{screen_part.screen_source(m.screen)}",
            "frozen guide": (f"{gcfg.label()}: {gcfg.method}, {gcfg.spp} spp at "
                             f"{gcfg.width}x{gcfg.height}, {len(frozen.specs)} surface "
                             f"points, training {frozen.train_seconds:.1f} s"
                             + (" (panels cached)" if frozen.cached else "")
                             if frozen else "none"),
            "variant": settings.variant, "quick": settings.quick,
            "wall time (s)": f"warps {m.seconds['warps']:.1f}, point sets "
                             f"{m.seconds['points']:.1f}, screen space "
                             f"{m.seconds['screen']:.1f} (panels and point sets "
                             f"cached under {NAME}/cache/ are not recomputed; renders "
                             f"come from the job store)"}


def summary_of(m: Measured) -> dict:
    """summary.json: every part's numbers, tables and sentences."""
    checks, screen = m.checks, m.screen
    return {
        "warps": m.warp_panels.rows, "frozen_guide": m.frozen.rows if m.frozen else [],
        "warp_conclusion": m.warp_found.sentences,
        "warp_table": [dataclasses.asdict(r) for r in m.warp_found.rows],
        "mass_albedo": {"z": checks.z, "tests": checks.tests,
                        "sentences": checks_report.sentences(checks),
                        "panels": [dataclasses.asdict(r) for r in checks.rows]},
        "point_conclusion": m.point_found.sentences,
        "point_table": [dataclasses.asdict(r) for r in m.point_found.rows],
        "discrepancy": [{"spp": spp, "sampler": n, "pair": list(p), "discrepancy_cd": v}
                        for (spp, n, p), v in m.point_sets.cd.items()],
        "screen": {"source": screen_part.screen_source(screen), "shares": [
            {"sampler": s, "spp": c, "spp_rendered": screen.rendered[(s, c)],
             "low_frequency_share": screen.shares[(s, c)]}
            for s in screen.labels for c in screen.counts]}}


def run(args) -> None:
    timer = clock.Timer()
    settings = settings_of(args)
    m = measure(settings, StudySettings(**cli.common_fields(args)))
    blocks = blocks_of(settings, m)
    report.write_section(settings.out, NAME, TITLE, ORDER, described(settings, m), blocks,
                         settings.variant, timer.elapsed())
    files.write_json(os.path.join(settings.out, NAME, "summary.json"), summary_of(m))


STUDY = register_study(StudySpec(NAME, TITLE, ORDER, build_parser, run, quick=("--quick",)))
