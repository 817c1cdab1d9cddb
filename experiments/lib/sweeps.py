"""The stability sweeps: where each sampling method breaks down (plan, analysis, prose).

Four sweeps on the scene's parameters, each a chart of error and error x time
against the swept value per method, with breakdown points computed from the
data: (1) the Phong exponent of the glossy object, every ``vr_path``
strategy (:func:`~.methods.strategies`), (2) the size of the light at
constant power, with and without next-event estimation, (3) grazing
incidence (wasted zero-weight samples and efficiency loss, measured on the
scene's Phong material, no rendering), (4) Halton without and with
randomization at low and high path depth (error curves, image crops,
neighbour-pixel correlation). Outliers (largest pixel, fireflies, NaN/Inf)
are counted over every render.

:class:`Sweeps` plans every render of the chosen sweeps up front
(:meth:`Sweeps.plan`), the script executes them in one go, then each sweep
reads its results from the store and returns report blocks. Sweep points
are scene variants (:func:`~.methods.scene_variant`, the scene file with
one ``<default>`` changed) written to ``<out>/stability/scenes``.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from . import figures, metrics, report
from . import plan as P
from .methods import Depth, scene_defaults, scene_variant, strategies
from .scene_probes import (direction_sampling_stats, first_hit_sampling, phong_bsdf,
                           phong_mask, probe_scene)
from .study import Study

NAME = "stability"
SWEEPS = ("exponent", "light", "grazing", "halton")
#: relMSE ratio at which a method counts as broken down against the robust one.
BREAK_FACTOR = 10.0
g = "{:.3g}".format


def _onset(quantity: str, value, fmt) -> str:
    """'from <quantity> <value>' for the first sweep point where a condition holds, or
    'nowhere in the sweep' when it never does."""
    if value is None:
        return "nowhere in the sweep"
    return " ".join(p for p in ("from", quantity, fmt(value)) if p)


@dataclass(frozen=True)
class Config:
    exponents: tuple
    light_sizes: tuple
    angles: tuple             # incidence angles (degrees) of the grazing sweep
    grazing_exponents: tuple
    grazing_samples: int
    halton_spp: int


NORMAL = Config((1, 10, 100, 1000, 10000), (2, 1, 0.5, 0.2, 0.05, 0.02),
                (0, 30, 60, 75, 80, 85, 88, 89), (10, 100, 1000), 2 ** 16, 64)
QUICK = Config((1, 10000), (2, 0.02), (0, 60, 89), (10, 1000), 2 ** 12, 2)


class Outliers:
    """Largest pixel, fireflies and non-finite pixels per method over every sweep render."""

    def __init__(self):
        self.rows: dict[str, dict] = {}

    def add(self, label: str, image, reference) -> dict:
        o = metrics.outliers(image, reference)
        r = self.rows.setdefault(label, {"images": 0, "max": 0.0, "fireflies": 0,
                                         "nonfinite": 0})
        r["images"] += 1
        r["max"] = max(r["max"], o["max"])
        r["fireflies"] += o["fireflies"]
        r["nonfinite"] += o["nonfinite"]
        return o


def label(method: str) -> str:
    return method.replace("+nee", " + NEE")


class Sweeps:
    """Plans, then analyses, the chosen sweeps of one study (see the module docstring)."""

    def __init__(self, args, config: Config):
        self.args = args
        self.cfg = config
        self.st = Study(args)
        self.out = args.out
        self.width, self.height = args.resolution
        self.outliers = Outliers()
        self.notes: list[str] = []          # closing note, one sentence per finding
        #: strategies of --methods (their vr_path strategy; path has none)
        self.strategies = list(dict.fromkeys(m.strategy for m in args.method_objs
                                             if m.strategy is not None)) or ["bsdf"]
        self.scene_dir = os.path.join(self.out, NAME, "scenes")
        self.ref_jobs: list[P.Job] = []
        self.plans: dict[str, object] = {}
        high = args.depth.max_depth
        self.halton_depths = [2, high if high is not None and (high > 2 or high == -1) else 8]

    def path(self, name: str) -> str:
        return os.path.join(self.out, NAME, name)

    # ----------------------------------------------------------- plan

    def _reference(self, info, depth: Depth | None = None) -> list[P.Job]:
        jobs = self.st.reference_jobs(info, depth)
        self.ref_jobs += jobs
        return jobs

    def _point(self, sweep: str, x, info, methods) -> dict:
        """Jobs of one sweep point: its reference and one render per method."""
        return {"x": x, "info": info, "ref": self._reference(info),
                "jobs": {m: self.st.job(f"{NAME}/{sweep}/{x:g}/{m}", m, self.args.spp,
                                        info=info, timing_group=f"{NAME}/{sweep}")
                         for m in methods}}

    def exponent_methods(self) -> list[str]:
        """Every vr_path strategy (the list the plugin defines), no NEE, as in the writeup."""
        return list(strategies())

    def light_methods(self) -> list[str]:
        nee = ("bsdf" if "bsdf" in self.strategies else self.strategies[0]) + "+nee"
        return self.strategies + [nee]

    def halton_methods(self) -> list[str]:
        from .methods import RANDOMIZATIONS
        strategy = "uniform" if "uniform" in self.strategies else self.strategies[0]
        return [strategy] + [f"{strategy}+halton:{r}" for r in RANDOMIZATIONS]

    def plan(self, sweeps) -> list[P.Job]:
        """Every render job of ``sweeps`` (scene variants are written now). A sweep whose
        scene parameter the scene lacks is left out and listed in :attr:`skipped`."""
        self.skipped: dict[str, str] = {}
        for name in sweeps:
            planner = getattr(self, f"_plan_{name}", None)
            if planner is None:
                continue
            try:
                self.plans[name] = planner()
            except KeyError as e:        # the scene lacks a swept <default> parameter
                self.skipped[name] = str(e).strip("'")
        jobs = list(self.ref_jobs)
        for name, plan in self.plans.items():
            points = plan[2] if name == "light" else plan
            for point in points:
                for j in point["jobs"].values():
                    jobs += j if isinstance(j, list) else [j]
        return jobs

    def _plan_exponent(self):
        info = self.args.info
        return [self._point("exponent", n, scene_variant(info, self.scene_dir, f"exponent-{n:g}",
                                                         {"exponent": float(n)}),
                            self.exponent_methods()) for n in self.cfg.exponents]

    def _plan_light(self):
        info = self.args.info
        defaults = scene_defaults(info.path)
        if "light_size" not in defaults or "light_radiance" not in defaults:
            raise KeyError("light_size, light_radiance")
        size0, rad0 = float(defaults["light_size"]), float(defaults["light_radiance"])
        points = []
        for size in self.cfg.light_sizes:
            radiance = rad0 * (size0 / size) ** 2
            variant = scene_variant(info, self.scene_dir, f"light-{size:g}",
                                    {"light_size": float(size), "light_radiance": radiance})
            point = self._point("light", size, variant, self.light_methods())
            point["radiance"] = radiance
            points.append(point)
        return size0, rad0, points

    def _plan_halton(self):
        targets = P.doubling_targets(self.cfg.halton_spp)
        return [{"depth": d, "ref": self._reference(self.args.info, self._depth(d)),
                 "jobs": {m: self.st.ladder(f"{NAME}/halton/depth{d}/{m}", m, targets,
                                            depth=self._depth(d), timing_group=f"{NAME}/halton")
                          for m in self.halton_methods()}}
                for d in self.halton_depths]

    def _depth(self, max_depth: int) -> Depth:
        d = self.args.depth
        return Depth(max_depth, d.rr_depth, d.hide_emitters)

    # ----------------------------------------------------------- analysis

    def reference(self, jobs) -> np.ndarray:
        return self.st.reference(jobs)[0]

    def result(self, job: P.Job, method: str, ref, mask=None) -> dict:
        r = self.st.store.get(job.key)
        image = r.image.astype(np.float64)
        o = self.outliers.add(label(method), image, ref)
        sel = mask if mask is not None else np.ones(image.shape[:2], bool)
        level = metrics.ratio(float(np.mean(image[sel])), float(np.mean(ref[sel])))
        return {"relmse": metrics.relmse(image, ref), "level": level,
                "relmse_mask": metrics.relmse(image, ref, mask),
                "seconds": r.seconds, "image": image, **o}

    # ----------------------------------------------------------- 1: exponent

    def exponent_sweep(self) -> list[dict]:
        a = self.args
        points = self.plans["exponent"]
        methods = self.exponent_methods()
        mask = phong_mask(probe_scene(a.scene, self.width, self.height))
        res = {m: [] for m in methods}
        rows = []
        for p in points:
            ref = self.reference(p["ref"])
            for m, job in p["jobs"].items():
                r = self.result(job, m, ref, mask)
                res[m].append(r)
                rows.append([g(p["x"]), m, a.spp, g(r["relmse_mask"]), g(r["relmse"]),
                             round(r["seconds"], 3), g(r["relmse_mask"] * r["seconds"]),
                             g(r["max"]), r["fireflies"], r["nonfinite"]])
        xs = [p["x"] for p in points]
        figures.sweep_chart(self.path("exponent.png"), "Phong exponent of the glossy object",
                            xs, {k: ([r["relmse_mask"] for r in v], [r["seconds"] for r in v])
                                 for k, v in res.items()}, "relMSE on the Phong pixels",
                            "Exponent")
        text = [f"{int(mask.sum())} of {mask.size} pixels see a Phong surface first; the errors "
                f"are measured on them (full-image relMSE in the table)."]
        eff = {k: [metrics.efficiency(r["relmse_mask"], r["seconds"]) for r in v]
               for k, v in res.items()}
        if "bsdf" in res:
            bs = res["bsdf"]
            for other in [k for k in ("cosine", "uniform") if k in res]:
                pays = metrics.first_where(xs, [e_b >= 2 * e_o for e_b, e_o
                                                in zip(eff["bsdf"], eff[other])])
                worse = [x for x, e_b, e_o in zip(xs, eff["bsdf"], eff[other]) if e_b < e_o]
                boom = metrics.first_where(xs, [r["relmse_mask"] > BREAK_FACTOR * b["relmse_mask"]
                                                for r, b in zip(res[other], bs)])
                sentence = (
                    f"Exponent sweep, bsdf (lobe) vs {other}: lobe sampling pays off "
                    f"(efficiency 1/(relMSE x time) at least 2x {other}'s) "
                    + _onset("exponent", pays, g)
                    + (f"; it does not pay off (less efficient than {other}) at exponent "
                       f"{', '.join(g(x) for x in worse)}" if worse else
                       f"; it is never less efficient than {other}")
                    + f". {other} sampling explodes (relMSE > {BREAK_FACTOR:g}x lobe "
                      f"sampling's) "
                    + _onset("exponent", boom, g)
                    + f"; at exponent {g(xs[-1])} its relMSE is "
                      f"{g(metrics.ratio(res[other][-1]['relmse_mask'], bs[-1]['relmse_mask']))}x "
                      f"lobe sampling's, and its Phong pixels average "
                      f"{res[other][-1]['level']:.0%} of the reference"
                    + (f" (the narrow lobe is rarely hit: the error hides in rare, huge "
                       f"samples that a {a.spp}-spp image mostly lacks)."
                       if res[other][-1]['level'] < 0.9 else
                       " (a few huge samples dominate)." if res[other][-1]['level'] > 1.1
                       else "."))
                text.append(sentence)
                self.notes.append(sentence)
        if {"mis", "cosine", "bsdf"} <= set(res):
            ratios = [metrics.ratio(r["relmse_mask"], min(c["relmse_mask"], b["relmse_mask"]))
                      for r, c, b in zip(res["mis"], res["cosine"], res["bsdf"])]
            sentence = ("Exponent sweep, mis against the better of cosine and bsdf: relMSE(mis) "
                        "/ min(relMSE(cosine), relMSE(bsdf)) = "
                        + ", ".join(f"{g(q)} at exponent {g(x)}" for x, q in zip(xs, ratios))
                        + f" (at most {g(max(ratios))}; 1 would match the better strategy "
                          f"everywhere).")
            text.append(sentence)
            self.notes.append(sentence)
        return [
            report.text(
                f"1. Phong exponent of the glossy object from {g(xs[0])} to {g(xs[-1])}, every "
                f"vr_path strategy ({', '.join(methods)}) without NEE (as in the writeup), "
                f"{a.spp} spp each, against a {a.reference_spp}-spp reference per exponent."),
            report.image(f"{NAME}/exponent.png", "relMSE on the Phong pixels, and relMSE x "
                         "render time, against the exponent (log-log)."),
            report.text("\n\n".join(text)),
            report.write_table(self.out, f"{NAME}/exponent",
                               ["exponent", "method", "spp", "relMSE (Phong px)",
                                "relMSE (all)", "seconds", "relMSE x s", "max pixel",
                                "fireflies", "NaN/Inf px"], rows,
                               "Exponent sweep", collapsed=True)]

    # ----------------------------------------------------------- 2: light size

    def light_sweep(self) -> list[dict]:
        a = self.args
        size0, rad0, points = self.plans["light"]
        methods = self.light_methods()
        nee = methods[-1]
        res = {m: [] for m in methods}
        rows = []
        for p in points:
            ref = self.reference(p["ref"])
            for m, job in p["jobs"].items():
                r = self.result(job, m, ref)
                res[m].append(r)
                rows.append([g(p["x"]), g(p["radiance"]), label(m), a.spp, g(r["relmse"]),
                             round(r["seconds"], 3), g(r["relmse"] * r["seconds"]),
                             g(r["max"]), r["fireflies"], r["nonfinite"]])
        xs = [p["x"] for p in points]
        figures.sweep_chart(self.path("light.png"), "light half edge (2 = whole ceiling), "
                            "constant power", xs, {label(k): ([r["relmse"] for r in v],
                                                              [r["seconds"] for r in v])
                                                   for k, v in res.items()},
                            "relMSE", "Light size", reverse_x=True)
        text = []
        base = res[nee]
        for m in methods[:-1]:
            v = res[m]
            brk = metrics.first_where(xs, [r["relmse"] > BREAK_FACTOR * b["relmse"]
                                           for r, b in zip(v, base)])
            text.append(
                f"Light sweep, {m} without NEE: relMSE exceeds {BREAK_FACTOR:g}x "
                f"{label(nee)}'s "
                + _onset("light size", brk, g)
                + f"; it grows {g(metrics.ratio(v[-1]['relmse'], v[0]['relmse']))}x from size "
                  f"{g(xs[0])} to {g(xs[-1])} (at {g(xs[-1])}: "
                  f"{g(metrics.ratio(v[-1]['relmse'], base[-1]['relmse']))}x {label(nee)}).")
        text.append(f"Light sweep, {label(nee)}: relMSE changes "
                    f"{g(metrics.ratio(base[-1]['relmse'], base[0]['relmse']))}x from size "
                    f"{g(xs[0])} to {g(xs[-1])}: next-event estimation + MIS holds.")
        self.notes += text
        return [
            report.text(
                f"2. Light size from the whole ceiling (half edge {g(xs[0])}) to a tiny patch "
                f"({g(xs[-1])}) at constant power (radiance x size^2 fixed, {g(rad0)} at size "
                f"{g(size0)}): direction sampling alone must hit the light; {label(nee)} "
                f"samples it directly. {a.spp} spp each."),
            report.image(f"{NAME}/light.png", "relMSE and relMSE x time against the light "
                         "size (x axis reversed: smaller lights to the right)."),
            report.text("\n\n".join(text)),
            report.write_table(self.out, f"{NAME}/light",
                               ["light size", "radiance", "method", "spp", "relMSE", "seconds",
                                "relMSE x s", "max pixel", "fireflies", "NaN/Inf px"], rows,
                               "Light-size sweep", collapsed=True)]

    # ----------------------------------------------------------- 3: grazing

    def grazing_sweep(self) -> list[dict]:
        cfg, a = self.cfg, self.args
        import mitsuba as mi
        scene = probe_scene(a.scene, self.width, self.height)
        bsdf, shape = phong_bsdf(scene)
        if bsdf is None:
            return [report.text("3. Grazing incidence: skipped, the scene has no phong BSDF.")]
        params = mi.traverse(bsdf)
        scene_n = float(params["exponent"][0])
        strategies = [s for s in ("bsdf", "cosine", "uniform") if s in self.strategies]
        rows, wasted, eff, text = [], {}, {}, []
        nonfinite = 0
        for n in cfg.grazing_exponents:
            params["exponent"] = float(n)
            params.update()
            for s in strategies:
                stats = [direction_sampling_stats(bsdf, math.cos(math.radians(t)), s,
                                                    cfg.grazing_samples, a.seed)
                         for t in cfg.angles]
                base = stats[0]["relvar"]
                wasted[f"{s}, n={n:g}"] = (list(cfg.angles), [st["wasted"] for st in stats])
                eff[f"{s}, n={n:g}"] = (list(cfg.angles),
                                        [metrics.ratio(base, st["relvar"]) for st in stats])
                nonfinite += sum(st["nonfinite"] for st in stats)
                for t, st in zip(cfg.angles, stats):
                    rows.append([g(n), s, t, g(st["albedo"]), f"{st['wasted']:.3f}",
                                 g(st["relvar"]), g(metrics.ratio(base, st["relvar"]))])
                if s == "bsdf":
                    half = metrics.first_where(cfg.angles, [st["wasted"] >= 0.5 for st in stats])
                    loss = metrics.first_where(cfg.angles, [metrics.ratio(base, st["relvar"]) < 0.5
                                                      for st in stats])
                    text.append(
                        f"Grazing, lobe sampling at exponent {g(n)}: "
                        f"{stats[-1]['wasted']:.0%} of the samples are wasted (zero weight, "
                        f"below the horizon) at {cfg.angles[-1]} degrees; half are wasted "
                        + _onset("", half, lambda a: f"{a} degrees")
                        + "; efficiency falls below half of normal incidence's "
                        + _onset("", loss, lambda a: f"{a} degrees")
                        + f" (at {cfg.angles[-1]} degrees: "
                          f"{g(metrics.ratio(base, stats[-1]['relvar']))}x).")
        # the scene itself: first hits of the camera on the Phong surface
        params["exponent"] = scene_n
        params.update()
        cos_i, zero = first_hit_sampling(scene, bsdf, shape, seed=a.seed)
        grazing = cos_i < math.cos(math.radians(75))
        scene_sentence = (
            f"Grazing, in the scene (exponent {g(scene_n)}): {grazing.mean():.0%} of the "
            f"camera's first hits on the Phong object are beyond 75 degrees; lobe sampling "
            f"wastes {zero.mean():.1%} of its samples over all hits, "
            f"{zero[grazing].mean() if grazing.any() else 0:.0%} over the grazing ones.")
        text.append(scene_sentence)
        text.append(f"Grazing: {nonfinite} non-finite sample weights over "
                    f"{len(rows) * cfg.grazing_samples} samples.")
        self.notes += text
        figures.line_chart(self.path("grazing.png"), [
            ("Wasted samples (zero weight)", "fraction of samples", wasted),
            ("Efficiency relative to normal incidence", "relVar(0) / relVar(angle)", eff)],
            "incidence angle (degrees from the normal)", (False, True))
        return [
            report.text(
                f"3. Grazing incidence on the scene's Phong material (exponents "
                f"{', '.join(g(n) for n in cfg.grazing_exponents)}): at each incidence angle "
                f"{cfg.grazing_samples} directions are drawn by each strategy and weighted by "
                f"eval/pdf, estimating the directional albedo. A wasted sample has zero "
                f"weight (lobe sampling: below the horizon; cosine/uniform: outside the lobe "
                f"only where cos(alpha) <= 0); efficiency is the inverse relative variance "
                f"per sample (the cost per sample is the same), relative to normal "
                f"incidence."),
            report.image(f"{NAME}/grazing.png", "Wasted-sample fraction and efficiency "
                         "against the incidence angle (solid: bsdf, dashed: cosine, dotted: "
                         "uniform)."),
            report.text("\n\n".join(text)),
            report.write_table(self.out, f"{NAME}/grazing",
                               ["exponent", "strategy", "angle", "albedo", "wasted",
                                "relVar / sample", "efficiency vs normal"], rows,
                               "Grazing sweep", collapsed=True)]

    # ----------------------------------------------------------- 4: Halton

    def halton_sweep(self) -> list[dict]:
        methods = self.halton_methods()
        strategy = methods[0]
        targets = P.doubling_targets(self.cfg.halton_spp)
        h, w = self.height, self.width
        side = max(4, h // 2)
        y0, x0 = (h - side) // 2, min(w - side, w // 2 + side // 4)
        crops, crop_caps, rows, text, viewers = [], [], [], [], []
        for point in self.plans["halton"]:
            d = point["depth"]
            ref = self.reference(point["ref"])
            series, final, images = {}, {}, []
            crops.append([])
            crop_caps.append([])
            for m, jobs in point["jobs"].items():
                pts = []
                for acc in P.accumulate(self.st.store, jobs):
                    pts.append((acc.spp, acc.seconds, metrics.relmse(acc.mean, ref)))
                image = acc.mean
                self.outliers.add(m, image, ref)
                corr = metrics.neighbour_correlation(image, ref)
                spp, secs, err = (list(v) for v in zip(*pts))
                series[m] = (spp, secs, err)
                final[m] = (err[-1], corr, metrics.loglog_slope(spp, err))
                rows.append([d, m, spp[-1], g(err[-1]), g(final[m][2]), f"{corr:.3f}"])
                crops[-1].append(image[y0:y0 + side, x0:x0 + side])
                images.append((m, image))
                crop_caps[-1].append(f"relMSE {err[-1]:.2e}\ncorr {corr:.2f}")
            figures.error_plots(self.path(f"halton_depth{d}.png"), series, "relMSE")
            viewers.append(report.viewer(
                self.out, f"Halton at max_depth {d}, {targets[-1]} spp", images, ref,
                f"Every method of the Halton sweep at max_depth {d} after the last spp: zoom "
                f"in to see plain Halton's structured artifacts."))
            plain = f"{strategy}+halton:none"
            rand = [n for n in final if n != plain and "halton" in n]
            indep = final[strategy]
            worse = metrics.first_where(series[plain][0], [
                e > ei for e, ei in zip(series[plain][2], series[strategy][2])])
            text.append(
                f"Halton at max_depth {d}: without randomization ('none') relMSE after "
                f"{targets[-1]} spp is {g(final[plain][0])} (slope {g(final[plain][2])}), "
                + ", ".join(f"{n.split(':')[-1]} {g(final[n][0])} (slope "
                            f"{g(final[n][2])})" for n in rand)
                + f", independent {g(indep[0])}; 'none' is worse than independent "
                  f"sampling "
                + _onset("", worse, lambda n: f"{n} spp")
                + f". Neighbour-pixel error correlation: none {final[plain][1]:.2f}, "
                + ", ".join(f"{n.split(':')[-1]} {final[n][1]:.2f}" for n in rand)
                + f", independent {indep[1]:.2f}.")
        depths = self.halton_depths
        figures.image_grid(self.path("halton_crops.png"),
                           [list(c) for c in zip(*crops)], methods,
                           [f"max_depth {d}" for d in depths],
                           [list(c) for c in zip(*crop_caps)],
                           title=f"Crops after {targets[-1]} spp")
        self.notes += text
        blocks = [report.text(
            f"4. Halton sequences ({strategy} strategy): plain ('none', the same points in "
            f"every pixel) against the scrambled randomizations and independent sampling, at "
            f"max_depth 2 (direct light only) and {depths[1]} (high dimensions, large prime "
            f"bases), progressive to {targets[-1]} spp (the Halton passes continue one "
            f"sequence). Correlation: Pearson correlation of the luminance errors of "
            f"horizontally adjacent pixels (about 0 when pixels are independent).")]
        blocks += [report.image(f"{NAME}/halton_depth{d}.png",
                                f"relMSE against spp and time at max_depth {d}.")
                   for d in depths]
        blocks += viewers + [report.image(f"{NAME}/halton_crops.png", "Image crops after the "
                                          "last spp: structured artifacts of plain Halton."),
                             report.text("\n\n".join(text)),
                             report.write_table(self.out, f"{NAME}/halton",
                                                ["max_depth", "method", "spp", "relMSE",
                                                 "slope vs spp", "neighbour corr."], rows,
                                                "Halton sweep")]
        return blocks

    # ----------------------------------------------------------- 5: outliers

    def outlier_blocks(self) -> list[dict]:
        rows = [[k, v["images"], g(v["max"]), v["fireflies"], v["nonfinite"]]
                for k, v in self.outliers.rows.items()]
        total_nan = sum(v["nonfinite"] for v in self.outliers.rows.values())
        worst = max(self.outliers.rows.items(), key=lambda kv: kv[1]["fireflies"],
                    default=None)
        sentence = (f"Outliers over all sweep renders: {total_nan} NaN/Inf pixels in total"
                    + (f"; most fireflies: {worst[0]} ({worst[1]['fireflies']} in "
                       f"{worst[1]['images']} images, largest pixel {g(worst[1]['max'])})"
                       if worst else "") + ".")
        self.notes.append(sentence)
        return [report.write_table(
            self.out, f"{NAME}/outliers", ["method", "images", "largest pixel", "fireflies",
                                           "NaN/Inf pixels"], rows,
            f"5. Outliers per method over every sweep render. Firefly: a pixel whose "
            f"luminance error exceeds the image's median error by {metrics.FIREFLY_MADS:g} median "
            f"absolute deviations. NaN/Inf: non-finite pixels of the accumulated image (one "
            f"non-finite sample makes its pixel non-finite)."), report.text(sentence)]


