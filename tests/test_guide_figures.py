"""Seeing the guide (experiments/lib/guide_figures.py, studies/lab/guide.py): the figure's
files on a tiny film, the units map (every pixel a valid unit or -1 for a miss), the picks, the
suite's choice of scenes, and the lab's frozen-guide panels: they pass the chi-square,
mass and albedo checks, and a guide whose density is 10% high fails them (negative
control)."""
import types

import mitsuba as mi
import numpy as np
import pytest

from _paths import scene_path
from experiments.lib import guide_figures
from experiments.lib.methods import parse_method
from experiments.lib.studies.lab import guide, warps
from experiments.lib.studies.lab.mass import FAIL, PASS, checks, z_value
from experiments.lib.studies.suite import report as suite_report
from integrators import sdtree, strategies

DOOR = scene_path("suite/door_room.xml")


def plane_with_misses():
    """A diffuse square under an empty sky, seen obliquely: the upper rows look past it."""
    return mi.load_dict({
        "type": "scene",
        "floor": {"type": "rectangle", "bsdf": {"type": "diffuse"}},
        "sensor": {"type": "perspective", "fov": 60,
                   "to_world": mi.ScalarTransform4f().look_at([0, -2.5, 1.2], [0, 0, 0.6],
                                                              [0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": 16, "height": 12}}})


def test_units_map_is_a_unit_per_hit_and_minus_one_per_miss():
    scene = plane_with_misses()
    tree = sdtree.SDTree(4, 8)
    tree.set_bbox(scene.bbox())
    units = guide_figures.unit_map(tree, scene, scene.sensors()[0])
    assert units.shape == (12, 16) and units.dtype == np.int64
    assert (units == -1).any() and (units >= 0).any()       # the sky and the floor
    # one leaf: the floor (normal +z) is unit 0 * CLASSES + 4, nothing else is hit
    assert set(np.unique(units[units >= 0])) == {4}
    assert (units[0] == -1).all() and (units[-1, 4:12] == 4).all()  # top: sky; floor


def test_pick_units_chooses_learned_units_at_their_own_pixels():
    tree = sdtree.SDTree(4, 8)
    units = np.full((6, 8), -1)
    units[:, :4], units[:3, 4:], units[3:, 4:] = 4, 10, 11
    tree.learned[[4, 10]] = True
    tree.share[[4, 10]] = [0.9, 0.3]
    picks = guide_figures.pick_units(units, tree, 4)
    assert [u for u, _ in picks] == [10, 4]           # learned only; the most guided first
    assert all(units[y, x] == u for u, (x, y) in picks)
    assert guide_figures.pick_units(units, tree, 4, pixels=[(5, 4), (0, 0)]) == \
        [(11, (5, 4)), (4, (0, 0))]


def test_guide_figure_writes_its_files_on_a_tiny_film(tmp_path):
    fig = guide_figures.guide_figure(str(tmp_path / "door"), DOOR, 12, 9, spp=16)
    for path in (fig.png, fig.pdf):
        with open(path, "rb") as f:
            assert len(f.read()) > 1000
    assert fig.units.shape == (9, 12)
    valid = fig.units[fig.units >= 0]
    assert ((fig.units == -1) | (fig.units >= 0)).all()
    assert valid.size == fig.units.size                # a closed room: every ray hits
    assert valid.max() < fig.leaves * sdtree.CLASSES
    assert 1 <= len(fig.picks) <= guide_figures.PICKS
    assert fig.train_seconds > 0 and fig.seconds >= fig.train_seconds
    assert "12x9" in fig.caption("door_room", 12, 9, 16, "guided+nee")


def test_suite_draws_the_guide_only_where_a_guiding_method_rendered():
    cfg = types.SimpleNamespace(methods=[parse_method(m) for m in ("path", "guided+nee")],
                                baseline=parse_method("path"))
    header = types.SimpleNamespace(favours=("guided+nee*",))
    scene = types.SimpleNamespace(left_out={}, header=header)
    assert suite_report.guide_method(cfg, scene, {}).name == "guided+nee"
    scene.header = None                                  # a user's scene: no hypothesis
    assert suite_report.guide_method(cfg, scene, {}).name == "guided+nee"
    scene.header = types.SimpleNamespace(favours=("bsdf+nee*", "path"))
    assert suite_report.guide_method(cfg, scene, {}) is None     # not a guiding scene
    scene.header = types.SimpleNamespace(favours=("*+nee*",))
    assert suite_report.guide_method(cfg, scene, {}) is None     # matches bsdf+nee too
    scene.header = header
    assert suite_report.guide_method(cfg, scene, {"guided+nee": "boom"}) is None
    assert suite_report.guide_method(cfg, types.SimpleNamespace(
        left_out={"guided+nee": "not in the header"}, header=header), {}) is None


class Scaled(strategies.Strategy):
    """``base``'s directions with ``factor`` x its density, reported and weighted by."""
    dispatch = False

    def __init__(self, base, factor):
        self.base, self.factor = base, factor

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        ds = self.base.sample(bsdf, ctx, si, sample1, sample2, active)
        return ds._replace(pdf=ds.pdf * self.factor, weight=ds.weight / self.factor)

    def pdf(self, bsdf, ctx, si, wo, active):
        return self.factor * self.base.pdf(bsdf, ctx, si, wo, active)


@pytest.fixture(scope="module")
def trained():
    return guide_figures.train(DOOR, 32, 24, "guided+nee", 128, 3)


def test_frozen_guide_panels_pass_and_a_ten_percent_high_density_fails(trained):
    cfg = guide.GuideConfig(DOOR, 32, 24, 128, 0, sites=2, samples=100_000)
    specs, panels, _ = guide.compute(cfg, trained=trained)
    assert len(specs) == 2
    assert all(s.strategy == "guided (frozen, trained on door_room)" for s in specs)
    # the guide is in use at the points checked (else this would test BSDF sampling)
    assert any(trained.tree.share[s.bsdf["unit"]] < 1.0 for s in specs)
    rows = guide.rows_of(specs, panels)
    alpha, z = warps.significance(2 * len(rows)), z_value(4 * len(rows))
    for r in rows:
        mass, albedo = checks(r, r["samples"], z)
        assert r["p_value"] >= alpha, r
        assert mass.verdict == PASS and albedo.verdict != FAIL, r
    # negative control: the same guide reporting (and weighting by) 1.1 x its density
    bad_specs, bad, _ = guide.compute(cfg, trained=trained,
                                          strategy=Scaled(trained.strategy, 1.1))
    for r in guide.rows_of(bad_specs, bad):
        mass, albedo = checks(r, r["samples"], z)
        assert r["p_value"] < alpha
        assert mass.verdict == FAIL and mass.low > 1.05
        assert albedo.verdict == FAIL


def test_frozen_guide_panels_are_cached(tmp_path, monkeypatch):
    cfg = guide.GuideConfig(DOOR, 16, 12, 16, 0, sites=1, samples=2000)
    first = guide.measure(cfg, str(tmp_path))
    monkeypatch.setattr(guide, "compute", lambda *a, **k: pytest.fail("recomputed"))
    again = guide.measure(cfg, str(tmp_path))
    assert again.cached and not first.cached
    assert again.rows == first.rows
