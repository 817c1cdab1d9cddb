"""The scene suite's report: matrix heatmap and tables, a viewer and a crop figure per scene,
the sentences, the findings box (summary.json) and the section in index.html."""
from __future__ import annotations

import fnmatch
import math
import os
import time

import numpy as np

from .. import figures, files, metrics, prose, report, stats
from ..execute import VIEW_CACHE
from ..methods import parse_method
from . import suite_analysis, suite_bias, suite_plan
from .suite_bias_report import (BLOCK_HEADER, bias_finding, bias_words, block_bias_rows,
                                names)
from .suite_plan import NAME, ORDER, TIME, TITLE

g = stats.g
BASELINE_WHY = ("Mitsuba's own path tracer (next-event estimation + MIS), what a user would "
                "run instead")


def _cells(e: stats.Estimate) -> list[str]:
    """[value, lo, hi] cells; a bound (an error below the reference's noise) as '<hi'."""
    return [f"<{g(e.hi)}", "0", g(e.hi)] if e.bound else e.cells()


def _safe(x):
    """NaN and infinities as None in summary.json."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_safe(v) for v in x]
    return x


# ------------------------------------------------------------------ words

#: Longest "where each method wins" paragraph, in words.
MAX_WORDS = 80
VERDICT_WORDS = {"held": "held", "failed": "failed", "undecided": "is undecided",
                 "untestable": "cannot be tested"}
VERDICT = {
    "none": "the scene states no hypothesis",
    "untestable": "no method run matches its '{{ missing }}' patterns "
                  "({{ patterns | join(', ') }})",
    "failed": "{{ against[0] }} is more efficient than {{ favoured }}, the best favoured "
              "method (ratio {{ ratio.text() }})",
    "undecided": "{{ favoured }}, the best favoured method, cannot be told from {{ names }} "
                 "at this budget",
    "held": "{{ favoured }} beats every method it should beat (by the least against "
            "{{ against[0] }}: {{ ratio.text() }})"}
WINNER = ("On {{ scene }}, {{ winner }} wins at equal time: {% if winner != base %}"
          "{{ ratio.text() }} times {{ base }}'s efficiency{% else %}ahead of every other "
          "method{% endif %}.")
TIES = ("On {{ scene }}, {{ names }} cannot be told apart at equal time (best estimate: "
        "{% if lead != base %}{{ lead }}, {{ value | g }} times {{ base }}{% else %}"
        "{{ base }} itself{% endif %}).")
HYPOTHESIS = "Its hypothesis {{ words }}: {{ why }}."
TIME_RATIO = "vr_path {{ a }} takes {{ ratio.text() }} of {{ b }}'s time per sample."


def verdict_text(v: suite_analysis.Verdict) -> str:
    """The hypothesis' verdict in words."""
    return prose.say(VERDICT[v.status], missing=v.missing, patterns=v.patterns,
                     favoured=v.favoured, against=v.against, ratio=v.ratio,
                     names=names(v.against))


def sentences(r: suite_analysis.SceneResult) -> list[str]:
    """Where each method wins on this scene: at most three sentences, at most
    :data:`MAX_WORDS` words together (the last ones are dropped to fit)."""
    rank, base, out = r.ranking, r.baseline, []
    if rank.winner:
        out.append(prose.say(WINNER, scene=r.name, winner=rank.winner, base=base,
                             ratio=r.cells[rank.winner].relative["equal_time"]))
    elif rank.ties:
        lead = rank.ties[0]
        out.append(prose.say(TIES, scene=r.name, names=names(rank.ties), lead=lead, base=base,
                             value=r.cells[lead].relative["equal_time"].value))
    if r.verdict.status != "none":
        out.append(prose.say(HYPOTHESIS, words=VERDICT_WORDS[r.verdict.status],
                             why=verdict_text(r.verdict)))
    if r.time_ratio is not None:
        a, b = suite_analysis.TIMED_PAIR
        out.append(prose.say(TIME_RATIO, a=a, b=b, ratio=r.time_ratio))
    while len(out) > 1 and len(" ".join(out).split()) > MAX_WORDS:
        out.pop()
    return out[:3]


def findings(results: list, failed_scenes: dict) -> list[str]:
    """The report's findings box: the best method per scene and the overall picture."""
    if not results:
        return [f"No scene could be compared ({len(failed_scenes)} failed)."]
    best = "; ".join(f"{r.name}: " + (r.ranking.winner or
                                      f"{names(r.ranking.ties)} (cannot be told apart)")
                     for r in results)
    out = [f"Best method per scene at equal time (relMSE efficiency, 95% intervals): {best}."]
    methods = list(dict.fromkeys(m for r in results for m in r.cells))
    top = {m: sum(m in r.ranking.best() for r in results) for m in methods}
    leaders = sorted((m for m in methods if top[m]), key=lambda m: -top[m])[:4]
    if leaders:
        out.append("Best or tied for best most often: " + ", ".join(
            f"{m} ({top[m]} of {len(results)} scenes)" for m in leaders) + ".")
    gm = suite_analysis.geometric_means(results)
    if gm:
        order = sorted(gm, key=lambda m: -gm[m][0])
        shown = order[:3] + [m for m in order[-2:] if m not in order[:3]]
        out.append(f"Geometric mean of the equal-time efficiency over {results[0].baseline} "
                   f"across scenes: " + ", ".join(f"{m} {g(gm[m][0])} ({gm[m][1]} scenes)"
                                                  for m in shown) + ".")
    for m, (rows, mean, n) in suite_analysis.learned_over_plain(results).items():
        plain = parse_method(m).plain
        out.append(f"{m} over {plain} (equal-time efficiency) on the scenes that do not "
                   f"favour it: " + ", ".join(f"{s} {x.short()}" for s, x in rows)
                   + f"; geometric mean {g(mean)} ({n} scenes).")
    status = {}
    for r in results:
        status.setdefault(r.verdict.status, []).append(r.name)
    words = {"held": "held", "failed": "failed", "undecided": "undecided",
             "untestable": "could not be tested", "none": "stated none"}
    out.append("Hypotheses: " + "; ".join(f"{words[s]} on {', '.join(n)}"
                                          for s, n in status.items()) + ".")
    checks = [(r.name, m, c.bias) for r in results for m, c in r.cells.items() if c.bias]
    if checks:
        outside = [f"{m} on {n} ({b.text()}, exact {g(b.exact)})" for n, m, b in checks
                   if b.checked and not b.inside]
        scenes_checked = sorted({n for n, _, _ in checks})
        out.append(f"Bias check ({', '.join(scenes_checked)}): " + (
            "the exact value lies inside every method's interval." if not outside else
            "the exact value lies outside the interval of " + "; ".join(outside) + "."))
    tested = bias_finding(results)
    if tested:
        out.append(tested)
    noisy = [r.name for r in results if not r.reference_adequate]
    if noisy:
        out.append(f"The reference is too noisy for a full comparison on {', '.join(noisy)} "
                   f"(see the suite section).")
    if failed_scenes:
        out.append(f"Not compared: {', '.join(failed_scenes)} (errors in the suite section).")
    return out


# ------------------------------------------------------------------ the matrix

def matrix(results: dict, methods: list[str],
           left_out: dict | None = None) -> tuple[list, list, list, list]:
    """(values, heatmap texts, marks, table rows) of the scene x method matrix of
    equal-time efficiency over the baseline (``left_out``: {scene: {method: why}}, the
    methods a scene's header leaves out, shown as 'left out')."""
    values, texts, marks, rows = [], [], [], []
    for name, r in results.items():
        v, t, k, row = [], [], [], [name]
        for m in methods:
            c = r.cells.get(m)
            if c is None:
                word = ("failed" if m in r.failed else
                        "left out" if m in (left_out or {}).get(name, {}) else "")
                v.append(math.nan), t.append(word or "-"), k.append(0)
                row.append(word)
                continue
            ratio = c.relative["equal_time"]
            v.append(ratio.value if ratio.side in ("", ">", "<") else math.nan)
            flag = "BIASED\n" if c.biased else ""
            if ratio.side == "" and ratio.est.known:
                t.append(f"{flag}{g(ratio.value)}\n{g(ratio.est.lo)}-{g(ratio.est.hi)}")
            else:
                t.append(flag + ratio.short())
            k.append(2 if r.ranking.winner == m else 1 if m in r.ranking.ties else 0)
            row.append(("BIASED " if c.biased else "") + ratio.short())
        values.append(v), texts.append(t), marks.append(k), rows.append(row)
    return values, texts, marks, rows


CELL_HEADER = ["scene", "method", "budget", "spp", "repeats", "relMSE", "relMSE_lo",
               "relMSE_hi", "relMSE rejected", "relMSE rejected_lo",
               "relMSE rejected_hi", "MSE", "MSE_lo", "MSE_hi", "FLIP", "FLIP_lo", "FLIP_hi",
               "ns per sample", "ns per sample_lo", "ns per sample_hi", "per call (ms)",
               "efficiency / baseline", "efficiency / baseline_lo",
               "efficiency / baseline_hi", "efficiency bound"]


def cell_rows(results: dict) -> tuple[list[list], list[dict]]:
    rows, records = [], []
    for name, r in results.items():
        for m, c in r.cells.items():
            for b in suite_analysis.BUDGETS:
                e, rel = c.errors[b], c.relative[b]
                rows.append([name, m, suite_analysis.BUDGET_NAMES[b], c.spp[b], e["relmse"].n,
                             *_cells(e["relmse"]), *_cells(e["relmse_rejected"]),
                             *_cells(e["mse"]), *_cells(e["flip"]), *c.ns_per_sample.cells(),
                             g(c.overhead * 1e3), *rel.est.cells(), rel.side])
                records.append({"scene": name, "method": m, "budget": b, "spp": c.spp[b],
                                **{k: v for key in suite_analysis.METRICS for k, v in
                                   e[key].fields(key).items()},
                                **{f"{k}_bound": e[k].bound for k in suite_analysis.METRICS},
                                **c.ns_per_sample.fields("ns_per_sample"),
                                "per_call_seconds": c.overhead, **rel.fields("efficiency"),
                                **(c.block_bias.fields() if c.block_bias is not None else
                                   {"biased": None})})
    return rows, records


# ------------------------------------------------------------------ per scene

def scene_row(r: suite_analysis.SceneResult, header, numbers: suite_analysis.SceneNumbers,
              ref) -> list:
    best = r.ranking.winner or ", ".join(r.ranking.ties) + " (cannot be told apart)"
    ratio = r.time_ratio.text() if r.time_ratio is not None else "-"
    reference = (f"{ref.spp} spp, own relMSE {g(numbers.floor.relmse)} = "
                 f"{r.floor_share:.1%} of the smallest measured"
                 + ("" if r.reference_adequate else " (too noisy)")
                 if ref.floor_known else f"user's EXR (own error unknown)")
    return [r.name, header.isolates if header else "(no header)", best, r.verdict.status,
            verdict_text(r.verdict), ratio, reference]


def bias_rows(results: dict) -> list[list]:
    return [[name, m, f"{c.bias.mean:.5g}", f"{c.bias.lo:.5g}", f"{c.bias.hi:.5g}",
             g(c.bias.exact), f"{c.bias.level:.4f}",
             ("yes" if c.bias.inside else "NO") if c.bias.checked else "not checked"]
            for name, r in results.items() for m, c in r.cells.items() if c.bias]


def images_of(sp, measured, methods) -> list[tuple[str, np.ndarray]]:
    """The first repeat's equal-time image of every compared method."""
    return [(m, measured.final(sp.cell(m, TIME))[0].image) for m in methods]


def error_maps(sp, measured, methods, ref) -> list[np.ndarray]:
    """Per method the relMSE map averaged over its equal-time repeats."""
    return [np.mean([metrics.relmse_map(run.image, ref)
                     for run in measured.final(sp.cell(m, TIME))], axis=0) for m in methods]


def crop_block(cfg, sp, measured, r: suite_analysis.SceneResult, ref) -> dict:
    methods = list(r.cells)
    maps = error_maps(sp, measured, methods, ref.image)
    boxes = suite_analysis.crop_boxes(maps, max(4, min(sp.width, sp.height) // 3))
    crops = []
    for (m, image), emap in zip(images_of(sp, measured, methods), maps):
        first = metrics.relmse_map(image, ref.image)
        caps = [f"relMSE {g(float(first[y:y + h, x:x + w].mean()))}\n"
                f"x{r.cells[m].relative['equal_time'].short().split(' [')[0]}"
                for x, y, w, h in boxes]
        crops.append((m, image, caps))
    stem = os.path.join(cfg.out, NAME, "crops", sp.name)
    figures.crop_figure(stem, ref.image, boxes, crops,
                        f"{sp.name}: reference and the equal-time crops (first repeat)")
    return report.image(
        f"{NAME}/crops/{sp.name}.png",
        f"{sp.name}: the reference with two crops chosen from the data (orange: where the "
        f"errors are largest; blue: where the methods differ most), each method's "
        f"equal-time crop beneath with the crop's relMSE (first repeat) and the method's "
        f"equal-time efficiency over {r.baseline} ('x'); PDF: {NAME}/crops/{sp.name}.pdf")


def viewer_block(cfg, sp, measured, r: suite_analysis.SceneResult, ref) -> dict:
    images = images_of(sp, measured, list(r.cells))
    notes = [f"{r.cells[m].spp['equal_time']} spp · relMSE "
             f"{r.cells[m].errors['equal_time']['relmse'].text()} · x"
             f"{r.cells[m].relative['equal_time'].short()} over {r.baseline}" for m, _ in images]
    maps = [(f"{m}: biased blocks", suite_bias.flag_overlay(image, r.cells[m].block_bias.flagged))
            for m, image in images if r.cells[m].biased]
    notes += [f"the blocks where the bias test flags {label.split(':')[0]} (red)"
              for label, _ in maps]
    return report.viewer(cfg.out, f"{sp.name}: equal time", images + maps, ref.image,
                         f"{sp.name} at equal time "
                         f"({cfg.time_budget * suite_plan.time_scale(sp):g} s of samples each; "
                         f"first repeat shown) and its reference: {ref.describe()}."
                         + (" Red: the blocks the bias test flags." if maps else ""), notes)


def guide_method(cfg, sp):
    """The first of the scene's rendered methods that trains a guide (its integrator is
    ``vr_guided_path``) and that its header favours by name (a pattern that does not also
    match the baseline or ``bsdf+nee``: ``*+nee*`` is not a guiding scene's; any such
    method in a scene without a header: a user's scene), or None: one training job per
    guiding scene."""
    favours = getattr(sp.header, "favours", ()) if sp.header else ()
    generic = {cfg.baseline.name, "bsdf+nee"}
    own = tuple(p for p in favours if not any(fnmatch.fnmatchcase(g, p) for g in generic))
    for m in cfg.methods:
        if (m.name in sp.methods and m.name not in sp.failed
                and m.integrator_dict().get("type") == "vr_guided_path"
                and (sp.header is None or suite_analysis.matching(own, [m.name]))):
            return m
    return None


def guide_blocks(cfg, plans) -> dict:
    """Per scene where a guiding method rendered: a figure of the guide it learns
    (:func:`.guide_figures.guide_figure`: one training job of
    :data:`.guide_figures.TRAIN_SPP` spp on the scene's film), as a report block; a figure
    that fails gives a line saying why (the comparison stands without it)."""
    from .. import guide_figures
    out = {}
    for sp in plans:
        method = None if sp.error else guide_method(cfg, sp)
        if method is None:
            continue
        stem = os.path.join(cfg.out, NAME, "guides", sp.name)
        try:
            fig = guide_figures.guide_figure(stem, sp.path, sp.width, sp.height, method,
                                             guide_figures.TRAIN_SPP, cfg.seed, sp.depth,
                                             title=f"{sp.name}: the guide {method} learns")
        except Exception as error:      # noqa: BLE001 (a figure never stops the suite)
            out[sp.name] = report.text(f"{sp.name}: the guide figure failed: "
                                       f"{type(error).__name__}: {error}")
            continue
        out[sp.name] = report.image(
            f"{NAME}/guides/{sp.name}.png",
            fig.caption(sp.name, sp.width, sp.height, guide_figures.TRAIN_SPP, method.name)
            + f" PDF: {NAME}/guides/{sp.name}.pdf")
    return out


# ------------------------------------------------------------------ the section

def scaled(plans) -> str:
    """The scenes whose equal-time budget is scaled (header or precision rule), and those
    without the precision rule, as text."""
    text = ", ".join(f"{sp.name} {suite_plan.time_scale(sp):g}x" for sp in plans
                     if suite_plan.time_scale(sp) != 1) or "none"
    notes = [f"{sp.name}: {sp.precision_note}" for sp in plans if sp.precision_note]
    return text + ("; no precision rule for " + "; ".join(notes) if notes else "")


def intro(cfg, plans, numbers) -> str:
    methods = ", ".join(m.name for m in cfg.methods)
    films = sorted({f"{sp.width}x{sp.height}" for sp in plans if sp.width})
    return (
        f"{len(plans)} scenes x {len(cfg.methods)} methods ({methods}). {cfg.best_note}. "
        f"Films: {', '.join(films) or '-'} ("
        + (f"--resolution {cfg.forced_resolution[0]}x{cfg.forced_resolution[1]}"
           if cfg.forced_resolution else
           f"each scene's own film scaled so that its long side is at most {cfg.max_size} "
           f"pixels, aspect kept") + "). "
        f"Each cell is rendered {cfg.repeats} times at equal spp ({cfg.spp}) and {cfg.repeats} "
        f"times at equal time (about {cfg.time_budget:g} s of sample work each at the cell's own "
        f"time per sample, a learning method's from one pilot render at the count its "
        f"equal-spp renders give, which are too short to train, the spp rounded to a power of "
        f"two (a learning method's not: its efficiency grows with its count), times a factor "
        f"per scene: the "
        f"larger of its header's budget and what the baseline's error needs to be known to "
        f"{suite_plan.PRECISION:.1%} from its equal-spp renders, at most "
        f"{suite_plan.MAX_PRECISION_SCALE}x: {scaled(plans)}), independent seeds (a "
        f"deterministic sampler once). "
        f"Time per sample: the execution time of the renders' kernels (Dr.Jit's kernel "
        f"history: the sample work, without the per-call cost of tracing the integrator and "
        f"launching kernels, listed as 'per call') over their samples, per repeat summed "
        f"over both budgets; the time budget is in the same seconds. A scene's methods are "
        f"timed in groups of at most {VIEW_CACHE} (the methods a process keeps warm), the "
        f"baseline and {suite_analysis.TIMED_PAIR[0]} leading the first, their renders taking "
        f"turns; the "
        f"intervals count the spread of the repeats, not a drift of the machine's load "
        f"between groups. "
        f"Errors are expected values over the repeats "
        f"against a reference per scene ({cfg.reference_method}, at least "
        f"{cfg.reference_spp} spp, extended up to {cfg.reference_max_spp} spp where its own "
        f"relMSE exceeds {suite_analysis.FLOOR_SHARE:.0%} of the smallest error measured "
        f"against it), "
        f"cached in {cfg.reference_root} and shared by every run, its own expected error "
        f"(the spread of its chunks) subtracted: an error that cannot be told from it is "
        f"reported as an upper bound. relMSE rejected: without the top "
        f"{metrics.OUTLIER_SHARE:.1%} of the pixels' errors. Efficiency = 1/(relMSE x time per "
        f"render) over the baseline {cfg.baseline} ({BASELINE_WHY}); verdicts use relMSE at "
        f"equal time; MSE is in the tables. A method wins a scene only where the "
        f"{stats.LEVEL:.0%} interval of its efficiency over every other method excludes 1. "
        f"FLIP (HDR): {'every repeat' if cfg.flip == 'all' else 'the first equal-time repeat only (the image shown; --flip all gives intervals)'}. "
        f"Intervals: {stats.LEVEL:.0%}, {stats.METHOD}. " + prose.say(PRECISE))


#: How the cells of the independent sampler under a box filter are measured (suite_errors).
PRECISE = """Where a method uses the independent sampler and the scene's filter is a box,
    each render keeps its samples' second moments per pixel and its relMSE is the expected
    one from their variance (the variance part; the bias is tested apart), pooled
    over the repeats with each pixel's variance across them (a normal quantile, no reference
    floor to subtract); the efficiency of two such methods pairs their renders' costs per
    sample (same repeat and budget, rendered in turn), each budget's renders against the
    method's mean at that budget, weighted by the budget's share of the seconds. Other
    cells use the repeats."""


def timing_text(clock, analysis: tuple[float, float], cfg) -> str:
    parts = dict(clock.parts)
    parts["analysis and report"] = [analysis[0], analysis[1]]
    total_w = sum(v[0] for v in parts.values())
    return ("Wall time of the suite: " + ", ".join(
        f"{k} {v[0]:.1f} s (CPU {v[1]:.1f} s)" for k, v in parts.items())
        + f"; total {total_w:.1f} s. Renders include loading each scene per method, "
          f"compiling its kernels and the untimed warm-up renders; CPU time counts every "
          f"thread of this process.")


def left_out_words(cfg, sp) -> list[str]:
    """The sentences that say which methods a scene's header leaves out, and why."""
    out = []
    if sp.left_out:
        out.append(f"Its header renders only {', '.join(sp.header.methods)} (and the "
                   f"baseline {cfg.baseline}): left out here are "
                   f"{', '.join(sp.left_out)}.")
    missing = suite_plan.unmatched(cfg, sp.header)
    if missing:
        out.append(f"Its header's methods {', '.join(missing)} match none of this run's "
                   f"methods.")
    return out


def write(cfg, st, plans, numbers, refs, results, viewers, measured, failed, clock, since,
          start, guides: dict | None = None) -> dict:
    out, blocks = cfg.out, []
    by_name = {sp.name: sp for sp in plans}
    methods = [m.name for m in cfg.methods]
    blocks.append(report.text(intro(cfg, plans, numbers)))
    found = findings(list(results.values()), failed)
    blocks.append(report.text("Findings (also at the top of the report): " + " ".join(found)))
    if results:
        values, texts, marks, rows = matrix(results, methods,
                                            {n: sp.left_out for n, sp in by_name.items()})
        figures.matrix_heatmap(
            os.path.join(out, NAME, "matrix"), list(results), methods, values, texts, marks,
            f"Equal-time efficiency over {cfg.baseline} (relMSE; 95% interval beneath)",
            f"log10 efficiency / {cfg.baseline}")
        blocks += [
            report.image(f"{NAME}/matrix.png", f"Scene x method: equal-time efficiency "
                         f"1/(relMSE x time) over {cfg.baseline} with its {stats.LEVEL:.0%} "
                         f"interval; thick outline: the scene's winner, thin: the methods it "
                         f"cannot be told from; BIASED: flagged by the bias test (never a "
                         f"winner nor tied); '>x'/'<x': a bound (an error below the "
                         f"reference's noise). PDF: {NAME}/matrix.pdf"),
            report.write_table(out, f"{NAME}/matrix", ["scene"] + methods, rows,
                               f"Equal-time efficiency over {cfg.baseline}: value "
                               f"[{stats.LEVEL:.0%} interval]")]
        blocks.append(report.write_table(
            out, f"{NAME}/scenes", ["scene", "isolates", "best at equal time", "hypothesis",
                                    "why", f"{suite_analysis.TIMED_PAIR[0]} / "
                                    f"{suite_analysis.TIMED_PAIR[1]} time per sample",
                                    "reference"],
            [scene_row(r, by_name[n].header, numbers[n], refs[n]) for n, r in results.items()],
            "Per scene: the winner (or the methods that cannot be told apart), the "
            "hypothesis of its header, vr_path's time per sample over path's, the reference"))
        biases = bias_rows(results)
        if biases:
            blocks.append(report.write_table(
                out, f"{NAME}/bias", ["scene", "method", "mean", "lo", "hi", "exact", "level",
                                      "exact inside"], biases,
                "Bias check: the image mean of every render of each method (weighted by spp) "
                "with its interval from the pixels' spread, at a level that makes the "
                f"scene's check {suite_analysis.BIAS_LEVEL:.0%} family-wise (Sidak over its "
                f"methods)"))
        tested = block_bias_rows(results)
        if tested:
            blocks.append(report.write_table(
                out, f"{NAME}/bias_test", BLOCK_HEADER, tested,
                f"Bias test of every cell: its renders at both budgets against the reference's "
                f"chunks, Welch's t per block and channel and a pooled test per channel, "
                f"levels {suite_bias.LEVEL:.0%} family-wise over the run (Sidak); variance "
                f"from the pixels (independent sampler, box filter) or the renders; "
                f"'detectable bias': the smallest uniform bias found about 90% of the time; "
                f"'ruled by one sample': the share of blocks whose variance one pixel of one "
                f"render holds the most of (above {suite_bias.TAILS_SHARE:.0%}: heavy tails, "
                f"untestable)"))
        rows, records = cell_rows(results)
        blocks.append(report.write_table(out, f"{NAME}/cells", CELL_HEADER, rows,
                                         "Every cell at both budgets, with intervals",
                                         collapsed=True))
    for name, r in results.items():
        sp, ref = by_name[name], refs[name]
        head = by_name[name].header
        lead = f"{name}" + (f" (isolates {head.isolates})" if head else "") + ": "
        extra = [] if r.reference_adequate else [
            f"The reference is too noisy for this comparison even at {ref.spp} spp (its own "
            f"relMSE is {r.floor_share:.0%} of the smallest measured); bounded errors: "
            f"{', '.join(r.bounds()) or 'none'}."]
        if sp.header_note:
            extra.append(f"Note: {sp.header_note}.")
        extra += left_out_words(cfg, sp)
        if bias_words(r):
            extra.append(bias_words(r))
        blocks += [report.text(lead + " ".join(sentences(r) + extra)),
                   viewers[name], crop_block(cfg, sp, measured[name], r, ref)]
        if (guides or {}).get(name):
            blocks.append(guides[name])
    fails = [[n, "(scene)", e] for n, e in failed.items()]
    fails += [[n, m, e] for n, r in results.items() for m, e in r.failed.items()]
    if fails:
        blocks.append(report.write_table(out, f"{NAME}/failures", ["scene", "method", "error"],
                                         fails, "Scenes and methods that could not be "
                                                "compared, with their errors (the others ran)"))
    analysis = (time.perf_counter() - since[0], time.process_time() - since[1])
    blocks.append(report.text(timing_text(clock, analysis, cfg)))
    summary = _safe({
        "findings": found, "baseline": cfg.baseline.name, "methods": methods,
        "scenes": [{"name": n, "winner": r.ranking.winner, "ties": list(r.ranking.ties),
                    "order": list(r.ranking.order), "hypothesis": r.verdict.status,
                    "hypothesis_text": verdict_text(r.verdict),
                    "sentences": sentences(r),
                    "reference_spp": refs[n].spp, "reference_floor_share": r.floor_share,
                    "reference_adequate": r.reference_adequate,
                    **(r.time_ratio.fields("time_ratio") if r.time_ratio else {}),
                    "failed": r.failed, "left_out": dict(by_name[n].left_out),
                    "bias_power": r.power,
                    "bias_power_method": r.power_method,
                    "biased": [m for m, c in r.cells.items() if c.biased]}
                   for n, r in results.items()],
        "cells": cell_rows(results)[1] if results else [],
        "failed_scenes": failed,
        "timing": {k: {"wall": v[0], "cpu": v[1]} for k, v in
                   {**clock.parts, "analysis": list(analysis)}.items()}})
    files.write_json(os.path.join(out, NAME, "summary.json"), summary)
    settings = {"scenes": ", ".join(cfg.scenes), "methods": ", ".join(methods),
                "baseline": cfg.baseline.name, "equal spp": cfg.spp,
                "equal time (s of samples)": cfg.time_budget, "repeats": cfg.repeats,
                "resolution": ("x".join(map(str, cfg.forced_resolution))
                               if cfg.forced_resolution else f"own film, long side <= "
                                                             f"{cfg.max_size}"),
                "reference": f"{cfg.reference_method}, >= {cfg.reference_spp} spp (cap "
                             f"{cfg.reference_max_spp}), chunks of " + (
                    ", ".join(sorted({f"{sp.ref.chunk} spp" for sp in plans if sp.ref}))
                    or "-"),
                "reference store": cfg.reference_root, "variant": cfg.variant,
                "seed": cfg.seed, "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
                "render times measured on": st.timed_on(
                    [j for sp in plans for j in sp.all_jobs() if st.store.has(j.key)])}
    report.write_section(out, NAME, TITLE, ORDER, settings, blocks, cfg.variant,
                         time.perf_counter() - start)
    return summary
