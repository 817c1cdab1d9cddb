"""Cluster rows of ``make bench``: what Dask costs and what a second worker gains.

6a. Overhead: wall time of the default convergence study
    (``python -m experiments.convergence``, a fresh ``--out`` each run, so
    every job renders) with ``--workers 1`` over the same study on the local
    loop. Runs alternate local, dask, dask, local (drift cancels); the row
    gives the median of the per-pair ratios. Target <= 1.10.
6b. Speed-up: the default reference (Mitsuba's ``path``, 1024 spp, 256x128)
    split into jobs of at most ``MAX_LANES`` samples, rendered by the local
    loop and by a ``LocalCluster`` of 1 and 2 workers, each warm (every
    process has loaded and compiled the scene first); wall time of the whole
    set of jobs, rounds local, 1, 2, 2, 1, local, medians of per-round ratios. This machine's cores are shared by the
    workers (Dr.Jit threads per worker = cores // workers), so the gain here
    is bounded by the cores, not by Dask.

    python -m benchmarks.cluster [--repeats N] [--quick] [--parts overhead,speedup]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

import integrators  # noqa: F401  (chooses libLLVM; must come before mitsuba/drjit)
import mitsuba as mi  # noqa: E402

from experiments.lib import cluster, execute  # noqa: E402
from experiments.lib import scenes  # noqa: E402
from experiments.lib.methods import parse_method  # noqa: E402
from experiments.lib.references import RefSpec, ReferenceStore  # noqa: E402
from experiments.lib import plan  # noqa: E402
from experiments.lib.jobs import cpu_model  # noqa: E402

from .common import ROOT, SCENE  # noqa: E402

VARIANT = "llvm_ad_rgb"
OVERHEAD_TARGET = 1.10


def _study_seconds(extra: list[str], argv: list[str]) -> float:
    """Wall time of one convergence study in a fresh process and a fresh output folder."""
    with tempfile.TemporaryDirectory(prefix="bench-cluster-") as out:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "experiments.convergence", "--out", out,
                        *argv, *extra], cwd=ROOT, check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        return time.perf_counter() - start


def overhead(repeats: int, argv: list[str]) -> dict:
    """Dask with 1 worker over the local loop, on the convergence study."""
    local, dask = [], []
    for _ in range(repeats):                      # local, dask, dask, local
        local.append(_study_seconds([], argv))
        dask.append(_study_seconds(["--workers", "1"], argv))
        dask.append(_study_seconds(["--workers", "1"], argv))
        local.append(_study_seconds([], argv))
    ratios = [d / l for d, l in zip(dask, local)]
    return {"ratio": statistics.median(ratios), "local_s": statistics.median(local),
            "dask_s": statistics.median(dask), "runs": len(ratios)}


def _reference_jobs(spp: int, width: int, height: int) -> tuple[list, list]:
    """The reference jobs, and 1-spp warm-up jobs of the same scene (one per worker)."""
    info = scenes.read_scene(SCENE)
    depth = scenes.effective_depth(info)
    jobs = ReferenceStore("").plan(RefSpec(info, width, height, depth, parse_method("path"),
                                           VARIANT), spp)
    warm = [plan.make_job(f"warm-up/{i}", info, parse_method("path"), width, height, 1, 7 + i,
                          depth, VARIANT, timing_group=f"warm-up/{i}") for i in range(2)]
    return jobs, warm


def _timed(executor, jobs) -> float:
    start = time.perf_counter()
    n = sum(1 for _ in executor.map_unordered(jobs))
    assert n == len(jobs)
    return time.perf_counter() - start


def speedup(repeats: int, spp: int, width: int, height: int) -> dict:
    """Local loop, Dask 1 worker, Dask 2 workers on the reference jobs (warm).

    Each round runs local, dask1, dask2, dask2, dask1, local (drift cancels);
    the ratios are medians of the per-round ratios."""
    jobs, warm = _reference_jobs(spp, width, height)
    mi.set_variant(VARIANT)
    local = execute.LocalExecutor(VARIANT)
    _timed(local, warm[:1])
    start = time.perf_counter()
    with cluster.DaskExecutor.local(1, VARIANT) as d1, cluster.DaskExecutor.local(2, VARIANT) as d2:
        startup = (time.perf_counter() - start) / 2
        _timed(d1, warm[:1])
        _timed(d2, warm)                          # one warm-up job pinned to each worker
        rounds = []
        for _ in range(repeats):
            t = {}
            for name, ex in (("local", local), ("dask1", d1), ("dask2", d2),
                             ("dask2", d2), ("dask1", d1), ("local", local)):
                t[name] = t.get(name, 0.0) + _timed(ex, jobs) / 2
            rounds.append(t)
    med = {k: statistics.median(r[k] for r in rounds) for k in rounds[0]}
    return {**med, "jobs": len(jobs), "startup_s": startup, "rounds": len(rounds),
            "speedup2": statistics.median(r["local"] / r["dask2"] for r in rounds),
            "ratio1": statistics.median(r["dask1"] / r["local"] for r in rounds)}


def rows(repeats: int = 1, quick: bool = False, parts=("overhead", "speedup")) -> list[list[str]]:
    """The benchmark rows: [measure, value, target, holds?]."""
    out = []
    if "overhead" in parts:
        argv = ["--resolution", "64x32", "--spp", "16", "--reference-spp", "64"] if quick else []
        o = overhead(repeats, argv)
        study = "convergence study" + (" (quick sizes)" if quick else ", default")
        out.append([f"6a. Dask 1 worker / local loop, wall time of the {study}",
                    f"{o['ratio']:.3f} ({o['dask_s']:.1f} s / {o['local_s']:.1f} s, "
                    f"{o['runs']} pairs)", f"<= {OVERHEAD_TARGET:.2f}",
                    "yes" if o["ratio"] <= OVERHEAD_TARGET else "no"])
    if "speedup" in parts:
        spp, (w, h) = (256, (64, 32)) if quick else (1024, (256, 128))
        s = speedup(max(2, repeats), spp, w, h)
        out += [
            [f"6b. reference {spp} spp {w}x{h} as {s['jobs']} jobs: local loop / Dask 2 "
             f"workers (speed-up, {os.cpu_count()} cores)",
             f"{s['speedup2']:.2f}x ({s['local']:.2f} s / {s['dask2']:.2f} s, "
             f"{s['rounds']} rounds)", "(info)", ""],
            ["6b. same, Dask 1 worker / local loop",
             f"{s['ratio1']:.3f} ({s['dask1']:.2f} s / {s['local']:.2f} s); cluster start "
             f"{s['startup_s']:.1f} s", "(info)", ""]]
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.cluster", description=__doc__)
    p.add_argument("--repeats", type=int, default=1,
                   help="alternating local/dask pairs per overhead measurement")
    p.add_argument("--quick", action="store_true", help="tiny sizes (checks the script runs)")
    p.add_argument("--parts", default="overhead,speedup",
                   help="comma-separated: overhead (6a), speedup (6b)")
    args = p.parse_args(argv)
    table = rows(args.repeats, args.quick, args.parts.split(","))
    print("| measure | value | target | holds? |\n|---|---|---|---|")
    for row in table:
        print("| " + " | ".join(row) + " |")
    print(f"\nMeasured on {cpu_model()} ({os.cpu_count()} logical cores), {VARIANT}.")


if __name__ == "__main__":
    main()
