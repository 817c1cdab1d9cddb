"""Strategies as objects (``integrators.strategies``): the registry, and a user's strategy
through every check a built-in one gets.

* The registry: the built-in names in order, importable before a variant is set; a
  registered object is shared, a registered factory makes one object per ``vr_path``;
  unknown names list the registered ones; a name is taken once unless replaced; bad
  registrations get errors that name the bad value.
* A user strategy written as a file would write it (:class:`MirrorLobe`: a cos^n lobe
  about the mirror direction, only ``sample`` and ``pdf``), and mixtures of it and of
  built-in strategies: their directions follow their densities (the chi-square
  machinery of ``test_strategy_warps``, significance 0.01 Sidak-corrected over the
  grid), the defaults of ``eval_pdf`` and ``sample_and_eval`` agree with ``sample`` and
  ``pdf``, BSDFs with a delta lobe take their own sampling, and renders through
  ``vr_path`` by name agree with Mitsuba's ``path`` per pixel block and pooled
  (``_blocks``, 0.01 Sidak-corrected over every comparison of the module).
* Negative controls of realistic size: a copy of the lobe whose density is off by a
  direction-dependent factor (it reports exponent 2n, draws n) fails the chi-square
  test and the render agreement; the lobe alone, whose density is 0 on part of the
  hemisphere where a diffuse BSDF is not (no defensive mixture), fails the render
  agreement.
"""
import os
import subprocess
import sys

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import _blocks as B
import integrators
from experiments.lib import extensions
import integrators.path as vr_path
from conftest import ROOT
from integrators import strategies, warps
from test_strategy_warps import BSDFS, strategy_chi2

SIGNIFICANCE = 0.01

#: The user strategy of the worked example (examples/mirror_lobe.py, docs/extending.md),
#: loaded from its file as a researcher's own file is (it registers ``mirror_lobe``).
EXAMPLE = extensions.load(os.path.join(ROOT, "examples", "mirror_lobe.py"))
MirrorLobe = EXAMPLE.MirrorLobe


class WrongMirrorLobe(MirrorLobe):
    """Negative control: draws the cos^n lobe, reports the density of cos^2n (still
    normalised, off by the direction-dependent factor (2n+1)/(n+1) cos^n)."""

    def pdf(self, bsdf, ctx, si, wo, active):
        local = mi.Frame3f(mi.reflect(si.wi)).to_local(wo)
        return warps.square_to_phong_lobe_pdf(local, 2.0 * self.exponent)


#: The user strategies of this module, registered for its duration (see ``user``).
USER = {
    "mirror_lobe_alone": MirrorLobe,                                  # a factory (class)
    "mirror_mix": EXAMPLE.mirror_lobe,                                # the example's own
    "uniform_bsdf": strategies.Mixture(strategies.uniform, strategies.bsdf, 0.5),  # shared
    "wrong_mirror_mix": lambda: strategies.Mixture(WrongMirrorLobe(), strategies.cosine,
                                                   0.5),
}


#: Strategies the package registers beside the built-in ones (integrators/guided.py).
PACKAGED = ("guided",)


@pytest.fixture(scope="module", autouse=True)
def user():
    for name, strategy in USER.items():
        integrators.register_strategy(name, strategy)
    yield
    for name in (*USER, "mirror_lobe"):             # and the example file's own
        strategies.unregister(name)
    assert strategies.names() == strategies.BUILTIN + PACKAGED


@pytest.fixture
def scratch():
    """Register names for one test; removed afterwards."""
    added = []

    def add(name, strategy, **kw):
        integrators.register_strategy(name, strategy, **kw)
        added.append(name)
    yield add
    for name in dict.fromkeys(added):
        strategies.unregister(name)


def local_vertex(cos_i, n):
    from _chi2 import incident, interaction
    return interaction(incident(cos_i), n)


def same(a, b) -> bool:
    """Bit for bit equal (a Dr.Jit literal of width 1 broadcast to the other's width)."""
    return np.array_equal(*np.broadcast_arrays(np.array(a), np.array(b)))


def samples(n):
    u = (dr.arange(mi.Float, n) + 0.5) / n
    return u, mi.Point2f(u * 37.0 - dr.floor(u * 37.0), u * 101.0 - dr.floor(u * 101.0))


# ---------------------------------------------------------------- registry

def test_builtin_strategies_in_order_and_as_objects():
    assert strategies.BUILTIN == ("uniform", "cosine", "bsdf", "mis")
    assert strategies.names()[:4] == strategies.BUILTIN
    assert strategies.names()[4:] == (*PACKAGED, "mirror_lobe", *USER)  # registration order
    from integrators import choices
    assert choices.STRATEGIES == vr_path.STRATEGIES == strategies.BUILTIN
    for name in strategies.BUILTIN:
        assert strategies.get(name) is getattr(strategies, name)
    mis = strategies.mis
    assert isinstance(mis, strategies.Mixture)
    assert (mis.a, mis.b, mis.weight) == (strategies.cosine, strategies.bsdf,
                                          strategies.MIS_COSINE_WEIGHT)
    assert not strategies.bsdf.dispatch and strategies.cosine.dispatch and mis.dispatch


def test_registry_is_usable_before_a_variant_is_set():
    """Names are listed (``guided`` too: its class comes with a variant, its name and
    integrator before, so that ``guided+nee`` parses), and a user strategy defined and
    registered, before mi.set_variant; it renders by name once a variant is set."""
    code = (
        "import integrators, mitsuba as mi\n"
        "from integrators import strategies, choices\n"
        "assert mi.variant() is None\n"
        "print(strategies.names(), choices.STRATEGIES)\n"
        "print(strategies.integrator_type('guided'))\n"
        "try:\n"
        "    strategies.get('guided')\n"
        "except RuntimeError as e:\n"
        "    print('set_variant' in str(e))\n"
        "class Cos(strategies.Strategy):\n"
        "    def sample(self, bsdf, ctx, si, s1, s2, active):\n"
        "        return strategies.cosine.sample(bsdf, ctx, si, s1, s2, active)\n"
        "    def pdf(self, bsdf, ctx, si, wo, active):\n"
        "        return strategies.cosine.pdf(bsdf, ctx, si, wo, active)\n"
        "integrators.register_strategy('early', Cos)\n"
        "assert mi.variant() is None\n"
        "mi.set_variant('llvm_ad_rgb')\n"
        "scene = mi.load_dict({**mi.cornell_box(), 'integrator': {'type': 'vr_path', "
        "'strategy': 'early'}})\n"
        "print(type(scene.integrator().sampling_strategy).__name__, "
        "float(mi.render(scene, spp=4).numpy().mean()) > 0)\n")
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        "('uniform', 'cosine', 'bsdf', 'mis', 'guided') ('uniform', 'cosine', 'bsdf', 'mis')",
        "vr_guided_path", "True", "Cos True"]


def test_an_object_is_shared_and_a_factory_makes_one_per_vr_path():
    assert strategies.get("uniform_bsdf") is USER["uniform_bsdf"]
    a, b = (mi.load_dict({"type": "vr_path", "strategy": "uniform_bsdf"}) for _ in range(2))
    assert a.sampling_strategy is b.sampling_strategy is USER["uniform_bsdf"]
    for name in ("mirror_lobe_alone", "mirror_mix"):  # a class, a zero-argument callable
        a, b = (mi.load_dict({"type": "vr_path", "strategy": name}) for _ in range(2))
        assert a.strategy == name and a.sampling_strategy is not b.sampling_strategy
        assert type(a.sampling_strategy) is type(b.sampling_strategy)
        assert strategies.get(name) is not strategies.get(name)
    assert isinstance(strategies.get("mirror_lobe_alone"), MirrorLobe)


def test_unknown_name_lists_the_registered_ones():
    valid = "valid choices are uniform, cosine, bsdf, mis, guided, mirror_lobe, " + ", ".join(USER)
    with pytest.raises(ValueError, match=f"unknown strategy 'nope'; {valid}$"):
        strategies.get("nope")
    with pytest.raises(ValueError, match=f"unknown strategy 'nope'; {valid}$"):
        vr_path.sample_direction("nope", mi.load_dict({"type": "diffuse"}),
                                 mi.BSDFContext(), local_vertex(0.6, 4), *samples(4))
    with pytest.raises(RuntimeError) as error:
        mi.load_dict({"type": "vr_path", "strategy": "nope"})
    assert f"vr_path: unknown strategy 'nope'; {valid}" in str(error.value)
    with pytest.raises(TypeError, match="strategy name .* or a Strategy object, got 3"):
        strategies.resolve(3)


def test_a_name_is_taken_once_unless_replaced(scratch):
    with pytest.raises(ValueError, match="'cosine' is already registered.*replace=True"):
        integrators.register_strategy("cosine", MirrorLobe)
    scratch("mine", MirrorLobe)
    with pytest.raises(ValueError, match="'mine' is already registered"):
        integrators.register_strategy("mine", strategies.uniform)
    assert isinstance(strategies.get("mine"), MirrorLobe)
    scratch("mine", strategies.uniform, replace=True)
    assert strategies.get("mine") is strategies.uniform
    assert strategies.names().count("mine") == 1


@pytest.mark.parametrize("name", ["", "a+b", "halton:owen", "1st", "two words", None, 7])
def test_bad_names_are_refused(name):
    with pytest.raises(ValueError, match="invalid name"):
        integrators.register_strategy(name, MirrorLobe)


def test_bad_registrations_are_refused(scratch):
    with pytest.raises(TypeError, match="'x' must be a Strategy object.*got 42"):
        integrators.register_strategy("x", 42)
    scratch("returns_junk", lambda: "cosine")
    with pytest.raises(TypeError, match="'returns_junk': its factory .* returned 'cosine', "
                                        "not a Strategy"):
        strategies.get("returns_junk")
    with pytest.raises(ValueError, match="'mis' is a built-in strategy"):
        strategies.unregister("mis")
    with pytest.raises(ValueError, match="unknown strategy 'never'; valid choices are"):
        strategies.unregister("never")


@pytest.mark.parametrize("a,b,weight,error,match", [
    (strategies.uniform, "bsdf", 0.5, TypeError, "'b' must be a Strategy object, got 'bsdf'"),
    (None, strategies.bsdf, 0.5, TypeError, "'a' must be a Strategy object, got None"),
    (strategies.uniform, strategies.bsdf, 0.0, ValueError, r"in \(0, 1\), got 0.0"),
    (strategies.uniform, strategies.bsdf, 1, ValueError, r"in \(0, 1\), got 1"),
    (strategies.uniform, strategies.bsdf, "0.5", ValueError, r"in \(0, 1\), got '0.5'"),
])
def test_bad_mixtures_are_refused(a, b, weight, error, match):
    with pytest.raises(error, match=match):
        strategies.Mixture(a, b, weight)


def test_a_strategy_without_sample_or_pdf_says_which():
    with pytest.raises(NotImplementedError, match="Half.pdf"):
        type("Half", (strategies.Strategy,), {})().pdf(None, None, None, None, None)


# ------------------------------------------------------------ the protocol

def test_mixture_density_is_the_weighted_sum():
    """Mixture(uniform, bsdf, 0.3): 0.3 / (2 pi) + 0.7 p_bsdf, exactly, by object and name."""
    bsdf = mi.load_dict(BSDFS["phong"])
    ctx, si = mi.BSDFContext(), local_vertex(0.6, 1)
    wo = dr.normalize(mi.Vector3f(-0.5, 0.2, 0.7))
    mixture = strategies.Mixture(strategies.uniform, strategies.bsdf, 0.3)
    expected = 0.3 / (2 * np.pi) + 0.7 * bsdf.pdf(ctx, si, wo)[0]
    assert vr_path.direction_pdf(mixture, bsdf, ctx, si, wo)[0] == pytest.approx(expected,
                                                                                 rel=1e-6)
    expected = 0.5 / (2 * np.pi) + 0.5 * bsdf.pdf(ctx, si, wo)[0]
    assert vr_path.direction_pdf("uniform_bsdf", bsdf, ctx, si, wo)[0] == pytest.approx(
        expected, rel=1e-6)


@pytest.mark.parametrize("name", ["phong", "roughdielectric", "dielectric", "conductor"])
def test_defaults_and_the_delta_fallback_for_a_user_strategy(name):
    """A strategy that writes only sample and pdf: its NEE form is its sample plus
    bsdf.eval and its pdf at wo_em (through dr.dispatch and on one BSDF); on BSDFs with
    a delta lobe every answer is the BSDF's own sampling's, bit for bit."""
    bsdf = mi.load_dict(BSDFS.get(name, {"type": name}))
    ctx, n = mi.BSDFContext(), 1024
    u, u2 = samples(n)
    si = local_vertex(0.6, n)
    wo_em = dr.normalize(mi.Vector3f(u2.x - 0.5, u2.y - 0.5, u - 0.3))
    lobe = MirrorLobe()
    delta = mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta)
    for b in (mi.BSDFPtr(bsdf), bsdf):
        vs = vr_path.sample_direction_and_eval(lobe, b, ctx, si, u, u2, wo_em)
        ds = vr_path.sample_direction(lobe, b, ctx, si, u, u2)
        own = vr_path.sample_direction_and_eval("bsdf", b, ctx, si, u, u2, wo_em)
        for field in strategies.DirectionSample._fields:
            got = getattr(vs.direction, field)
            assert same(got, getattr(ds, field)), field
            if delta:
                assert same(got, getattr(own.direction, field)), field
        pdf = vr_path.direction_pdf(lobe, b, ctx, si, wo_em)
        assert same(vs.em_pdf, pdf)
        assert same(vs.em_value, bsdf.eval(ctx, si, wo_em))
        if delta:
            assert same(pdf, bsdf.pdf(ctx, si, wo_em))
        else:
            assert same(pdf, lobe.pdf(bsdf, ctx, si, wo_em, True))
            assert same(ds.delta, False) and same(ds.null, False)


# ------------------------------------------------------------- chi-square

CHI2 = [(s, b, c) for s in ("mirror_lobe_alone", "mirror_lobe", "uniform_bsdf")
        for b in ("diffuse", "phong", "roughdielectric") for c in (1.0, 0.6, -0.6)]


@pytest.mark.parametrize("strategy,name,cos_i", CHI2,
                         ids=[f"{s}-{b}-cos{c}" for s, b, c in CHI2])
def test_user_strategy_density_matches_its_samples(strategy, name, cos_i, monkeypatch,
                                                   tmp_path):
    strategy_chi2(strategy, mi.load_dict(BSDFS[name]), cos_i, monkeypatch, tmp_path,
                  len(CHI2), seed=100 + CHI2.index((strategy, name, cos_i)))


def test_user_strategy_with_a_wrong_density_fails_the_chi2(monkeypatch, tmp_path):
    with pytest.raises(AssertionError):
        strategy_chi2(WrongMirrorLobe(), mi.load_dict(BSDFS["phong"]), 0.6, monkeypatch,
                      tmp_path, len(CHI2))


# ------------------------------------------------- renders through vr_path

RENDERS = [("mirror_lobe", False), ("mirror_lobe", True), ("uniform_bsdf", False),
           ("uniform_bsdf", True)]
CONTROLS = [("wrong_mirror_mix", False), ("mirror_lobe_alone", False)]
SEEDS, SPP, SIZE, BLOCKS_PER_IMAGE = 8, 64, 32, (32 // B.BLOCK) ** 2 * 3
ALPHA_BLOCKS = B.sidak(SIGNIFICANCE, 2 * len(RENDERS) * BLOCKS_PER_IMAGE)
ALPHA_POOLED = B.sidak(SIGNIFICANCE, 2 * len(RENDERS) * 3)


def scene_dict():
    """Mitsuba's Cornell box at 32 x 32 (box filter: independent pixels), the small box
    a glossy phong, depth 5."""
    d = mi.cornell_box()
    d["sensor"]["film"].update(width=SIZE, height=SIZE, rfilter={"type": "box"})
    d["small-box"]["bsdf"] = {"type": "phong", "diffuse_reflectance": 0.2,
                              "specular_reflectance": 0.6, "exponent": EXAMPLE.EXPONENT}
    return d


@pytest.fixture(scope="module")
def reference():
    return B.summarize(B.render(scene_dict(), {"type": "path", "max_depth": 5},
                                range(1, 1 + SEEDS), 4 * SPP))


def vr_renders(strategy, nee):
    """SEEDS renders by name; without NEE at twice the spp (more variance per sample)."""
    return B.summarize(B.render(scene_dict(), {"type": "vr_path", "strategy": strategy,
                                               "emitter_sampling": nee, "max_depth": 5},
                                range(50, 50 + SEEDS), SPP if nee else 2 * SPP))


@pytest.mark.parametrize("strategy,nee", RENDERS, ids=[f"{s}-{n}" for s, n in RENDERS])
def test_user_strategy_renders_by_name_agree_with_path(strategy, nee, reference):
    result = B.agree(vr_renders(strategy, nee), reference, ALPHA_BLOCKS, ALPHA_POOLED)
    assert result.passed, result.describe()
    assert result.detectable < 0.05, result.describe()   # the test would see a 5% bias


@pytest.mark.parametrize("strategy,nee", CONTROLS, ids=[f"{s}-{n}" for s, n in CONTROLS])
def test_wrong_user_strategies_fail_the_render_agreement(strategy, nee, reference):
    result = B.agree(vr_renders(strategy, nee), reference, ALPHA_BLOCKS, ALPHA_POOLED)
    assert not result.passed, result.describe()


def test_user_strategy_follows_a_variant_switch():
    """The registry survives mi.set_variant; a strategy uses the current variant's types."""
    d = scene_dict()
    d["integrator"] = {"type": "vr_path", "strategy": "mirror_mix", "max_depth": 3}
    mi.set_variant("llvm_ad_mono")
    try:
        img = np.array(mi.render(mi.load_dict(d), spp=8))
        assert img.shape == (SIZE, SIZE, 1) and np.all(np.isfinite(img)) and img.mean() > 0
    finally:
        mi.set_variant("llvm_ad_rgb")
    assert "mirror_mix" in strategies.names()
