"""Sweep 4: Halton without and with randomization, at max_depth 2 and a high depth.

Per depth, the strategy alone (independent sampling) and ``STRATEGY+halton:R``
for every randomization R render progressively to ``halton_spp`` / R (a ladder of
jobs per repeat; the Halton passes continue one sequence), R repeats each
with their own seeds (scrambles). The analysis gives relMSE against spp with
intervals, fitted slopes, where plain Halton ('none') becomes worse than
independent sampling (the interval of the ratio above 1), and the
neighbour-pixel correlation of the errors (structured artifacts).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from .. import figures, metrics, prose, report, stats
from .. import samplers
from ..engine import Budget, Declaration, Measurements
from ..plan import doubling_targets
from ..scenes import Needs
from .base import (NAME, Context, SweepReport, basis, cells, exceeds, g, mean_interval, onset,
                   ratio)


@dataclass(frozen=True)
class HaltonData:
    """``curves[depth][method][repeat]`` = [(spp, seconds, relMSE) per ladder step],
    ``corr[depth][method][repeat]`` = neighbour-pixel error correlation of the final image."""
    strategy: str
    curves: dict
    corr: dict
    images: dict = field(default_factory=dict)   # depth -> (reference, [(method, image)])


@dataclass(frozen=True)
class Line:
    method: str
    spp: list
    seconds: list             # mean over repeats, per step
    relmse: list              # Estimate per step
    slope: float              # of the mean relMSE against spp (log-log)
    corr: float               # mean over repeats


@dataclass(frozen=True)
class HaltonResult:
    strategy: str
    repeats: int
    lines: dict               # depth -> {method: Line}
    worse_from: dict          # depth -> first spp where 'none' is worse than independent
    images: dict = field(default_factory=dict)
    worse_at: dict = field(default_factory=dict)   # depth -> every such spp
    identical: dict = field(default_factory=dict)  # depth -> 'none''s repeats are identical
    #: depth -> {method: Estimate of relMSE(independent) / relMSE(method) at the last spp}
    accuracy: dict = field(default_factory=dict)


def plain(strategy: str) -> str:
    return f"{strategy}+halton:none"


def analyse(data: HaltonData) -> HaltonResult:
    """Pure: intervals per ladder step, slopes, the onset, the accuracy ratios at the last
    step (the words: :func:`sentences`)."""
    s, lines, worse, worse_at, repeats = data.strategy, {}, {}, {}, 1
    identical, accuracy = {}, {}
    for d, by_method in data.curves.items():
        lines[d] = {}
        for m, reps in by_method.items():
            repeats = len(reps)
            spp = [p[0] for p in reps[0]]
            err = [[rep[i][2] for rep in reps] for i in range(len(spp))]
            est = [mean_interval(e) for e in err]
            secs = [sum(rep[i][1] for rep in reps) / len(reps) for i in range(len(spp))]
            corr = data.corr[d][m]
            lines[d][m] = Line(m, spp, secs, est, metrics.loglog_slope(spp, [e.value for e in est]),
                               sum(corr) / len(corr))
        ln, none, indep = lines[d], plain(s), s
        err_of = {m: [[rep[i][2] for rep in by_method[m]] for i in range(len(ln[m].spp))]
                  for m in by_method}
        rat = [ratio(a, b) for a, b in zip(err_of[none], err_of[indep])]
        worse_at[d] = [n for n, q in zip(ln[none].spp, rat) if exceeds(q, 1.0)]
        worse[d] = worse_at[d][0] if worse_at[d] else None
        identical[d] = repeats > 1 and len(set(err_of[none][-1])) == 1
        accuracy[d] = {m: ratio(err_of[indep][-1], err_of[m][-1])
                       for m in ln if m != indep}
    return HaltonResult(s, repeats, lines, worse, dict(data.images), worse_at, identical,
                        accuracy)


# ------------------------------------------------------------------ words

DEPTH = """Halton at max_depth {{ d }}: without randomization ('none') relMSE after {{ last }}
    spp is {{ plain.relmse[-1].text() }} (slope {{ plain.slope | g }}),
    {% for ln in rand %}{{ ln.method.split(':')[-1] }} {{ ln.relmse[-1].text() }} (slope
    {{ ln.slope | g }}), {% endfor %}independent {{ indep.relmse[-1].text() }}; 'none' is
    worse than independent sampling {{ where }} ({{ how }}
    {%- if identical %}; 'none' is deterministic: its repeats are identical{% endif %}).
    {% for v in verdicts %}At {{ last }} spp, {{ v }}. {% endfor %}
    Neighbour-pixel error correlation: none {{ '%.2f' | format(plain.corr) }},
    {% for ln in rand %}{{ ln.method.split(':')[-1] }} {{ '%.2f' | format(ln.corr) }},
    {% endfor %}independent {{ '%.2f' | format(indep.corr) }}."""


def sentences(res: HaltonResult) -> list[str]:
    """One paragraph per depth: final errors and slopes, where plain Halton is worse than
    independent sampling, the verdicts at the last spp, the neighbour correlations."""
    out, none, indep = [], plain(res.strategy), res.strategy
    for d, ln in res.lines.items():
        rand = [m for m in ln if m not in (none, indep)]
        out.append(prose.say(
            DEPTH, d=d, last=ln[indep].spp[-1], plain=ln[none], indep=ln[indep],
            rand=[ln[m] for m in rand], where=_where(res.worse_at[d], ln[none].spp),
            how=basis(res.repeats), identical=res.identical[d],
            verdicts=[stats.verdict(m, indep, res.accuracy[d][m], "accurate")
                      for m in [none] + rand]))
    return out


def _where(at: list, spp: list) -> str:
    """'from N spp' when it holds from N to the end of the ladder, 'at N, M spp only'
    when it stops holding, 'nowhere in the sweep' when it never holds."""
    if not at:
        return onset("", None, str)
    if at == spp[spp.index(at[0]):]:
        return f"from {at[0]} spp"
    return f"at {', '.join(map(str, at))} spp only"


class HaltonSweep:
    name = "halton"
    needs = Needs()

    def methods(self, ctx: Context) -> list[str]:
        strategy = "uniform" if "uniform" in ctx.strategies else ctx.strategies[0]
        randomizations = samplers.get("halton").randomizations
        return [strategy] + [f"{strategy}+halton:{r}" for r in randomizations]

    def declare(self, ctx: Context) -> Declaration:
        """Every method at every depth, progressive to the Halton budget per repeat (a
        ladder of doubling counts; a deterministic method renders once)."""
        return ctx.declare(self.name, ctx.halton_depths,
                           lambda d, scene: replace(scene, depth=ctx.depth(d)),
                           self.methods(ctx), Budget.progressive(doubling_targets(ctx.halton_spp)),
                           point=lambda d: f"depth{d}")

    def measure(self, ctx: Context, measured: Measurements) -> HaltonData:
        methods = self.methods(ctx)
        curves, corr, images = {}, {}, {}
        for i, d in enumerate(measured.declaration.sweep.values):
            ref, meta = measured.reference_of(cells(measured, methods[0])[i][1])
            curves[d], corr[d], images[d] = {}, {}, (ref, [])
            for m in methods:
                curves[d][m], corr[d][m] = [], []
                for r, rungs in enumerate(measured.runs[cells(measured, m)[i][1]]):
                    curves[d][m].append([(a.spp, a.cost, a.relmse - meta["relmse_floor"])
                                         for a in rungs])
                    image = rungs[-1].image
                    ctx.outliers.add(m, image, ref)
                    corr[d][m].append(metrics.neighbour_correlation(image, ref))
                    if r == 0:
                        images[d][1].append((m, image))
        return HaltonData(methods[0], curves, corr, images)

    analyse = staticmethod(analyse)

    def report(self, ctx: Context, res: HaltonResult) -> SweepReport:
        h, w, words = ctx.height, ctx.width, sentences(res)
        side = max(4, h // 2)
        y0, x0 = (h - side) // 2, min(w - side, w // 2 + side // 4)
        depths = list(res.lines)
        crops, caps, viewers, rows, summary = [], [], [], [], []
        last = None
        for d in depths:
            lines = res.lines[d]
            figures.error_bands(ctx.path(f"halton_depth{d}.png"),
                                {m: (ln.spp, ln.seconds, ln.relmse) for m, ln in lines.items()},
                                "relMSE")
            ref, images = res.images[d]
            finals = dict(images)
            last = lines[res.strategy].spp[-1]
            crops.append([finals[m][y0:y0 + side, x0:x0 + side] for m in lines])
            caps.append([f"relMSE {ln.relmse[-1].value:.2e}\ncorr {ln.corr:.2f}"
                         for ln in lines.values()])
            viewers.append(report.viewer(
                ctx.out, f"Halton at max_depth {d}, {last} spp", images, ref,
                f"Every method of the Halton sweep at max_depth {d} after the last spp (repeat "
                f"0): zoom in to see plain Halton's structured artifacts."))
            for m, ln in lines.items():
                e = ln.relmse[-1]
                rows.append([d, m, ln.spp[-1], res.repeats, g(e.value), g(e.lo), g(e.hi),
                             g(ln.slope), f"{ln.corr:.3f}"])
                summary.append({"sweep": self.name, "x": d, "method": m, "spp": ln.spp[-1],
                                "repeats": res.repeats, **e.fields("relmse"),
                                "slope": ln.slope, "corr": ln.corr})
        methods = list(res.lines[depths[0]])
        figures.image_grid(ctx.path("halton_crops.png"), [list(c) for c in zip(*crops)],
                           methods, [f"max_depth {d}" for d in depths],
                           [list(c) for c in zip(*caps)], title=f"Crops after {last} spp")
        blocks = [report.text(
            f"4. Halton sequences ({res.strategy} strategy): plain ('none', the same points in "
            f"every pixel) against the scrambled randomizations and independent sampling, at "
            f"max_depth 2 (direct light only) and {depths[-1]} (high dimensions, large prime "
            f"bases), progressive to {last} spp (the Halton passes continue one sequence), "
            f"{res.repeats} independent repeats each (own seeds and scrambles). Correlation: "
            f"Pearson correlation of the luminance errors of horizontally adjacent pixels "
            f"(about 0 when pixels are independent), mean over the repeats.")]
        blocks += [report.image(f"{NAME}/halton_depth{d}.png", f"relMSE against spp and time "
                                f"at max_depth {d} (bands: 95% intervals).") for d in depths]
        blocks += viewers + [
            report.image(f"{NAME}/halton_crops.png", "Image crops after the last spp: "
                         "structured artifacts of plain Halton."),
            report.text("\n\n".join(words)),
            report.write_table(ctx.out, f"{NAME}/halton",
                               ["max_depth", "method", "spp", "repeats", "relmse", "relmse_lo",
                                "relmse_hi", "slope_vs_spp", "neighbour_corr"], rows,
                               "Halton sweep")]
        return SweepReport(blocks, words, summary)


SWEEP = HaltonSweep()
