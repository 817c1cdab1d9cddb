"""The one clock (experiments/lib/clock.py) and the executor's fresh integrator per job.

* Only the clock reads a render's timings (``wall_seconds``, ``cpu_seconds``,
  ``kernel_seconds``, ``host_seconds``): an AST scan of every module of the package, tools,
  benchmarks and examples, with a negative control on synthetic source.
* A method that renders in two passes of its own (:class:`~experiments.lib.multipass.MultiPass`,
  declared here) is costed for both passes' kernels and for the host work between them: the
  host work is a known amount of thread CPU time; the kernels of a heavy first pass must be
  counted (negative control: a render of the last pass alone costs far less).
* Every job starts from an untrained integrator: a method that counts the passes it has
  seen reports 2 per two-pass job, job after job (negative control: an executor that kept
  one integrator gives 4 for the second job).
"""
from __future__ import annotations

import ast
import os
import time

import numpy as np
import pytest

from _paths import ROOT, scene_path
from experiments.lib import clock, execute, methods, plan
from experiments.lib.jobs import JobResult

#: The attributes of a render result that only the clock may read.
TIMINGS = {"wall_seconds", "cpu_seconds", "kernel_seconds", "host_seconds"}
#: Modules that write the timings (the executor, the result type, the store) or are the clock.
WRITERS = {os.path.join("experiments", "lib", name)
           for name in ("clock.py", "execute.py", "jobs.py", "store.py")}
#: Thread CPU seconds of host work each pass of the two-pass method does.
HOST_WORK = 0.08


def timing_reads(source: str) -> list[str]:
    """The timing attributes ``source`` reads (``x.kernel_seconds``...)."""
    return [node.attr for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Attribute) and node.attr in TIMINGS]


def test_timing_reader_finds_a_read():
    assert timing_reads("t = result.kernel_seconds + r.host_seconds\n") == \
        ["kernel_seconds", "host_seconds"]
    assert timing_reads("seconds = 1\nx.wall = 2\n") == []


def test_only_the_clock_reads_render_timings():
    readers, scanned = [], 0
    for top in ("experiments", "tools", "benchmarks", "examples"):
        for directory, _, names in os.walk(os.path.join(ROOT, top)):
            for name in names:
                if not name.endswith(".py"):
                    continue
                path = os.path.join(directory, name)
                rel = os.path.relpath(path, ROOT)
                with open(path, encoding="utf-8") as f:
                    found = timing_reads(f.read())
                scanned += 1
                if found and rel not in WRITERS:
                    readers.append((rel, sorted(set(found))))
    assert scanned >= 40
    assert not readers, f"read a render's timings outside experiments/lib/clock.py: {readers}"


def test_cost_is_kernel_plus_host_time_and_overhead_the_rest():
    r = JobResult(np.zeros((1, 1, 3)), None, 4, 2, wall_seconds=1.0, kernel_seconds=0.25,
                  host_seconds=0.5)
    assert clock.cost(r) == 0.75 and clock.overhead(r) == 0.25 and clock.wall(r) == 1.0
    assert clock.kernels(r) == 0.25 and clock.fixed(r) == 0.5
    assert clock.total([r, r]) == 1.5
    stale = JobResult(np.zeros((1, 1, 3)), None, 4, 2, wall_seconds=1.0)
    with pytest.raises(clock.ClockError, match="no kernel time"):
        clock.cost(stale)


# ------------------------------------------------------------------ a two-pass method

@pytest.fixture(scope="module")
def two_pass():
    """A Mitsuba integrator plugin ``clock_two_pass``: Mitsuba's ``path`` rendered in two
    passes (7/8 of the samples, then 1/8), with ``HOST_WORK`` seconds of CPU work after
    each; its image is the number of passes the instance has seen (a learning method's
    state), constant over the film. ``work`` = 0 gives a method without host work."""
    import mitsuba as mi

    class TwoPass(mi.SamplingIntegrator):
        def __init__(self, props):
            mi.SamplingIntegrator.__init__(self, props)
            self.work = props.get("work", HOST_WORK)
            self.merge = props.get("merge", False)
            self.inner = mi.load_dict({"type": "path", "max_depth": 3})
            self.seen = 0

        def sample(self, scene, sampler, ray, medium=None, active=True):
            return self.inner.sample(scene, sampler, ray, medium, active)

        def pass_schedule(self, spp, pixels):
            return [spp // 8] * 8 if self.merge else [spp - spp // 8, spp // 8]

        def after_pass(self, index, image, spp):
            self.seen += 1
            start = time.thread_time()
            while time.thread_time() - start < self.work:
                np.linalg.svd(np.ones((40, 40)))
            return [7 * spp] if self.merge and index == 0 else None

        def combine(self, images, spps):
            return np.full_like(images[0], float(self.seen))

    mi.register_integrator("clock_two_pass", lambda props: TwoPass(props))

    class TwoPassMethod(methods.Method):
        def integrator_dict(self, depth=methods.Depth()):
            return {"type": "clock_two_pass", "work": self.work, "merge": self.merge}

    def method(work=HOST_WORK, merge=False):
        m = TwoPassMethod("two-pass", None)
        object.__setattr__(m, "work", work)
        object.__setattr__(m, "merge", merge)
        return m
    return method


def _job(method, spp: int, prefix: str):
    from experiments.lib.scenes import read_scene
    return plan.make_job(prefix, read_scene(scene_path("cbox.xml")), method, 64, 64, spp, 5,
                         methods.Depth(3), "llvm_ad_rgb")


def test_two_pass_method_is_costed_for_both_passes_and_its_host_work(two_pass):
    execute.clear_cache()
    result = execute.run_job(_job(two_pass(), 64, "clock/two-pass"), "llvm_ad_rgb")
    assert len(result.pass_seconds) == 2 and result.spp == 64
    assert result.passes == 1       # its passes are not samples of one estimator
    # the host work: HOST_WORK of thread CPU per pass, and little else (combine is cheap)
    assert 2 * HOST_WORK <= result.host_seconds < 2 * HOST_WORK + 0.2, result.host_seconds
    assert clock.cost(result) == pytest.approx(result.kernel_seconds + result.host_seconds)
    # negative control for the host part: the same method without host work
    idle = execute.run_job(_job(two_pass(0.0), 64, "clock/idle"), "llvm_ad_rgb")
    assert idle.host_seconds < HOST_WORK, idle.host_seconds
    # the kernels of both passes: the heavy first pass (56 of 64 spp) is counted. A render
    # of the light last pass alone (8 spp, the negative control) costs far less.
    path = methods.parse_method("path")
    full = min(execute.run_job(_job(path, 64, f"clock/full/{i}"), "llvm_ad_rgb").kernel_seconds
               for i in range(3))
    last = min(execute.run_job(_job(path, 8, f"clock/last/{i}"), "llvm_ad_rgb").kernel_seconds
               for i in range(3))
    assert last < 0.5 * full, (last, full)
    assert min(result.kernel_seconds, idle.kernel_seconds) > 0.6 * full, \
        (result.kernel_seconds, idle.kernel_seconds, full)


def test_a_method_may_render_its_rest_in_other_passes(two_pass):
    """after_pass may return the passes after it anew (a guide that stopped learning
    renders its rest in one pass): eight passes of 8 spp become one of 8 and one of 56,
    the job's samples unchanged."""
    execute.clear_cache()
    result = execute.run_job(_job(two_pass(0.0, merge=True), 64, "clock/merged"),
                             "llvm_ad_rgb")
    assert len(result.pass_seconds) == 2 and result.spp == 64, result.pass_seconds


def test_every_job_starts_with_an_untrained_integrator(two_pass, monkeypatch):
    execute.clear_cache()
    jobs = [_job(two_pass(0.0), 16, f"clock/fresh/{i}") for i in range(3)]
    seen = [float(execute.run_job(j, "llvm_ad_rgb").image.mean()) for j in jobs]
    assert seen == [2.0, 2.0, 2.0]
    # negative control: an executor that kept the integrator of its first job
    kept = {}
    real = execute.fresh_integrator
    monkeypatch.setattr(execute, "fresh_integrator",
                        lambda job: kept.setdefault(job.method.name, real(job)))
    again = [float(execute.run_job(j, "llvm_ad_rgb").image.mean()) for j in jobs[:2]]
    assert again[1] > 2.0, again


def test_a_pilot_is_rendered_once_whatever_compiles(monkeypatch):
    """A job during which a kernel compiled is rendered again, warm (up to WARM_TRIES
    tries), except a count's pilot, which only gives its cost (kernel execution, which
    a compile is not part of): one try. The key does not depend on the flag."""
    tries = []

    def compiling(view, integrator, job):
        tries.append(job.key)
        image = np.zeros((job.height, job.width, 3))
        return execute.Timed(image, image, job.spp, 1, [0.1], 0.1, 0.05, 0.0, compiled=1)
    monkeypatch.setattr(execute, "render_passes", compiling)
    monkeypatch.setattr(execute, "_view", lambda job, variant: None)
    monkeypatch.setattr(execute, "fresh_integrator", lambda job: None)
    from experiments.lib.scenes import read_scene
    args = ("clock/pilot", read_scene(scene_path("cbox.xml")), methods.parse_method("path"),
            8, 8, 4, 5, methods.Depth(3), "llvm_ad_rgb")
    pilot, job = plan.make_job(*args, pilot=True), plan.make_job(*args)
    assert pilot.key == job.key and pilot.pilot and not job.pilot
    result = execute.run_job(pilot, "llvm_ad_rgb")
    assert len(tries) == 1 and result.recompiled == 0 and result.compiled_passes == 1
    tries.clear()
    result = execute.run_job(job, "llvm_ad_rgb")          # negative control: retried
    assert len(tries) == execute.WARM_TRIES and result.recompiled == execute.WARM_TRIES - 1
