"""The stability sweeps (issue #5): their measurements, and the script end to end.

Statistical checks state their margin: sample means are compared within 5
standard errors (a false failure has probability < 1e-6 per check), and the
zero correlation of independent noise within 5 / sqrt(n).
"""
import csv
import json
import math
import os
import xml.etree.ElementTree as ET

import mitsuba as mi
import numpy as np
import pytest

from _paths import scene_path
from experiments import run_all
from experiments.lib.studies import stability
from experiments.lib import methods as M
from experiments.lib import metrics
from experiments.lib.plan import job_name
from experiments.lib import scenes as SC
from experiments.lib import scene_probes as SP
from experiments.lib import sweeps as SW
from integrators.choices import STRATEGIES

CBOX = scene_path("cbox.xml")


def phong(kd, ks, n):
    return mi.load_dict({"type": "phong", "diffuse_reflectance": kd,
                         "specular_reflectance": ks, "exponent": n})


# ------------------------------------------------------------ scene variants

def test_scene_variant_changes_only_the_given_defaults(tmp_path):
    info = SC.read_scene(CBOX)
    v = SC.scene_variant(info, str(tmp_path), "e", {"exponent": 1234.0, "light_size": 0.25})
    defaults = SC.scene_defaults(v.path)
    original = SC.scene_defaults(CBOX)
    assert float(defaults["exponent"]) == 1234.0 and float(defaults["light_size"]) == 0.25
    assert {k: d for k, d in defaults.items() if k not in ("exponent", "light_size")} == \
        {k: d for k, d in original.items() if k not in ("exponent", "light_size")}
    assert v.depth == info.depth and v.sha256 != info.sha256
    scene = SC.load_scene(v.path, 8, 4, M.parse_method("bsdf"))
    exps = [float(p["exponent"][0]) for s in scene.shapes()
            if type(s.bsdf()).__name__ == "PhongBSDF" for p in [mi.traverse(s.bsdf())]]
    assert exps == [1234.0]
    with pytest.raises(KeyError, match="roughness"):
        SC.scene_variant(info, str(tmp_path), "x", {"roughness": 0.1})


def test_phong_mask_is_the_glossy_sphere():
    mask = SP.phong_mask(SP.probe_scene(CBOX, 64, 32))
    # the glossy sphere is right of centre, in the lower half; nothing else is Phong
    ys, xs = np.nonzero(mask)
    assert 20 < mask.sum() < 0.25 * mask.size
    assert xs.min() >= 32 and ys.mean() > 16


# ------------------------------------------------------------ measurements

def test_outliers_counts_planted_nan_inf_and_fireflies_but_not_highlights():
    rng = np.random.default_rng(0)
    ref = np.full((32, 64, 3), 0.5)
    ref[4:8, 4:8] = 200.0                              # a correct, very bright highlight
    image = ref + rng.normal(0, 0.01, ref.shape)       # small noise everywhere
    image[20, 30] = np.nan
    image[21, 31, 1] = np.inf
    image[10, 40] = 50.0                               # fireflies: errors far beyond the MAD
    image[11, 50] = 9.0
    o = metrics.outliers(image, ref)
    assert o["nonfinite"] == 2
    assert o["fireflies"] == 2
    assert o["max"] == pytest.approx(image[4:8, 4:8].max())


def test_neighbour_correlation_of_independent_and_shared_noise():
    rng = np.random.default_rng(1)
    ref = np.ones((64, 128, 3))
    independent = ref + rng.normal(0, 0.1, ref.shape)
    n = 64 * 127
    assert abs(metrics.neighbour_correlation(independent, ref)) < 5 / math.sqrt(n)
    row = rng.normal(0, 0.1, (64, 1, 1))               # the same error along each row
    assert metrics.neighbour_correlation(ref + row, ref) > 0.999


def test_lambertian_is_sampled_perfectly_and_lobe_sampling_wastes_samples_at_grazing():
    diffuse = phong(0.5, 0.0, 10.0)
    st = SP.direction_sampling_stats(diffuse, 1.0, "bsdf", 4096)
    assert st["wasted"] == 0 and st["relvar"] < 1e-10 and st["albedo"] == pytest.approx(0.5)

    glossy = phong(0.0, 0.9, 1000.0)
    n = 2 ** 14
    normal = SP.direction_sampling_stats(glossy, 1.0, "bsdf", n)
    steep = SP.direction_sampling_stats(glossy, math.cos(math.radians(60)), "bsdf", n)
    grazing = SP.direction_sampling_stats(glossy, math.cos(math.radians(89)), "bsdf", n)
    assert normal["wasted"] == 0
    # binomial standard error <= 0.5 / sqrt(n) = 0.004: margins of > 5 of them
    assert grazing["wasted"] > steep["wasted"] + 0.1
    assert grazing["relvar"] > 10 * max(normal["relvar"], 1e-3)
    for s in (normal, steep, grazing):
        assert s["nonfinite"] == 0


@pytest.mark.parametrize("cos_i", [1.0, 0.5, 0.1])
def test_strategies_estimate_the_same_albedo(cos_i):
    """Unbiased: every vr_path strategy agrees with bsdf within 5 combined standard errors."""
    bsdf = phong(0.3, 0.5, 20.0)
    n = 2 ** 16
    stats = {s: SP.direction_sampling_stats(bsdf, cos_i, s, n, seed=i)
             for i, s in enumerate(STRATEGIES)}
    se = {s: st["albedo"] * math.sqrt(st["relvar"] / n) for s, st in stats.items()}
    for s in STRATEGIES:
        diff = abs(stats[s]["albedo"] - stats["bsdf"]["albedo"])
        assert diff < 5 * math.hypot(se[s], se["bsdf"]) + 1e-12, (s, stats)
        assert stats[s]["nonfinite"] == 0


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_direction_sampling_stats_measure_the_plugins_own_sample_direction(strategy):
    """The statistics are those of integrators.path.sample_direction's weights (the function
    vr_path calls), not of a copy of the strategies."""
    import drjit as dr
    from integrators.path import sample_direction
    bsdf = phong(0.2, 0.6, 200.0)
    n, cos_i, seed = 4096, math.cos(math.radians(70)), 3
    st = SP.direction_sampling_stats(bsdf, cos_i, strategy, n, seed)
    u = np.random.default_rng(seed).random((3, n))
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(math.sqrt(1 - cos_i ** 2), 0.0, cos_i)
    si.uv = mi.Point2f(0.5, 0.5)
    ds = sample_direction(strategy, bsdf, mi.BSDFContext(), si, mi.Float(u[0]),
                          mi.Point2f(u[1], u[2]))
    w = metrics.luminance(np.array(ds.weight).T)
    assert st["albedo"] == pytest.approx(w.mean(), rel=1e-12)
    assert st["wasted"] == np.mean(w == 0)
    assert st["relvar"] == pytest.approx(w.var() / w.mean() ** 2, rel=1e-9)


def test_mis_wastes_fewer_samples_than_lobe_sampling_at_grazing():
    """mis draws a quarter of its samples from the cosine lobe, which never falls below the
    horizon: at 89 degrees it wastes about 3/4 of bsdf's share (binomial margins > 5 SE)."""
    glossy = phong(0.1, 0.8, 1000.0)
    n, c = 2 ** 14, math.cos(math.radians(89))
    lobe = SP.direction_sampling_stats(glossy, c, "bsdf", n)
    mis = SP.direction_sampling_stats(glossy, c, "mis", n, seed=1)
    assert lobe["wasted"] > 0.1
    assert mis["wasted"] == pytest.approx(0.75 * lobe["wasted"], abs=5 * 0.5 / math.sqrt(n))


def test_unknown_strategy_raises_and_names_the_valid_ones():
    with pytest.raises(ValueError) as exc:
        SP.direction_sampling_stats(phong(0.5, 0.0, 1.0), 1.0, "bogus", 16)
    for s in STRATEGIES:
        assert s in str(exc.value)


def test_first_where_and_ratio():
    assert metrics.first_where([1, 10, 100], [False, True, True]) == 10
    assert metrics.first_where([1, 10], [False, False]) is None
    assert metrics.ratio(1.0, 0.0) == math.inf and metrics.ratio(3.0, 2.0) == 1.5


# ----------------------------------------------------------------- plans

def planned(ctx, declaration):
    """{cell: [per repeat: [jobs]]} of a sweep's one budget, as the engine plans it."""
    (budget,) = declaration.budgets
    return ctx.engine.jobs(declaration, budget)


def test_every_sweep_declares_cells_of_one_shape_with_independent_repeats(tmp_path):
    args = stability.parse(["--quick", "--repeats", "3", "--out", str(tmp_path / "r")])
    ctx = SW.Context(stability.settings_from(args))
    declarations, skipped = stability.declare(ctx, SW.SWEEPS)
    assert set(declarations) == set(SW.SWEEPS) and not skipped
    assert declarations["grazing"] is None                      # measured, not rendered
    for name in ("exponent", "light", "halton"):
        decl = declarations[name]
        assert decl.repeats == 3 and len(decl.sweep.values) >= 2, name
        for cell, runs in planned(ctx, decl).items():
            method = M.parse_method(cell.method)
            # one run per repeat (a deterministic method: one run stands for every repeat)
            assert len(runs) == (1 if method.deterministic else 3), (name, cell)
            if not method.deterministic:
                seeds = [run[0].seed for run in runs]
                assert len(set(seeds)) == 3, (name, cell)        # independent repeats
            assert all(j.timing_group == f"stability/{name}" for run in runs for j in run)
    jobs = planned(ctx, declarations["exponent"])
    bsdf = next(runs for cell, runs in jobs.items() if cell.method == "bsdf" and cell.point == 1)
    # repeat 0 keeps the single run's key prefix (results stored before repeats are reused)
    assert bsdf[0][0].key.startswith("stability/exponent/1/bsdf-")
    assert bsdf[1][0].key.startswith("stability/exponent/1/bsdf/r1-")
    halton = planned(ctx, declarations["halton"])
    assert {run[0].key.split("/spp")[0] for runs in halton.values() for run in runs[:1]} >= \
        {job_name("stability/halton/depth2/uniform"),
         job_name("stability/halton/depth8/uniform+halton:none")}
    single = stability.parse(["--quick", "--repeats", "1", "--out", str(tmp_path / "r")])
    one_ctx = SW.Context(stability.settings_from(single))
    one = planned(one_ctx, stability.declare(one_ctx, ["exponent"])[0]["exponent"])
    (job,), = next(runs for cell, runs in one.items() if cell.method == "bsdf" and cell.point == 1)
    assert job.spp == single.spp == 4                   # one repeat: the whole --spp
    assert job.seed == bsdf[0][0].seed                  # the same seed as repeat 0
    assert job.key.rsplit("-", 1)[0] == bsdf[0][0].key.rsplit("-", 1)[0]
    # the --spp budget is split over the repeats (the same total cost for any R)
    assert bsdf[0][0].spp == round(4 / 3) and ctx.spp == 1


# ----------------------------------------------------------------- end to end

def test_sweep_list_rejects_unknown_sweeps():
    with pytest.raises(SystemExit) as exc:
        stability.STUDY.main(["--sweeps", "exponent,bogus"])
    assert exc.value.code == 2


def test_stability_quick_end_to_end(tmp_path, capsys):
    out = tmp_path / "r"
    stability.STUDY.main(["--quick", "--resolution", "24x12", "--out", str(out)])
    settings = json.loads((out / "stability" / "section.json").read_text())["settings"]
    assert settings["resolution"] == "24x12" and settings["spp"] == 4     # quick, not 32
    section = json.loads((out / "stability" / "section.json").read_text())
    assert section["settings"]["repeats"] == stability.REPEATS >= 2
    images = [b["src"] for b in section["blocks"] if b["kind"] == "image"]
    assert {"stability/exponent.png", "stability/light.png", "stability/grazing.png",
            "stability/halton_crops.png"} <= set(images)
    for src in images:
        assert (out / src).stat().st_size > 0
    summary = json.loads((out / "stability" / "summary.json").read_text())
    notes = " ".join(summary["notes"])
    for start in ("Exponent sweep", "Light sweep", "Grazing", "Halton at max_depth",
                  "Outliers"):
        assert start in notes
    # no NaN/Inf from our plugins anywhere on the sweep grid
    assert summary["outliers"] and all(v["nonfinite"] == 0
                                       for v in summary["outliers"].values())
    assert "0 non-finite sample weights" in notes
    # the exponent sweep compares every vr_path strategy the plugin defines
    table = (out / "stability" / "exponent.csv").read_text()
    for strategy in M.strategies():
        assert f",{strategy}," in table
    if "mis" in M.strategies():
        assert "relMSE(mis) / min(relMSE(cosine), relMSE(bsdf))" in notes
    # every comparison carries its interval over the repeats: lo <= value <= hi
    for name, value in (("exponent", "relmse_phong"), ("exponent", "relmse_all"),
                        ("light", "relmse"), ("halton", "relmse"),
                        ("grazing", "efficiency_vs_normal")):
        rows = list(csv.DictReader(open(out / "stability" / f"{name}.csv")))
        assert rows, name
        for r in rows:
            assert int(r["repeats"]) == stability.REPEATS
            v, lo, hi = (float(r[value + k]) for k in ("", "_lo", "_hi"))
            assert lo <= v * (1 + 1e-9) and v <= hi * (1 + 1e-9), (name, r)
        md = (out / "stability" / f"{name}.md").read_text()
        assert f"{value}_lo" in md and f"{value}_hi" in md
    assert summary["repeats"] == stability.REPEATS
    relmse_rows = [r for r in summary["rows"] if "relmse" in r]
    assert {r["sweep"] for r in relmse_rows} == {"exponent", "light", "halton"}
    for r in relmse_rows:
        assert r["relmse_lo"] <= r["relmse"] * (1 + 1e-9) <= r["relmse_hi"] * (1 + 1e-9)
    # grazing measures every strategy the plugin defines (mis too)
    grazing = (out / "stability" / "grazing.csv").read_text()
    for strategy in STRATEGIES:
        assert f",{strategy}," in grazing
    # the store holds both repeats: repeat 0 under the single run's prefix, repeat 1 under /r1
    point = out / "store" / "stability" / "exponent" / "1"
    assert len(list(point.glob("bsdf-*.npz"))) == 1
    assert len(list((point / "bsdf").glob("r1-*.npz"))) == 1
    closing = [b["text"] for b in section["blocks"] if b["kind"] == "text"][-1]
    assert closing.startswith("Closing note")
    page = (out / "index.html").read_text()
    assert 'id="stability"' in page
    # the sweep points are plain scene files, loadable by Mitsuba
    for name in os.listdir(out / "stability" / "scenes"):
        ET.parse(out / "stability" / "scenes" / name)


def test_sweeps_are_skipped_with_a_sentence_on_a_scene_without_their_parameters(tmp_path):
    out = tmp_path / "r"
    stability.STUDY.main(["--quick", "--scene", "cornell_box", "--sweeps", "exponent,light,halton",
                    "--out", str(out)])
    section = json.loads((out / "stability" / "section.json").read_text())
    texts = " ".join(b["text"] for b in section["blocks"] if b["kind"] == "text")
    assert "Sweep 'exponent' skipped: the scene has no <default> parameter exponent" in texts
    assert "Sweep 'light' skipped" in texts and "Halton at max_depth 2" in texts


def test_adaptive_sweep_only_with_full_and_on_the_light_sweeps_cells(tmp_path):
    """--full (make full) adds the adaptive sweep; its plain methods are the light sweep's
    cells (one store entry for both), and each point compares adaptive with its twin."""
    assert "adaptive" not in stability.parse(["--out", str(tmp_path)]).sweeps
    assert "adaptive" in stability.parse(["--full", "--out", str(tmp_path)]).sweeps
    args = run_all.cli.parse_args(run_all.build_parser(), ["--full", "--out", str(tmp_path)])
    assert "--full" in run_all.sub_argv(args, stability.STUDY)
    out = tmp_path / "r"
    # 24 spp over 3 repeats: 8 per repeat, the adaptive sweep's least, so the light sweep's
    # plain renders are the adaptive sweep's
    stability.STUDY.main(["--quick", "--resolution", "16x8", "--spp", "24",
                          "--sweeps", "light,adaptive", "--out", str(out)])
    rows = list(csv.DictReader(open(out / "stability" / "adaptive.csv")))
    assert {r["method"] for r in rows} == {"bsdf", "bsdf + adaptive", "bsdf + NEE",
                                           "bsdf + NEE + adaptive"}
    assert len(rows) == 4 * len(stability.QUICK.light_sizes)
    for r in rows:
        v, lo, hi = (float(r["ratio_to_plain" if k == "" else f"ratio{k}"])
                     for k in ("", "_lo", "_hi"))
        assert lo <= v * (1 + 1e-9) and v <= hi * (1 + 1e-9), r
    # the plain methods at the adaptive sweep's samples are cells of the light sweep
    point = out / "store" / "stability" / "light" / "2"
    assert len(list(point.glob("bsdf_nee-*.npz"))) == 1              # rendered once
    assert len(list(point.glob("bsdf_nee_adaptive-*.npz"))) == 1
    notes = " ".join(json.loads((out / "stability" / "summary.json").read_text())["notes"])
    assert "Adaptive sweep, bsdf + adaptive against bsdf at equal samples" in notes


def test_adaptive_sweep_is_skipped_without_a_box_filter(tmp_path):
    """Per-pixel counts need each sample in its own pixel: on the stability scene with a
    Gaussian filter the sweep is skipped, and says why."""
    scene = tmp_path / "cbox_gaussian.xml"
    text = open(scene_path("cbox.xml")).read()
    assert '<rfilter type="box"/>' in text
    scene.write_text(text.replace('<rfilter type="box"/>', '<rfilter type="gaussian"/>'))
    out = tmp_path / "r"
    stability.STUDY.main(["--quick", "--scene", str(scene), "--sweeps", "adaptive",
                          "--out", str(out)])
    section = json.loads((out / "stability" / "section.json").read_text())
    texts = " ".join(b["text"] for b in section["blocks"] if b["kind"] == "text")
    assert "Sweep 'adaptive' skipped: adaptive sampling needs a box reconstruction filter" \
        in texts
