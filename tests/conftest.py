"""Test set-up: every test runs on Mitsuba's LLVM backend (``llvm_ad_rgb``), with no
garbage left by the tests before it."""
import gc
import sys

from _paths import ROOT, SCENES, scene_path  # noqa: F401  (tests import them from here too)

if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import integrators  # noqa: E402  (first: chooses libLLVM before drjit is imported)
import mitsuba as mi  # noqa: E402
import pytest  # noqa: E402

VARIANT = "llvm_ad_rgb"

#: A crashed xdist worker: its fatal-error report printed at the end of the run, the test
#: rerun once in a fresh worker.
pytest_plugins = ["_crashlog"]

mi.set_variant(VARIANT)  # registers the plugins (integrators' variant callback)


def pytest_collection_finish(session):
    """What exists once the tests are collected (modules, the plugins) lives to the end:
    frozen out of the collector, so that the collection before each test is cheap."""
    gc.collect()
    gc.freeze()


@pytest.fixture(autouse=True)
def variant():
    """Each test starts (and ends) in the LLVM variant with the plugins registered, and
    without the garbage of the tests before it: Dr.Jit traces every live shape, BSDF and
    emitter into a kernel, so a scene of an earlier test kept alive by a reference cycle
    (a caught exception's traceback holds its frame) changes the kernels of this one (a
    cache miss where a test asserts a hit) until the collector frees it, mid-test."""
    gc.collect()
    mi.set_variant(VARIANT)
    yield VARIANT
    mi.set_variant(VARIANT)


@pytest.fixture
def count_jobs(monkeypatch):
    """The keys of the jobs rendered during the test (through execute.run_job, in this
    process), in order."""
    from experiments.lib import execute
    calls = []
    real = execute.run_job

    def counting(job, variant):
        calls.append(job.key)
        return real(job, variant)
    monkeypatch.setattr(execute, "run_job", counting)
    return calls
