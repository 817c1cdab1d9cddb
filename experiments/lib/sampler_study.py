"""The sampler study's numbers and its conclusion (no rendering here).

Every sampler renders every count of the ladder R times with independent
randomizations. :func:`table` turns those renders into one row per sampler and
depth at the largest count: expected MSE and relMSE over the repeats (the
reference's own expected error subtracted), time per sample, Veach efficiency
1/(MSE x time) relative to ``independent``, each with its 95% interval
(:mod:`.stats`), and the fitted slope of MSE against spp. :func:`curves` gives
the relative efficiency at every count of the ladder; :func:`conclude` writes
the conclusion from those numbers alone: which sampler wins at each depth and
whether the interval lets us say so, where halton stands against the best
native sampler, and at which counts the order between halton and each native
sampler changes. Tests feed it synthetic points whose answer is known.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import metrics, stats

BASELINE = "independent"


@dataclass(frozen=True)
class Point:
    """A sampler at one count of the ladder, over R repeats."""
    spp: int                    # samples per pixel actually rendered
    seconds: tuple              # warm render time per repeat
    mse: tuple                  # MSE per repeat (reference floor subtracted)
    relmse: tuple
    requested: int = 0          # the ladder's count (0: the same as spp)


@dataclass(frozen=True)
class Row:
    """A sampler at one depth, at the largest count of its ladder."""
    depth: int
    sampler: str                # independent, ..., halton:owen
    spp: int                    # rendered (orthogonal: a prime squared, stratified: a square)
    requested: int
    repeats: int
    mse: stats.Estimate
    relmse: stats.Estimate
    us_per_sample: float
    relative_efficiency: stats.Estimate   # efficiency / independent's at the same depth
    relative_mse: stats.Estimate          # MSE / independent's
    slope: float                          # fitted slope of log MSE against log spp

    def record(self) -> dict:
        """Flat fields for summary.json (intervals as ``*_lo`` / ``*_hi``)."""
        out = {"depth": self.depth, "sampler": self.sampler, "spp": self.spp,
               "requested_spp": self.requested, "repeats": self.repeats,
               "us_per_sample": self.us_per_sample, "slope": self.slope}
        for name in ("mse", "relmse", "relative_efficiency", "relative_mse"):
            out.update(getattr(self, name).fields(name))
        return out


def sampler_label(method_sampler: str, randomization: str | None) -> str:
    return method_sampler + (f":{randomization}" if randomization else "")


def _base(by_sampler: dict) -> str:
    return BASELINE if BASELINE in by_sampler else next(iter(by_sampler))


def _ratio(a: Point, b: Point) -> stats.Estimate:
    """Efficiency of ``a`` over ``b``."""
    return stats.efficiency_ratio(a.mse, a.seconds, b.mse, b.seconds)


def table(points: dict[int, dict[str, list[Point]]], pixels: int) -> list[Row]:
    """Rows from ``points[depth][sampler]`` (ladder points, increasing spp)."""
    rows = []
    for depth, by_sampler in points.items():
        base = by_sampler[_base(by_sampler)][-1]
        for s, pts in by_sampler.items():
            p = pts[-1]
            mean_seconds = sum(p.seconds) / len(p.seconds)
            rows.append(Row(depth, s, p.spp, p.requested or p.spp, len(p.mse),
                            stats.mean_interval(p.mse), stats.mean_interval(p.relmse),
                            mean_seconds / (p.spp * pixels) * 1e6, _ratio(p, base),
                            stats.ratio_interval([p.mse], [base.mse]),
                            metrics.loglog_slope([q.spp for q in pts],
                                                 [sum(q.mse) / len(q.mse) for q in pts])))
    return rows


def curves(points: dict[int, dict[str, list[Point]]]) -> dict[int, dict[str, list]]:
    """``{depth: {sampler: [(spp rendered, efficiency / independent's at that count)]}}``."""
    out = {}
    for depth, by_sampler in points.items():
        base = by_sampler[_base(by_sampler)]
        out[depth] = {s: [(p.spp, _ratio(p, b)) for p, b in zip(pts, base)]
                      for s, pts in by_sampler.items()}
    return out


def _sign(e: stats.Estimate) -> int:
    """+1: more efficient (interval above 1), -1: less (below 1), 0: not distinguishable."""
    return 0 if not e.excludes(1.0) else (1 if e.value > 1 else -1)


WORDS = {1: "more efficient", -1: "less efficient", 0: "not distinguishable"}


def order_changes(a: list[Point], b: list[Point]) -> list[tuple[int, int, stats.Estimate]]:
    """``(count of a, sign, efficiency a / b)`` at every count of two ladders."""
    return [(p.spp, _sign(r), r) for p, q in zip(a, b) for r in [_ratio(p, q)]]


def describe_order(name_a: str, name_b: str, changes) -> str:
    """'Against B, A is less efficient at 1-4 spp, ... and more efficient from 64 spp'; plus
    'A overtakes B from N spp' when it wins from some count to the end and not before."""
    signs = [s for _, s, _ in changes]
    if signs and set(signs) == {0}:
        return (f"against {name_b}, {name_a} is not distinguishable at any count of the "
                f"ladder ({changes[0][0]}-{changes[-1][0]} spp)")
    runs: list[list] = []
    for spp, sign, _ in changes:
        if runs and runs[-1][0] == sign:
            runs[-1][2] = spp
        else:
            runs.append([sign, spp, spp])
    parts = []
    for i, (sign, lo, hi) in enumerate(runs):
        last = i == len(runs) - 1 and i > 0
        where = (f"from {lo} spp" if last and lo != hi else
                 f"at {lo} spp" if lo == hi else f"at {lo}-{hi} spp")
        parts.append(f"{WORDS[sign]} {where}")
    text = f"against {name_b}, {name_a} is " + ", ".join(parts)
    if signs and signs[-1] == 1 and any(s != 1 for s in signs):
        first = next(i for i in range(len(signs)) if all(s == 1 for s in signs[i:]))
        text += f" ({name_a} overtakes {name_b} from {changes[first][0]} spp)"
    elif signs and signs[-1] == -1 and any(s != -1 for s in signs):
        first = next(i for i in range(len(signs)) if all(s == -1 for s in signs[i:]))
        text += f" ({name_b} overtakes {name_a} from {changes[first][0]} spp)"
    elif signs and len(set(signs)) == 1:
        text += " (the order does not change within the ladder)"
    return text


def halton_vs_native(rows: list[Row], points: dict) -> dict[int, tuple[str, str, stats.Estimate]]:
    """Per depth: halton's best randomization, the best native sampler (both by efficiency
    at the largest count) and the efficiency ratio of the first over the second."""
    out = {}
    for depth in sorted({r.depth for r in rows}):
        at = [r for r in rows if r.depth == depth]
        halton = [r for r in at if r.sampler.startswith("halton")]
        native = [r for r in at if not r.sampler.startswith("halton")]
        if halton and native:
            h = max(halton, key=lambda r: r.relative_efficiency.value)
            n = max(native, key=lambda r: r.relative_efficiency.value)
            out[depth] = (h.sampler, n.sampler, _ratio(points[depth][h.sampler][-1],
                                                       points[depth][n.sampler][-1]))
    return out


def conclude(rows: list[Row], points: dict[int, dict[str, list[Point]]]) -> list[str]:
    """One paragraph per depth, computed from the rows and the ladder points."""
    sentences = []
    for depth in sorted({r.depth for r in rows}):
        at = [r for r in rows if r.depth == depth]
        by_sampler = points[depth]
        best = max(at, key=lambda r: r.relative_efficiency.value)
        lowest = min(at, key=lambda r: r.mse.value)
        text = (f"At max_depth {depth} and {best.requested} spp ({best.repeats} independent "
                f"runs each), {best.sampler} has the highest efficiency 1/(MSE x time): "
                f"{best.relative_efficiency.text()}x {BASELINE}'s")
        others = [r for r in at if r is not best]
        if others:
            second = max(others, key=lambda r: r.relative_efficiency.value)
            text += ("; " + stats.verdict(best.sampler, second.sampler,
                                          _ratio(by_sampler[best.sampler][-1],
                                                 by_sampler[second.sampler][-1])))
        text += (f". The lowest expected MSE is {lowest.sampler}'s "
                 f"({lowest.relative_mse.text()}x {BASELINE}'s at {lowest.spp} spp).")
        pair = halton_vs_native(at, points).get(depth)
        if pair:
            h, n, hn = (next(r for r in at if r.sampler == pair[0]),
                        next(r for r in at if r.sampler == pair[1]), pair[2])
            base = next((r for r in at if r.sampler == BASELINE), at[0])
            text += (f" Halton's best randomization at this count, {h.sampler}, reaches "
                     f"{h.relative_efficiency.text()}x {BASELINE}'s efficiency (MSE "
                     f"{h.relative_mse.text()}x, "
                     f"{h.us_per_sample / base.us_per_sample:.2f}x its time per sample); "
                     f"against the best native sampler, {n.sampler}: "
                     + stats.verdict(h.sampler, n.sampler, hn) + ".")
            changes = [describe_order(h.sampler, s, order_changes(by_sampler[h.sampler],
                                                                  by_sampler[s]))
                       for s in by_sampler if not s.startswith("halton")]
            text += " Over the ladder, " + "; ".join(changes) + "."
        sentences.append(text)
    return sentences
