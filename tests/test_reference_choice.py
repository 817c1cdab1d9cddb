"""Which reference a suite scene's errors are measured against
(experiments/lib/studies/suite/reference_choice.py): the best sampler's method's reference
stands in for path's only where its chunks pass the bias test against path's chunks.

Its test (bias_test.check_reference) on chunks drawn here with a known mean: its size at
its level, and a 1% bias found (negative control); then on a real scene, with the right
candidate (bsdf+nee+zsobol:owen) adopted and a wrong one (BSDF sampling with its density
reported 10% high, a plugin written as a user writes one) rejected, and a scene whose
header leaves the candidate out keeping path's.
"""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats as sps

from experiments.lib import bias_image, references
from experiments.lib.methods import parse_method
from experiments.lib.studies.suite import bias_test, declare, reference_choice
from experiments.lib.studies.suite import study as S
from experiments.lib.study import Study
from test_suite_bias_plugins import WRONG_STRATEGY, register_plugins, unregister_plugins

ZSOBOL, PATH = parse_method("bsdf+nee+zsobol:owen"), parse_method("path")
H, W = 24, 32
_y, _x = np.mgrid[0:H, 0:W]
#: A smooth image with structure per channel (the chunks' common mean).
MEAN = (0.2 + np.sin(_x / 5.0) ** 2 + 0.5 * _y / H)[..., None] * np.array([1.0, 0.8, 0.6])
LEVEL = 1.0 - reference_choice.LEVEL
SEEDS = 100


def chunks(rng, n: int, relative_sd: float, factor: float = 1.0) -> np.ndarray:
    """``n`` chunk images of mean ``factor`` x MEAN, independent normal noise per pixel."""
    return factor * MEAN + relative_sd * MEAN * rng.standard_normal((n, H, W, 3))


def statuses(factor: float) -> list[str]:
    """The test of 8 candidate chunks (5% noise, the candidate's mean ``factor`` x path's)
    against 16 of path (20% noise), in SEEDS draws."""
    out = []
    for seed in range(SEEDS):
        rng = np.random.default_rng(seed)
        out.append(bias_test.check_reference(chunks(rng, 8, 0.05, factor),
                                             chunks(rng, 16, 0.2), ZSOBOL, PATH, True,
                                             LEVEL).status)
    return out


def test_the_reference_test_keeps_its_level_and_finds_a_one_percent_bias():
    """Size: rejections of a right candidate over SEEDS draws within the binomial's 99.9%
    bound at the test's level (measured: 1 of 100). Power: a candidate 1% high (its
    detectable bias about 0.9% here) is rejected in every draw."""
    right = statuses(1.0)
    assert set(right) <= {"unbiased", "biased"}
    bound = sps.binom.isf(1e-3, SEEDS, LEVEL)
    assert right.count("biased") <= bound, right.count("biased")
    wrong = statuses(1.01)
    assert wrong.count("biased") >= SEEDS - 2, wrong.count("biased")


def test_a_deterministic_candidate_or_too_few_chunks_is_not_proven():
    rng = np.random.default_rng(0)
    fixed = parse_method("bsdf+nee+zsobol:none")
    assert bias_test.check_reference(chunks(rng, 8, 0.05), chunks(rng, 16, 0.2), fixed, PATH,
                                     True, LEVEL).reason == "deterministic"
    assert bias_test.check_reference(chunks(rng, 3, 0.05), chunks(rng, 16, 0.2), ZSOBOL,
                                     PATH, True, LEVEL).reason == "too_few_renders"


# ------------------------------------------------------------ on a real scene

def choose(tmp_path, candidate: str, scenes: str = "cbox"):
    """reference_choice.choose on ``scenes`` at a small film, ``candidate`` as the run's
    precise method; the scene plans after it."""
    args = S.parse(["--quick", "--out", str(tmp_path), "--scenes", scenes, "--max-size", "32",
                    "--reference-spp", "256"])
    cfg = replace(S.settings(args), precise_reference=parse_method(candidate))
    plans = declare.plan_scenes(cfg)
    reference_choice.choose(Study(cfg), cfg, plans, references.ReferenceStore(cfg.reference_root))
    return cfg, plans


def test_the_best_samplers_reference_stands_in_where_it_agrees_with_paths(tmp_path,
                                                                         monkeypatch):
    looked = []            # path's reference is looked at before the candidate is tested
    render_on = reference_choice._render_on
    monkeypatch.setattr(reference_choice, "_render_on",
                        lambda study, cfg, refs, spec: (looked.append(spec),
                                                        render_on(study, cfg, refs, spec)))
    cfg, (cbox,) = choose(tmp_path, "bsdf+nee+zsobol:owen")
    assert looked == [cbox.bias_ref]
    assert cbox.ref.method.name == "bsdf+nee+zsobol:owen", cbox.reference_note
    assert cbox.bias_ref.method.name == "path" and "agrees with path's" in cbox.reference_note
    assert cbox.setup().reference_method.name == "bsdf+nee+zsobol:owen"   # the engine's
    # its own error is smaller than path's at the same samples (measured on this 32x16
    # film of 8 chunks of 32 spp: 0.63 times; 0.47 at 48x24 and 1024 spp, in make run)
    store = references.ReferenceStore(cfg.reference_root)
    mine, paths = store.read(cbox.ref, cfg.reference_spp), store.read(cbox.bias_ref,
                                                                      cfg.reference_spp)
    assert mine.relmse_floor < 0.8 * paths.relmse_floor, (mine.relmse_floor,
                                                          paths.relmse_floor)


def test_a_wrong_candidate_is_rejected_and_path_kept(tmp_path):
    """The 10%-high density (about 8% darker on cbox): rejected, path's reference kept."""
    register_plugins()
    try:
        _, (cbox,) = choose(tmp_path, WRONG_STRATEGY)
    finally:
        unregister_plugins()
    assert cbox.ref.method.name == "path" and cbox.ref is cbox.bias_ref
    assert cbox.reference_test.status == "biased", cbox.reference_note
    assert "not proven" in cbox.reference_note and "differs" in cbox.reference_note
    assert min(cbox.reference_test.delta) < -0.05


def test_a_scene_that_leaves_the_candidate_out_keeps_paths(tmp_path):
    _, (room,) = choose(tmp_path, "bsdf+nee+zsobol:owen", "door_room")
    assert not room.header.renders("bsdf+nee+zsobol:owen")
    assert room.ref.method.name == "path" and room.reference_note == ""
    assert reference_choice.candidate(replace(S.settings(S.parse(["--quick"])),
                                              precise_reference=None), room) is None


def test_the_default_run_tries_the_best_samplers_method_unless_a_reference_is_given(tmp_path):
    base = ["--out", str(tmp_path), "--best-sampler", "zsobol:owen"]
    assert S.parse(base).precise_reference.name == "bsdf+nee+zsobol:owen"
    assert S.parse(base + ["--reference-method", "path"]).precise_reference is None
    assert S.parse(base + ["--quick"]).precise_reference is None
    with pytest.raises(SystemExit):
        S.parse(base + ["--reference-method", "nonsense"])


class ChunkStore:
    """A reference as ``refs.read`` and ``reference_chunks`` see it: its chunks (8 spp
    each) and the seconds each took."""

    def __init__(self, images, seconds):
        self.images, self.seconds = images, seconds

    def read(self, spec, spp):
        n = len(self.images)
        return SimpleNamespace(spp=8 * n, seconds=self.seconds * n)


class RenderOn:
    """A study whose reference renders add smooth chunks to its ``store`` (no firefly), and
    which records the samples asked for (``rendered``)."""

    def __init__(self, rng):
        self.rng, self.store, self.rendered = rng, None, []

    def reference_jobs(self, info, depth, resolution, spp, method, typical):
        return spp

    def run(self, spp, label):
        self.rendered.append(spp)
        self.store.images = np.concatenate([self.store.images, chunks(
            self.rng, spp // 8 - len(self.store.images), 0.2)])


def test_paths_reference_renders_on_while_one_chunks_pixel_rules_its_spread(monkeypatch):
    """One pixel of one chunk far above the others holds a third of path's spread (every image
    test on the scene void): its reference is doubled while that holds and the whole costs
    at most the reference's extension budget (reference_max_seconds, at least
    reference_choice.AGAINST_SECONDS); smooth chunks, or a reference too dear, render
    nothing more."""
    rng = np.random.default_rng(3)
    smooth = chunks(rng, 16, 0.2)
    firefly = smooth.copy()
    firefly[3, 5, 7] += 12.0
    assert reference_choice.top_share(smooth) < 0.01
    assert reference_choice.top_share(firefly) > 0.3

    study = RenderOn(rng)
    rendered = study.rendered

    monkeypatch.setattr(bias_test, "reference_chunks", lambda refs, spec: refs.images)
    spec = SimpleNamespace(info=None, depth=None, width=W, height=H, method=PATH)
    cfg = SimpleNamespace(reference_typical_spp=None, reference_max_seconds=0.0)
    study.store = store = ChunkStore(firefly, 0.001)
    reference_choice._render_on(study, cfg, store, spec)
    assert rendered[:2] == [2 * 8 * 16, 4 * 8 * 16]            # doubled while it rules
    assert reference_choice.top_share(store.images) <= bias_image.MAX_TERM_SHARE
    rendered.clear()
    study.store = store = ChunkStore(smooth, 0.001)
    reference_choice._render_on(study, cfg, store, spec)
    assert rendered == []
    study.store = store = ChunkStore(firefly.copy(), reference_choice.AGAINST_SECONDS / 16)   # 16 chunks: all of it
    reference_choice._render_on(study, cfg, store, spec)
    assert rendered == []
    # the same reference within the extension budget that path's reference would get
    # anyway where the candidate fails: rendered on
    cfg.reference_max_seconds = 4.5 * reference_choice.AGAINST_SECONDS
    reference_choice._render_on(study, cfg, store, spec)
    assert rendered[:1] == [2 * 8 * 16]
    rendered.clear()
    study.store = store = ChunkStore(firefly.copy(), cfg.reference_max_seconds / 16)       # dearer than that
    reference_choice._render_on(study, cfg, store, spec)
    assert rendered == []


def test_a_candidate_whose_own_tails_void_its_test_renders_on_until_it_is_testable(
        monkeypatch):
    """veach_mis: the candidate's few chunks held a rare bright path, so its test was void
    (heavy tails) and path's reference stayed, too noisy. A void test doubles the candidate
    and tests again, within the reference's extension budget; a test that fails, or a
    candidate too dear to double, renders nothing more (no second try at a rejection)."""
    rng = np.random.default_rng(5)
    firefly = chunks(rng, 16, 0.2)
    firefly[2, 3, 4] += 40.0
    paths = chunks(rng, 16, 0.2)

    study = RenderOn(rng)
    rendered = study.rendered

    monkeypatch.setattr(bias_test, "reference_chunks", lambda refs, spec: refs.images)
    spec = SimpleNamespace(info=None, depth=None, width=W, height=H, method=ZSOBOL)
    sp = SimpleNamespace(bias_ref=SimpleNamespace(method=PATH), box=True)
    cfg = SimpleNamespace(reference_typical_spp=None, reference_max_seconds=6.0)
    study.store = store = ChunkStore(firefly.copy(), 0.001)
    first = bias_test.check_reference(firefly, paths, ZSOBOL, PATH, True, LEVEL)
    assert first.reason == "heavy_tails"                # the premise: void at first
    test = reference_choice._tested(study, cfg, store, spec, paths, sp)
    assert rendered and rendered[0] == 2 * 8 * 16
    assert test.status == "unbiased"
    # too dear to double within the budget: the void test stands
    rendered.clear()
    study.store = store = ChunkStore(firefly.copy(), 6.0 / 16)
    test = reference_choice._tested(study, cfg, store, spec, paths, sp)
    assert rendered == [] and test.reason == "heavy_tails"
    # a candidate that differs (10% high) is not rendered on
    study.store = store = ChunkStore(chunks(rng, 16, 0.2, 1.1), 0.001)
    test = reference_choice._tested(study, cfg, store, spec, paths, sp)
    assert rendered == [] and test.status == "biased"
