"""The suite report's words: sentences per scene, the findings box, the section's intro.

Analysis returns data (:mod:`.analysis`); every sentence of the suite's section comes from
here, through the report layer's templates (:mod:`experiments.lib.prose`).
"""
from __future__ import annotations

from ... import metrics, prose, scenes, stats
from ...execute import VIEW_CACHE
from ...methods import parse_method
from . import analysis, bias_renders, declare, precision
from .bias_report import bias_finding, names

g = stats.g
BASELINE_WHY = ("Mitsuba's own path tracer (next-event estimation + MIS), what a user would "
                "run instead")


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
        "{% if lead != base %}{{ lead }}, {{ ratio.value | g }} times {{ base }}"
        "{% if ratio.side %} ({{ ratio.text() }}){% endif %}"
        "{% if not ratio.firm %}, {{ ratio.typical | g }} by the median of each one's "
        "renders' errors: a rare firefly rules the mean{% endif %}{% else %}"
        "{{ base }} itself{% endif %}).")
HYPOTHESIS = "Its hypothesis {{ words }}: {{ why }}."
TIME_RATIO = "vr_path {{ a }} takes {{ ratio.text() }} of {{ b }}'s time per sample."


def verdict_text(v: analysis.Verdict) -> str:
    """The hypothesis' verdict in words."""
    return prose.say(VERDICT[v.status], missing=v.missing, patterns=v.patterns,
                     favoured=v.favoured, against=v.against, ratio=v.ratio,
                     names=names(v.against))


def sentences(r: analysis.SceneResult) -> list[str]:
    """Where each method wins on this scene: at most three sentences, at most
    :data:`MAX_WORDS` words together (the last ones are dropped to fit)."""
    rank, base, out = r.ranking, r.baseline, []
    if rank.winner:
        out.append(prose.say(WINNER, scene=r.name, winner=rank.winner, base=base,
                             ratio=r.cells[rank.winner].relative["equal_time"]))
    elif rank.ties:
        lead = rank.ties[0]
        out.append(prose.say(TIES, scene=r.name, names=names(rank.ties), lead=lead, base=base,
                             ratio=r.cells[lead].relative["equal_time"]))
    if r.verdict.status != "none":
        out.append(prose.say(HYPOTHESIS, words=VERDICT_WORDS[r.verdict.status],
                             why=verdict_text(r.verdict)))
    if r.time_ratio is not None:
        a, b = analysis.TIMED_PAIR
        out.append(prose.say(TIME_RATIO, a=a, b=b, ratio=r.time_ratio))
    while len(out) > 1 and len(" ".join(out).split()) > MAX_WORDS:
        out.pop()
    return out[:3]


def table_header(baseline: str) -> list[str]:
    """The findings table's columns (:func:`findings_table`)."""
    return ["scene", "best at equal time", f"its efficiency over {baseline}",
            "flagged biased", "untestable cells"]


def findings_table(results: list) -> list[list]:
    """One row per scene for the report's opening table: the winner (or the methods that
    cannot be told apart), the best method's equal-time efficiency over the baseline with
    its interval, the methods the bias test flags, and how many cells it cannot test."""
    rows = []
    for r in results:
        best = r.ranking.winner or (f"{names(r.ranking.ties)} (tied)" if r.ranking.ties
                                    else "-")
        lead = r.ranking.winner or (r.ranking.ties[0] if r.ranking.ties else None)
        ratio = r.cells[lead].relative["equal_time"].short() if lead in r.cells else "-"
        flagged = [m for m, c in r.cells.items() if c.biased]
        untestable = sum(c.block_bias is not None and c.block_bias.status == "untestable"
                         for c in r.cells.values())
        rows.append([r.name, best, ratio, ", ".join(flagged) or "none", untestable])
    return rows


def findings(results: list, failed_scenes: dict) -> list[str]:
    """The report's findings box, beneath its table (:func:`findings_table`): the overall
    picture in a few sentences."""
    if not results:
        return [f"No scene could be compared ({len(failed_scenes)} failed)."]
    out = []
    methods = list(dict.fromkeys(m for r in results for m in r.cells))
    top = {m: sum(m in r.ranking.best() for r in results) for m in methods}
    leaders = sorted((m for m in methods if top[m]), key=lambda m: -top[m])[:4]
    if leaders:
        out.append("Best or tied for best most often: " + ", ".join(
            f"{m} ({top[m]} of {len(results)} scenes)" for m in leaders) + ".")
    gm = analysis.geometric_means(results)
    if gm:
        order = sorted(gm, key=lambda m: -gm[m][0])
        shown = order[:3] + [m for m in order[-2:] if m not in order[:3]]
        out.append(f"Geometric mean of the equal-time efficiency over {results[0].baseline} "
                   f"across scenes: " + ", ".join(f"{m} {g(gm[m][0])} ({gm[m][1]} scenes)"
                                                  for m in shown) + ".")
    for m, (rows, mean, n, untrained) in analysis.learned_over_plain(results).items():
        plain = parse_method(m).plain
        out.append(f"{m} over {plain} (equal-time efficiency) on the scenes that do not "
                   f"favour it: " + ", ".join(f"{s} {x.short()}" for s, x in rows)
                   + f"; geometric mean {g(mean)} ({n} scenes)."
                   + untrained_words(untrained, len(rows), plain))
    for m, (rows, mean, n) in analysis.adapted_over_plain(results).items():
        out.append(adapted_words(m, rows, mean, n))
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


def adapted_words(method: str, rows: list, mean: float, n: int) -> str:
    """The adaptive method over its twin that samples every pixel alike
    (``analysis.adapted_over_plain``): per scene, then where it is below 1 at the interval's
    level (:meth:`.ratios.Ratio.less`: it loses there)."""
    twin = parse_method(method).unadapted
    loses = [s for s, x in rows if x.less()]
    return (f"{method} over {twin} (equal-time efficiency): "
            + ", ".join(f"{s} {x.short()}" for s, x in rows)
            + f"; geometric mean {g(mean)} ({n} scenes); "
            + (f"it loses on {', '.join(loses)}." if loses else "it loses on no scene."))


def untrained_words(untrained: list, rows: int, plain: str) -> str:
    """What the learner-over-plain finding says of the scenes where the learner's
    equal-time renders did not train (``analysis.learned_over_plain``): there
    it is ``plain``'s estimator at ``plain``'s count, so those ratios measure the cells'
    noise and its host work per job."""
    if not untrained:
        return ""
    return (f" It did not train at its equal-time count on {len(untrained)} of the {rows} "
            f"({', '.join(untrained)}): below its training thresholds it is {plain}'s "
            f"estimator at {plain}'s count, so those ratios are the two cells' noise and "
            f"its host work per job (a few hundredths of a millisecond).")


def scaled(scales: dict) -> str:
    """The scenes whose equal-time budget is scaled (header or precision rule), and those
    without the precision rule, as text (``scales``: {scene: (factor, note)})."""
    text = ", ".join(f"{n} {f:g}x" for n, (f, _) in scales.items() if f != 1) or "none"
    notes = [f"{n}: {note}" for n, (_, note) in scales.items() if note]
    return text + ("; no precision rule for " + "; ".join(notes) if notes else "")


def intro(cfg, plans, scales: dict) -> str:
    """The section's first paragraph: what was run and how it is measured."""
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
        f"{precision.PRECISION:.1%} from its equal-spp renders, at most "
        f"{precision.MAX_PRECISION_SCALE}x: {scaled(scales)}), independent seeds (a "
        f"deterministic sampler once). Where that factor is capped and the equal-spp "
        f"renders still predict the baseline's or {analysis.TIMED_PAIR[0]}'s error known to "
        f"worse than {precision.PRECISION:.1%}, both render {bias_renders.MORE} x the "
        f"repeats again at their equal-time counts, and their errors (not their costs) pool "
        f"those renders too (the 'repeats' of suite/cells.csv count them). "
        f"Time per sample: the execution time of the renders' kernels (Dr.Jit's kernel "
        f"history: the sample work, without the per-call cost of tracing the integrator and "
        f"launching kernels, listed as 'per call') over their samples, per repeat summed "
        f"over both budgets; the time budget is in the same seconds. A scene's methods are "
        f"timed in groups of at most {VIEW_CACHE} (the methods a process keeps warm), the "
        f"baseline and {analysis.TIMED_PAIR[0]} leading the first, their renders taking "
        f"turns; the "
        f"intervals count the spread of the repeats, not a drift of the machine's load "
        f"between groups. "
        f"Errors are expected values over the repeats "
        f"against a reference per scene ({cfg.reference_method}"
        + (f", or {cfg.precise_reference} where its chunks pass the bias test against "
           f"{cfg.reference_method}'s reference on the scene (which every cell's bias test "
           f"reads)" if cfg.precise_reference else "")
        + f", at least "
        f"{cfg.reference_spp} spp, extended up to {cfg.reference_max_spp} spp"
        + (f" (or as far as {cfg.reference_max_seconds:g} s of its rendering go)"
           if cfg.reference_max_seconds else "") + " where its own "
        f"relMSE exceeds {analysis.FLOOR_SHARE:.0%} of the smallest error measured "
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


#: How the cells of the independent sampler under a box filter are measured (:mod:`.errors`).
PRECISE = """Where a method uses the independent sampler and the scene's filter is a box,
    each render keeps its samples' moments per pixel and its relMSE is the expected one
    from their variance (the variance part; the bias is tested apart), pooled over the
    repeats with each pixel's variance across them or, where larger, each render's own from
    its samples' fourth moments (a normal quantile, no reference floor to subtract); the
    efficiency of two such methods pairs their renders' costs per
    sample (same repeat and budget, rendered in turn), each budget's renders against the
    method's mean at that budget, weighted by the budget's share of the seconds. Other
    cells use the repeats."""


def timing_text(timer) -> str:
    """How long the suite's parts took (:class:`experiments.lib.clock.Timer`)."""
    parts = dict(timer.parts)
    total_w = sum(v[0] for v in parts.values())
    return ("Wall time of the suite: " + ", ".join(
        f"{k} {v[0]:.1f} s (CPU {v[1]:.1f} s)" for k, v in parts.items())
        + f"; total {total_w:.1f} s. Renders include loading each scene per method, "
          f"compiling its kernels and the untimed warm-up renders; CPU time counts every "
          f"thread of this process.")


def unreachable(cfg, sp) -> dict:
    """{"methods": [...], "emitters": [...]}: the methods the scene renders that sample no
    emitter (no next-event estimation), and the scene's emitters only that reaches
    (:func:`.scenes.delta_emitters`); empty where either list is."""
    emitters = scenes.delta_emitters(sp.path)
    blind = [m.name for m in cfg.methods if m.name not in sp.left_out
             and m.strategy is not None and not m.nee]
    return {"methods": blind, "emitters": list(emitters)} if emitters and blind else {}


def unreachable_words(cfg, sp) -> list[str]:
    """The sentence that says which methods cannot see the scene's delta emitters."""
    found = unreachable(cfg, sp)
    if not found:
        return []
    lights = ", ".join(dict.fromkeys(found["emitters"]))
    return [f"{names(found['methods'])} sample no emitter, and the scene's {lights} "
            f"light{'s' if len(found['emitters']) > 1 else ''} only next-event estimation "
            f"reaches: their images miss that light (biased low by construction)."]


def left_out_words(cfg, sp) -> list[str]:
    """The sentences that say which methods a scene's header leaves out, and why."""
    out = []
    if sp.left_out:
        out.append(f"Its header renders only {', '.join(sp.header.methods)} (and the "
                   f"baseline {cfg.baseline}): left out here are "
                   f"{', '.join(sp.left_out)}.")
    missing = declare.unmatched(cfg, sp.header)
    if missing:
        out.append(f"Its header's methods {', '.join(missing)} match none of this run's "
                   f"methods.")
    return out


