"""Test set-up: every test runs on Mitsuba's LLVM backend (``llvm_ad_rgb``)."""
import sys

from _paths import ROOT, SCENES, scene_path  # noqa: F401  (tests import them from here too)

if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import integrators  # noqa: E402  (first: chooses libLLVM before drjit is imported)
import mitsuba as mi  # noqa: E402
import pytest  # noqa: E402

VARIANT = "llvm_ad_rgb"

mi.set_variant(VARIANT)  # registers the plugins (integrators' variant callback)


@pytest.fixture(autouse=True)
def variant():
    """Each test starts (and ends) in the LLVM variant with the plugins registered."""
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
