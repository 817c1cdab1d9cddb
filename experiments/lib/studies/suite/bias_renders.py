"""More renders where a cell's verdict is unsure: one more round, for three reasons.

* **Its bias test is void.** A cell whose rare large samples void its bias test
  (:mod:`.bias_test`: reason ``heavy_tails``: its image sum's variance rests on too few
  degrees of freedom, the sum is skewed, or one render's pixel rules it) renders
  :data:`MORE` times the run's repeats again at its equal-time count, and is tested again
  with them beside its equal-time renders (the same count, the same estimator: only more
  samples, so that one sample rules less). Not for a cell it cannot help (:func:`hopeless`:
  an estimator of infinite variance, rough_glass sampled by the cosine): a cell whose tails
  stay heavy stays untestable. Its errors read the suite's renders alone: it was chosen by
  what its equal-time renders drew, and pooling more renders into a cell because its
  first draws caught a rare bright sample would bias its error low (optional stopping).
* **Its test flagged it.** A flagged cell renders the same round, and its flag stands only
  where the round's renders alone, fresh, flag it again at the same level
  (:func:`confirmed`): a flag is a verdict that a careful re-measurement must not
  contradict. Those renders are independent of what chose the cell, so a flag that chance
  gave does not come back: a reference low by its missed rare bright paths (every cell
  of veach_mis read +2.9% to +4.2% against one) with a cell's own upward draw on top of
  it (mis+nee +5.8%, p 2.3e-5 against a level of 2.9e-5, in a default run). A wrong
  method's bias does (its size is the same in every render).
* **The A/A pair's error is unsure** (:func:`imprecise`): where the precision rule's factor
  is capped (:data:`.precision.MAX_PRECISION_SCALE`) and the equal-spp renders of the
  baseline or of the timed pair (:data:`.analysis.TIMED_PAIR`) predict their equal-time
  error known to worse than :data:`.precision.PRECISION`, all of them render the round, and
  its renders join their equal-time errors (not their costs: the round is timed apart from
  the suite's interleaved renders). Chosen from the equal-spp renders alone, never from
  the equal-time errors, so the pooled error stays unbiased. Its bias test reads the
  suite's renders: the round's "renders again" are the void and flagged cells' alone.

The round is a declaration of its own over the engine (job keys
``suite-bias/SCENE/METHOD/bias``: their seeds differ from every other render's). What it
cost is the suite's "more renders" wall time (its timing line); a void cell's extra
renders are in summary.json (``bias_extra_renders``), the pair's in the renders that
suite/cells.csv's "repeats" counts for its equal-time errors.
"""
from __future__ import annotations

import dataclasses
import math

from ... import bias_image
from ...declaration import Budget, Cell, Declaration
from . import analysis, declare, errors, precision

#: More renders of a void cell, in multiples of the run's repeats (three cold default runs:
#: 7, 7 and 8 cells rendered again, 2, 1 and 3 of them testable then; 3 x the repeats cleared
#: no more in 6 draws of veach_mis, grazing and environment: docs/methodology.md).
MORE = 2
#: The declaration's name (the first part of its job keys).
NAME = "suite-bias"
#: The budget's name.
BUDGET = "bias"


def hopeless(test) -> bool:
    """Whether a cell's test, read from its renders' own moments, stays void after the
    round however its draws fall: its image sum's skewness, which falls as one over the
    square root of the samples, would still be over twice :data:`.bias_image.MAX_SKEW`,
    or its degrees of freedom, which grow with them, under half :data:`.bias_image.MIN_DOF`
    (the equal-time renders hold almost all of a cell's samples: the round multiplies
    them by about 1 + :data:`MORE`). An estimator of infinite variance (rough glass sampled
    by the cosine: 2 to 9 degrees of freedom, skewness 0.6 to 1) is left as it is."""
    gain = 1.0 + MORE
    return test.variance == "moments" and (
        test.own_skew / math.sqrt(gain) > 2.0 * bias_image.MAX_SKEW or
        test.own_dof * gain < 0.5 * bias_image.MIN_DOF)


def void(tests: dict) -> dict:
    """{scene: [method]} of the cells whose test ``tests`` ({scene: {method: CellBias}})
    found heavy tails, but those the round cannot help (:func:`hopeless`)."""
    out = {}
    for scene, cells in tests.items():
        methods = [m for m, t in cells.items()
                   if t.reason == "heavy_tails" and not hopeless(t)]
        if methods:
            out[scene] = methods
    return out


def predicted_error(spp_runs: list, ref, count: int) -> float | None:
    """The relative standard error of a cell's pooled expected relMSE at ``count`` samples
    per pixel, predicted from its equal-spp runs (:class:`~...measurements.Run` values with
    their pixels' variances) against the reference image ``ref``
    (:func:`.precision.predicted`). None without pixel variances or an error."""
    maps = [errors.pixel_map(r.variance, ref) for r in spp_runs]
    if not maps or any(m is None for m in maps):
        return None
    return precision.predicted(maps, [errors.pixel_map_variance(r.variance_var, ref)
                                      for r in spp_runs], spp_runs[0].spp, count)


def imprecise(cfg: declare.Settings, plans: list, measured, reference_of) -> dict:
    """{scene: [method]} of the baseline and the timed pair (those of them rendered with
    their pixels' variances) on every scene of ``plans`` where one of them, predicted from
    its equal-spp renders at its equal-time count (:func:`predicted_error`, against
    ``reference_of(plan)``'s image: the reference at its smallest size, as the precision
    rule reads it, so that a rerun or a longer reference decides alike), has its error
    known to worse than :data:`.precision.PRECISION`: the precision rule's factor was
    capped there."""
    out = {}
    pair = (cfg.baseline.name,) + analysis.TIMED_PAIR
    for sp in plans:
        failed = measured.failed_on(sp.name)
        names = [m.name for m in cfg.methods if m.name in pair and m.name not in sp.left_out
                 and m.name not in failed and precision.precise(m, sp.box)]
        if not names:
            continue
        ref = reference_of(sp).image
        worst = [predicted_error(measured.final(Cell(sp.name, n, declare.SPP)), ref,
                                 measured.final(Cell(sp.name, n, declare.TIME))[0].spp)
                 for n in names]
        if any(e is not None and e > precision.PRECISION for e in worst):
            out[sp.name] = names
    return out


def flagged(tests: dict) -> dict:
    """{scene: [method]} of the cells whose test ``tests`` ({scene: {method: CellBias}})
    flagged biased: each renders the round, and its flag is tested again (:func:`confirmed`)."""
    out = {}
    for scene, cells in tests.items():
        methods = [m for m, t in cells.items() if t.status == "biased"]
        if methods:
            out[scene] = methods
    return out


def confirmed(first, fresh):
    """The verdict of a cell that its first test (``first``) flagged, tested again on the
    round's renders alone (``fresh``: the same count, fresh seeds, at the same level): the
    first test's numbers, ``retest`` saying whether the fresh renders flag it too (it stays
    biased), do not (not biased) or cannot tell (their tails void the test: the flag
    stands, as the first test, which passed every gate, found it), ``retest_p`` their
    smallest p and ``extra`` their number."""
    ps = [p for p in (fresh.p_blocks, fresh.p_pooled) if math.isfinite(p)]
    p = min(ps) if ps else float("nan")
    if fresh.status == "untestable":
        return dataclasses.replace(first, retest="void", retest_p=p, extra=fresh.extra)
    if fresh.status == "biased":
        return dataclasses.replace(first, retest="confirmed", retest_p=p, extra=fresh.extra)
    return dataclasses.replace(first, status="unbiased", retest="not confirmed",
                               retest_p=p, extra=fresh.extra)


def only(runs: dict, methods) -> dict:
    """``runs`` ({method: [Run]}) of ``methods`` alone: a cell's round serves the reason
    it was chosen for (a void cell's test, the pair's errors), never the other."""
    return {m: r for m, r in runs.items() if m in methods}


def union(*cells: dict) -> dict:
    """{scene: [method]} of every cell in any of ``cells``, in order, once."""
    out = {}
    for c in cells:
        for scene, names in c.items():
            out[scene] = list(dict.fromkeys(out.get(scene, []) + list(names)))
    return out


def declarations(cfg: declare.Settings, plans: list, measured, cells: dict) -> list:
    """One declaration per scene and equal-time count of the round's ``cells`` ({scene:
    [method]}): its methods at that count, :data:`MORE` x the run's repeats, the suite's
    per-pixel moments where the suite keeps them."""
    out = []
    boxes = frozenset(sp.name for sp in plans if sp.box)
    for sp in plans:
        by_count = {}
        for name in cells.get(sp.name, ()):
            runs = measured.final(Cell(sp.name, name, declare.TIME))
            by_count.setdefault(runs[0].spp, []).append(name)
        for spp, names in sorted(by_count.items()):
            methods = tuple(m for m in cfg.methods if m.name in names)
            setup = dataclasses.replace(sp.setup(), left_out=())
            out.append(Declaration(
                NAME, methods, (setup,), (Budget.equal_spp(spp, BUDGET),),
                MORE * cfg.repeats, reference_spp=cfg.reference_spp,
                reference_method=cfg.reference_method,
                reference_typical_spp=cfg.reference_typical_spp,
                sample_moments=lambda method, scene: precision.precise(method,
                                                                       scene.name in boxes),
                isolate_failures=True))
    return out


def render(engine, cfg: declare.Settings, plans: list, measured, cells: dict) -> dict:
    """Render the round's ``cells`` again (:func:`declarations`); returns {scene: {method:
    [Run]}} of those that rendered (a cell that fails here keeps its first test)."""
    out = {}
    for declaration in declarations(cfg, plans, measured, cells):
        more = engine.run(declaration)
        scene = declaration.scenes[0].name
        for method in declaration.methods:
            cell = Cell(scene, method.name, BUDGET)
            if cell in more.runs:
                out.setdefault(scene, {})[method.name] = more.final(cell)
    return out
