"""The convergence study's report: images, viewers, charts, tables, prose and summary.json.

Everything here is presentation of a :class:`~.convergence_analysis.Result`: numbers and
sentences come from the analysis (one source for the tables and the prose), this module
only writes them down.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from .. import clock, files, figures, metrics, prose, stats
from .. import report as rep
from .. import jobs
from .conclusion import BOUNDS, HEADER as CONCLUSION_HEADER, ratio_cells
from .conclusion import rows as conclusion_rows
from . import convergence_analysis
from .convergence_analysis import NAME, Result


@dataclass(frozen=True)
class Context:
    """What the report needs besides the analysis: the settings, the study (its output
    folder and reference description), the measured numbers and images."""
    settings: object              # ConvergenceSettings
    st: object                    # Study
    measured: object              # Measured
    targets: tuple                # the ladder's requested counts
    timed_on: str                 # which machine measured the render times
    title: str
    order: int
    timer: clock.Timer            # started when the study began


ERRORS_HEADER = ["method", "spp", "repeats", "seconds", "MSE", "MSE_lo", "MSE_hi", "relMSE",
                 "relMSE_lo", "relMSE_hi", "FLIP (first repeat)", "image", BOUNDS]
SLOPES_HEADER = ["method", "MSE vs spp", "MSE vs time", "relMSE vs spp", "relMSE vs time"]
EFFICIENCY_HEADER = ["method", "spp", "repeats", "seconds", "MSE", "MSE_lo", "MSE_hi",
                     "relMSE", "relMSE_lo", "relMSE_hi", "relative efficiency",
                     "relative efficiency_lo", "relative efficiency_hi", "equal-time spp",
                     "equal-time MSE", "equal-time MSE_lo", "equal-time MSE_hi",
                     "equal-time relMSE", "equal-time relMSE_lo", "equal-time relMSE_hi",
                     "equal-time relative efficiency", "equal-time relative efficiency_lo",
                     "equal-time relative efficiency_hi", BOUNDS]


#: Where the best combination was chosen (:class:`~.convergence_analysis.BestNote`).
BEST_NOTE = """
{% if note.given %}{{ note.method }} is the combination given by --best-sampler.
{% else %}
{{ note.method }} is the best combination the sampler study found: bsdf+nee with its pick
(its most efficient randomized sampler, or of those it could not tell apart the last in its
table), chosen at {{ where | join(", ") }}; this study runs at max_depth
{{ note.here_depth }}, {{ note.here_spp }} spp, {{ note.here_resolution }}.
{% if note.differs %} A sampler picked at another count or depth is not claimed to be the
best here: its row in the conclusion says how it does at this study's count.{% endif %}
{% endif %}
"""


def best_text(note) -> str:
    """The best combination's note as a sentence ("" without one)."""
    if note is None:
        return ""
    where = [p for p in (f"max_depth {note.depth}", f"{note.spp} spp" if note.spp else "",
                         note.resolution or "") if p]
    return prose.say(BEST_NOTE, note=note, where=where)


def _stem(method: str, spp: int) -> str:
    return f"{NAME}/{method}/spp{spp:05d}"


def intro(ctx: Context, result: Result) -> list[dict]:
    s, st, meta = ctx.settings, ctx.st, ctx.measured.reference
    return [rep.text(
        f"Progressive renders of {os.path.basename(s.scene)} at {st.width}x{st.height} "
        f"({s.depth.describe()}): each method accumulates jobs (a new seed each; Halton "
        f"continues its sequence) to 1, 2, 4, ... {s.spp} spp, {st.repeats} times with "
        f"independent randomizations (plain Halton, deterministic, once). Mitsuba's "
        f"stratified, orthogonal and ldsampler round counts up; the spp shown are those "
        f"rendered.\n\n"
        f"Errors are expected values over the repeats against the reference: "
        f"{st.describe_reference(meta)}; an error that cannot be told from the reference's "
        f"noise is given as an upper bound.\n\n"
        f"Times are warm render times in the timed configuration (JIT compilation excluded), "
        f"cumulative over passes. Intervals: {stats.LEVEL:.0%}, {stats.METHOD}.\n\n"
        + (best_text(result.best_note) or
           "The sampler study's pick is not among the methods (run the sampler study "
           "first, as run_all does, or give --best-sampler)."))]


def _short(e: stats.Estimate, fmt: str = "{:.2e}") -> str:
    """A tile caption's number: '< x' for an upper bound."""
    return ("< " if e.bound else "") + fmt.format(e.value)


def sequences(ctx: Context, result: Result) -> list[dict]:
    """The convergence sequences: images, viewers, error charts, errors and slopes."""
    s, st, images = ctx.settings, ctx.st, ctx.measured.images
    out, ref = st.out, images.reference
    table, grid, captions, viewers, last_notes = [], [], [], [], []
    for m, lines in result.lines.items():
        grid.append(images.ladders[m])
        captions.append([f"MSE {_short(x.mse)}\nrelMSE {_short(x.relmse)}\n"
                         f"{x.seconds:.2f} s" for x in lines])
        notes = [f"{x.first_seconds:.2f} s · expected relMSE {_short(x.relmse, '{:.3g}')} · "
                 f"FLIP {x.flip:.3f}" for x in lines]
        last_notes.append(notes[-1])
        for x, image in zip(lines, images.ladders[m]):
            files.write_image(os.path.join(out, _stem(m, x.spp)), image)
            table.append([m, x.spp, x.runs, round(x.seconds, 4), *x.mse.cells(),
                          *x.relmse.cells(), stats.g(x.flip), _stem(m, x.spp) + ".exr",
                          ", ".join(x.bounds())])
        viewers.append(rep.viewer(
            out, f"{m}: 1 to {lines[-1].spp} spp",
            [(f"{x.spp} spp", im) for x, im in zip(lines, images.ladders[m])], ref,
            f"The convergence sequence of {m} against the reference (first repeat; the "
            f"notes give expected errors over the repeats).", notes))
    viewers.insert(0, rep.viewer(
        out, f"Every method at {s.spp} spp", [(m, g[-1]) for m, g in zip(result.lines, grid)],
        ref, "The last image of each sequence.", last_notes))
    figures.image_grid(os.path.join(out, NAME, "sequences.png"), grid, list(result.lines),
                       [f"{t} spp" for t in ctx.targets], captions)
    for metric, series in result.bands.items():
        figures.error_bands(os.path.join(out, NAME, f"error_{metric.lower()}.png"), series,
                            metric)
    band = (f"expected over {st.repeats} repeats with {stats.LEVEL:.0%} bands; the reference's "
            f"own expected error is subtracted")
    slopes = [[m, *(stats.g(v) for v in values)] for m, values in result.slopes.items()]
    return viewers + [
        rep.image(f"{NAME}/sequences.png", "Convergence sequences (first repeat): rows = "
                     "methods, columns = spp; expected MSE, relMSE and cumulative render time "
                     "under each tile."),
        rep.image(f"{NAME}/error_mse.png", f"MSE against spp and against render time "
                     f"(log-log), {band}; fitted slopes in the legend (-1 is the Monte Carlo "
                     f"rate)."),
        rep.image(f"{NAME}/error_relmse.png", f"relMSE = mean((x - ref)^2 / (ref^2 + "
                     f"{metrics.RELMSE_EPS})) against spp and time, {band}."),
        rep.image(f"{NAME}/error_flip.png", "Mean FLIP (NVIDIA's perceptual error in "
                     "[0, 1], flip-evaluator, HDR) of the images shown (the first repeat) "
                     "against spp and time; a perceptual measure of one image, not an "
                     "expected error (no band), and not a squared error, so its slope is not "
                     "the Monte Carlo -1."),
        rep.write_table(out, f"{NAME}/errors", ERRORS_HEADER, table,
                           f"Every intermediate image with its expected error ({band}) and "
                           f"mean cumulative time", collapsed=True),
        rep.write_table(out, f"{NAME}/slopes", SLOPES_HEADER, slopes,
                           "Fitted convergence slopes of the expected errors (least squares "
                           "in log-log; -1 is the Monte Carlo rate)"),
    ]


def equal_time(ctx: Context, result: Result) -> list[dict]:
    """The equal-time panel."""
    s, st, images = ctx.settings, ctx.st, ctx.measured.images
    shown, captions, notes = [], [], []
    for row in result.efficiency:
        image = images.equal[row.method]
        files.write_image(os.path.join(st.out, "equal_time", row.method), image)
        shown.append(image)
        captions.append(f"{row.equal_spp} spp, {row.equal_seconds:.2f} s\n"
                        f"relMSE {_short(row.equal_relmse)}")
        notes.append(f"{row.equal_spp} spp, {row.equal_seconds:.2f} s · expected relMSE "
                     f"{row.equal_relmse.text()} · FLIP "
                     f"{ctx.measured.equal[row.method].flip:.3f}")
    names = [row.method for row in result.efficiency]
    figures.image_grid(os.path.join(st.out, NAME, "equal_time.png"), [shown], ["equal time"],
                       names, [captions])
    return [rep.viewer(
        st.out, f"Equal time ({s.time_budget:g} s)", list(zip(names, shown)),
        images.reference,
        f"Equal time: each method renders the samples that fit in {s.time_budget:g} s "
        f"at the speed measured on its convergence sequences, {st.repeats} times (the first "
        f"repeat is shown; the notes give the expected relMSE over the repeats with its "
        f"{stats.LEVEL:.0%} interval).", notes, figure=f"{NAME}/equal_time.png")]


def efficiency(ctx: Context, result: Result) -> list[dict]:
    s, st = ctx.settings, ctx.st
    rows = [[r.method, r.spp, r.repeats, round(r.seconds, 3), *r.mse.cells(),
             *r.relmse.cells(), *ratio_cells(r.relative), r.equal_spp,
             *r.equal_mse.cells(), *r.equal_relmse.cells(), *ratio_cells(r.equal_relative),
             ", ".join(r.bounds())]
            for r in result.efficiency]
    return [
        rep.write_table(
            st.out, f"{NAME}/efficiency", EFFICIENCY_HEADER, rows,
            f"Veach efficiency 1/({convergence_analysis.METRIC} x time) after {s.spp} spp and "
            f"at equal time, relative to {result.base}: expected values over {st.repeats} "
            f"repeats with "
            f"{stats.LEVEL:.0%} intervals ({stats.METHOD}); n/a where an error is below "
            f"the reference's own noise"),
        rep.text(convergence_analysis.WHY_METRIC + "\n\nTimings are warm render times on this "
                 "machine and vary with its load (other processes sharing the cores slow every "
                 "method); the errors do not."),
    ]


def conclusion(ctx: Context, result: Result) -> list[dict]:
    """The conclusion: a short table and at most three sentences made from its rows."""
    if not result.conclusion:
        return []
    return [rep.write_table(ctx.st.out, f"{NAME}/conclusion", CONCLUSION_HEADER,
                            conclusion_rows(result.conclusion),
                            f"Conclusion: each comparison by its ratio (above 1: A is better) "
                            f"with its {stats.LEVEL:.0%} interval, and the counts of the "
                            f"ladder where the interval-decided order changes"),
            rep.text(" ".join(result.sentences))]


def settings_table(ctx: Context) -> dict:
    s, st = ctx.settings, ctx.st
    return {"scene": s.scene, "resolution": f"{st.width}x{st.height}", "spp": s.spp,
            "methods": ", ".join(m.name for m in s.methods), "repeats": st.repeats,
            "variant": s.variant, "seed": s.seed, "time budget (s)": s.time_budget,
            "path settings": s.depth.describe(),
            "reference": st.describe_reference(ctx.measured.reference),
            "max lanes per pass": jobs.MAX_LANES,
            "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
            "render times measured on": ctx.timed_on}


def report(ctx: Context, result: Result) -> None:
    """Write the section, its files and summary.json."""
    blocks = intro(ctx, result) + sequences(ctx, result) + equal_time(ctx, result) \
        + efficiency(ctx, result) + conclusion(ctx, result)
    s = ctx.settings
    rep.write_section(s.out, NAME, ctx.title, ctx.order, settings_table(ctx), blocks,
                         s.variant, ctx.timer.elapsed())
    files.write_json(os.path.join(s.out, NAME, "summary.json"),
                     {"efficiency": [r.record() for r in result.efficiency],
                      "efficiency_metric": convergence_analysis.METRIC,
                      "conclusion": [dict(zip(CONCLUSION_HEADER, row))
                                     for row in conclusion_rows(result.conclusion)],
                      "sentences": result.sentences,
                      "best_combination": best_text(result.best_note)})
