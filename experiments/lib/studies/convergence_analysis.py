"""The convergence study's numbers and conclusions: a pure function of measured numbers.

:func:`analyse` takes :class:`Measured` (per method, count and repeat: the error against
the reference, its own expected error not yet subtracted, the cumulative seconds, the spp)
and returns a :class:`Result` with every interval, slope, ratio, ranking, verdict and
sentence of the report. No store, no files, no rendering here: the tests feed it
synthetic numbers whose answer is known (``tests/test_convergence.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import metrics, stats

NAME = "convergence"


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
    ladders: dict               # method -> [Rung], increasing spp
    equal: dict                 # method -> Rung of its equal-time render
    floor: Floor
    repeats: int
    images: Images | None = None
    reference: dict = field(default_factory=dict)    # how the reference was made


def equal_time_spp(seconds, spp, budget: float) -> int:
    """Samples per pixel that fit in ``budget`` seconds at the speed of jobs that took
    ``seconds`` for ``spp`` samples each (at least 1)."""
    per_sample = sum(seconds) / sum(spp)
    return max(1, int(budget / per_sample))


# ------------------------------------------------------------------ the result

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


@dataclass(frozen=True)
class EfficiencyRow:
    method: str
    spp: int
    repeats: int
    seconds: float
    mse: stats.Estimate
    relmse: stats.Estimate
    relative: stats.Estimate            # efficiency / the baseline's, after --spp
    equal_spp: int
    equal_seconds: float
    equal_mse: stats.Estimate
    equal_relmse: stats.Estimate
    equal_relative: stats.Estimate      # at equal time

    def record(self) -> dict:
        """Flat fields for summary.json (intervals as ``*_lo`` / ``*_hi``)."""
        return {"method": self.method, "spp": self.spp, "repeats": self.repeats,
                "seconds": self.seconds, **self.mse.fields("mse"),
                **self.relmse.fields("relmse"),
                **self.relative.fields("relative_efficiency"),
                "equal_time_spp": self.equal_spp, **self.equal_mse.fields("equal_time_mse"),
                **self.equal_relative.fields("equal_time_relative_efficiency")}


@dataclass(frozen=True)
class Result:
    lines: dict                 # method -> [Line] per rung
    bands: dict                 # metric -> method -> (spp, mean seconds, [Estimate])
    slopes: dict                # method -> (MSE vs spp, MSE vs time, relMSE vs spp, vs time)
    base: str                   # the efficiency baseline
    efficiency: list            # [EfficiencyRow]
    ranking: list               # methods, most efficient first
    sentences: list             # the efficiency verdicts


# ------------------------------------------------------------------ analysis

def _excess(values, floor: float) -> tuple:
    """Per-repeat errors with the reference's own expected error subtracted."""
    return tuple(v - floor for v in values)


def _means(values: list) -> list[float]:
    return [float(np.mean(v)) for v in values]


def analyse(measured: Measured, settings) -> Result:
    """Pure: the tables, slopes, ratios and verdicts of ``measured``. ``settings`` gives
    ``spp`` (the ladder's top) and ``time_budget`` (the equal-time budget)."""
    floor = measured.floor
    lines, bands, slopes = {}, {"MSE": {}, "relMSE": {}, "FLIP": {}}, {}
    for m, rungs in measured.ladders.items():
        mse = [_excess(r.mse, floor.mse) for r in rungs]
        rel = [_excess(r.relmse, floor.relmse) for r in rungs]
        spp = [r.spp for r in rungs]
        secs = [r.seconds for r in rungs]
        lines[m] = [Line(m, r.spp, r.runs, float(np.mean(r.seconds)),
                         stats.mean_interval(e), stats.mean_interval(q), r.flip, r.seconds[0])
                    for r, e, q in zip(rungs, mse, rel)]
        bands["MSE"][m] = (spp, _means(secs), [x.mse for x in lines[m]])
        bands["relMSE"][m] = (spp, _means(secs), [x.relmse for x in lines[m]])
        bands["FLIP"][m] = (spp, _means(secs), [stats.mean_interval((r.flip,)) for r in rungs])
        row = []
        for err in (mse, rel):
            row += [metrics.loglog_slope(spp, _means(err)),
                    metrics.loglog_slope(_means(secs), _means(err))]
        slopes[m] = tuple(row)
    base, efficiency, ranking, sentences = _efficiency(measured, settings)
    return Result(lines, bands, slopes, base, efficiency, ranking, sentences)


def _efficiency(measured: Measured, settings):
    """The efficiency table (relative to uniform, with intervals) and its verdicts."""
    floor = measured.floor
    final = {m: (rungs[-1], _excess(rungs[-1].mse, floor.mse),
                 _excess(rungs[-1].relmse, floor.relmse))
             for m, rungs in measured.ladders.items()}
    equal = {m: (r, _excess(r.mse, floor.mse), _excess(r.relmse, floor.relmse))
             for m, r in measured.equal.items()}
    base = "uniform" if "uniform" in final else next(iter(final))
    one = stats.Estimate(1.0, 1.0, 1.0, len(final[base][1]))    # the baseline against itself

    def relative(table, m):
        (r, e, _), (rb, eb, _) = table[m], table[base]
        return one if m == base else stats.efficiency_ratio(e, r.seconds, eb, rb.seconds)
    rel = {m: relative(final, m) for m in final}
    rel_eq = {m: relative(equal, m) for m in equal}
    rows = []
    for m, (r, mse, relmse) in final.items():
        eq, eq_mse, eq_rel = equal[m]
        rows.append(EfficiencyRow(
            m, r.spp, len(mse), float(np.mean(r.seconds)), stats.mean_interval(mse),
            stats.mean_interval(relmse), rel[m], eq.spp, float(np.mean(eq.seconds)),
            stats.mean_interval(eq_mse), stats.mean_interval(eq_rel), rel_eq[m]))
    ranked = sorted(rel, key=lambda m: rel[m].value, reverse=True)
    best = ranked[0]
    sentences = [f"Most efficient after {settings.spp} spp: {best}; "
                 + stats.verdict(best, base, rel[best]) + "."]
    if len(ranked) > 2 or (len(ranked) == 2 and ranked[1] != base):
        second = ranked[1]
        (rb, eb, _), (rs, es, _) = final[best], final[second]
        sentences.append("Against the next best, " + stats.verdict(
            best, second, stats.efficiency_ratio(eb, rb.seconds, es, rs.seconds)) + ".")
    best_eq = max(rel_eq, key=lambda m: rel_eq[m].value)
    sentences.append(f"At equal time ({settings.time_budget:g} s) the most efficient is "
                     f"{best_eq}: " + stats.verdict(best_eq, base, rel_eq[best_eq]) + ".")
    return base, rows, ranked, sentences
