"""Tests of the experiment suite (experiments/): metrics, jobs and their store, resume,
reference cache, scene loading, argument errors, report, and tiny end-to-end runs.
The method grammar has its own file (test_methods.py), the sampler study too."""
import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, scene_path

from experiments import run_all
from experiments.lib import jobs as J
from experiments.lib import studies
from experiments.lib.studies import conclusion, convergence, writeup
from experiments.lib import execute as X
from experiments.lib import methods as M
from experiments.lib import clock, metrics, report, store
from experiments.lib import plan as P
from experiments.lib import samplers as S
from experiments.lib import scenes as SC
from experiments.lib.jobs import accumulate

PYTHON = sys.executable


# ------------------------------------------------------------------ metrics

def test_metrics_against_hand_computed_values():
    ref = np.zeros((1, 2, 3))
    ref[0, 1] = 2.0                      # not 1: ref and ref^2 must differ
    img = ref.copy()
    img[0, 0] = [1.0, 0.0, 0.0]          # error 1 in one of 6 values
    img[0, 1] = [2.0, 2.0, 4.0]          # error 2 in another
    assert metrics.mse(img, ref) == pytest.approx((1 + 4) / 6)
    assert metrics.rmse(img, ref) == pytest.approx(math.sqrt(5 / 6))
    # relMSE: 1 / (0^2 + 0.01) and 4 / (2^2 + 0.01), averaged over 6 values
    assert metrics.relmse(img, ref) == pytest.approx((1 / 0.01 + 4 / 4.01) / 6)
    mask = np.array([[False, True]])                 # only the second pixel: 4 / 4.01 over 3
    assert metrics.relmse(img, ref, mask) == pytest.approx(4 / 4.01 / 3)
    assert metrics.efficiency(0.5, 4.0) == pytest.approx(0.5)
    assert metrics.loglog_slope([1, 2, 4, 8], [3.0, 1.5, 0.75, 0.375]) == pytest.approx(-1.0)
    assert metrics.loglog_slope([1, 10, 100], [1, 100, 10000]) == pytest.approx(2.0)
    assert math.isnan(metrics.loglog_slope([4, 4, 4], [1.0, 0.5, 0.2]))   # one abscissa


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


def test_deterministic_check_passes_a_converging_sequence_and_fails_a_stuck_one():
    rng = np.random.default_rng(2)
    ref = rng.random((8, 16, 3))
    noise = rng.normal(0, 1, ref.shape)
    spps = [4, 8, 16]
    converging = [ref + noise / n for n in spps]              # error ~ 1/n: QMC-like
    check = metrics.deterministic_check(spps, converging, ref, np.zeros_like(ref))
    assert check["converges"] and check["slope"] == pytest.approx(-2.0)
    # negative control: a biased sequence whose error stays (plain Halton with a bug)
    stuck = [ref + 0.1 + noise / 1000 / n for n in spps]
    check = metrics.deterministic_check(spps, stuck, ref, np.zeros_like(ref))
    assert not check["converges"]
    assert check["mean_diff"][-1] == pytest.approx([0.1] * 3, abs=1e-3)


# ------------------------------------------------------------- accumulation

def test_accumulator_is_the_weighted_average_of_pass_images():
    rng = np.random.default_rng(1)
    passes = [(rng.random((3, 4, 3)), k) for k in (1, 1, 2, 4)]
    acc = J.Accumulator.empty(3, 4)
    for image, k in passes:
        acc.add(image, k, 0.5)
    expected = sum(im * k for im, k in passes) / 8
    np.testing.assert_allclose(acc.mean, expected, rtol=1e-14)
    assert (acc.spp, acc.passes, acc.cost) == (8, 4, 2.0)
    # equal passes: variance of the mean = sample variance / passes
    equal = J.Accumulator.empty(3, 4)
    images = [rng.random((3, 4, 3)) for _ in range(5)]
    for image in images:
        equal.add(image, 2)
    np.testing.assert_allclose(equal.variance_of_mean(),
                               np.var(images, axis=0, ddof=1) / 5, rtol=1e-9)


def _info():
    return SC.read_scene(scene_path("cbox.xml"))


def test_job_keys_change_with_everything_the_image_depends_on():
    """A job's key (its store entry) differs when any input of its image differs, and is
    the same for the same inputs; negative control: a key that forgets one field would
    let two different renders share a store entry (the first would be reused)."""
    import dataclasses
    info = _info()
    base = dict(prefix="t/key", info=info, method=M.parse_method("bsdf+halton"), width=16,
                height=8, spp=4, seed=3, depth=M.Depth(3, 2, False), variant="llvm_ad_rgb",
                sample_offset=0, pass_spp=0, sequence_spp=0)
    key = P.make_job(**base).key
    assert P.make_job(**base).key == key
    changes = dict(method=M.parse_method("bsdf+halton:none"), width=8, height=16, spp=5,
                   seed=4, depth=M.Depth(4, 2, False), variant="cuda_ad_rgb", sample_offset=4,
                   pass_spp=2, sequence_spp=8,
                   info=dataclasses.replace(info, sha256="0" * 64),
                   prefix="t/other")
    for field, value in changes.items():
        assert P.make_job(**{**base, field: value}).key != key, field
    for field in ("max_depth", "rr_depth", "hide_emitters"):
        depth = dataclasses.replace(base["depth"], **{field: None})
        assert P.make_job(**{**base, "depth": depth}).key != key, field
    moved = dataclasses.replace(info, path=info.path + ".copy.xml")
    assert P.make_job(**{**base, "info": moved}).key != key


def _ladder(name="uniform", targets=(1, 2, 4, 8), width=16, height=8, seed=7, **options):
    info = _info()
    return P.ladder(f"t/{name}", info, M.parse_method(name), width, height, targets, seed, info.depth,
                    "llvm_ad_rgb", **options)


@pytest.fixture
def count_jobs(monkeypatch):
    """Record every job rendered (job, result) through execute.run_job."""
    calls = []
    real = X.run_job

    def counting(job, variant):
        result = real(job, variant)
        calls.append((job, result))
        return result
    monkeypatch.setattr(X, "run_job", counting)
    return calls


def test_ladder_images_are_the_average_of_their_passes(tmp_path, count_jobs):
    st = store.JobStore(str(tmp_path))
    jobs = _ladder(pass_spp=2)
    X.execute(jobs, st, progress=False)
    assert [j.passes() for j in jobs] == [[1], [1], [2], [2, 2]]
    assert [r.passes for _, r in count_jobs] == [1, 1, 1, 2]
    assert all(clock.cost(r) > 0 and clock.wall(r) > 0 for _, r in count_jobs)
    accs = accumulate(st.results(jobs))
    assert [a.spp for a in accs] == [1, 2, 4, 8] and accs[-1].passes == 5
    expected = sum(r.spp * r.image.astype(float) for _, r in count_jobs) / 8
    np.testing.assert_allclose(accs[-1].mean, expected, rtol=1e-6)
    times = [a.cost for a in accs]
    assert times == sorted(times) and times[0] > 0
    # seeds come from the plan: every stretch of an independent ladder has its own
    assert len({j.seed for j in jobs}) == len(jobs)


CONTINUING = [n for n in S.names() if S.get(n).continues_sequence]


@pytest.mark.parametrize("sampler", CONTINUING)
def test_passes_of_a_continuing_sampler_continue_one_sequence(tmp_path, sampler):
    """A ladder of stretches is exactly one render of all their samples (halton, zsobol:
    the seed kept, the offset moved, and where the sampler needs it the whole length)."""
    assert {"halton", "zsobol"} <= set(CONTINUING)
    st = store.JobStore(str(tmp_path))
    stretched = _ladder(f"bsdf+{sampler}", (1, 2, 4))
    whole = _ladder(f"bsdf+{sampler}", (4,), pass_spp=4)
    assert [j.sample_offset for j in stretched] == [0, 1, 2]
    assert len({j.seed for j in stretched + whole}) == 1
    length = 4 if S.get(sampler).sequence_length else 0
    assert {j.sequence_spp for j in stretched + whole} == {length}
    X.execute(stretched + whole, st, progress=False)
    np.testing.assert_allclose(accumulate(st.results(stretched))[-1].mean,
                               accumulate(st.results(whole))[-1].mean, atol=1e-5)


@pytest.mark.parametrize("name", ["uniform", "path", "bsdf+nee+stratified", "cosine+ldsampler",
                                  "path+halton:owen"])
def test_resume_skips_finished_jobs_and_reproduces_results(name, tmp_path, count_jobs,
                                                          monkeypatch):
    """Our methods, Mitsuba's path and native samplers go through the same job renderer."""
    once = store.JobStore(str(tmp_path / "once"))
    jobs = _ladder(name, (1, 2, 4))
    X.execute(jobs, once, progress=False)
    full = accumulate(once.results(jobs))
    assert len(count_jobs) == 3
    count_jobs.clear()
    X.execute(jobs, once, progress=False)             # the same command again
    assert count_jobs == []
    # interrupted after the first job (Ctrl-C inside the second), then resumed
    cut = store.JobStore(str(tmp_path / "cut"))
    real, calls = X.run_job, []

    def interrupted(job, variant):
        calls.append(job)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(job, variant)
    monkeypatch.setattr(X, "run_job", interrupted)
    with pytest.raises(KeyboardInterrupt):
        X.execute(jobs, cut, progress=False)
    files = [f for _, _, names in os.walk(tmp_path / "cut") for f in names]
    assert len(files) == 1 and not [f for f in files if f.startswith(".tmp")]
    monkeypatch.setattr(X, "run_job", real)
    assert [j.key for j in X.pending(jobs, cut)] == [j.key for j in jobs[1:]]
    X.execute(jobs, cut, progress=False)
    resumed = accumulate(cut.results(jobs))
    for a, b in zip(resumed, full):
        assert a.spp == b.spp
        np.testing.assert_allclose(a.mean, b.mean, rtol=1e-6, atol=1e-7)


def test_native_samplers_count_the_samples_they_render(tmp_path):
    """orthogonal renders a prime squared (16 -> 25), ldsampler a power of two (1 -> 4)."""
    st = store.JobStore(str(tmp_path))
    jobs = {n: _ladder(n, (16,))[0] for n in ("bsdf+orthogonal", "bsdf+ldsampler")}
    jobs["ld1"] = _ladder("bsdf+ldsampler", (1,))[0]
    X.execute(list(jobs.values()), st, progress=False)
    assert [st.get(j.key).spp for j in jobs.values()] == [25, 16, 4]


def test_changed_settings_make_another_job():
    a, b = _ladder(targets=(2,))[0], _ladder(targets=(2,), pass_spp=1)[0]
    c = _ladder(targets=(2,), width=8)[0]
    assert len({a.key, b.key, c.key}) == 3
    assert a.key == _ladder(targets=(2,))[0].key          # stable


def test_a_job_refuses_a_scene_file_other_than_the_planned_one(tmp_path):
    """A worker that sees another file (or none) at the planned path stops with a clear
    error instead of rendering another scene; the planned file itself renders."""
    import dataclasses
    job = _ladder(targets=(1,))[0]
    assert X.run_job(job, "llvm_ad_rgb").spp == 1                      # the planned file
    with pytest.raises(ValueError, match=r"differs from the one the jobs were planned"):
        X.run_job(dataclasses.replace(job, scene_sha256="0" * 64), "llvm_ad_rgb")
    with pytest.raises(FileNotFoundError, match=r"not found on host"):
        X.run_job(dataclasses.replace(job, scene=str(tmp_path / "gone.xml")), "llvm_ad_rgb")


def test_jobs_are_plain_picklable_data():
    import pickle
    job = _ladder("bsdf+halton:owen", (1, 4))[1]
    assert pickle.loads(pickle.dumps(job)) == job
    assert job.sample_offset == 1 and job.spp == 3


# ------------------------------------------------------------- scenes, methods

def test_any_scene_keeps_its_integrator_settings_unless_overridden(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "light.xml").write_text(
        '<scene version="3.0.0"><emitter type="constant"/></scene>')
    scene = tmp_path / "user.xml"
    scene.write_text("""<scene version="3.0.0">
      <integrator type="path"><integer name="max_depth" value="5"/>
        <integer name="rr_depth" value="3"/><boolean name="hide_emitters" value="true"/>
      </integrator>
      <sensor type="perspective"><sampler type="stratified"/>
        <film type="hdrfilm"><integer name="width" value="40"/></film></sensor>
      <include filename="sub/light.xml"/>
      <shape type="sphere"><bsdf type="diffuse"/></shape></scene>""")
    info = SC.read_scene(str(scene))
    assert (info.width, info.depth) == (40, M.Depth(5, 3, True))
    loaded = SC.load_scene(info.path, 12, 6, M.parse_method("cosine"), info.depth)
    integrator = loaded.integrator()
    assert (integrator.strategy, integrator.max_depth, integrator.rr_depth,
            integrator.hide_emitters) == ("cosine", 5, 3, True)
    assert list(loaded.sensors()[0].film().size()) == [12, 6]
    assert "Independent" in str(loaded.sensors()[0].sampler())
    # --max-depth 2 replaces only max_depth; path keeps the scene's others too
    depth = SC.effective_depth(info, max_depth=2)
    assert depth == M.Depth(2, 3, True)
    path = SC.load_scene(info.path, 12, 6, M.parse_method("path+orthogonal"), depth)
    assert "max_depth = 2" in str(path.integrator())
    assert "Orthogonal" in str(path.sensors()[0].sampler())


def test_a_scene_without_integrator_gets_the_plugin_defaults_not_a_silent_8(tmp_path):
    scene = tmp_path / "bare.xml"
    scene.write_text('<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"/>'
                     '</sensor><shape type="sphere"/></scene>')
    info = SC.read_scene(str(scene))
    assert info.depth == M.Depth(None, None, None)
    loaded = SC.load_scene(info.path, 8, 4, M.parse_method("bsdf"), info.depth)
    assert loaded.integrator().max_depth == -1          # vr_path's own default


def test_cornell_box_as_xml_renders_like_mitsubas_dict(tmp_path):
    import mitsuba as mi
    path = SC.builtin_scene("cornell_box", str(tmp_path))
    info = SC.read_scene(path)
    assert (info.width, info.height, info.depth.max_depth) == (256, 256, 8)
    from_xml = SC.load_scene(path, 32, 32, M.parse_method("path"), info.depth)
    d = mi.cornell_box()
    d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = 32
    d["sensor"]["sampler"] = {"type": "independent"}
    from_dict = mi.load_dict(d)
    a = np.array(mi.render(from_xml, spp=4, seed=3))
    b = np.array(mi.render(from_dict, spp=4, seed=3))
    assert a.mean() > 0.05
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5)


# ------------------------------------------------------------ argument errors

BAD_ARGS = [
    (["--scene", "nope.xml"], "scene file 'nope.xml' does not exist"),
    (["--methods", "uniform,phong"], "unknown method 'phong'"),
    (["--max-depth", "-2"], "invalid value '-2'"),
    (["--rr-depth", "0"], "invalid value '0'"),
    (["--reference-method", "path+sobol"], "unknown method 'path+sobol'"),
    (["--scene", "cornell"], "scene file 'cornell' does not exist (or use a built-in scene"),
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
        convergence.STUDY.main(argv)
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


@pytest.mark.parametrize("module", ["convergence", "writeup", "samplers", "stability",
                                    "run_all"])
def test_help(module):
    proc = subprocess.run([PYTHON, "-m", f"experiments.{module}", "--help"], cwd=ROOT,
                          capture_output=True, text=True)
    assert proc.returncode == 0
    for option in ("--scene", "--resolution", "--methods", "--variant", "--seed", "--out",
                   "--max-depth", "--rr-depth"):
        assert option in proc.stdout


# ----------------------------------------------------------------- end to end

TINY = ["--resolution", "16x8", "--reference-spp", "8"]


def _report_links(out):
    page = (out / "index.html").read_text()
    return page, set(re.findall(r'href="([^"#]+)"', page))


def _csv(path) -> list[dict]:
    import csv
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


BOUNDS = "upper bounds (below the reference's noise)"


def _assert_intervals(rows, *names):
    """Every row's interval brackets its value: 0 < lo <= value <= hi; an error below the
    reference's own noise (named in the row's bounds column) is a bound: 0 = lo < value =
    hi, never NaN; a ratio that cannot be told is n/a."""
    for row in rows:
        for name in names:
            cells = [row[f"{name}{s}"] for s in ("_lo", "", "_hi")]
            if cells == ["n/a"] * 3:
                assert row[BOUNDS], (name, row)
                continue
            lo, value, hi = map(float, cells)
            if name in row.get(BOUNDS, "").split(", "):
                assert lo == 0 and value == hi >= 0, (name, row)
                continue
            assert 0 < lo <= value * (1 + 1e-9) and value <= hi * (1 + 1e-9), (name, row)


def _short_paragraphs(out, study):
    """No paragraph (text or caption) of the study's section is over 80 words."""
    blocks = json.loads((out / study / "section.json").read_text())["blocks"]
    assert conclusion.long_paragraphs(blocks) == []
    return blocks


def test_convergence_end_to_end(tmp_path):
    out = tmp_path / "r"
    convergence.STUDY.main(TINY + ["--spp", "4", "--time-budget", "0.02", "--out", str(out),
                             "--methods", "uniform,cosine,bsdf", "--repeats", "3"])
    errors = _csv(out / "convergence" / "errors.csv")
    assert [(r["method"], int(r["spp"])) for r in errors] == \
        [(m, n) for m in ("uniform", "cosine", "bsdf") for n in (1, 2, 4)]
    assert {r["repeats"] for r in errors} == {"3"}
    _assert_intervals(errors, "MSE", "relMSE")
    assert (out / "convergence" / "bsdf" / "spp00004.exr").exists()
    eff = {r["method"]: r for r in _csv(out / "convergence" / "efficiency.csv")}
    _assert_intervals(eff.values(), "MSE", "relMSE", "relative efficiency",
                      "equal-time relative efficiency")
    # the baseline against itself is exactly 1; the others follow from the table's own
    # expected relMSE and mean time: (relMSE_u T_u) / (relMSE_m T_m), in full precision
    # (summary.json: the CSV's three significant digits alone differ by up to 2.5%)
    assert eff["uniform"]["relative efficiency"] == "1"
    summary = json.loads((out / "convergence" / "summary.json").read_text())
    full = {r["method"]: r for r in summary["efficiency"]}
    u = full["uniform"]
    for m in ("cosine", "bsdf"):
        if eff[m]["relative efficiency"] == "n/a":
            assert "relMSE" in eff[m][BOUNDS]
            continue
        ratio = (u["relmse"] * u["seconds"]) / (full[m]["relmse"] * full[m]["seconds"])
        assert full[m]["relative_efficiency"] == pytest.approx(ratio, rel=1e-9)
        assert float(eff[m]["relative efficiency"]) == pytest.approx(ratio, rel=0.005)
    assert {r["method"] for r in summary["efficiency"]} == set(eff)
    assert all("relative_efficiency_lo" in r for r in summary["efficiency"])
    assert summary["efficiency_metric"] == "relMSE"
    # the conclusion: a short table, and at most three sentences made from its rows
    rows = _csv(out / "convergence" / "conclusion.csv")
    assert 1 <= len(rows) <= 4 and summary["conclusion"] == rows
    assert 1 <= len(summary["sentences"]) <= 3
    for sentence in summary["sentences"]:
        assert any(r["A vs B"].split(" vs ")[0] in sentence for r in rows)
    blocks = _short_paragraphs(out, "convergence")
    assert any("use relMSE" in b.get("text", "") for b in blocks)
    for name in ("sequences.png", "error_mse.png", "error_relmse.png", "equal_time.png"):
        assert (out / "convergence" / name).stat().st_size > 0
    page, links = _report_links(out)
    assert "Convergence" in page and "mitsuba" in page and "libLLVM" in page


def test_convergence_adds_the_sampler_studys_pick(tmp_path):
    """The default methods gain bsdf+nee with the sampler study's pick at the nearest
    depth; not when --methods is given, nor when it is independent."""
    out = tmp_path / "r"
    summary = out / "samplers" / "summary.json"
    summary.parent.mkdir(parents=True)

    def methods(*argv, best):
        summary.write_text(json.dumps({"pick": {d: {"sampler": s, "tied": [s],
                                                    "most_efficient": s}
                                                for d, s in best.items()}}))
        args = convergence.cli.parse_args(convergence.build_parser(),
                                          TINY + ["--out", str(out), *argv])
        return [m.name for m in convergence.settings_from(args).methods]

    plain = list(M.DEFAULT_METHODS)
    assert methods(best={"2": "multijitter", "8": "halton:owen"}) == plain + [
        "bsdf+nee+halton:owen"]                          # the scene's max_depth is 8
    assert methods("--max-depth", "3", best={"2": "multijitter", "8": "halton:owen"}) == \
        plain + ["bsdf+nee+multijitter"]
    assert methods(best={"8": "independent"}) == plain    # bsdf+nee is there already
    assert methods("--methods", "uniform", best={"8": "orthogonal"}) == ["uniform"]
    assert methods("--best-sampler", "none", best={"8": "orthogonal"}) == plain
    assert methods("--best-sampler", "ldsampler", best={}) == plain + ["bsdf+nee+ldsampler"]
    summary.unlink()
    args = convergence.cli.parse_args(convergence.build_parser(), TINY + ["--out", str(out)])
    assert [m.name for m in convergence.settings_from(args).methods] == plain   # no study yet


def test_writeup_end_to_end_with_full(tmp_path):
    out = tmp_path / "r"
    writeup.STUDY.main(TINY + ["--short-spp", "2", "--halton-spp", "3", "--full", "--full-spp", "4",
                         "--full-resolution", "8x4", "--out", str(out)])
    rmse = {r["pair A vs B"]: r for r in _csv(out / "writeup" / "rmse.csv")}
    assert set(rmse) == {"cosine vs uniform", "bsdf vs uniform", "uniform+halton vs uniform"}
    _assert_intervals(rmse.values(), "RMSE ratio B/A", "variance ratio B/A")
    for r in rmse.values():      # the RMSE ratio is the square root of the variance ratio
        if r["RMSE ratio B/A"] != "n/a":
            assert float(r["RMSE ratio B/A"]) ** 2 == pytest.approx(
                float(r["variance ratio B/A"]), rel=0.01)
    # the conclusion names, for each pair, the method its own RMSE ratio says is better
    for row in _csv(out / "writeup" / "conclusion.csv"):
        a, b = row["A vs B"].split(" vs ")
        if row["ratio"] == "n/a":
            assert row["verdict"].startswith("cannot be told")
        elif row["verdict"] != "not distinguishable":
            ratio = float(rmse[row["A vs B"]]["RMSE ratio B/A"])
            assert row["verdict"] == f"{a if ratio > 1 else b} is more accurate"
    _short_paragraphs(out, "writeup")
    bias = (out / "writeup" / "bias_full.md").read_text()
    assert "cosine − uniform" in bias and "uniform+halton" not in bias
    # plain Halton: the deterministic check, not the z-test, and the report says why
    det = (out / "writeup" / "deterministic_short.md").read_text()
    assert "| uniform+halton | 3 |" in det
    assert "uniform+halton" not in (out / "writeup" / "bias_short.md").read_text()
    assert "not independent samples" in (out / "writeup" / "summary.md").read_text()
    assert (out / "writeup" / "bias_cosine_vs_uniform_z.png").exists()


def test_run_all_report_lists_every_produced_file_and_reruns_resume(tmp_path, count_jobs):
    out = tmp_path / "r"
    argv = TINY + ["--spp", "2", "--time-budget", "0.02", "--short-spp", "2",
                   "--halton-spp", "2", "--methods", "uniform,cosine,bsdf,bsdf+nee,path",
                   "--out", str(out), "--stability", "quick", "--samplers", "quick",
                   "--lab", "quick", "--suite", "quick", "--repeats", "2"]
    run_all.main(argv)
    assert count_jobs
    errors = (out / "convergence" / "errors.csv").read_text()
    rmse = (out / "writeup" / "rmse.csv").read_text()
    count_jobs.clear()
    run_all.main(argv)                                  # the same command again
    assert count_jobs == []                             # nothing rendered
    assert (out / "convergence" / "errors.csv").read_text() == errors
    assert (out / "writeup" / "rmse.csv").read_text() == rmse
    files = report.produced_files(str(out))
    page, links = _report_links(out)
    assert files and set(files) <= links
    for f in links:
        assert (out / f).exists(), f
    # the job store is summarised in one line, not listed file by file
    stored = len(list((out / store.STORE_DIR).rglob("*.npz")))
    assert stored and not any(f.startswith(store.STORE_DIR + "/") for f in links)
    assert f"holds the {stored} finished render jobs" in page
    sections = [s["name"] for s in report.read_sections(str(out))]
    # the registered studies in their declared order, then the run's own section
    assert sections == [s.name for s in studies.ordered()] + ["run_all"]
    assert not any("/cache/" in f or f.startswith("cache/") for f in files)
    eff = (out / "convergence" / "efficiency.md").read_text()
    assert "| bsdf+nee |" in eff and "| path |" in eff
    # the sub-studies honour the options given to run_all (here only --resolution)
    stab = json.loads((out / "stability" / "section.json").read_text())["settings"]
    assert stab["resolution"] == "16x8"


def test_run_all_forwards_the_options_it_is_given_and_no_others(tmp_path):
    out = str(tmp_path / "r")
    parser = run_all.build_parser()
    args = run_all.cli.parse_args(parser, ["--methods", "cosine,bsdf+nee", "--spp", "8",
                                           "--max-depth", "3", "--repeats", "2", "--out", out])
    stability, writeup_study = studies.get("stability"), studies.get("writeup")
    sub = stability.parse_args(run_all.sub_argv(args, stability))
    assert (sub.spp, sub.methods, sub.depth.max_depth, sub.repeats) == \
        (8, ["cosine", "bsdf+nee"], 3, 2)
    # the writeup takes no --spp: only what its parser knows reaches it
    wu = run_all.sub_argv(args, writeup_study)
    assert "--spp" not in wu and wu[wu.index("--repeats") + 1] == "2"
    # options left at run_all's defaults are not forwarded: every study keeps its own
    # defaults, exactly as if it were run alone with the shared options
    args = run_all.cli.parse_args(parser, ["--out", out])
    for study in studies.ordered():
        via_run_all = study.parse_args(run_all.sub_argv(args, study))
        alone = study.parse_args(["--out", out])
        for key in ("spp", "resolution", "repeats", "methods", "reference_spp",
                    "time_budget"):
            assert getattr(via_run_all, key, None) == getattr(alone, key, None), \
                (study.name, key)
