"""The worked examples of docs/extending.md: a strategy, a sampler, a scene and a study, each
one file under examples/, loaded with ``--plugin FILE`` (or given as a scene) and run from a
folder outside the checkout, with no edit inside integrators/ or experiments/.

The strategy's chi-square and per-block checks, and the failing wrong copy, are in
tests/test_strategies.py (which takes its user strategy from examples/mirror_lobe.py);
here every example runs through the studies it is meant for, as a researcher would run it.
The sampler is also checked for unbiasedness per pixel block against Mitsuba's ``path``
(tests/_blocks.py), with a negative control of the size of a realistic bug.
"""
from __future__ import annotations

import csv
import os
import subprocess
import sys

import mitsuba as mi
import numpy as np
import pytest

import _blocks as B
from conftest import ROOT
from experiments.lib import extensions

EXAMPLES = os.path.join(ROOT, "examples")
#: Deadline of one example command (seconds).
DEADLINE = 400
TINY = ["--resolution", "16x8", "--spp", "4", "--reference-spp", "16", "--repeats", "2"]


def run(tmp_path, *argv) -> subprocess.CompletedProcess:
    """``python -m ...`` from a folder outside the checkout (the installed package)."""
    proc = subprocess.run([sys.executable, "-m", *argv], cwd=tmp_path, capture_output=True,
                          text=True, timeout=DEADLINE)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def column(path, name) -> list[str]:
    with open(path, newline="") as f:
        return [row[name] for row in csv.DictReader(f)]


def example(name: str) -> str:
    return os.path.join(EXAMPLES, name)


# ------------------------------------------------------------------ (a) a strategy

def test_strategy_example_runs_through_a_convergence_study_and_the_lab(tmp_path):
    out = tmp_path / "out"
    run(tmp_path, "experiments.convergence", "--plugin", example("mirror_lobe.py"),
        "--methods", "mirror_lobe,mirror_lobe+nee,bsdf", "--time-budget", "0.02",
        "--best-sampler", "none", "--out", str(out), *TINY)
    methods = column(out / "convergence" / "efficiency.csv", "method")
    assert {"mirror_lobe", "mirror_lobe+nee", "bsdf"} <= set(methods)
    run(tmp_path, "experiments.lab", "--quick", "--plugin", example("mirror_lobe.py"),
        "--out", str(out))
    with open(out / "lab" / "warps.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["strategy"] == "mirror_lobe"]
    assert rows, "the lab drew no warp panel of the example strategy"


# ------------------------------------------------------------------ (b) a sampler

def test_sampler_example_runs_through_the_sampler_study_and_the_lab(tmp_path):
    out = tmp_path / "out"
    run(tmp_path, "experiments.samplers", "--plugin", example("lattice_sampler.py"),
        "--depths", "2", "--resolution", "8x4", "--spp", "4", "--reference-spp", "16",
        "--repeats", "2", "--out", str(out))
    assert "lattice" in column(out / "samplers" / "samplers.csv", "sampler")
    run(tmp_path, "experiments.lab", "--quick", "--plugin", example("lattice_sampler.py"),
        "--out", str(out))
    assert "lattice" in (out / "lab" / "summary.md").read_text()


SCENE = {"type": "scene",
         "sensor": {"type": "perspective", "fov": 40,
                    "to_world": mi.ScalarTransform4f().look_at(origin=[0, 1, 3.5],
                                                               target=[0, 0, 0], up=[0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": 32, "height": 32,
                             "rfilter": {"type": "box"}}},
         "floor": {"type": "rectangle", "to_world": mi.ScalarTransform4f().rotate(
             [1, 0, 0], -90).scale(3), "bsdf": {"type": "diffuse"}},
         "ball": {"type": "sphere", "radius": 0.5,
                  "bsdf": {"type": "roughconductor", "alpha": 0.2}},
         "light": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate(
             [0, 2, 0]).rotate([1, 0, 0], 90).scale(0.5),
             "emitter": {"type": "area", "radiance": 6.0}}}


def test_sampler_example_is_unbiased_per_block():
    """bsdf+nee with the example sampler against path (independent) per 8x8 block and
    pooled (0.01, Sidak over blocks and channels); negative control: the same renders
    2% darker (a realistic bias, above the test's own detectable size) fail."""
    extensions.load(example("lattice_sampler.py"))
    vr = {"type": "vr_path", "strategy": "bsdf", "emitter_sampling": True, "max_depth": 4}
    seeds = list(range(8))
    ours = B.render_blocks(SCENE, vr, {"type": "lattice", "sample_count": 16}, seeds, 16)
    theirs = B.render_blocks(SCENE, {"type": "path", "max_depth": 4}, None,
                             [100 + s for s in seeds], 16)
    blocks, pooled = B.sidak(0.01, 2 * ours.images[0].size // B.BLOCK ** 2), B.sidak(0.01, 6)
    agreement = B.agree(ours, theirs, blocks, pooled)
    assert agreement.detectable < 0.02, agreement.describe()
    assert agreement.passed, agreement.describe()
    assert not B.agree(ours.scaled(0.98), theirs, blocks, pooled).passed


# ------------------------------------------------------------------ (c) a scene

def test_scene_example_runs_in_the_suite_beside_a_bundled_scene(tmp_path):
    """One XML file in a folder of one's own: the suite takes it with --scenes, reads its
    hypothesis from its header and judges every method on it."""
    import scenes
    out = tmp_path / "out"
    folder = os.path.join(EXAMPLES, "scenes")
    assert scenes.header(os.path.join(folder, "two_lights.xml")) is not None
    run(tmp_path, "experiments.suite", "--scenes",
        f"{folder},{scenes.path('suite/furnace.xml')}", "--methods", "bsdf,bsdf+nee,path",
        "--resolution", "16x12", "--spp", "4", "--reference-spp", "32", "--repeats", "2",
        "--time-budget", "0.004", "--out", str(out))
    summary = (out / "suite" / "summary.md").read_text()
    assert "two_lights" in summary and "furnace" in summary
    assert "glossy floor lit by two lights" in summary      # its header's 'isolates'


# ------------------------------------------------------------------ (d) a study

def test_study_example_runs_in_run_all_with_the_built_in_studies_off(tmp_path):
    out = tmp_path / "out"
    from experiments.lib import studies
    off = [a for s in studies.ordered() for a in (f"--{s.name}", "off")]
    run(tmp_path, "experiments.run_all", "--plugin", example("roulette_study.py"),
        "--roulette", "quick", *off, "--out", str(out))
    assert column(out / "roulette" / "efficiency.csv", "rr_depth") == ["1", "5"]
    assert 'id="roulette"' in (out / "index.html").read_text()
    # and alone, as a script of its own
    proc = subprocess.run([sys.executable, example("roulette_study.py"), "--rr-depths", "0",
                           "--out", str(tmp_path / "bad")], cwd=tmp_path, capture_output=True,
                          text=True, timeout=DEADLINE)
    assert proc.returncode == 2 and "invalid --rr-depths '0'" in proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr
