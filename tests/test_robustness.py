"""Robustness (issue #5): no NaN/Inf from the plugins, clear parameter errors, clean script exits.

* Non-finite values: ``vr_path`` (every strategy, next-event estimation on and
  off) renders a scene built from the cases that break naive code: Phong
  exponents 0, 1 and 10^4, zero reflectance, a surface seen from behind, a
  tiny sphere (degenerate frames), normals exactly along the axes, and a
  grazing view. Every raw sample (the integrator's ``sample`` on the camera
  rays) and every film pixel must be finite and >= 0; the ``phong`` plugin's
  ``sample``/``eval``/``pdf`` must be finite on a grid of incident directions
  down to exactly grazing and below the horizon. These are deterministic
  properties: a single non-finite value fails.
* Parameter errors: each bad plugin parameter raises with a message that names
  the bad value and the valid choices.
* Script errors: each experiment script, given each bad input, exits with code
  2 and one line on stderr, no traceback, and writes nothing.
"""
import os
import subprocess
import sys

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from _paths import ROOT
from experiments.lib.methods import Depth, parse_method, strategies

PYTHON = sys.executable


# ------------------------------------------------------------ NaN / Inf grid

def phong(kd, ks, exponent):
    return {"type": "phong", "diffuse_reflectance": {"type": "rgb", "value": kd},
            "specular_reflectance": {"type": "rgb", "value": ks}, "exponent": exponent}


def grid_scene(view: str, strategy: str, nee: bool, spp: int = 8):
    """A small scene holding every troublesome case at once, seen head-on or grazing."""
    if view == "front":      # looks straight down -z: normals exactly along the axes
        origin, target = [0, 1, 4], [0, 1, 0]
    else:                    # eye 1e-3 above a Phong floor, looking along it
        origin, target = [0, 1e-3, 4], [0, 1e-3, -4]
    scene = {
        "type": "scene",
        "integrator": parse_method(strategy + ("+nee" if nee else "")).integrator_dict(
            Depth(max_depth=6, rr_depth=3)),
        "sensor": {"type": "perspective", "fov": 60,
                   "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=target,
                                                              up=[0, 1, 0]),
                   "sampler": {"type": "independent", "sample_count": spp},
                   "film": {"type": "hdrfilm", "width": 24, "height": 12,
                            "rfilter": {"type": "box"}}},
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": 0.5}},
        "light": {"type": "rectangle",
                  "to_world": mi.ScalarTransform4f().translate([0, 3, 0]).rotate([1, 0, 0], 90),
                  "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 20.0}}},
        # floor with a mirror-like lobe (n = 10^4): grazing view reflects the horizon
        "floor": {"type": "rectangle", "bsdf": phong(0.0, 0.9, 1e4),
                  "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], -90).scale(10)},
        "n0": {"type": "sphere", "center": [-1.5, 1, 0], "radius": 0.4,
               "bsdf": phong(0.3, 0.6, 0.0)},
        "n1": {"type": "sphere", "center": [-0.5, 1, 0], "radius": 0.4,
               "bsdf": phong(0.3, 0.6, 1.0)},
        "n1e4": {"type": "sphere", "center": [0.5, 1, 0], "radius": 0.4,
                 "bsdf": phong(0.0, 1.0, 1e4)},
        "black": {"type": "sphere", "center": [1.5, 1, 0], "radius": 0.4,
                  "bsdf": phong(0.0, 0.0, 30.0)},
        # one-sided Phong rectangle seen from behind (normal pointing away from the camera)
        "back": {"type": "rectangle", "flip_normals": True, "bsdf": phong(0.5, 0.5, 100.0),
                 "to_world": mi.ScalarTransform4f().translate([0, 2.0, 1]).scale(0.5)},
        # degenerate frames: a sphere far below a pixel and a tiny rectangle
        "tiny": {"type": "sphere", "center": [0, 0.4, 1], "radius": 1e-5,
                 "bsdf": phong(0.5, 0.5, 1e4)},
        "sliver": {"type": "rectangle", "bsdf": phong(0.5, 0.5, 10.0),
                   "to_world": mi.ScalarTransform4f().translate([1, 0.3, 1]).scale([1e-6, 0.5, 1])},
    }
    return mi.load_dict(scene)


def raw_samples(scene, spp: int, seed: int = 0) -> np.ndarray:
    """Radiance of every camera sample as the integrator returns it (before the film)."""
    sensor = scene.sensors()[0]
    width, height = sensor.film().crop_size()
    n = width * height * spp
    sampler = sensor.sampler().clone()
    sampler.set_sample_count(spp)
    sampler.seed(seed, n)
    pixel = dr.arange(mi.UInt32, n) // spp
    pos = (mi.Point2f(mi.Float(pixel % width), mi.Float(pixel // width)) + sampler.next_2d())
    ray, _ = sensor.sample_ray(0.0, sampler.next_1d(), pos / mi.ScalarVector2f(width, height),
                               sampler.next_2d())
    L, _, _ = scene.integrator().sample(scene, sampler, ray, None, True)
    return np.array(L)


@pytest.mark.parametrize("strategy", strategies())
@pytest.mark.parametrize("nee", [False, True], ids=["no_nee", "nee"])
@pytest.mark.parametrize("view", ["front", "grazing"])
def test_no_nan_or_inf_reaches_the_film(view, strategy, nee):
    scene = grid_scene(view, strategy, nee)
    samples = raw_samples(scene, 8, seed=1)
    assert samples.size > 0
    assert np.isfinite(samples).all(), f"{np.count_nonzero(~np.isfinite(samples))} bad samples"
    assert (samples >= 0).all()
    image = np.array(mi.render(scene, spp=8, seed=2))
    assert np.isfinite(image).all(), f"{np.count_nonzero(~np.isfinite(image))} bad pixels"
    assert (image >= 0).all()
    assert image.max() > 0          # the scene is lit: the check is not vacuous


@pytest.mark.parametrize("exponent", [0.0, 1.0, 1e4])
@pytest.mark.parametrize("kd,ks", [(0.0, 0.0), (0.3, 0.6), (0.0, 1.0)])
def test_phong_is_finite_at_grazing_and_below_the_horizon(exponent, kd, ks):
    """sample/eval/pdf on incident directions from normal to exactly grazing and below."""
    bsdf = mi.load_dict(phong(kd, ks, exponent))
    cos_i = [1.0, 0.5, 1e-2, 1e-4, 1e-7, 0.0, -1e-7, -0.5, -1.0]
    m = 4096
    rng = np.random.default_rng(3)
    ci = np.repeat(cos_i, m)
    wi = mi.Vector3f(np.sqrt(np.maximum(0.0, 1 - ci * ci)), 0.0 * ci, ci)
    si = dr.zeros(mi.SurfaceInteraction3f, len(ci))
    si.wi = wi
    si.uv = mi.Point2f(0.5, 0.5)
    u = rng.random((3, len(ci)))
    u[1:, :m] = 0.0                      # include the corners of the square
    u[1:, m:2 * m] = np.nextafter(1.0, 0.0)
    ctx = mi.BSDFContext()
    bs, weight = bsdf.sample(ctx, si, mi.Float(u[0]), mi.Point2f(u[1], u[2]))
    wo = bs.wo
    value, pdf = bsdf.eval_pdf(ctx, si, wo)
    for name, array in (("weight", weight), ("pdf", bs.pdf), ("wo", wo), ("eval", value),
                        ("eval_pdf pdf", pdf)):
        a = np.array(array)
        assert np.isfinite(a).all(), f"non-finite {name}"
    for name, array in (("weight", weight), ("pdf", bs.pdf), ("eval", value)):
        assert (np.array(array) >= 0).all(), f"negative {name}"
    below = ci <= 0
    assert (np.array(weight)[:, below] == 0).all()       # one-sided: nothing from behind


# ---------------------------------------------------------------- parameters

BAD_PARAMETERS = [
    ({"type": "vr_path", "strategy": "importance"}, ["'importance'", ", ".join(strategies())]),
    ({"type": "vr_path", "max_depth": -2}, ["-2", "-1", ">= 0"]),
    ({"type": "vr_path", "rr_depth": 0}, ["got 0", "> 0"]),
    ({"type": "phong", "exponent": -1.0}, ["-1.0", ">= 0"]),
    ({"type": "phong", "exponent": float("nan")}, ["nan", ">= 0"]),
    ({"type": "phong", "diffuse_reflectance": 1.5}, ["diffuse_reflectance", "1.5", "[0, 1]"]),
    ({"type": "phong", "specular_reflectance": -0.25}, ["specular_reflectance", "-0.25",
                                                        "[0, 1]"]),
    ({"type": "phong", "diffuse_reflectance": float("nan")}, ["diffuse_reflectance", "nan",
                                                              "[0, 1]"]),
    ({"type": "halton", "randomization": "sobol"}, ["'sobol'", "none", "permute_digits",
                                                    "owen"]),
    ({"type": "halton", "sample_count": 0}, ["sample_count", "got 0", "> 0"]),
]


@pytest.mark.parametrize("props, expected", BAD_PARAMETERS,
                         ids=[f"{p['type']}-{list(p)[1]}={list(p.values())[1]}"
                              for p, _ in BAD_PARAMETERS])
def test_bad_parameter_names_value_and_valid_choices(props, expected):
    with pytest.raises(Exception) as exc:
        mi.load_dict(props)
    # Mitsuba wraps the plugin's ValueError; its last line is the plugin's message
    message = str(exc.value).strip().splitlines()[-1]
    assert message.startswith("ValueError: " + props["type"]), message
    for part in expected:
        assert part in message, (part, message)


def test_bad_parameter_in_a_scene_file_is_reported_too(tmp_path):
    path = tmp_path / "s.xml"
    path.write_text('<scene version="3.0.0"><integrator type="vr_path">'
                    '<string name="strategy" value="bogus"/></integrator></scene>')
    with pytest.raises(Exception) as exc:
        mi.load_file(str(path))
    assert f"unknown strategy 'bogus'; valid choices are {', '.join(strategies())}" in \
        str(exc.value)


# ------------------------------------------------------------------ scripts

SCRIPTS = ["convergence", "writeup", "run_all", "stability", "samplers"]


def _bad_inputs(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    return {
        "missing scene": (["--scene", str(tmp_path / "missing.xml")], "missing.xml"),
        "unknown method": (["--methods", "bsdf,sphere"], "unknown method 'sphere'"),
        "bad resolution": (["--resolution", "64by32"], "invalid resolution '64by32'"),
        "unwritable out": (["--out", str(blocker / "sub")], "is not writable"),
        "out is a file": (["--out", str(blocker)], "is not a directory"),
        "scalar variant": (["--variant", "scalar_rgb"], "variant 'scalar_rgb' is not supported"),
    }


CASES = ["missing scene", "unknown method", "bad resolution", "unwritable out",
         "out is a file", "scalar variant"]


def _files(directory):
    return sorted(os.path.relpath(os.path.join(r, f), directory)
                  for r, _, names in os.walk(directory) for f in names)


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("script", SCRIPTS)
def test_script_rejects_bad_input_with_exit_2(script, case, tmp_path, capsys, monkeypatch):
    import importlib
    module = importlib.import_module(f"experiments.{script}")
    work = tmp_path / "work"
    work.mkdir()
    argv, message = _bad_inputs(work)[case]
    if "--out" not in argv:
        argv = argv + ["--out", str(work / "out")]
    before = _files(work)
    monkeypatch.chdir(work)
    with pytest.raises(SystemExit) as exc:
        module.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert message in err and "Traceback" not in err, err
    assert _files(work) == before                         # no (partial) output file
    assert not (work / "out").exists()


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_in_a_real_process_exits_2_without_traceback(script, tmp_path):
    """A real interpreter (the import order and the variant callback included)."""
    out = tmp_path / "out"
    proc = subprocess.run([PYTHON, "-m", f"experiments.{script}", "--variant", "scalar_rgb",
                           "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "scalar_rgb" in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists()
