"""The sampler study's screen-space pass: FLIP, the error's power spectrum and MSE efficiency.

On a larger image (:class:`.sampler_comparison.plan.ScreenSettings`), at every count of a
short ladder: declared on the engine (:func:`.sampler_comparison.plan.declare_screen`;
renders grouped so that a process keeps their methods warm), measured from the engine's
runs (per repeat: mean FLIP, the error's periodogram and its low-frequency share with the
reference's floor subtracted, MSE, relMSE and cost), the pure analysis
(:mod:`.sampler_comparison.screen_analysis`) and the report: the FLIP and spectrum charts,
each depth's conclusion table and sentences, the table of every label and count.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from experiments.lib import figures, metrics, report, screen_space, stats
from experiments.lib.engine import Cell, Declaration, Measurements
from experiments.lib.jobs import Job
from experiments.lib.study import Study
from experiments.lib.studies.sampler_comparison.analysis import families
from experiments.lib.studies.sampler_comparison.efficiency import interval_header, point
from experiments.lib.studies.sampler_comparison import words
from experiments.lib.studies.sampler_comparison.plan import (
    NAME, PassReport, Planned, Settings, declare_screen, default_screen_labels)
from experiments.lib.studies.sampler_comparison.screen_analysis import (
    SCREEN_HEADER, ScreenAnalysis, ScreenPoint, ScreenRow, analyse_screen)


@dataclass(frozen=True)
class ScreenMeasured:
    points: dict                  # {depth: {label: [ScreenPoint per count]}}
    floors: dict                  # {depth: the reference's metadata, spectrum floor included}
    pixels: int
    kinds: dict                   # {label: Family}
    white: float                  # the low-frequency share of white noise on the grid


def screen_floor(st: Study, refs: list[Job]) -> float:
    """The white power the reference's own noise adds to an error spectrum
    (:func:`.screen_space.reference_floor` of its chunks)."""
    chunks = st.results(refs)
    return screen_space.reference_floor([r.image for r in chunks], [r.spp for r in chunks])


def _replicate(values, n: int) -> tuple:
    """A deterministic label's one value stands for every repeat."""
    values = tuple(values)
    return values * n if len(values) == 1 else values


class ScreenSpace:
    """FLIP, the error's power spectrum and MSE efficiency on a larger image
    (:class:`ScreenSettings`), at every count of a short ladder."""
    name = "screen"

    def declare(self, st: Study, cfg: Settings) -> Declaration | None:
        return None if cfg.screen is None else declare_screen(cfg, cfg.screen, st.info)

    def measure(self, st: Study, cfg: Settings, planned: Planned,
                measurements: Measurements) -> ScreenMeasured:
        """Per repeat: FLIP, the error's periodogram (its low-frequency share, the
        reference's floor subtracted), MSE, relMSE and cost (the engine's runs); spectra
        averaged over the repeats rendered."""
        sc, decl = cfg.screen, planned.declaration
        points, floors = {}, {}
        for d, scene in zip(sc.depths, decl.scenes):
            ref, meta = measurements.references[(scene.name, None)]
            floor = screen_floor(st, planned.refs[(scene.name, None)])
            floors[d] = dict(meta, spectrum_floor=floor)
            points[d] = {}
            for s, m in zip(sc.samplers, decl.methods):
                pts = []
                for budget in decl.budgets:
                    cell = Cell(scene.name, m.name, budget.name)
                    runs = measurements.final(cell)
                    rendered = runs[:len(planned.cells[budget.name][cell])]
                    pts.append(screen_point(runs, rendered, ref, floor, meta, budget.spp))
                points[d][s] = pts
        width, height = sc.resolution
        return ScreenMeasured(points, floors, width * height, families(sc.samplers),
                              screen_space.white_share((height, width)))

    def analyse(self, measured: ScreenMeasured) -> ScreenAnalysis:
        return analyse_screen(measured.points, measured.pixels, measured.kinds,
                                 measured.white)

    def report(self, st: Study, cfg: Settings, planned: Planned, measured: ScreenMeasured,
               result: ScreenAnalysis) -> PassReport:
        """The introduction, per depth the charts, conclusion table and sentences, then the
        tables of every label and count."""
        conclusions = words.screen_conclusions(result)
        blocks = [report.text(screen_introduction(cfg, measured))]
        for d in measured.points:
            blocks += depth_blocks(st, cfg, measured, result, conclusions[d], d)
        blocks += screen_tables(st.out, cfg, measured, result)
        return PassReport(blocks, screen_summary(cfg, measured, result, conclusions),
                          planned.renders())


def depth_blocks(st: Study, cfg: Settings, measured: ScreenMeasured, result: ScreenAnalysis,
                 sentences: list, d: int) -> list:
    """At max_depth ``d``: the FLIP chart, the spectra, the conclusion table and its
    sentences."""
    sc, out, by_sampler = cfg.screen, st.out, measured.points[d]
    width, height = sc.resolution
    curves = {s: [(p.spp, p.mean_flip()) for p in pts] for s, pts in by_sampler.items()}
    figures.estimate_lines(os.path.join(out, NAME, f"screen_flip_depth{d}.png"),
                           curves, "samples per pixel (rendered)", "mean FLIP",
                           f"max_depth {d}, {width}x{height}: mean FLIP against the "
                           f"reference")
    shown = spectrum_counts(sc.counts)
    panels = {f"{n} spp requested": {s: (pts[sc.counts.index(n)].frequencies,
                                         pts[sc.counts.index(n)].power)
                                     for s, pts in by_sampler.items()} for n in shown}
    figures.spectrum_panels(os.path.join(out, NAME, f"screen_spectra_depth{d}.png"),
                            panels, screen_space.LOW, f"max_depth {d}: radially "
                            f"averaged power spectrum of the luminance error, mean "
                            f"over the repeats")
    return [
        report.image(f"{NAME}/screen_flip_depth{d}.png",
                     f"max_depth {d}: mean FLIP against spp per sampler at "
                     f"{width}x{height}, with {stats.LEVEL:.0%} bands over the "
                     f"repeats (lower is better); reference: "
                     f"{st.describe_reference(measured.floors[d])}."),
        report.image(f"{NAME}/screen_spectra_depth{d}.png",
                     f"max_depth {d}: power spectrum of the error (render minus "
                     f"reference, luminance, mean subtracted; the reference's white "
                     f"noise subtracted), relative to its mean (white noise: 1), at "
                     f"{' and '.join(map(str, shown))} spp. Dashed: "
                     f"{screen_space.LOW} cycles per pixel, below which the "
                     f"low-frequency share is taken."),
        report.write_table(out, f"{NAME}/screen_conclusion_depth{d}",
                           SCREEN_HEADER,
                           [c.cells() for c in result.comparisons if c.depth == d],
                           f"Screen-space conclusion at max_depth {d}: each bundled "
                           f"sampler's best (lowest FLIP) against every native "
                           f"sampler and the other bundled ones, at every count; "
                           f"ratios A / B with {stats.LEVEL:.0%} intervals; a verdict "
                           f"only where the interval excludes 1, in FLIP only "
                           f"between equal counts rendered"),
        report.text("\n\n".join(sentences))]


def screen_tables(out: str, cfg: Settings, measured: ScreenMeasured,
                  result: ScreenAnalysis) -> list:
    """The table of every label and count, and the spectra as numbers."""
    width, height = cfg.screen.resolution
    header = (["max_depth", "sampler", "spp rendered", "spp requested", "repeats"]
              + interval_header("mean FLIP") + interval_header("low-frequency share")
              + interval_header("MSE") + ["µs / sample"])
    return [
        report.write_table(out, f"{NAME}/screen_space", header, screen_table_rows(
            result.rows), f"Every sampler and count of the screen-space pass at "
            f"{width}x{height} (means over the repeats, {stats.LEVEL:.0%} intervals; "
            f"low-frequency share of white noise on this grid: {result.white:.4f})"),
        report.write_table(out, f"{NAME}/screen_spectra",
                           ["max_depth", "sampler", "spp rendered", "frequency (cycles "
                            "per pixel)", "power / mean"],
                           [[d, s, p.spp, f"{f:.5g}", f"{v:.4g}"]
                            for d, by in measured.points.items() for s, pts in by.items()
                            for p in pts for f, v in zip(p.frequencies, p.power)],
                           "Radially averaged error spectra (white noise: 1)",
                           collapsed=True)]


def screen_summary(cfg: Settings, measured: ScreenMeasured, result: ScreenAnalysis,
                   conclusions: dict) -> dict:
    """The pass's part of summary.json."""
    sc = cfg.screen
    width, height = sc.resolution
    return {"screen": {
        "resolution": f"{width}x{height}", "counts": list(sc.counts),
        "depths": list(sc.depths), "samplers": list(sc.samplers),
        "repeats": sc.repeats, "reference_spp": sc.reference_spp,
        "white_share": result.white, "low_frequency_cutoff": screen_space.LOW,
        "spectrum_floor": {d: f["spectrum_floor"] for d, f in measured.floors.items()},
        "rows": [r.record() for r in result.rows],
        "comparisons": [c.record() for c in result.comparisons],
        "conclusion": conclusions}}


def screen_point(runs: list, rendered: list, ref, floor: float, meta: dict,
                 requested: int) -> ScreenPoint:
    """A label at one count: FLIP and the low-frequency share of each render (``rendered``:
    the distinct runs, one for a deterministic label, standing for every repeat of
    ``runs``), their mean spectrum, and the :class:`Point` of errors and costs."""
    repeats = len(runs)
    powers = [screen_space.periodogram(screen_space.error_field(r.image, ref))
              for r in rendered]
    freqs, power = screen_space.spectrum(screen_space.normalized(np.mean(powers, axis=0),
                                                                 floor))
    return ScreenPoint(
        runs[0].spp,
        _replicate((metrics.flip_mean(r.image, ref) for r in rendered), repeats),
        _replicate((screen_space.low_share(p, floor) for p in powers), repeats),
        point(runs, requested, meta), tuple(float(f) for f in freqs),
        tuple(float(v) for v in power), requested)


def spectrum_counts(counts) -> list[int]:
    """The counts whose spectra are drawn: 4 and 16 where rendered, else the last two."""
    shown = [n for n in (4, 16) if n in counts]
    return shown or list(counts[-2:])


def screen_table_rows(rows: list[ScreenRow]) -> list[list]:
    def cells(e):
        return [f"< {stats.g(e.hi)}", "0", stats.g(e.hi)] if e.bound else e.cells()
    return [[r.depth, r.sampler, r.spp, r.requested, r.repeats, *r.flip.cells(),
             *r.share.cells(), *cells(r.mse), f"{r.us_per_sample:.3f}"] for r in rows]


def screen_introduction(cfg: Settings, m: ScreenMeasured) -> str:
    """Two paragraphs of at most 80 words: what the pass renders, what it measures."""
    sc = cfg.screen
    width, height = sc.resolution
    subset = (" (the default subset: the baseline, the native samplers with the lowest FLIP "
              "in the zsobol calibration, each other sampler's last randomization; FLIP "
              "at this size is costly)" if sc.samplers == tuple(default_screen_labels())
              else "")
    return (f"Screen-space pass: {', '.join(sc.samplers)}{subset} at {width}x{height}, "
            f"max_depth {', '.join(map(str, sc.depths))}, {', '.join(map(str, sc.counts))} "
            f"spp, {sc.repeats} repeats, against {sc.reference_spp} spp of {sc.reference}."
            f"\n\nPer count: mean FLIP, the low-frequency share of the error's power (below "
            f"{screen_space.LOW} cycles per pixel; white noise {m.white:.3f}) with the "
            f"reference's own white noise subtracted, and MSE efficiency. FLIP is not "
            f"corrected for the reference's noise, which pulls every FLIP ratio towards 1.")
