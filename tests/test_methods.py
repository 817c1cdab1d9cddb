"""The method grammar: STRATEGY[+nee][+SAMPLER[:RANDOMIZATION]] and path[+SAMPLER[:RANDOMIZATION]].

Every valid form must parse to the right integrator and sampler settings (checked on the
loaded Mitsuba objects, not only on our dataclass); every invalid form must end a script
with exit code 2 and one line naming the bad part.
"""
import os

import mitsuba as mi
import numpy as np
import pytest
from conftest import scene_path

from experiments.lib.studies import convergence
from experiments.lib import methods as M
from experiments.lib import samplers as S
from experiments.lib.scenes import load_scene

STRATEGIES = M.strategies()
#: What the loaded Mitsuba sampler calls itself, for Mitsuba's own samplers.
NATIVE_NAMES = {"independent": "Independent", "stratified": "Stratified",
                "multijitter": "MultiJitter", "orthogonal": "Orthogonal",
                "ldsampler": "LowDiscrepancy"}


def valid_forms():
    """(name, strategy or None for path, nee, sampler, randomization) for every form."""
    forms = [("uniform+halton", "uniform", False, "halton", "none")]     # the writeup's
    heads = ([(s, s, False) for s in STRATEGIES] + [(s + "+nee", s, True) for s in STRATEGIES]
             + [("path", None, True)])
    for stem, strategy, nee in heads:
        forms.append((stem, strategy, nee, "independent", None))
        for sampler in S.names():
            if strategy and S.get(sampler).bakes_spp and \
                    M.parse_method(strategy).integrator != "vr_path":
                continue        # a strategy that learns refuses them (test_guiding.py)
            if f"{stem}+{sampler}" not in M.FIXED:                      # fixed name above
                forms.append((f"{stem}+{sampler}", strategy, nee, sampler, None))
            forms += [(f"{stem}+{sampler}:{r}", strategy, nee, sampler, r)
                      for r in S.get(sampler).randomizations]
    return forms


@pytest.mark.parametrize("name, strategy, nee, sampler, randomization", valid_forms(),
                         ids=[f[0] for f in valid_forms()])
def test_every_valid_form_parses_to_the_right_settings(name, strategy, nee, sampler,
                                                       randomization):
    m = M.parse_method(name)
    assert (m.strategy, m.nee, m.sampler, m.randomization) == (strategy, nee, sampler,
                                                               randomization)
    scene = load_scene(scene_path("cbox.xml"), 8, 4, m, M.Depth(3, 2, None))
    integrator, s = scene.integrator(), scene.sensors()[0].sampler()
    if strategy is None:
        assert type(integrator).__name__ == "PathIntegrator" or "PathIntegrator" in str(
            integrator)
        assert "max_depth = 3" in str(integrator)
    else:
        assert (integrator.strategy, integrator.emitter_sampling, integrator.max_depth,
                integrator.rr_depth) == (strategy, nee, 3, 2)
    expected = NATIVE_NAMES.get(sampler, sampler)     # a Python plugin: its class names it
    assert expected.lower() in (type(s).__name__ + str(s)).lower()
    if sampler == "halton":
        want = randomization or "owen"                     # the sampler's documented default
        assert s.randomization == want


INVALID = [
    ("phong", "strategy 'phong'"),
    ("", "strategy ''"),
    ("bsdf+sobol", "sampler 'sobol'"),
    ("cosine:owen", "strategy 'cosine:owen'"),
    ("bsdf+stratified:owen", "sampler 'stratified' takes no randomization"),
    ("bsdf+halton:bogus", "randomization 'bogus'"),
    ("bsdf+halton:", "randomization ''"),
    ("path+nee", "path always uses next-event estimation"),
    ("bsdf+nee+nee", "sampler 'nee'"),
    ("bsdf+halton+nee", "too many parts"),
    ("nee+bsdf", "strategy 'nee'"),
    ("BSDF", "strategy 'BSDF'"),
]


@pytest.mark.parametrize("name, part", INVALID, ids=[n or "empty" for n, _ in INVALID])
def test_every_invalid_form_exits_2_with_one_line(name, part, capsys, tmp_path, monkeypatch):
    with pytest.raises(ValueError, match="unknown method"):
        M.parse_method(name)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        convergence.STUDY.main(["--methods", f"cosine,{name}" if name else "cosine,,+"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    if name:
        assert f"unknown method '{name}'" in err and part in err, err
        for strategy in STRATEGIES:                  # the valid parts are listed
            assert strategy in err
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_every_listed_strategy_is_accepted_and_renders(strategy):
    """Each entry of the one strategy list is a strategy ``vr_path`` accepts and renders
    with (finite, non-negative, lit image), with and without NEE."""
    for nee in (False, True):
        scene = mi.load_file(scene_path("cbox.xml"), width=8, height=4, spp=4,
                             strategy=strategy, emitter_sampling=str(nee).lower())
        assert scene.integrator().strategy == strategy
        img = np.array(mi.render(scene, seed=1))
        assert np.all(np.isfinite(img)) and np.all(img >= 0) and img.mean() > 0, (strategy, nee)


@pytest.mark.parametrize("name", ["phong", "BSDF", "cosine+nee", ""])
def test_a_name_not_listed_is_rejected_naming_the_choices(name):
    assert name not in STRATEGIES
    with pytest.raises(Exception) as exc:
        mi.load_dict({"type": "vr_path", "strategy": name})
    message = str(exc.value) + str(exc.value.__cause__ or "")
    assert f"unknown strategy {name!r}" in message, message
    assert "valid choices are " + ", ".join(STRATEGIES) in message, message


def test_a_scene_loads_with_an_adaptive_methods_integrator():
    """The executor loads a scene with the first job's method: an adaptive one nests its
    integrator, which the scene's integrator node takes as an object."""
    scene = load_scene(scene_path("cbox.xml"), 8, 4, M.parse_method("bsdf+nee+adaptive"),
                       M.Depth(3, 2, None))
    integrator = scene.integrator()
    assert type(integrator).__name__ == "AdaptiveIntegrator"
    assert (integrator.nested.strategy, integrator.nested.emitter_sampling,
            integrator.nested.max_depth) == ("bsdf", True, 3)
