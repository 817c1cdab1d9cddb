"""The experiment engine (experiments/lib/engine.py): a study declared here, run end to end.

* Two methods on two bundled scenes at both budgets (equal spp, then equal time at the
  cost per sample the equal-spp renders measured), two repeats: every cell measured, the
  equal-time count the rule's, a rerun renders nothing, and on two Dask workers the same
  jobs give the same images (negative control: another seed does not).
* A deterministic sampler renders once for every repeat (negative control: its randomized
  twin renders each repeat).
* Bad declarations are refused naming the bad value.
(That every job starts with an untrained integrator, and that the clock counts every pass
of a method and its host work, is tests/test_clock.py's: the engine renders through the
same executor.)
"""
from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest

from _paths import scene_path
from experiments.lib import clock
from experiments.lib.engine import Budget, Cell, Declaration, Engine, SceneSetup
from experiments.lib.methods import Depth, parse_method
from experiments.lib.scenes import read_scene
from experiments.lib.store import ReplayError
from experiments.lib.study import Study, StudySettings

VARIANT = "llvm_ad_rgb"
METHODS = (parse_method("bsdf+nee"), parse_method("path"))
SCENES = tuple(SceneSetup(name, read_scene(scene_path(f"{name}.xml")), (16, 8), Depth(3))
               for name in ("cbox", "furnace"))
BUDGETS = (Budget.equal_spp(4), Budget.equal_time(2e-3))
DECLARED = Declaration("engine-test", METHODS, SCENES, BUDGETS, repeats=2)


def make_study(out, seed: int = 0, executor=None, repeats: int = 2, replay=None) -> Study:
    settings = StudySettings(
        out=str(out), scene=SCENES[0].info.path, info=SCENES[0].info, resolution=(16, 8),
        depth=Depth(3), methods=METHODS, repeats=repeats, variant=VARIANT, seed=seed,
        reference_spp=64, reference_method=parse_method("path"), executor=executor,
        replay_counts=None if replay is None else str(replay))
    return Study(settings, executor)


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    out = tmp_path_factory.mktemp("engine-local")
    engine = Engine(make_study(out))
    return out, engine, engine.run(DECLARED)


def test_every_cell_of_the_declaration_is_measured(local):
    _, engine, measured = local
    cells = {Cell(s.name, m.name, b.name) for s in SCENES for m in METHODS for b in BUDGETS}
    assert set(measured.runs) == cells
    for cell, runs in measured.runs.items():
        assert len(runs) == 2 and all(len(rungs) == 1 for rungs in runs)
        for run in (rungs[-1] for rungs in runs):
            assert run.cost > 0 and np.isfinite(run.relmse) and run.image.shape == (8, 16, 3)
            if cell.budget == "equal-spp":
                assert run.spp == 4
    # the two repeats are independent renders
    first = measured.runs[Cell("cbox", "path", "equal-spp")]
    assert not np.array_equal(first[0][0].image, first[1][0].image)
    # the furnace's reference is exact up to its floor: its errors are small
    assert measured.error(Cell("furnace", "path", "equal-spp")).hi < 1e-2
    ratio = measured.efficiency(Cell("cbox", "bsdf+nee", "equal-spp"),
                                Cell("cbox", "path", "equal-spp"))
    assert 0 < ratio.lo <= ratio.value <= ratio.hi < np.inf


def test_equal_time_count_is_the_budget_at_the_measured_cost_per_sample(local):
    out, engine, measured = local
    for s in SCENES:
        for m in METHODS:
            spp_runs = [rungs[0] for rungs in measured.runs[Cell(s.name, m.name, "equal-spp")]]
            per_sample = np.mean([r.cost / r.spp for r in spp_runs])
            expected = max(1, int(BUDGETS[1].seconds / per_sample))
            got = {rungs[0].spp for rungs in measured.runs[Cell(s.name, m.name, "equal-time")]}
            assert got == {expected}, (s.name, m.name, got, expected)


def test_a_rerun_renders_nothing(local, count_jobs):
    out, _, measured = local
    again = Engine(make_study(out)).run(DECLARED)
    assert count_jobs == []
    cell = Cell("cbox", "bsdf+nee", "equal-spp")
    np.testing.assert_array_equal(again.runs[cell][1][0].image, measured.runs[cell][1][0].image)


def test_replayed_counts_are_the_earlier_runs(local, tmp_path):
    """--replay-counts: the equal-time counts of an earlier run, whatever this run's timings
    say (a budget of 1e-9 s would give 1 spp: the negative control is that budget unreplayed)."""
    out, _, measured = local
    tiny = Declaration("engine-test", METHODS, SCENES, (BUDGETS[0], Budget.equal_time(1e-9)),
                       repeats=2)
    earlier = {c: {r[0].spp for r in runs} for c, runs in measured.runs.items()
               if c.budget == "equal-time"}
    assert any(n != {1} for n in earlier.values())
    replayed = Engine(make_study(tmp_path / "replayed", replay=out)).run(tiny)
    assert {c: {r[0].spp for r in runs} for c, runs in replayed.runs.items()
            if c.budget == "equal-time"} == earlier
    unreplayed = Engine(make_study(tmp_path / "measured")).run(tiny)
    assert {r[0].spp for c, runs in unreplayed.runs.items() if c.budget == "equal-time"
            for r in runs} == {1}
    other = Declaration("engine-other", METHODS, SCENES[:1], tiny.budgets)
    with pytest.raises(ReplayError, match="no job 'engine-other/cbox/bsdf_nee/equal-time'"):
        Engine(make_study(tmp_path / "missing", replay=out)).run(other)


def _equal_spp_images(measured) -> dict:
    return {(cell, r): rungs[0].image for cell, runs in measured.runs.items()
            if cell.budget == "equal-spp" for r, rungs in enumerate(runs)}


def test_on_two_dask_workers_the_same_jobs_give_the_same_images(local, tmp_path):
    from dask.distributed import Client
    from experiments.lib import cluster
    _, _, measured = local
    with cluster.local_cluster(2, silence_logs=logging.CRITICAL) as dask_cluster:
        with cluster.DaskExecutor(Client(dask_cluster, set_as_default=False),
                                  VARIANT) as executor:
            remote = Engine(make_study(tmp_path / "dask", executor=executor)).run(DECLARED)
            other = Engine(make_study(tmp_path / "seed1", seed=1,
                                      executor=executor)).run(DECLARED)
    ours, theirs = _equal_spp_images(measured), _equal_spp_images(remote)
    assert sorted(map(str, ours)) == sorted(map(str, theirs))
    for key, image in ours.items():
        np.testing.assert_allclose(theirs[key], image, rtol=1e-5, atol=1e-6, err_msg=str(key))
    assert all(r[0].cost > 0 for runs in remote.runs.values() for r in runs)
    # negative control: another seed gives other images, and the comparison says so
    seed1 = _equal_spp_images(other)
    key = (Cell("cbox", "path", "equal-spp"), 0)
    assert not np.allclose(seed1[key], ours[key], rtol=1e-5, atol=1e-6)


def test_a_deterministic_sampler_renders_once_for_every_repeat(tmp_path, count_jobs):
    fixed, randomized = parse_method("bsdf+halton:none"), parse_method("bsdf+halton:owen")
    declared = Declaration("engine-det", (fixed, randomized), SCENES[:1],
                           (Budget.equal_spp(4),), repeats=3)
    measured = Engine(make_study(tmp_path, repeats=3)).run(declared)
    rendered = [key for key in count_jobs if key.startswith("engine-det")]
    assert sum("halton-none" in k for k in rendered) == 1
    assert sum("halton-owen" in k for k in rendered) == 3          # the negative control
    runs = {m.name: measured.runs[Cell("cbox", m.name, "equal-spp")] for m in (fixed, randomized)}
    assert all(len(r) == 3 for r in runs.values())
    images = [r[0].image for r in runs[fixed.name]]
    assert all(np.array_equal(images[0], im) for im in images)
    assert not np.array_equal(runs[randomized.name][0][0].image, runs[randomized.name][1][0].image)
    # one run standing for three has no spread: its error's interval is a point
    error = measured.error(Cell("cbox", fixed.name, "equal-spp"))
    assert error.lo == pytest.approx(error.hi)


def test_bad_declarations_are_refused():
    with pytest.raises(ValueError, match="'equal-time' measures its cost per sample on budget "
                                         "'ladder'"):
        Declaration("x", METHODS, SCENES, (Budget.equal_spp(4), Budget.equal_time(1.0, "ladder")))
    with pytest.raises(ValueError, match=r"repeats >= 1 \(got 0\)"):
        Declaration("x", METHODS, SCENES, BUDGETS, repeats=0)
    assert clock.NAME == "kernel time"


def test_runs_carry_their_overhead_their_variance_and_their_jobs(local):
    """A run's overhead is its renders' wall time the clock does not count; its per-pixel
    variance is known only from two passes or more (the 4-spp renders here are one pass);
    the measurements keep the jobs each cell was made of."""
    _, _, measured = local
    cell = Cell("cbox", "path", "equal-spp")
    run = measured.runs[cell][0][0]
    assert run.overhead >= 0 and run.variance is None
    jobs = measured.jobs[cell]
    assert len(jobs) == 2 and all(j.spp == 4 for reps in jobs for j in reps)
    assert len(measured.all_jobs()) == sum(len(j) for reps in measured.jobs.values()
                                           for j in reps)


def test_a_ladder_accumulates_its_stretches(tmp_path):
    """Budget.progressive: each rung the image of all samples up to its count, costed by
    the clock over the stretches so far (cumulative), with a variance from their spread."""
    declared = Declaration("engine-ladder", METHODS[1:], SCENES[:1],
                           (Budget.progressive([1, 2, 4]),), repeats=1)
    runs = Engine(make_study(tmp_path, repeats=1)).run(declared).runs[
        Cell("cbox", "path", "ladder")][0]
    assert [r.spp for r in runs] == [1, 2, 4]
    assert runs[0].cost < runs[1].cost < runs[2].cost
    assert runs[0].variance is None and runs[2].variance.shape == (8, 16, 3)


def test_a_replay_without_a_store_or_without_the_job_ends_with_one_line(tmp_path):
    """--replay-counts on the command line: a folder without store/ is refused by the parser
    (exit 2), and an earlier run that lacks a replayed job ends the run with one line."""
    import subprocess
    import sys
    from _paths import ROOT
    base = [sys.executable, "-m", "experiments.convergence", "--resolution", "8x4", "--spp",
            "2", "--reference-spp", "8", "--repeats", "1", "--methods", "path", "--out"]
    bad = subprocess.run(base + [str(tmp_path / "a"), "--replay-counts", str(tmp_path)],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and "has no store/ folder" in bad.stderr, bad.stderr
    (tmp_path / "empty" / "store").mkdir(parents=True)
    missing = subprocess.run(base + [str(tmp_path / "b"), "--replay-counts",
                                     str(tmp_path / "empty")],
                             cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert missing.returncode == 2, missing.stderr
    assert missing.stderr.strip().splitlines()[-1].startswith("error: --replay-counts")


def test_errors_and_efficiencies_are_measured_above_the_references_floor():
    """Measurements.error and .efficiency subtract the reference's own expected error (its
    floor): with a floor of 0.01, relMSEs of 0.02 and 0.03 are excesses of 0.01 and 0.02, an
    efficiency of 2 at equal cost (negative control: 1.5 without the floor)."""
    from experiments.lib.engine import Measurements, Run
    declared = Declaration("floor", ("a", "b"), ("s",), (Budget.equal_spp(4),), 3)
    spread = (0.99, 1.0, 1.01)
    runs = {Cell("s", m, "equal-spp"): [[Run(4, 1.0, 0.0, 0.01 + e * x, None)] for x in spread]
            for m, e in (("a", 0.01), ("b", 0.02))}
    measured = Measurements(declared, runs, {("s", None): (None, {"relmse_floor": 0.01})})
    ratio = measured.efficiency(Cell("s", "a", "equal-spp"), Cell("s", "b", "equal-spp"))
    assert ratio.value == pytest.approx(2.0, rel=1e-3) and ratio.lo > 1.5
    assert measured.error(Cell("s", "a", "equal-spp")).value == pytest.approx(0.01, rel=1e-3)


def test_a_zsobol_job_split_into_passes_is_one_sequence():
    """A job of a sampler that must know its sequence's length (zsobol), split into passes
    (for memory, or by ``pass_spp``), renders the same samples as the job in one pass (the
    split once failed: a pass beyond the first did not fit the sequence of its own count;
    then a pass of 6 took 8 samples of the sequence, zsobol's rounding)."""
    from experiments.lib import execute, plan
    info, method = SCENES[0].info, parse_method("bsdf+nee+zsobol:owen")

    def job(pass_spp):
        return plan.make_job(f"zsobol-split/{pass_spp}", info, method, 16, 8, 16, 3,
                             Depth(3), VARIANT, pass_spp=pass_spp)
    split, whole = job(6), job(0)      # passes of a power of two: 6 -> 4
    assert split.passes() == [4, 4, 4, 4] and whole.passes() == [16]
    a = execute.run_job(split, VARIANT).image
    b = execute.run_job(whole, VARIANT).image
    assert np.allclose(a, b, rtol=1e-5, atol=1e-6), np.abs(a - b).max()


def test_renders_take_turns_and_a_failing_cell_is_isolated(tmp_path, monkeypatch):
    """The engine renders the budgets whose counts are known up front together, repeat by
    repeat, every method at one count before the next (a drifting load affects them alike),
    the declaration's ``lead`` first; negative control of the order: the methods' own order
    without ``lead``. With ``isolate_failures``, a method whose renders fail is recorded and
    the others are measured; without it, the error ends the run."""
    methods = tuple(parse_method(m) for m in ("bsdf", "bsdf+nee", "path"))
    budgets = (Budget.equal_spp(1, "one"), Budget.equal_spp(2, "two"))
    study = make_study(tmp_path)
    order = []
    run = study.run
    monkeypatch.setattr(study, "run", lambda jobs, label="": (
        order.extend(j for j in jobs if "/chunk-" not in j.key), run(jobs, label))[1])
    Engine(study).run(Declaration("order", methods, SCENES[:1], budgets, repeats=2,
                                  lead=("path",)))
    got = [(j.key.split("/")[2], j.spp, "/r1" in j.key) for j in order]
    names = ["path", "bsdf", "bsdf_nee"]
    assert got == [(m, n, r) for r in (False, True) for n in (1, 2) for m in names]
    order.clear()
    Engine(study).run(Declaration("order", methods, SCENES[:1], budgets, repeats=2))
    assert [j.key.split("/")[2] for j in order][:3] == ["bsdf", "bsdf_nee", "path"]

    real = study.run

    def failing(jobs, label=""):
        if any(j.method.name == "bsdf" for j in jobs):
            raise RuntimeError("a broken plugin\nwith a traceback")
        return real(jobs, label)
    monkeypatch.setattr(study, "run", failing)
    declared = Declaration("isolated", methods, SCENES[:1], budgets, isolate_failures=True)
    measured = Engine(study).run(declared)
    assert measured.failed == {("cbox", None, "bsdf"): "RuntimeError: a broken plugin"}
    assert {c.method for c in measured.runs} == {"bsdf+nee", "path"}
    with pytest.raises(RuntimeError, match="a broken plugin"):
        Engine(study).run(replace(declared, name="not-isolated", isolate_failures=False))


def test_a_time_scale_policy_is_asked_once_per_scene_with_the_reference_at_its_smallest(
        tmp_path):
    """A TimeScale policy decides an equal-time budget's factor on each scene once, after
    the budgets before it, from the reference's first MIN_CHUNKS chunks (the same in every
    run, whatever the reference's length: here 64 spp of chunks of 2 asked for, 32 chunks,
    and the policy sees the image of the first 8); the factor scales the budget's count.
    ``lead`` names a method twice: it renders once (negative control of the count: the
    policy's factor 1 gives the unscaled count)."""
    from experiments.lib import references
    seen = []

    def policy(engine, declaration, scene, planned, reference):
        seen.append((scene.name, reference))
        return 4.0, ""
    budgets = (Budget.equal_spp(4), Budget.equal_time(2e-3, scale=policy))
    declared = Declaration("policy", METHODS, SCENES[:1], budgets, lead=("path", "path"),
                           reference_spp=64, reference_typical_spp=16)
    assert [m.name for m in declared.methods_on(SCENES[0])] == ["path", "bsdf+nee"]
    engine = Engine(make_study(tmp_path))
    measured = engine.run(declared)
    chunks = engine.reference_jobs(declared)[("cbox", None)]
    assert len(chunks) > references.MIN_CHUNKS
    first = engine.study.reference(chunks[:references.MIN_CHUNKS])[0]
    assert [name for name, _ in seen] == ["cbox"]
    np.testing.assert_array_equal(seen[0][1], first)
    assert not np.array_equal(first, measured.references[("cbox", None)][0])
    assert measured.scales == {("cbox", None, "equal-time"): (4.0, "")}
    for m in METHODS:
        runs = measured.runs[Cell("cbox", m.name, "equal-spp")]
        per_sample = np.mean([r[0].cost / r[0].spp for r in runs])
        got = {r[0].spp for r in measured.runs[Cell("cbox", m.name, "equal-time")]}
        assert got == {max(1, int(4 * 2e-3 / per_sample))} != {max(1, int(2e-3 / per_sample))}


def test_a_runs_variance_comes_only_from_independent_passes(tmp_path):
    """Two passes per job (``pass_spp``): their spread is the image's variance where they
    are independent (the independent sampler: reseeded per pass), and none for a sampler
    whose passes continue one sequence (zsobol: the two halves of one Owen-scrambled Sobol'
    sequence are not independent estimates; its cells then keep their repeats)."""
    plain, sobol = parse_method("bsdf+nee"), parse_method("bsdf+nee+zsobol:owen")
    declared = Declaration("engine-spread", (plain, sobol), SCENES[:1],
                           (Budget.equal_spp(8),), repeats=2,
                           pass_spp=lambda method, spp, repeat: 4)
    measured = Engine(make_study(tmp_path)).run(declared)
    plain_run = measured.runs[Cell("cbox", plain.name, "equal-spp")][0][0]
    sobol_run = measured.runs[Cell("cbox", sobol.name, "equal-spp")][0][0]
    assert plain_run.variance is not None and np.all(np.isfinite(plain_run.variance))
    assert sobol_run.variance is None
