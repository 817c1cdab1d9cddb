"""Halton benchmarks (issue 11): cost per sample and efficiency against Mitsuba's samplers.

``python -m benchmarks.halton [--quick] [--floor]`` prints two tables measured in this
process; :func:`rows` returns the first in ``benchmarks.run``'s row format
(``[measure, value, target, holds?]``), :func:`measure` everything.

1. Cost: CPU time per sample of ``halton`` (each randomization) over
   ``independent`` on ``mi.cornell_box()`` at 256x256 and 32 spp, under
   Mitsuba's ``path`` and under ``vr_path`` (bsdf, NEE), max_depth 8. Target
   <= 1.05.
2. Efficiency 1 / (MSE x time) of halton's best randomization over the best
   native sampler (``independent``, ``stratified``, ``multijitter``,
   ``orthogonal``, ``ldsampler``), ``vr_path`` bsdf + NEE, 64 spp requested
   (native samplers round it: ``orthogonal`` to a prime squared), max_depth 2
   and 8, on the bundled scene (``scenes/cbox.xml``) and ``mi.cornell_box()``.
   Target >= 1.0. The second table gives every sampler's efficiency over
   ``independent``.

3. ``--floor``: why the randomized variants cannot reach the cost target.
   Probes replace the odd bases' values by a hash of (dimension, index,
   seed) (random values, as ``independent`` draws) and add this module's
   radical inverse to it times 1e-30, so that its arithmetic runs but the
   rays are those of random samples: ``hash`` alone, ``+none`` (the plain
   radical inverse), ``+owen`` and ``+permute_digits`` (the randomized
   ones; base 2 stays ``owen``'s). The plain ones render faster than their arithmetic costs because
   a SIMD packet holds consecutive samples of one pixel, which a
   (rotated) lattice keeps together; randomized points scatter them.

Method: every sampler here is unbiased and randomized by the seed, so the MSE
of a render is its variance, estimated per pixel from ``seeds`` renders with
different seeds (no reference image whose own noise would bias the ratios)
and averaged over the pixels and channels. Renders are interleaved (each
round renders every sampler once, in alternating order, after a warm-up
render) and timed in process CPU time; a sampler's time is the median over
rounds of its time over ``independent``'s in the same round.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from . import common
from .common import mi
from experiments.lib.samplers import native as _native

NATIVE = _native()  # Mitsuba's own samplers

#: Other sample counts at which halton (owen) is measured: 3^4 and 2^3 3^2.
EXTRA_HALTON_SPP = (81, 72)
COST_TARGET = 1.05
EFFICIENCY_TARGET = 1.0


# ------------------------------------------------------------------ scenes

def cornell_box(width: int, height: int, spp: int, sampler: str, max_depth: int = 8,
                randomization: str | None = None):
    d = mi.cornell_box()
    d["sensor"]["film"]["width"], d["sensor"]["film"]["height"] = width, height
    d["sensor"]["sampler"] = {"type": sampler, "sample_count": spp}
    if randomization is not None:
        d["sensor"]["sampler"]["randomization"] = randomization
    d["integrator"]["max_depth"] = max_depth
    return mi.load_dict(d)


def scene_for(name: str, width: int, height: int, spp: int, sampler: str, max_depth: int,
              randomization: str | None = None):
    if name == "cornell_box":
        return cornell_box(width, height, spp, sampler, max_depth, randomization)
    return common.load_scene(width, height, spp, sampler, randomization, max_depth)


def sampler_label(sampler: str, randomization: str | None, spp: int | None = None) -> str:
    label = f"halton:{randomization}" if randomization else sampler
    return f"{label}@{spp}" if spp else label


# -------------------------------------------------------------------- cost

def measure_cost(reps: int, width: int = 256, spp: int = 32) -> dict:
    """{integrator: {halton:<r>: {cpu, wall}}}: time per sample over independent."""
    out = {}
    configs = [("independent", None)] + [("halton", r) for r in common.halton_randomizations()]
    scenes = {sampler_label(s, r): cornell_box(width, width, spp, s, 8, r) for s, r in configs}
    integrators = {"path": common.path_integrator(8),
                   "vr_path": common.vr_path_integrator("bsdf", 8)}
    for name, integrator in integrators.items():
        runs = {n: (lambda rep, s=s: common.render(s, integrator, seed=rep + 1))
                for n, s in scenes.items()}
        out[name] = common.interleaved(runs, "independent", reps)
    return out


def _probe(kind: str):
    """An odd-base radical inverse for the cost floor (see the module docs)."""
    import drjit as dr
    from integrators import qmc
    inner = qmc._radical_inverse_odd

    def odd(base_index, a, seed, randomization):
        x = qmc.mix32(qmc.mix32(seed ^ (base_index * 0x68E31DA4)) + a * qmc.HASH_MULTIPLIER)
        r = qmc._to_unit_fast(x)
        if kind == "hash":
            return r
        return dr.minimum(r + inner(base_index, a, seed, kind) * 1e-30, qmc.ONE_MINUS_EPSILON)
    return odd


def measure_cost_floor(reps: int, width: int = 256, spp: int = 32) -> dict:
    """{integrator: {probe: {cpu, wall}}}: the cost probes over independent."""
    from integrators import qmc
    original = qmc._radical_inverse_odd
    probes = ["hash", "none"] + [r for r in common.halton_randomizations() if r != "none"]
    configs = {"independent": None} \
        | {f"halton:{r}": None for r in common.halton_randomizations()} \
        | {"probe:hash" if p == "hash" else f"probe:hash+{p}": p for p in probes}
    scenes = {n: cornell_box(width, width, spp, "independent" if n == "independent" else "halton",
                             8, None if n == "independent" else
                             (n.split(":")[1] if p is None else "owen"))
              for n, p in configs.items()}
    probe_fns = {p: _probe(p) for p in probes}
    out = {}
    integrators = {"path": common.path_integrator(8),
                   "vr_path": common.vr_path_integrator("bsdf", 8)}
    try:
        for name, integrator in integrators.items():
            def run(n, integrator=integrator):
                def fn(rep):
                    p = configs[n]
                    qmc._radical_inverse_odd = original if p is None else probe_fns[p]
                    common.render(scenes[n], integrator, seed=rep + 1)
                return fn
            out[name] = common.interleaved({n: run(n) for n in configs}, "independent", reps)
    finally:
        qmc._radical_inverse_odd = original
    return out


# -------------------------------------------------------------- efficiency

def measure_efficiency(scene: str, max_depth: int, seeds: int, width: int, height: int,
                       spp: int = 64) -> dict:
    """Per sampler: MSE (variance over seeds), time over independent, efficiency.

    Halton (owen) also runs at 81 = 3^4 spp (dimension 1, base 3, fully
    stratified) and 72 = 2^3 3^2 (dimensions 0-1 stratified into 8 x 9
    boxes), to see which counts stratify best; efficiency accounts for the
    different sample counts.
    """
    configs = [(s, None, None) for s in NATIVE]
    configs += [("halton", r, None) for r in common.halton_randomizations() if r != "none"]
    configs += [("halton", "owen", n) for n in EXTRA_HALTON_SPP]
    integrator = common.vr_path_integrator("bsdf", max_depth)
    scenes = {sampler_label(s, r, n): scene_for(scene, width, height, n or spp, s, max_depth, r)
              for s, r, n in configs}
    images: dict[str, list[np.ndarray]] = {n: [] for n in scenes}

    def run(name):
        def fn(rep):
            img = common.render(scenes[name], integrator, seed=rep + 1 if rep >= 0 else 999)
            if rep >= 0:
                images[name].append(np.array(img, dtype=np.float64)[..., :3])
        return fn
    times = common.interleaved({n: run(n) for n in scenes}, "independent", seeds)
    out = {}
    for n, s in scenes.items():
        stack = np.stack(images[n])
        mse = float(np.mean(np.var(stack, axis=0, ddof=1)))
        t = 1.0 if n == "independent" else times[n]["cpu"]
        out[n] = {"mse": mse, "time": t, "spp": s.sensors()[0].sampler().sample_count()}
    base = out["independent"]
    for n, r in out.items():
        r["efficiency"] = base["mse"] * base["time"] / (r["mse"] * r["time"])
        r["mse_ratio"] = r["mse"] / base["mse"]
    return out


def measure(quick: bool = False) -> dict:
    common.set_variant()
    res = {"machine": common.machine_info(), "quick": quick}
    t0 = time.perf_counter()
    res["cost"] = measure_cost(reps=3 if quick else 7, width=128 if quick else 256)
    seeds = 3 if quick else 5
    cases = {}
    for scene, (w, h) in (("cbox.xml", (128, 64) if quick else (256, 128)),
                          ("cornell_box", (64, 64) if quick else (128, 128))):
        for depth in (2, 8):
            cases[f"{scene} depth {depth}"] = measure_efficiency(scene, depth, seeds, w, h)
    res["efficiency"] = cases
    res["seconds"] = time.perf_counter() - t0
    res["load_average_end"] = [round(x, 2) for x in os.getloadavg()]
    return res


# ------------------------------------------------------------------ tables

def _holds(ok: bool) -> str:
    return "yes" if ok else "no"


def build_rows(res: dict) -> list[list[str]]:
    rows = []
    res_label = "128x128" if res["quick"] else "256x256"
    for integrator, ratios in res["cost"].items():
        label = "path" if integrator == "path" else "vr_path bsdf NEE"
        for n, r in ratios.items():
            rows.append([f"H1. {n.replace(':', ' ')} / independent, per-sample time "
                         f"({label}, mi.cornell_box() {res_label}, 32 spp)",
                         f"{r['cpu']:.3f} (wall {r['wall']:.3f})", f"<= {COST_TARGET:.2f}",
                         _holds(r["cpu"] <= COST_TARGET)])
    for case, samplers in res["efficiency"].items():
        native = {n: r for n, r in samplers.items() if n in NATIVE}
        halton = {n: r for n, r in samplers.items() if n.startswith("halton")}
        best_n = max(native, key=lambda n: native[n]["efficiency"])
        best_h = max(halton, key=lambda n: halton[n]["efficiency"])
        at64 = max((n for n in halton if "@" not in n), key=lambda n: halton[n]["efficiency"])
        ratio = halton[best_h]["efficiency"] / native[best_n]["efficiency"]
        ratio64 = halton[at64]["efficiency"] / native[best_n]["efficiency"]
        short = "" if ratio >= EFFICIENCY_TARGET else f", {1 - ratio:.0%} short"
        rows.append([f"H2. efficiency {best_h.replace(':', ' ')} / {best_n} (best native), "
                     f"vr_path bsdf NEE, {case}, 64 spp requested",
                     f"{ratio:.2f}{short} ({at64.replace(':', ' ')} at 64 spp: {ratio64:.2f})",
                     f">= {EFFICIENCY_TARGET:.1f}", _holds(ratio >= EFFICIENCY_TARGET)])
    return rows


def sampler_table(res: dict) -> list[list[str]]:
    """Efficiency over independent (MSE ratio, time ratio) of every sampler, per case."""
    cases = list(res["efficiency"])
    names = list(next(iter(res["efficiency"].values())))
    table = [["sampler"] + cases]
    for n in names:
        cells = []
        for c in cases:
            r = res["efficiency"][c][n]
            cells.append(f"{r['efficiency']:.2f} (MSE {r['mse_ratio']:.3f}, time {r['time']:.2f})")
        spp = res["efficiency"][cases[0]][n]["spp"]
        table.append([f"{n} ({spp} spp)"] + cells)
    return table


def rows(quick: bool = False) -> list[list[str]]:
    """The target rows (``benchmarks.run``'s format), measured now."""
    return build_rows(measure(quick))


def markdown(table: list[list[str]]) -> str:
    lines = ["| " + " | ".join(table[0]) + " |", "|" + "---|" * len(table[0])]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in table[1:]])


def main(argv=None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.halton", description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="smaller images, fewer rounds")
    p.add_argument("--floor", action="store_true",
                   help="only the cost probes (why the randomized variants cost more)")
    args = p.parse_args(argv)
    if args.floor:
        common.set_variant()
        t0 = time.perf_counter()
        floor = measure_cost_floor(reps=3 if args.quick else 7, width=128 if args.quick else 256)
        table = [["sampler / probe", "path", "vr_path bsdf NEE"]]
        for n in next(iter(floor.values())):
            table.append([n] + [f"{floor[i][n]['cpu']:.3f}" for i in floor])
        print("CPU time per sample over independent (mi.cornell_box(), 32 spp, max_depth 8):")
        print()
        print(markdown(table))
        print()
        print(f"load average {[round(x, 2) for x in os.getloadavg()]}; "
              f"{time.perf_counter() - t0:.0f} s.")
        sys.stdout.flush()
        os._exit(0)
    res = measure(args.quick)
    m = res["machine"]
    print(markdown([["measure", "value", "target", "holds?"]] + build_rows(res)))
    print()
    print("Efficiency 1/(MSE x time) over independent (MSE and time ratios in brackets):")
    print()
    print(markdown(sampler_table(res)))
    print()
    print(f"{m['cpu']}, Mitsuba {m['mitsuba']}, Dr.Jit {m['drjit']}, libLLVM {m['libllvm']}; "
          f"load average {m['load_average']} at start, {res['load_average_end']} at the end; "
          f"{res['seconds']:.0f} s.")
    sys.stdout.flush()
    os._exit(0)       # skip LLVM/interpreter teardown


if __name__ == "__main__":
    main()
