"""The bundled scene suite (``scenes/suite/``): every scene is listed, loads the way the
suite loads it, says in its header what it isolates and which methods should win there
in patterns that name real methods, and the furnace's exact value is right."""
import fnmatch
import math
import os
import re
import xml.etree.ElementTree as ET

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest
from scipy import stats

import scenes
from conftest import SCENES
from integrators.choices import STRATEGIES

#: Every suite scene, as names for scenes.path().
SUITE = scenes.suite_names()
#: The suite's default method names (experiments' grammar: STRATEGY[+nee][+SAMPLER],
#: ``path`` for Mitsuba's path tracer): every vr_path strategy with and without NEE,
#: path guiding with NEE, bsdf+nee with a sampler, and path.
METHODS = (list(STRATEGIES) + [f"{s}+nee" for s in STRATEGIES]
           + ["guided+nee", "bsdf+nee+independent", "path"])
#: The suite scenes that isolate what path guiding is for (their header's methods).
GUIDING = ("suite/door_room.xml", "suite/glossy_indirect.xml", "suite/hidden_lamp.xml",
           "suite/sunlit_room.xml")
#: The $ parameters every suite scene declares with a <default> (the suite sets them).
PARAMETERS = ("width", "height", "spp", "max_depth", "strategy", "emitter_sampling",
              "sampler")
#: Family-wise level of the furnace's agreement test (Sidak over its comparisons).
ALPHA = 1e-4


def defaults(file: str) -> dict:
    """The file's own <default name=... value=...> entries (not those of its includes)."""
    return {d.get("name"): d.get("value") for d in ET.parse(file).getroot().iter("default")}


def problems(text: str, source: str = "<scene>") -> list:
    """What is wrong with a scene's suite header (``text``: the scene file): nothing,
    or one line per problem (no header, a malformed one, a pattern that names no
    default method, a method that the header both favours and puts under ``over``)."""
    try:
        header = scenes.parse_header(text, source)
    except ValueError as error:
        return [str(error)]
    if header is None:
        return [f"{source}: no suite header"]
    found = []
    for key in ("favours", "over", "methods"):
        patterns = getattr(header, key)
        if not patterns and key != "methods":
            found.append(f"{source}: '{key}' lists no pattern")
        for pattern in patterns:
            if not fnmatch.filter(METHODS, pattern):
                found.append(f"{source}: {key} pattern {pattern!r} matches no method "
                             f"(methods: {', '.join(METHODS)})")
    rendered = [m for m in METHODS if m == "path" or header.renders(m)]
    favoured = {m for p in header.favours for m in fnmatch.filter(rendered, p)}
    beaten = {m for p in header.over for m in fnmatch.filter(rendered, p)}
    for key, found_methods in (("favours", favoured), ("over", beaten)):
        if getattr(header, key) and not found_methods:
            found.append(f"{source}: '{key}' names only methods that its 'methods' leaves "
                         f"out ({', '.join(header.methods)})")
    if favoured & beaten:
        found.append(f"{source}: {', '.join(sorted(favoured & beaten))} both favoured and over")
    return found


def read(name: str) -> str:
    with open(scenes.path(name), encoding="utf-8") as f:
        return f.read()


# ------------------------------------------------------------------ listing

def test_every_suite_file_is_listed_in_a_stable_order():
    on_disk = sorted(f"suite/{n}" for n in os.listdir(os.path.join(SCENES, "suite"))
                     if n.endswith(".xml"))
    assert SUITE == on_disk
    assert len(SUITE) >= 9                      # the writeup's box and at least 8 new scenes
    assert "suite/cbox.xml" in SUITE and "suite/furnace.xml" in SUITE
    assert scenes.suite() == [scenes.path(n) for n in SUITE]
    for name, file in zip(SUITE, scenes.suite()):
        assert os.path.samefile(file, os.path.join(SCENES, *name.split("/")))


def test_unknown_scene_is_named_with_the_choices():
    with pytest.raises(FileNotFoundError, match=r"suite/nope\.xml.*suite/cbox\.xml"):
        scenes.path("suite/nope.xml")


# ------------------------------------------------------------------ headers

@pytest.mark.parametrize("name", SUITE)
def test_header_is_complete_and_names_real_methods(name):
    assert problems(read(name), name) == []
    header = scenes.header(scenes.path(name))
    assert all(getattr(header, key).strip() for key in ("isolates", "hypothesis"))


GOOD = """<!--
suite:
  isolates: a thing
  hypothesis: bsdf wins
  favours: bsdf*
  over: uniform, cosine
-->
<scene version="3.0.0"/>
"""


def test_header_check_accepts_a_good_header():
    assert problems(GOOD) == []
    header = scenes.parse_header(GOOD)
    assert header.favours == ("bsdf*",) and header.over == ("uniform", "cosine")
    assert header.exact is None


@pytest.mark.parametrize("broken, message", [
    (GOOD.replace("  over: uniform, cosine\n", ""), "lacks over"),
    (GOOD.replace("  isolates: a thing\n", ""), "lacks isolates"),
    (GOOD.replace("bsdf*", "bsfd*"), "'bsfd\\*' matches no method"),
    (GOOD.replace("uniform, cosine", "uniform, halton"), "'halton' matches no method"),
    (GOOD.replace("uniform, cosine", "uniform, bsdf+nee"), "both favoured and over"),
    (GOOD.replace("  over:", "  under:"), "unknown suite header key 'under'"),
    (GOOD.replace("  over: uniform, cosine", "  over: uniform\n  over: cosine"), "twice"),
    (GOOD.replace("  over: uniform, cosine", "  over:"), "'over' is empty"),
    (GOOD.replace("-->", "  exact: two\n-->"), "'exact' is 'two'"),
    (GOOD.replace("  isolates: a thing", "isolates a thing"), "not an indented"),
    (GOOD.replace("suite:\n", ""), "no suite header"),
    (GOOD.replace("-->", "  methods: bsdf*, halton\n-->"), "methods pattern 'halton' matches"),
    (GOOD.replace("-->", "  methods: cosine, uniform\n-->"), "'favours' names only methods"),
    (GOOD.replace("-->", "  methods: , ,\n-->"), "'methods' is ', ,', which names no method"),
    (GOOD.replace("-->", "  methods: bsdf nee\n-->"), "'bsdf nee' is not a method-name pattern"),
    (GOOD.replace("-->", "  methods:\n-->"), "'methods' is empty"),
])
def test_header_check_catches(broken, message):
    """Negative controls: each defect is reported by the same check the scenes pass."""
    found = problems(broken)
    assert found, broken
    assert any(re.search(message, p) for p in found), found


def test_methods_key_keeps_the_methods_it_names():
    header = scenes.parse_header(GOOD.replace("-->", "  methods: path, bsdf+nee, guided+nee*\n-->"))
    assert header.methods == ("path", "bsdf+nee", "guided+nee*")
    assert [m for m in METHODS if header.renders(m)] == ["bsdf+nee", "guided+nee", "path"]
    assert header.renders("guided+nee+halton:owen") and not header.renders("bsdf")
    every = scenes.parse_header(GOOD)
    assert every.methods == () and all(every.renders(m) for m in METHODS)


def test_bad_methods_name_the_value_and_the_valid_form():
    with pytest.raises(ValueError, match=r"mine\.xml: suite header 'methods' entry 'a/b' is "
                                         r"not a method-name pattern.*'\*'"):
        scenes.parse_header(GOOD.replace("-->", "  methods: path, a/b\n-->"), "mine.xml")


def test_guiding_scenes_render_guiding_and_its_rival_at_a_longer_budget():
    """Every guiding scene renders path and the guide at a longer budget, the guide
    favoured over path (bsdf+nee is path's estimator: its A/A comparison is the other
    scenes', and the default run's budget goes to the guide's training)."""
    for name in GUIDING:
        header = scenes.header(scenes.path(name))
        assert header.methods == ("path", "guided+nee*"), name
        assert header.over == ("path",), name
        assert header.favours == ("guided+nee*",) and header.budget > 1, name


def test_only_the_furnace_claims_an_exact_value():
    exact = [n for n in SUITE if scenes.header(scenes.path(n)).exact is not None]
    assert exact == ["suite/furnace.xml"]


# ------------------------------------------------------------------ loading

@pytest.mark.parametrize("name", SUITE)
def test_loads_with_its_defaults_and_with_overrides(name):
    file = scenes.path(name)
    own = defaults(file)
    assert set(PARAMETERS) <= set(own), sorted(set(PARAMETERS) - set(own))

    scene = mi.load_file(file)
    sensor = scene.sensors()[0]
    assert tuple(sensor.film().size()) == (int(own["width"]), int(own["height"]))
    assert sensor.sampler().sample_count() == int(own["spp"])
    integrator = scene.integrator()
    assert type(integrator).__name__ == "VRPathIntegrator"
    assert integrator.max_depth == int(own["max_depth"])
    assert integrator.strategy == own["strategy"]
    assert int(own["width"]) * int(own["height"]) <= 64 * 64      # cheap by default

    scene = mi.load_file(file, width=10, height=6, spp=3, max_depth=3, strategy="cosine",
                         emitter_sampling=True)
    sensor = scene.sensors()[0]
    assert tuple(sensor.film().size()) == (10, 6)
    assert sensor.sampler().sample_count() == 3
    assert (scene.integrator().max_depth, scene.integrator().strategy,
            scene.integrator().emitter_sampling) == (3, "cosine", True)


@pytest.mark.parametrize("name", SUITE)
def test_renders_with_vr_path_and_with_mitsubas_path_swapped_in(name):
    """At the scene's own max_depth, both integrators give a finite image that is not black
    (the guiding scenes, lit through one bounce off a small region, with NEE and 16 spp:
    BSDF sampling alone rarely finds their light at 4)."""
    guiding = name in GUIDING
    scene = mi.load_file(scenes.path(name), width=16, height=12, spp=16 if guiding else 4,
                         emitter_sampling=guiding)
    path = mi.load_dict({"type": "path", "max_depth": scene.integrator().max_depth})
    for integrator in (scene.integrator(), path):
        img = np.array(mi.render(scene, integrator=integrator, seed=1))
        assert img.shape == (12, 16, 3)
        assert np.all(np.isfinite(img)) and img.mean() > 0, (name, integrator)


def test_the_suites_box_is_cbox_xml_at_the_suites_defaults():
    """suite/cbox.xml includes ../cbox.xml: the same shapes and emitters, its own
    defaults win over cbox.xml's, and cbox.xml's own parameters still pass through."""
    box, own = mi.load_file(os.path.join(SCENES, "cbox.xml")), mi.load_file(
        scenes.path("suite/cbox.xml"))
    ids = sorted(s.id() for s in own.shapes())       # (Mitsuba merges the white walls)
    assert ids == sorted(s.id() for s in box.shapes())
    assert {"light", "diffuse_sphere", "glossy_sphere", "left", "right"} <= set(ids)
    assert own.bbox() == box.bbox()
    outer = defaults(scenes.path("suite/cbox.xml"))
    assert tuple(own.sensors()[0].film().size()) == (int(outer["width"]), int(outer["height"]))
    assert tuple(box.sensors()[0].film().size()) != tuple(own.sensors()[0].film().size())
    narrow = mi.load_file(scenes.path("suite/cbox.xml"), light_size=0.2)
    light = [s for s in narrow.shapes() if s.id() == "light"][0]
    assert math.isclose(light.surface_area()[0], 0.4 * 0.4, rel_tol=1e-4)


# ------------------------------------------------------------------ furnace

def furnace_agrees(file: str, exact: float, **params) -> bool:
    """Does a render with Mitsuba's path agree with ``exact`` everywhere? Per channel:
    the image mean, and the mean of each 4 x 4 pixel block, against ``exact`` with a
    standard error from the pixels' spread (independent sampler, box filter: the
    pixels are independent estimates of one value); Sidak over every comparison."""
    scene = mi.load_file(file, width=16, height=16, spp=32, **params)
    path = mi.load_dict({"type": "path", "max_depth": -1})
    img = np.array(mi.render(scene, integrator=path, seed=7), dtype=np.float64)
    blocks = img.reshape(4, 4, 4, 4, 3).transpose(0, 2, 1, 3, 4).reshape(16, 16, 3)
    groups = [img.reshape(-1, 3)] + list(blocks)               # (pixels, channels) each
    level = 1 - (1 - ALPHA) ** (1 / (len(groups) * 3))
    for values in groups:
        se = values.std(axis=0, ddof=1) / math.sqrt(len(values))
        t = np.abs(values.mean(axis=0) - exact) / np.maximum(se, 1e-12)
        if np.any(t > stats.t.ppf(1 - level / 2, len(values) - 1)):
            return False
    return True


def test_furnace_exact_value_is_its_own_le_over_one_minus_rho():
    file = scenes.path("suite/furnace.xml")
    own = defaults(file)
    exact = float(own["radiance"]) / (1 - float(own["albedo"]))
    assert scenes.header(file).exact == pytest.approx(exact, rel=1e-6)
    assert int(own["max_depth"]) == -1                          # the exact value needs it
    assert furnace_agrees(file, exact)


def test_furnace_check_sees_a_wrong_albedo():
    """Negative control: a 4% error (albedo 0.52 rendered, 0.5's value claimed) fails."""
    file = scenes.path("suite/furnace.xml")
    assert not furnace_agrees(file, scenes.header(file).exact, albedo=0.52)


# ------------------------------------------------------------------ guiding scenes

#: Per guiding scene: where its camera's first hits must get no light sample through
#: (the room: NEE cannot see the light), and where some must (what the light lights
#: directly, seen from the camera): functions of the hit points (x, y, z), numpy arrays.
HIDDEN = {
    "suite/door_room.xml": (lambda x, y, z: x < 1.9, lambda x, y, z: x > 2.1),
    "suite/hidden_lamp.xml": (lambda x, y, z: z > -1.9, lambda x, y, z: (z < -1.99) &
                              (abs(x) < 0.5) & (abs(y - 1.3) < 0.3)),
    "suite/glossy_indirect.xml": (lambda x, y, z: y < 0.01, lambda x, y, z: y > 1.99),
}


def light_samples_reaching(file: str, width=48, height=36, per_pixel=64, **params):
    """First hits of the camera's pixel-centre rays, and per pixel whether any of
    ``per_pixel`` light samples from the hit (Mitsuba's emitter sampling, visibility
    tested) carries light: (x, y, z, reached), each (height, width). ``params``: the
    scene's parameters."""
    scene = mi.load_file(file, width=width, height=height, **params)
    sensor = scene.sensors()[0]
    px = np.repeat(np.arange(width * height), per_pixel)
    u = ((px % width) + 0.5) / width
    v = ((px // width) + 0.5) / height
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u, v), mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    rng = np.random.default_rng(5)
    sample = mi.Point2f(*(rng.random(px.size).astype(np.float32) for _ in range(2)))
    _, weight = scene.sample_emitter_direction(si, sample, True, si.is_valid())
    w = np.array(weight).max(axis=0)                   # (channels, lanes)
    reached = (w.reshape(-1, per_pixel) > 0).any(axis=1).reshape(height, width)
    p = [np.array(c).reshape(-1, per_pixel)[:, 0].reshape(height, width) for c in si.p]
    return (*p, reached)


@pytest.mark.parametrize("name", sorted(HIDDEN))
def test_light_samples_from_the_room_never_reach_the_light(name):
    """The guiding scenes' premise: no light sample from the hidden region reaches the
    light, while light samples from what it lights directly do (positive control)."""
    hidden, lit = HIDDEN[name]
    x, y, z, reached = light_samples_reaching(scenes.path(name))
    room, seen = hidden(x, y, z), lit(x, y, z)
    assert room.mean() > 0.4, "the camera sees the hidden region"
    assert not reached[room].any(), f"{reached[room].sum()} room pixels see the light"
    assert seen.any() and reached[seen].mean() > 0.5, "the lit region is seen and lit"


def test_the_sunlit_room_s_camera_sees_no_sunlit_point():
    """sunlit_room's premise: no point the camera sees gets a sun sample through (the sky
    turned off, every light sample is the sun's), while the patch of floor behind the
    camera does (positive control: its points, lit through the window)."""
    file = scenes.path("suite/sunlit_room.xml")
    *_, reached = light_samples_reaching(file, sky_radiance=0.0)
    assert not reached.any(), f"{reached.sum()} pixels see sunlit points"
    scene = mi.load_file(file, sky_radiance=0.0)
    rng = np.random.default_rng(2)
    n = 256
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.p = mi.Point3f(rng.uniform(0.3, 0.8, n), np.full(n, 1e-3), rng.uniform(1.4, 1.7, n))
    si.n = mi.Normal3f(0, 1, 0)
    si.sh_frame = mi.Frame3f(si.n)
    _, weight = scene.sample_emitter_direction(
        si, mi.Point2f(*(rng.random(n).astype(np.float32) for _ in range(2))), True)
    # half the samples pick the (dark) sky: every sun sample gets through
    assert (np.array(weight).max(axis=0) > 0).mean() > 0.4
