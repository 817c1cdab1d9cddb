"""The sampling lab (experiments.lab): its numbers are the ones Mitsuba and scipy give.

- the lab's own chi-square test (numpy histogram, pooling, p-value) gives
  mitsuba.chi2.ChiSquareTest's p-value for the same seed and grid;
- its centered L2 discrepancy equals scipy.stats.qmc.discrepancy(method="CD");
- a strategy that reports a wrong density is rejected (p < 1e-6) and its
  difference image is far from noise;
- the point sets it reports are the ones an instrumented mi.render receives;
- ``python -m experiments.lab --quick`` writes its section and CSVs (the screen-space
  error images of the sampler study's jobs among them), resumes from its cache and the
  job store, and rejects bad input with exit code 2.
"""
import csv
import json
import math
import os
import types

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import _qmc_oracle as oracle
import integrators.path as vr_path
from experiments.lib import execute, samplers
from experiments.lib.studies.lab import figures, points, warps
from experiments.lib.studies.sampler_comparison import plan


def spec(label, strategy, incidence, samples=100_000, seed=3):
    bsdf = dict(warps.BSDFS)[label]
    return warps.PanelSpec(label, bsdf, strategy, incidence, samples, seed)


@pytest.mark.parametrize("label,strategy,incidence", [
    ("phong n=10", "cosine", 60.0),
    ("roughdielectric a=0.3", "mis", 60.0),        # both sides of the surface
    ("phong n=1000", "bsdf", 60.0),                # the cap grid about the lobe
])
def test_lab_p_value_is_mitsubas(label, strategy, incidence, monkeypatch, tmp_path):
    s = spec(label, strategy, incidence)
    panel = warps.compute(s)
    bsdf = mi.load_dict(s.bsdf)
    wi = warps.incident(incidence)
    domain = warps.domain_for(s)
    monkeypatch.chdir(tmp_path)               # ChiSquareTest may write chi2_data.py
    test = mi.chi2.ChiSquareTest(domain=domain,
                                 sample_func=warps.sample_func(strategy, bsdf, wi, domain),
                                 pdf_func=warps.pdf_func(strategy, bsdf, wi), sample_dim=3,
                                 sample_count=s.samples, res=s.res, ires=s.ires, seed=s.seed)
    test.run(quiet=True)
    hist = np.asarray(test.histogram).reshape(s.res, s.res)
    assert np.array_equal(hist, panel["histogram"])          # the same directions, binned alike
    assert panel["p_value"] == pytest.approx(test.p_value[0] if hasattr(test.p_value, "__len__")
                                             else float(test.p_value), rel=1e-5, abs=1e-9)
    assert panel["p_value"] > 1e-4


def test_chi2_test_pools_as_mitsuba():
    rng = np.random.default_rng(1)
    expected = rng.exponential(3.0, 500)
    observed = rng.poisson(expected).astype(float)
    order = np.argsort(expected, kind="stable")
    stat, dof, p = warps.chi2_test(observed, expected, order)
    ref = mi.math_py.chi2(observed[order], expected[order], 5)
    assert stat == pytest.approx(ref[0]) and dof == ref[1]
    assert warps.chi2_test([1.0, 0.0], [0.0, 1.0])[2] == 0.0     # a sample where none can be


def test_discrepancy_equals_scipys():
    from scipy.stats import qmc
    for name in ("independent", "stratified", "halton:owen"):
        pts, count = points.draw(name, 16, 2, 2, 2)
        for a, b in points.PAIRS:
            pair = pts[..., [a, b]]
            ours = points.centered_discrepancy(pair)
            theirs = [qmc.discrepancy(p, method="CD") for p in pair]
            np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=0)
    x = np.random.default_rng(0).random((50, 3))
    assert points.centered_discrepancy(x) == pytest.approx(qmc.discrepancy(x, method="CD"),
                                                       rel=1e-12)


def test_power_spectrum_of_independent_points_is_flat():
    x = np.random.default_rng(0).random((200, 64, 2))
    freqs, power, joint = points.power_spectrum(x, 12)
    assert np.all(np.abs(power - 1.0) < 0.15) and abs(joint - 1.0) < 0.15
    # a jittered 8x8 grid is jointly stratified: low power at low frequencies
    rng = np.random.default_rng(1)
    grid = (np.stack(np.meshgrid(np.arange(8), np.arange(8)), -1).reshape(64, 2)
            + rng.random((100, 64, 2))) / 8
    assert points.power_spectrum(grid, 12)[2] < 0.6


def test_wrong_density_is_rejected_and_visible():
    """uniform sampling that reports the cosine density, as a plugin bug would."""
    real = vr_path.direction_pdf

    def wrong_pdf(strategy, bsdf, ctx, si, wo, active=True):
        return real("cosine" if strategy == "uniform" else strategy, bsdf, ctx, si, wo, active)

    fake = types.SimpleNamespace(sample_direction=vr_path.sample_direction,
                                 direction_pdf=wrong_pdf)
    s = spec("phong n=1", "uniform", 0.0)
    bad, good = warps.compute(s, path_module=fake), warps.compute(s)
    assert bad["p_value"] < 1e-6 and good["p_value"] > 1e-4

    def z(panel):
        return (panel["histogram"] - panel["expected"]) / np.sqrt(np.maximum(panel["expected"], 1))
    saturated = np.mean(np.abs(z(bad)) >= figures.Z_RANGE)
    assert bad["max_z"] > 20 and good["max_z"] < 7
    assert saturated > 0.05 and np.mean(np.abs(z(good)) >= figures.Z_RANGE) < 1e-3
    tile = figures.panel_tiles(bad)[3]                              # the difference tile drawn
    white = np.all(np.abs(tile - tile[tile.shape[0] // 2, 0]) < 0.05, axis=-1)
    assert tile.std() > 0.1 and np.mean(~white) > 0.2


class Recorder(mi.SamplingIntegrator):
    """Records what the sampler gives a render: the camera ray (film position) and
    every value the integrator draws, in points.PATTERN's order after the camera."""

    def __init__(self, props):
        mi.SamplingIntegrator.__init__(self, props)
        self.values = []

    def sample(self, scene, sampler, ray, medium=None, active=True):
        values = [ray.o.x, ray.o.y]
        for kind, _ in points.PATTERN[1:]:
            if kind == "2d":
                p = sampler.next_2d(active)
                values += [p.x, p.y]
            else:
                values.append(sampler.next_1d(active))
        self.values = values
        return mi.Spectrum(0.0), mi.Bool(True), []


@pytest.mark.parametrize("name", points.samplers())
def test_points_are_what_a_render_draws(name):
    mi.register_integrator("lab_recorder", Recorder)
    width, height, spp, seed = 4, 2, 16, 5
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "lab_recorder"},
        "sensor": {"type": "orthographic",
                   "film": {"type": "hdrfilm", "width": width, "height": height,
                            "rfilter": {"type": "box"}},
                   "sampler": samplers.label_dict(name, spp, width, height)}})
    mi.render(scene, seed=seed)
    rec = scene.integrator().values
    dr.eval(rec)
    rec = np.stack([np.asarray(v, np.float64) for v in rec], axis=1)
    lab, count = points.draw(name, spp, seed, width, height)
    assert rec.shape[0] == width * height * count           # the count actually drawn
    rec = rec.reshape(width * height, count, -1)
    # dims 2...: exactly the values the integrator received, pixel = lane // spp
    np.testing.assert_array_equal(rec[..., 2:], lab[..., 2:])
    # dims 0, 1: the film position, from the camera ray (affine in the position)
    sensor = scene.sensors()[0]

    def origin(u, v):
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u, v), mi.Point2f(0.5))
        return np.array([ray.o.x[0], ray.o.y[0]])
    o0, ou, ov = origin(0, 0), origin(1, 0), origin(0, 1)
    m = np.stack([ou - o0, ov - o0], axis=1)
    film = np.linalg.solve(m, (rec[..., :2] - o0).reshape(-1, 2).T).T.reshape(rec.shape[:2] + (2,))
    film *= [width, height]
    pixel = np.arange(width * height)
    film -= np.stack([pixel % width, pixel // width], axis=1)[:, None, :]
    np.testing.assert_allclose(film, lab[..., :2], atol=2e-4)


@pytest.mark.parametrize("randomization", ["none", "permute_digits", "owen"])
def test_halton_point_sets_are_the_halton_points(randomization):
    """The lab's halton point sets are the Halton points of their definition (the numpy
    oracle of tests/_qmc_oracle.py), not merely what the sampler gives: every dimension
    of points.PATTERN, sample index = position in the pixel's set, the pixel's scramble
    seed from the render seed."""
    width, height, spp, seed = 4, 2, 16, 5
    pts, count = points.draw(f"halton:{randomization}", spp, seed, width, height)
    assert count == spp and pts.shape == (width * height, spp, len(points.dimensions()))
    lanes = width * height * spp
    for k in range(pts.shape[-1]):
        expected = oracle.sampler_values(k, lanes, spp, seed, randomization)
        np.testing.assert_allclose(pts[..., k].ravel(), expected, rtol=0,
                                   atol=oracle.TOLERANCE, err_msg=f"dimension {k}")


def read_header(path):
    with open(path, newline="") as f:
        return next(csv.reader(f))


def test_quick_run_writes_section_and_resumes(tmp_path, monkeypatch):
    from experiments.lib.studies.lab import config, study
    out = str(tmp_path / "out")
    study.STUDY.main(["--quick", "--out", out])
    section = json.load(open(os.path.join(out, "lab", "section.json")))
    assert section["order"] == study.ORDER and section["name"] == "lab"
    kinds = {b["kind"] for b in section["blocks"]}
    assert {"text", "image", "table"} <= kinds
    for stem, cols in [("warps", {"p_value", "rel_variance", "strategy", "bsdf"}),
                       ("p_values", {"p_value bsdf", "rel_variance uniform"}),
                       ("discrepancy", {"discrepancy_cd", "sampler", "pair", "count"}),
                       ("discrepancy_64", {"(0,1)", "(30,31)"}),
                       ("mass_albedo", {"mass / share drawn", "E[w] / albedo", "panel"})]:
        assert cols <= set(read_header(os.path.join(out, "lab", stem + ".csv"))), stem
    with open(os.path.join(out, "lab", "warps.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    # one row per quick BSDF and every strategy registered in this process (a test may have
    # registered one of its own: the lab picks it up like the built-in four)
    assert len(rows) == 2 * len(config.QUICK.strategy_names()) >= 2 * 4
    assert all(0 <= float(r["p_value"]) <= 1 for r in rows)
    for block in section["blocks"]:
        if block["kind"] == "image":
            assert os.path.isfile(os.path.join(out, block["src"]))
    # the screen-space error images: every default label at 4 spp, rendered by the lab
    with open(os.path.join(out, "lab", "screen.csv"), newline="") as f:
        screen = list(csv.DictReader(f))
    assert [(r["sampler"], r["spp requested"]) for r in screen] == [
        (s, "4") for s in plan.default_screen_labels()]
    assert "made by the lab" in section["settings"]["screen-space error"]
    # a rerun computes nothing: every panel and point set comes from the cache, every
    # render from the store
    monkeypatch.setattr(warps, "compute", lambda *a, **k: pytest.fail("panel recomputed"))
    monkeypatch.setattr(points, "compute", lambda *a, **k: pytest.fail("point set recomputed"))
    monkeypatch.setattr(execute, "run_job", lambda *a, **k: pytest.fail("render made again"))
    study.STUDY.main(["--quick", "--out", out])
    assert os.path.isfile(os.path.join(out, "index.html"))
    section = json.load(open(os.path.join(out, "lab", "section.json")))
    assert "found in the job store" in section["settings"]["screen-space error"]


def test_bad_input_is_one_line_exit_2(tmp_path, capsys):
    from experiments.lib.studies.lab import study
    with pytest.raises(SystemExit) as e:
        study.STUDY.parse_args(["--samples", "0", "--out", str(tmp_path)])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--samples" in err


def test_dimension_meaning():
    assert points.describe_pair(0, 1).startswith("one next_2d: camera")
    assert points.describe_pair(2, 3).startswith("one next_2d: emitter")
    assert points.describe_pair(1, 2).startswith("two calls")
    assert len(points.dimensions()) >= 32
    assert points.random_expectation(64) == pytest.approx(
        np.mean([points.centered_discrepancy(np.random.default_rng(i).random((64, 2)))
                 for i in range(400)]), rel=0.1)
    assert math.isclose(warps.significance(1), 0.01)


def test_run_all_runs_the_lab(tmp_path, monkeypatch):
    """run_all --lab quick: the lab's section is in the report (the other studies stubbed)."""
    import dataclasses

    from experiments import run_all
    from experiments.lib import studies
    for spec in studies.ordered():
        if spec.name != "lab":
            monkeypatch.setitem(studies._REGISTRY, spec.name,
                                dataclasses.replace(spec, run=lambda args: None))
    out = tmp_path / "r"
    run_all.main(["--lab", "quick", "--samplers", "off", "--stability", "off", "--seed", "4",
                  "--out", str(out)])
    section = json.load(open(out / "lab" / "section.json"))
    assert section["settings"]["seed"] == 4 and section["settings"]["quick"] is True
    assert 'id="lab"' in (out / "index.html").read_text()
    assert run_all.build_parser().parse_args(["--lab", "off"]).study_mode_lab == "off"


def test_help_lists_the_usual_options():
    import subprocess
    import sys
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    proc = subprocess.run([sys.executable, "-m", "experiments.lab", "--help"], cwd=root,
                          capture_output=True, text=True)
    assert proc.returncode == 0
    for option in ("--out", "--variant", "--seed", "--samples", "--quick"):
        assert option in proc.stdout
