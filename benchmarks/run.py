"""``make bench``: our plugins against Mitsuba's built-ins and the ray-casting limit.

Prints one table and writes it, with the machine and versions, to
``<out>/bench.md`` and ``<out>/bench.json`` (and, with ``--update-docs``, as
``make bench`` runs it, into the generated ``bench`` block of ``docs/benchmarks.md``
through :func:`tools.docs.write_benchmarks`). Every speed figure is a ratio
measured in this process after a warm-up render (compilation excluded): the
configurations are interleaved (A, B, A, B, ... in alternating order) and each
figure is the median of the per-round ratios. Ratios are of process CPU time,
which other processes on a shared machine perturb far less than wall-clock
time; the wall-clock ratio is given next to it. On the default scene
(``scenes/cbox.xml``, NEE on):

1. ``vr_path`` (``emitter_sampling=true``, each strategy) / built-in ``path``,
   same ``max_depth`` and spp: per-sample time. Target <= 1.00.
2. ``halton`` (each randomization) / ``independent``, both with ``vr_path``
   (bsdf, NEE) and the same spp. Target <= 1.05.
3. Path segments traced per second by ``vr_path`` (bsdf, NEE; counted by a
   counting render, ``count_segments``) / rays per second of
   ``scene.ray_intersect`` on as many random rays (origins uniform in the box,
   directions uniform) in the same scene. Target >= 0.70.
4. Peak RSS of the experiment suite's pass renderer at 1024x512 and N spp and
   at N/10 spp, in a subprocess each (N = 1000 with ``--rss-full``; the
   default N keeps ``make bench`` short). Target <= 1.5 GB, flat in spp.
5. JIT compile time of each configuration (first render minus warm render) in
   a fresh process with an empty kernel cache, and the same in a second
   process that finds the kernels in Dr.Jit's cache (``~/.drjit``).
2b. (:mod:`benchmarks.halton`) halton's cost per sample over ``independent``
   on ``mi.cornell_box()`` 256x256, 32 spp, under ``path`` and ``vr_path``
   (target <= 1.05), and its efficiency 1/(MSE x time) over the best of
   Mitsuba's samplers at max_depth 2 and 8 on both scenes (target >= 1.0), with
   the table of every sampler's efficiency over ``independent``.
6. (:mod:`benchmarks.cluster`) Dask with one worker over the local loop on the
   default convergence study (target <= 1.10 wall time), and the speed-up of
   two workers on a reference split into jobs.
7. (:mod:`benchmarks.guiding`) ``guided+nee`` over ``path`` on the door-lit room
   (``scenes/suite/door_room.xml``, 64x48, 5 repeats): efficiency at path's time (path
   1024 spp, guided's training counted by the executor's one clock) with its interval
   (target >= 3, issue 31), guided's time per sample after training over path's, and the
   training's share of guided's time.
8. (:mod:`benchmarks.adaptive`) ``bsdf+nee+adaptive`` over ``bsdf+nee`` at equal time on
   four suite scenes, beside the ceiling an oracle's allocation of the same samples
   reaches at equal time and at equal samples (issue 43's targets).

Usage: ``python -m benchmarks.run [--reps 11] [--spp 8] [--rss-full] ...``
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from experiments.lib import files

from . import cluster
from . import common
from . import adaptive, guiding
from . import halton
from .common import dr, mi

RSS_LIMIT_MB = 1.5e9 / 2**20          # 1.5 GB in MiB
RSS_FLAT = 1.10                       # "flat": peak at 10x the spp within 10 %


# ------------------------------------------------------------ 1: vs path

def bench_vs_path(args) -> dict:
    scene = common.load_scene(args.width, args.height, args.spp, max_depth=args.max_depth)
    configs = {"path": common.path_integrator(args.max_depth)}
    for s in common.STRATEGIES:
        configs[f"vr_path:{s}"] = common.vr_path_integrator(s, args.max_depth)
    runs = {n: (lambda rep, i=i: common.render(scene, i, seed=rep + 1)) for n, i in configs.items()}
    ratios = common.interleaved(runs, "path", args.reps)
    kernels = {n: common.jit_kernels(lambda i=i: common.render(scene, i, seed=12345))
               for n, i in configs.items()}
    samples = args.width * args.height * args.spp
    base = next(iter(ratios.values()))
    return {"ratios": ratios, "kernels": kernels, "samples_per_render": samples,
            "path_us_per_sample_cpu": base["base_cpu"] / samples * 1e6,
            "path_us_per_sample_wall": base["base_wall"] / samples * 1e6}


# ---------------------------------------------------------- 2: halton

def bench_halton(args) -> dict:
    randomizations = common.halton_randomizations()
    integrator = common.vr_path_integrator("bsdf", args.max_depth)
    scenes = {"independent": common.load_scene(args.width, args.height, args.spp,
                                          max_depth=args.max_depth)}
    for r in randomizations:
        scenes[f"halton:{r}"] = common.load_scene(args.width, args.height, args.spp, "halton", r,
                                                  args.max_depth)
    runs = {n: (lambda rep, s=s: common.render(s, integrator, seed=rep + 1))
            for n, s in scenes.items()}
    ratios = common.interleaved(runs, "independent", args.reps)
    # Passes must not recompile: a new seed and (Halton) a new sample offset.
    recompiles = {}
    for n, s in scenes.items():
        sampler = s.sensors()[0].sampler()

        def two_passes(s=s, sampler=sampler):
            for k in (1, 2):
                if hasattr(sampler, "sample_offset"):
                    sampler.sample_offset = k * args.spp
                common.render(s, integrator, seed=1000 + k)
        recompiles[n] = sum(not k["cache_hit"] for k in common.jit_kernels(two_passes))
        if hasattr(sampler, "sample_offset"):
            sampler.sample_offset = 0
    return {"ratios": ratios, "recompiles_per_2_passes": recompiles}


# ------------------------------------------------ 3: segments vs ray casting

def random_rays(n: int, seed: int = 7) -> mi.Ray3f:
    """``n`` rays, origins uniform in the box [-2,2]x[0,2]x[-2,2], directions uniform."""
    rng = np.random.default_rng(seed)
    o = rng.uniform([-1.999, 0.001, -1.999], [1.999, 1.999, 1.999], size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ray = mi.Ray3f(mi.Point3f(*(mi.Float(o[:, i].astype(np.float32)) for i in range(3))),
                   mi.Vector3f(*(mi.Float(d[:, i].astype(np.float32)) for i in range(3))))
    dr.eval(ray)
    return ray


def count_segments(scene, integrator, spp: int) -> tuple[int, int]:
    """(path segments, shadow rays) of one render, from ``vr_path``'s counting AOVs."""
    integrator.count_segments = True
    try:
        img = np.array(common.render(scene, integrator, seed=1), dtype=np.float64)
    finally:
        integrator.count_segments = False
    # Box filter: each sample lands in one pixel with weight 1, so a pixel's
    # AOV is the mean count of its samples; channels R, G, B, segments, shadow_rays.
    return int(round(img[..., -2].sum() * spp)), int(round(img[..., -1].sum() * spp))


def bench_segments(args) -> dict:
    """Segments per second of vr_path (bsdf) with and without NEE, over ray_intersect's rays/s."""
    scene = common.load_scene(args.width, args.height, args.spp, max_depth=args.max_depth)
    samples = args.width * args.height * args.spp
    integrators = {"nee": common.vr_path_integrator("bsdf", args.max_depth),
                   "no_nee": common.vr_path_integrator("bsdf", args.max_depth,
                                                       emitter_sampling=False)}
    counts = {n: count_segments(scene, i, args.spp) for n, i in integrators.items()}
    n_rays = counts["nee"][0]
    rays = random_rays(n_rays)

    def cast(rep):
        si = scene.ray_intersect(rays)      # what the path loop calls, on random rays
        dr.eval(si.t, si.n)
        dr.sync_thread()
    runs = {"ray_intersect": cast}
    runs.update({n: (lambda rep, i=i: common.render(scene, i, seed=rep + 1))
                 for n, i in integrators.items()})
    ratios = common.interleaved(runs, "ray_intersect", args.reps)
    out = {"samples": samples, "rays": n_rays,
           "rays_per_s_cpu": n_rays / ratios["nee"]["base_cpu"],
           "rays_per_s_wall": n_rays / ratios["nee"]["base_wall"]}
    for n, (segments, shadow) in counts.items():
        r = ratios[n]
        scale = segments / n_rays       # ratio of throughputs = (seg / t) / (rays / t_rays)
        out[n] = {"segments": segments, "shadow_rays": shadow,
                  "segments_per_sample": segments / samples,
                  "shadow_rays_per_sample": shadow / samples,
                  "ratio_cpu": scale / r["cpu"], "ratio_wall": scale / r["wall"],
                  "ratio_with_shadow_cpu": (segments + shadow) / n_rays / r["cpu"],
                  "segments_per_s_wall": segments / (r["base_wall"] * r["wall"])}
    return out


# ----------------------------------------------------- subprocess probes

def run_probe(argv: list[str], env: dict | None = None, timeout: float = 3600) -> dict:
    cmd = [sys.executable, "-m", "benchmarks.probes", *argv]
    proc = subprocess.run(cmd, cwd=common.ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        raise RuntimeError(f"probe {' '.join(argv)} failed: {' | '.join(tail)}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def bench_rss(args) -> dict:
    hi = 1000 if args.rss_full else args.rss_spp
    lo = max(1, hi // 10)
    out = {}
    for spp in (lo, hi):
        res = run_probe(["rss", "--width", str(args.rss_width), "--height",
                         str(args.rss_height), "--spp", str(spp)])
        res["maxrss_children_mb"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        out[str(spp)] = res
        print(f"  rss probe {args.rss_width}x{args.rss_height} {spp} spp: "
              f"{res['maxrss_mb']:.0f} MiB, {res['seconds']:.1f} s", flush=True)
    return {"lo_spp": lo, "hi_spp": hi, "runs": out, "full": hi == 1000}


def bench_compile(args, configs: list[str]) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-cache-") as home:
        env = dict(os.environ, HOME=home)       # Dr.Jit's kernel cache: $HOME/.drjit
        argv = ["compile", "--configs", ",".join(configs), "--width", str(args.width),
                "--height", str(args.height), "--spp", "1", "--max-depth", str(args.max_depth)]
        t0 = time.perf_counter()
        cold = run_probe(argv, env)
        t1 = time.perf_counter()
        cached = run_probe(argv, env)
        t2 = time.perf_counter()
    return {"cold": cold, "cached": cached, "cold_process_s": t1 - t0,
            "cached_process_s": t2 - t1}


# --------------------------------------------------------------- table

def fmt_ratio(cpu: float, wall: float) -> str:
    return f"{cpu:.3f} (wall {wall:.3f})"


def build_rows(res: dict, args) -> list[list[str]]:
    rows = []
    vp = res.get("vs_path")
    if vp:
        for s in common.STRATEGIES:
            r = vp["ratios"][f"vr_path:{s}"]
            rows.append([f"1. vr_path {s} (NEE) / path, per-sample time", fmt_ratio(r["cpu"], r["wall"]),
                         "<= 1.00", "yes" if r["cpu"] <= 1.0 else "no"])
    h = res.get("halton")
    if h is not None:
        for n, r in h["ratios"].items():
            rows.append([f"2. {n.replace(':', ' ')} / independent (vr_path bsdf, NEE)",
                         fmt_ratio(r["cpu"], r["wall"]), "<= 1.05",
                         "yes" if r["cpu"] <= 1.05 else "no"])
    sg = res.get("segments")
    if sg:
        for n, label in (("nee", "NEE"), ("no_nee", "no NEE, as the experiments")):
            r = sg[n]
            rows.append([f"3. path segments/s (vr_path bsdf, {label}) / ray_intersect rays/s",
                         fmt_ratio(r["ratio_cpu"], r["ratio_wall"]), ">= 0.70",
                         "yes" if r["ratio_cpu"] >= 0.70 else "no"])
        rows.append(["3. same with NEE, shadow rays counted as rays traced",
                     f"{sg['nee']['ratio_with_shadow_cpu']:.3f}", "(info)", ""])
    rss = res.get("rss")
    if rss:
        runs = rss["runs"]
        lo, hi = runs[str(rss["lo_spp"])], runs[str(rss["hi_spp"])]
        size = f"{args.rss_width}x{args.rss_height}"
        for spp, r in ((rss["hi_spp"], hi), (rss["lo_spp"], lo)):
            rows.append([f"4. peak RSS, experiment pass renderer, {size}, {spp} spp "
                         f"({r['passes']} passes)", f"{r['maxrss_mb']:.0f} MiB",
                         "<= 1.5 GB (1431 MiB)", "yes" if r["maxrss_mb"] <= RSS_LIMIT_MB else "no"])
        flat = hi["maxrss_mb"] / lo["maxrss_mb"]
        rows.append([f"4. peak RSS {rss['hi_spp']} spp / {rss['lo_spp']} spp", f"{flat:.3f}",
                     f"flat (<= {RSS_FLAT:.2f})", "yes" if flat <= RSS_FLAT else "no"])
    hn = res.get("halton_native")
    if hn:
        rows += [[f"2b. {r[0].split('. ', 1)[-1]}"] + r[1:] for r in halton.build_rows(hn)]
    cl = res.get("cluster")
    if cl:
        rows += cl["rows"]
    gd = res.get("guiding")
    if gd:
        rows += guiding.rows(gd)
    ad = res.get("adaptive")
    if ad:
        rows += adaptive.rows(ad)
    cp = res.get("compile")
    if cp:
        for n, c in cp["cold"].items():
            cached = cp["cached"][n]
            rows.append([f"5. JIT compile {n}: cold cache / 2nd process (cache)",
                         f"{c['compile_s']:.2f} s / {cached['compile_s']:.2f} s",
                         "(info)", f"cache hits {cached['cache_hits']}/{cached['kernels']}"])
    return rows


def markdown(rows: list[list[str]], res: dict) -> str:
    m = res["machine"]
    lines = ["| measure | value | target | holds? |", "|---|---|---|---|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    s = res["settings"]
    notes = [
        "",
        f"Measured {res['date']} on {m['cpu']} ({m.get('simd', 'SIMD unknown')}), "
        f"{m['cores']} logical cores, {m['memory_gb']} GiB "
        f"({m['os']}); Mitsuba {m['mitsuba']}, Dr.Jit {m['drjit']}, libLLVM {m['libllvm']}, "
        f"variant {m['variant']}, Python {m['python']}; load average at start "
        f"{', '.join(map(str, m['load_average']))}.",
        "",
        f"Default scene `scenes/cbox.xml` at {s['width']}x{s['height']}, {s['spp']} spp per timed "
        f"render, max_depth {s['max_depth']}, NEE on; ratios are medians over {s['reps']} "
        f"interleaved rounds of process CPU time (wall-clock ratio in brackets), after a warm-up "
        f"render. Compile times: first render minus warm render at 1 spp, in a process with an "
        f"empty kernel cache, then in a second process with the cache it left.",
    ]
    vp = res.get("vs_path")
    if vp:
        notes.append(f"Built-in path: {vp['path_us_per_sample_cpu']:.2f} us CPU per sample.")
    sg = res.get("segments")
    if sg:
        nee = sg["nee"]
        notes.append(f"vr_path (bsdf, NEE) traces {nee['segments_per_sample']:.2f} path segments "
                     f"and {nee['shadow_rays_per_sample']:.2f} shadow rays per sample (without "
                     f"NEE {sg['no_nee']['segments_per_sample']:.2f} segments); ray_intersect "
                     f"(hit distance and normal evaluated) on {sg['rays']} random rays: "
                     f"{sg['rays_per_s_wall'] / 1e6:.1f} M rays/s wall-clock, "
                     f"{sg['rays_per_s_cpu'] / 1e6:.1f} M per CPU-second.")
    rss = res.get("rss")
    if rss and not rss["full"]:
        notes.append(f"Peak RSS measured at {rss['hi_spp']} and {rss['lo_spp']} spp to keep "
                     f"`make bench` short; `--rss-full` measures 1000 and 100 spp.")
    hn = res.get("halton_native")
    if hn:
        notes += ["", "Efficiency 1/(MSE x time) of every sampler over independent "
                  "(rows 2b; MSE and time ratios in brackets):", "",
                  halton.markdown(halton.sampler_table(hn))]
    h = res.get("halton")
    if h:
        rc = h["recompiles_per_2_passes"]
        # a paragraph of its own: right below the sampler table, a line is a table row
        notes += ["", "Kernels recompiled over two further passes (new seed, new sample offset): "
                  + ", ".join(f"{n} {v}" for n, v in rc.items()) + "."]
    gd = res.get("guiding")
    if gd:
        notes += ["", guiding.note(gd)]
    return "\n".join(lines + notes) + "\n"


#: Every file is written atomically (temporary name, then rename).
write_atomic = files.write_text


def update_docs(md: str) -> str:
    """Put the table into docs/benchmarks.md (its generated ``bench`` block); the path."""
    sys.path.insert(0, common.ROOT)
    from tools import docs
    return docs.write_benchmarks(md, common.ROOT)


# ---------------------------------------------------------------- main

def parse_args(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.run", description=__doc__.split("\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--width", type=int, default=256)
    p.add_argument("--height", type=int, default=128)
    p.add_argument("--spp", type=int, default=8, help="spp of each timed render")
    p.add_argument("--max-depth", type=int, default=8)
    p.add_argument("--reps", type=int, default=11, help="interleaved rounds per comparison")
    p.add_argument("--rss-width", type=int, default=1024)
    p.add_argument("--rss-height", type=int, default=512)
    p.add_argument("--rss-spp", type=int, default=80,
                   help="spp of the larger peak-RSS probe (the other has 1/10 of it)")
    p.add_argument("--rss-full", action="store_true",
                   help="peak RSS at 1000 and 100 spp (about 15 minutes on 2 cores)")
    p.add_argument("--skip", default="", help="comma-separated parts to skip: "
                   "vs_path,halton,halton_native,segments,rss,cluster,guiding,adaptive,"
                   "compile")
    p.add_argument("--quick", action="store_true",
                   help="smaller images and fewer rounds for the halton_native, cluster, "
                        "guiding and adaptive parts (checks that they run; not figures to "
                        "quote)")
    p.add_argument("--out", default=os.path.join(common.ROOT, "results"))
    p.add_argument("--update-docs", action="store_true",
                   help="also put the table into docs/benchmarks.md (make bench does; by "
                        "default the tracked docs are left alone)")
    args = p.parse_args(argv)
    args.skip = {s.strip() for s in args.skip.split(",") if s.strip()}
    return args


def main(argv=None) -> None:
    args = parse_args(argv)
    start = time.perf_counter()
    common.set_variant()
    res = {"date": datetime.datetime.now().isoformat(timespec="seconds"),
           "machine": common.machine_info(),
           "settings": {k: (sorted(v) if isinstance(v, set) else v) for k, v in vars(args).items()}}
    parts = [("vs_path", bench_vs_path), ("halton", bench_halton),
             ("halton_native", lambda a: halton.measure(a.quick)), ("segments", bench_segments),
             ("rss", bench_rss), ("cluster", lambda a: {"rows": cluster.rows(quick=a.quick)}),
             ("guiding", lambda a: guiding.measure(**guiding.quick_settings(a.quick))),
             ("adaptive", lambda a: adaptive.measure(**adaptive.quick_settings(a.quick)))]
    for name, fn in parts:
        if name in args.skip:
            continue
        t0 = time.perf_counter()
        print(f"[bench] {name} ...", flush=True)
        res[name] = fn(args)
        print(f"[bench] {name} done in {time.perf_counter() - t0:.0f} s", flush=True)
    if "compile" not in args.skip:
        configs = ["path"] + [f"vr:{s}" for s in common.STRATEGIES]
        configs += [f"halton:{r}" for r in common.halton_randomizations()]
        t0 = time.perf_counter()
        print("[bench] compile ...", flush=True)
        res["compile"] = bench_compile(args, configs)
        print(f"[bench] compile done in {time.perf_counter() - t0:.0f} s", flush=True)
    res["seconds"] = time.perf_counter() - start

    rows = build_rows(res, args)
    md = markdown(rows, res)
    res["table"] = rows
    out_md, out_json = os.path.join(args.out, "bench.md"), os.path.join(args.out, "bench.json")
    write_atomic(out_md, "# Benchmarks\n\n" + md)
    write_atomic(out_json, json.dumps(res, indent=1, default=str) + "\n")
    page = update_docs(md) if args.update_docs else None
    print()
    print(md)
    print(f"wrote {out_md}, {out_json}" + (f", {page}" if page else "")
          + f" in {res['seconds']:.0f} s")
    sys.stdout.flush()
    os._exit(0)       # skip LLVM/interpreter teardown


if __name__ == "__main__":
    main()
