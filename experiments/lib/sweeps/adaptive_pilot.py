"""Sweep 5: adaptive sampling where its pilot misleads it: fireflies and dark pixels.

Each method of :data:`PLAIN` renders plain and ``+adaptive`` (:mod:`integrators.adaptive`)
at the same samples per pixel, on the light sweep's scenes (:mod:`.light`: the light shrunk
from the whole ceiling to a tiny patch at constant power). Without NEE a small light is
found by BSDF sampling alone: a pixel's few pilot samples catch it or miss it by chance
(fireflies in the pilot), and the allocation follows what they caught; the pixels whose
pilot saw little light get the floor (dark pixels). Per point, the relMSE of the adaptive
method over its plain twin's, on the whole image and on the darkest :data:`DARK_SHARE` of
the reference's pixels, with intervals over the repeats: adaptive loses where the interval
is above 1. The cells are the light sweep's (its scene name and job keys), so a plain
method at the light sweep's samples renders once for both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import figures, metrics, prose, report, stats
from ..engine import Budget, Declaration, Measurements
from ..methods import ADAPTIVE
from ..scenes import box_filter
from .base import NAME, Context, Run, SweepReport, Skip, basis, budget, cells, exceeds, g, \
    label, mean_interval, onset, ratio, worst
from .light import SWEEP as LIGHT

#: The plain methods, each compared with its ``+adaptive`` twin.
PLAIN = ("bsdf", "bsdf+nee")
#: Share of the reference's pixels, the darkest, whose error is read on its own.
DARK_SHARE = 0.25
#: Fewest samples per pixel of a repeat: the pilot takes a quarter, at least 2.
MIN_SPP = 8


def adaptive(method: str) -> str:
    return f"{method}+{ADAPTIVE}"


def dark_mask(reference: np.ndarray, share: float = DARK_SHARE) -> np.ndarray:
    """The ``share`` of the pixels of ``reference`` (H, W, 3) whose luminance is lowest
    (at least one pixel)."""
    lum = metrics.luminance(reference)
    k = max(1, int(round(share * lum.size)))
    mask = np.zeros(lum.size, bool)
    mask[np.argsort(lum, axis=None, kind="stable")[:k]] = True
    return mask.reshape(lum.shape)


@dataclass(frozen=True)
class AdaptiveData:
    """``runs[method][point][repeat]`` for every method of ``plain`` and its twin."""
    xs: list
    runs: dict[str, list[list[Run]]]
    plain: tuple
    spp: int


@dataclass(frozen=True)
class AdaptiveComparison:
    method: str               # the plain method
    ratio: list               # Estimate per point: relMSE(adaptive) / relMSE(plain)
    dark: list                # ... on the dark pixels
    loses_from: float | None  # first point where the ratio is above 1
    dark_loses_from: float | None


@dataclass(frozen=True)
class AdaptiveResult:
    xs: list
    methods: list
    repeats: int
    spp: int
    relmse: dict              # method -> Estimate per point (whole image)
    dark: dict                # method -> Estimate per point (dark pixels)
    seconds: dict             # method -> mean seconds per point
    outliers: dict            # method -> (largest pixel, fireflies, NaN/Inf) per point
    comparisons: list


def analyse(data: AdaptiveData) -> AdaptiveResult:
    """Pure: the ratios and where adaptive loses (the words: :func:`sentences`)."""
    xs, runs = list(data.xs), data.runs
    repeats = min(len(r) for per in runs.values() for r in per)
    err = {m: [[r.relmse for r in rs] for rs in per] for m, per in runs.items()}
    dark = {m: [[r.relmse_mask for r in rs] for rs in per] for m, per in runs.items()}
    comparisons = []
    for m in data.plain:
        whole = [ratio(a, b) for a, b in zip(err[adaptive(m)], err[m])]
        darks = [ratio(a, b) for a, b in zip(dark[adaptive(m)], dark[m])]
        comparisons.append(AdaptiveComparison(
            m, whole, darks, metrics.first_where(xs, [exceeds(q, 1.0) for q in whole]),
            metrics.first_where(xs, [exceeds(q, 1.0) for q in darks])))
    return AdaptiveResult(
        xs, list(runs), repeats, data.spp,
        {m: [mean_interval(v) for v in e] for m, e in err.items()},
        {m: [mean_interval(v) for v in e] for m, e in dark.items()},
        {m: [float(np.mean([r.seconds for r in rs])) for rs in per] for m, per in runs.items()},
        {m: [worst(rs) for rs in per] for m, per in runs.items()}, comparisons)


# ------------------------------------------------------------------ words

SAYS = """Adaptive sweep, {{ a }} against {{ p }} at equal samples ({{ spp }} spp): relMSE
    ratio {{ c.ratio[0].text() }} at light size {{ first | g }} and
    {{ c.ratio[-1].text() }} at {{ last | g }}; it loses (ratio above 1) {{ loses }}.
    On the darkest {{ '%d' | format(100 * dark) }}% of the pixels: {{ c.dark[0].text() }}
    and {{ c.dark[-1].text() }}; it loses there {{ dark_loses }} ({{ how }})."""


def sentences(res: AdaptiveResult) -> list[str]:
    """One sentence per plain method and its adaptive twin."""
    return [prose.say(SAYS, a=label(adaptive(c.method)), p=label(c.method), c=c, spp=res.spp,
                      first=res.xs[0], last=res.xs[-1], dark=DARK_SHARE,
                      loses=onset("light size", c.loses_from, g),
                      dark_loses=onset("light size", c.dark_loses_from, g),
                      how=basis(res.repeats))
            for c in res.comparisons]


class AdaptiveSweep:
    name = "adaptive"
    needs = LIGHT.needs

    def methods(self) -> list[str]:
        return [m for p in PLAIN for m in (p, adaptive(p))]

    def spp(self, ctx: Context) -> int:
        return max(ctx.spp, MIN_SPP)

    def declare(self, ctx: Context) -> Declaration:
        """Every method at every light size of the light sweep, as its cells."""
        if not box_filter(ctx.settings.info.path):
            raise Skip("adaptive sampling needs a box reconstruction filter (each sample in "
                       "its own pixel); the scene has another")
        return LIGHT.declare(ctx, self.methods(), Budget.equal_spp(self.spp(ctx)))

    def measure(self, ctx: Context, measured: Measurements) -> AdaptiveData:
        methods = self.methods()
        xs = list(measured.declaration.sweep.values)
        runs = {m: [] for m in methods}
        for i in range(len(xs)):
            ref, meta = measured.reference_of(cells(measured, methods[0])[i][1])
            mask = dark_mask(ref)
            for m in methods:
                runs[m].append([ctx.read_run(run, m, ref, mask=mask,
                                             floor=meta["relmse_floor_map"])[0]
                                for run in measured.final(cells(measured, m)[i][1])])
        return AdaptiveData(xs, runs, PLAIN, self.spp(ctx))

    analyse = staticmethod(analyse)

    def report(self, ctx: Context, res: AdaptiveResult) -> SweepReport:
        xs, words = res.xs, sentences(res)
        figures.sweep_chart(ctx.path("adaptive.png"), "light half edge (2 = whole ceiling), "
                            "constant power", xs,
                            {label(m): (res.relmse[m], res.seconds[m]) for m in res.methods},
                            "relMSE", "Adaptive sampling against the light size",
                            reverse_x=True)
        header = ["light size", "method", "spp", "repeats", "relmse", "relmse_lo",
                  "relmse_hi", "dark_relmse", "dark_relmse_lo", "dark_relmse_hi",
                  "ratio_to_plain", "ratio_lo", "ratio_hi", "seconds", "max_pixel",
                  "fireflies", "nonfinite_px"]
        twin = {adaptive(c.method): c for c in res.comparisons}
        rows, summary = [], []
        for i, x in enumerate(xs):
            for m in res.methods:
                e, d, s = res.relmse[m][i], res.dark[m][i], res.seconds[m][i]
                q = twin[m].ratio[i] if m in twin else stats.Estimate(1.0, 1.0, 1.0, 0)
                peak, fireflies, nonfinite = res.outliers[m][i]
                rows.append([g(x), label(m), res.spp, res.repeats, g(e.value), g(e.lo),
                             g(e.hi), g(d.value), g(d.lo), g(d.hi), g(q.value), g(q.lo),
                             g(q.hi), round(s, 3), g(peak), fireflies, nonfinite])
                summary.append({"sweep": self.name, "x": x, "method": m,
                                "repeats": res.repeats, **e.fields("relmse"),
                                **d.fields("dark_relmse"), "seconds": s})
        blocks = [
            report.text(
                f"5. Adaptive sampling where its pilot can mislead it: each of "
                f"{', '.join(label(p) for p in PLAIN)} plain and with +adaptive at equal "
                f"samples, on the light sweep's scenes (the light from half edge {g(xs[0])} "
                f"to {g(xs[-1])} at constant power). Without NEE a small light is found by "
                f"BSDF sampling alone, so a pixel's pilot catches it or misses it by chance; "
                f"the darkest {DARK_SHARE:.0%} of the reference's pixels (those the floor "
                f"serves) are measured on their own. {budget(res.spp * res.repeats, res.repeats)}"
                f" each; errors are means over the repeats with {stats.LEVEL:.0%} intervals."),
            report.image(f"{NAME}/adaptive.png", "relMSE and relMSE x time against the light "
                         "size, plain and adaptive (x axis reversed; bands: 95% intervals)."),
            report.text("\n\n".join(words)),
            report.write_table(ctx.out, f"{NAME}/adaptive", header, rows,
                               "Adaptive sweep (ratio_to_plain: the adaptive method's relMSE "
                               "over its plain twin's; dark: the darkest pixels)",
                               collapsed=True)]
        return SweepReport(blocks, words, summary)


SWEEP = AdaptiveSweep()
