"""The lab's warps part: every strategy's panels and the frozen guide's, planned, measured
(or read from the cache) and reported.

Plan (:func:`plan_warps`: a :class:`.lab.warps.PanelSpec` per strategy, BSDF and
incidence) -> measure (:func:`measure_warps`: the panels, cached under OUT/lab/cache, and
one row of numbers per panel) -> the pure analyses (:func:`.lab.warps.analyse`,
:func:`.lab.mass.analyse`, run by :mod:`.lab.study` over these rows and the frozen guide's)
-> report (:func:`report_warps`: a mosaic per BSDF, the relative variance chart, the
tables and the conclusion; :func:`report_guide`: the frozen guide's mosaic and table).
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from experiments.lib import report
from experiments.lib.studies.lab import checks_report, figures, guide, mass, warps
from experiments.lib.studies.lab.config import NAME, Config


def slug(label: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in label)



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


def report_warps(out: str, cfg: Config, m: WarpsMeasured, found: warps.Findings,
                 checks: mass.Findings) -> list:
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
        out, f"{NAME}/warps_conclusion", [checks_report.VERDICT_HEADER] + warps.HEADER,
        [[checks_report.strategy_verdict(r.strategy, r.rejected, checks)] + r.cells()
         for r in found.rows],
        f"Warps, per strategy over {found.configurations} configurations: the verdict of "
        f"all three checks of every panel (the chi-square test, and the mass and albedo "
        f"checks of {NAME}/mass_albedo.csv), chi-square rejections at 1% (Sidak over the "
        f"panels: p < {found.alpha:.1e}), the lowest p-value, where Var[w]/E[w]^2 exceeds "
        f"{warps.EXPLODES:g}, and in how many configurations the strategy's Var[w]/E[w]^2 "
        f"is the lowest"),
        report.text("\n\n".join(found.sentences))]
    return blocks


def guide_config(cfg: Config) -> guide.GuideConfig | None:
    """The frozen guide's settings (the lab's samples per panel and seed), or None."""
    if not cfg.guide_scene:
        return None
    scene = cfg.guide_scene
    if not os.path.isabs(scene):            # relative to the checkout's root
        root = os.path.join(os.path.dirname(os.path.abspath(guide.__file__)), *[".."] * 4)
        scene = os.path.join(root, scene)
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

