"""Rows 8 of ``make bench``: adaptive sampling against its ceiling at equal time.

Per scene of :data:`SCENES` (the suite's film, 48x36; ``bsdf+nee`` nested, at the count
the suite gives it at equal time):

1. **The ceiling at equal samples**: an oracle that knew every pixel's relative variance of
   one sample v (here from :data:`ORACLE_SPP` samples per pixel) and gave the pixels
   samples in proportion to sqrt v would lower the relMSE mean(v) / mean(sqrt v)^2 times
   (the suite's "adaptive ceiling", ``suite.errors.oracle_gain``).
2. **The ceiling at equal time**: the same allocation, each sample costing what a sample
   costs in its pixel. A pixel's marginal time per sample is measured on :data:`CLASSES`
   classes of pixels by sqrt v: the process CPU time of a render of :data:`COST_SPP[1]`
   samples in each of the class's pixels less that of :data:`COST_SPP[0]`, over the
   difference in samples (their fixed cost cancels), the median of :data:`COST_REPS`.
   The allocation's time per sample is then sum(sqrt v c) / sum(sqrt v), a uniform
   render's mean(c), and the ceiling the first ceiling times their ratio. Allocated by
   sqrt(v / c) instead (cost-aware, the optimum at equal time) it is
   mean(v) mean(c) / mean(sqrt(v c))^2.
3. **Measured**: ``bsdf+nee+adaptive`` over ``bsdf+nee``, efficiency 1/(relMSE x CPU time)
   at the same count, :data:`REPEATS` renders of each, interleaved; relMSE against the
   oracle's image less its own expected relMSE (mean(v) / :data:`ORACLE_SPP`).

Issue 43's targets for the measured ratio: at least 2 on phong_highlight and veach_mis,
1.3 on grazing and environment. A target over the equal-time ceiling cannot be met by
any allocation of the same estimator's samples.

Usage: ``python -m benchmarks.adaptive [--scenes environment,grazing] [--repeats 10]``
"""
from __future__ import annotations

import argparse
import os
import statistics

import numpy as np

from . import common

#: (scene of scenes/suite, its count: the suite's equal-time count of ``bsdf+nee``).
SCENES = (("phong_highlight", 256), ("veach_mis", 4096), ("grazing", 256),
          ("environment", 256))
#: Issue 43's target for the measured ratio, per scene.
TARGETS = {"phong_highlight": 2.0, "veach_mis": 2.0, "grazing": 1.3, "environment": 1.3}
#: The suite's film.
WIDTH, HEIGHT = 48, 36
#: Samples per pixel of the oracle's variances and image.
ORACLE_SPP = 16384
#: Classes of pixels (by sqrt v) whose marginal cost per sample is measured.
CLASSES = 6
#: The two counts per pixel of a class whose renders' difference gives its marginal cost.
COST_SPP = (512, 2048)
#: Renders per count and class (their median).
COST_REPS = 5
#: Renders of each method for the measured ratio.
REPEATS = 10


def _scene(name: str):
    """(the suite scene at the suite's film, the ``bsdf+nee`` integrator, vr_adaptive
    nesting it)."""
    import mitsuba as mi
    from experiments.lib.methods import parse_method
    from experiments.lib.scenes import effective_depth, read_scene
    path = os.path.join(common.ROOT, "scenes", "suite", f"{name}.xml")
    depth = effective_depth(read_scene(path))
    return (mi.load_file(path, width=WIDTH, height=HEIGHT),
            *(mi.load_dict(parse_method(m).integrator_dict(depth))
              for m in ("bsdf+nee", "bsdf+nee+adaptive")))


def _samples(adaptive, scene, seed: int, pixels: np.ndarray, per: int):
    """``per`` samples in each of ``pixels``: the per-pixel RGB sums and the luminance's
    per-pixel sums and squares (both halves added)."""
    import drjit as dr
    import mitsuba as mi
    sensor = scene.sensors()[0]
    index = mi.UInt32(np.repeat(pixels.astype(np.uint32), per))
    total, (sums, squares) = adaptive.render_samples(
        scene, sensor, sensor.sampler(), seed, index, dr.arange(mi.UInt32, dr.width(index)))
    pair = lambda x: np.array(x).reshape(-1, 2).sum(axis=1)          # noqa: E731
    return np.stack([np.array(c) for c in total], axis=-1), pair(sums), pair(squares)


def oracle(adaptive, scene) -> tuple[np.ndarray, np.ndarray]:
    """(the image of :data:`ORACLE_SPP` samples per pixel (H, W, 3), every pixel's relative
    variance of one sample v, from its luminance, with the relMSE's offset)."""
    from integrators.adaptive import RELMSE_EPS
    pixels = np.arange(WIDTH * HEIGHT)
    total, lum, squares = _samples(adaptive, scene, 1, pixels, ORACLE_SPP)
    mean = lum / ORACLE_SPP
    var = np.maximum(squares / ORACLE_SPP - mean ** 2, 0.0) * ORACLE_SPP / (ORACLE_SPP - 1)
    image = (total / ORACLE_SPP).reshape(HEIGHT, WIDTH, 3)
    return image, var / (mean ** 2 + RELMSE_EPS)


def pixel_costs(adaptive, scene, v: np.ndarray) -> np.ndarray:
    """Every pixel's marginal CPU seconds per sample, measured per class of pixels by
    sqrt v (see the module)."""
    order = np.argsort(np.sqrt(v), kind="stable")
    cost = np.empty(len(v))
    for part in np.array_split(order, CLASSES):
        pixels = np.sort(part)
        times = []
        for per in COST_SPP:
            times.append(statistics.median(
                common.timed(lambda r=r, per=per: _samples(adaptive, scene, 100 + r, pixels,
                                                           per))[1]
                for r in range(COST_REPS)))
        cost[part] = max(times[1] - times[0], 1e-12) / (len(pixels) * (COST_SPP[1]
                                                                       - COST_SPP[0]))
    return cost


def ceilings(v: np.ndarray, cost: np.ndarray) -> dict:
    """The oracle's gains (see the module): at equal samples, at equal time allocated by
    sqrt v, at equal time allocated by sqrt(v / c)."""
    r = np.sqrt(v)
    samples = float(np.mean(v) / np.mean(r) ** 2)
    return {"samples": samples,
            "time": samples * float(np.mean(cost) / (np.sum(r * cost) / np.sum(r))),
            "time_cost_aware": float(np.mean(v) * np.mean(cost)
                                     / np.mean(np.sqrt(v * cost)) ** 2)}


def measured(plain, adaptive, scene, spp: int, reference: np.ndarray,
             floor: float, repeats: int) -> dict:
    """``bsdf+nee+adaptive`` over ``bsdf+nee`` at ``spp``: efficiency, relMSE and CPU
    time ratios (``floor``: the reference's own expected relMSE, subtracted)."""
    from experiments.lib import metrics
    errors = {"plain": [], "adaptive": []}

    def run(name, integrator):
        def one(rep):
            image = np.array(integrator.render(scene, seed=1000 + max(rep, 0), spp=spp))
            if rep >= 0:
                errors[name].append(metrics.relmse(image[..., :3], reference) - floor)
        return one
    times = common.interleaved({"plain": run("plain", plain),
                                "adaptive": run("adaptive", adaptive)}, "plain", repeats)
    error = float(np.mean(errors["plain"]) / np.mean(errors["adaptive"]))
    cost = times["adaptive"]["cpu"]
    return {"efficiency": error / cost, "relmse": error, "cost": cost}


def quick_settings(quick: bool) -> dict:
    """:func:`measure`'s settings for ``benchmarks.run`` (``--quick``: a check that it runs)."""
    return {"scenes": (("grazing", 64),), "repeats": 2} if quick else {}


def measure(scenes=SCENES, repeats: int = REPEATS) -> dict:
    common.set_variant()
    import integrators  # noqa: F401  (registers vr_adaptive)
    out = {}
    for name, spp in scenes:
        scene, plain, adaptive = _scene(name)
        reference, v = oracle(adaptive, scene)
        out[name] = {"spp": spp, **ceilings(v, pixel_costs(adaptive, scene, v)),
                     "measured": measured(plain, adaptive, scene, spp, reference,
                                          float(np.mean(v)) / ORACLE_SPP, repeats)}
    return out


def rows(res: dict) -> list[list[str]]:
    table = []
    for name, r in res.items():
        m, target = r["measured"], TARGETS.get(name)
        reachable = target is None or r["time_cost_aware"] >= target
        holds = "" if target is None else ("yes" if m["efficiency"] >= target else
                                           "no" if reachable else "no (over the ceiling)")
        table.append([f"8. bsdf+nee+adaptive / bsdf+nee on {name} ({WIDTH}x{HEIGHT}, "
                      f"{r['spp']} spp): efficiency; the oracle's ceiling at equal time "
                      f"(cost-aware) and at equal samples",
                      f"{m['efficiency']:.2f} (relMSE {m['relmse']:.2f}, time "
                      f"{m['cost']:.2f}); ceiling {r['time']:.2f} ({r['time_cost_aware']:.2f}),"
                      f" {r['samples']:.2f}",
                      f">= {target:g} (issue 43)" if target else "(info)", holds])
    return table


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(n for n, _ in SCENES),
                    help="comma-separated scenes of SCENES")
    ap.add_argument("--repeats", type=int, default=REPEATS)
    args = ap.parse_args(argv)
    known = dict(SCENES)
    names = args.scenes.split(",")
    bad = [n for n in names if n not in known]
    if bad:
        ap.error(f"unknown scene(s) {', '.join(bad)}; choose from {', '.join(known)}")
    for row in rows(measure([(n, known[n]) for n in names], args.repeats)):
        print(" | ".join(row))


if __name__ == "__main__":
    main()
