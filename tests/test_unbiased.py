"""``vr_path`` converges to Mitsuba's ``path``, per pixel block and over the image, on
every Mitsuba BSDF, at depths where Russian roulette acts.

Each case renders :data:`SEEDS` independent renders (different seeds) of ``vr_path``
and as many of Mitsuba's ``path`` (always with next-event estimation, at 4x the
samples) and compares them with :mod:`_blocks` (tests/_blocks.py):

* per block (8 x 8 pixels) and channel, Welch's t-test of the two block means: a
  biased estimator can keep the image mean (energy moved between pixels), and only
  a per-block test sees that;
* pooled, per channel, the best linear estimate of a uniform relative difference
  from every block, each half of the renders weighted by the other half's blocks (so
  that the weights do not follow the noise they weight): a bias spread over the image
  (a missing factor, a clamp of large weights) moves every block a little, and this
  test sees it first.

The variance of a block mean is the sum of its pixels' own variances over the
renders (the ``independent`` sampler and a ``box`` filter keep the pixels of a render
independent), so each t-test has hundreds of degrees of freedom and needs no large
critical value. Pixels that are the same in every render of both sides (a directly
visible constant environment or emitter) carry no estimate and are left out.

Significance: 0.01 for the whole module, half of it for the per-block tests (Sidak
over every block, channel and case, :data:`BLOCK_COMPARISONS`) and half for the
pooled ones (Sidak over every channel and case, :data:`POOLED_COMPARISONS`).

Power: each case computes, from its own measured variances, the smallest uniform
relative bias (brighter or darker) that one of its two tests detects about 90% of
the time (:attr:`_blocks.Agreement.detectable`), and asserts that it is at most the
size :data:`CLAIMS` states for its scene: 5% for every case without next-event
estimation (where only the directions sampled by the strategy find the light, and a
bias confined to that branch is seen by no other test), 1.5-3% with it, 1.5% on the
glass scene. A negative control checks that a 5% darkening of a case without
next-event estimation does fail.

Cases: every strategy (``STRATEGIES``) with and without next-event estimation on
scenes that between them use ``diffuse``, ``twosided``, ``roughconductor``,
``conductor``, ``roughplastic``, ``plastic``, ``roughdielectric``, ``dielectric`` and
a textured ``phong``, lit by an area light, a spot light and a constant environment
(the spot light only with next-event estimation: no sampled direction reaches a
delta light), and edge cases (:data:`EDGE_CASES`).

Russian roulette starts at depth 5 (both integrators' default), which the Cornell
box scenes at ``max_depth`` 5 never reach. ``cbox-deep`` renders at unbounded depth
(roulette from depth 5 on every long path) and ``glass-env`` with ``rr_depth`` 1
(roulette at every vertex, inside the glass too, where the survival probability
carries the eta^2 of the interfaces crossed). Besides, ``vr_path``'s ``bsdf``
strategy with next-event estimation is Mitsuba's ``path`` estimator drawing the same
sampler dimensions in the same order, so on scenes without a purely specular BSDF
(where ``path`` draws an emitter sample that ``vr_path`` skips) its renders equal
``path``'s, sample for sample, to float rounding, at every depth and ``rr_depth``:
an exact check of that branch's roulette, emission and MIS weights.

Variance, not habit, sets the sizes: a t-test needs block means that are close to
normal. Uniform and cosine sampling of a narrow transmission lobe have heavy-tailed
weights (their product over several glass vertices is a Pareto-like tail of index
< 2 for alpha 0.2 glass and a small light), and their variance estimates then
understate the variance in most renders, so no t-test has its size there (at
unbounded depth, or with a diffuse floor under the rough sphere, the statistics of
such cases swing by many standard errors, both ways, between seeds). The glass case
therefore uses a wide lobe (alpha 0.5) under a constant environment and at most 3
vertices, where the tail is light; :data:`SPP_FACTOR` gives the strategies whose
weights are skewed on glossy lobes more samples.

Negative controls, each about the size its test claims to detect, that must fail
the same tests: a strategy whose reported pdf is off by a direction-dependent factor
of at most 5% (a bias of about the claimed size of its case), a 5% darkening and a
5% brightening of the images of a case without next-event estimation, and energy
moved between the image halves by 3% of the image mean (which keeps the image mean:
only the per-block test can see it). The machinery itself is checked on synthetic
renders of known law: its size without bias, and its power at the bias it reports
as detectable.
"""
from dataclasses import dataclass, field

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import _blocks
import integrators.path as vr_path
from integrators import strategies

SIGNIFICANCE = 0.01
BLOCK = _blocks.BLOCK
SEEDS = 8                       # independent renders per side (4 per half)
#: Samples per pixel relative to the scene's, per (strategy, next-event estimation).
#: Uniform sampling of glossy lobes (and, less, cosine sampling) has skewed per-sample
#: weights: at the scene's spp its block means missed the lobe's rare large samples in
#: most seeds. Without next-event estimation the light is found only by the sampled
#: directions: more samples give the power :data:`CLAIMS` states.
SPP_FACTOR = {("uniform", False): 8, ("uniform", True): 8, ("cosine", False): 4,
              ("cosine", True): 2, ("bsdf", False): 3, ("bsdf", True): 1,
              ("mis", False): 3, ("mis", True): 1}
STRATEGIES = vr_path.STRATEGIES
T = mi.ScalarTransform4f


# ------------------------------------------------------------------ scenes

def cbox(large=None, small=None):
    """Mitsuba's Cornell box at 32 x 32 (area light, box filter), boxes' BSDFs replaced."""
    d = mi.cornell_box()
    d["sensor"]["film"].update(width=32, height=32, rfilter={"type": "box"})
    if large is not None:
        d["large-box"]["bsdf"] = large
    if small is not None:
        d["small-box"]["bsdf"] = small
    return d


def open_scene(objects, emitters, size=32, floor=True):
    """A camera looking at the origin from +z, 32 x 32, with a diffuse floor."""
    d = {"type": "scene",
         "sensor": {"type": "perspective", "fov": 40,
                    "to_world": T().look_at(origin=[0, 1.2, 4], target=[0, 0.2, 0], up=[0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": size, "height": size,
                             "rfilter": {"type": "box"}}},
         "floor": {"type": "rectangle",
                   "to_world": T().translate([0, -0.5, 0]).rotate([1, 0, 0], -90).scale(3),
                   "bsdf": {"type": "diffuse",
                            "reflectance": {"type": "rgb", "value": [0.5, 0.45, 0.4]}}}}
    if not floor:
        del d["floor"]
    d.update(objects)
    d.update(emitters)
    return d


CHECKER = {"type": "checkerboard", "color0": {"type": "rgb", "value": [0.1, 0.3, 0.05]},
           "color1": {"type": "rgb", "value": [0.4, 0.1, 0.1]},
           "to_uv": mi.ScalarTransform3f().scale([4, 4])}
PHONG = {"type": "phong", "diffuse_reflectance": CHECKER, "specular_reflectance": 0.5,
         "exponent": 30.0}


def spheres(a, b):
    return {"a": {"type": "sphere", "radius": 0.5, "to_world": T().translate([-0.6, 0, 0]), "bsdf": a},
            "b": {"type": "sphere", "radius": 0.5, "to_world": T().translate([0.6, 0, 0]), "bsdf": b}}


def null_scene():
    """Alpha (valid_ray) through a ``null`` shape: a diffuse sphere half behind an
    invisible one, a constant environment, hidden emitters, an RGBA film."""
    d = open_scene(
        {"ghost": {"type": "sphere", "radius": 0.7, "to_world": T().translate([0.4, 0.2, 1.0]),
                   "bsdf": {"type": "null"}},
         "ball": {"type": "sphere", "radius": 0.5, "bsdf": {"type": "diffuse"}}},
        {"env": {"type": "constant"}}, floor=False)
    d["sensor"]["film"]["pixel_format"] = "rgba"
    return d


@dataclass(frozen=True)
class Scene:
    build: object            # () -> scene dict (without integrator)
    spp: int                 # samples per pixel of a vr_path render at factor 1
    depth: dict = field(default_factory=dict)   # max_depth / rr_depth of both integrators
    nee_only: bool = False   # delta lights: only with next-event estimation


SCENES = {
    "cbox-diffuse": Scene(lambda: cbox(), 32, {"max_depth": 5}),
    "cbox-metal": Scene(lambda: cbox({"type": "twosided",
                                      "bsdf": {"type": "roughconductor", "alpha": 0.2}},
                                     {"type": "conductor"}), 32, {"max_depth": 5}),
    "cbox-plastic": Scene(lambda: cbox({"type": "roughplastic", "alpha": 0.3},
                                       {"type": "plastic"}), 32, {"max_depth": 5}),
    "cbox-phong": Scene(lambda: cbox(PHONG), 32, {"max_depth": 5}),
    "cbox-deep": Scene(lambda: cbox(PHONG, {"type": "roughplastic", "alpha": 0.3}), 32,
                       {"max_depth": -1}),
    "glass-env": Scene(lambda: open_scene(
        spheres({"type": "roughdielectric", "alpha": 0.5, "int_ior": 1.5},
                {"type": "dielectric", "int_ior": 1.5}),
        {"env": {"type": "constant", "radiance": {"type": "rgb", "value": [0.8, 0.9, 1.0]}}},
        floor=False), 64, {"max_depth": 3, "rr_depth": 1}),
    "spot-phong": Scene(lambda: open_scene(
        spheres(PHONG, {"type": "diffuse"}),
        {"spot": {"type": "spot", "cutoff_angle": 35.0, "intensity": 20.0,
                  "to_world": T().look_at(origin=[1.5, 3, 2], target=[0, 0, 0], up=[0, 1, 0])},
         "env": {"type": "constant", "radiance": 0.1}}), 32, {"max_depth": 4}, nee_only=True),
}
CASES = [(scene, strategy, nee) for scene, s in SCENES.items()
         for strategy in STRATEGIES for nee in ([True] if s.nee_only else [False, True])]
#: Scenes of the edge cases and of the sample-for-sample comparison only.
SCENES.update({
    "null-alpha": Scene(null_scene, 32, {"max_depth": 4}, nee_only=True),
    "rough-glass": Scene(lambda: open_scene(
        spheres({"type": "roughdielectric", "alpha": 0.3, "int_ior": 1.5},
                {"type": "roughconductor", "alpha": 0.1}),
        {"env": {"type": "constant", "radiance": {"type": "rgb", "value": [0.8, 0.9, 1.0]}}}),
        16),
})

#: Edge cases compared the same way: (scene, integrator parameters shared by both
#: sides, vr_path strategy, NEE, channels).
EDGE_CASES = [("cbox-diffuse", {"hide_emitters": True}, "uniform", True, 3),
              ("cbox-diffuse", {"hide_emitters": True}, "mis", True, 3),
              ("null-alpha", {"hide_emitters": True}, "cosine", True, 4),
              ("null-alpha", {"hide_emitters": True}, "bsdf", False, 4)]
BLOCKS_PER_IMAGE = (32 // BLOCK) ** 2
#: Comparisons the module's per-block half of the significance is shared over (Sidak).
BLOCK_COMPARISONS = (len(CASES) * 3 + sum(c for *_, c in EDGE_CASES)) * BLOCKS_PER_IMAGE
#: ... and the pooled half.
POOLED_COMPARISONS = len(CASES) * 3 + sum(c for *_, c in EDGE_CASES)
ALPHA_BLOCKS = _blocks.sidak(SIGNIFICANCE / 2, BLOCK_COMPARISONS)
ALPHA_POOLED = _blocks.sidak(SIGNIFICANCE / 2, POOLED_COMPARISONS)


def case_id(name, strategy, nee):
    return f"{name}-{strategy}-{'nee' if nee else 'nonee'}"


#: The smallest uniform relative bias each case claims to detect about 90% of the time
#: (asserted from its own measured variances): scene -> (without NEE, with NEE).
CLAIMS = {"cbox-diffuse": (0.05, 0.015), "cbox-metal": (0.05, 0.03),
          "cbox-plastic": (0.05, 0.015), "cbox-phong": (0.05, 0.015),
          "cbox-deep": (0.05, 0.02), "glass-env": (0.015, 0.015), "spot-phong": (None, 0.02),
          "null-alpha": (0.03, 0.03)}


def claimed_detectable(name, nee):
    return CLAIMS[name][1 if nee else 0]


# --------------------------------------------------------------- rendering

def scene_dict(name, integrator):
    s = SCENES[name]
    return s.build(), {**integrator, **s.depth}


def render(name, integrator, spp, seed0, k=SEEDS):
    """:class:`_blocks.Renders` of k renders with independent seeds."""
    d, integ = scene_dict(name, integrator)
    return _blocks.summarize(_blocks.render(d, integ, [seed0 + 7919 * i for i in range(k)],
                                            spp))


def assert_blocks_agree(images, reference, what=""):
    """Per-block and pooled tests at the module's levels; returns the Agreement."""
    agreement = _blocks.agree(images, reference, ALPHA_BLOCKS, ALPHA_POOLED)
    assert agreement.passed, f"{what}: {agreement.describe()}"
    return agreement


_references = {}


def reference(name, **params):
    """K renders of Mitsuba's path (NEE + MIS) at 4x the spp, cached per scene."""
    key = (name, tuple(sorted(params.items())))
    if key not in _references:
        _references[key] = render(name, {"type": "path", **params}, 4 * SCENES[name].spp,
                                  seed0=1)
    return _references[key]


_vr = {}


def vr_images(name, strategy, nee, seed0=5, **params):
    """K renders of vr_path (cached for the default seeds, which the tests share)."""
    key = (name, strategy, nee, seed0, tuple(sorted(params.items())))
    if key in _vr:
        return _vr[key]
    spp = SCENES[name].spp * SPP_FACTOR[(strategy, nee)]
    images = render(name, {"type": "vr_path", "strategy": strategy, "emitter_sampling": nee,
                           **params}, spp, seed0)
    if seed0 == 5:
        _vr[key] = images
    return images


# ------------------------------------------------------------------- tests

#: Scenes without a purely specular BSDF, at depths and rr_depths where roulette acts.
SAME_SAMPLES = [("cbox-diffuse", {"max_depth": -1, "rr_depth": 1}),
                ("cbox-phong", {"max_depth": -1}),
                ("cbox-deep", {"max_depth": 12, "rr_depth": 2}),
                ("rough-glass", {"max_depth": -1, "rr_depth": 1}),
                ("spot-phong", {"max_depth": 6, "rr_depth": 1, "hide_emitters": True})]


@pytest.mark.parametrize("name,params", SAME_SAMPLES, ids=[n for n, _ in SAME_SAMPLES])
def test_bsdf_with_nee_is_mitsubas_path_sample_for_sample(name, params):
    """The same seed gives the same image as Mitsuba's path, to float rounding: the
    same estimator (NEE with the power heuristic, roulette with eta^2, the same
    sampler dimensions per bounce), whose every bug shows in many pixels. A rounding
    difference may flip one decision of a path (a roulette draw at its threshold), so
    a few pixels in a thousand may differ."""
    d = SCENES[name].build()
    path = mi.load_dict({"type": "path", **params})
    ours = mi.load_dict({"type": "vr_path", "strategy": "bsdf", "emitter_sampling": True,
                         **params})
    scene = mi.load_dict(d)
    for seed in (3, 4):
        a = np.array(mi.render(scene, integrator=path, spp=8, seed=seed), dtype=np.float64)
        b = np.array(mi.render(scene, integrator=ours, spp=8, seed=seed), dtype=np.float64)
        err = np.abs(a - b) / np.maximum(np.abs(a), 1e-3)
        differ = np.mean(np.any(err > 1e-4, axis=-1))
        assert differ <= 0.005, (name, params, seed, differ, float(err.max()))


@pytest.mark.parametrize("name,strategy,nee", CASES, ids=[case_id(*c) for c in CASES])
def test_blocks_agree_with_builtin_path(name, strategy, nee):
    agreement = assert_blocks_agree(vr_images(name, strategy, nee), reference(name),
                                    case_id(name, strategy, nee))
    assert_detects_its_claim(agreement, name, nee, case_id(name, strategy, nee))


def assert_detects_its_claim(agreement, name, nee, what):
    claim = claimed_detectable(name, nee)
    assert agreement.detectable <= claim, (
        f"{what} detects only a {agreement.detectable:.2%} uniform bias, it claims "
        f"{claim:.1%}: {agreement.describe()}")


@pytest.mark.parametrize("name,params,strategy,nee,channels", EDGE_CASES,
                         ids=[f"{n}-{s}-{'nee' if e else 'nonee'}" for n, _, s, e, _ in EDGE_CASES])
def test_edge_cases_agree_with_builtin_path(name, params, strategy, nee, channels):
    """hide_emitters with NEE (camera rays pass through area emitters), and the alpha
    channel (valid_ray) through a ``null`` BSDF with a hidden environment."""
    images = vr_images(name, strategy, nee, **params)
    assert images.images.shape[-1] == channels
    what = f"{name}, {params}, {strategy}, nee={nee}"
    assert_detects_its_claim(assert_blocks_agree(images, reference(name, **params), what),
                             name, nee, what)


class TiltedUniform(strategies.HemisphereSampling):
    """Uniform sampling that reports (and weights by) a density off by the factor
    1 + TILT (2 |cos theta| - 1): still normalised, at most TILT wrong anywhere."""
    TILT = 0.05

    def __init__(self):
        super().__init__("uniform")

    def pdf(self, bsdf, ctx, si, wo, active):
        return super().pdf(bsdf, ctx, si, wo, active) * (1 + self.TILT * (2 * dr.abs(wo.z) - 1))


def test_wrong_pdf_fails():
    """Negative control: a pdf off by a direction-dependent factor of at most 5%
    (:class:`TiltedUniform`, registered as 'uniform'), which biases this case by about
    its claimed detectable size, must fail."""
    strategies.register("uniform", TiltedUniform(), replace=True)
    try:
        images = vr_images("cbox-diffuse", "uniform", True, seed0=11)
    finally:
        strategies.register("uniform", strategies.uniform, replace=True)
    with pytest.raises(AssertionError):
        assert_blocks_agree(images, reference("cbox-diffuse"))


def test_five_percent_darker_without_nee_fails():
    """Negative control of the power claim: the images of a case without next-event
    estimation darkened by 5% (the issue's firefly clamp darkened this case by 5.8%)
    fail the pooled test, and so does 5% brighter; unscaled they pass."""
    name, strategy, nee = "cbox-metal", "cosine", False
    images, ref = vr_images(name, strategy, nee), reference(name)
    assert assert_blocks_agree(images, ref).detectable <= 0.05
    for factor in (0.95, 1.05):
        agreement = _blocks.agree(images.scaled(factor), ref, ALPHA_BLOCKS, ALPHA_POOLED)
        assert not agreement.passed, agreement.describe()
        assert agreement.p_pooled.min() <= ALPHA_POOLED


def test_mean_preserving_bias_fails_blocks():
    """Negative control: energy moved from the right half of every image to the left
    half, by 3% of the image mean: the image mean is unchanged, the per-block test must
    fail."""
    ref = reference("cbox-diffuse")
    images = vr_images("cbox-diffuse", "bsdf", True)
    x = images.images
    shift = 0.03 * x.mean(axis=(1, 2), keepdims=True)
    moved = x.copy()
    half = x.shape[2] // 2
    moved[:, :, :half] += shift
    moved[:, :, half:] -= shift
    assert np.allclose(moved.mean(axis=(1, 2)), x.mean(axis=(1, 2)))
    agreement = _blocks.agree(_blocks.summarize(moved), ref, ALPHA_BLOCKS, ALPHA_POOLED)
    assert agreement.p_blocks.min() <= ALPHA_BLOCKS, agreement.describe()


@pytest.mark.parametrize("skewed", [False, True], ids=["normal", "skewed"])
def test_agreement_has_its_size_and_power_on_synthetic_renders(skewed):
    """The machinery on renders of known law (8 per side, 32 x 32 pixels of unequal means
    and variances; normal, or gamma with skewness up to 6): without bias the per-block
    p-values are uniform (rejections at 0.05 within 3.5 sigma of 5%) and the pooled z
    has mean 0 and standard deviation 1 (within 3.5 standard errors, and 1.3); a
    uniform bias of the size ``detectable`` reports is detected (by the pooled test at
    the same level) in about 90% of the repetitions (at least 75%)."""
    rng = np.random.default_rng(7 + skewed)
    mu = rng.uniform(0.2, 1.0, (32, 32, 1))
    sd = mu * rng.uniform(0.3, 3.0, (32, 32, 1))

    def renders():
        if skewed:
            shape = np.square(mu / sd)
            return _blocks.summarize(rng.gamma(shape, np.square(sd) / mu, (8, 32, 32, 1)))
        return _blocks.summarize(mu + sd * rng.standard_normal((8, 32, 32, 1)))

    reps, alpha = 40, 0.05
    rejected, z, detected = 0, [], 0
    for _ in range(reps):
        a, b = renders(), renders()
        agreement = _blocks.agree(a, b, alpha, alpha)
        rejected += int(np.sum(agreement.p_blocks <= alpha))
        z.append(float(agreement.z_pooled[0]))
        biased = _blocks.agree(renders().scaled(1 + agreement.detectable_pooled), b, alpha, alpha)
        detected += bool(biased.p_pooled[0] <= alpha)
    n = reps * BLOCKS_PER_IMAGE
    assert abs(rejected - alpha * n) < 3.5 * np.sqrt(alpha * (1 - alpha) * n), rejected / n
    z = np.array(z)
    assert abs(z.mean()) < 3.5 / np.sqrt(reps), z.mean()
    assert 1 / 1.3 < z.std(ddof=1) < 1.3, z.std(ddof=1)
    assert detected >= 0.75 * reps, detected / reps
