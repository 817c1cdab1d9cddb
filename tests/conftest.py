"""Test set-up: every test runs on Mitsuba's LLVM backend (``llvm_ad_rgb``)."""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import integrators  # noqa: E402  (first: chooses libLLVM before drjit is imported)
import mitsuba as mi  # noqa: E402
import pytest  # noqa: E402

VARIANT = "llvm_ad_rgb"
SCENES = os.path.join(ROOT, "scenes")

mi.set_variant(VARIANT)  # registers the plugins (integrators' variant callback)


@pytest.fixture(autouse=True)
def variant():
    """Each test starts (and ends) in the LLVM variant with the plugins registered."""
    mi.set_variant(VARIANT)
    yield VARIANT
    mi.set_variant(VARIANT)


def scene_path(name: str) -> str:
    return os.path.join(SCENES, name)
