"""The ``vr_path`` integrator: unbiased for every strategy, deterministic, robust.

Statistical comparisons use independent passes (different seeds): per pixel,
the pass images give a mean and a sample variance; two renders agree when the
difference of their image means lies within z standard errors, z = 3.89
(two-sided p = 1e-4 per comparison).
"""
import math
import re
import subprocess
import sys

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from conftest import ROOT, scene_path
from integrators.path import STRATEGIES

Z = 3.89              # two-sided p = 1e-4


def render_passes(scene, passes, spp, integrator=None, seed0=0):
    """Pass images as float64 array (passes, H, W, C)."""
    imgs = [np.array(mi.render(scene, integrator=integrator, spp=spp, seed=seed0 + 1000 * k),
                     dtype=np.float64) for k in range(passes)]
    return np.stack(imgs)


def image_mean_and_se(passes):
    """Per-channel image mean and its standard error from the spread of pass means."""
    per_pass = passes.mean(axis=(1, 2))                # (passes, C)
    return per_pass.mean(axis=0), per_pass.std(axis=0, ddof=1) / math.sqrt(len(per_pass))


def assert_agree(a, b, z=Z):
    ma, sa = image_mean_and_se(a)
    mb, sb = image_mean_and_se(b)
    bound = z * np.sqrt(sa ** 2 + sb ** 2)
    assert np.all(np.abs(ma - mb) < bound), f"means {ma} vs {mb}, |diff| {np.abs(ma - mb)} >= {bound}"
    return ma - mb, bound


def cbox_variant(**replacements):
    """The default scene with the glossy sphere's BSDF replaced (XML text substitution)."""
    text = open(scene_path("cbox.xml")).read()
    phong = re.search(r'<bsdf type="phong">.*?</bsdf>', text, re.S).group(0)
    return mi.load_string(text.replace(phong, replacements["glossy"]),
                          **{k: v for k, v in replacements.items() if k != "glossy"})


# ----------------------------------------------------------------- furnace

@pytest.mark.parametrize("emitter_sampling", [False, True])
@pytest.mark.parametrize("strategy", STRATEGIES)
def test_furnace_is_analytic(strategy, emitter_sampling):
    """Closed sphere, albedo rho, emission Le: every pixel is Le / (1 - rho) = 2."""
    scene = mi.load_file(scene_path("furnace.xml"), strategy=strategy,
                         emitter_sampling=emitter_sampling, spp=64)
    img = np.array(mi.render(scene, seed=3), dtype=np.float64)
    n = img.shape[0] * img.shape[1]
    mean = img.mean(axis=(0, 1))
    se = img.std(axis=(0, 1), ddof=1) / math.sqrt(n)   # pixels are iid estimates of 2
    assert np.all(np.abs(mean - 2.0) < Z * se + 1e-6), (mean, se)
    assert np.all(np.isfinite(img))


def test_furnace_with_bounded_depth_is_geometric_sum():
    """max_depth d sees d vertices of emission: sum_{k<d} rho^k, exactly per sample."""
    scene = mi.load_file(scene_path("furnace.xml"), strategy="cosine", max_depth=3, spp=4)
    img = np.array(mi.render(scene, seed=1))
    # Cosine sampling of a diffuse BSDF has weight exactly rho: no variance at all.
    assert np.allclose(img, 1 + 0.5 + 0.25, rtol=1e-5)


# --------------------------------------------------- agreement on cbox.xml

@pytest.fixture(scope="module")
def cbox_small():
    return dict(width=48, height=24, max_depth=6)


@pytest.fixture(scope="module")
def builtin_reference(cbox_small):
    scene = mi.load_file(scene_path("cbox.xml"), **cbox_small)
    path = mi.load_dict({"type": "path", "max_depth": cbox_small["max_depth"]})
    return render_passes(scene, 8, 64, integrator=path, seed0=99)


@pytest.mark.parametrize("emitter_sampling", [False, True])
@pytest.mark.parametrize("strategy", STRATEGIES)
def test_strategies_agree_with_builtin_path(strategy, emitter_sampling, cbox_small,
                                            builtin_reference):
    """Default scene (phong glossy sphere): vr_path == Mitsuba's path, every strategy."""
    scene = mi.load_file(scene_path("cbox.xml"), strategy=strategy,
                         emitter_sampling=emitter_sampling, **cbox_small)
    spp = 64 if emitter_sampling else 128
    assert_agree(render_passes(scene, 8, spp), builtin_reference)


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_diffuse_scene_agrees_with_builtin_path_and_diffuse_bsdf(strategy, cbox_small):
    """All-diffuse scene: vr_path (each strategy) against path + Mitsuba's diffuse BSDF."""
    glossy = '<bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.4, 0.3"/></bsdf>'
    scene = cbox_variant(glossy=glossy, strategy=strategy, **cbox_small)
    path = mi.load_dict({"type": "path", "max_depth": cbox_small["max_depth"]})
    assert_agree(render_passes(scene, 8, 128),
                 render_passes(scene, 8, 64, integrator=path, seed0=7))


@pytest.mark.parametrize("strategy", ["uniform", "cosine"])
def test_delta_bsdf_falls_back_to_bsdf_sampling(strategy, cbox_small):
    """A mirror sphere and a glass sphere (delta lobes) under uniform/cosine stay correct."""
    for glossy in ['<bsdf type="conductor"/>', '<bsdf type="dielectric"/>']:
        scene = cbox_variant(glossy=glossy, strategy=strategy, **cbox_small)
        path = mi.load_dict({"type": "path", "max_depth": cbox_small["max_depth"]})
        assert_agree(render_passes(scene, 6, 128),
                     render_passes(scene, 6, 64, integrator=path, seed0=7))


class WriteupPhong(mi.BSDF):
    """Negative control: the writeup's bug, dividing by the chosen lobe's pdf only."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        self.inner = mi.load_dict({"type": "phong", "diffuse_reflectance": 0.2,
                                   "specular_reflectance": 0.7, "exponent": 50.0})
        self.m_flags = self.inner.m_flags
        self.m_components = self.inner.m_components

    def sample(self, ctx, si, s1, s2, active=True):
        bs, _ = self.inner.sample(ctx, si, s1, s2, active)
        value = self.inner.eval(ctx, si, bs.wo, active)
        kd, ks, p = self.inner._lobes(ctx, si, active)
        glossy = mi.has_flag(bs.sampled_type, mi.BSDFFlags.GlossyReflection)
        lobe_pdf = dr.select(glossy, p * self.inner._glossy_pdf(si.wi, bs.wo),
                             (1 - p) * dr.maximum(bs.wo.z, 0) * dr.inv_pi)
        return bs, dr.select(lobe_pdf > 0, value / dr.maximum(lobe_pdf, 1e-20), 0.0)

    def eval(self, ctx, si, wo, active=True):
        return self.inner.eval(ctx, si, wo, active)

    def pdf(self, ctx, si, wo, active=True):
        return self.inner.pdf(ctx, si, wo, active)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self.inner.eval_pdf(ctx, si, wo, active)


def test_writeup_darkening_bug_is_detected(cbox_small):
    """The agreement test must reject a sampler whose weight uses the chosen lobe's pdf."""
    mi.register_bsdf("writeup_phong", lambda props: WriteupPhong(props))
    correct = '<bsdf type="phong"><float name="diffuse_reflectance" value="0.2"/>' \
              '<float name="specular_reflectance" value="0.7"/><float name="exponent" value="50"/></bsdf>'
    good = render_passes(cbox_variant(glossy=correct, strategy="bsdf", **cbox_small), 8, 128)
    bad = render_passes(cbox_variant(glossy='<bsdf type="writeup_phong"/>', strategy="bsdf",
                                     **cbox_small), 8, 128)
    with pytest.raises(AssertionError):
        assert_agree(good, bad)


# -------------------------------------------------------------- behaviour

def test_same_seed_same_image_different_seed_different():
    scene = mi.load_file(scene_path("cbox.xml"), width=32, height=16, spp=4)
    a = np.array(mi.render(scene, seed=5))
    b = np.array(mi.render(scene, seed=5))
    c = np.array(mi.render(scene, seed=6))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_max_depth_one_shows_only_emitters_and_hide_emitters_hides_them():
    scene = mi.load_file(scene_path("furnace.xml"), max_depth=1)
    assert np.all(np.array(mi.render(scene)) == 1.0)             # Le, exactly
    hidden = mi.load_dict({"type": "vr_path", "hide_emitters": True, "max_depth": 1})
    assert np.all(np.array(mi.render(scene, integrator=hidden)) == 0)
    scene = mi.load_file(scene_path("cbox.xml"), width=32, height=16, spp=4, max_depth=1)
    assert np.all(np.array(mi.render(scene)) == 0)               # the light is out of view


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_max_depth_zero_renders_black_as_path(strategy):
    scene = mi.load_file(scene_path("furnace.xml"), max_depth=0, strategy=strategy)
    assert np.all(np.array(mi.render(scene, spp=2)) == 0)
    path = mi.load_dict({"type": "path", "max_depth": 0})
    assert np.all(np.array(mi.render(scene, integrator=path, spp=2)) == 0)


def _light_in_front_of_wall(integrator):
    """An area light covering the view, 0.5 in front of a red wall, constant environment."""
    return mi.load_dict({
        "type": "scene", "integrator": integrator,
        "sensor": {"type": "perspective", "fov": 20,
                   "film": {"type": "hdrfilm", "width": 4, "height": 4, "rfilter": {"type": "box"}}},
        "light": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, 3])
                  .rotate([0, 1, 0], 180), "emitter": {"type": "area", "radiance": 10.0}},
        "wall": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, 3.5])
                 .rotate([0, 1, 0], 180).scale(5),
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0, 0]}}},
        "env": {"type": "constant", "radiance": 1.0}})


@pytest.mark.parametrize("nee", [False, True])
def test_hide_emitters_sees_through_area_lights_as_path(nee):
    """Camera rays pass through hidden area emitters (Mitsuba 3.9's path): the pixels show
    the red wall behind the light (lit by the environment around the light), not the
    light, and agree with path."""
    vr = {"type": "vr_path", "hide_emitters": True, "emitter_sampling": nee, "max_depth": 3}
    img = np.array(mi.render(_light_in_front_of_wall(vr), spp=256, seed=1))
    ref = np.array(mi.render(_light_in_front_of_wall({"type": "path", "hide_emitters": True,
                                                      "max_depth": 3}), spp=256, seed=2))
    assert np.all(img[..., 1:] == 0) and np.all(img[..., 0] > 0)     # the red wall, not the light
    assert abs(img.mean() - ref.mean()) < 0.05 * ref.mean()


def test_participating_medium_is_refused_with_its_name():
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "vr_path"},
                          "sensor": {"type": "perspective",
                                     "film": {"type": "hdrfilm", "width": 4, "height": 4}},
                          "fog": {"type": "sphere", "bsdf": {"type": "null"},
                                  "interior": {"type": "homogeneous", "id": "thick_fog"}}})
    with pytest.raises(Exception) as info:
        mi.render(scene, spp=1)
    chain, e = [], info.value       # mi.render re-raises it as the cause of its own error
    while e is not None:
        chain.append(str(e))
        e = e.__cause__ or e.__context__
    expected = r"medium \('thick_fog', HomogeneousMedium.*'fog'.*volpath"
    assert any(re.search(expected, m) for m in chain), chain


def test_delta_emitter_without_nee_warns():
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "vr_path"},
                          "sensor": {"type": "perspective",
                                     "film": {"type": "hdrfilm", "width": 4, "height": 4}},
                          "bulb": {"type": "point", "position": [0, 0, 1]}})
    with pytest.warns(RuntimeWarning, match="bulb.*emitter_sampling"):
        mi.render(scene, spp=1)


@pytest.mark.parametrize("props,match", [
    ({"strategy": "halton"}, r"'halton'.*uniform, cosine, bsdf"),
    ({"max_depth": -2}, r"max_depth.*-2"),
    ({"rr_depth": 0}, r"rr_depth.*0"),
])
def test_bad_parameters_raise(props, match):
    with pytest.raises(Exception, match=match):
        mi.load_dict({"type": "vr_path", **props})


def test_xml_loading_of_plugins():
    scene = mi.load_file(scene_path("cbox.xml"), width=8, height=4, spp=1)
    assert type(scene.integrator()).__name__ == "VRPathIntegrator"
    bsdfs = {type(s.bsdf()).__name__ for s in scene.shapes()}
    assert "PhongBSDF" in bsdfs
    assert scene.integrator().strategy == "bsdf"


def test_registration_follows_variant_switch():
    mi.set_variant("llvm_ad_mono")
    try:
        scene = mi.load_file(scene_path("furnace.xml"), spp=16, max_depth=2)
        img = np.array(mi.render(scene))
        assert img.shape[-1] == 1 and np.allclose(img, 1.5)  # emission + rho * emission
        assert mi.load_dict({"type": "phong"}) is not None
    finally:
        mi.set_variant("llvm_ad_rgb")
    # Back in the first variant, its own classes are still the registered ones.
    for plugin in ({"type": "phong"}, {"type": "vr_path"}, {"type": "halton"}):
        obj = mi.load_dict(plugin)
        assert isinstance(obj, (mi.BSDF, mi.SamplingIntegrator, mi.Sampler))
    # fork() builds this variant's class (not the one of the variant it was defined
    # first in): a new object, the same settings, its own state, the same draws.
    sampler = mi.load_dict({"type": "halton", "sample_count": 8, "seed": 3,
                            "randomization": "permute_digits"})
    fork = sampler.fork()
    assert fork is not sampler and type(fork) is type(sampler)
    assert isinstance(fork, mi.Sampler)
    assert (fork.sample_count(), fork.base_seed, fork.randomization) == (8, 3, "permute_digits")
    sampler.seed(5, 16)
    fork.seed(5, 16)
    first = np.array(fork.next_1d())
    second = np.array(fork.next_1d())
    assert not np.array_equal(first, second)
    assert np.array_equal(np.array(sampler.next_1d()), first)   # fork's draws left it alone


def _python(code):
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)


def test_import_before_variant_registers_later():
    result = _python("import integrators, mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
                     "print(mi.load_dict({'type': 'vr_path', 'strategy': 'cosine'}))")
    assert result.returncode == 0, result.stderr
    assert "strategy=cosine" in result.stdout


def test_scalar_variant_gives_clear_error():
    result = _python("import mitsuba as mi; mi.set_variant('scalar_rgb'); import integrators")
    assert result.returncode != 0
    assert "variant 'scalar_rgb' is not supported" in result.stderr
    assert "Traceback" in result.stderr   # an ImportError, raised at import


def test_llvm_version_is_usable():
    assert dr.detail.llvm_version()[0] >= 17
