"""The sampler study's efficiency pass: every label over the ladder, at every depth.

Declared on the engine (:func:`.sampler_comparison.plan.declare`; the engine interleaves the renders so
that drifting machine load affects every sampler alike), measured (the engine's per-repeat
costs and errors against each depth's reference, as :class:`Point` values), the pure
analysis (:mod:`.sampler_comparison.analysis`) and the report: the error and efficiency
charts, the viewer, the table of every label, the efficiency along the ladder and each
depth's conclusion table and sentences.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

from experiments.lib import figures, files, report, stats
from experiments.lib.engine import Cell, Declaration, Measurements
from experiments.lib.study import Study
from experiments.lib.studies.sampler_comparison.analysis import (
    BASELINE, COMPARISON_HEADER, METRIC, METRIC_NAMES, Analysis, Point, Row, analyse,
    families)
from experiments.lib.studies.sampler_comparison import words
from experiments.lib.studies.sampler_comparison.plan import (
    NAME, PassReport, Planned, Settings, declare)


@dataclass(frozen=True)
class Measured:
    points: dict                  # {depth: {label: [Point per count]}}
    floors: dict                  # {depth: the reference's metadata}
    pixels: int
    kinds: dict                   # {label: Family}
    images: dict                  # {depth: {label: the first repeat's image at the last count}}
    references: dict              # {depth: the reference image}


def interval_header(name: str) -> list[str]:
    return [name, f"{name}_lo", f"{name}_hi"]


#: The error every efficiency (and so every verdict) uses, as the tables name it.
EFFICIENCY = f"efficiency 1/({METRIC_NAMES[METRIC]} x time) / {BASELINE}"
TABLE_HEADER = (["max_depth", "sampler", "spp rendered", "spp requested", "repeats"]
                + interval_header("MSE") + interval_header("relMSE") + ["µs / sample"]
                + interval_header(f"MSE / {BASELINE}") + interval_header(f"relMSE / {BASELINE}")
                + interval_header(EFFICIENCY) + ["MSE slope"])


def table_rows(rows: list[Row]) -> list[list]:
    """Errors below the reference's own noise are bounds: their cells read '< x'."""
    def cells(e):
        return [f"< {stats.g(e.hi)}", "0", stats.g(e.hi)] if e.bound else e.cells()
    return [[r.depth, r.sampler, r.spp, r.requested, r.repeats, *cells(r.mse),
             *cells(r.relmse), f"{r.us_per_sample:.3f}", *cells(r.relative_mse),
             *cells(r.relative_relmse), *r.relative_efficiency.cells(),
             f"{r.slope:.2f}"] for r in rows]


def curve_rows(curves: dict) -> list[list]:
    return [[d, s, i, spp, *e.cells()]
            for d, by_sampler in curves.items() for s, pts in by_sampler.items()
            for i, (spp, e) in enumerate(pts)]


class Efficiency:
    """Errors and render times of every label over the ladder, at every depth."""
    name = "efficiency"

    def declare(self, st: Study, cfg: Settings) -> Declaration:
        return declare(cfg, st.info, st.repeats)

    def measure(self, st: Study, cfg: Settings, planned: Planned,
                measured: Measurements) -> Measured:
        """Per-repeat costs and errors against each depth's reference (the engine's runs; a
        deterministic label's one run stands for every repeat)."""
        points, floors, images, refs = {}, {}, {}, {}
        decl = planned.declaration
        for d, scene in zip(cfg.depths, decl.scenes):
            refs[d], floors[d] = measured.references[(scene.name, None)]
            points[d], images[d] = {}, {}
            for s, m in zip(cfg.samplers, decl.methods):
                cells = [Cell(scene.name, m.name, b.name) for b in decl.budgets]
                points[d][s] = [point(measured.final(c), b.spp, floors[d])
                                for c, b in zip(cells, decl.budgets)]
                images[d][s] = measured.runs[cells[-1]][0][-1].image
        return Measured(points, floors, st.width * st.height, families(cfg.samplers), images,
                        refs)

    def analyse(self, measured: Measured) -> Analysis:
        return analyse(measured.points, measured.pixels, measured.kinds)

    def report(self, st: Study, cfg: Settings, planned: Planned, measured: Measured,
               result: Analysis) -> PassReport:
        """Per depth the charts and the viewer, then the tables of every label, then per
        depth the conclusion table and its sentences."""
        conclusions = words.conclusions(result)
        blocks = []
        for d in measured.points:
            blocks += depth_charts(st, cfg, measured, result, d)
        blocks += label_tables(st, cfg, result)
        for d in measured.points:
            blocks += depth_conclusion(st.out, result, conclusions[d], d)
        return PassReport(blocks, summary_of(result, conclusions), planned.renders())


def depth_charts(st: Study, cfg: Settings, measured: Measured, result: Analysis,
                 d: int) -> list:
    """At max_depth ``d``: the error chart, the efficiency chart (or why there is none) and
    the viewer."""
    out, metric = st.out, METRIC_NAMES[METRIC]
    bands = {s: ([p.spp for p in pts], [sum(p.seconds) / len(p.seconds) for p in pts],
                 [p.expected(METRIC) for p in pts])
             for s, pts in measured.points[d].items()}
    figures.error_bands(os.path.join(out, NAME, f"error_depth{d}.png"), bands, metric)
    blocks = [report.image(
        f"{NAME}/error_depth{d}.png", f"max_depth {d}: expected {metric} against "
        f"spp and against render (CPU) time per sampler, with {stats.LEVEL:.0%} "
        f"bands over the repeats (log-log, fitted slopes in the legend); "
        f"reference: {st.describe_reference(measured.floors[d])}.")]
    if any(math.isfinite(e.value) for pts in result.curves[d].values() for _, e in pts):
        figures.ratio_bands(os.path.join(out, NAME, f"efficiency_depth{d}.png"),
                            result.curves[d], EFFICIENCY,
                            f"max_depth {d}: efficiency relative to {BASELINE}")
        blocks.append(report.image(
            f"{NAME}/efficiency_depth{d}.png", f"max_depth {d}: {EFFICIENCY} at "
            f"every count of the ladder, with {stats.LEVEL:.0%} bands: where the "
            f"curves cross, the order of the samplers changes with the sample "
            f"count."))
    else:
        blocks.append(report.text(
            f"max_depth {d}: no efficiency relative to {BASELINE} is known at "
            f"this budget (at every count an error is below the reference's own "
            f"noise, only a bound), so no chart of them is drawn; a better reference "
            f"(--reference-spp) or more repeats cure it."))
    blocks.append(comparison_viewer(st, cfg, measured, d))
    return blocks


def label_tables(st: Study, cfg: Settings, result: Analysis) -> list:
    """The table of every label at the largest count and the efficiency along the ladder."""
    out, metric = st.out, METRIC_NAMES[METRIC]
    return [
        report.write_table(out, f"{NAME}/samplers", TABLE_HEADER, table_rows(result.rows),
                           f"Samplers with {cfg.base} at the largest sample count "
                           f"(expected values over {st.repeats} runs with the "
                           f"reference's own expected error subtracted, '< x' where an "
                           f"error is below the reference's noise; {stats.LEVEL:.0%} "
                           f"intervals as _lo/_hi; the efficiency uses {metric})"),
        report.write_table(out, f"{NAME}/efficiency_ladder",
                           ["max_depth", "sampler", "ladder index", "spp rendered"]
                           + interval_header(EFFICIENCY), curve_rows(result.curves),
                           f"{EFFICIENCY} at every count of the ladder", collapsed=True)]


def depth_conclusion(out: str, result: Analysis, sentences: list, d: int) -> list:
    """At max_depth ``d``: the conclusion table, its sentences and the pick."""
    metric = METRIC_NAMES[METRIC]
    mine = [c for c in result.comparisons if c.depth == d]
    blocks = [report.write_table(
        out, f"{NAME}/conclusion_depth{d}", COMPARISON_HEADER,
        [c.cells() for c in mine],
        f"Conclusion at max_depth {d}: efficiency 1/({metric} x time) of A over B at "
        f"the largest count, its {stats.LEVEL:.0%} interval, "
        f"the verdict (only where the interval excludes 1) and the counts where the "
        f"order changes along the ladder"),
        report.text("\n\n".join(sentences))]
    if d in result.picks:
        p = result.picks[d]
        blocks.append(report.text(
            f"The suite and the convergence study add bsdf+nee with {p.sampler}: "
            f"{pick_text(d, p.record())}."))
    return blocks


def summary_of(result: Analysis, conclusions: dict) -> dict:
    """The pass's part of summary.json (the pick is what the other studies read)."""
    return {
        "rows": [r.record() for r in result.rows],
        "conclusion": {d: s for d, s in conclusions.items()},
        "comparisons": [c.record() for c in result.comparisons],
        "best": {d: r.sampler for d, r in result.best.items()},
        "pick": {d: p.record() for d, p in result.picks.items()},
        "curves": {d: {s: [dict(spp=spp, **e.fields("relative_efficiency"))
                           for spp, e in pts] for s, pts in by.items()}
                   for d, by in result.curves.items()}}


def pick_near(out: str, depth: float) -> tuple[int, dict] | None:
    """The sampler study's pick (:func:`.sampler_comparison.analysis.picks`, as its
    summary.json in ``out`` records it) at the depth nearest ``depth`` (the smaller of two
    as near): ``(depth, record)``; None where that study has not run or picked nothing."""
    summary = files.read_json(os.path.join(out, NAME, "summary.json"), {}) or {}
    chosen = summary.get("pick") or {}
    if not chosen:
        return None
    key = min(chosen, key=lambda d: (abs(int(d) - depth), int(d)))
    return int(key), chosen[key]


def pick_text(depth: int, record: dict) -> str:
    """How the pick was made, for the studies that add it: one clause."""
    tied = record.get("tied") or [record["sampler"]]
    if len(tied) == 1:
        return (f"the sampler study's most efficient randomized sampler at max_depth {depth}, "
                f"ahead of every other by its interval")
    others = [s for s in tied if s != record["most_efficient"]]
    return (f"at max_depth {depth} the sampler study could not tell its most efficient "
            f"randomized sampler ({record['most_efficient']}) from {', '.join(others)}: of "
            f"these the last in its table's order")


def point(runs: list, requested: int, meta: dict) -> Point:
    """A label at one count: its runs' spp rendered, costs (the clock) and errors, per
    repeat, with the reference's floors."""
    return Point(runs[0].spp, tuple(r.cost for r in runs), tuple(r.mse for r in runs),
                 tuple(r.relmse for r in runs), requested, meta["mse_floor"],
                 meta["relmse_floor"])


def comparison_viewer(st: Study, cfg: Settings, measured: Measured, d: int) -> dict:
    """Viewer block: every label's image at the largest count of the ladder, at max_depth d
    (the first repeat)."""
    return report.viewer(st.out, f"Samplers at max_depth {d}, {cfg.targets[-1]} spp",
                         list(measured.images[d].items()), measured.references[d],
                         f"{cfg.base} with each sampler at max_depth {d} after the "
                         f"largest sample count (first repeat), against the reference.")
