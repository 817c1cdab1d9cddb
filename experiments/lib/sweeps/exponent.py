"""Sweep 1: the Phong exponent of the glossy object, every ``vr_path`` strategy, no NEE.

Per exponent, each strategy renders R repeats at --spp; errors are relMSE on
the pixels that see the Phong surface first (:func:`~..scene_probes.phong_mask`).
The analysis compares lobe sampling (``bsdf``) with ``cosine`` and ``uniform``:
where it pays off (efficiency at least 2x), where it is less efficient, and
where the hemisphere strategies explode (relMSE ratio above ``BREAK_FACTOR``,
on the interval's lower bound); and ``mis`` against the better of the two.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from .. import metrics, prose, report, stats
from ..engine import Budget, Declaration, Measurements
from ..methods import strategies
from ..scenes import Needs, scene_variant
from ..scene_probes import phong_mask
from .. import figures
from .base import (BREAK_FACTOR, NAME, Context, Run, SweepReport, basis, below, budget, cells,
                   exceeds, g, mean_interval, onset, ratio, worst)


@dataclass(frozen=True)
class ExponentData:
    """What the renders measured: ``runs[method][point][repeat]``."""
    xs: list
    runs: dict[str, list[list[Run]]]
    spp: int
    mask_pixels: int = 0
    pixels: int = 0


@dataclass(frozen=True)
class Comparison:
    """Lobe sampling (bsdf) against one hemisphere strategy over the sweep."""
    other: str
    efficiency: list          # Estimate per point: efficiency of bsdf / of other
    relmse_ratio: list        # Estimate per point: relMSE of other / of bsdf
    pays_from: float | None   # first exponent where bsdf is at least 2x as efficient
    worse_at: list            # exponents where bsdf is less efficient than other
    explodes_from: float | None   # first exponent where relMSE ratio > BREAK_FACTOR
    level_last: float         # other's mean image level at the last exponent (1 = right)


@dataclass(frozen=True)
class ExponentResult:
    xs: list
    methods: list
    repeats: int
    relmse: dict              # method -> Estimate per point (Phong pixels)
    relmse_all: dict          # method -> Estimate per point (whole image)
    seconds: dict             # method -> mean seconds per point
    outliers: dict            # method -> (largest pixel, fireflies, NaN/Inf) per point
    comparisons: list
    mis: list | None          # Estimate per point: relMSE(mis) / min(cosine, bsdf)
    spp: int = 0              # per repeat
    mask_pixels: int = 0      # pixels that see a Phong surface first (0: no mask)
    pixels: int = 0


def analyse(data: ExponentData) -> ExponentResult:
    """Pure: intervals and onsets from the measured numbers (the words: :func:`sentences`)."""
    xs, runs = list(data.xs), data.runs
    repeats = min(len(r) for per in runs.values() for r in per)
    err = {m: [[r.relmse_mask for r in rs] for rs in per] for m, per in runs.items()}
    secs = {m: [[r.seconds for r in rs] for rs in per] for m, per in runs.items()}
    relmse = {m: [mean_interval(v) for v in e] for m, e in err.items()}
    relmse_all = {m: [mean_interval([r.relmse for r in rs]) for rs in per]
                  for m, per in runs.items()}
    seconds = {m: [sum(v) / len(v) for v in s] for m, s in secs.items()}
    peaks = {m: [worst(rs) for rs in per] for m, per in runs.items()}
    comparisons = []
    if "bsdf" in runs:
        for other in [k for k in ("cosine", "uniform") if k in runs]:
            eff = [stats.efficiency_ratio(eb, sb, eo, so) for eb, sb, eo, so
                   in zip(err["bsdf"], secs["bsdf"], err[other], secs[other])]
            rat = [ratio(eo, eb) for eo, eb in zip(err[other], err["bsdf"])]
            c = Comparison(other, eff, rat,
                           metrics.first_where(xs, [exceeds(e, 2.0) for e in eff]),
                           [x for x, e in zip(xs, eff) if below(e, 1.0)],
                           metrics.first_where(xs, [exceeds(q, BREAK_FACTOR) for q in rat]),
                           sum(r.level for r in runs[other][-1]) / len(runs[other][-1]))
            comparisons.append(c)
    mis = None
    if {"mis", "cosine", "bsdf"} <= set(runs):
        mis = []
        for em, ec, eb in zip(err["mis"], err["cosine"], err["bsdf"]):
            best = ec if sum(ec) <= sum(eb) else eb
            mis.append(ratio(em, best))
    return ExponentResult(xs, list(runs), repeats, relmse, relmse_all, seconds, peaks,
                          comparisons, mis, data.spp, data.mask_pixels, data.pixels)


# ------------------------------------------------------------------ words

MASK = """{{ mask_pixels }} of {{ pixels }} pixels see a Phong surface first; the errors are
    measured on them (full-image relMSE in the table)."""

COMPARISON = """Exponent sweep, bsdf (lobe) vs {{ c.other }}: lobe sampling pays off
    (efficiency 1/(relMSE x time) at least 2x {{ c.other }}'s) {{ pays }}
    {%- if c.worse_at %}; it is less efficient than {{ c.other }} at exponent
    {{ c.worse_at | map('g') | join(', ') }}
    {%- else %}; it is never less efficient than {{ c.other }}{% endif %}.
    {{ c.other }} sampling explodes (relMSE > {{ '%g' | format(factor) }}x lobe sampling's)
    {{ explodes }}; at exponent {{ last_x | g }} its relMSE is {{ c.relmse_ratio[-1].text() }}x
    lobe sampling's and its Phong pixels average {{ c.level_last | pct }} of the reference
    {%- if c.level_last < 0.9 %} (the narrow lobe is rarely hit: the error hides in rare, huge
    samples that a {{ spp }}-spp image mostly lacks)
    {%- elif c.level_last > 1.1 %} (a few huge samples dominate){% endif %}.
    At exponent {{ last_x | g }}, {{ verdict }} ({{ how }})."""

MIS = """Exponent sweep, mis against the better of cosine and bsdf: relMSE(mis) /
    min(relMSE(cosine), relMSE(bsdf)) =
    {% for x, q in points %}{{ q.text() }} at exponent {{ x | g }}
    {%- if not loop.last %}, {% endif %}{% endfor %} (at most {{ worst | g }}; 1 would match
    the better strategy everywhere)."""


def sentences(res: ExponentResult) -> list[str]:
    """The sweep's findings in words: the mask, each comparison, mis."""
    out = [prose.say(MASK, mask_pixels=res.mask_pixels, pixels=res.pixels)] if res.pixels \
        else []
    how = basis(res.repeats)
    out += [prose.say(COMPARISON, c=c, spp=res.spp, how=how, factor=BREAK_FACTOR,
                      pays=onset("exponent", c.pays_from, g), last_x=res.xs[-1],
                      explodes=onset("exponent", c.explodes_from, g),
                      verdict=stats.verdict("bsdf", c.other, c.efficiency[-1]))
            for c in res.comparisons]
    if res.mis is not None:
        out.append(prose.say(MIS, points=list(zip(res.xs, res.mis)),
                             worst=max(q.value for q in res.mis)))
    return out


class ExponentSweep:
    name = "exponent"
    needs = Needs(defaults=("exponent",), bsdfs=("phong",))

    def methods(self) -> list[str]:
        """Every vr_path strategy (the list the plugin defines), no NEE, as in the writeup."""
        return list(strategies())

    def declare(self, ctx: Context) -> Declaration:
        """Every strategy at every exponent (a scene variant each), --spp split over the
        repeats."""
        info = ctx.settings.info

        def variant(n, scene):
            return replace(scene, info=scene_variant(info, ctx.scene_dir, f"exponent-{n:g}",
                                                     {"exponent": float(n)}))
        return ctx.declare(self.name, ctx.cfg.exponents, variant, self.methods(),
                           Budget.equal_spp(ctx.spp))

    def measure(self, ctx: Context, measured: Measurements) -> ExponentData:
        mask = phong_mask(ctx.probe())
        methods = self.methods()
        runs = {m: [] for m in methods}
        for i, x in enumerate(measured.declaration.sweep.values):
            ref, meta = measured.reference_of(cells(measured, methods[0])[i][1])
            for m in methods:
                runs[m].append([ctx.read_run(run, m, ref, mask, meta["relmse_floor_map"])[0]
                                for run in measured.final(cells(measured, m)[i][1])])
        return ExponentData(list(measured.declaration.sweep.values), runs, ctx.spp,
                            int(mask.sum()), int(mask.size))

    analyse = staticmethod(analyse)

    def report(self, ctx: Context, res: ExponentResult) -> SweepReport:
        a, xs, words = ctx.settings, res.xs, sentences(res)
        figures.sweep_chart(ctx.path("exponent.png"), "Phong exponent of the glossy object", xs,
                           {m: (res.relmse[m], res.seconds[m]) for m in res.methods},
                           "relMSE on the Phong pixels", "Exponent")
        header = ["exponent", "method", "spp", "repeats", "relmse_phong", "relmse_phong_lo",
                  "relmse_phong_hi", "relmse_all", "relmse_all_lo", "relmse_all_hi", "seconds",
                  "relmse_x_s", "max_pixel", "fireflies", "nonfinite_px"]
        rows, summary = [], []
        for m in res.methods:
            for i, x in enumerate(xs):
                e, e_all, s = res.relmse[m][i], res.relmse_all[m][i], res.seconds[m][i]
                peak, fireflies, nonfinite = res.outliers[m][i]
                rows.append([g(x), m, ctx.spp, res.repeats, g(e.value), g(e.lo), g(e.hi),
                             g(e_all.value), g(e_all.lo), g(e_all.hi), round(s, 3),
                             g(e.value * s), g(peak), fireflies, nonfinite])
                summary.append({"sweep": self.name, "x": x, "method": m, "repeats": res.repeats,
                                **e.fields("relmse"), "seconds": s})
        rows.sort(key=lambda r: (float(r[0]), res.methods.index(r[1])))
        blocks = [
            report.text(
                f"1. Phong exponent of the glossy object from {g(xs[0])} to {g(xs[-1])}, every "
                f"vr_path strategy ({', '.join(res.methods)}) without NEE (as in the writeup), "
                f"{budget(ctx.spp, res.repeats)} each, against a "
                f"{a.reference_spp}-spp reference per exponent; errors are means over the "
                f"repeats with {stats.LEVEL:.0%} intervals."),
            report.image(f"{NAME}/exponent.png", "relMSE on the Phong pixels, and relMSE x "
                         "render time, against the exponent (log-log; bands: 95% intervals)."),
            report.text("\n\n".join(words)),
            report.write_table(ctx.out, f"{NAME}/exponent", header, rows, "Exponent sweep",
                               collapsed=True)]
        notes = [s for s in words if s.startswith("Exponent sweep")]
        return SweepReport(blocks, notes, summary)


SWEEP = ExponentSweep()
