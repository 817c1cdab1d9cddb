"""The sampling lab's conclusions (lab.warps.analyse, lab.points.analyse) on synthetic numbers.

Each conclusion is a table computed from the numbers plus at most three sentences computed
from that table, none over 80 words. Negative controls: a panel whose p-value is below the
Sidak level is counted as rejected and one just above it is not; a pair whose discrepancy
is that of independent points is "lost" and a stratified one is not; swapping which sampler
stratifies the NEE sample better swaps the prediction; bundled or native comes from the
sampler table's flag, not from the name.
"""
import math

import pytest

from experiments.lib.studies.lab import points, warps
from experiments.lib.studies.sampler_comparison.analysis import Family


def panel(bsdf, inc, strategy, p, rel):
    return {"bsdf": bsdf, "incidence_deg": inc, "strategy": strategy, "p_value": p,
            "rel_variance": rel}


def warp_rows(p_bad=0.3):
    rows = []
    for bsdf in ("phong n=10", "phong n=1000"):
        for inc in (0.0, 85.0):
            rows += [panel(bsdf, inc, "uniform", 0.5, 50.0 if bsdf.endswith("1000") else 2.0),
                     panel(bsdf, inc, "cosine", 0.4, 20.0 if inc == 85.0 else 0.5),
                     panel(bsdf, inc, "bsdf", 0.6, 0.1)]
    rows[4]["p_value"] = p_bad            # cosine on phong n=10 at 85 deg
    return rows


def test_warps_conclusion_counts_what_the_numbers_say():
    found = warps.analyse(warp_rows())
    assert found.alpha == pytest.approx(warps.significance(12))
    by = {r.strategy: r for r in found.rows}
    assert [r.strategy for r in found.rows] == ["uniform", "cosine", "bsdf"]
    assert {s: r.rejected for s, r in by.items()} == {"uniform": 0, "cosine": 0, "bsdf": 0}
    assert by["uniform"].exploding == 2 and by["cosine"].exploding == 2
    assert by["bsdf"].exploding == 0 and by["bsdf"].lowest_in == 4
    assert by["uniform"].largest == 50.0 and by["uniform"].largest_at.startswith("phong n=1000")
    assert found.configurations == 4 and len(found.sentences) == 3
    assert found.sentences[0].startswith("Every one of the 12 panels accepts")
    assert "bsdf in 4 of 4" in found.sentences[1]
    assert "uniform in 2, cosine in 2 of 4 configurations (largest 50, uniform" \
        in found.sentences[2]
    assert all(len(s.split()) <= 80 for s in found.sentences)


def test_a_rejected_panel_is_reported_and_one_just_above_the_level_is_not():
    alpha = warps.significance(12)
    bad = warps.analyse(warp_rows(p_bad=alpha / 2))
    assert {r.strategy: r.rejected for r in bad.rows}["cosine"] == 1
    assert bad.sentences[0].startswith("1 of 12 panels reject")
    assert "cosine on phong n=10 at 85 deg" in bad.sentences[0]
    fine = warps.analyse(warp_rows(p_bad=alpha * 1.01))
    assert sum(r.rejected for r in fine.rows) == 0
    # many rejections stay one short sentence
    rows = [dict(r, p_value=0.0) for r in warp_rows()]
    many = warps.analyse(rows)
    assert "and 9 more (table)" in many.sentences[0]
    assert len(many.sentences[0].split()) <= 80


def test_a_cached_panel_reads_back_as_computed(tmp_path):
    """A rerun from the cache writes the same tables as the run that computed the panel
    (dof an int both times)."""
    spec = warps.PanelSpec("phong n=10", dict(warps.BSDFS)["phong n=10"], "cosine", 60.0, 2000, 1)
    first = warps.cached(spec, str(tmp_path))
    again = warps.cached(spec, str(tmp_path))
    for key in warps.SCALARS:
        assert type(first[key]) is type(again[key]) and first[key] == again[key], key
    assert isinstance(again["dof"], int)


# ------------------------------------------------------------------ point sets

PAIRS = [(0, 1), (2, 3), (10, 11), (30, 31), (1, 2)]


def point_numbers(halton_nee=0.3, owen_nee=0.1, native_nee=0.05):
    """Discrepancy ratios (to independent points) and joint powers per label and pair: the
    native 'jitter' stratifies the pairs within one call jointly, 'array' every pair;
    bundled 'halton:none'/'halton:owen' and 'mine'."""
    count = 64
    e = points.random_expectation(count)
    ratios = {
        "independent": dict.fromkeys(PAIRS, 1.0),
        "jitter": {(0, 1): 0.05, (2, 3): native_nee, (10, 11): 0.2, (30, 31): 0.2,
                   (1, 2): 0.3},
        "array": {p: 0.05 for p in PAIRS},
        "halton:none": {(0, 1): 0.1, (2, 3): halton_nee, (10, 11): 0.9, (30, 31): 3.0,
                        (1, 2): 0.1},
        "halton:owen": {(0, 1): 0.1, (2, 3): owen_nee, (10, 11): 0.4, (30, 31): 0.7,
                        (1, 2): 0.1},
        "mine": dict.fromkeys(PAIRS, 1.0)}
    joint_of = {"independent": 1.0, "jitter": None, "array": 0.1, "halton:none": 0.5,
                "halton:owen": 0.5, "mine": 1.0}
    cd, joint = {}, {}
    for s, by in ratios.items():
        for p, r in by.items():
            cd[(s, p)] = r * e
            within = p in ((0, 1), (2, 3))
            joint[(s, p)] = (0.1 if within else 0.9) if joint_of[s] is None else joint_of[s]
    return cd, joint, dict.fromkeys(ratios, count)


KINDS = {"independent": Family("independent", True), "jitter": Family("jitter", True),
         "array": Family("array", True), "halton:none": Family("halton", False),
         "halton:owen": Family("halton", False), "mine": Family("mine", False)}


def test_point_table_classifies_each_pair():
    cd, joint, counts = point_numbers()
    found = points.analyse(cd, joint, counts, 64, KINDS)
    rows = {r.sampler: r for r in found.rows}
    assert "independent" not in rows                         # the baseline
    assert rows["jitter"].joint == ((0, 1), (2, 3))
    assert rows["jitter"].coordinate == ((10, 11), (30, 31), (1, 2)) and not rows["jitter"].lost
    assert rows["array"].joint == tuple(PAIRS)
    assert rows["mine"].lost == tuple(PAIRS) and not rows["mine"].native   # negative control
    assert rows["halton:none"].lost == ((10, 11), (30, 31))
    assert rows["halton:owen"].nee == pytest.approx(0.1) and rows["halton:owen"].deep == \
        pytest.approx(0.7)
    cells = dict(zip(points.HEADER, rows["mine"].cells()))
    assert cells["kind"] == "bundled" and cells["stratified jointly (2-D)"] == "-"


def test_point_sentences_predict_from_the_table():
    cd, joint, counts = point_numbers()
    found = points.analyse(cd, joint, counts, 64, KINDS)
    first, nee, deep = found.sentences
    assert "jointly (2-D) (0, 1), (2, 3); array also every pair across calls" in first
    # the best native at NEE is 'array' (0.05 = jitter's: the first), each family's best
    assert "the best native sampler, jitter, reaches 0.05" in nee or \
        "the best native sampler, array, reaches 0.05" in nee
    assert "halton:owen 0.1 (joint power 0.50: expect higher MSE" in nee
    assert "mine 1 (joint power 1.00: expect higher MSE" in nee
    assert "halton:none" not in nee                          # not halton's best
    assert "halton 0.7-3" in deep and "native samplers 0.05-0.2" in deep
    assert all(len(s.split()) <= 80 for s in found.sentences)
    # negative control: halton:owen now stratifies the NEE sample better than every native
    better = points.analyse(*point_numbers(owen_nee=0.01), 64, KINDS)
    assert "halton:owen 0.01 (joint power 0.50: expect lower MSE" in better.sentences[1]


def test_point_kinds_come_from_the_table_not_the_name():
    """Negative control: 'mine' declared native joins the native samplers' sentences."""
    cd, joint, counts = point_numbers()
    kinds = dict(KINDS, mine=Family("mine", True))
    found = points.analyse(cd, joint, counts, 64, kinds)
    assert next(r for r in found.rows if r.sampler == "mine").native
    assert "no pair that all of them share" in found.sentences[0]
    assert "mine 1" not in found.sentences[1]
    assert math.isnan(points.analyse({("a", (0, 1)): 0.1}, {("a", (0, 1)): 0.5}, {"a": 4}, 4,
                                 {"a": Family("a", False)}).rows[0].nee)
