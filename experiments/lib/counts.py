"""The engine's counting rules, as pure functions: how many samples a render takes.

* :func:`equal_time_spp`: the count that costs an equal-time budget's seconds at the cost
  per sample measured (the method's fixed cost per job taken off first);
* :func:`reference_spp`: the samples that bring a reference's own error (its floor) under
  the share of the smallest error measured against it that a comparison needs.

A learning method's equal-time count comes from a pilot render (:meth:`.engine.Engine.pilot`)
and is exact: never rounded to a power of two. Its efficiency grows with its count, so a
rounding that gave it 0.71 to 1.41 times the budget would move its verdict with the
rounding, and two runs whose pilots cost a few percent apart could measure it at counts a
factor of two apart. Where its training thresholds fall near its budget, the count that
its pilot's cost gives may not train although the pilot did (or the reverse): the cost it
was measured at is then not its cost. :func:`learner_spp` decides such a count by the
regime whose count comes nearest the budget (:func:`seconds_at`, :func:`least`).
"""
from __future__ import annotations

import math

import numpy as np

from . import clock


def _costs(measured: list) -> tuple[float, float]:
    """(fixed seconds per job, seconds per sample) of the ``measured`` renders (a list per
    repeat of results; the repeats' costs averaged): their fixed cost per job is
    :func:`.clock.fixed`, a learning method's host work between passes, which a short
    render would otherwise spread over its few samples."""
    fixed = np.mean([sum(clock.fixed(r) for r in rs) / len(rs) for rs in measured])
    per_sample = np.mean([(clock.total(rs) - sum(clock.fixed(r) for r in rs)) /
                          sum(r.spp for r in rs) for rs in measured])
    return float(fixed), float(per_sample)


def seconds_at(spp: int, measured: list) -> float:
    """What a job of ``spp`` samples per pixel costs at the ``measured`` renders' costs
    (:func:`_costs`): the inverse of :func:`equal_time_spp` before its rounding."""
    fixed, per_sample = _costs(measured)
    return fixed + spp * per_sample


def equal_time_spp(seconds: float, measured: list, power_of_two: bool = False,
                   max_spp: int = 0) -> int:
    """Samples per pixel that cost ``seconds`` at the cost per sample of the ``measured``
    renders (:func:`_costs`: their fixed cost per job taken off first); rounded to the
    nearest power of two where ``power_of_two``; at most ``max_spp`` (0: no cap)."""
    fixed, per_sample = _costs(measured)
    spp = (seconds - fixed) / max(per_sample, 1e-12)
    if power_of_two:
        spp = 2 ** max(0, round(math.log2(max(spp, 1.0))))
    spp = max(1, int(spp))
    return min(spp, max_spp) if max_spp else spp


def least(trains, hi: int) -> int:
    """The smallest count from 1 to ``hi`` at which ``trains(count)`` (monotone: false
    below a threshold, true from it on) holds; ``hi`` where none below it does."""
    lo = 1
    while lo < hi:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if trains(mid) else (mid + 1, hi)
    return hi


def learner_spp(seconds: float, pilot_spp: int, count: int, trains, piloted: list,
                plain: list) -> int:
    """A learning method's equal-time count from its pilot: ``count``, what the pilot of
    ``pilot_spp`` samples (its results ``piloted``) gives for ``seconds``, where it trains
    as the pilot did (``trains(spp)``: the method's training thresholds). Otherwise the
    pilot's cost is not that count's cost, and the budget falls between the regimes:
    where the pilot trained, of the least count that trains (at the pilot's cost) and the
    one below it (plain: at the cost of the ``plain`` renders, which did not train), the
    one whose seconds come nearest the budget (by their ratio); where the pilot did not
    train, the most that does not."""
    if trains(count) == trains(pilot_spp):
        return count
    first = least(trains, max(count, pilot_spp))
    if not trains(pilot_spp):
        return max(1, first - 1)
    options = [(first, seconds_at(first, piloted)), (first - 1, seconds_at(first - 1, plain))]
    return min((o for o in options if o[0] >= 1),
               key=lambda o: abs(math.log(max(o[1], 1e-12) / seconds)))[0]


def floor_share(floor: float, errors) -> float:
    """A reference's own expected relMSE ``floor`` over the smallest positive error of
    ``errors`` (0 without one)."""
    smallest = min((x for x in errors if x > 0), default=math.inf)
    return floor / smallest if math.isfinite(smallest) else 0.0


def share_at(share: float, spp: int, more: int) -> float:
    """The floor share ``share`` of a reference of ``spp`` samples at ``more`` samples (the
    floor falls as 1/spp, the measured error's own part stays)."""
    if share >= 1:
        return 1.0
    ratio = share / (1 - share) * spp / more
    return ratio / (1 + ratio)


def reference_cap(spp: int, seconds: float, max_spp: int, max_seconds: float,
                  share: float = 1.0, wanted: float = 0.0) -> int:
    """The most samples a reference of ``spp`` samples that took ``seconds`` is extended to:
    ``max_spp``, or where its floor ``share`` would still be over ``wanted`` there, more,
    as far as the whole then costs at most ``max_seconds`` at its time per sample (a cheap
    scene's heavy tails need more samples than its budget's share gives them); a power of
    two times ``spp``."""
    cap = max(max_spp, spp)
    if max_seconds > 0 and seconds > 0 and share_at(share, spp, cap) > wanted:
        affordable = max_seconds / seconds
        if affordable >= 2:
            cap = max(cap, spp * 2 ** int(math.floor(math.log2(affordable))))
    return cap


def reference_spp(share: float, wanted: float, spp: int, cap: int) -> int:
    """Reference spp for a reference whose floor is ``share`` of the smallest error measured
    against it, to bring that share to ``wanted / 2`` (so that the spread of the next
    measurement keeps it under ``wanted``), at most ``cap`` (a power of two times ``spp``);
    ``spp`` where the share is ``wanted`` or under. The measured error is the method's plus
    the floor f, and f falls as 1/spp: a share s = f / (e + f) becomes F after
    k = s (1 - F) / ((1 - s) F) times the samples."""
    target = wanted / 2
    if share <= wanted:
        return spp
    if share >= 1:
        return cap
    k = share * (1 - target) / ((1 - share) * target)
    return int(min(cap, spp * 2 ** math.ceil(math.log2(k))))
