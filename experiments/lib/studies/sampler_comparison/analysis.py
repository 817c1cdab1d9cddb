"""The sampler study's analysis: numbers in, numbers and verdicts out (no rendering, no files).

Every sampler label (:func:`experiments.lib.samplers.labels`) renders every count of the
ladder R times with independent randomizations; :class:`Point` holds one count's numbers per
repeat (render time, MSE and relMSE against the reference) and the reference's own expected
errors (the floors under them). :func:`analyse`, a pure function of those numbers, gives

- :class:`Row`: each label at each depth at the largest count: expected MSE and relMSE (the
  floor subtracted through :func:`stats.excess_interval`: an upper bound, never NaN, where an
  error cannot be told from the reference's own noise), time per sample, MSE and relMSE
  relative to the baseline (``independent``), efficiency 1/(relMSE x time) relative to the
  baseline (:data:`METRIC`: every verdict uses relMSE, which bright pixels do not dominate),
  each with its 95% interval (:mod:`.stats`), and the fitted slope of MSE against spp;
- curves: the relative efficiency at every count of the ladder;
- per depth the conclusion table, :class:`Comparison` rows: the most efficient label against
  the runner-up; each bundled sampler family's best label against the best native sampler
  (Mitsuba's own, :attr:`SamplerSpec.native`), and against every other native sampler,
  each with its ratio, interval, verdict and the counts where the order changes;
- the most efficient label per depth with the count it was chosen at;
- :class:`Pick`, per depth the randomized label that other studies add as the best
  combination (:func:`picks`): the most efficient one where its interval sets it apart,
  else, of the labels it cannot be told from, the last in the study's order (the sampler
  table lists each family's randomizations weakest first, Mitsuba's samplers before the
  bundled ones), so that a re-measurement that swaps two tied estimates picks the same.

The sentences made from the conclusion table are the report layer's
(:mod:`.sampler_comparison.words`).

The screen-space pass's analysis is :mod:`.sampler_comparison.screen_analysis`.

Which label is bundled and which native comes from :class:`Family` values (the sampler
table's ``native``), never from a name. Tests feed synthetic points whose answer is known.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from experiments.lib import metrics, samplers, stats

#: The sampler every efficiency and MSE is relative to.
BASELINE = samplers.DEFAULT
#: The error of the efficiency 1/(error x time) that every verdict uses.
METRIC = "relmse"
METRIC_NAMES = {"mse": "MSE", "relmse": "relMSE"}
#: Roles of the conclusion table's rows.
BEST, BUNDLED, NATIVE = "most efficient / runner-up", "bundled best / best native", \
    "bundled best / native"


@dataclass(frozen=True)
class Family:
    """What the analysis knows of a label's sampler: its name, whether it is native and
    whether it is deterministic (one run stands for every repeat: no interval of its own,
    never picked for other studies, :func:`picks`)."""
    name: str
    native: bool
    deterministic: bool = False


def families(labels) -> dict[str, Family]:
    """``{label: Family}`` from the sampler table (:mod:`experiments.lib.samplers`)."""
    out = {}
    for label in labels:
        spec, randomization = samplers.split_label(label)
        out[label] = Family(spec.name, spec.native, spec.is_deterministic(randomization))
    return out


@dataclass(frozen=True)
class Point:
    """A sampler at one count of the ladder, over R repeats."""
    spp: int                    # samples per pixel actually rendered
    seconds: tuple              # warm render time per repeat
    mse: tuple                  # MSE per repeat against the reference (floor included)
    relmse: tuple
    requested: int = 0          # the ladder's count (0: the same as spp)
    mse_floor: float = 0.0      # the reference's own expected MSE
    relmse_floor: float = 0.0

    def net(self, metric: str) -> tuple:
        """Per-repeat errors with the reference's own expected error subtracted."""
        floor = getattr(self, metric + "_floor")
        return tuple(v - floor for v in getattr(self, metric))

    def expected(self, metric: str) -> stats.Estimate:
        """The expected error over the repeats, the floor subtracted
        (:func:`stats.excess_interval`: an upper bound where the error cannot be told from
        the reference's own noise, never NaN)."""
        return stats.excess_interval(getattr(self, metric), getattr(self, metric + "_floor"))


@dataclass(frozen=True)
class Row:
    """A sampler at one depth, at the largest count of its ladder."""
    depth: int
    sampler: str                # a label: independent, ..., halton:owen
    spp: int                    # rendered (orthogonal: a prime squared, stratified: a square)
    requested: int
    repeats: int
    mse: stats.Estimate
    relmse: stats.Estimate
    us_per_sample: float
    relative_efficiency: stats.Estimate   # efficiency 1/(METRIC x time) / the baseline's
    relative_mse: stats.Estimate          # MSE / the baseline's
    slope: float                          # fitted slope of log MSE against log spp
    relative_relmse: stats.Estimate = stats.Estimate(math.nan, math.nan, math.nan, 0)

    def record(self) -> dict:
        """Flat fields for summary.json (intervals as ``*_lo`` / ``*_hi``)."""
        out = {"depth": self.depth, "sampler": self.sampler, "spp": self.spp,
               "requested_spp": self.requested, "repeats": self.repeats,
               "us_per_sample": self.us_per_sample, "slope": self.slope}
        for name in ("mse", "relmse", "relative_efficiency", "relative_mse",
                     "relative_relmse"):
            out.update(getattr(self, name).fields(name))
        return out


def _base(by_sampler: dict) -> str:
    return BASELINE if BASELINE in by_sampler else next(iter(by_sampler))


def _unknown(n: int) -> stats.Estimate:
    return stats.Estimate(math.nan, math.nan, math.nan, n)


def ratio(a: Point, b: Point, metric: str = METRIC) -> stats.Estimate:
    """Efficiency 1/(error x time) of ``a`` over ``b``, the errors net of the reference's
    floor; unknown (NaN: no verdict) where either error is only a bound."""
    if a.expected(metric).bound or b.expected(metric).bound:
        return _unknown(min(len(a.seconds), len(b.seconds)))
    return stats.efficiency_ratio(a.net(metric), a.seconds, b.net(metric), b.seconds)


def relative(a: Point, b: Point, metric: str) -> stats.Estimate:
    """Expected error of ``a`` over ``b``'s; an upper bound where ``a``'s error is one,
    unknown where ``b``'s is."""
    ea, eb = a.expected(metric), b.expected(metric)
    if eb.bound:
        return _unknown(eb.n)
    if ea.bound:
        upper = ea.hi / (eb.lo if eb.known else eb.value)
        return stats.Estimate(upper, 0.0, upper, ea.n, ea.level, bound=True)
    return stats.ratio_interval([a.net(metric)], [b.net(metric)])


def table(points: dict[int, dict[str, list[Point]]], pixels: int) -> list[Row]:
    """Rows from ``points[depth][label]`` (ladder points, increasing spp)."""
    rows = []
    for depth, by_sampler in points.items():
        base = by_sampler[_base(by_sampler)][-1]
        for s, pts in by_sampler.items():
            p = pts[-1]
            mean_seconds = sum(p.seconds) / len(p.seconds)
            rows.append(Row(depth, s, p.spp, p.requested or p.spp, len(p.mse),
                            p.expected("mse"), p.expected("relmse"),
                            mean_seconds / (p.spp * pixels) * 1e6, ratio(p, base),
                            relative(p, base, "mse"),
                            metrics.loglog_slope([q.spp for q in pts],
                                                 [q.expected("mse").value for q in pts]),
                            relative(p, base, "relmse")))
    return rows


def curves(points: dict[int, dict[str, list[Point]]]) -> dict[int, dict[str, list]]:
    """``{depth: {label: [(spp rendered, efficiency / the baseline's at that count)]}}``."""
    out = {}
    for depth, by_sampler in points.items():
        base = by_sampler[_base(by_sampler)]
        out[depth] = {s: [(p.spp, ratio(p, b)) for p, b in zip(pts, base)]
                      for s, pts in by_sampler.items()}
    return out


# ------------------------------------------------------------ order along the ladder

def sign(e: stats.Estimate) -> int:
    """+1: more efficient (interval above 1), -1: less (below 1), 0: not distinguishable
    (or unknown)."""
    return 0 if not e.excludes(1.0) else (1 if e.value > 1 else -1)


WORDS = {1: "more efficient", -1: "less efficient", 0: "not distinguishable"}


def order_changes(a: list[Point], b: list[Point]) -> list[tuple[int, int, stats.Estimate]]:
    """``(count of a, sign, efficiency a / b)`` at every count of two ladders."""
    return [(p.spp, sign(r), r) for p, q in zip(a, b) for r in [ratio(p, q)]]


def onsets(changes) -> list[int]:
    """The counts at which the sign differs from the previous count's: where the order
    changes along the ladder."""
    return [spp for (_, before, _), (spp, now, _) in zip(changes, changes[1:])
            if now != before]


def order_text(changes, words: dict = WORDS) -> str:
    """'less efficient at 1-4 spp, not distinguishable at 16 spp, more efficient from 64
    spp', or 'not distinguishable at 1-256 spp (no change)' (``words``: the phrase of each
    sign)."""
    runs: list[list] = []
    for spp, s, _ in changes:
        if runs and runs[-1][0] == s:
            runs[-1][2] = spp
        else:
            runs.append([s, spp, spp])
    parts = []
    for i, (s, lo, hi) in enumerate(runs):
        last = i == len(runs) - 1 and i > 0
        where = (f"from {lo} spp" if last and lo != hi else
                 f"at {lo} spp" if lo == hi else f"at {lo}-{hi} spp")
        parts.append(f"{words[s]} {where}")
    return ", ".join(parts) + (" (no change)" if len(runs) == 1 else "")


def overtakes(a: str, b: str, changes) -> tuple[str, str, int] | None:
    """(winner, loser, count) when one of ``a``, ``b`` wins from some count to the end of
    the ladder and did not before; None otherwise."""
    signs = [s for _, s, _ in changes]
    if not signs or signs[-1] == 0 or all(s == signs[-1] for s in signs):
        return None
    first = next(i for i in range(len(signs)) if all(s == signs[-1] for s in signs[i:]))
    return (a, b, changes[first][0]) if signs[-1] == 1 else (b, a, changes[first][0])


# ------------------------------------------------------------ the conclusion table

@dataclass(frozen=True)
class Comparison:
    """One row of a depth's conclusion table: the efficiency of ``a`` over ``b``."""
    depth: int
    role: str                   # BEST, BUNDLED or NATIVE
    a: str
    b: str
    spp: int                    # a's count at the largest count of the ladder
    ratio: stats.Estimate       # efficiency a / b there
    changes: tuple = field(default=())   # (spp, sign, Estimate) at every count

    @property
    def verdict(self) -> str:
        return stats.verdict(self.a, self.b, self.ratio)

    @property
    def sign(self) -> int:
        return sign(self.ratio)

    @property
    def onsets(self) -> list[int]:
        return onsets(list(self.changes))

    @property
    def overtakes(self):
        return overtakes(self.a, self.b, list(self.changes))

    def short_verdict(self) -> str:
        if not math.isfinite(self.ratio.value):
            return "cannot be compared (below the reference's noise)"
        if self.sign == 0:
            return "not distinguishable"
        return f"{self.a if self.sign > 0 else self.b} is more efficient"

    def cells(self) -> list:
        interval = (f"{stats.g(self.ratio.lo)}-{stats.g(self.ratio.hi)}" if self.ratio.known
                    else f"none ({self.ratio.n} run)")
        return [self.depth, self.role, f"{self.a} / {self.b}", self.spp,
                stats.g(self.ratio.value), interval, self.short_verdict(),
                order_text(list(self.changes)) if self.changes else "",
                ", ".join(map(str, self.onsets)) or "none"]

    def record(self) -> dict:
        return {"depth": self.depth, "role": self.role, "a": self.a, "b": self.b,
                "spp": self.spp, **self.ratio.fields("efficiency_ratio"),
                "verdict": self.short_verdict(), "order_changes_at": self.onsets}


COMPARISON_HEADER = ["max_depth", "comparison", "A / B", "spp (A)", "efficiency A / B",
                     f"{stats.LEVEL:.0%} interval", "verdict", "order along the ladder",
                     "order changes at spp"]


def _best(rows: list[Row]) -> Row:
    """The most efficient row (an unknown efficiency counts as the lowest)."""
    return max(rows, key=lambda r: (math.isfinite(r.relative_efficiency.value),
                                    r.relative_efficiency.value))


def comparisons(rows: list[Row], points: dict, kinds: dict[str, Family]) -> list[Comparison]:
    """The conclusion table's rows of every depth (see the module docstring)."""
    out = []
    for depth in sorted({r.depth for r in rows}):
        at = [r for r in rows if r.depth == depth]
        ladders = points[depth]

        def compare(role, a, b):
            return Comparison(depth, role, a, b, ladders[a][-1].spp,
                              ratio(ladders[a][-1], ladders[b][-1]),
                              tuple(order_changes(ladders[a], ladders[b])))
        best = _best(at)
        others = [r for r in at if r is not best]
        if others:
            out.append(compare(BEST, best.sampler, _best(others).sampler))
        native = [r for r in at if kinds[r.sampler].native]
        bundled = list(dict.fromkeys(kinds[r.sampler].name for r in at
                                     if not kinds[r.sampler].native))
        if not native:
            continue
        top = _best(native)
        for family in bundled:
            mine = _best([r for r in at if kinds[r.sampler].name == family])
            out.append(compare(BUNDLED, mine.sampler, top.sampler))
            out += [compare(NATIVE, mine.sampler, n.sampler) for n in native if n is not top]
    return out


# ------------------------------------------------------------ the pick

@dataclass(frozen=True)
class Pick:
    """The randomized label other studies add as the best combination, at one depth."""
    depth: int
    sampler: str                # the label picked
    spp: int                    # its count rendered at the top of the ladder
    requested: int              # ... the ladder's count there
    most_efficient: str         # the randomized label of the highest estimate
    tied: tuple                 # the randomized labels not told from it (itself included)

    @property
    def clear(self) -> bool:
        """True where every other randomized label is less efficient, by its interval."""
        return self.tied == (self.most_efficient,)

    def record(self) -> dict:
        return {"sampler": self.sampler, "spp": self.spp, "requested_spp": self.requested,
                "most_efficient": self.most_efficient, "tied": list(self.tied)}


def picks(rows: list[Row], points: dict, kinds: dict[str, Family]) -> dict[int, Pick]:
    """Per depth the randomized label that other studies take (the suite's and the
    convergence study's best combination, bsdf+nee with it): the most efficient randomized
    label where the efficiency interval of every other one over it lies below 1; else the
    last, in the study's order of labels, of those it cannot be told from (the order is a
    prior: the sampler table lists each family's randomizations weakest first). The largest
    estimate alone would flip between re-measurements wherever two labels tie. Depths with
    no randomized label of known efficiency have no pick."""
    out = {}
    for depth in sorted({r.depth for r in rows}):
        at = [r for r in rows if r.depth == depth and not kinds[r.sampler].deterministic
              and r.relative_efficiency.known]
        if not at:
            continue
        top = _best(at)
        ladder = points[depth]

        def untold(r: Row) -> bool:
            e = ratio(ladder[r.sampler][-1], ladder[top.sampler][-1])
            return r is top or (e.known and not e.excludes(1.0))
        tied = [r for r in at if untold(r)]
        chosen = tied[-1]
        out[depth] = Pick(depth, chosen.sampler, chosen.spp, chosen.requested, top.sampler,
                          tuple(r.sampler for r in tied))
    return out


# ------------------------------------------------------------ everything at once

@dataclass(frozen=True)
class Analysis:
    rows: list                  # Row per depth and label
    curves: dict                # {depth: {label: [(spp, Estimate)]}}
    comparisons: list           # Comparison rows of every depth
    best: dict                  # {depth: Row of the most efficient label}
    picks: dict = field(default_factory=dict)   # {depth: Pick}, see :func:`picks`


def analyse(points: dict[int, dict[str, list[Point]]], pixels: int,
            kinds: dict[str, Family]) -> Analysis:
    """Everything the report says, from the numbers alone."""
    rows = table(points, pixels)
    comps = comparisons(rows, points, kinds)
    depths = sorted(points)
    return Analysis(rows, curves(points), comps,
                    {d: _best([r for r in rows if r.depth == d]) for d in depths},
                    picks(rows, points, kinds))
