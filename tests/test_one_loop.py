"""One loop under every study: a method that learns is the same method in every study.

The convergence study's ladder and the scene suite's equal-spp budget both go through
:meth:`experiments.lib.engine.Engine.run`. On the bundled door_room (48x36, 1024 spp, three
repeats), where the guide pays most, both must measure the same gain of ``guided+nee`` over
``path`` (relMSE at 1024 spp, the reference's floor subtracted): their 95% intervals
overlap, and both exclude 1. Negative control: the ladder as it was (the learning method's
rungs as a sum of stretches of 1, 1, 2, ..., 512 spp, each too short to train) gives a gain
whose interval lies below the suite's, near 1: the two studies would disagree.

Both runs are measured against one reference (path, 16384 spp), so that its floor is well
under guided+nee's error and the gains are known to a few tens of percent.
"""
from __future__ import annotations

import dataclasses

import pytest

import scenes
from experiments.lib import cli, methods, stats
from experiments.lib.declaration import Cell
from experiments.lib.engine import Engine
from experiments.lib.study import Study
from experiments.lib.studies import convergence
from experiments.lib.studies.suite import declare
from experiments.lib.studies.suite import study as suite

DOOR = scenes.path("suite/door_room.xml")
SPP, REPEATS, FILM, REFERENCE_SPP = 1024, 3, "48x36", 16384
METHODS = "guided+nee,path"


def _convergence(out):
    args = cli.parse_args(convergence.build_parser(), [
        "--scene", DOOR, "--resolution", FILM, "--spp", str(SPP), "--repeats", str(REPEATS),
        "--methods", METHODS, "--reference-spp", str(REFERENCE_SPP), "--out", str(out)])
    settings = convergence.settings_from(args)
    decl = convergence.declare(settings)
    # the ladder is what differs between the studies; the equal-time budget is not needed
    return Engine(Study(settings)), dataclasses.replace(decl, budgets=decl.budgets[:1])


def _suite(out):
    cfg = suite.settings(suite.parse([
        "--scenes", DOOR, "--resolution", FILM, "--spp", str(SPP), "--repeats", str(REPEATS),
        "--methods", METHODS, "--out", str(out)]))
    decl = declare.declaration(cfg, declare.plan_scenes(cfg))
    chosen = tuple(m for m in decl.methods if m.name in METHODS.split(","))
    return Engine(Study(cfg)), dataclasses.replace(decl, methods=chosen,
                                                   budgets=decl.budgets[:1])


def _gain(measured, scene: str, budget: str) -> stats.Estimate:
    """relMSE of path over guided+nee at the cell's last rung, per repeat, the
    reference's floor subtracted."""
    def excess(method):
        cell = Cell(scene, method, budget)
        return [r.relmse - measured.floor(cell) for r in measured.final(cell)]
    return stats.ratio_interval([excess("path")], [excess("guided+nee")])


@pytest.fixture(scope="module")
def gains(tmp_path_factory):
    out = tmp_path_factory.mktemp("one-loop")
    engine, decl = _convergence(out)
    refs = engine.references(decl)
    conv = _gain(engine.run(decl, refs), "scene", decl.budgets[0].name)
    s_engine, s_decl = _suite(out)
    own = {("door_room", None): refs[("scene", None)]}
    in_suite = _gain(s_engine.run(s_decl, own), "door_room", s_decl.budgets[0].name)
    # the negative control: the learning method's rungs summed from untrained stretches
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(methods.Method, "learns", property(lambda self: False))
        old = dataclasses.replace(decl, name="convergence-old-ladder",
                                  key=lambda d, c: f"old-ladder/{c.method}")
        stretched = _gain(engine.run(old, refs), "scene", decl.budgets[0].name)
    return conv, in_suite, stretched


def test_the_convergence_study_and_the_suite_agree_on_a_learning_methods_gain(gains):
    conv, in_suite, _ = gains
    assert conv.lo > 1.5 and in_suite.lo > 1.5, (conv, in_suite)
    assert conv.lo <= in_suite.hi and in_suite.lo <= conv.hi, (conv, in_suite)


def test_the_old_ladder_never_trains_and_disagrees_with_the_suite(gains):
    _, in_suite, stretched = gains
    assert stretched.hi < in_suite.lo, (stretched, in_suite)
    assert stretched.lo < 1.3, stretched
