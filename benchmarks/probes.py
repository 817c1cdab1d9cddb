"""Probes that must run in a process of their own; each prints one JSON line.

``python -m benchmarks.probes compile --configs path,vr:bsdf,halton:owen ...``
    For each configuration: the first render (tracing + JIT compilation, or a
    kernel-cache lookup) and a warm render, both timed, and what Dr.Jit's
    kernel history says about the first one (LLVM backend time, cache hits).
    Run with ``HOME`` pointing at an empty directory for a cold kernel cache
    (Dr.Jit keeps it in ``~/.drjit``), then again with the same ``HOME`` to see
    whether the cache makes a second process fast.

``python -m benchmarks.probes rss --width 1024 --height 512 --spp 1000``
    Renders one job with the experiment suite's job renderer
    (``experiments.lib.execute.run_job``, the ``bsdf`` method, in passes of
    at most ``MAX_LANES`` samples) and reports this process's peak RSS.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time

from . import common
from .common import mi


# ------------------------------------------------------------ compile

def config_scene_and_integrator(name: str, width: int, height: int, spp: int, max_depth: int):
    """``path``, ``vr:<strategy>`` or ``halton:<randomization>`` (vr_path bsdf + halton)."""
    if name == "path":
        return (common.load_scene(width, height, spp, max_depth=max_depth),
                common.path_integrator(max_depth))
    kind, _, arg = name.partition(":")
    if kind == "vr":
        return (common.load_scene(width, height, spp, max_depth=max_depth),
                common.vr_path_integrator(arg, max_depth))
    if kind == "halton":
        return (common.load_scene(width, height, spp, "halton", arg, max_depth),
                common.vr_path_integrator("bsdf", max_depth))
    raise ValueError(f"unknown configuration {name!r}")


def probe_compile(args) -> dict:
    out = {}
    for name in args.configs.split(","):
        scene, integrator = config_scene_and_integrator(name, args.width, args.height,
                                                        args.spp, args.max_depth)
        kernels = []
        first = common.timed(lambda: kernels.extend(
            common.jit_kernels(lambda: common.render(scene, integrator, seed=1))))
        warm = min(common.timed(lambda s=s: common.render(scene, integrator, seed=s))
                   for s in (2, 3))
        out[name] = {"first_s": first[0], "warm_s": warm[0],
                     "compile_s": max(first[0] - warm[0], 0.0),
                     "kernels": len(kernels),
                     "cache_hits": sum(k["cache_hit"] for k in kernels),
                     "backend_ms": sum(k["backend_ms"] for k in kernels),
                     "codegen_ms": sum(k["codegen_ms"] for k in kernels)}
    return out


# ---------------------------------------------------------------- RSS

def probe_rss(args) -> dict:
    from experiments.lib import execute
    from experiments.lib import methods
    from experiments.lib import plan
    from experiments.lib import scenes
    width, height, spp = args.width, args.height, args.spp
    start = time.perf_counter()
    info = scenes.read_scene(common.SCENE)
    job = plan.make_job("bench-rss", info, methods.parse_method(args.method), width, height,
                        spp, 0, info.depth, mi.variant())
    result = execute.run_job(job, mi.variant())
    seconds = time.perf_counter() - start
    return {"width": width, "height": height, "spp": spp, "passes": result.passes,
            "seconds": seconds, "runner": "experiments.lib.execute.run_job",
            "method": args.method,
            "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.probes")
    sub = p.add_subparsers(dest="probe", required=True)
    c = sub.add_parser("compile")
    c.add_argument("--configs", required=True)
    c.add_argument("--width", type=int, default=256)
    c.add_argument("--height", type=int, default=128)
    c.add_argument("--spp", type=int, default=1)
    c.add_argument("--max-depth", type=int, default=8)
    r = sub.add_parser("rss")
    r.add_argument("--width", type=int, default=1024)
    r.add_argument("--height", type=int, default=512)
    r.add_argument("--spp", type=int, default=1000)
    r.add_argument("--method", default="bsdf")
    args = p.parse_args(argv)
    common.set_variant()
    result = probe_compile(args) if args.probe == "compile" else probe_rss(args)
    sys.stdout.write(json.dumps(result) + "\n")
    sys.stdout.flush()
    os._exit(0)       # skip interpreter/LLVM teardown (not part of what is measured)


if __name__ == "__main__":
    main()
