"""Sweep 2: the size of the light at constant power, with and without next-event estimation.

Each strategy of --methods renders the scene with the light shrunk from the
whole ceiling to a tiny patch (radiance x size^2 fixed), R repeats each; the
NEE method (``bsdf+nee``, or the first strategy's) samples the light directly.
A method without NEE breaks down where its relMSE exceeds ``BREAK_FACTOR`` x
the NEE method's (on the interval's lower bound).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from .. import metrics, prose, report, stats
from ..engine import Budget, Declaration, Measurements
from ..scenes import Needs, scene_defaults, scene_variant
from .. import figures
from .base import (BREAK_FACTOR, NAME, Context, Run, SweepReport, basis, budget, cells,
                   exceeds, g, label, mean_interval, ratio, onset, worst)


@dataclass(frozen=True)
class LightData:
    """``runs[method][point][repeat]``; the last method is the NEE one."""
    xs: list
    runs: dict[str, list[list[Run]]]
    nee: str
    spp: int
    radiance: list = ()
    size0: float = 2.0
    rad0: float = 1.0


@dataclass(frozen=True)
class LightComparison:
    method: str
    ratio: list               # Estimate per point: relMSE(method) / relMSE(NEE)
    breaks_from: float | None     # first size where the ratio exceeds BREAK_FACTOR
    growth: object            # Estimate: relMSE at the last size / at the first
    efficiency_last: object   # Estimate: efficiency of NEE / of method at the last size


@dataclass(frozen=True)
class LightResult:
    xs: list
    methods: list
    nee: str
    repeats: int
    relmse: dict              # method -> Estimate per point
    seconds: dict             # method -> mean seconds per point
    outliers: dict            # method -> (largest pixel, fireflies, NaN/Inf) per point
    comparisons: list
    nee_change: object        # Estimate: NEE's relMSE at the last size / at the first
    nee_holds: bool           # NEE's change is not above BREAK_FACTOR
    radiance: list = ()       # the light's radiance per point


def analyse(data: LightData) -> LightResult:
    """Pure: intervals and breakdown sizes from the measured numbers (the words:
    :func:`sentences`)."""
    xs, runs, nee = list(data.xs), data.runs, data.nee
    repeats = min(len(r) for per in runs.values() for r in per)
    err = {m: [[r.relmse for r in rs] for rs in per] for m, per in runs.items()}
    secs = {m: [[r.seconds for r in rs] for rs in per] for m, per in runs.items()}
    relmse = {m: [mean_interval(v) for v in e] for m, e in err.items()}
    seconds = {m: [sum(v) / len(v) for v in s] for m, s in secs.items()}
    comparisons = []
    for m in [k for k in runs if k != nee]:
        rat = [ratio(a, b) for a, b in zip(err[m], err[nee])]
        c = LightComparison(m, rat, metrics.first_where(xs, [exceeds(q, BREAK_FACTOR)
                                                              for q in rat]),
                            ratio(err[m][-1], err[m][0]),
                            stats.efficiency_ratio(err[nee][-1], secs[nee][-1], err[m][-1],
                                                   secs[m][-1]))
        comparisons.append(c)
    change = ratio(err[nee][-1], err[nee][0])
    return LightResult(xs, list(runs), nee, repeats, relmse, seconds,
                       {m: [worst(rs) for rs in per] for m, per in runs.items()},
                       comparisons, change, not exceeds(change, BREAK_FACTOR),
                       list(data.radiance))


# ------------------------------------------------------------------ words

BREAKS = """Light sweep, {{ c.method }} without NEE: relMSE exceeds {{ '%g' | format(factor) }}x
    {{ nee }}'s {{ breaks }}; it grows {{ c.growth.text() }}x from size {{ first | g }} to
    {{ last | g }} (at {{ last | g }}: {{ c.ratio[-1].text() }}x {{ nee }}). At size
    {{ last | g }}, {{ verdict }} ({{ how }})."""

NEE = """Light sweep, {{ nee }}: relMSE changes {{ change.text() }}x from size {{ first | g }}
    to {{ last | g }}: next-event estimation + MIS
    {% if holds %}holds.{% else %}degrades too (more than {{ '%g' | format(factor) }}x).
    {%- endif %}"""


def sentences(res: LightResult) -> list[str]:
    """The sweep's findings in words: each method without NEE, then the NEE method."""
    nee, how, ends = label(res.nee), basis(res.repeats), dict(first=res.xs[0], last=res.xs[-1])
    return [prose.say(BREAKS, c=c, nee=nee, factor=BREAK_FACTOR, how=how,
                      breaks=onset("light size", c.breaks_from, g),
                      verdict=stats.verdict(nee, c.method, c.efficiency_last), **ends)
            for c in res.comparisons] + [
        prose.say(NEE, nee=nee, change=res.nee_change, holds=res.nee_holds,
                  factor=BREAK_FACTOR, **ends)]


class LightSweep:
    name = "light"
    needs = Needs(defaults=("light_size", "light_radiance"))

    def methods(self, ctx: Context) -> list[str]:
        nee = ("bsdf" if "bsdf" in ctx.strategies else ctx.strategies[0]) + "+nee"
        return ctx.strategies + [nee]

    def lights(self, ctx: Context) -> tuple[float, float]:
        """The scene's light size and radiance (the sweep keeps size^2 x radiance)."""
        defaults = scene_defaults(ctx.settings.info.path)
        return float(defaults["light_size"]), float(defaults["light_radiance"])

    def declare(self, ctx: Context, methods=None, at: Budget | None = None) -> Declaration:
        """Every method (default :meth:`methods`) at every light size (a scene variant
        each, constant power), at ``at`` (default --spp split over the repeats). Another
        sweep declares its methods on these scenes so (:mod:`.adaptive_pilot`): the same cells."""
        info, (size0, rad0) = ctx.settings.info, self.lights(ctx)

        def variant(size, scene):
            return replace(scene, info=scene_variant(
                info, ctx.scene_dir, f"light-{size:g}",
                {"light_size": float(size), "light_radiance": rad0 * (size0 / size) ** 2}))
        return ctx.declare(self.name, ctx.cfg.light_sizes, variant,
                           methods or self.methods(ctx), at or Budget.equal_spp(ctx.spp))

    def measure(self, ctx: Context, measured: Measurements) -> LightData:
        methods, (size0, rad0) = self.methods(ctx), self.lights(ctx)
        xs = list(measured.declaration.sweep.values)
        runs = {m: [] for m in methods}
        for i in range(len(xs)):
            ref, meta = measured.reference_of(cells(measured, methods[0])[i][1])
            for m in methods:
                runs[m].append([ctx.read_run(run, m, ref, floor=meta["relmse_floor_map"])[0]
                                for run in measured.final(cells(measured, m)[i][1])])
        return LightData(xs, runs, methods[-1], ctx.spp,
                         [rad0 * (size0 / size) ** 2 for size in xs], size0, rad0)

    analyse = staticmethod(analyse)

    def report(self, ctx: Context, res: LightResult) -> SweepReport:
        xs, nee, words = res.xs, res.nee, sentences(res)
        figures.sweep_chart(ctx.path("light.png"), "light half edge (2 = whole ceiling), "
                           "constant power", xs,
                           {label(m): (res.relmse[m], res.seconds[m]) for m in res.methods},
                           "relMSE", "Light size", reverse_x=True)
        header = ["light size", "radiance", "method", "spp", "repeats", "relmse", "relmse_lo", "relmse_hi",
                  "seconds", "relmse_x_s", "max_pixel", "fireflies", "nonfinite_px"]
        rows, summary = [], []
        for i, x in enumerate(xs):
            for m in res.methods:
                e, s = res.relmse[m][i], res.seconds[m][i]
                peak, fireflies, nonfinite = res.outliers[m][i]
                radiance = res.radiance[i] if res.radiance else float("nan")
                rows.append([g(x), g(radiance), label(m), ctx.spp, res.repeats, g(e.value), g(e.lo),
                             g(e.hi), round(s, 3), g(e.value * s), g(peak), fireflies,
                             nonfinite])
                summary.append({"sweep": self.name, "x": x, "method": m, "repeats": res.repeats,
                                **e.fields("relmse"), "seconds": s})
        blocks = [
            report.text(
                f"2. Light size from the whole ceiling (half edge {g(xs[0])}) to a tiny patch "
                f"({g(xs[-1])}) at constant power (radiance x size^2 fixed): direction "
                f"sampling alone must hit the light; {label(nee)} samples it directly. "
                f"{budget(ctx.spp, res.repeats)} each; errors are means over "
                f"the repeats with {stats.LEVEL:.0%} intervals."),
            report.image(f"{NAME}/light.png", "relMSE and relMSE x time against the light "
                         "size (x axis reversed: smaller lights to the right; bands: 95% "
                         "intervals)."),
            report.text("\n\n".join(words)),
            report.write_table(ctx.out, f"{NAME}/light", header, rows, "Light-size sweep",
                               collapsed=True)]
        return SweepReport(blocks, words, summary)


SWEEP = LightSweep()
