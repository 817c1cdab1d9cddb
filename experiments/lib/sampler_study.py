"""The sampler study's analysis: numbers in, numbers and sentences out (no rendering, no files).

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
- at most three sentences per depth computed from those rows (:func:`sentences`), and the
  most efficient label per depth with the count it was chosen at.

The screen-space pass (:func:`analyse_screen`): :class:`ScreenPoint` holds a label's
mean FLIP, low-frequency share of the error spectrum (:mod:`.screen_space`) and MSE per
repeat at one count; the result is a :class:`ScreenRow` per label and count, a
:class:`ScreenComparison` per pair and count (each bundled family's lowest-FLIP label
against every native label and the other families': mean FLIP A / B, share A / B and MSE
efficiency A / B, each with its interval and a verdict only where the interval excludes
1, FLIP only between equal counts rendered) and at most three sentences per depth computed from them (:func:`screen_sentences`).

Which label is bundled and which native comes from :class:`Family` values (the sampler
table's ``native``), never from a name. Tests feed synthetic points whose answer is known.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from . import metrics, stats
from . import samplers as S

#: The sampler every efficiency and MSE is relative to.
BASELINE = S.DEFAULT
#: The error of the efficiency 1/(error x time) that every verdict uses.
METRIC = "relmse"
METRIC_NAMES = {"mse": "MSE", "relmse": "relMSE"}
#: Roles of the conclusion table's rows.
BEST, BUNDLED, NATIVE = "most efficient / runner-up", "bundled best / best native", \
    "bundled best / native"


@dataclass(frozen=True)
class Family:
    """What the analysis knows of a label's sampler: its name and whether it is native."""
    name: str
    native: bool


def families(labels) -> dict[str, Family]:
    """``{label: Family}`` from the sampler table (:mod:`.samplers`)."""
    out = {}
    for label in labels:
        spec, _ = S.split_label(label)
        out[label] = Family(spec.name, spec.native)
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


def _overtake_text(c: Comparison) -> str:
    winner, loser, n = c.overtakes
    last = c.changes[-1][0]
    return (f"{winner} overtakes {loser} at the largest count ({n} spp)" if n == last else
            f"{winner} overtakes {loser} from {n} spp")


def sentences(table_rows: list[Comparison], limit: int = 3) -> list[str]:
    """At most three sentences about one depth, computed from its conclusion table alone:
    the winner, the bundled samplers against the best native one, and where the order
    between a bundled and a native sampler changes along the ladder."""
    out = []
    best = next((c for c in table_rows if c.role == BEST), None)
    bundled = [c for c in table_rows if c.role == BUNDLED]
    same = [c for c in bundled if best is not None and {c.a, c.b} == {best.a, best.b}]
    if best is not None:
        runner = (f"{best.b} (also the best native sampler)"
                  if same and same[0].b == best.b else best.b)
        out.append(f"At max_depth {best.depth} and {best.spp} spp, {best.a} is the most "
                   f"efficient sampler by {METRIC_NAMES[METRIC]}; against the runner-up, "
                   f"{runner}: {best.verdict}.")
    rest = [c for c in bundled if c not in same]
    if rest:
        out.append(f"Against the best native sampler, {rest[0].b}: "
                   + "; ".join(c.verdict for c in rest) + ".")
    ladder = [c for c in table_rows if c.role in (BUNDLED, NATIVE)]
    moves = [c for c in ladder if c.overtakes]
    flips = [c for c in ladder if c.onsets]
    if moves:
        more = f" and {len(moves) - 3} more (table)" if len(moves) > 3 else ""
        out.append("Along the ladder, " + "; ".join(map(_overtake_text, moves[:3]))
                   + f"{more}.")
    elif flips:
        out.append(f"Along the ladder the order changes without a lasting winner in "
                   f"{len(flips)} comparison(s) (table).")
    elif bundled:
        first = bundled[0].changes
        span = f" ({first[0][0]}-{first[-1][0]} spp)" if first else ""
        out.append(f"No order between a bundled and a native sampler changes along the "
                   f"ladder{span}.")
    return out[:limit]


# ------------------------------------------------------------ everything at once

@dataclass(frozen=True)
class Analysis:
    rows: list                  # Row per depth and label
    curves: dict                # {depth: {label: [(spp, Estimate)]}}
    comparisons: list           # Comparison rows of every depth
    conclusions: dict           # {depth: [sentence]}
    best: dict                  # {depth: Row of the most efficient label}


def analyse(points: dict[int, dict[str, list[Point]]], pixels: int,
            kinds: dict[str, Family]) -> Analysis:
    """Everything the report says, from the numbers alone."""
    rows = table(points, pixels)
    comps = comparisons(rows, points, kinds)
    depths = sorted(points)
    return Analysis(rows, curves(points), comps,
                    {d: sentences([c for c in comps if c.depth == d]) for d in depths},
                    {d: _best([r for r in rows if r.depth == d]) for d in depths})


# ------------------------------------------------------------ the screen-space pass
#
# Every label renders every count of a short ladder R times at a resolution with a
# spectrum worth the name (128x128 by default). Per count: the mean FLIP against the
# reference, the low-frequency share of the error's power spectrum
# (:mod:`.screen_space`), and the MSE and render time (for the MSE efficiency), each over
# the repeats. The conclusion compares each bundled sampler family's best label (lowest
# mean FLIP at the largest count) with every native sampler and with the other families'
# best, at every count, in three ways: mean FLIP A / B (below 1: A is better), low-frequency
# share A / B (below 1: A's error is bluer) and MSE efficiency A / B (above 1: A is
# better); a verdict only where the interval excludes 1, in FLIP only where both rendered
# the same count (orthogonal renders 25 samples for 16: more samples, not a better
# sampler; the efficiency, per unit of time, allows for it).

@dataclass(frozen=True)
class ScreenPoint:
    """A sampler at one count of the screen-space pass, over R repeats."""
    spp: int                    # samples per pixel rendered
    flip: tuple                 # mean FLIP per repeat, against the reference
    share: tuple                # low-frequency share per repeat (reference floor subtracted)
    error: Point                # MSE, relMSE and render times per repeat
    frequencies: tuple = ()     # the spectrum's frequencies (cycles per pixel)
    power: tuple = ()           # radially averaged power, mean over repeats (white noise 1)
    requested: int = 0          # the ladder's count (0: the same as spp)

    @property
    def repeats(self) -> int:
        return len(self.flip)

    def mean_flip(self) -> stats.Estimate:
        return stats.mean_interval(self.flip)

    def mean_share(self) -> stats.Estimate:
        return stats.mean_interval(self.share)


@dataclass(frozen=True)
class ScreenRow:
    """A sampler at one depth and count: a row of the screen-space table."""
    depth: int
    sampler: str
    spp: int
    requested: int
    repeats: int
    flip: stats.Estimate
    share: stats.Estimate
    mse: stats.Estimate         # expected MSE, the reference's floor subtracted
    us_per_sample: float

    def record(self) -> dict:
        out = {"depth": self.depth, "sampler": self.sampler, "spp": self.spp,
               "requested_spp": self.requested, "repeats": self.repeats,
               "us_per_sample": self.us_per_sample, "mse_bound": self.mse.bound}
        for name in ("flip", "share", "mse"):
            out.update(getattr(self, name).fields(name))
        return out


#: Phrases of a verdict's sign (+1: A is better, -1: B is better, 0: neither; None: not
#: compared, the two rendered different counts).
UNEQUAL = "not compared (unequal counts)"
FLIP_WORDS = {1: "lower", -1: "higher", 0: "not distinguishable", None: UNEQUAL}


def lower_sign(ratio: stats.Estimate) -> int:
    """For a ratio A / B where lower is better (FLIP, share): +1 when the interval lies
    below 1 (A is better), -1 above 1, 0 when it contains 1 or is unknown."""
    return 0 if not ratio.excludes(1.0) else (1 if ratio.value < 1 else -1)


def lower_verdict(a: str, b: str, ratio: stats.Estimate, what: str) -> str:
    """'A's mean FLIP is lower than B's: 0.82x (95% CI 0.8-0.84)', the other way round,
    or 'A and B are not distinguishable in mean FLIP (...)'."""
    s = lower_sign(ratio)
    if s:
        return (f"{a}'s {what} is {'lower' if s > 0 else 'higher'} than {b}'s: "
                f"{ratio.text()}x")
    if not math.isfinite(ratio.value):
        return f"{a} and {b} cannot be compared in {what}"
    why = (f"{ratio.level:.0%} CI {stats.g(ratio.lo)}-{stats.g(ratio.hi)} contains 1"
           if ratio.known else f"{ratio.n} run gives no interval")
    return (f"{a} and {b} are not distinguishable in {what} (ratio {stats.g(ratio.value)}, "
            f"{why})")


def _short(a: str, b: str, s: int | None, words: dict) -> str:
    if s is None:
        return UNEQUAL
    return words[0] if s == 0 else f"{a if s > 0 else b} {words[1]}"


@dataclass(frozen=True)
class ScreenComparison:
    """Label ``a`` against ``b`` at one depth and count of the screen-space pass."""
    depth: int
    a: str
    b: str
    spp: tuple                  # (a's, b's) count rendered
    requested: int
    flip: stats.Estimate        # mean FLIP a / b (below 1: a is better)
    share: stats.Estimate       # low-frequency share a / b (below 1: a's error is bluer)
    efficiency: stats.Estimate  # MSE efficiency a / b (above 1: a is more efficient)

    @property
    def equal(self) -> bool:
        """Both rendered the same count. FLIP is compared only then: a sampler that rounds
        the count up renders more samples (MSE efficiency, per unit of time, allows for
        that; the share, a shape of the spectrum and not a size, is compared anyway)."""
        return self.spp[0] == self.spp[1]

    @property
    def signs(self) -> tuple:
        """(FLIP, share, efficiency): +1 where a is better, -1 where b is, 0 neither; FLIP
        None where it is not compared (unequal counts)."""
        return (lower_sign(self.flip) if self.equal else None, lower_sign(self.share),
                sign(self.efficiency))

    def verdicts(self) -> tuple[str, str, str]:
        f, s, e = self.signs
        eff = ("cannot be compared (below the reference's noise)"
               if not math.isfinite(self.efficiency.value) else
               _short(self.a, self.b, e, {0: "not distinguishable", 1: "more efficient"}))
        return (_short(self.a, self.b, f, {0: "not distinguishable", 1: "lower FLIP"}),
                _short(self.a, self.b, s, {0: "not distinguishable", 1: "bluer"}), eff)

    def cells(self) -> list:
        def interval(e):
            return (f"{stats.g(e.lo)}-{stats.g(e.hi)}" if e.known else
                    "n/a" if not math.isfinite(e.value) else f"none ({e.n} run)")

        def value(e):
            return stats.g(e.value) if math.isfinite(e.value) else "n/a"
        vf, vs, ve = self.verdicts()
        return [self.depth, f"{self.a} / {self.b}", f"{self.spp[0]} / {self.spp[1]}",
                value(self.flip), interval(self.flip), vf,
                value(self.share), interval(self.share), vs,
                value(self.efficiency), interval(self.efficiency), ve]

    def record(self) -> dict:
        vf, vs, ve = self.verdicts()
        return {"depth": self.depth, "a": self.a, "b": self.b, "spp_a": self.spp[0],
                "spp_b": self.spp[1], "requested_spp": self.requested,
                **self.flip.fields("flip_ratio"), "flip_verdict": vf,
                **self.share.fields("share_ratio"), "share_verdict": vs,
                **self.efficiency.fields("mse_efficiency_ratio"), "efficiency_verdict": ve}


SCREEN_HEADER = ["max_depth", "A / B", "spp (A / B)", "mean FLIP A / B",
                 f"FLIP {stats.LEVEL:.0%} interval", "FLIP verdict",
                 "low-frequency share A / B", f"share {stats.LEVEL:.0%} interval",
                 "share verdict", "MSE efficiency A / B",
                 f"efficiency {stats.LEVEL:.0%} interval", "efficiency verdict"]


def screen_rows(points: dict[int, dict[str, list[ScreenPoint]]], pixels: int) -> list:
    """:class:`ScreenRow` per depth, label and count."""
    rows = []
    for depth, by_sampler in points.items():
        for s, pts in by_sampler.items():
            for p in pts:
                e = p.error
                rows.append(ScreenRow(depth, s, p.spp, p.requested or p.spp, p.repeats,
                                      p.mean_flip(), p.mean_share(), e.expected("mse"),
                                      sum(e.seconds) / len(e.seconds) / (p.spp * pixels)
                                      * 1e6))
    return rows


def compare_screen(depth: int, a: str, b: str, pa: ScreenPoint,
                   pb: ScreenPoint) -> ScreenComparison:
    return ScreenComparison(depth, a, b, (pa.spp, pb.spp), pa.requested or pa.spp,
                            stats.ratio_interval([pa.flip], [pb.flip]),
                            stats.ratio_interval([pa.share], [pb.share]),
                            ratio(pa.error, pb.error, "mse"))


def _lowest_flip(labels, by_sampler) -> str:
    return min(labels, key=lambda s: by_sampler[s][-1].mean_flip().value)


def screen_pairs(by_sampler: dict[str, list[ScreenPoint]],
                 kinds: dict[str, Family]) -> list[tuple[str, str]]:
    """(A, B): each bundled family's best label (lowest mean FLIP at the largest count)
    against every native label, then against each later family's best."""
    labels = list(by_sampler)
    native = [s for s in labels if kinds[s].native]
    families = list(dict.fromkeys(kinds[s].name for s in labels if not kinds[s].native))
    best = [_lowest_flip([s for s in labels if kinds[s].name == f], by_sampler)
            for f in families]
    return ([(a, n) for a in best for n in native]
            + [(a, b) for i, a in enumerate(best) for b in best[i + 1:]])


def screen_comparisons(points: dict, kinds: dict[str, Family]) -> list[ScreenComparison]:
    """Every pair of :func:`screen_pairs` at every count, per depth."""
    out = []
    for depth, by_sampler in points.items():
        for a, b in screen_pairs(by_sampler, kinds):
            out += [compare_screen(depth, a, b, pa, pb)
                    for pa, pb in zip(by_sampler[a], by_sampler[b])]
    return out


def _along(changes, words: dict) -> str:
    """:func:`order_text` without its '(no change)'."""
    return order_text(changes, words).removesuffix(" (no change)")


def _fit(parts: list[str], head: str, tail: str = ".", limit: int = 80) -> str:
    """``head`` + the parts joined by '; ' + ``tail``, leaving out the last parts (said to
    be in the table) where the sentence would pass ``limit`` words."""
    for n in range(len(parts), 0, -1):
        more = "" if n == len(parts) else "; the others in the table"
        text = head + "; ".join(parts[:n]) + more + tail
        if len(text.split()) <= limit:
            return text
    return head + "see the table" + tail


def screen_sentences(depth: int, comps: list[ScreenComparison], rows: list[ScreenRow],
                     kinds: dict[str, Family], white: float) -> list[str]:
    """At most three sentences about one depth, from its comparisons and rows alone: each
    bundled family's best against the best native sampler in mean FLIP along the ladder;
    the counts at which its error is bluer than every native sampler's; and its MSE
    efficiency against the most efficient native sampler."""
    mine = [c for c in comps if c.depth == depth]
    at = [r for r in rows if r.depth == depth]
    if not mine:
        return []
    top = max(r.requested for r in at)
    last = [r for r in at if r.requested == top]
    natives = [r for r in last if kinds[r.sampler].native]
    if not natives:
        return []
    families = list(dict.fromkeys(c.a for c in mine if kinds[c.a].name != kinds[c.b].name
                                  and kinds[c.b].native))

    def ladder(a, b):
        return [c for c in mine if (c.a, c.b) == (a, b)]

    # the lowest FLIP among the natives that render the count asked for
    best = min([r for r in natives if r.spp == r.requested] or natives,
               key=lambda r: r.flip.value).sampler
    parts = []
    for a in families:
        cs = ladder(a, best)
        changes = [(c.spp[0], c.signs[0], c.flip) for c in cs]
        parts.append(f"{a} {_along(changes, FLIP_WORDS)}, ratio {cs[-1].flip.text()} at "
                     f"{cs[-1].spp[0]} spp")
    out = [_fit(parts, f"By mean FLIP at max_depth {depth}, against the native sampler "
                       f"lowest at {top} spp ({best}): ")]
    parts = []
    for a in families:
        against = [c for c in mine if c.a == a and kinds[c.b].native]
        counts = sorted({c.requested for c in against})
        bluer = [n for n in counts
                 if all(c.signs[1] > 0 for c in against if c.requested == n)]
        share = next(r.share for r in last if r.sampler == a)
        parts.append((f"{a} at {', '.join(map(str, bluer))} spp" if bluer else
                      f"{a} at no count") + f", share {share.text()} at {top} spp")
    lo, hi = min(r.share.value for r in natives), max(r.share.value for r in natives)
    out.append(_fit(parts, f"Error bluer than every native sampler's (low-frequency share, "
                           f"white noise {white:.3f}; natives {stats.g(lo)}-{stats.g(hi)} "
                           f"at {top} spp): "))
    known = [r for r in natives if not r.mse.bound and r.mse.value > 0]
    if known:
        # Veach's efficiency 1 / (MSE x time per pixel) of each native label
        eff = max(known, key=lambda r: 1 / (r.mse.value * r.us_per_sample * r.spp)).sampler
        parts = []
        for a in families:
            cs = ladder(a, eff)
            changes = [(c.spp[0], sign(c.efficiency), c.efficiency) for c in cs]
            parts.append(f"{a} {_along(changes, WORDS)}")
        out.append(_fit(parts, f"In MSE efficiency against the most efficient native "
                               f"sampler at {top} spp ({eff}): "))
    return out[:3]


@dataclass(frozen=True)
class ScreenAnalysis:
    rows: list                  # ScreenRow per depth, label and count
    comparisons: list           # ScreenComparison per depth, pair and count
    conclusions: dict           # {depth: [sentence]}
    white: float                # the low-frequency share of white noise on this grid


def analyse_screen(points: dict[int, dict[str, list[ScreenPoint]]], pixels: int,
                   kinds: dict[str, Family], white: float) -> ScreenAnalysis:
    """The screen-space pass's report, from the numbers alone."""
    rows = screen_rows(points, pixels)
    comps = screen_comparisons(points, kinds)
    return ScreenAnalysis(rows, comps, {d: screen_sentences(d, comps, rows, kinds, white)
                                        for d in sorted(points)}, white)
