"""Sweep 3: grazing incidence on the scene's Phong material, no rendering.

At each incidence angle and exponent, every ``vr_path`` strategy
(``integrators.strategies.names()``) draws directions with the plugin's own
``sample_direction`` (:func:`~..scene_probes.direction_sampling_table`),
R independent sample sets each. A wasted sample has zero weight; efficiency
is the inverse relative variance per sample (the cost per sample is the same)
relative to normal incidence, with its interval over the repeats.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .. import jobs
from .. import metrics, prose, report, stats
from ..methods import strategies
from ..scenes import Needs
from ..scene_probes import direction_sampling_table, first_hit_sampling, phong_bsdf
from .. import figures
from .base import NAME, Context, SweepReport, basis, below, g, onset

#: Strategies whose prose is in the closing note (every strategy is in the table).
LOBE = ("bsdf", "mis")


@dataclass(frozen=True)
class GrazingData:
    """``stats[(strategy, exponent)][angle index][repeat]``: dicts of
    :func:`direction_sampling_stats` (albedo, wasted, relvar, nonfinite)."""
    angles: list
    stats: dict
    samples: int                       # samples per repeat and angle
    scene: dict | None = None          # first hits in the scene (see GrazingSweep.measure)


@dataclass(frozen=True)
class Curve:
    strategy: str
    exponent: float
    albedo: list              # mean over repeats, per angle
    wasted: list              # mean fraction over repeats, per angle
    efficiency: list          # Estimate per angle: relVar(normal) / relVar(angle)
    half_from: float | None   # first angle where at least half the samples are wasted
    loss_from: float | None   # first angle where efficiency falls below half of normal's


@dataclass(frozen=True)
class GrazingResult:
    angles: list
    repeats: int
    curves: list
    nonfinite: int
    samples: int              # samples over everything measured
    scene: dict | None = None  # first hits in the scene (GrazingData.scene)


def _efficiency(base: list, at: list):
    """relVar(normal) / relVar(angle) over repeats (no interval when one is not finite)."""
    if all(math.isfinite(v) and v > 0 for v in base + at):
        return stats.ratio_interval([base], [at])
    return stats.Estimate(metrics.ratio(sum(base) / len(base), sum(at) / len(at)),
                          float("nan"), float("nan"), len(at))


def analyse(data: GrazingData) -> GrazingResult:
    """Pure: wasted fractions, efficiencies and their onsets from the per-repeat stats (the
    words: :func:`sentences`)."""
    angles, curves, nonfinite, repeats = list(data.angles), [], 0, 1
    for (s, n), per_angle in data.stats.items():
        repeats = min(len(r) for r in per_angle)
        relvar = [[st["relvar"] for st in reps] for reps in per_angle]
        eff = [_efficiency(relvar[0], rv) for rv in relvar]
        wasted = [sum(st["wasted"] for st in reps) / len(reps) for reps in per_angle]
        albedo = [sum(st["albedo"] for st in reps) / len(reps) for reps in per_angle]
        nonfinite += sum(st["nonfinite"] for reps in per_angle for st in reps)
        curves.append(Curve(s, n, albedo, wasted, eff,
                            metrics.first_where(angles, [w >= 0.5 for w in wasted]),
                            metrics.first_where(angles, [below(e, 0.5) for e in eff])))
    total = data.samples * repeats * len(angles) * len(data.stats)
    return GrazingResult(angles, repeats, curves, nonfinite, total, data.scene)


# ------------------------------------------------------------------ words

CURVE = """Grazing, {{ c.strategy }} at exponent {{ c.exponent | g }}: {{ c.wasted[-1] | pct }}
    of the samples are wasted (zero weight) at {{ last }}; half are wasted {{ half }};
    efficiency falls below half of normal incidence's {{ loss }} (at {{ last }}:
    {{ c.efficiency[-1].text() }}x; {{ how }})."""

SCENE = """Grazing, in the scene (exponent {{ hits.exponent | g }}):
    {{ hits.grazing_share | pct }} of the camera's first hits on the Phong object are beyond
    75 degrees; lobe sampling wastes {{ hits.wasted_all | pct(1) }} of its samples over all
    hits, {{ hits.wasted_grazing | pct }} over the grazing ones."""

NONFINITE = "Grazing: {{ nonfinite }} non-finite sample weights over {{ samples }} samples."


def degrees(angle) -> str:
    return f"{angle:g} degrees"


def sentences(res: GrazingResult) -> list[str]:
    """The sweep's findings in words: the lobe strategies' curves, the scene's hits, the
    non-finite weights."""
    out = [prose.say(CURVE, c=c, last=degrees(res.angles[-1]), how=basis(res.repeats),
                     half=onset("", c.half_from, degrees), loss=onset("", c.loss_from, degrees))
           for c in res.curves if c.strategy in LOBE]
    if res.scene:
        out.append(prose.say(SCENE, hits=res.scene))
    return out + [prose.say(NONFINITE, nonfinite=res.nonfinite, samples=res.samples)]


class GrazingSweep:
    name = "grazing"
    needs = Needs(bsdfs=("phong",))

    def strategies(self) -> list[str]:
        return list(strategies())

    def declare(self, ctx: Context) -> None:
        """Nothing to render: the samples are drawn in :meth:`measure`, per exponent."""
        return None

    def measure(self, ctx: Context, measured=None) -> GrazingData:
        import mitsuba as mi
        cfg, seed = ctx.cfg, ctx.settings.seed
        scene = ctx.probe()
        bsdf, shape = phong_bsdf(scene)
        params = mi.traverse(bsdf)
        scene_n = float(params["exponent"][0])
        out = {}
        for n in cfg.grazing_exponents:
            params["exponent"] = float(n)
            params.update()
            for s in self.strategies():
                # repeat 0 keeps the single run's seed; repeat r draws an independent set
                seeds = [seed] + [jobs.derive_seed(seed, NAME, self.name, r)
                                  for r in range(1, ctx.repeats)]
                out[(s, n)] = direction_sampling_table(
                    bsdf, [math.cos(math.radians(t)) for t in cfg.angles], s,
                    ctx.grazing_samples, seeds)
        params["exponent"] = scene_n
        params.update()
        cos_i, zero = first_hit_sampling(scene, bsdf, shape, seed=seed)
        grazing = cos_i < math.cos(math.radians(75))
        hits = {"exponent": scene_n, "grazing_share": float(grazing.mean()),
                "wasted_all": float(zero.mean()),
                "wasted_grazing": float(zero[grazing].mean()) if grazing.any() else 0.0}
        return GrazingData(list(cfg.angles), out, ctx.grazing_samples, hits)

    analyse = staticmethod(analyse)

    def report(self, ctx: Context, res: GrazingResult) -> SweepReport:
        words = sentences(res)
        figures.grazing_chart(ctx.path("grazing.png"), res.angles,
                             {(c.strategy, c.exponent): c.wasted for c in res.curves},
                             {(c.strategy, c.exponent): c.efficiency for c in res.curves})
        header = ["exponent", "strategy", "angle", "repeats", "albedo", "wasted",
                  "efficiency_vs_normal", "efficiency_vs_normal_lo", "efficiency_vs_normal_hi"]
        rows, summary = [], []
        for c in res.curves:
            for t, alb, w, e in zip(res.angles, c.albedo, c.wasted, c.efficiency):
                rows.append([g(c.exponent), c.strategy, t, res.repeats, g(alb), f"{w:.3f}",
                             g(e.value), g(e.lo), g(e.hi)])
                summary.append({"sweep": self.name, "x": t, "exponent": c.exponent,
                                "method": c.strategy, "repeats": res.repeats, "wasted": w,
                                **e.fields("efficiency_vs_normal")})
        exps = sorted({c.exponent for c in res.curves})
        blocks = [
            report.text(
                f"3. Grazing incidence on the scene's Phong material (exponents "
                f"{', '.join(g(n) for n in exps)}): at each incidence angle "
                f"{ctx.grazing_samples} directions x {res.repeats} independent repeats are "
                f"drawn by each vr_path strategy ({', '.join(self.strategies())}) with the "
                f"plugin's own sample_direction, weighted by f cos / pdf, estimating the "
                f"directional albedo. A wasted sample has zero weight (lobe sampling: below "
                f"the horizon; cosine/uniform: outside the lobe only where cos(alpha) <= 0); "
                f"efficiency is the inverse relative variance per sample (the cost per sample "
                f"is the same), relative to normal incidence."),
            report.image(f"{NAME}/grazing.png", "Wasted-sample fraction and efficiency "
                         "against the incidence angle (solid: bsdf, dash-dot: mis, dashed: "
                         "cosine, dotted: uniform; bands: 95% intervals)."),
            report.text("\n\n".join(words)),
            report.write_table(ctx.out, f"{NAME}/grazing", header, rows, "Grazing sweep",
                               collapsed=True)]
        return SweepReport(blocks, words, summary)


SWEEP = GrazingSweep()
