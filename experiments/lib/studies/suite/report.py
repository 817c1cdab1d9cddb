"""The scene suite's report: matrix heatmap and tables, a viewer and a crop figure per scene,
the guide figures, the findings box (summary.json) and the section in index.html.

:func:`write` takes one :class:`SceneOutcome` per compared scene (its plan, numbers,
analysis, reference and viewer); the sentences are :mod:`.words`'.
"""
from __future__ import annotations

import fnmatch
import math
import os
from dataclasses import dataclass

import numpy as np

from ... import figures, files, metrics, references, report, stats
from ...declaration import Cell
from . import analysis, bias_report, bias_test, declare, words
from .bias_report import BLOCK_HEADER, bias_words, block_bias_rows
from .declare import NAME, ORDER, TIME, TITLE

g = stats.g


@dataclass
class SceneOutcome:
    """One compared scene: what was declared, measured, concluded and shown."""
    plan: declare.ScenePlan
    numbers: analysis.SceneNumbers
    result: analysis.SceneResult
    reference: references.Reference
    viewer: dict                 # the report block of its image viewer


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
    """Every cell at both budgets: the table's rows and summary.json's records."""
    rows, records = [], []
    for name, r in results.items():
        for m, c in r.cells.items():
            for b in analysis.BUDGETS:
                e, rel = c.errors[b], c.relative[b]
                rows.append([name, m, analysis.BUDGET_NAMES[b], c.spp[b], e["relmse"].n,
                             *_cells(e["relmse"]), *_cells(e["relmse_rejected"]),
                             *_cells(e["mse"]), *_cells(e["flip"]), *c.ns_per_sample.cells(),
                             g(c.overhead * 1e3), *rel.est.cells(), rel.side])
                records.append({"scene": name, "method": m, "budget": b, "spp": c.spp[b],
                                **{k: v for key in analysis.METRICS for k, v in
                                   e[key].fields(key).items()},
                                **{f"{k}_bound": e[k].bound for k in analysis.METRICS},
                                **c.ns_per_sample.fields("ns_per_sample"),
                                "per_call_seconds": c.overhead, **rel.fields("efficiency"),
                                **(c.block_bias.fields() if c.block_bias is not None else
                                   {"biased": None})})
    return rows, records


# ------------------------------------------------------------------ per scene

def scene_row(r: analysis.SceneResult, header, numbers: analysis.SceneNumbers,
              ref, note: str = "") -> list:
    best = r.ranking.winner or ", ".join(r.ranking.ties) + " (cannot be told apart)"
    ratio = r.time_ratio.text() if r.time_ratio is not None else "-"
    reference = (f"{ref.method}, {ref.spp} spp, own relMSE {g(numbers.floor.relmse)} = "
                 f"{r.floor_share:.1%} of the smallest measured"
                 + ("" if r.reference_adequate else " (too noisy)")
                 if ref.floor_known else f"user's EXR (own error unknown)")
    reference += f" [{note}]" if note else ""
    ceiling = (f"{r.oracle_gain:.3g} ({r.oracle_method})" if math.isfinite(r.oracle_gain)
               else "-")
    return [r.name, header.isolates if header else "(no header)", best, r.verdict.status,
            words.verdict_text(r.verdict), ratio, ceiling, reference]


def bias_rows(results: dict) -> list[list]:
    return [[name, m, f"{c.bias.mean:.5g}", f"{c.bias.lo:.5g}", f"{c.bias.hi:.5g}",
             g(c.bias.exact), f"{c.bias.level:.4f}",
             ("yes" if c.bias.inside else "NO") if c.bias.checked else "not checked"]
            for name, r in results.items() for m, c in r.cells.items() if c.bias]


def images_of(sp, measured, methods) -> list[tuple[str, np.ndarray]]:
    """The first repeat's equal-time image of every compared method."""
    return [(m, measured.final(Cell(sp.name, m, TIME))[0].image) for m in methods]


def error_maps(sp, measured, methods, ref) -> list[np.ndarray]:
    """Per method the relMSE map averaged over its equal-time repeats."""
    return [np.mean([metrics.relmse_map(run.image, ref)
                     for run in measured.final(Cell(sp.name, m, TIME))], axis=0) for m in methods]


def scale_of(measured, scene: str) -> float:
    """The factor of the equal-time budget on ``scene`` (1 where it was not decided)."""
    return measured.scales.get((scene, None, TIME), (1.0, ""))[0]


def crop_block(cfg, sp, measured, r: analysis.SceneResult, ref) -> dict:
    """The crop figure of a scene (two crops chosen from the errors) as a report block."""
    methods = list(r.cells)
    maps = error_maps(sp, measured, methods, ref.image)
    boxes = analysis.crop_boxes(maps, max(4, min(sp.width, sp.height) // 3))
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


def viewer_block(cfg, sp, measured, r: analysis.SceneResult, ref) -> dict:
    """The scene's interactive viewer: each method's first equal-time image, the biased
    blocks where the bias test flags any, against the reference."""
    images = images_of(sp, measured, list(r.cells))
    notes = [f"{r.cells[m].spp['equal_time']} spp · relMSE "
             f"{r.cells[m].errors['equal_time']['relmse'].text()} · x"
             f"{r.cells[m].relative['equal_time'].short()} over {r.baseline}" for m, _ in images]
    maps = [(f"{m}: biased blocks", bias_test.flag_overlay(image, r.cells[m].block_bias.flagged))
            for m, image in images if r.cells[m].biased]
    notes += [f"the blocks where the bias test flags {label.split(':')[0]} (red)"
              for label, _ in maps]
    return report.viewer(cfg.out, f"{sp.name}: equal time", images + maps, ref.image,
                         f"{sp.name} at equal time "
                         f"({cfg.time_budget * scale_of(measured, sp.name):g} s of samples "
                         f"each; "
                         f"first repeat shown) and its reference: {ref.describe()}."
                         + (" Red: the blocks the bias test flags." if maps else ""), notes)


def guide_method(cfg, sp, failed: dict):
    """The first of the scene's rendered methods that trains a guide (its integrator is
    ``vr_guided_path``) and that its header favours by name (a pattern that does not also
    match the baseline or ``bsdf+nee``: ``*+nee*`` is not a guiding scene's; any such
    method in a scene without a header: a user's scene), or None: one training job per
    guiding scene."""
    favours = getattr(sp.header, "favours", ()) if sp.header else ()
    generic = {cfg.baseline.name, "bsdf+nee"}
    own = tuple(p for p in favours if not any(fnmatch.fnmatchcase(g, p) for g in generic))
    for m in cfg.methods:
        if (m.name not in sp.left_out and m.name not in failed
                and m.integrator_dict().get("type") == "vr_guided_path"
                and (sp.header is None or analysis.matching(own, [m.name]))):
            return m
    return None


def guide_blocks(cfg, plans, measured) -> dict:
    """Per scene where a guiding method rendered: a figure of the guide it learns
    (:func:`.guide_figures.guide_figure`: one training job of
    :data:`.guide_figures.TRAIN_SPP` spp on the scene's film), as a report block; a figure
    that fails gives a line saying why (the comparison stands without it)."""
    from ... import guide_figures
    out = {}
    for sp in plans:
        method = None if sp.error else guide_method(cfg, sp, measured.failed_on(sp.name))
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


def adaptive_blocks(cfg, plans, measured, refs: dict) -> dict:
    """Per scene and adaptive method that rendered: a figure of where it put its samples
    (:func:`.adaptive_figures.allocation`: one untimed render at its first equal-time
    count) beside the equal-time relMSE maps of its plain twin (the method without
    ``+adaptive``, where it ran) and of itself (:func:`error_maps`), as report blocks;
    ``refs``: the scenes' reference images. A figure that fails gives a line saying why."""
    from ... import adaptive_figures
    out = {}
    for sp in plans:
        if sp.error or sp.name not in refs:
            continue
        failed = measured.failed_on(sp.name)
        ran = [m.name for m in cfg.methods if m.name not in sp.left_out and m.name not in failed]
        for m in cfg.methods:
            if not m.adaptive or m.name not in ran:
                continue
            shown = [n for n in (m.unadapted, m.name) if n in ran]
            stem = os.path.join(cfg.out, NAME, "adaptive", f"{sp.name}-{m.name}")
            spp = measured.final(Cell(sp.name, m.name, TIME))[0].spp
            try:
                chosen = adaptive_figures.allocation(sp.path, sp.width, sp.height, m, spp,
                                                     cfg.seed, sp.depth)
                counts = chosen.counts
                adaptive_figures.draw(stem, counts, list(zip(shown, error_maps(
                    sp, measured, shown, refs[sp.name]))), f"{sp.name}: where {m} samples")
            except Exception as error:      # noqa: BLE001 (a figure never stops the suite)
                out.setdefault(sp.name, []).append(report.text(
                    f"{sp.name}: the allocation figure of {m} failed: "
                    f"{type(error).__name__}: {error}"))
                continue
            out.setdefault(sp.name, []).append(report.image(
                f"{NAME}/adaptive/{sp.name}-{m.name}.png",
                f"{sp.name}: where {m} puts its samples (one render at its equal-time count, "
                f"{spp} spp on average: {counts.min():.0f} to {counts.max():.0f} per pixel; "
                f"its pilot predicted a gain of {chosen.gain:.2f} at equal samples"
                f"{'' if chosen.allocated else ', too little to allocate: every pixel alike'}), "
                f"beside the per-pixel relMSE at equal time (mean over the repeats) of "
                f"{' and '.join(shown)}. PDF: {NAME}/adaptive/{sp.name}-{m.name}.pdf"))
    return out


# ------------------------------------------------------------------ the section

def write(cfg, st, plans, outcomes: list[SceneOutcome], measured, timer,
          guides: dict | None = None, allocations: dict | None = None) -> dict:
    """The suite's section, tables, figures and summary.json (returned); ``measured``: the
    engine's measurements (None where no scene rendered), ``timer``: the suite's
    :class:`~experiments.lib.clock.Timer`; ``guides``, ``allocations``: per scene, the
    blocks of :func:`guide_blocks` and :func:`adaptive_blocks`."""
    failed = {sp.name: sp.error for sp in plans if sp.error}
    results = {o.plan.name: o.result for o in outcomes}
    scales = {sp.name: measured.scales[(sp.name, None, TIME)] for sp in plans
              if measured is not None and (sp.name, None, TIME) in measured.scales}
    found = words.findings(list(results.values()), failed)
    blocks = [report.text(words.intro(cfg, plans, scales))]
    if results:
        blocks.append(report.write_table(
            cfg.out, f"{NAME}/findings", words.table_header(cfg.baseline.name),
            words.findings_table(list(results.values())),
            "Findings per scene (also at the top of the report): the winner at equal time "
            "or the methods that cannot be told apart, the best method's efficiency over "
            f"{cfg.baseline} [{stats.LEVEL:.0%} interval], the methods the bias test "
            f"flags, the cells it cannot test (why: {bias_report.BIAS_TABLE})"))
    blocks.append(report.text("Findings (also at the top of the report): " + " ".join(found)))
    if results:
        blocks += matrix_blocks(cfg, outcomes)
    for o in outcomes:
        blocks += scene_blocks(cfg, o, measured, (guides or {}).get(o.plan.name))
        blocks += (allocations or {}).get(o.plan.name, [])
    fails = [[n, "(scene)", e] for n, e in failed.items()]
    fails += [[n, m, e] for n, r in results.items() for m, e in r.failed.items()]
    if fails:
        blocks.append(report.write_table(cfg.out, f"{NAME}/failures",
                                         ["scene", "method", "error"], fails,
                                         "Scenes and methods that could not be compared, with "
                                         "their errors (the others ran)"))
    blocks.append(report.text(words.timing_text(timer)))
    summary = _safe(summary_of(cfg, outcomes, found, failed, timer))
    files.write_json(os.path.join(cfg.out, NAME, "summary.json"), summary)
    report.write_section(cfg.out, NAME, TITLE, ORDER, settings_of(cfg, st, plans, measured),
                         blocks, cfg.variant, timer.elapsed())
    return summary


def matrix_blocks(cfg, outcomes: list[SceneOutcome]) -> list[dict]:
    """The matrix (heatmap and table), the per-scene table, the bias tables and every
    cell's numbers."""
    out, methods = cfg.out, [m.name for m in cfg.methods]
    results = {o.plan.name: o.result for o in outcomes}
    values, texts, marks, rows = matrix(results, methods,
                                        {o.plan.name: o.plan.left_out for o in outcomes})
    figures.matrix_heatmap(
        os.path.join(out, NAME, "matrix"), list(results), methods, values, texts, marks,
        f"Equal-time efficiency over {cfg.baseline} (relMSE; 95% interval beneath)",
        f"log10 efficiency / {cfg.baseline}")
    blocks = [
        report.image(f"{NAME}/matrix.png", f"Scene x method: equal-time efficiency "
                     f"1/(relMSE x time) over {cfg.baseline} with its {stats.LEVEL:.0%} "
                     f"interval; thick outline: the scene's winner, thin: the methods it "
                     f"cannot be told from; BIASED: flagged by the bias test (never a "
                     f"winner nor tied); '>x'/'<x': a bound (an error below the "
                     f"reference's noise). PDF: {NAME}/matrix.pdf"),
        report.write_table(out, f"{NAME}/matrix", ["scene"] + methods, rows,
                           f"Equal-time efficiency over {cfg.baseline}: value "
                           f"[{stats.LEVEL:.0%} interval]"),
        report.write_table(
            out, f"{NAME}/scenes", ["scene", "isolates", "best at equal time", "hypothesis",
                                    "why", f"{analysis.TIMED_PAIR[0]} / "
                                    f"{analysis.TIMED_PAIR[1]} time per sample",
                                    "adaptive ceiling", "reference"],
            [scene_row(o.result, o.plan.header, o.numbers, o.reference, o.plan.reference_note)
             for o in outcomes],
            "Per scene: the winner (or the methods that cannot be told apart), the "
            "hypothesis of its header, vr_path's time per sample over path's, the adaptive "
            f"ceiling (how many times an oracle's allocation of the samples of the method "
            f"named, the first of {', '.join(analysis.CEILING_METHODS)} the scene renders, "
            "to its pixels, by their relative standard deviations from its "
            "equal-time renders, would lower its relMSE at equal samples; at equal time it "
            "is lower where the pixels that need samples are dearer, make bench rows 8), "
            "the reference")]
    biases = bias_rows(results)
    if biases:
        blocks.append(report.write_table(
            out, f"{NAME}/bias", ["scene", "method", "mean", "lo", "hi", "exact", "level",
                                  "exact inside"], biases,
            "Bias check: the image mean of every render of each method (weighted by spp) "
            "with its interval from the pixels' spread, at a level that makes the "
            f"scene's check {analysis.BIAS_LEVEL:.0%} family-wise (Sidak over its "
            f"methods)"))
    tested = block_bias_rows(results)
    if tested:
        blocks.append(report.write_table(
            out, f"{NAME}/bias_test", BLOCK_HEADER, tested,
            bias_report.TABLE_CAPTION))
    rows, _ = cell_rows(results)
    blocks.append(report.write_table(out, f"{NAME}/cells", CELL_HEADER, rows,
                                     "Every cell at both budgets, with intervals",
                                     collapsed=True))
    return blocks


def precise_only(numbers: analysis.SceneNumbers) -> bool:
    """Whether every cell's equal-time relMSE comes from its pixels' variances (none is
    measured against the reference)."""
    return bool(numbers.cells) and all(c.runs["equal_time"].expected
                                       for c in numbers.cells.values())


def scene_blocks(cfg, o: SceneOutcome, measured, guide: dict | None) -> list[dict]:
    """A scene's paragraph, viewer, crop figure and guide figure."""
    sp, r, ref = o.plan, o.result, o.reference
    head = sp.header
    lead = f"{sp.name}" + (f" (isolates {head.isolates})" if head else "") + ": "
    extra = [] if r.reference_adequate else [
        f"The reference is too noisy for this comparison even at {ref.spp} spp (its own "
        f"relMSE is {r.floor_share:.0%} of the smallest measured); bounded errors: "
        f"{', '.join(r.bounds()) or 'none'}." + (
            " No verdict here rests on its noise: every cell's relMSE comes from its "
            "pixels' variances, where the reference is only the denominator, the same "
            "for every method of the scene; its noise enters the raw errors, FLIP and "
            "the bias test." if precise_only(o.numbers) else "")]
    if sp.header_note:
        extra.append(f"Note: {sp.header_note}.")
    extra += words.left_out_words(cfg, sp) + words.unreachable_words(cfg, sp)
    if bias_words(r):
        extra.append(bias_words(r))
    blocks = [report.text(lead + " ".join(words.sentences(r) + extra)), o.viewer,
              crop_block(cfg, sp, measured, r, ref)]
    return blocks + ([guide] if guide else [])


def summary_of(cfg, outcomes: list[SceneOutcome], found: list, failed: dict, timer) -> dict:
    """summary.json: the findings, every scene's verdicts and every cell."""
    results = {o.plan.name: o.result for o in outcomes}
    return {
        "findings": found,
        report.FINDINGS_TABLE_KEY: {
            "header": words.table_header(cfg.baseline.name),
            "rows": words.findings_table(list(results.values())),
            "figure": f"{NAME}/matrix.png" if results else ""},
        "baseline": cfg.baseline.name,
        "methods": [m.name for m in cfg.methods],
        "scenes": [{"name": o.plan.name, "winner": r.ranking.winner,
                    "ties": list(r.ranking.ties), "order": list(r.ranking.order),
                    "hypothesis": r.verdict.status,
                    "hypothesis_text": words.verdict_text(r.verdict),
                    "sentences": words.sentences(r),
                    "adaptive_ceiling": r.oracle_gain,
                    "adaptive_ceiling_method": r.oracle_method,
                    "reference_method": o.reference.method,
                    "reference_note": o.plan.reference_note,
                    "reference_spp": o.reference.spp, "reference_floor_share": r.floor_share,
                    "reference_adequate": r.reference_adequate,
                    **(r.time_ratio.fields("time_ratio") if r.time_ratio else {}),
                    "failed": r.failed, "left_out": dict(o.plan.left_out),
                    "unreachable_lights": words.unreachable(cfg, o.plan),
                    "bias_power": r.power, "bias_power_method": r.power_method,
                    "biased": [m for m, c in r.cells.items() if c.biased]}
                   for o in outcomes for r in [o.result]],
        "cells": cell_rows(results)[1] if results else [],
        "failed_scenes": failed,
        "timing": {k: {"wall": v[0], "cpu": v[1]} for k, v in timer.parts.items()}}


def settings_of(cfg, st, plans, measured) -> dict:
    """The section's settings table."""
    jobs = measured.all_jobs() if measured is not None else []
    return {"scenes": ", ".join(cfg.scenes), "methods": ", ".join(m.name for m in cfg.methods),
            "baseline": cfg.baseline.name, "equal spp": cfg.spp,
            "equal time (s of samples)": cfg.time_budget, "repeats": cfg.repeats,
            "resolution": ("x".join(map(str, cfg.forced_resolution))
                           if cfg.forced_resolution else f"own film, long side <= "
                                                         f"{cfg.max_size}"),
            "reference": f"{cfg.reference_method}" + (
                f" (or {cfg.precise_reference} where proven)" if cfg.precise_reference
                else "") + f", >= {cfg.reference_spp} spp (cap "
                         f"{cfg.reference_max_spp}" + (
                f", or {cfg.reference_max_seconds:g} s" if cfg.reference_max_seconds
                else "") + "), chunks of " + (
                ", ".join(sorted({f"{sp.ref.chunk} spp" for sp in plans if sp.ref})) or "-"),
            "reference store": cfg.reference_root, "variant": cfg.variant,
            "seed": cfg.seed, "intervals": f"{stats.LEVEL:.0%}, {stats.METHOD}",
            "render times measured on": st.timed_on([j for j in jobs if st.store.has(j.key)])}
