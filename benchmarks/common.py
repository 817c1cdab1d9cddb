"""Set-up, scenes, configurations and timed renders shared by the benchmarks."""
from __future__ import annotations

import os
import platform
import statistics
import time
from typing import Callable

import integrators  # noqa: F401  (chooses libLLVM; must come before mitsuba/drjit)
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

import scenes  # noqa: E402
from experiments.lib import methods  # noqa: E402  (strategies, the method grammar)
from experiments.lib import samplers  # noqa: E402  (the sampler table)
from experiments.lib import scenes as scene_loading  # noqa: E402  (`scenes`: the bundled ones)
from experiments.lib.jobs import cpu_model, cpu_simd  # noqa: E402  (one definition, shared)

#: The checkout (the benchmarks run from it: docs/benchmarks.md, results/); the one definition for
#: the benchmarks.
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The bundled default scene (package data of :mod:`scenes`).
SCENE = scenes.path("cbox.xml")
VARIANT = "llvm_ad_rgb"
RANDOMIZATIONS = samplers.get("halton").randomizations
STRATEGIES = methods.strategies()


def set_variant(variant: str = VARIANT) -> None:
    mi.set_variant(variant)


# ------------------------------------------------------------------ scenes

def load_scene(width: int, height: int, spp: int, sampler: str = "independent",
               randomization: str | None = None, max_depth: int = 8):
    """The default scene (``scenes/cbox.xml``) with ``vr_path`` bsdf + NEE and the given
    sampler, loaded through the experiments' scene route
    (:func:`experiments.lib.scenes.load_scene`)."""
    name = "bsdf+nee" + ("" if sampler == "independent" else f"+{sampler}") \
        + (f":{randomization}" if randomization is not None else "")
    return scene_loading.load_scene(SCENE, width, height, methods.parse_method(name),
                                    methods.Depth(max_depth), spp)


def plugin_available(plugin: str) -> bool:
    try:
        mi.load_dict({"type": plugin})
        return True
    except Exception:  # noqa: BLE001
        return False


def halton_randomizations() -> tuple[str, ...]:
    """The ``halton`` sampler's randomizations, all of them (one definition:
    the sampler table, :mod:`experiments.lib.samplers`)."""
    return tuple(RANDOMIZATIONS)


def path_integrator(max_depth: int):
    """Mitsuba's built-in ``path`` (NEE + MIS, as always)."""
    return mi.load_dict({"type": "path", "max_depth": max_depth})


def vr_path_integrator(strategy: str, max_depth: int, count_segments: bool = False,
                       emitter_sampling: bool = True):
    """``vr_path``, by default with emitter sampling (NEE + MIS), comparable with ``path``."""
    method = methods.Method(strategy, strategy, emitter_sampling)
    integrator = mi.load_dict(method.integrator_dict(methods.Depth(max_depth)))
    integrator.count_segments = count_segments
    return integrator


# ---------------------------------------------------------------- timing

def render(scene, integrator=None, seed: int = 0, spp: int | None = None):
    """One render, evaluated and synchronised."""
    img = mi.render(scene, integrator=integrator, seed=seed, spp=spp or 0)
    dr.eval(img)
    dr.sync_thread()
    return img


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall-clock seconds, CPU seconds of this process) of ``fn()``."""
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def interleaved(runs: dict[str, Callable[[int], object]], baseline: str, reps: int,
                warmup: bool = True) -> dict[str, dict]:
    """Per-pair time ratios of each run against ``baseline``.

    ``runs[name](rep)`` does one timed unit of work. After one warm-up call
    each (compilation), every round runs all of them once, alternating the
    order (forward, backward) so that drifting load does not favour either
    side; each ratio divides by the baseline of the same round. Returns
    ``{name: {wall, cpu, wall_all, cpu_all, base_wall, base_cpu}}``, medians
    over rounds (CPU = process CPU time, which other processes on the machine
    perturb far less than wall-clock time).
    """
    if warmup:
        for name, fn in runs.items():
            fn(-1)
    names = list(runs)
    ratios = {n: ([], []) for n in names if n != baseline}
    base_times = ([], [])
    for rep in range(reps):
        order = names if rep % 2 == 0 else names[::-1]
        times = {n: timed(lambda n=n: runs[n](rep)) for n in order}
        bw, bc = times[baseline]
        base_times[0].append(bw)
        base_times[1].append(bc)
        for n in ratios:
            ratios[n][0].append(times[n][0] / bw)
            ratios[n][1].append(times[n][1] / bc)
    out = {}
    for n, (w, c) in ratios.items():
        out[n] = {"wall": statistics.median(w), "cpu": statistics.median(c),
                  "wall_all": w, "cpu_all": c,
                  "base_wall": statistics.median(base_times[0]),
                  "base_cpu": statistics.median(base_times[1])}
    return out


# ----------------------------------------------------------- kernel history

def jit_kernels(fn: Callable[[], object]) -> list[dict]:
    """The JIT kernels ``fn()`` launched, from Dr.Jit's kernel history."""
    dr.kernel_history()                                  # clear
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        fn()
        history = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    out = []
    for k in history:
        if k.get("type") != dr.KernelType.JIT:
            continue
        out.append({"size": int(k.get("size", 0)),
                    "ops": int(k.get("operation_count", 0)),
                    "cache_hit": bool(k.get("cache_hit", False)),
                    "cache_disk": bool(k.get("cache_disk", False)),
                    "codegen_ms": float(k.get("codegen_time", 0.0)),
                    "backend_ms": float(k.get("backend_time", 0.0)),
                    "exec_ms": float(k.get("execution_time", 0.0)),
                    "hash": str(k.get("hash", ""))})
    return out


# ------------------------------------------------------------- machine

def machine_info() -> dict:
    try:
        llvm = ".".join(map(str, dr.detail.llvm_version()))
    except Exception:  # noqa: BLE001
        llvm = "unknown"
    try:
        mem_gb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError):
        mem_gb = float("nan")
    return {"cpu": cpu_model(), "simd": cpu_simd(), "cores": os.cpu_count(),
            "memory_gb": round(mem_gb, 1),
            "os": platform.platform(), "python": platform.python_version(),
            "mitsuba": mi.__version__, "drjit": dr.__version__, "variant": mi.variant(),
            "libllvm": llvm, "libllvm_path": os.environ.get("DRJIT_LIBLLVM_PATH", ""),
            "load_average": [round(x, 2) for x in os.getloadavg()]}
