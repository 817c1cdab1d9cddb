"""Where a cell's samples cannot reach a narrow lobe's light, its biased verdict is void.

A strategy that ignores the BSDF draws the core of a narrow lobe (the directions of highest
BSDF density that carry half its albedo) with a tiny probability per vertex, squared
through a closed glass object. A correct estimator then misses that light in almost every
render, and its samples cannot tell that from a bias: the suite's bias test keeps a biased
verdict only where the cell's samples could pass through that core at least
``bias_test.REACH_MIN`` times (experiments/lib/scene_probes.py, ``core_reach`` and
``path_reach``; experiments/lib/studies/suite/bias_test.py, ``unreached``).
"""
from __future__ import annotations

import math

import pytest

import integrators  # noqa: F401  (libLLVM for Dr.Jit)
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")

from experiments.lib import scene_probes  # noqa: E402
from experiments.lib.studies.suite import bias_test  # noqa: E402


def test_core_reach_of_known_lobes():
    """Exact values: on a diffuse BSDF the core is the cone cos > 1/sqrt(2), which
    uniform sampling draws with probability 1 - 1/sqrt(2) and cosine sampling (its own
    sampling) with 1/2 (n = 65536: standard error about 0.002); a delta lobe is sampled by
    every strategy through the BSDF's own sampling (1). Narrow rough dielectrics, for
    uniform sampling: measured 1.3e-3 (Beckmann 0.1) and 5e-5 (Beckmann 0.02, Mitsuba's
    test_roughdielectric_path); for the BSDF's own sampling 0.59."""
    diffuse = mi.load_dict({"type": "diffuse"})
    assert scene_probes.core_reach(diffuse, "uniform") == pytest.approx(1 - math.sqrt(0.5),
                                                                        abs=0.01)
    assert scene_probes.core_reach(diffuse, "cosine") == pytest.approx(0.5, abs=0.01)
    assert scene_probes.core_reach(mi.load_dict({"type": "conductor"}), "uniform") == 1.0
    rough = mi.load_dict({"type": "roughdielectric", "alpha": 0.1})
    narrow = mi.load_dict({"type": "roughdielectric", "distribution": "beckmann",
                           "alpha": 0.02, "int_ior": "bk7"})
    assert 1e-3 < scene_probes.core_reach(rough, "uniform") < 1e-2
    assert 1e-5 < scene_probes.core_reach(narrow, "uniform") < 2e-4
    assert 0.45 < scene_probes.core_reach(narrow, "bsdf") < 0.7


def test_a_path_crosses_a_glass_object_twice():
    """path_reach: the least over the scene's BSDFs, squared for one that transmits."""
    glass = {"type": "roughdielectric", "alpha": 0.1}
    scene = mi.load_dict({"type": "scene",
                          "floor": {"type": "rectangle", "bsdf": {"type": "diffuse"}},
                          "ball": {"type": "sphere", "bsdf": glass}})
    one = scene_probes.core_reach(mi.load_dict(glass), "uniform")
    assert scene_probes.path_reach(scene, "uniform") == pytest.approx(one * one, rel=1e-6)


def cells() -> dict:
    return {"a": bias_test.CellBias("biased"), "b": bias_test.CellBias("biased"),
            "c": bias_test.CellBias("unbiased"),
            "d": bias_test.CellBias("untestable", "heavy_tails")}


def test_only_a_biased_verdict_below_the_reach_is_void():
    """a: 1e6 samples x 1e-6 reach = 1 passage (void); b: 1e6 x 1e-4 = 100 (kept); the
    reach is asked for biased cells alone (it loads the scene); every number is kept."""
    asked = []

    def reach(name):
        asked.append(name)
        return {"a": 1e-6, "b": 1e-4}[name]
    got = bias_test.unreached(cells(), dict.fromkeys("abcd", 10 ** 6), reach)
    assert got["a"].status == "untestable" and got["a"].reason == "unreached_lobe"
    assert got["b"].status == "biased" and got["c"].status == "unbiased"
    assert got["d"] == cells()["d"] and sorted(asked) == ["a", "b"]
    # at the bound: 1e6 x 1e-5 = REACH_MIN passages stand
    assert bias_test.REACH_MIN == 10.0
    kept = bias_test.unreached({"a": bias_test.CellBias("biased")}, {"a": 10 ** 6},
                               lambda name: 1e-5)
    assert kept["a"].status == "biased"


def test_the_suites_rough_glass_keeps_its_uniform_verdicts():
    """The negative control on a bundled scene: rough_glass' uniform cells draw 19 million
    samples (64x48, 2048 + 16 spp, 3 repeats each) at a reach of about 7e-6 (its GGX 0.1
    glass, 2.6e-3 per surface, squared): about 130 passages, so a bias found there would
    stand. Mitsuba's test_roughdielectric_path (Beckmann 0.02) at 64x36, 1024 spp x 8
    renders (19 million samples) at about 2.5e-9: 0.05 passages, void."""
    scene = scene_probes.probe_scene("scenes/suite/rough_glass.xml", 16, 12)
    assert 64 * 48 * (2048 + 16) * 3 * scene_probes.path_reach(scene, "uniform") \
        > 5 * bias_test.REACH_MIN
    narrow = mi.load_dict({"type": "roughdielectric", "distribution": "beckmann",
                           "alpha": 0.02, "int_ior": "bk7"})
    assert 64 * 36 * 1024 * 8 * scene_probes.core_reach(narrow, "uniform") ** 2 \
        < bias_test.REACH_MIN / 10


def test_a_strategy_whose_reach_cannot_be_probed_keeps_its_verdict():
    """A registered strategy without a ``pdf`` (the base class's raises): the reach is
    infinite, so a biased verdict stands, and a warning names the method and why; a
    method of a built-in strategy is probed."""
    from integrators import strategies
    from experiments.lib.methods import parse_method
    from experiments.lib.studies.suite import declare, measure

    class NoPdf(strategies.Strategy):
        def sample(self, bsdf, ctx, si, sample1, sample2, active):
            raise NotImplementedError

    strategies.register("test_no_pdf", NoPdf)
    try:
        sp = declare.ScenePlan("rough_glass", "scenes/suite/rough_glass.xml")
        with pytest.warns(UserWarning, match="test_no_pdf.*could not be probed"):
            assert measure.reach(sp, parse_method("test_no_pdf")) == math.inf
        assert measure.reach(sp, parse_method("uniform")) < 1e-4
    finally:
        strategies.unregister("test_no_pdf")
