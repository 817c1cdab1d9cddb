"""The sampler study's screen-space analysis: numbers in, numbers and verdicts out.

The screen-space pass (:func:`analyse_screen`): :class:`ScreenPoint` holds a label's
mean FLIP, low-frequency share of the error spectrum (:mod:`experiments.lib.screen_space`)
and MSE per repeat at one count; the result is a :class:`ScreenRow` per label and count, a
:class:`ScreenComparison` per pair and count (each bundled family's lowest-FLIP label
against every native label and the other families': mean FLIP A / B, share A / B and MSE
efficiency A / B, each with its interval and a verdict only where the interval excludes
1, FLIP only between equal counts rendered); the sentences made from them are the report
layer's (:func:`.sampler_comparison.words.screen_sentences`).

Every label renders every count of a short ladder R times at a resolution with a spectrum
worth the name (128x128 by default). Per count: the mean FLIP against the reference, the
low-frequency share of the error's power spectrum (:mod:`experiments.lib.screen_space`), and
the MSE and render time (for the MSE efficiency), each over the repeats. The conclusion
compares each bundled sampler family's best label (lowest mean FLIP at the largest count)
with every native sampler and with the other families' best, at every count, in three ways:
mean FLIP A / B (below 1: A is better), low-frequency share A / B (below 1: A's error is
bluer) and MSE efficiency A / B (above 1: A is better); a verdict only where the interval
excludes 1, in FLIP only where both rendered the same count (orthogonal renders 25 samples
for 16: more samples, not a better sampler; the efficiency, per unit of time, allows for
it).

Which label is bundled and which native comes from :class:`.sampler_comparison.analysis.Family`
values (the sampler table's ``native``), never from a name. Tests feed synthetic points
whose answer is known.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from experiments.lib import stats
from experiments.lib.studies.sampler_comparison.analysis import (
    Family, Point, ratio, sign)


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


@dataclass(frozen=True)
class ScreenAnalysis:
    rows: list                  # ScreenRow per depth, label and count
    comparisons: list           # ScreenComparison per depth, pair and count
    kinds: dict                 # {label: Family}
    white: float                # the low-frequency share of white noise on this grid


def analyse_screen(points: dict[int, dict[str, list[ScreenPoint]]], pixels: int,
                   kinds: dict[str, Family], white: float) -> ScreenAnalysis:
    """The screen-space pass's report, from the numbers alone."""
    rows = screen_rows(points, pixels)
    comps = screen_comparisons(points, kinds)
    return ScreenAnalysis(rows, comps, kinds, white)
