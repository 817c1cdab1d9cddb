"""zsobol benchmark (issue 25): cost per sample over ``independent``.

``python -m benchmarks.zsobol [--quick] [--rounds N]`` prints a table of CPU
time per sample of the ``zsobol`` sampler (each randomization) over
``independent``, measured in this process: ``vr_path`` (bsdf, NEE) and
Mitsuba's ``path``, max_depth 8, 32 spp, on the bundled scene
(``scenes/cbox.xml``, 256x128) and on ``mi.cornell_box()`` (256x256). Target
<= :data:`COST_TARGET`. Ratios, not a test: timings on a loaded machine move.

Method (as :mod:`benchmarks.halton`): one warm-up render per configuration
(compilation), then rounds that render every configuration once in
alternating order, each timed in process CPU time (and wall-clock time); a
ratio is the median over rounds of a configuration's time over
``independent``'s in the same round. Every configuration renders at the
count it is timed at, so no timed render compiles a kernel (checked: the
table says how many timed renders launched an uncached kernel).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

from . import common
from .common import mi

#: Cost per sample over independent that the sampler must stay under.
COST_TARGET = 1.10
RANDOMIZATIONS = ("none", "permute_digits", "owen")
MAX_DEPTH = 8
SPP = 32


def _sampler(name: str, spp: int, width: int, randomization: str | None) -> dict:
    d = {"type": name, "sample_count": spp}
    if name == "zsobol":
        d.update(film_width=width, randomization=randomization)
    return d


def scene(which: str, width: int, height: int, sampler: str,
          randomization: str | None = None, spp: int = SPP):
    """``cbox.xml`` or ``mi.cornell_box()`` with the given sampler."""
    if which == "cornell_box":
        d = mi.cornell_box()
        d["sensor"]["film"]["width"], d["sensor"]["film"]["height"] = width, height
        d["sensor"]["sampler"] = _sampler(sampler, spp, width, randomization)
        return mi.load_dict(d)
    s = mi.load_file(common.SCENE, width=width, height=height, spp=spp, max_depth=MAX_DEPTH,
                     sampler=sampler)
    if sampler == "zsobol":
        smp = s.sensors()[0].sampler()
        smp.film_width, smp.randomization = width, randomization
    return s


def integrators() -> dict:
    return {"vr_path bsdf+nee": mi.load_dict({"type": "vr_path", "strategy": "bsdf",
                                              "emitter_sampling": True,
                                              "max_depth": MAX_DEPTH}),
            "path": mi.load_dict({"type": "path", "max_depth": MAX_DEPTH})}


CASES = {"cbox.xml 256x128": ("cbox.xml", 256, 128),
         "mi.cornell_box() 256x256": ("cornell_box", 256, 256)}


def measure(rounds: int = 7, quick: bool = False) -> dict:
    """{case: {integrator: {config: interleaved ratios}}} and the uncached timed kernels."""
    out, uncached = {}, 0
    for case, (which, w, h) in CASES.items():
        if quick:
            w, h = w // 2, h // 2
        configs = {"independent": scene(which, w, h, "independent")}
        configs |= {f"zsobol:{r}": scene(which, w, h, "zsobol", r) for r in RANDOMIZATIONS}
        out[case] = {}
        for name, integrator in integrators().items():
            def run(n, integrator=integrator):
                def fn(rep):
                    nonlocal uncached
                    if rep < 0:
                        common.render(configs[n], integrator, seed=999)
                        return
                    ks = common.jit_kernels(
                        lambda: common.render(configs[n], integrator, seed=rep + 1))
                    uncached += sum(not k["cache_hit"] for k in ks)
                return fn
            out[case][name] = common.interleaved({n: run(n) for n in configs}, "independent",
                                                 rounds)
    return {"ratios": out, "uncached_timed_kernels": uncached}


def table(res: dict) -> list[list[str]]:
    rows = [["case", "integrator"] + [f"zsobol:{r}" for r in RANDOMIZATIONS]]
    for case, by_integrator in res["ratios"].items():
        for integrator, ratios in by_integrator.items():
            rows.append([case, integrator] + [
                f"{ratios[f'zsobol:{r}']['cpu']:.3f} (wall {ratios[f'zsobol:{r}']['wall']:.3f})"
                for r in RANDOMIZATIONS])
    return rows


def markdown(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows[1:]])


def main(argv=None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.zsobol",
                                description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="half the resolution, 3 rounds")
    p.add_argument("--rounds", type=int, default=None, help="timed rounds (default 7)")
    args = p.parse_args(argv)
    common.set_variant()
    t0 = time.perf_counter()
    load0 = [round(x, 2) for x in os.getloadavg()]
    res = measure(args.rounds or (3 if args.quick else 7), args.quick)
    print(f"CPU time per sample over independent, {SPP} spp, max_depth {MAX_DEPTH} "
          f"(target <= {COST_TARGET:.2f}):")
    print()
    print(markdown(table(res)))
    print()
    m = common.machine_info()
    print(f"{m['cpu']}, Mitsuba {m['mitsuba']}, Dr.Jit {m['drjit']}, libLLVM {m['libllvm']}; "
          f"load average {load0} at start, {m['load_average']} at the end; timed renders "
          f"that compiled a kernel: {res['uncached_timed_kernels']}; "
          f"{time.perf_counter() - t0:.0f} s.")
    sys.stdout.flush()
    os._exit(0)       # skip LLVM/interpreter teardown


if __name__ == "__main__":
    main()
