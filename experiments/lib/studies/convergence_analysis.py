"""The convergence study's numbers and conclusions: a pure function of measured numbers.

:func:`analyse` takes :class:`Measured` (per method, count and repeat: the error against
the reference, its own expected error not yet subtracted, the cumulative seconds, the spp)
and returns a :class:`Result` with every interval, slope, ratio, ranking, verdict and
sentence of the report. No store, no files, no rendering here: the tests feed it
synthetic numbers whose answer is known (``tests/test_convergence.py``).

Every expected error has the reference's own expected error subtracted
(:func:`~..stats.excess_interval`): where a method's error cannot be told from the
reference's noise it is an upper bound, never NaN, and a ratio involving it cannot be told.
Efficiency ratios, rankings and verdicts use relMSE (efficiency 1/(relMSE x time)): MSE over
an image with directly visible bright lights is ruled by the lights' edge pixels and can
rank the methods the wrong way round; MSE stays in the tables.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import metrics, stats
from .conclusion import MAX_SENTENCES, Comparison, order_changes, untold

NAME = "convergence"
#: The depth the sampler study's pick is looked up at when the scene leaves max_depth to
#: the integrator (its default).
DEFAULT_DEPTH = 8


# ------------------------------------------------------------------ what was measured

@dataclass(frozen=True)
class Rung:
    """One method at one count (a rung of its ladder, or its equal-time render), over the
    repeats (a deterministic method's one run stands for every repeat)."""
    spp: int                    # samples per pixel rendered
    runs: int                   # renders made (1 for a deterministic method)
    seconds: tuple              # cumulative warm render time per repeat
    mse: tuple                  # per repeat, against the reference (its floor included)
    relmse: tuple
    flip: float = float("nan")  # mean FLIP of the first repeat's image (the one shown)


@dataclass(frozen=True)
class Floor:
    """The reference's own expected errors, under every error measured against it."""
    mse: float
    relmse: float


@dataclass(frozen=True)
class Images:
    """What the report shows: the reference, the first repeat's image at every rung, and
    the first repeat's equal-time image (not used by the analysis)."""
    reference: object
    ladders: dict               # method -> [image per rung]
    equal: dict                 # method -> image


@dataclass(frozen=True)
class Measured:
    ladders: dict               # method -> [Rung], one per count of the ladder
    equal: dict                 # method -> Rung of its equal-time render
    floor: Floor
    repeats: int
    targets: tuple = ()         # the ladder's requested counts (default: the first's spp)
    images: Images | None = None
    reference: dict = field(default_factory=dict)    # how the reference was made

    def counts(self) -> list[int]:
        return list(self.targets) or [r.spp for r in next(iter(self.ladders.values()))]


# ------------------------------------------------------------------ the result

#: The metric of every efficiency ratio, ranking and verdict, and why (for the report).
METRIC = "relMSE"
WHY_METRIC = (
    "Efficiencies, rankings and verdicts use relMSE, efficiency 1/(relMSE x time): MSE over "
    "an image with directly visible bright lights is ruled by the lights' edge pixels and "
    "can rank the methods the wrong way round, while relMSE weighs each pixel's error by its "
    "brightness (the literature's metric for such verdicts). MSE stays in the tables.")


@dataclass(frozen=True)
class Line:
    """A row of the errors table: one method at one count."""
    method: str
    spp: int
    runs: int
    seconds: float              # mean cumulative seconds over the repeats
    mse: stats.Estimate         # expected error, the reference's own subtracted
    relmse: stats.Estimate
    flip: float
    first_seconds: float        # the first repeat's (the image shown)

    def bounds(self) -> list[str]:
        """The errors that are only upper bounds (below the reference's noise)."""
        return [name for name, e in (("MSE", self.mse), ("relMSE", self.relmse)) if e.bound]


@dataclass(frozen=True)
class EfficiencyRow:
    method: str
    spp: int
    repeats: int
    seconds: float
    mse: stats.Estimate
    relmse: stats.Estimate
    relative: stats.Estimate            # 1/(relMSE x time) / the baseline's, after --spp
    equal_spp: int
    equal_seconds: float
    equal_mse: stats.Estimate
    equal_relmse: stats.Estimate
    equal_relative: stats.Estimate      # at equal time
    baseline_bounds: tuple = ()         # the baseline's errors that are bounds (its ratios n/a)

    def bounds(self) -> list[str]:
        """The errors of this row that are only upper bounds (below the reference's noise),
        and the baseline's that make its ratios impossible to tell."""
        return [name for name, e in (("MSE", self.mse), ("relMSE", self.relmse),
                                     ("equal-time MSE", self.equal_mse),
                                     ("equal-time relMSE", self.equal_relmse)) if e.bound] \
            + list(self.baseline_bounds)

    def record(self) -> dict:
        """Flat fields for summary.json (intervals as ``*_lo`` / ``*_hi``)."""
        return {"method": self.method, "spp": self.spp, "repeats": self.repeats,
                "seconds": self.seconds, **self.mse.fields("mse"),
                **self.relmse.fields("relmse"),
                **self.relative.fields("relative_efficiency"),
                "equal_time_spp": self.equal_spp, **self.equal_mse.fields("equal_time_mse"),
                **self.equal_relmse.fields("equal_time_relmse"),
                **self.equal_relative.fields("equal_time_relative_efficiency"),
                "efficiency_metric": METRIC, "upper_bounds": self.bounds()}


@dataclass(frozen=True)
class Result:
    lines: dict                 # method -> [Line] per rung
    bands: dict                 # metric -> method -> (spp, mean seconds, [Estimate])
    slopes: dict                # method -> (MSE vs spp, MSE vs time, relMSE vs spp, vs time)
    base: str                   # the efficiency baseline
    efficiency: list            # [EfficiencyRow]
    ranking: list               # methods, most efficient first (those that can be told)
    conclusion: list            # [conclusion.Comparison]: the conclusion table
    sentences: list             # at most three, made from the conclusion's rows
    best_note: BestNote | None = None   # where the best combination was chosen, against here


# ------------------------------------------------------------------ analysis

def _excess(values, floor: float) -> tuple:
    """Per-repeat errors with the reference's own expected error subtracted."""
    return tuple(v - floor for v in values)


def _means(values: list) -> list[float]:
    return [float(np.mean(v)) for v in values]


def efficiency_ratio(a: Rung, b: Rung, floor: Floor) -> stats.Estimate:
    """Efficiency 1/(relMSE x time) of ``a`` over ``b``, both errors over the reference's
    own; it cannot be told (NaN, :func:`.conclusion.untold`) when either is a bound."""
    ea, eb = (stats.excess_interval(r.relmse, floor.relmse) for r in (a, b))
    if ea.bound or eb.bound:
        return untold(min(len(a.relmse), len(b.relmse)))
    return stats.efficiency_ratio(_excess(a.relmse, floor.relmse), a.seconds,
                                  _excess(b.relmse, floor.relmse), b.seconds)


def analyse(measured: Measured, settings) -> Result:
    """Pure: the tables, slopes, ratios, verdicts and conclusion of ``measured``.
    ``settings`` (a ConvergenceSettings) gives ``spp`` (the ladder's top), ``time_budget``,
    ``best`` (the best combination and where it was chosen), ``resolution`` and ``depth``."""
    floor = measured.floor
    lines, bands, slopes = {}, {"MSE": {}, "relMSE": {}, "FLIP": {}}, {}
    for m, rungs in measured.ladders.items():
        spp = [r.spp for r in rungs]
        secs = _means([r.seconds for r in rungs])
        lines[m] = [Line(m, r.spp, r.runs, s, stats.excess_interval(r.mse, floor.mse),
                         stats.excess_interval(r.relmse, floor.relmse), r.flip, r.seconds[0])
                    for r, s in zip(rungs, secs)]
        bands["MSE"][m] = (spp, secs, [x.mse for x in lines[m]])
        bands["relMSE"][m] = (spp, secs, [x.relmse for x in lines[m]])
        bands["FLIP"][m] = (spp, secs, [stats.mean_interval((r.flip,)) for r in rungs])
        row = []
        for err in ([_excess(r.mse, floor.mse) for r in rungs],
                    [_excess(r.relmse, floor.relmse) for r in rungs]):
            row += [metrics.loglog_slope(spp, _means(err)),
                    metrics.loglog_slope(secs, _means(err))]
        slopes[m] = tuple(row)
    base = "uniform" if "uniform" in measured.ladders else next(iter(measured.ladders))
    rows = efficiency_rows(measured, base)
    rel = {r.method: r.relative for r in rows}
    ranking = sorted((m for m in rel if math.isfinite(rel[m].value)),
                     key=lambda m: rel[m].value, reverse=True)
    table, said = conclusion(measured, settings, base, ranking, rows)
    return Result(lines, bands, slopes, base, rows, ranking, table, said, best_note(settings))


def efficiency_rows(measured: Measured, base: str) -> list[EfficiencyRow]:
    """The efficiency table: after --spp and at equal time, relative to ``base``."""
    floor, rows = measured.floor, []
    last = {m: rungs[-1] for m, rungs in measured.ladders.items()}
    base_bounds = tuple(f"{base}'s {name}" for name, values in (
        ("relMSE", last[base].relmse), ("equal-time relMSE", measured.equal[base].relmse))
        if stats.excess_interval(values, floor.relmse).bound)
    for m, r in last.items():
        one = stats.Estimate(1.0, 1.0, 1.0, len(r.relmse))     # the baseline against itself
        eq = measured.equal[m]
        rows.append(EfficiencyRow(
            m, r.spp, len(r.mse), float(np.mean(r.seconds)),
            stats.excess_interval(r.mse, floor.mse),
            stats.excess_interval(r.relmse, floor.relmse),
            one if m == base else efficiency_ratio(r, last[base], floor),
            eq.spp, float(np.mean(eq.seconds)), stats.excess_interval(eq.mse, floor.mse),
            stats.excess_interval(eq.relmse, floor.relmse),
            one if m == base else efficiency_ratio(eq, measured.equal[base], floor),
            () if m == base else base_bounds))
    return rows


def _along(measured: Measured, a: str, b: str) -> tuple:
    """The counts where the order of ``a`` and ``b`` changes along their ladders."""
    ratios = [efficiency_ratio(x, y, measured.floor)
              for x, y in zip(measured.ladders[a], measured.ladders[b])]
    return order_changes(measured.counts(), ratios)


def conclusion(measured: Measured, settings, base: str, ranking: list,
               rows: list) -> tuple[list, list]:
    """The conclusion table and its sentences. Rows: the most efficient method against the
    baseline (or, when the baseline leads, the baseline against the next), against the
    next best, the best combination against bsdf+nee, and the most efficient at equal time
    against the baseline. Sentences (at most three): the first row, the best combination's
    (else the next best's), and the equal-time one."""
    final = {r.method: measured.ladders[r.method][-1] for r in rows}
    equal = {r.method: r.equal_relative for r in rows}

    def ladder_row(a, b, context):
        return Comparison(a, b, f"efficiency A/B after {settings.spp} spp",
                            efficiency_ratio(final[a], final[b], measured.floor),
                            context=context, changes=_along(measured, a, b))
    leader = ranking[0] if ranking else base
    others = [m for m in ranking if m not in (leader, base)]
    lead = next_best = combo = at_equal = None
    if leader != base:
        lead = ladder_row(leader, base, f"The most efficient after {settings.spp} spp is "
                                        f"{leader}")
    elif len(ranking) > 1:
        lead = ladder_row(base, ranking[1], f"The most efficient after {settings.spp} spp is "
                                            f"{base}")
    if leader != base and others:
        next_best = ladder_row(leader, others[0], "Against the next best")
    best = settings.best.method.name if settings.best is not None else None
    if best in final and "bsdf+nee" in final and best != "bsdf+nee" and \
            {best, "bsdf+nee"} not in [{c.a, c.b} for c in (lead, next_best) if c]:
        combo = ladder_row(best, "bsdf+nee", f"The best combination after {settings.spp} spp")
    told = [m for m in equal if math.isfinite(equal[m].value)]
    best_eq = max(told, key=lambda m: equal[m].value) if told else base
    if best_eq != base:
        at_equal = Comparison(best_eq, base, f"efficiency A/B at equal time "
                                f"({settings.time_budget:g} s)", equal[best_eq],
                                context=f"At equal time ({settings.time_budget:g} s)")
    table = [c for c in (lead, next_best, combo, at_equal) if c is not None]
    said = [c for c in (lead, combo or next_best, at_equal) if c is not None]
    return table, [c.sentence() for c in said][:MAX_SENTENCES]


@dataclass(frozen=True)
class BestNote:
    """Where the best combination was chosen (None where --best-sampler gave it) against
    this study's depth, count and resolution, and whether they differ."""
    method: str
    given: bool                 # named by --best-sampler (nothing more to say)
    depth: int | None = None
    spp: int | None = None
    resolution: str | None = None
    here_depth: int = DEFAULT_DEPTH
    here_spp: int = 0
    here_resolution: str = ""
    differs: bool = False


def best_note(settings) -> BestNote | None:
    """Where the best combination was chosen, and whether that differs from this study."""
    best = settings.best
    if best is None:
        return None
    if best.depth is None:
        return BestNote(best.method.name, True)
    w, h = settings.resolution
    depth = settings.depth.max_depth
    here_depth = depth if depth is not None else DEFAULT_DEPTH
    differs = (best.spp not in (None, settings.spp) or best.depth != here_depth
               or best.resolution not in (None, f"{w}x{h}"))
    return BestNote(best.method.name, False, best.depth, best.spp, best.resolution,
                    here_depth, settings.spp, f"{w}x{h}", differs)
