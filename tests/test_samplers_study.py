"""The sampler study's analysis (experiments.lib.studies.sampler_comparison.analysis and
.screen_analysis) on synthetic numbers.

Synthetic ladders with a known answer: every count of a ladder has R repeats whose errors
scatter around a known value (a fixed relative spread, the same pattern for every sampler,
so the expected values and ratios are exact). Each property has its negative control:

- the verdict's direction: a sampler known to be better reads "A is more efficient", the
  same numbers swapped read the other way, equal ones "not distinguishable";
- the comparison of each bundled sampler family with the best native sampler picks the
  pair the numbers say, decided by the sampler table's ``native`` and never by a name;
- the counts where the order changes along a ladder (onsets), on constructed curves that
  cross, and none on parallel ones;
- the reference floor: an error with a known floor comes out as the excess, and an error
  below the floor is a bound (``stats.excess_interval``), never NaN;
- the verdicts use relMSE: where MSE and relMSE disagree, relMSE decides.
"""
import dataclasses
import math

import pytest

from experiments.lib import samplers, stats
from experiments.lib.studies.sampler_comparison import analysis
from experiments.lib.studies.sampler_comparison.analysis import (
    BEST, BUNDLED, COMPARISON_HEADER, METRIC, NATIVE, Family, Point, onsets, order_changes,
    order_text, overtakes, ratio)
from experiments.lib.studies.sampler_comparison.efficiency import Efficiency
from experiments.lib.studies.sampler_comparison.plan import SCREEN_REFERENCE_SPP, plan
from experiments.lib.studies.sampler_comparison.screen import ScreenSpace
from experiments.lib.studies.sampler_comparison.screen_analysis import (
    SCREEN_HEADER, UNEQUAL, ScreenPoint, analyse_screen, lower_sign, lower_verdict,
    screen_pairs)
from experiments.lib.studies.sampler_comparison.words import conclusions, screen_conclusions

PIXELS = 100
#: Relative scatter of the repeats around their mean (mean exactly 1).
SPREAD = (0.9, 1.0, 1.1)
IS_NATIVE, IS_BUNDLED = True, False


def ladder(mse_at_1: float, slope: float, us: float, spps=(1, 4, 16, 64), spread=SPREAD,
           rel: float = 2.0, floor: float = 0.0, requested=None):
    """MSE = mse_at_1 * spp^slope (scattered by ``spread``), relMSE = ``rel`` x MSE, time
    = ``us`` per sample; ``floor`` added to both errors (the reference's own, subtracted
    again by the analysis)."""
    requested = requested or spps
    return [Point(n, tuple(us * 1e-6 * n * PIXELS for _ in spread),
                     tuple(floor + mse_at_1 * n ** slope * f for f in spread),
                     tuple(floor + rel * mse_at_1 * n ** slope * f for f in spread), t,
                     floor, floor)
            for n, t in zip(spps, requested)]


def kinds(**natives):
    """``{label: Family}``: the family is the label's part before ':'; ``natives`` says which
    are native (every label not named is bundled)."""
    return {label: Family(label.split(":")[0], native) for label, native in natives.items()}


def analyse(points, families):
    return analysis.analyse(points, PIXELS, families)


def of(analysis, role, depth=2):
    return [c for c in analysis.comparisons if c.role == role and c.depth == depth]


# ------------------------------------------------------------------ the table

def test_table_numbers_follow_from_the_points():
    points = {2: {"independent": ladder(1.0, -1.0, 10.0),
                  "orthogonal": ladder(0.07, -1.0, 20.0)}}
    rows = {r.sampler: r for r in analysis.table(points, PIXELS)}
    o = rows["orthogonal"]
    assert o.relative_mse.value == pytest.approx(0.07)
    assert o.relative_efficiency.value == pytest.approx(1 / (0.07 * 2.0))
    assert o.relative_efficiency.lo < o.relative_efficiency.value < o.relative_efficiency.hi
    assert o.us_per_sample == pytest.approx(20.0)
    assert o.slope == pytest.approx(-1.0)
    assert (o.spp, o.repeats) == (64, 3)
    assert o.mse.value == pytest.approx(0.07 / 64) and o.relmse.value == pytest.approx(
        0.14 / 64)
    assert rows["independent"].relative_efficiency.value == pytest.approx(1.0)
    record = o.record()
    assert record["relative_efficiency_lo"] < record["relative_efficiency"] \
        < record["relative_efficiency_hi"]
    assert {"mse_lo", "mse_hi", "relmse_lo", "relmse_hi"} <= set(record)


def test_curves_give_the_ratio_at_every_count():
    curves = analysis.curves({2: {"independent": ladder(1.0, -1.0, 10.0),
                            "orthogonal": ladder(0.07, -1.0, 20.0)}})
    pts = curves[2]["orthogonal"]
    assert [spp for spp, _ in pts] == [1, 4, 16, 64]
    assert all(e.value == pytest.approx(1 / (0.07 * 2.0)) for _, e in pts)


def test_slope_of_a_qmc_like_ladder():
    rows = analysis.table({2: {"independent": ladder(1.0, -1.0, 10.0),
                         "ldsampler": ladder(1.0, -1.5, 20.0)}}, PIXELS)
    assert [r.slope for r in rows] == pytest.approx([-1.0, -1.5])
    assert math.isfinite(rows[1].relative_efficiency.value)


# ------------------------------------------------------------------ verdicts

def three(bundled_mse, native_mse, spread=SPREAD):
    """independent (1.0), a native sampler and a bundled one at the same time per sample."""
    return {2: {"independent": ladder(1.0, -1.0, 10.0, spread=spread),
                "nat": ladder(native_mse, -1.0, 10.0, spread=spread),
                "bund": ladder(bundled_mse, -1.0, 10.0, spread=spread)}}


FAMILIES = kinds(independent=IS_NATIVE, nat=IS_NATIVE, bund=IS_BUNDLED)


def test_the_better_sampler_reads_more_efficient():
    better = analyse(three(0.1, 0.2), FAMILIES)
    c, = of(better, BUNDLED)
    assert (c.a, c.b) == ("bund", "nat")
    assert c.ratio.value == pytest.approx(2.0) and c.ratio.excludes(1.0)
    assert c.short_verdict() == "bund is more efficient"
    assert c.verdict.startswith("bund is more efficient than nat by 2 (95% CI")
    prose = " ".join(conclusions(better)[2])
    assert "bund is more efficient than nat by 2 (95% CI" in prose
    # the runner-up is the best native sampler: said once, not twice
    assert "runner-up, nat (also the best native sampler)" in prose
    assert prose.count("bund is more efficient than nat") == 1
    # negative control: the same numbers swapped read the other way
    worse = analyse(three(0.2, 0.1), FAMILIES)
    c, = of(worse, BUNDLED)
    assert c.ratio.value == pytest.approx(0.5)
    assert c.short_verdict() == "nat is more efficient"
    assert c.verdict.startswith("nat is more efficient than bund by 2 (95% CI")
    assert "bund is more efficient" not in " ".join(conclusions(worse)[2])


def test_a_tie_is_not_distinguishable():
    tie = analyse(three(0.2, 0.2), FAMILIES)
    c, = of(tie, BUNDLED)
    assert c.ratio.value == pytest.approx(1.0)
    assert c.short_verdict() == "not distinguishable"
    assert "nat and bund are not distinguishable at this budget" in conclusions(tie)[2][0]
    # 3% apart with a 20% scatter: still no verdict; 2x apart with it: a verdict
    wide = (0.8, 1.0, 1.2)
    assert of(analyse(three(0.2 / 1.03, 0.2, wide), FAMILIES), BUNDLED)[0] \
        .short_verdict() == "not distinguishable"
    assert of(analyse(three(0.1, 0.2, wide), FAMILIES), BUNDLED)[0] \
        .short_verdict() == "bund is more efficient"


def test_one_repeat_gives_no_interval_and_no_verdict():
    one = analyse(three(0.1, 0.2, spread=(1.0,)), FAMILIES)
    assert not any(r.relative_efficiency.known for r in one.rows if r.sampler != "independent")
    c, = of(one, BUNDLED)
    assert c.short_verdict() == "not distinguishable" and "1 run" in c.cells()[5]
    assert "no interval" in conclusions(one)[2][0]
    assert "is more efficient than" not in " ".join(conclusions(one)[2])


# ------------------------------------------------------------------ which pair

def many():
    """Natives independent < stratified < orthogonal; two bundled families (halton with two
    randomizations, and 'mine'); the most efficient of all is halton:owen."""
    return {2: {"independent": ladder(1.0, -1.0, 10.0),
                "stratified": ladder(0.5, -1.0, 10.0),
                "orthogonal": ladder(0.2, -1.0, 10.0),
                "halton:none": ladder(0.4, -1.0, 10.0),
                "halton:owen": ladder(0.1, -1.0, 10.0),
                "mine": ladder(0.3, -1.0, 10.0)}}


def test_each_bundled_family_meets_the_best_native_sampler():
    families = kinds(independent=IS_NATIVE, stratified=IS_NATIVE, orthogonal=IS_NATIVE,
                     **{"halton:none": IS_BUNDLED, "halton:owen": IS_BUNDLED, "mine": IS_BUNDLED})
    a = analyse(many(), families)
    best, = of(a, BEST)
    assert (best.a, best.b) == ("halton:owen", "orthogonal")
    assert [(c.a, c.b) for c in of(a, BUNDLED)] == [("halton:owen", "orthogonal"),
                                                    ("mine", "orthogonal")]
    assert {(c.a, c.b) for c in of(a, NATIVE)} == {
        (f, n) for f in ("halton:owen", "mine") for n in ("independent", "stratified")}
    assert of(a, BUNDLED)[1].short_verdict() == "orthogonal is more efficient"
    assert conclusions(a)[2][1].startswith("Against the best native sampler, orthogonal: "
                                          "orthogonal is more efficient than mine by 1.5")
    assert a.best[2].sampler == "halton:owen"


def test_native_or_bundled_comes_from_the_table_not_the_name():
    """Negative control: the same numbers with halton's labels declared native and
    orthogonal bundled: the pairs follow the declaration."""
    families = kinds(independent=IS_NATIVE, stratified=IS_NATIVE, orthogonal=IS_BUNDLED,
                     **{"halton:none": IS_NATIVE, "halton:owen": IS_NATIVE, "mine": IS_BUNDLED})
    a = analyse(many(), families)
    assert [(c.a, c.b) for c in of(a, BUNDLED)] == [("orthogonal", "halton:owen"),
                                                    ("mine", "halton:owen")]


def test_families_come_from_the_sampler_table():
    table = analysis.families(samplers.labels())
    for label, family in table.items():
        spec, randomization = samplers.split_label(label)
        assert family == Family(spec.name, spec.native, spec.is_deterministic(randomization))
    assert not table["halton:owen"].native and table["independent"].native
    spec = samplers.register_sampler(samplers.SamplerSpec("haltonlike_test", native=True))
    try:
        mine = samplers.register_sampler(samplers.SamplerSpec("independent_test"))
        assert analysis.families(["haltonlike_test", "independent_test"]) == {
            "haltonlike_test": Family("haltonlike_test", True),
            "independent_test": Family("independent_test", False)}
    finally:
        samplers.unregister_sampler(spec.name)
        samplers.unregister_sampler(mine.name)


# ------------------------------------------------------------------ order along the ladder

SPPS = (1, 4, 16, 64, 256)


def test_order_changes_are_found_where_the_curves_cross():
    """A's MSE falls faster (slope -1.5) than B's (-1): the efficiency ratio A/B is 0.25 x
    spp^0.5, i.e. 0.25, 0.5, 1, 2, 4: A loses at 1 and 4 spp, ties at 16, wins from 64."""
    b = ladder(0.1, -1.0, 10.0, SPPS)
    a = ladder(0.4, -1.5, 10.0, SPPS)
    changes = order_changes(a, b)
    assert [c[1] for c in changes] == [-1, -1, 0, 1, 1]
    assert changes[3][2].value == pytest.approx(2.0)
    assert onsets(changes) == [16, 64]
    assert overtakes("A", "B", changes) == ("A", "B", 64)
    assert order_text(changes) == ("less efficient at 1-4 spp, not distinguishable at "
                                   "16 spp, more efficient from 64 spp")
    # the other way round: B overtakes... no, B is overtaken; swapped roles agree
    back = order_changes(b, a)
    assert onsets(back) == [16, 64] and overtakes("B", "A", back) == ("A", "B", 64)


def test_parallel_curves_have_no_order_change():
    """Negative control: A twice as efficient at every count: no onset, nobody overtakes."""
    b = ladder(0.2, -1.0, 10.0, SPPS)
    a = ladder(0.1, -1.0, 10.0, SPPS)
    changes = order_changes(a, b)
    assert [c[1] for c in changes] == [1] * 5
    assert onsets(changes) == [] and overtakes("A", "B", changes) is None
    assert order_text(changes) == "more efficient at 1-256 spp (no change)"
    same = order_changes(b, b)
    assert onsets(same) == [] and order_text(same) == \
        "not distinguishable at 1-256 spp (no change)"


def test_the_table_and_the_sentences_report_the_crossing():
    points = {8: {"independent": ladder(1.0, -1.0, 10.0, SPPS),
                  "orthogonal": ladder(0.1, -1.0, 10.0, SPPS),
                  "halton:owen": ladder(0.4, -1.5, 10.0, SPPS)}}
    a = analysis.analyse(
        points, PIXELS, kinds(independent=IS_NATIVE, orthogonal=IS_NATIVE,
                              **{"halton:owen": IS_BUNDLED}))
    c, = [c for c in a.comparisons if c.role == BUNDLED]
    cells = dict(zip(COMPARISON_HEADER, c.cells()))
    assert cells["A / B"] == "halton:owen / orthogonal"
    assert cells["order changes at spp"] == "16, 64"
    assert cells["verdict"] == "halton:owen is more efficient"
    assert cells["efficiency A / B"] == stats.g(c.ratio.value) == "4"
    assert "halton:owen overtakes orthogonal from 64 spp" in conclusions(a)[8][-1]


# ------------------------------------------------------------------ the conclusion's shape

def test_conclusions_are_short_and_come_from_the_table():
    """Ten labels, three bundled families, crossing curves: per depth at most three
    sentences, none over 80 words, and the best label with the count it was chosen at."""
    points = {d: {"independent": ladder(1.0, -1.0, 10.0, SPPS),
                  "stratified": ladder(0.5, -1.1, 12.0, SPPS),
                  "multijitter": ladder(0.3, -1.2, 12.0, SPPS),
                  "orthogonal": ladder(0.3, -1.25, 20.0, (1, 4, 25, 81, 289),
                                       requested=SPPS),
                  "ldsampler": ladder(0.2, -1.1, 20.0, SPPS),
                  "halton:none": ladder(0.9, -1.4, 11.0, SPPS),
                  "halton:permute_digits": ladder(0.8, -1.3, 11.0, SPPS),
                  "halton:owen": ladder(0.7, -1.35, 11.0, SPPS),
                  "zsobol": ladder(0.6, -1.3, 12.0, SPPS),
                  "mine": ladder(1.0, -1.0, 9.0, SPPS)} for d in (2, 8)}
    families = kinds(independent=IS_NATIVE, stratified=IS_NATIVE, multijitter=IS_NATIVE,
                     orthogonal=IS_NATIVE, ldsampler=IS_NATIVE,
                     **{"halton:none": IS_BUNDLED, "halton:permute_digits": IS_BUNDLED,
                        "halton:owen": IS_BUNDLED, "zsobol": IS_BUNDLED, "mine": IS_BUNDLED})
    a = analysis.analyse(points, PIXELS, families)
    for d in (2, 8):
        assert 1 <= len(conclusions(a)[d]) <= 3
        for sentence in conclusions(a)[d]:
            assert len(sentence.split()) <= 80, sentence
        mine = [c for c in a.comparisons if c.depth == d]
        assert len([c for c in mine if c.role == BUNDLED]) == 3      # one per family
        for c in mine:                    # each verdict in the prose is the table's
            if c.role in (BEST, BUNDLED):
                assert c.verdict in " ".join(conclusions(a)[d])
    best = a.best[2]
    top = max(a.rows, key=lambda r: (r.depth == 2, r.relative_efficiency.value))
    assert (best.sampler, best.spp, best.requested) == (top.sampler, top.spp, top.requested)
    ortho = next(r for r in a.rows if r.sampler == "orthogonal")
    assert (ortho.spp, ortho.requested) == (289, 256)


# ------------------------------------------------------------------ the pick

def _pick_points(a_mse: float, b_mse: float, spread=SPREAD):
    return {2: {"independent": ladder(1.0, -1.0, 10.0, spread=spread),
                "x:a": ladder(a_mse, -1.0, 10.0, spread=spread),
                "x:b": ladder(b_mse, -1.0, 10.0, spread=spread),
                "x:none": ladder(0.05, -1.0, 10.0, spread=spread)}}


PICK_KINDS = {"independent": Family("independent", True), "x:a": Family("x", False),
              "x:b": Family("x", False), "x:none": Family("x", False, True)}


def test_the_pick_among_tied_samplers_survives_a_re_measurement_that_swaps_them():
    """Two randomized samplers 4% apart, within the repeats' 10% spread: a re-measurement
    that swaps their estimates must not change what the suite and the convergence study
    add. The pick is the last of the tied ones in the study's order; the deterministic
    label (ten times as efficient) is never picked."""
    first = analysis.analyse(_pick_points(0.50, 0.52), PIXELS, PICK_KINDS)
    again = analysis.analyse(_pick_points(0.52, 0.50), PIXELS, PICK_KINDS)
    for a in (first, again):
        p = a.picks[2]
        assert p.sampler == "x:b" and set(p.tied) == {"x:a", "x:b"} and not p.clear
        assert a.best[2].sampler == "x:none"                 # the most efficient label
    assert first.picks[2].most_efficient == "x:a" and again.picks[2].most_efficient == "x:b"
    # negative control: the largest randomized estimate alone flips with the re-measurement
    assert {first.picks[2].most_efficient, again.picks[2].most_efficient} == {"x:a", "x:b"}


def test_a_sampler_that_its_interval_sets_apart_is_picked_wherever_it_stands():
    """The first of the table (x:a) twice as efficient as x:b, by an interval excluding 1:
    picked, alone in its tie, although the order would prefer x:b."""
    a = analysis.analyse(_pick_points(0.25, 0.5), PIXELS, PICK_KINDS)
    p = a.picks[2]
    assert (p.sampler, p.tied, p.clear) == ("x:a", ("x:a",), True)
    assert (p.spp, p.requested) == (64, 64)
    assert p.record()["tied"] == ["x:a"]


def test_no_pick_without_a_randomized_sampler_of_known_efficiency():
    """Only the baseline and a deterministic label: nothing to pick (the studies that read
    the pick say so instead of adding a sampler with no interval)."""
    points = {2: {"independent": ladder(1.0, -1.0, 10.0), "x:none": ladder(0.1, -1.0, 10.0)}}
    a = analysis.analyse(points, PIXELS, {
        "independent": Family("independent", True), "x:none": Family("x", False, True)})
    assert a.picks == {2: analysis.Pick(
        2, "independent", 64, 64, "independent", ("independent",))}
    a = analysis.analyse({2: {"x:none": ladder(0.1, -1.0, 10.0)}}, PIXELS,
                                            {"x:none": Family("x", False, True)})
    assert a.picks == {}


def test_the_sampler_tables_deterministic_labels_are_known_as_such():
    kinds = analysis.families(samplers.labels())
    assert {label for label, f in kinds.items() if f.deterministic} == \
        {label for label in samplers.labels()
         if samplers.split_label(label)[0].is_deterministic(samplers.split_label(label)[1])}
    assert kinds["zsobol:none"].deterministic and not kinds["zsobol:owen"].deterministic


# ------------------------------------------------------------------ the reference floor

def test_the_known_floor_is_subtracted():
    """Errors measured against a noisy reference carry its own expected error (the floor):
    the analysis reports the excess, with the interval of the raw mean shifted."""
    floor = 0.01
    p = ladder(0.1, -1.0, 10.0, (1,), floor=floor)[0]
    raw = stats.mean_interval(p.mse)
    e = p.expected("mse")
    assert e == stats.excess_interval(p.mse, floor)
    assert e.value == pytest.approx(0.1) and not e.bound
    assert (e.lo, e.hi) == pytest.approx((raw.lo - floor, raw.hi - floor))
    assert p.expected("relmse").value == pytest.approx(0.2)
    rows = analysis.table(
        {2: {"independent": ladder(1.0, -1.0, 10.0, floor=floor),
             "x": ladder(0.1, -1.0, 10.0, floor=floor)}}, PIXELS)
    row = next(r for r in rows if r.sampler == "x")
    assert row.mse.value == pytest.approx(0.1 / 64) and row.relative_mse.value == \
        pytest.approx(0.1)
    # negative control: without the floor the raw mean is reported
    assert Point(1, p.seconds, p.mse, p.relmse).expected("mse").value == \
        pytest.approx(0.1 + floor)


def test_an_error_below_the_floor_is_a_bound_never_nan():
    """A sampler whose raw errors scatter around the floor itself (its own error cannot be
    told from the reference's noise): an upper bound, '< x', and no verdict against it."""
    floor = 0.01
    near = Point(64, (1.0, 1.0, 1.0), (0.0098, 0.0101, 0.0103), (0.0198, 0.02, 0.0204), 64,
                    floor, 0.02)
    e = near.expected("mse")
    assert e.bound and math.isfinite(e.value) and e.value >= 0 and e.lo == 0
    assert e.value == pytest.approx(stats.mean_interval(near.mse).hi - floor)
    assert e.text().startswith("< ")
    base = Point(64, (1.0, 1.0, 1.0), (0.09, 0.1, 0.11), (0.19, 0.2, 0.21), 64, floor, 0.02)
    points = {2: {"independent": [base], "x": [near]}}
    row = next(r for r in analysis.table(points, PIXELS) if r.sampler == "x")
    assert row.mse.bound and row.relmse.bound and row.relative_mse.bound
    assert math.isfinite(row.relative_mse.hi) and row.relative_mse.hi < 0.1
    a = analysis.analyse(points, PIXELS,
                                            kinds(independent=IS_NATIVE, x=IS_BUNDLED))
    c, = [c for c in a.comparisons if c.role == BUNDLED]
    assert c.short_verdict() == "cannot be compared (below the reference's noise)"
    assert "cannot be compared" in c.verdict
    assert a.best[2].sampler == "independent"           # an unknown efficiency never wins
    # negative control: the same raw errors with a floor well below them are no bound
    clear = Point(64, near.seconds, near.mse, near.relmse, 64, 0.001, 0.002)
    assert not clear.expected("mse").bound
    assert clear.expected("mse").value == pytest.approx(sum(near.mse) / 3 - 0.001)


# ------------------------------------------------------------------ relMSE decides

def test_verdicts_use_relmse():
    """A has half B's MSE but 2.5x its relMSE (its error sits in dark pixels), at the same
    time: by relMSE B is 2.5x more efficient, and that is the verdict."""
    points = {2: {"independent": ladder(1.0, -1.0, 10.0, rel=1.0),
                  "a": ladder(0.1, -1.0, 10.0, rel=5.0),
                  "b": ladder(0.2, -1.0, 10.0, rel=1.0)}}
    assert METRIC == "relmse"
    an = analysis.analyse(
        points, PIXELS, kinds(independent=IS_NATIVE, b=IS_NATIVE, a=IS_BUNDLED))
    c, = [c for c in an.comparisons if c.role == BUNDLED]
    assert (c.a, c.b) == ("a", "b") and c.ratio.value == pytest.approx(0.4)
    assert c.short_verdict() == "b is more efficient"
    rows = {r.sampler: r for r in an.rows}
    assert rows["a"].relative_mse.value == pytest.approx(0.1)          # MSE stays reported
    assert rows["a"].relative_relmse.value == pytest.approx(0.5)
    assert rows["a"].relative_efficiency.value == pytest.approx(2.0)
    # negative control: by MSE the verdict would have gone the other way
    mse = ratio(points[2]["a"][-1], points[2]["b"][-1], "mse")
    assert mse.value == pytest.approx(2.0) and mse.excludes(1.0)


# ------------------------------------------------------------------ the screen-space pass

COUNTS = (1, 4, 16)


def screen(flip: float, share: float, mse: float = 0.01, us: float = 10.0, counts=COUNTS,
           spread=SPREAD, rel: float = 2.0):
    """A screen-space ladder: mean FLIP ``flip`` x spp^-0.5, low-frequency share ``share``,
    MSE ``mse`` / spp, all scattered by ``spread``; ``us`` per sample."""
    err = ladder(mse, -1.0, us, counts, spread, rel)
    return [ScreenPoint(n, tuple(flip * n ** -0.5 * f for f in spread),
                           tuple(share * f for f in spread), e, requested=n)
            for n, e in zip(counts, err)]


SCREEN_FAMILIES = kinds(independent=IS_NATIVE, nat=IS_NATIVE, bund=IS_BUNDLED)


def screen_analysis(points):
    return analyse_screen({2: points}, PIXELS, SCREEN_FAMILIES, 0.0487)


def test_lower_flip_reads_as_better_and_swapped_the_other_way():
    better = screen_analysis({"independent": screen(0.2, 0.049), "nat": screen(0.1, 0.049),
                              "bund": screen(0.07, 0.049)})
    c = next(c for c in better.comparisons if (c.a, c.b, c.requested) == ("bund", "nat", 4))
    assert c.flip.value == pytest.approx(0.7) and c.flip.hi < 1
    assert lower_sign(c.flip) == 1 and c.verdicts()[0] == "bund lower FLIP"
    assert lower_verdict("bund", "nat", c.flip, "mean FLIP").startswith(
        "bund's mean FLIP is lower than nat's: 0.7 (95% CI")
    assert "bund lower at 1-16 spp, ratio 0.7" in screen_conclusions(better)[2][0]
    # negative control: the same numbers swapped
    worse = screen_analysis({"independent": screen(0.2, 0.049), "nat": screen(0.07, 0.049),
                             "bund": screen(0.1, 0.049)})
    c = next(c for c in worse.comparisons if (c.a, c.b, c.requested) == ("bund", "nat", 4))
    assert c.flip.value == pytest.approx(1 / 0.7) and c.verdicts()[0] == "nat lower FLIP"
    assert lower_verdict("bund", "nat", c.flip, "mean FLIP").startswith(
        "bund's mean FLIP is higher than nat's")
    assert "bund higher at 1-16 spp" in screen_conclusions(worse)[2][0]


def test_a_flip_tie_is_not_distinguishable():
    tie = screen_analysis({"independent": screen(0.2, 0.049), "nat": screen(0.1, 0.049),
                           "bund": screen(0.1, 0.049)})
    for c in tie.comparisons:
        if c.b == "nat":
            assert c.flip.value == pytest.approx(1.0) and c.verdicts()[0] == \
                "not distinguishable"
    assert "bund not distinguishable at 1-16 spp" in screen_conclusions(tie)[2][0]
    assert "are not distinguishable in mean FLIP (ratio 1" in lower_verdict(
        "bund", "nat", tie.comparisons[-1].flip, "mean FLIP")
    # 3% apart within a 20% scatter: a tie; 20% apart with it: a verdict
    wide = (0.8, 1.0, 1.2)
    near = screen_analysis({"independent": screen(0.2, 0.049, spread=wide),
                            "nat": screen(0.1, 0.049, spread=wide),
                            "bund": screen(0.097, 0.049, spread=wide)})
    assert {c.verdicts()[0] for c in near.comparisons if c.b == "nat"} == \
        {"not distinguishable"}
    one = screen_analysis({"independent": screen(0.2, 0.049, spread=(1.0,)),
                           "nat": screen(0.1, 0.049, spread=(1.0,)),
                           "bund": screen(0.05, 0.049, spread=(1.0,))})
    assert {c.verdicts()[0] for c in one.comparisons} == {"not distinguishable"}


def test_a_bluer_error_is_found_where_it_is_below_every_native():
    """bund's share is 0.037 at 4 spp only (0.049 at 1 and 16), against independent's and
    nat's 0.049: bluer than every native sampler at 4 spp alone."""
    bund = screen(0.1, 0.049)
    bund[1] = ScreenPoint(4, bund[1].flip, tuple(0.037 * f for f in SPREAD), bund[1].error,
                             requested=4)
    a = screen_analysis({"independent": screen(0.2, 0.049), "nat": screen(0.1, 0.049),
                         "bund": bund})
    at4 = [c for c in a.comparisons if c.requested == 4]
    assert {c.verdicts()[1] for c in at4} == {"bund bluer"}
    assert {c.verdicts()[1] for c in a.comparisons if c.requested != 4} == \
        {"not distinguishable"}
    assert "bund at 4 spp, share 0.049" in screen_conclusions(a)[2][1]
    # negative control: bluer than one native but not the other is not "every native"
    a = screen_analysis({"independent": screen(0.2, 0.049), "nat": screen(0.1, 0.037),
                         "bund": bund})
    assert "bund at no count" in screen_conclusions(a)[2][1]
    rows = {(r.sampler, r.requested): r for r in a.rows}
    assert rows[("bund", 4)].share.value == pytest.approx(0.037)
    assert rows[("bund", 4)].share.lo < 0.037 < rows[("bund", 4)].share.hi


def test_flip_is_compared_only_at_equal_counts():
    """nat renders 25 samples where 16 are asked (orthogonal's rounding): its lower FLIP
    there is more samples, not a verdict; the efficiency (per unit of time) and the share
    (a shape, not a size) still are. Negative control: the same numbers at an equal count
    give the FLIP verdict."""
    nat = screen(0.07, 0.049, counts=(1, 4, 25))
    nat = [dataclasses.replace(p, requested=r) for p, r in zip(nat, COUNTS)]
    a = screen_analysis({"independent": screen(0.2, 0.049), "nat": nat,
                         "bund": screen(0.1, 0.037)})
    c = next(c for c in a.comparisons if (c.a, c.b, c.requested) == ("bund", "nat", 16))
    assert c.spp == (16, 25) and not c.equal and c.flip.excludes(1.0)
    # MSE per sample and time per sample alike: equally efficient
    assert c.verdicts() == (UNEQUAL, "bund bluer", "not distinguishable")
    assert c.cells()[2] == "16 / 25"
    assert "bund at 1, 4, 16 spp" in screen_conclusions(a)[2][1]
    # the sentence's native is the lowest FLIP among those that render 16 for 16
    assert "lowest at 16 spp (independent)" in screen_conclusions(a)[2][0]
    same = next(c for c in a.comparisons if (c.a, c.b, c.requested) == ("bund", "nat", 4))
    assert same.equal and same.verdicts()[0] == "nat lower FLIP"


def test_the_screen_efficiency_uses_mse():
    """bund has half nat's MSE but 2.5x its relMSE at the same time: in MSE efficiency
    bund is 2x more efficient (the verdict); by relMSE it would be nat."""
    pts = {"independent": screen(0.2, 0.049, mse=0.1, rel=1.0),
           "nat": screen(0.1, 0.049, mse=0.02, rel=1.0),
           "bund": screen(0.1, 0.049, mse=0.01, rel=5.0)}
    a = screen_analysis(pts)
    c = next(c for c in a.comparisons if (c.a, c.b, c.requested) == ("bund", "nat", 16))
    assert c.efficiency.value == pytest.approx(2.0) and c.verdicts()[2] == \
        "bund more efficient"
    assert "against the most efficient native sampler at 16 spp (nat): bund more " \
           "efficient at 1-16 spp" in screen_conclusions(a)[2][2]
    relmse = ratio(pts["bund"][-1].error, pts["nat"][-1].error, "relmse")   # control
    assert relmse.value == pytest.approx(0.4) and relmse.excludes(1.0)


def test_screen_pairs_come_from_the_table_and_the_lowest_flip():
    """Each bundled family's label with the lowest FLIP at the largest count meets every
    native label and the other families' best; declared native instead, the pairs follow
    the declaration (negative control: never by name)."""
    pts = {"independent": screen(0.2, 0.049), "nat": screen(0.1, 0.049),
           "halton:none": screen(0.12, 0.049), "halton:owen": screen(0.09, 0.049),
           "zsobol:none": screen(0.07, 0.04), "zsobol:owen": screen(0.08, 0.037)}
    families = kinds(independent=IS_NATIVE, nat=IS_NATIVE, **{
        "halton:none": IS_BUNDLED, "halton:owen": IS_BUNDLED, "zsobol:none": IS_BUNDLED,
        "zsobol:owen": IS_BUNDLED})
    assert screen_pairs(pts, families) == [
        ("halton:owen", "independent"), ("halton:owen", "nat"), ("zsobol:none", "independent"),
        ("zsobol:none", "nat"), ("halton:owen", "zsobol:none")]
    swapped = kinds(independent=IS_NATIVE, nat=IS_BUNDLED, **{
        "halton:none": IS_NATIVE, "halton:owen": IS_NATIVE, "zsobol:none": IS_BUNDLED,
        "zsobol:owen": IS_BUNDLED})
    assert screen_pairs(pts, swapped) == [
        ("nat", "independent"), ("nat", "halton:none"), ("nat", "halton:owen"),
        ("zsobol:none", "independent"), ("zsobol:none", "halton:none"),
        ("zsobol:none", "halton:owen"), ("nat", "zsobol:none")]


def test_screen_conclusions_are_short_and_from_the_table():
    """Three bundled families, five natives, five counts: at most three sentences of at
    most 80 words; each verdict of the first sentence is the table's."""
    counts = (1, 2, 4, 8, 16)
    pts = {"independent": screen(0.2, 0.049, mse=0.1, counts=counts),
           "stratified": screen(0.12, 0.048, mse=0.03, counts=counts),
           "multijitter": screen(0.1, 0.049, mse=0.02, counts=counts),
           "orthogonal": screen(0.11, 0.05, mse=0.02, us=20.0, counts=counts),
           "ldsampler": screen(0.105, 0.047, mse=0.025, counts=counts),
           "halton:owen": screen(0.12, 0.049, mse=0.03, counts=counts),
           "zsobol:owen": screen(0.07, 0.037, mse=0.02, counts=counts),
           "mine": screen(0.2, 0.049, mse=0.1, counts=counts)}
    families = kinds(independent=IS_NATIVE, stratified=IS_NATIVE, multijitter=IS_NATIVE,
                     orthogonal=IS_NATIVE, ldsampler=IS_NATIVE, **{
                         "halton:owen": IS_BUNDLED, "zsobol:owen": IS_BUNDLED, "mine": IS_BUNDLED})
    a = analyse_screen({2: pts, 8: pts}, PIXELS, families, 0.0487)
    for d in (2, 8):
        assert 1 <= len(screen_conclusions(a)[d]) <= 3
        for sentence in screen_conclusions(a)[d]:
            assert len(sentence.split()) <= 80, sentence
        assert "(multijitter)" in screen_conclusions(a)[d][0]          # the lowest native FLIP
        assert "zsobol:owen lower at 1-16 spp" in screen_conclusions(a)[d][0]
        assert "zsobol:owen at 1, 2, 4, 8, 16 spp" in screen_conclusions(a)[d][1]
    assert len(a.rows) == 2 * len(pts) * len(counts)
    assert len(a.comparisons) == 2 * (3 * 5 + 3) * len(counts)
    cells = dict(zip(SCREEN_HEADER, next(c for c in a.comparisons if (
        c.a, c.b, c.requested) == ("zsobol:owen", "multijitter", 16)).cells()))
    assert cells["mean FLIP A / B"] == "0.7" and cells["FLIP verdict"] == \
        "zsobol:owen lower FLIP"
    assert cells["share verdict"] == "zsobol:owen bluer"
    assert cells["efficiency verdict"] == "not distinguishable"


# ------------------------------------------------------------------ the pass's plan

TINY_SCREEN = ["--resolution", "8x4", "--spp", "4", "--depths", "2", "--repeats", "2",
               "--reference-spp", "16", "--screen-resolution", "8x8", "--screen-counts",
               "1,2", "--screen-repeats", "2", "--screen-reference-spp", "16",
               "--screen-samplers", "independent,zsobol:owen,zsobol:none"]


def tiny_study(out, *argv):
    from experiments.lib import cli
    from experiments.lib.studies.sampler_comparison import study
    from experiments.lib.study import Study, StudySettings
    args = cli.parse_args(study.build_parser(),
                          ["--out", str(out), *TINY_SCREEN, *argv])
    return (Study(StudySettings(**cli.common_fields(args))),
            study.settings_of(args))


def planned(st, cfg, p):
    """The pass ``p``'s jobs as the engine plans them (None: the pass is switched off)."""
    from experiments.lib.engine import Engine
    declared = p.declare(st, cfg)
    return None if declared is None else plan(Engine(st), declared)


def by_label(planned_pass, scene: str = "depth2") -> dict:
    """``{method name: [repeat: [job per count]]}`` of one scene of a planned pass."""
    decl, out = planned_pass.declaration, {}
    for budget in decl.budgets:
        for cell, reps in planned_pass.cells[budget.name].items():
            if cell.scene == scene:
                mine = out.setdefault(cell.method, [[] for _ in reps])
                for r, jobs in enumerate(reps):
                    mine[r] += jobs
    return out


def test_the_screen_pass_plans_exactly_the_jobs_it_needs(tmp_path):
    st, cfg = tiny_study(tmp_path)
    sc = cfg.screen
    assert (sc.resolution, sc.counts, sc.depths, sc.repeats, sc.reference_spp) == \
        ((8, 8), (1, 2), (2,), 2, 16)
    plan = planned(st, cfg, ScreenSpace())
    ladders = {label: by_label(plan)[m.name] for label, m in
               zip(sc.samplers, plan.declaration.methods)}
    assert {s: len(reps) for s, reps in ladders.items()} == {
        "independent": 2, "zsobol:owen": 2, "zsobol:none": 1}       # deterministic: one run
    ladder_jobs = [j for reps in ladders.values() for rep in reps for j in rep]
    assert len(ladder_jobs) == 10 == len({j.key for j in ladder_jobs})
    for s, reps in ladders.items():
        for rep in reps:
            assert [j.spp for j in rep] == [1, 2]
            for j in rep:
                assert (j.width, j.height, j.max_depth) == (8, 8, 2)
                assert j.method.name == ("bsdf+nee" if s == "independent" else f"bsdf+nee+{s}")
                assert j.key.startswith(f"samplers/screen-8x8-depth2/{s.replace(':', '-')}/"
                                        f"spp0000{j.spp}")
                assert j.timing_group == "samplers/screen/depth2"
    # the key names the repeat as it always did (the seed derives from it)
    assert [j.key.split("-")[2] for j in ladders["independent"][1]] == [
        "depth2/independent/spp00001/r1", "depth2/independent/spp00002/r1"]
    (_, refs), = plan.refs.items()
    # the reference store's chunks (their size set by the film) give at least the 16 asked
    from experiments.lib import references
    chunk = references.chunk_spp_for(8, 8, SCREEN_REFERENCE_SPP)
    chunks = references.MIN_CHUNKS
    assert [j.spp for j in refs] == [chunk] * chunks and chunk * chunks >= 16
    assert {j.method.name for j in refs} == {"path"}
    assert {(j.width, j.height) for j in refs} == {(8, 8)}
    assert sorted(j.key for j in plan.renders()) == sorted(j.key for j in ladder_jobs)
    # the efficiency pass's jobs do not depend on the screen options
    st2, cfg2 = tiny_study(tmp_path, "--screen-counts", "4,16", "--screen-repeats", "5")
    keys = [j.key for j in planned(st, cfg, Efficiency()).renders()]
    assert keys == [j.key for j in planned(st2, cfg2, Efficiency()).renders()]
    assert all(k.startswith("samplers/depth2/") for k in keys)
    # negative controls: switched off, no pass; --max-depth replaces its depths too
    st3, cfg3 = tiny_study(tmp_path, "--screen-space", "off")
    assert planned(st3, cfg3, ScreenSpace()) is None
    st4, cfg4 = tiny_study(tmp_path, "--max-depth", "3")
    assert cfg4.screen.depths == (3,) and cfg4.depths == (3,)


def test_bad_screen_options_name_the_valid_choices(tmp_path, capsys):
    with pytest.raises(SystemExit):
        tiny_study(tmp_path, "--screen-samplers", "independent,bogus")
    err = capsys.readouterr().err
    assert "bogus" in err and "zsobol" in err and "'default', 'all'" in err
    with pytest.raises(SystemExit):
        tiny_study(tmp_path, "--screen-counts", "0,4")
    assert "invalid counts '0,4'" in capsys.readouterr().err


def test_the_lab_plans_the_same_screen_jobs(tmp_path):
    """The lab's error images are the sampler study's renders (first repeat): the same
    keys, so it finds them in the store; with another seed it would not (control)."""
    from experiments.lib.engine import Engine
    from experiments.lib.studies.lab.config import Config
    from experiments.lib.studies.lab.screen_part import plan_screen
    st, cfg = tiny_study(tmp_path)
    study = planned(st, cfg, ScreenSpace())
    keys = {j.key for j in study.renders()} | {j.key for c in study.refs.values() for j in c}
    config = Config(screen_resolution=(8, 8), screen_counts=(2,),
                    screen_samplers=("independent", "zsobol:owen"), screen_reference_spp=16)
    mine = plan_screen(Engine(st), config, cfg.screen.reference)
    ours = {j.key for j in mine.renders()} | {j.key for c in mine.refs.values() for j in c}
    assert len(ours) == 8 + 2 and ours <= keys
    other, _ = tiny_study(tmp_path, "--seed", "7")
    moved = plan_screen(Engine(other), config, cfg.screen.reference)
    assert not {j.key for j in moved.renders()} & keys


def test_the_screen_pass_resumes_from_the_store(tmp_path):
    from experiments.lib.engine import Engine
    st, cfg = tiny_study(tmp_path)
    p, engine = ScreenSpace(), Engine(st)
    plan = planned(st, cfg, p)
    jobs = plan.renders()
    engine.run(plan.declaration)
    assert st.run(jobs) == 0                                # a rerun renders nothing
    result = p.analyse(p.measure(st, cfg, plan, engine.run(plan.declaration)))
    assert len(result.rows) == 3 * 2
    rows = {(r.sampler, r.requested): r for r in result.rows}
    assert rows[("zsobol:none", 2)].repeats == 2            # its one run stands for both
    assert rows[("zsobol:none", 2)].flip.lo == rows[("zsobol:none", 2)].flip.hi
    assert all(0 < r.flip.value < 1 for r in result.rows)
    lowest = min(("zsobol:none", "zsobol:owen"), key=lambda s: rows[(s, 2)].flip.value)
    assert [(c.a, c.b) for c in result.comparisons] == [(lowest, "independent")] * 2
