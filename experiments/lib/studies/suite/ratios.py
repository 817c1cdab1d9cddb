"""Efficiency ratios with bounds: :class:`Ratio` (an interval, a bound or unknown) and
:func:`efficiency`, one cell's runs over another's (:class:`.analysis.Runs`), for the
suite's analysis (:mod:`.analysis`): pure functions of numbers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ... import stats
from . import errors

g = stats.g


#: Why a ratio is a bound (``Ratio.why``): an error below the reference's noise, or an
#: error that one pixel of one render rules (:func:`.errors.ruled`).
NOISE, TAIL = "noise", "tail"
BOUND_WORDS = {NOISE: "an error below the reference's noise",
               TAIL: "an error that one pixel of one render rules, so at least its rest"}


@dataclass(frozen=True)
class Ratio:
    """An efficiency ratio: an interval (``side`` ""), a lower bound (">"), an upper bound
    ("<"), or unknown ("?"); ``why`` a bound (:data:`BOUND_WORDS`): the numerator's error
    (">") or the denominator's ("<") is below the reference's noise, or the denominator's
    (">") or the numerator's ("<") is ruled by one pixel of one render, so that only its
    rest is known, a lower bound of it. ``typical``: the same ratio from the median of each
    cell's renders' own expected errors (:func:`.errors.typical_efficiency`; nan where not
    known)."""
    est: stats.Estimate
    side: str = ""
    typical: float = math.nan
    why: str = NOISE

    @property
    def value(self) -> float:
        return self.est.value

    @property
    def firm(self) -> bool:
        """Whether the interval, moved to the typical ratio, is on the same side of 1: a
        verdict that one render's rare firefly makes (its cell's mean error ruled by it,
        its median not) is no verdict (:func:`.errors.typical_efficiency`)."""
        if not math.isfinite(self.typical) or not self.est.known or not self.value > 0:
            return True
        shift = self.typical / self.value
        if self.est.lo > 1:
            return self.est.lo * shift > 1
        return self.est.hi >= 1 or self.est.hi * shift < 1

    def greater(self) -> bool:
        """Above 1 at the interval's level, and firmly so (:attr:`firm`)."""
        if self.side == ">":
            return self.value > 1
        return self.side == "" and self.est.known and self.est.lo > 1 and self.firm

    def less(self) -> bool:
        if self.side == "<":
            return self.value < 1
        return self.side == "" and self.est.known and self.est.hi < 1 and self.firm

    def score(self) -> float:
        """For ranking: the value (a lower bound counts as its value), unknown last."""
        return self.value if self.side != "?" and math.isfinite(self.value) else -math.inf

    def text(self) -> str:
        if self.side == "?":
            return ("unknown (both errors below the reference's noise)" if self.why == NOISE
                    else "unknown (both errors ruled by one pixel of one render)")
        if self.side in "<>" and self.side:
            return f"{self.side} {g(self.value)} ({BOUND_WORDS[self.why]})"
        return self.est.text()

    def short(self) -> str:
        """'3.1 [2.0, 4.8]', '> 3.1', '1.2' (no interval), '?'."""
        if self.side == "?":
            return "?"
        if self.side:
            return f"{self.side}{g(self.value)}"
        if not self.est.known:
            return g(self.value)
        return f"{g(self.value)} [{g(self.est.lo)}, {g(self.est.hi)}]"

    def fields(self, name: str) -> dict:
        return {**self.est.fields(name), f"{name}_bound": self.side}


def _shift(values, floor: float) -> list[float]:
    return [float(v) - floor for v in values]


def efficiency(a, b, floor: float, metric: str = "relmse") -> Ratio:
    """Efficiency 1/(error x time) of ``a`` over ``b`` (errors over the reference's own
    expected error ``floor``). Where one error is below the reference's noise, its upper
    bound gives a bound on the ratio; where both are, it is unknown. Where both have the
    pixels' pass variances (relMSE only): :func:`.errors.efficiency`."""
    precise = errors.efficiency(a, b) if metric == "relmse" else None
    if precise is not None:
        typical = errors.typical_efficiency(a, b)
        if (errors.ruled(a) or errors.ruled(b)) and a is not b:
            return _tail_bound(a, b, typical)
        return Ratio(precise, typical=typical)
    ea, eb = (getattr(r, metric) for r in (a, b))
    xa, xb = stats.excess_interval(ea, floor), stats.excess_interval(eb, floor)
    n = min(len(ea), len(eb))
    if xa.bound and xb.bound or (xa.bound and xa.hi <= 0) or (xb.bound and xb.hi <= 0):
        return Ratio(stats.Estimate(math.nan, math.nan, math.nan, n), "?")
    if not xa.bound and not xb.bound:
        return Ratio(stats.ratio_interval([_shift(eb, floor), list(b.seconds)],
                                          [_shift(ea, floor), list(a.seconds)]))
    if xa.bound:      # a's error < xa.hi: a is at least this efficient
        r = stats.ratio_interval([_shift(eb, floor), list(b.seconds)],
                                 [[xa.hi] * len(ea), list(a.seconds)])
        low = r.lo if r.known else r.value
        return Ratio(stats.Estimate(low, low, math.inf, n), ">")
    r = stats.ratio_interval([[xb.hi] * len(eb), list(b.seconds)],
                             [_shift(ea, floor), list(a.seconds)])
    high = r.hi if r.known else r.value
    return Ratio(stats.Estimate(high, 0.0, high, n), "<")


def _tail_bound(a, b, typical: float) -> Ratio:
    """The efficiency of ``a`` over ``b`` where one pixel of one render rules the error of
    one of them (:func:`.errors.ruled`): that error is at least its estimate without the
    term (``Runs.rest``), so the interval's end on that side, computed with the rest, is a
    bound; unknown where both are ruled (or the rest is no error)."""
    n = min(len(a.relmse), len(b.relmse))
    unknown = Ratio(stats.Estimate(math.nan, math.nan, math.nan, n), "?", typical, TAIL)
    if errors.ruled(a) and errors.ruled(b):
        return unknown
    if errors.ruled(b):       # b's error at least its rest: a at least this efficient
        r = errors.efficiency(a, replace(b, expected=b.rest))
        if r is None:
            return unknown
        low = r.lo if r.known else r.value
        return Ratio(stats.Estimate(low, low, math.inf, n), ">", typical, TAIL)
    r = errors.efficiency(replace(a, expected=a.rest), b)
    if r is None:
        return unknown
    high = r.hi if r.known else r.value
    return Ratio(stats.Estimate(high, 0.0, high, n), "<", typical, TAIL)
