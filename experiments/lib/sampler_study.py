"""The sampler study's numbers and its conclusion (no rendering here).

:func:`table` turns the renders of every sampler at every spp of the ladder
into rows (MSE, relMSE, time per sample, Veach efficiency 1/(MSE x time)
relative to ``independent``, fitted slope of MSE against spp);
:func:`conclude` writes the conclusion from those rows alone: which sampler
wins at each depth and by how much, and where ``halton`` stands. Tests feed
it synthetic rows whose winner is known.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import metrics

BASELINE = "independent"


@dataclass(frozen=True)
class Point:
    """One render of the ladder: a sampler at one sample count."""
    spp: int            # samples per pixel actually rendered
    seconds: float      # warm render time
    mse: float
    relmse: float


@dataclass(frozen=True)
class Row:
    """A sampler at one depth, at the largest sample count of its ladder."""
    depth: int
    sampler: str        # independent, ..., halton:owen
    spp: int
    mse: float
    relmse: float
    us_per_sample: float
    efficiency: float   # 1 / (MSE x seconds)
    relative_efficiency: float   # efficiency / independent's at the same depth
    relative_mse: float          # MSE / independent's
    slope: float                 # fitted slope of log MSE against log spp


def sampler_label(method_sampler: str, randomization: str | None) -> str:
    return method_sampler + (f":{randomization}" if randomization else "")


def table(points: dict[int, dict[str, list[Point]]], pixels: int) -> list[Row]:
    """Rows from ``points[depth][sampler]`` (ladder points, increasing spp)."""
    rows = []
    for depth, by_sampler in points.items():
        last = {s: pts[-1] for s, pts in by_sampler.items()}
        eff = {s: metrics.efficiency(p.mse, p.seconds) for s, p in last.items()}
        base = BASELINE if BASELINE in last else next(iter(last))
        for s, pts in by_sampler.items():
            p = last[s]
            rows.append(Row(depth, s, p.spp, p.mse, p.relmse,
                            p.seconds / (p.spp * pixels) * 1e6, eff[s],
                            metrics.ratio(eff[s], eff[base]),
                            metrics.ratio(p.mse, last[base].mse),
                            metrics.loglog_slope([q.spp for q in pts], [q.mse for q in pts])))
    return rows


def conclude(rows: list[Row]) -> list[str]:
    """One sentence per depth, computed from the rows."""
    sentences = []
    for depth in sorted({r.depth for r in rows}):
        at = [r for r in rows if r.depth == depth]
        best = max(at, key=lambda r: r.efficiency)
        lowest = min(at, key=lambda r: r.mse)
        native = [r for r in at if not r.sampler.startswith("halton")]
        halton = [r for r in at if r.sampler.startswith("halton")]
        text = (f"At max_depth {depth}, {best.sampler} is the most efficient sampler: "
                f"{best.relative_efficiency:.2f}x the efficiency 1/(MSE x time) of "
                f"{BASELINE}")
        others = [r for r in at if r is not best]
        if others:
            second = max(others, key=lambda r: r.efficiency)
            text += (f", {best.efficiency / second.efficiency:.2f}x the next best "
                     f"({second.sampler})")
        text += (f"; the lowest MSE is {lowest.sampler}'s ({lowest.relative_mse:.2f}x "
                 f"{BASELINE}'s at {lowest.spp} spp).")
        if halton and native:
            h = max(halton, key=lambda r: r.efficiency)
            n = max(native, key=lambda r: r.efficiency)
            text += (f" Halton's best randomization, {h.sampler}, reaches "
                     f"{h.relative_efficiency:.2f}x {BASELINE}'s efficiency "
                     f"(MSE {h.relative_mse:.2f}x, "
                     f"{h.us_per_sample / _base(at).us_per_sample:.2f}x its time per sample): {h.efficiency / n.efficiency:.2f}x the best "
                     f"native sampler's ({n.sampler}), so it "
                     + ("wins." if h.efficiency > n.efficiency else "does not win."))
        sentences.append(text)
    return sentences


def _base(rows: list[Row]) -> Row:
    return next((r for r in rows if r.sampler == BASELINE), rows[0])
