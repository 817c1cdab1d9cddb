"""Timed renders are warm in exactly the configuration they time (experiments/lib/execute.py).

Mitsuba's multijitter (like stratified, orthogonal and ldsampler) bakes the
sample count into its kernel: a warm-up at 1 spp leaves the first render at
64 spp to compile. The compile detector (Dr.Jit's kernel history) must catch
that render (negative control), must find nothing in a second render at the
same count, and ``run_job`` must keep only renders that compiled nothing, while
giving the same image as a cold render of the same seed.
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

from experiments.lib import execute as E
from experiments.lib import plan as P
from experiments.lib.methods import Depth, parse_method
from experiments.lib.scenes import load_scene, read_scene

VARIANT = "llvm_ad_rgb"
SCENE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "scenes",
                     "cbox.xml")


@pytest.fixture(scope="module")
def mitsuba():
    import mitsuba as mi
    mi.set_variant(VARIANT)
    return mi


def test_a_one_spp_warm_up_does_not_warm_a_64_spp_render(mitsuba):
    """Negative control: the detector catches the render that compiled (the in-memory kernel
    cache is emptied first: an earlier test may have compiled the same kernel; a kernel
    loaded from the disk cache also counts as not warm)."""
    import drjit as dr
    dr.flush_kernel_cache()
    scene = load_scene(SCENE, 16, 8, parse_method("bsdf+nee+multijitter"), Depth(2))
    E._render(scene, None, 1, 1)                       # warm-up at 1 spp (the old way)
    first = E._render(scene, None, 64, 2)
    second = E._render(scene, None, 64, 3)
    assert first[3] > 0, "a render at a new sample count compiled, and must be caught"
    assert second[3] == 0, "the second render at the same count is warm"


def test_independent_does_not_recompile_for_a_new_count(mitsuba):
    """The opposite case: independent's kernel does not depend on the count."""
    scene = load_scene(SCENE, 16, 8, parse_method("bsdf+nee"), Depth(2))
    E._render(scene, None, 1, 1)
    assert E._render(scene, None, 64, 2)[3] == 0


@pytest.mark.parametrize("method", ["bsdf+nee+multijitter", "bsdf+nee+orthogonal",
                                    "bsdf+nee+halton:owen", "path+stratified"])
def test_run_job_times_only_warm_renders(mitsuba, method):
    import drjit as dr
    dr.flush_kernel_cache()                 # as in a fresh process: every count compiles once
    E.clear_cache()
    info = read_scene(SCENE)
    m = parse_method(method)
    jobs = P.ladder(f"timing/{method}", info, m, 16, 8, [1, 4, 16], 7, Depth(2), VARIANT)
    results = [E.run_job(j, VARIANT) for j in jobs]
    assert all(r.compiled_passes == 0 for r in results), [r.compiled_passes for r in results]
    # each new count's kernel (a sampler that bakes its count) compiled by its own warm-up
    assert [r.recompiled for r in results] == [0] * len(results)
    # a discarded render does not change the image: the same job in a fresh scene cache
    E.clear_cache()
    again = E.run_job(jobs[-1], VARIANT)
    np.testing.assert_array_equal(again.image, results[-1].image)


def _kernels(scene, spp: int) -> set:
    """The hashes of the large JIT kernels of a render of ``scene`` at ``spp``."""
    import drjit as dr
    import mitsuba as mi
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    dr.kernel_history_clear()
    dr.eval(mi.render(scene, spp=spp, seed=spp))
    dr.sync_thread()
    return {k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT
            and k.get("operation_count", 0) > 300}


@pytest.mark.parametrize("rfilter", ["gaussian", "box"])
def test_the_warm_up_count_compiles_the_kernel_of_the_timed_count(mitsuba, rfilter):
    """``warm_spp(n)`` renders Mitsuba's kernel of ``n`` samples per pixel (its render loop
    is a shift for a power of two, a division otherwise, and a Gaussian film merges a
    pixel's samples from 4 per pass on), on mi.cornell_box() (Mitsuba's own scene, with
    its Gaussian film and with a box). Negative control: on the Gaussian film the old
    1-spp warm-up renders another kernel than 16 spp."""
    d = mitsuba.cornell_box()
    d["sensor"]["film"].update(width=16, height=8, rfilter={"type": rfilter})
    scene = mitsuba.load_dict(d)
    kernels = {n: _kernels(scene, n)
               for n in (1, 2, 3, 4, 5, 6, 7, 8, 11, 16, 64, 100)}
    for n, kernel in kernels.items():
        assert kernel and kernels[E.warm_spp(n)] == kernel, (n, E.warm_spp(n))
        assert E.warm_spp(n) <= n
    if rfilter == "gaussian":
        assert kernels[1] != kernels[16]


def test_a_job_of_a_power_of_two_past_the_lane_cap_renders_warm_in_passes_of_one(
        mitsuba, monkeypatch):
    """A film's lane cap is rarely a power of two (48x36: 2427 spp per render); a job of a
    power of two past it (the suite's 4096 spp at equal time) renders in passes of a power
    of two (2048 + 2048), the kernel class of the cell's earlier jobs (warm_spp), so that
    after a 16-spp job of the same cell it compiles nothing, warm-up included. Negative
    control: a job of another count keeps passes of the lane cap (5000: 2427 + 2427 + 146)
    and compiles Mitsuba's other kernel class (in its warm-up: its timed render is warm)."""
    import drjit as dr
    dr.flush_kernel_cache()
    E.clear_cache()
    info = read_scene(SCENE)
    m = parse_method("bsdf+nee")
    small, = P.ladder("timing/lanes", info, m, 48, 36, [16], 7, Depth(2), VARIANT)
    big, other = (dataclasses.replace(small, key=f"{small.key}-{n}", spp=n, seed=8 + n)
                  for n in (4096, 5000))
    assert big.lane_cap == 2427 and big.passes() == [2048, 2048]
    assert other.passes() == [2427, 2427, 146]
    E.run_job(small, VARIANT)
    renders = []                   # kernels compiled by every render, warm-ups included
    real = E._render

    def counted(*args, **kwargs):
        out = real(*args, **kwargs)
        renders.append(out[3])
        return out
    monkeypatch.setattr(E, "_render", counted)
    compiled = []
    for job in (big, other):
        renders.clear()
        result = E.run_job(job, VARIANT)
        compiled.append(sum(renders))
        assert result.recompiled == 0 and result.compiled_passes == 0
    assert compiled[0] == 0 and compiled[1] > 0, compiled


def counted_passes(monkeypatch) -> list:
    """A list that grows by one at every call of execute.render_passes (a job's passes,
    warm-up or timed), emptied by the caller between jobs."""
    calls = []
    real = E.render_passes

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)
    monkeypatch.setattr(E, "render_passes", counted)
    return calls


def test_a_view_made_again_is_not_warmed_again_but_for_a_new_kind_of_job(mitsuba, monkeypatch):
    """The suite visits every scene once per budget, and a scene loaded again makes its
    views again; their kernels are in Dr.Jit's cache, so a view made again is not warmed
    up again (a trained guide's warm-up is a whole job): the trained job after a visit to
    another scene renders its passes once (the timed render), and nothing compiles.
    Negative control: an untrained job (under the guide's training thresholds) does not
    warm a trained one, whose first job renders its passes twice (warm-up, timed: before,
    the view made by the untrained job was taken as warm, and the trained job's timed
    render compiled, was discarded and rendered again)."""
    import drjit as dr
    dr.flush_kernel_cache()
    E.clear_cache()
    calls = counted_passes(monkeypatch)
    guided = parse_method("guided+nee")
    info = read_scene(SCENE)
    other = read_scene(os.path.join(os.path.dirname(SCENE), "suite", "furnace.xml"))
    untrained, = P.ladder("timing/warm/u", info, guided, 64, 64, [16], 7, Depth(2), VARIANT)
    trained, = P.ladder("timing/warm/t", info, guided, 64, 64, [256], 7, Depth(2), VARIANT)
    away, = P.ladder("timing/warm/o", other, parse_method("bsdf+nee"), 16, 16, [4], 7,
                     Depth(2), VARIANT)
    assert guided.trains(256, 64 * 64) and not guided.trains(16, 64 * 64)
    counts, last = [], None
    for job in (untrained, trained, away, trained):
        calls.clear()
        last = E.run_job(job, VARIANT)
        counts.append(len(calls))
    assert counts == [2, 2, 1, 1], counts
    assert last.recompiled == 0 and last.compiled_passes == 0
    assert not E.run_job(trained, VARIANT).recompiled


def test_a_pilot_is_rendered_once_and_warms_the_jobs_after_it(mitsuba, monkeypatch):
    """A pilot (the engine's render that measures a trained method's cost) renders once,
    not warmed up first (its cost is its kernels' execution): the trained jobs after it
    find their kernels compiled by it and render once, warm. (Warming the pilot up cost
    the suite a pilot-sized render per guiding scene.)"""
    import drjit as dr
    dr.flush_kernel_cache()
    E.clear_cache()
    calls = counted_passes(monkeypatch)
    guided = parse_method("guided+nee")
    info = read_scene(SCENE)
    untrained, = P.ladder("timing/pilot/u", info, guided, 64, 64, [16], 7, Depth(2), VARIANT)
    trained, = P.ladder("timing/pilot/t", info, guided, 64, 64, [256], 7, Depth(2), VARIANT)
    pilot = dataclasses.replace(trained, key=f"{trained.key}-pilot", seed=99, pilot=True)
    counts = []
    for job in (untrained, pilot, trained):
        calls.clear()
        result = E.run_job(job, VARIANT)
        counts.append(len(calls))
    assert counts == [2, 1, 1], counts
    assert result.recompiled == 0 and result.compiled_passes == 0


def test_the_reports_name_the_widest_simd_extension(tmp_path):
    """Exact values: ``cpu_simd`` names the widest vector extension of a cpuinfo's flags
    (the LLVM backend's kernels are that wide, so costs differ between an AVX2 and an
    AVX-512 machine), an ARM's NEON from its Features line, "unknown" without flags or
    without the file."""
    from experiments.lib.jobs import cpu_simd
    cases = {"flags\t\t: fpu sse4_2 avx avx2 avx512f avx512bw\n": "AVX-512",
             "flags\t\t: fpu sse4_2 avx avx2 fma\n": "AVX2",
             "flags\t\t: fpu sse4_2\n": "SSE4.2",
             "Features\t: fp asimd evtstrm\n": "NEON",
             "model name\t: a CPU\n": "unknown"}
    for text, name in cases.items():
        path = tmp_path / "cpuinfo"
        path.write_text("processor\t: 0\n" + text)
        assert cpu_simd(str(path)) == name
    assert cpu_simd(str(tmp_path / "absent")) == "unknown"
