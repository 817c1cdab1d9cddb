"""The ``vr_adaptive`` integrator (integrators/adaptive.py): unbiased per pixel block against
Mitsuba's path, its allocation the relMSE-optimal one, a clear refusal where per-pixel
counts cannot be served.

The bias tests use the pixels' spread over the renders. Given every pilot, the pixels'
final passes are independent; a pixel's pilot moves its neighbours' counts but never their
expected values, so two pixels' estimates are correlated only through how a pilot's
deviation goes with its spread (a second-order term), and the sum of the pixels' variances
is the block's. Negative controls: the pilot's samples counted twice (a realistic slip when
combining passes); a pixel's mean over all its samples while its count reads its own pilot
(a synthetic heavy pixel).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import _blocks
import integrators  # noqa: F401  (registers vr_adaptive)
import scenes
from experiments.lib.methods import parse_method
from experiments.lib.scenes import effective_depth, read_scene
from integrators import adaptive

SEEDS = 8                      # renders per side (4 per half)
SIGNIFICANCE = 0.01
T = mi.ScalarTransform4f


def cbox() -> dict:
    """Mitsuba's Cornell box at 32 x 32 with a box filter."""
    d = mi.cornell_box()
    d["sensor"]["film"].update(width=32, height=32, rfilter={"type": "box"})
    return d


def ball_on_floor(origin: list, target: list, fov: float, ball: dict, light: dict) -> dict:
    """A sphere of radius 0.5 with ``ball``'s BSDF on a diffuse floor, lit by ``light``
    (named entries), seen from ``origin`` over a 32 x 32 film with a box filter."""
    return {"type": "scene",
            "sensor": {"type": "perspective", "fov": fov,
                       "to_world": T().look_at(origin=origin, target=target, up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 32, "height": 32,
                                "rfilter": {"type": "box"}}},
            "floor": {"type": "rectangle",
                      "to_world": T().translate([0, -0.5, 0]).rotate([1, 0, 0], -90).scale(3),
                      "bsdf": {"type": "diffuse"}},
            "ball": {"type": "sphere", "radius": 0.5, "bsdf": ball}, **light}


def glossy() -> dict:
    """A rough-metal sphere (alpha 0.2) over a diffuse floor under a sphere light of radius
    0.3, 32 x 32: the highlight's pixels hold most of the variance, where the allocation
    matters, and tails light enough for the per-block test (a light of radius 0.1 and
    alpha 0.05: tail share 0.64, the plain method failed 6 of 20 seeds, the test's size
    void; here 0 of 12 for both, tail share 0.15 and 0.12)."""
    return ball_on_floor([0, 1.2, 4], [0, 0.2, 0], 40, {"type": "roughconductor", "alpha": 0.2},
                         {"light": {"type": "sphere", "radius": 0.3,
                                    "to_world": T().translate([1.0, 1.6, 1.0]),
                                    "emitter": {"type": "area",
                                                "radiance": {"type": "rgb", "value": 33}}}})


def even() -> dict:
    """A diffuse sphere on a diffuse floor under a constant sky, 32 x 32: every pixel's
    relative error about alike (the pilot predicts little gain), the camera looking down
    so that no pixel sees the sky (whose pixels have no error at all)."""
    return ball_on_floor([0, 4, 1], [0, -0.5, 0], 30, {"type": "diffuse"},
                         {"sky": {"type": "constant",
                                  "radiance": {"type": "rgb", "value": 1.0}}})


NESTED = {"type": "vr_path", "strategy": "bsdf", "emitter_sampling": True, "max_depth": 4}
#: min_gain 0: the allocation always runs (its own tests); the default, which may render
#: every pixel alike, has its own (test_where_the_pilot_predicts_little_gain_...)
ADAPTIVE = {"type": "vr_adaptive", "nested": NESTED, "min_gain": 0.0}
ADAPTIVE_DEFAULT = {"type": "vr_adaptive", "nested": NESTED}
PATH = {"type": "path", "max_depth": 4}
PATH_DEFAULT = {"type": "path"}
LEVELS = (_blocks.sidak(SIGNIFICANCE / 2, 3 * 16), _blocks.sidak(SIGNIFICANCE / 2, 3))


def blocks(scene: dict, integrator: dict, spp: int, seed0: int) -> _blocks.Renders:
    return _blocks.summarize(_blocks.render(scene, integrator,
                                            [seed0 + 7919 * i for i in range(SEEDS)], spp))


@pytest.mark.parametrize("scene", [cbox, glossy])
def test_adaptive_agrees_with_path_per_block(scene):
    """Size, measured over fresh seeds: 0 of 20 failed on cbox, 0 of 12 on glossy (the
    plain nested method: 0 of 12 there)."""
    images = blocks(scene(), ADAPTIVE, 32, 3)
    reference = blocks(scene(), PATH, 128, 1)
    agreement = _blocks.agree(images, reference, *LEVELS)
    assert agreement.passed, agreement.describe()
    assert agreement.detectable < 0.05, agreement.detectable


def test_where_the_pilot_predicts_little_gain_every_pixel_gets_the_same_count():
    """Under a constant sky the pixels' relative errors hardly differ, and the pilot (8 of
    32 spp) predicts a gain under min_gain: every pixel renders 32 samples, the rest by
    the nested integrator's own render, and the image still agrees with path per block.
    Negative control: on the glossy scene, whose highlight holds the variance, it
    allocates (its predicted gain over min_gain, the counts unequal). Size of the block
    test here, over fresh seeds: 0 of 10 failed (detectable bias 0.29%)."""
    integ = mi.load_dict(ADAPTIVE_DEFAULT)
    mi.render(mi.load_dict(even()), integrator=integ, spp=32, seed=1)
    assert integ.last_gain < adaptive.MIN_GAIN and not integ.last_allocated
    assert np.all(np.array(integ.last_counts) == 32)
    agreement = _blocks.agree(blocks(even(), ADAPTIVE_DEFAULT, 32, 3),
                              blocks(even(), PATH, 128, 1), *LEVELS)
    assert agreement.passed, agreement.describe()
    mi.render(mi.load_dict(glossy()), integrator=integ, spp=32, seed=1)
    assert integ.last_gain >= adaptive.MIN_GAIN and integ.last_allocated
    assert len(np.unique(np.array(integ.last_counts))) > 1


def test_the_pilot_counted_twice_is_found(monkeypatch):
    """Negative control: the pilot's samples added once more (the image about 1 + pilot's
    share times too bright) fails the same test."""
    combine = adaptive.combine
    monkeypatch.setattr(adaptive, "combine", lambda pilot, n_pilot, final, n_final, planned:
                        combine(2.0 * pilot, n_pilot, final, n_final, planned))
    agreement = _blocks.agree(blocks(cbox(), ADAPTIVE, 32, 3), blocks(cbox(), PATH, 128, 1),
                              *LEVELS)
    assert not agreement.passed


class Rare(mi.SamplingIntegrator):
    """A synthetic heavy pixel: every sample is 50 with probability 0.02, else 0 (mean 1,
    standard deviation 7): most pilots of 4 samples see nothing."""

    def sample(self, scene, sampler, ray, medium=None, active=True):
        return mi.Spectrum(dr.select(sampler.next_1d() < 0.02, 50.0, 0.0)), True, []

    def aov_names(self):
        return []


def rare_image_means(renders: int = 20) -> np.ndarray:
    mi.register_integrator("test_rare", lambda props: Rare(props))
    scene = mi.load_dict({"type": "scene", "sensor": {"type": "perspective", "film": {
        "type": "hdrfilm", "width": 64, "height": 64, "rfilter": {"type": "box"}}}})
    integrator = mi.load_dict({"type": "vr_adaptive", "nested": {"type": "test_rare"},
                               "min_gain": 0.0})
    return np.array([np.mean(np.array(mi.render(scene, integrator=integrator, spp=16,
                                                seed=s))[..., 0]) for s in range(renders)])


def test_a_heavy_pixel_stays_unbiased(monkeypatch):
    """The image mean of the synthetic heavy pixel over 20 renders of 64 x 64 pixels is 1
    within 4 standard errors (measured: 1.006, 0.5 standard errors). Negative control:
    each pixel's mean over all its samples, pilot and final, by their counts (the
    optional stopping that the module's fixed pilot weight avoids, since the counts read
    the pixel's own pilot): measured 0.56, 63 standard errors low."""
    means = rare_image_means()
    se = means.std(ddof=1) / np.sqrt(len(means))
    assert abs(means.mean() - 1.0) < 4 * se, (means.mean(), se)
    monkeypatch.setattr(adaptive, "combine", lambda pilot, n_pilot, final, n_final, planned:
                        (pilot + final) / (n_pilot + n_final))
    means = rare_image_means()
    se = means.std(ddof=1) / np.sqrt(len(means))
    assert means.mean() < 1.0 - 8 * se, (means.mean(), se)


def test_a_pilots_noise_predicts_no_gain():
    """Every pixel of the synthetic heavy pixel alike: no allocation gains, yet a pilot of
    4 samples catches the rare 50 in some pixels and not in others. The prediction,
    counts from one half of each pixel's pilot judged by the other half's variances,
    reads that allocating by such noise loses (measured 0.41 to 0.44 over 5 renders at
    16 spp), and every pixel gets the same count. Judged by the samples it allocated by
    (mutant adaptive-gain-in-sample) it read 5.2 to 5.4 and allocated. Negative control:
    on the glossy scene, whose highlight holds the variance, the prediction is over
    min_gain (test_where_the_pilot_predicts_little_gain_...)."""
    mi.register_integrator("test_rare", lambda props: Rare(props))
    scene = mi.load_dict({"type": "scene", "sensor": {"type": "perspective", "film": {
        "type": "hdrfilm", "width": 64, "height": 64, "rfilter": {"type": "box"}}}})
    integrator = mi.load_dict({"type": "vr_adaptive", "nested": {"type": "test_rare"}})
    for seed in range(3):
        mi.render(scene, integrator=integrator, spp=16, seed=seed)
        assert integrator.last_gain < 1.0 and not integrator.last_allocated, \
            integrator.last_gain
        assert np.all(np.array(integrator.last_counts) == 16)


def allocation(ratio: np.ndarray, budget: int, min_spp: int = 1,
               min_share: float = 0.0) -> np.ndarray:
    """The integrator's final-pass counts for a given per-pixel relative deviation (its
    pilot replaced by means 1 and second moments 1 + ratio^2, one row of pixels blurred)."""
    integ = mi.load_dict({**ADAPTIVE, "min_spp": min_spp, "min_share": min_share})
    width = len(ratio)
    mean = mi.Float(np.ones(width))
    second = mi.Float(1.0 + np.square(ratio))
    counts, _ = integ.allocate(mean, second, 2, budget, mi.ScalarVector2u(width, 1))
    return np.array(counts)


def test_the_allocation_is_proportional_to_the_relative_deviation():
    """The relMSE sum_i r_i^2 / n_i at a budget B is least at n_i proportional to r_i: its
    value (sum r_i)^2 / B. The counts (after the floor and rounding down) come within 5%
    of it on a field of 4 levels, stay within the budget, and the floor holds. Allocated
    by the variance r_i^2 instead, the same field's relMSE is 30% worse."""
    rng = np.random.default_rng(0)
    levels = rng.choice([0.1, 1.0, 5.0, 30.0], size=4096)
    ratio = np.repeat(levels, 3)[:4096]          # runs of 3: the neighbours' mean keeps some
    budget = 64 * len(ratio)
    n = allocation(ratio, budget)
    relative = 2.0 * np.square(ratio) / (1.0 + adaptive.RELMSE_EPS)         # pilot 2
    neighbours = np.array(adaptive._blur(mi.Float(relative), len(ratio), 1))
    r = np.sqrt(adaptive.OWN_SHARE * relative + (1 - adaptive.OWN_SHARE) * neighbours)
    assert n.min() >= 1 and n.sum() <= budget
    best = np.sum(r) ** 2 / budget
    assert np.sum(np.square(r) / n) < 1.05 * best
    by_variance = np.maximum(1, np.floor(np.square(r) / np.sum(np.square(r)) * budget))
    assert np.sum(np.square(r) / by_variance) > 1.3 * best
    floor = allocation(np.zeros(8), 8 * 10, min_spp=3)
    assert (floor >= 3).all() and floor.sum() <= 80      # no variance: the floor plus a share
    defended = allocation(ratio, budget, min_share=0.25)
    assert defended.min() == 16 and defended.sum() <= budget


def test_no_pixel_gets_no_samples_and_the_image_is_finite():
    scene = mi.load_dict({**glossy(), "integrator": {**ADAPTIVE, "min_spp": 1}})
    image = np.array(mi.render(scene, spp=8, seed=0))
    assert image.shape == (32, 32, 3) and np.isfinite(image).all()


@pytest.mark.parametrize("change, words", [
    ({"rfilter": {"type": "gaussian"}}, "box"),
    ({"sampler": {"type": "stratified"}}, "independent"),
])
def test_what_per_pixel_counts_cannot_serve_is_refused(change, words):
    d = glossy()
    film = {**d["sensor"]["film"], **({"rfilter": change["rfilter"]} if "rfilter" in change
                                      else {})}
    d["sensor"] = {**d["sensor"], "film": film, **({"sampler": change["sampler"]}
                                                   if "sampler" in change else {})}
    scene = mi.load_dict({**d, "integrator": ADAPTIVE})
    assert words in raised(lambda: mi.render(scene, spp=16))


@pytest.mark.parametrize("outer", [{"type": "moment"}, {"type": "aov", "aovs": "dd.y:depth"}])
def test_nested_in_another_integrator_it_is_refused_by_name(outer):
    """Mitsuba's ``moment`` (and, for its AOVs, ``aov``) call a nested integrator's
    ``sample``, which would skip the pilot and the per-pixel counts: a clear refusal that
    says what to nest in what (not a pure virtual function called, nor plain samples)."""
    d = glossy()
    scene = mi.load_dict({**d, "integrator": {**outer, "inner": ADAPTIVE}})
    words = raised(lambda: mi.render(scene, spp=16))
    assert "vr_adaptive: called by another integrator" in words
    assert "make vr_adaptive the scene's integrator" in words


def raised(fn) -> str:
    """The messages of the exception ``fn`` raises and of its causes (``mi.render`` wraps
    an integrator's error in its own)."""
    with pytest.raises(Exception) as info:
        fn()
    e, words = info.value, []
    while e is not None:
        words.append(str(e))
        e = e.__cause__ or e.__context__
    return " | ".join(words)


def test_bad_parameters_are_refused_with_their_values():
    with pytest.raises(Exception, match="pilot_share must be in"):
        mi.load_dict({**ADAPTIVE, "pilot_share": 1.5})
    with pytest.raises(Exception, match="min_share must be in"):
        mi.load_dict({**ADAPTIVE, "min_share": 1.0})
    with pytest.raises(Exception, match="min_gain must be >= 0, got -0.5"):
        mi.load_dict({**ADAPTIVE, "min_gain": -0.5})
    with pytest.raises(Exception, match="min_spp must be >= 1"):
        mi.load_dict({**ADAPTIVE, "min_spp": 0})
    with pytest.raises(Exception, match="learns between"):
        mi.load_dict({"type": "vr_adaptive", "nested": {"type": "vr_guided_path"}})
    with pytest.raises(Exception, match="exactly one nested"):
        mi.load_dict({"type": "vr_adaptive"})
    scene = mi.load_dict({**glossy(), "integrator": ADAPTIVE})
    assert "render more samples" in raised(lambda: mi.render(scene, spp=2))


def test_it_lowers_the_error_where_a_few_pixels_hold_the_variance():
    """At equal spp (32) on the suite's phong_highlight (a narrow lobe reflecting an area
    light: the highlight's pixels hold most of the relative variance), the adaptive image's
    relMSE against a 4096-spp path reference is below a third of the plain one's (measured
    over 8 renders each at the defaults: 8.7 times)."""
    scene = mi.load_file(scenes.path("suite/phong_highlight.xml"))

    def renders(integrator, seeds, spp):
        integrator = mi.load_dict(integrator)
        return np.stack([np.array(mi.render(scene, integrator=integrator, spp=spp, seed=s),
                                  dtype=np.float64)[..., :3] for s in seeds])
    ref = renders(PATH_DEFAULT, [99], 4096)[0]

    def relmse(integrator):
        images = renders(integrator, range(100, 108), 32)
        return float(np.mean(np.square(images - ref) / (np.square(ref) + 1e-2)))
    nested = {"type": "vr_path", "strategy": "bsdf", "emitter_sampling": True}
    assert relmse({"type": "vr_adaptive", "nested": nested}) < relmse(nested) / 3


# ------------------------------------------------------------ as a method of the studies

def test_the_method_grammar_nests_any_plain_method_and_refuses_the_rest():
    m = parse_method("bsdf+nee+adaptive")
    assert m.adaptive and m.integrator_dict() == {"type": "vr_adaptive", "nested": {
        "type": "vr_path", "strategy": "bsdf", "emitter_sampling": True}}
    assert parse_method("path+adaptive").integrator_dict()["nested"] == {"type": "path"}
    assert not parse_method("bsdf+nee").adaptive
    with pytest.raises(ValueError, match="learns between its own passes"):
        parse_method("guided+nee+adaptive")
    with pytest.raises(ValueError, match="break the points of 'zsobol'"):
        parse_method("bsdf+nee+zsobol:owen+adaptive")


def test_the_suite_measures_an_adaptive_cell(tmp_path):
    """End to end: its cells rendered at both budgets, their errors from the repeats (its
    passes keep no per-pixel moments), its bias test run, and the figure of where it put
    its samples beside the errors written and shown in the report."""
    import json
    from experiments.lib.studies.suite import study as S
    S.STUDY.main(["--quick", "--out", str(tmp_path), "--scenes", "cbox",
                  "--methods", "bsdf+nee,bsdf+nee+adaptive,path", "--spp", "8"])
    summary = json.loads((tmp_path / "suite" / "summary.json").read_text())
    cells = [c for c in summary["cells"] if c["method"] == "bsdf+nee+adaptive"]
    assert {c["budget"] for c in cells} == {"equal_spp", "equal_time"}
    assert all(c["biased"] in (False, "untestable") for c in cells), cells
    # the ceiling an oracle's allocation of bsdf+nee's samples would reach, beside it
    assert summary["scenes"][0]["adaptive_ceiling"] >= 1.0
    figure = tmp_path / "suite" / "adaptive" / "cbox-bsdf+nee+adaptive.png"
    assert figure.stat().st_size > 0
    section = (tmp_path / "suite" / "section.json").read_text()
    assert "suite/adaptive/cbox-bsdf+nee+adaptive.png" in section
    assert "the allocation figure of" not in section   # no failure line


def test_a_guiding_scene_gives_the_ceiling_of_its_guide(tmp_path):
    """The guiding scenes render no bsdf+nee: their adaptive ceiling reads guided+nee's
    equal-time renders (what guided+nee+adaptive, refused, could reach), and says so."""
    import json
    from experiments.lib.studies.suite import study as S
    S.STUDY.main(["--quick", "--out", str(tmp_path), "--scenes",
                  scenes.path("suite/door_room.xml"), "--methods", "path,guided+nee"])
    (scene,) = json.loads((tmp_path / "suite" / "summary.json").read_text())["scenes"]
    assert scene["adaptive_ceiling_method"] == "guided+nee"
    assert 1.0 <= scene["adaptive_ceiling"] < 100.0, scene["adaptive_ceiling"]
    assert "(guided+nee)" in (tmp_path / "suite" / "scenes.md").read_text()


def test_the_allocation_figure_reads_the_counts_the_render_used():
    """Every pixel's samples after one render on phong_highlight (48x36, 64 spp): at least
    the pilot and the floor each, together the budget less under one sample per pixel
    (the counts are rounded down), and more in the highlight than in the black background,
    where the pilot saw no deviation (its pixels get the floor)."""
    from experiments.lib import adaptive_figures
    info = read_scene(scenes.path("suite/phong_highlight.xml"))
    chosen = adaptive_figures.allocation(scenes.path("suite/phong_highlight.xml"), 48, 36,
                                         parse_method("bsdf+nee+adaptive"), 64, 3,
                                         effective_depth(info))
    assert chosen.allocated and chosen.gain >= adaptive.MIN_GAIN
    counts = chosen.counts
    pilot = round(64 * adaptive.PILOT_SHARE)
    least = int(adaptive.MIN_SHARE * (64 - pilot))
    assert counts.shape == (36, 48) and counts.min() >= pilot + least
    assert 64 * counts.size - counts.size < counts.sum() <= 64 * counts.size
    assert counts.max() > 4 * counts.min()
    assert np.median(counts) == pilot + least          # most of the film is background
