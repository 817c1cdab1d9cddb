"""Stability sweeps: where each sampling method breaks down, measured and charted.

Four sweeps on the scene's parameters, each a chart of error and error x time
against the swept value per method, with breakdown points computed from the
data: (1) the Phong exponent of the glossy object, (2) the size of the light
at constant power, with and without next-event estimation, (3) grazing
incidence (wasted zero-weight samples and efficiency loss, measured on the
scene's Phong material), (4) Halton without and with randomization at low and
high path depth (error curves, image crops, neighbour-pixel correlation).
Outliers (largest pixel, fireflies, NaN/Inf) are counted over every render.

    python -m experiments.stability --help
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np

from experiments.lib import cli, figures, metrics, report
from experiments.lib import methods as M
from experiments.lib import render as R
from experiments.lib import stability as S

NAME = "stability"
ORDER = 30
SWEEPS = ("exponent", "light", "grazing", "halton")
#: relMSE ratio at which a method counts as broken down against the robust one.
BREAK_FACTOR = 10.0


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
QUICK_DEFAULTS = {"resolution": (32, 16), "spp": 4, "reference_spp": 16}


def build_parser() -> cli.Parser:
    p = cli.common_parser("python -m experiments.stability", __doc__.split("\n")[0], spp=32)
    p.set_defaults(resolution="128x64", reference_spp=128)
    p.add_argument("--quick", action="store_true",
                   help=f"tiny run (for tests): fewer sweep points; resolution, --spp and "
                        f"--reference-spp default to {QUICK_DEFAULTS['resolution'][0]}x"
                        f"{QUICK_DEFAULTS['resolution'][1]}, {QUICK_DEFAULTS['spp']} and "
                        f"{QUICK_DEFAULTS['reference_spp']}")
    p.add_argument("--sweeps", type=sweep_list, default=",".join(SWEEPS),
                   help=f"comma-separated sweeps to run: {', '.join(SWEEPS)}")
    return p


def sweep_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in SWEEPS]
    if bad or not names:
        raise cli.argparse.ArgumentTypeError(
            f"unknown sweep '{bad[0] if bad else text}': choose from {', '.join(SWEEPS)}")
    return list(dict.fromkeys(names))


def parse(argv=None):
    parser = build_parser()
    args = cli.parse_args(parser, argv)
    if args.quick:       # quick values for every option left at its default
        for key, value in QUICK_DEFAULTS.items():
            default = parser.get_default(key)
            default = cli.resolution(default) if key == "resolution" else default
            if getattr(args, key) == default:
                setattr(args, key, value)
    args.config = QUICK if args.quick else NORMAL
    return args


def g(x: float) -> str:
    return f"{x:.3g}"


class Outliers:
    """Largest pixel, fireflies and non-finite pixels per method over every sweep render."""

    def __init__(self):
        self.rows: dict[str, dict] = {}

    def add(self, label: str, image, reference) -> dict:
        o = S.outliers(image, reference)
        r = self.rows.setdefault(label, {"images": 0, "max": 0.0, "fireflies": 0,
                                         "nonfinite": 0})
        r["images"] += 1
        r["max"] = max(r["max"], o["max"])
        r["fireflies"] += o["fireflies"]
        r["nonfinite"] += o["nonfinite"]
        return o


class Stability:
    def __init__(self, args):
        self.args = args
        self.out = args.out
        self.width, self.height = args.resolution
        self.outliers = Outliers()
        self.notes: list[str] = []          # closing note, one sentence per finding
        self.strategies = list(dict.fromkeys(m.strategy for m in args.method_objs))
        self.scene_dir = os.path.join(self.out, NAME, "scenes")
        self.ref_seconds = 0.0

    def path(self, name: str) -> str:
        return os.path.join(self.out, NAME, name)

    def reference(self, info):
        a = self.args
        ref, meta = R.reference(self.out, info, self.width, self.height, a.reference_spp,
                                a.reference_integrator, a.variant, a.seed)
        self.ref_seconds += meta.get("seconds", 0.0)
        return ref

    def render(self, directory: str, info, sm: S.SweepMethod, ref, mask=None) -> dict:
        a = self.args
        job = S.sweep_job(self.out, f"{NAME}/{directory}", info, sm, self.width, self.height,
                          a.variant, a.seed)
        acc = R.run_progressive(job, [a.spp])
        image = acc.mean
        o = self.outliers.add(sm.label, image, ref)
        sel = mask if mask is not None else np.ones(image.shape[:2], bool)
        level = S.ratio(float(np.mean(image[sel])), float(np.mean(ref[sel])))
        return {"relmse": S.masked_relmse(image, ref), "level": level,
                "relmse_mask": S.masked_relmse(image, ref, mask),
                "seconds": acc.seconds, "image": image, **o}

    def variant_scene(self, name: str, overrides: dict):
        return S.scene_variant(self.args.info, self.scene_dir, name, overrides)

    # ----------------------------------------------------------- 1: exponent

    def exponent_sweep(self) -> list[dict]:
        cfg, a = self.args.config, self.args
        sms = [S.SweepMethod(M.parse_method(s)) for s in ("uniform", "cosine", "bsdf")
               if s in self.strategies]
        mask = S.phong_mask(a.info, self.width, self.height)
        res = {sm.label: [] for sm in sms}
        rows = []
        for n in cfg.exponents:
            info = self.variant_scene(f"exponent-{n:g}", {"exponent": float(n)})
            ref = self.reference(info)
            for sm in sms:
                r = self.render(f"exponent/{n:g}", info, sm, ref, mask)
                res[sm.label].append(r)
                rows.append([g(n), sm.label, a.spp, g(r["relmse_mask"]), g(r["relmse"]),
                             round(r["seconds"], 3), g(r["relmse_mask"] * r["seconds"]),
                             g(r["max"]), r["fireflies"], r["nonfinite"]])
        xs = list(cfg.exponents)
        S.sweep_chart(self.path("exponent.png"), "Phong exponent of the glossy object", xs,
                      {k: ([r["relmse_mask"] for r in v], [r["seconds"] for r in v])
                       for k, v in res.items()}, "relMSE on the Phong pixels", "Exponent")
        text = [f"{int(mask.sum())} of {mask.size} pixels see a Phong surface first; the errors "
                f"are measured on them (full-image relMSE in the table)."]
        eff = {k: [metrics.efficiency(r["relmse_mask"], r["seconds"]) for r in v]
               for k, v in res.items()}
        if "bsdf" in res:
            bs = res["bsdf"]
            for other in [k for k in ("cosine", "uniform") if k in res]:
                pays = S.first_where(xs, [e_b >= 2 * e_o for e_b, e_o
                                          in zip(eff["bsdf"], eff[other])])
                worse = [x for x, e_b, e_o in zip(xs, eff["bsdf"], eff[other]) if e_b < e_o]
                boom = S.first_where(xs, [r["relmse_mask"] > BREAK_FACTOR * b["relmse_mask"]
                                          for r, b in zip(res[other], bs)])
                sentence = (
                    f"Exponent sweep, bsdf (lobe) vs {other}: lobe sampling pays off "
                    f"(efficiency 1/(relMSE x time) at least 2x {other}'s) from exponent "
                    f"{g(pays) if pays is not None else '(never in the sweep)'}"
                    + (f"; it does not pay off (less efficient than {other}) at exponent "
                       f"{', '.join(g(x) for x in worse)}" if worse else
                       f"; it is never less efficient than {other}")
                    + f". {other} sampling explodes (relMSE > {BREAK_FACTOR:g}x lobe "
                      f"sampling's) from exponent "
                    + (f"{g(boom)}" if boom is not None else "(never in the sweep)")
                    + f"; at exponent {g(xs[-1])} its relMSE is "
                      f"{g(S.ratio(res[other][-1]['relmse_mask'], bs[-1]['relmse_mask']))}x "
                      f"lobe sampling's, and its Phong pixels average "
                      f"{res[other][-1]['level']:.0%} of the reference"
                    + (f" (the narrow lobe is rarely hit: the error hides in rare, huge "
                       f"samples that a {a.spp}-spp image mostly lacks)."
                       if res[other][-1]['level'] < 0.9 else
                       " (a few huge samples dominate)." if res[other][-1]['level'] > 1.1
                       else "."))
                text.append(sentence)
                self.notes.append(sentence)
        return [
            report.text(
                f"1. Phong exponent of the glossy object from {g(xs[0])} to {g(xs[-1])}, direction "
                f"sampling without NEE (as in the writeup), {a.spp} spp each, against a "
                f"{a.reference_spp}-spp reference per exponent."),
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
        cfg, a = self.args.config, self.args
        defaults = S.scene_defaults(a.info.path)
        size0, rad0 = float(defaults["light_size"]), float(defaults["light_radiance"])
        sms = [S.SweepMethod(M.parse_method(s)) for s in ("uniform", "cosine", "bsdf")
               if s in self.strategies]
        nee = S.SweepMethod(M.parse_method("bsdf" if "bsdf" in self.strategies
                                           else self.strategies[0]), nee=True)
        sms.append(nee)
        res = {sm.label: [] for sm in sms}
        rows = []
        for size in cfg.light_sizes:
            radiance = rad0 * (size0 / size) ** 2
            info = self.variant_scene(f"light-{size:g}", {"light_size": float(size),
                                                          "light_radiance": radiance})
            ref = self.reference(info)
            for sm in sms:
                r = self.render(f"light/{size:g}", info, sm, ref)
                res[sm.label].append(r)
                rows.append([g(size), g(radiance), sm.label, a.spp, g(r["relmse"]),
                             round(r["seconds"], 3), g(r["relmse"] * r["seconds"]),
                             g(r["max"]), r["fireflies"], r["nonfinite"]])
        xs = list(cfg.light_sizes)
        S.sweep_chart(self.path("light.png"), "light half edge (2 = whole ceiling), "
                      "constant power", xs, {k: ([r["relmse"] for r in v],
                                                 [r["seconds"] for r in v])
                                             for k, v in res.items()},
                      "relMSE", "Light size", reverse_x=True)
        text = []
        base = res[nee.label]
        for sm in sms:
            if sm.nee:
                continue
            v = res[sm.label]
            brk = S.first_where(xs, [r["relmse"] > BREAK_FACTOR * b["relmse"]
                                     for r, b in zip(v, base)])
            text.append(
                f"Light sweep, {sm.label} without NEE: relMSE exceeds {BREAK_FACTOR:g}x "
                f"{nee.label}'s from light size "
                + (g(brk) if brk is not None else "(never in the sweep)")
                + f"; it grows {g(S.ratio(v[-1]['relmse'], v[0]['relmse']))}x from size "
                  f"{g(xs[0])} to {g(xs[-1])} (at {g(xs[-1])}: "
                  f"{g(S.ratio(v[-1]['relmse'], base[-1]['relmse']))}x {nee.label}).")
        text.append(f"Light sweep, {nee.label}: relMSE changes "
                    f"{g(S.ratio(base[-1]['relmse'], base[0]['relmse']))}x from size "
                    f"{g(xs[0])} to {g(xs[-1])}: next-event estimation + MIS holds.")
        self.notes += text
        return [
            report.text(
                f"2. Light size from the whole ceiling (half edge {g(xs[0])}) to a tiny patch "
                f"({g(xs[-1])}) at constant power (radiance x size^2 fixed, {g(rad0)} at size "
                f"{g(size0)}): direction sampling alone must hit the light; {nee.label} "
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
        cfg, a = self.args.config, self.args
        import drjit as dr
        import mitsuba as mi
        scene = M.load_scene(a.info, self.width, self.height,
                             {"type": "vr_path", "max_depth": 1})
        bsdf = next((s.bsdf() for s in scene.shapes()
                     if type(s.bsdf()).__name__ == "PhongBSDF"), None)
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
                stats = [S.direction_sampling_stats(bsdf, math.cos(math.radians(t)), s,
                                                    cfg.grazing_samples, a.seed)
                         for t in cfg.angles]
                base = stats[0]["relvar"]
                wasted[f"{s}, n={n:g}"] = (list(cfg.angles), [st["wasted"] for st in stats])
                eff[f"{s}, n={n:g}"] = (list(cfg.angles),
                                        [S.ratio(base, st["relvar"]) for st in stats])
                nonfinite += sum(st["nonfinite"] for st in stats)
                for t, st in zip(cfg.angles, stats):
                    rows.append([g(n), s, t, g(st["albedo"]), f"{st['wasted']:.3f}",
                                 g(st["relvar"]), g(S.ratio(base, st["relvar"]))])
                if s == "bsdf":
                    half = S.first_where(cfg.angles, [st["wasted"] >= 0.5 for st in stats])
                    loss = S.first_where(cfg.angles, [S.ratio(base, st["relvar"]) < 0.5
                                                      for st in stats])
                    text.append(
                        f"Grazing, lobe sampling at exponent {g(n)}: "
                        f"{stats[-1]['wasted']:.0%} of the samples are wasted (zero weight, "
                        f"below the horizon) at {cfg.angles[-1]} degrees; half are wasted from "
                        + (f"{half} degrees" if half is not None else "(never in the sweep)")
                        + "; efficiency falls below half of normal incidence's from "
                        + (f"{loss} degrees" if loss is not None else "(never in the sweep)")
                        + f" (at {cfg.angles[-1]} degrees: "
                          f"{g(S.ratio(base, stats[-1]['relvar']))}x).")
        # the scene itself: first hits of the camera on the Phong surface
        params["exponent"] = scene_n
        params.update()
        sensor = scene.sensors()[0]
        w, h, k = self.width, self.height, 16
        idx = dr.arange(mi.UInt32, w * h * k) // k
        pos = mi.Point2f((mi.Float(idx % w) + 0.5) / w, (mi.Float(idx // w) + 0.5) / h)
        ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
        si = scene.ray_intersect(ray)
        hit = si.is_valid() & (si.shape == mi.ShapePtr(
            next(s for s in scene.shapes() if type(s.bsdf()).__name__ == "PhongBSDF")))
        rng = np.random.default_rng(a.seed)
        u = rng.random((3, w * h * k))
        _, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(u[0]),
                                mi.Point2f(u[1], u[2]), hit)
        hit_np = np.array(hit)
        cos_i = np.array(si.wi.z)[hit_np]
        zero = (np.array(weight) == 0).all(axis=0)[hit_np]
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
        S.line_chart(self.path("grazing.png"), [
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
        cfg, a = self.args.config, self.args
        if not M.plugin_available("halton"):
            return [report.text("4. Halton: skipped, the halton sampler is not available.")]
        strategy = "uniform" if "uniform" in self.strategies else self.strategies[0]
        valid = M.halton_randomizations() or ("none", "owen")
        names = [strategy] + [f"{strategy}+halton:{r}" for r in valid]
        sms = [S.SweepMethod(M.parse_method(n)) for n in names]
        depths = [2, max(7, a.info.max_depth)]
        targets = R.doubling_targets(cfg.halton_spp)
        h, w = self.height, self.width
        side = max(4, h // 2)
        y0, x0 = (h - side) // 2, min(w - side, w // 2 + side // 4)
        crops, crop_caps, rows, text = [], [], [], []
        for d in depths:
            info = S.with_max_depth(a.info, d)
            ref = self.reference(info)
            series, final = {}, {}
            crops.append([])
            crop_caps.append([])
            for sm in sms:
                job = S.sweep_job(self.out, f"{NAME}/halton/depth{d}", info, sm, w, h,
                                  a.variant, a.seed)
                R.run_progressive(job, targets)
                pts = []
                for cp in job.checkpoints:
                    image = R.read_checkpoint(job, cp)
                    pts.append((cp["spp"], cp["seconds"], S.masked_relmse(image, ref)))
                self.outliers.add(sm.label, image, ref)
                corr = S.neighbour_correlation(image, ref)
                spp, secs, err = (list(v) for v in zip(*pts))
                series[sm.label] = (spp, secs, err)
                final[sm.label] = (err[-1], corr, metrics.loglog_slope(spp, err))
                rows.append([d, sm.label, spp[-1], g(err[-1]), g(final[sm.label][2]),
                             f"{corr:.3f}"])
                crops[-1].append(image[y0:y0 + side, x0:x0 + side])
                crop_caps[-1].append(f"relMSE {err[-1]:.2e}\ncorr {corr:.2f}")
            figures.error_plots(self.path(f"halton_depth{d}.png"), series, "relMSE")
            plain = f"{strategy}+halton:none"
            if plain in final:
                rand = [n for n in final if n != plain and "halton" in n]
                indep = final[strategy]
                worse = S.first_where(series[plain][0], [
                    e > ei for e, ei in zip(series[plain][2], series[strategy][2])])
                text.append(
                    f"Halton at max_depth {d} (about {2 + 4 * d} dimensions): without "
                    f"randomization ('none') relMSE after {targets[-1]} spp is "
                    f"{g(final[plain][0])} (slope {g(final[plain][2])}), "
                    + ", ".join(f"{n.split(':')[-1]} {g(final[n][0])} (slope "
                                f"{g(final[n][2])})" for n in rand)
                    + f", independent {g(indep[0])}; 'none' is worse than independent "
                      f"sampling from "
                    + (f"{worse} spp" if worse is not None else "(never in the sweep)")
                    + f". Neighbour-pixel error correlation: none {final[plain][1]:.2f}, "
                    + ", ".join(f"{n.split(':')[-1]} {final[n][1]:.2f}" for n in rand)
                    + f", independent {indep[1]:.2f}.")
        figures.image_grid(self.path("halton_crops.png"),
                           [list(c) for c in zip(*crops)], [sm.label for sm in sms],
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
        blocks += [report.image(f"{NAME}/halton_crops.png", "Image crops after the last spp: "
                                "structured artifacts of plain Halton."),
                   report.text("\n\n".join(text)),
                   report.write_table(self.out, f"{NAME}/halton",
                                      ["max_depth", "method", "spp", "relMSE", "slope vs spp",
                                       "neighbour corr."], rows, "Halton sweep")]
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
            f"luminance error exceeds the image's median error by {S.FIREFLY_MADS:g} median "
            f"absolute deviations. NaN/Inf: non-finite pixels of the accumulated image (one "
            f"non-finite sample makes its pixel non-finite)."), report.text(sentence)]


def run(args) -> None:
    start = time.perf_counter()
    st = Stability(args)
    blocks = [report.text(
        f"Where each sampling method breaks down, on {os.path.basename(args.scene)} at "
        f"{st.width}x{st.height}. Each sweep point is the scene with one parameter changed "
        f"(the scene files are in {NAME}/scenes/); errors are relMSE against a "
        f"{args.reference_spp}-spp reference ({args.reference_integrator} + NEE) of the same "
        f"point. Times are warm render times on this (shared) machine. Breakdown points "
        f"below are computed from the measurements.")]
    parts = {"exponent": st.exponent_sweep, "light": st.light_sweep,
             "grazing": st.grazing_sweep, "halton": st.halton_sweep}
    for name in args.sweeps:
        try:
            blocks += parts[name]()
        except KeyError as e:   # the scene lacks a swept <default> parameter
            blocks.append(report.text(f"Sweep '{name}' skipped: the scene has no <default> "
                                      f"parameter {e}."))
    blocks += st.outlier_blocks()
    blocks.append(report.text("Closing note, per sweep: " + " ".join(st.notes)))
    settings = {"scene": args.scene, "resolution": f"{st.width}x{st.height}", "spp": args.spp,
                "sweeps": ", ".join(args.sweeps), "quick": args.quick,
                "strategies": ", ".join(st.strategies), "variant": args.variant,
                "seed": args.seed, "reference": f"{args.reference_spp} spp, "
                f"{args.reference_integrator} + NEE ({st.ref_seconds:.1f} s)",
                "breakdown factor": BREAK_FACTOR, "firefly threshold (MADs)": S.FIREFLY_MADS}
    report.write_section(args.out, NAME, "Stability: where each method breaks down", ORDER,
                         settings, blocks, args.variant, time.perf_counter() - start)
    store_summary(args, st)


def store_summary(args, st: Stability) -> None:
    """Machine-readable results (breakdown sentences, outliers) for tests and other tools."""
    from experiments.lib import store
    store.write_json(os.path.join(args.out, NAME, "summary.json"),
                     {"notes": st.notes, "outliers": st.outliers.rows})


def main(argv=None) -> None:
    args = parse(argv)
    run(args)
    print(f"report: {report.build_report(args.out, args.variant)}")


if __name__ == "__main__":
    cli.main_wrapper(main)
