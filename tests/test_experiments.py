"""Tests of the experiment suite (experiments/): metrics, accumulation, resume,
reference cache, scene loading, argument errors, report, and tiny end-to-end runs."""
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, scene_path

from experiments import convergence, run_all, writeup
from experiments.lib import metrics, report, store
from experiments.lib import methods as M
from experiments.lib import render as R

PYTHON = sys.executable


# ------------------------------------------------------------------ metrics

def test_metrics_against_hand_computed_values():
    ref = np.zeros((1, 2, 3))
    ref[0, 1] = 1.0
    img = ref.copy()
    img[0, 0] = [1.0, 0.0, 0.0]          # error 1 in one of 6 values
    img[0, 1] = [1.0, 1.0, 3.0]          # error 2 in another
    assert metrics.mse(img, ref) == pytest.approx((1 + 4) / 6)
    assert metrics.rmse(img, ref) == pytest.approx(math.sqrt(5 / 6))
    # relMSE: 1 / (0 + 0.01) and 4 / (1 + 0.01), averaged over 6 values
    assert metrics.relmse(img, ref) == pytest.approx((1 / 0.01 + 4 / 1.01) / 6)
    assert metrics.efficiency(0.5, 4.0) == pytest.approx(0.5)
    assert metrics.loglog_slope([1, 2, 4, 8], [3.0, 1.5, 0.75, 0.375]) == pytest.approx(-1.0)
    assert metrics.loglog_slope([1, 10, 100], [1, 100, 10000]) == pytest.approx(2.0)


def test_bias_check_against_hand_computed_values():
    a = np.array([[[1.0, 2.0, 0.0], [3.0, 2.0, 0.0]]])
    b = np.array([[[1.0, 1.0, 0.0], [1.0, 2.0, 1.0]]])
    var = np.full(a.shape, 0.25)             # var_a + var_b = 0.5 per value
    check = metrics.bias_check(a, var, b, var)
    assert check["mean_diff"] == pytest.approx([1.0, 0.5, -0.5])
    # CI half width: z * sqrt(2 pixels * 0.5) / 2 pixels
    assert check["ci_half_width"] == pytest.approx([metrics.Z99 * 1.0 / 2] * 3)
    # |z| = |diff| / sqrt(0.5): 0, 2.83 | 1.41, 0 | 0, 1.41 -> 5 of 6 below 2.576
    assert check["pass_fraction"] == pytest.approx(5 / 6)
    assert check["pass_fraction_per_channel"] == pytest.approx([0.5, 1.0, 1.0])
    assert check["ci_contains_zero"] == [True, True, True]


# ------------------------------------------------------------- accumulation

def test_accumulator_is_the_weighted_average_of_pass_images():
    rng = np.random.default_rng(1)
    passes = [(rng.random((3, 4, 3)), k) for k in (1, 1, 2, 4)]
    acc = R.Accumulator.empty(3, 4)
    for image, k in passes:
        acc.add(image, k, 0.5)
    expected = sum(im * k for im, k in passes) / 8
    np.testing.assert_allclose(acc.mean, expected, rtol=1e-14)
    assert (acc.spp, acc.passes, acc.seconds) == (8, 4, 2.0)
    # equal passes: variance of the mean = sample variance / passes
    equal = R.Accumulator.empty(3, 4)
    images = [rng.random((3, 4, 3)) for _ in range(5)]
    for image in images:
        equal.add(image, 2)
    np.testing.assert_allclose(equal.variance_of_mean(),
                               np.var(images, axis=0, ddof=1) / 5, rtol=1e-9)


def _job(tmp_path, name="uniform", width=16, height=8, **options):
    info = M.read_scene(scene_path("cbox.xml"))
    return R.method_job(str(tmp_path), "t", info, M.parse_method(name), width, height,
                        "llvm_ad_rgb", 7, **options)


@pytest.fixture
def count_passes(monkeypatch):
    """Record every pass rendered (spp, image) through render_pass."""
    calls = []
    real = R.render_pass

    def counting(*args, **kwargs):
        image, seconds = real(*args, **kwargs)
        calls.append((args[2], image))
        return image, seconds
    monkeypatch.setattr(R, "render_pass", counting)
    return calls


def test_progressive_render_equals_average_of_its_passes(tmp_path, count_passes):
    job = _job(tmp_path, max_pass_spp=2)
    acc = R.run_progressive(job, [1, 2, 4, 8])
    passes = count_passes[1:]                       # the first call is the warm-up
    assert [k for k, _ in passes] == [1, 1, 2, 2, 2]
    expected = sum(k * im for k, im in passes) / 8
    np.testing.assert_allclose(acc.mean, expected, rtol=1e-12)
    assert [c["spp"] for c in job.checkpoints] == [1, 2, 4, 8]
    saved = store.read_exr(os.path.join(job.directory, job.checkpoints[-1]["exr"]))
    np.testing.assert_allclose(saved, expected, rtol=1e-6, atol=1e-7)
    assert all(os.path.exists(os.path.join(job.directory, c["png"])) for c in job.checkpoints)
    times = [c["seconds"] for c in job.checkpoints]
    assert times == sorted(times) and times[0] > 0


def test_halton_passes_continue_one_sequence(tmp_path, count_passes):
    if not M.plugin_available("halton"):
        pytest.skip("halton sampler not installed")
    a = R.run_progressive(_job(tmp_path / "a", "bsdf+halton"), [1, 2, 4])
    b = R.run_progressive(_job(tmp_path / "b", "bsdf+halton", max_pass_spp=4), [4])
    np.testing.assert_allclose(a.mean, b.mean, atol=1e-5)


def test_resume_skips_finished_work_and_reproduces_results(tmp_path, count_passes):
    full = R.run_progressive(_job(tmp_path / "once"), [1, 2, 4, 8])
    # the same command again: nothing rendered, same checkpoints
    count_passes.clear()
    job = _job(tmp_path / "once")
    again = R.run_progressive(job, [1, 2, 4, 8])
    assert count_passes == []
    np.testing.assert_array_equal(again.mean, full.mean)
    # a run stopped after 2 spp, then resumed: only the missing passes are rendered
    R.run_progressive(_job(tmp_path / "resumed"), [1, 2])
    count_passes.clear()
    resumed = R.run_progressive(_job(tmp_path / "resumed"), [1, 2, 4, 8])
    assert [k for k, _ in count_passes[1:]] == [2, 4]
    np.testing.assert_allclose(resumed.mean, full.mean, rtol=1e-12)
    assert resumed.passes == full.passes


def test_interrupted_render_keeps_files_and_resumes(tmp_path, monkeypatch):
    full = R.run_progressive(_job(tmp_path / "once"), [1, 2, 4])
    real, calls = R.render_pass, []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 4:                 # warm-up, 1, 1, then Ctrl-C in the 2-spp pass
            raise KeyboardInterrupt
        return real(*args, **kwargs)
    monkeypatch.setattr(R, "render_pass", interrupted)
    with pytest.raises(KeyboardInterrupt):
        R.run_progressive(_job(tmp_path / "cut"), [1, 2, 4])
    files = sorted(os.listdir(tmp_path / "cut" / "t" / "uniform"))
    assert not [f for f in files if f.startswith(".tmp")]
    assert "spp00002.exr" in files and "spp00004.exr" not in files
    monkeypatch.setattr(R, "render_pass", real)
    job = _job(tmp_path / "cut")
    resumed = R.run_progressive(job, [1, 2, 4])
    np.testing.assert_allclose(resumed.mean, full.mean, rtol=1e-12)
    assert [c["spp"] for c in job.checkpoints] == [1, 2, 4]


def test_changed_settings_start_over(tmp_path, count_passes):
    R.run_progressive(_job(tmp_path), [2])
    count_passes.clear()
    R.run_progressive(_job(tmp_path, name="uniform", max_pass_spp=1), [2])
    assert [k for k, _ in count_passes[1:]] == [1, 1]


def test_reference_is_cached_and_remade_when_settings_change(tmp_path, count_passes):
    info = M.read_scene(scene_path("cbox.xml"))
    ref, meta = R.reference(str(tmp_path), info, 16, 8, 4, "path", "llvm_ad_rgb")
    assert count_passes and meta["settings"]["spp"] == 4
    count_passes.clear()
    again, _ = R.reference(str(tmp_path), info, 16, 8, 4, "path", "llvm_ad_rgb")
    assert count_passes == []
    np.testing.assert_allclose(again, ref, rtol=1e-6)
    R.reference(str(tmp_path), info, 16, 8, 8, "path", "llvm_ad_rgb")
    assert count_passes
    assert len([f for f in os.listdir(tmp_path / "cache") if f.endswith(".exr")]) == 2


# ------------------------------------------------------------- scenes, methods

def test_method_names():
    assert M.parse_method("cosine") == M.Method("cosine", "cosine", "independent")
    assert M.parse_method("uniform+halton").sampler_params == (("randomization", "none"),)
    assert M.parse_method("bsdf+halton").sampler_params == ()
    assert M.parse_method("bsdf+halton:owen").sampler_params == (("randomization", "owen"),)
    for bad in ("phong", "bsdf+sobol", "cosine:owen", "bsdf+halton:bogus"):
        with pytest.raises(ValueError, match="unknown method"):
            M.parse_method(bad)


def test_any_scene_loads_with_the_methods_integrator_and_resolution(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "light.xml").write_text(
        '<scene version="3.0.0"><emitter type="constant"/></scene>')
    scene = tmp_path / "user.xml"
    scene.write_text("""<scene version="3.0.0">
      <integrator type="path"><integer name="max_depth" value="5"/></integrator>
      <sensor type="perspective"><sampler type="stratified"/>
        <film type="hdrfilm"><integer name="width" value="40"/></film></sensor>
      <include filename="sub/light.xml"/>
      <shape type="sphere"><bsdf type="diffuse"/></shape></scene>""")
    info = M.read_scene(str(scene))
    assert (info.width, info.max_depth) == (40, 5)
    loaded = M.load_method_scene(info, M.parse_method("cosine"), 12, 6)
    assert "strategy=cosine, max_depth=5" in str(loaded.integrator())
    assert list(loaded.sensors()[0].film().size()) == [12, 6]
    assert "Independent" in str(loaded.sensors()[0].sampler())


# ------------------------------------------------------------ argument errors

BAD_ARGS = [
    (["--scene", "nope.xml"], "scene file 'nope.xml' does not exist"),
    (["--methods", "uniform,phong"], "unknown method 'phong'"),
    (["--resolution", "256by128"], "invalid resolution '256by128'"),
    (["--resolution", "0x10"], "invalid resolution '0x10'"),
    (["--spp", "-3"], "invalid value '-3'"),
    (["--out", "/proc/forbidden"], "--out '/proc/forbidden' is not writable"),
    (["--variant", "scalar_rgb"], "variant 'scalar_rgb' is not supported"),
    (["--variant", "llvm_bogus"], "unknown variant 'llvm_bogus'"),
]


@pytest.mark.parametrize("argv, message", BAD_ARGS)
def test_bad_arguments_exit_2_with_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        convergence.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert os.listdir(tmp_path) == []                      # nothing written


def test_bad_argument_in_a_real_process_has_no_traceback(tmp_path):
    proc = subprocess.run([PYTHON, "-m", "experiments.writeup", "--methods", "bogus",
                           "--out", str(tmp_path / "r")], cwd=ROOT, capture_output=True,
                          text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert "Traceback" not in proc.stderr and not (tmp_path / "r").exists()


@pytest.mark.parametrize("module", ["convergence", "writeup", "run_all"])
def test_help(module):
    proc = subprocess.run([PYTHON, "-m", f"experiments.{module}", "--help"], cwd=ROOT,
                          capture_output=True, text=True)
    assert proc.returncode == 0
    for option in ("--scene", "--resolution", "--methods", "--variant", "--seed", "--out"):
        assert option in proc.stdout


# ----------------------------------------------------------------- end to end

TINY = ["--resolution", "16x8", "--reference-spp", "8"]


def _report_links(out):
    page = (out / "index.html").read_text()
    return page, set(re.findall(r'href="([^"#]+)"', page))


def test_convergence_end_to_end(tmp_path):
    out = tmp_path / "r"
    convergence.main(TINY + ["--spp", "4", "--time-budget", "0.02", "--out", str(out),
                             "--methods", "uniform,cosine,bsdf"])
    rows = (out / "convergence" / "errors.csv").read_text().splitlines()
    assert len(rows) == 1 + 3 * 3                    # header + 3 methods x (1, 2, 4 spp)
    eff = (out / "convergence" / "efficiency.md").read_text()
    assert "| uniform | 4 |" in eff and "1.00" in eff
    for name in ("sequences.png", "error_mse.png", "error_relmse.png", "equal_time.png"):
        assert (out / "convergence" / name).stat().st_size > 0
    page, links = _report_links(out)
    assert "Convergence" in page and "mitsuba" in page and "libLLVM" in page


def test_writeup_end_to_end_with_full(tmp_path):
    out = tmp_path / "r"
    writeup.main(TINY + ["--short-spp", "2", "--halton-spp", "3", "--full", "--full-spp", "4",
                         "--full-resolution", "8x4", "--out", str(out)])
    rmse = (out / "writeup" / "rmse.md").read_text()
    assert "cosine vs uniform" in rmse and "bsdf vs uniform" in rmse
    bias = (out / "writeup" / "bias_full.md").read_text()
    assert "cosine − uniform" in bias
    assert (out / "writeup" / "bias_cosine_vs_uniform_z.png").exists()


def test_run_all_report_lists_every_produced_file_and_reruns_resume(tmp_path, count_passes):
    out = tmp_path / "r"
    argv = TINY + ["--spp", "2", "--time-budget", "0.02", "--short-spp", "2",
                   "--halton-spp", "2", "--methods", "uniform,cosine,bsdf", "--out", str(out),
                   "--stability", "quick"]
    run_all.main(argv)
    assert count_passes
    errors = (out / "convergence" / "errors.csv").read_text()
    rmse = (out / "writeup" / "rmse.csv").read_text()
    count_passes.clear()
    run_all.main(argv)                                  # the same command again
    assert count_passes == []                           # nothing rendered
    assert (out / "convergence" / "errors.csv").read_text() == errors
    assert (out / "writeup" / "rmse.csv").read_text() == rmse
    files = report.produced_files(str(out))
    page, links = _report_links(out)
    assert files and set(files) <= links
    for f in links:
        assert (out / f).exists(), f
    sections = [s["name"] for s in report.read_sections(str(out))]
    assert sections == ["convergence", "writeup", "stability", "run_all"]
