"""The suite's bias test (experiments/lib/studies/suite/bias_test.py over experiments/lib/bias.py).

Synthetic renders of known law at the default budget of the suite (a 48x36 film; the method
side 3 renders at 16 spp and 3 at 64 spp, the reference 8 chunks of 128 spp; per-sample
standard deviation equal to the pixel's mean): a 2% bias is found in at least 18 of 20 seeds,
and no unbiased cell is flagged in 20 seeds at the run's level (99% family-wise over the 9 x 15
cells of a default run). The suite's ranking never names a flagged method; untestable cells
say why. Real scenes: tests/test_suite_bias_plugins.py.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from experiments.lib import bias, bias_image
from experiments.lib.studies.suite import analysis as A
from experiments.lib.studies.suite import bias_test as suite_bias

W, H, C = 48, 36, 3
#: The default run: 9 bundled scenes x 15 methods, one family.
ALPHA = suite_bias.cell_level(9 * 15)
SEEDS = 20


@dataclass(frozen=True)
class FakeMethod:
    name: str = "mine"
    sampler: str = "independent"
    deterministic: bool = False
    learns: bool = False

    def trains(self, spp, pixels):
        return self.learns


def renders(rng, mu, k, spp, factor=1.0):
    """k renders of spp samples per pixel: normal means, per-sample sd = mu."""
    return factor * (mu + mu / math.sqrt(spp) * rng.standard_normal((k, H, W, C)))


def cell(rng, factor=1.0, method=FakeMethod(), box=True):
    mu = rng.uniform(0.05, 1.0, (H, W, C))
    budgets = [[(x, 16) for x in renders(rng, mu, 3, 16, factor)],
               [(x, 64) for x in renders(rng, mu, 3, 64, factor)]]
    chunks = renders(rng, mu, 8, 128)
    return suite_bias.check_cell(method, budgets, chunks, box, box, FakeMethod("path"), ALPHA)


def test_a_2_percent_bias_is_found_in_90_percent_of_seeds_and_no_unbiased_cell_is_flagged():
    found = flagged = 0
    for seed in range(SEEDS):
        biased = cell(np.random.default_rng(seed), 1.02)
        right = cell(np.random.default_rng(1000 + seed))
        assert right.status != "untestable" and biased.status != "untestable", right.reason
        found += biased.biased is True
        flagged += right.biased is True
        assert right.detectable < 0.02, right.detectable
    assert found >= 0.9 * SEEDS, found
    assert flagged == 0, flagged


@pytest.mark.parametrize("sampler", ["independent", "halton"])
def test_budgets_of_unequal_samples_keep_the_pooled_tests_size(sampler):
    """The method's side is two budgets (16 and 1024 spp here; 16 and 256 on
    textured_phong in a default run): its halves' variances differ 64x. The pooled
    statistic of each half takes its variance from that half (with weights from the other):
    from the other half it misstated it (12 of 40 unbiased cells flagged, p < 0.01 in 78%
    of them; with a sampler judged by its renders' spread, where the weights follow that
    half's noise, 62% even at equal budgets)."""
    small = 0
    for seed in range(SEEDS):
        rng = np.random.default_rng(2000 + seed)
        mu = rng.uniform(0.05, 1.0, (H, W, C))
        budgets = [[(x, 16) for x in renders(rng, mu, 3, 16)],
                   [(x, 1024) for x in renders(rng, mu, 3, 1024)]]
        got = suite_bias.check_cell(FakeMethod(sampler=sampler), budgets,
                                    renders(rng, mu, 8, 128), True, True, FakeMethod("path"),
                                    ALPHA)
        assert got.p_pooled > got.alpha_pooled, (seed, got.p_pooled)
        small += got.p_pooled < 0.01
    assert small <= 3, small          # min over 3 channels: about 3% of seeds under 0.01


def test_a_mean_preserving_bias_is_found_by_its_blocks():
    """Energy moved from the left half of the image to the right: the image mean kept."""
    rng = np.random.default_rng(5)
    mu = rng.uniform(0.2, 1.0, (H, W, C))
    shift = np.where(np.arange(W) < W // 2, 0.9, 1.1)[None, :, None]
    budgets = [[(x * shift, 16) for x in renders(rng, mu, 3, 16)],
               [(x * shift, 64) for x in renders(rng, mu, 3, 64)]]
    got = suite_bias.check_cell(FakeMethod(), budgets, renders(rng, mu, 8, 128), True, True,
                                FakeMethod("path"), ALPHA)
    assert got.biased is True and got.flagged_blocks > 0
    assert got.flagged.shape == (math.ceil(H / 8), W // 8)


def rare(rng, mu, k, spp, p, factor=1.0):
    """k renders of spp samples per pixel, each sample mu / p with probability p, else 0
    (mean mu: heavy tails where p spp is small)."""
    return factor * mu * rng.binomial(spp, p, (k, H, W, C)) / (p * spp)


def heavy_cell(rng, factor=1.0):
    """A cell whose blocks are ruled by heavy tails (p = 0.002: about 0.1 hits per pixel
    at 64 spp) but whose image sum holds hundreds of hits."""
    mu = rng.uniform(0.05, 1.0, (H, W, C))
    budgets = [[(x, 16) for x in rare(rng, mu, 3, 16, 0.002, factor)],
               [(x, 64) for x in rare(rng, mu, 3, 64, 0.002, factor)]]
    return suite_bias.check_cell(FakeMethod(), budgets, renders(rng, mu, 8, 128), True,
                                 True, FakeMethod("path"), ALPHA)


def test_heavy_tailed_blocks_are_tested_by_the_image_sum_with_its_size_and_power():
    """Rare large values rule most blocks' variances (the per-block and pooled tests lose
    their size there) but not the image sum's (about 660 hits over the image, a relative
    standard error of 4%): the cell is tested by its image sum (bias_image). Size: no
    right cell flagged in 20 seeds at the run's level; power: a 32% darkening flagged in
    at least 18 of 20 (the stated detectable bias, 28-30% in these seeds at the image
    test's margin, bias_image.POWER_Z, under it)."""
    flagged = found = 0
    for seed in range(SEEDS):
        right = heavy_cell(np.random.default_rng(3000 + seed))
        wrong = heavy_cell(np.random.default_rng(4000 + seed), 0.68)
        assert right.scope == "image" and right.tail_share > suite_bias.TAILS_SHARE
        assert right.status != "untestable" and right.term_share <= bias_image.MAX_TERM_SHARE
        assert right.detectable < 0.32, right.detectable
        flagged += right.biased is True
        found += wrong.biased is True
    assert flagged == 0 and found >= 0.9 * SEEDS, (flagged, found)


def pareto(rng, mu, k, spp, a):
    """k renders of spp samples per pixel drawn from a Pareto law of index ``a`` scaled to
    mean mu (infinite variance for a <= 2: the sum of many is not close to normal)."""
    x = (rng.pareto(a, (k, spp) + mu.shape) + 1.0).mean(axis=1)
    return mu * x * (a - 1) / a


def test_an_image_ruled_by_infinite_variance_is_untestable_not_flagged(monkeypatch):
    """Samples of infinite variance (Pareto index 1.2; uniform sampling of rough glass is
    of this kind): one pixel of one render holds 34-66% of the image sum's variance, so
    the image test is withheld (untestable) in every seed; negative control: with its gate
    off (MAX_TERM_SHARE 1) the t test flags right cells (4 of 20 measured: the sum reads
    low in most seeds, its variance with it)."""
    def cells():
        out = []
        for seed in range(SEEDS):
            rng = np.random.default_rng(seed)
            mu = rng.uniform(0.05, 1.0, (H, W, C))
            budgets = [[(x, 16) for x in pareto(rng, mu, 3, 16, 1.2)],
                       [(x, 64) for x in pareto(rng, mu, 3, 64, 1.2)]]
            out.append(suite_bias.check_cell(FakeMethod(), budgets, renders(rng, mu, 8, 128),
                                             True, True, FakeMethod("path"), ALPHA))
        return out
    gated = cells()
    assert all(c.status == "untestable" and c.reason == "heavy_tails" and c.scope == "image"
               for c in gated)
    assert min(c.term_share for c in gated) > bias_image.MAX_TERM_SHARE
    monkeypatch.setattr(bias_image, "MAX_TERM_SHARE", 1.0)
    assert sum(c.biased is True for c in cells()) >= 2


@pytest.mark.parametrize("case, reason", [
    ("deterministic", "deterministic"), ("user", "user_reference"),
    ("one repeat", "too_few_renders"), ("heavy", "heavy_tails")])
def test_untestable_cells_say_why(case, reason):
    rng = np.random.default_rng(3)
    mu = rng.uniform(0.2, 1.0, (H, W, C))
    budgets = [[(x, 16) for x in renders(rng, mu, 3, 16)],
               [(x, 64) for x in renders(rng, mu, 3, 64)]]
    chunks = renders(rng, mu, 8, 128)
    method = FakeMethod(deterministic=case == "deterministic")
    if case == "user":
        chunks = None
    if case == "one repeat":
        budgets = [b[:1] for b in budgets]
    if case == "heavy":          # rare large values: a few over the whole image
        budgets = [[(x, 16) for x in rare(rng, mu, 3, 16, 2e-5)],
                   [(x, 64) for x in rare(rng, mu, 3, 64, 2e-5)]]
    got = suite_bias.check_cell(method, budgets, chunks, True, True, FakeMethod("path"), ALPHA)
    assert got.biased == "untestable" and got.reason == reason


def test_variance_from_the_renders_for_a_qmc_sampler_or_a_wide_filter():
    rng = np.random.default_rng(4)
    assert cell(rng, method=FakeMethod(sampler="halton")).variance == "renders"
    assert cell(rng, box=False).variance == "renders"
    assert cell(rng).variance == "pixels"


def test_the_run_is_one_family_at_99_percent():
    assert suite_bias.cell_level(1) == pytest.approx(0.01)
    assert (1 - suite_bias.cell_level(135)) ** 135 == pytest.approx(0.99)


def test_a_flagged_method_is_never_the_winner_nor_tied():
    def runs(err):
        return A.Runs(16, (err,) * 3, (err,) * 3, (err,) * 3, (1.0,) * 3)
    flagged = suite_bias.CellBias("biased", detectable=0.01)
    clean = suite_bias.CellBias("unbiased", detectable=0.01)
    cells = {"path": A.Cell("path", {b: runs(1.0) for b in A.BUDGETS}, (1.0,) * 3,
                            block_bias=clean),
             "fast": A.Cell("fast", {b: runs(0.01) for b in A.BUDGETS}, (1.0,) * 3,
                            block_bias=flagged)}
    result = A.analyse_scene(A.SceneNumbers("s", cells, A.Floor(0, 0, 0), "path",
                                            calibration="path"))
    assert result.ranking.winner == "path" and "fast" not in result.ranking.ties
    assert result.cells["fast"].biased and result.power == 0.01
    assert result.power_method == "path"


def test_padding_leaves_partial_blocks_out_of_nothing():
    images = bias.padded(np.ones((2, 36, 48, 3)))
    assert images.shape == (2, 40, 48, 3) and images[:, 36:].sum() == 0


def test_a_power_from_a_heavy_tailed_calibration_cell_is_indicative_only():
    from experiments.lib.studies.suite import bias_report as R

    def runs(err):
        return A.Runs(16, (err,) * 3, (err,) * 3, (err,) * 3, (1.0,) * 3)

    def scene(calibration):
        cells = {"path": A.Cell("path", {b: runs(1.0) for b in A.BUDGETS}, (1.0,) * 3,
                                block_bias=calibration)}
        return A.analyse_scene(A.SceneNumbers("s", cells, A.Floor(0, 0, 0), "path",
                                              calibration="path"))
    heavy = scene(suite_bias.CellBias("untestable", "heavy_tails", detectable=0.02))
    light = scene(suite_bias.CellBias("unbiased", detectable=0.02))
    assert "indicative only" in R.bias_words(heavy)
    assert "indicative only" in R.bias_finding([heavy])
    # negative control: a testable calibration cell's power is stated plainly
    assert "indicative" not in R.bias_words(light) + R.bias_finding([light])


def test_a_method_that_learns_is_tested_on_its_renders_spread_not_its_pixels():
    """A learned guide is shared by every pixel of a render: its pixels are not independent
    estimates, so its blocks' variances come from the spread of its renders."""
    assert suite_bias.variance_kind(FakeMethod(), True) == "pixels"
    assert suite_bias.variance_kind(FakeMethod(learns=True), True) == "renders"
    assert suite_bias.variance_kind(FakeMethod(sampler="halton"), True) == "renders"
    from experiments.lib.methods import parse_method
    assert parse_method("guided+nee").learns and not parse_method("bsdf+nee").learns
    assert not parse_method("path").learns


def test_a_learning_method_under_its_training_thresholds_is_tested_on_its_pixels():
    """A guided job under vr_guided_path's training thresholds (256 spp and 2^20 samples)
    learns nothing: it is bsdf+nee's estimator, its pixels independent, so its cell takes
    the pixels' variances (many degrees of freedom) unless one of its renders trained.
    Negative control: a cell with one render that trained takes the renders' spread."""
    from experiments.lib.methods import parse_method
    guided, pixels = parse_method("guided+nee"), 64 * 48
    assert not guided.trains(269, pixels) and not guided.trains(16, pixels)
    assert guided.trains(512, pixels) and not parse_method("bsdf+nee").trains(512, pixels)
    image = np.zeros((48, 64, 3))
    untrained = [[(image, 16)] * 3, [(image, 269)] * 3]
    assert not suite_bias.trained(guided, untrained, pixels)
    assert suite_bias.variance_kind(guided, True, False) == "pixels"
    assert suite_bias.trained(guided, [[(image, 16)] * 3, [(image, 512)] * 3], pixels)
    assert suite_bias.variance_kind(guided, True, True) == "renders"
    assert suite_bias.variance_kind(guided, False, False) == "renders"    # a wider filter


def test_a_failed_calibration_makes_the_scenes_biased_verdicts_untestable():
    """The method that renders the reference is tested against it too: where it fails its
    own test (heavy tails or a disagreement: the reference or the variances are not to be
    trusted), no other method of the scene is called biased; where it passes, verdicts
    stand; unbiased and untestable cells are kept as they are."""
    ok, bad = suite_bias.CellBias("unbiased"), suite_bias.CellBias("biased", delta=(0.1,))
    tails = suite_bias.CellBias("untestable", "heavy_tails")
    kept = suite_bias.calibrated({"path": ok, "mine": bad}, "path")
    assert kept["mine"].status == "biased"
    for own in (tails, suite_bias.CellBias("biased")):
        out = suite_bias.calibrated({"path": own, "mine": bad, "other": ok}, "path")
        assert out["mine"].status == "untestable" and out["mine"].reason == "calibration"
        assert out["mine"].delta == (0.1,) and out["other"].status == "unbiased"
    assert suite_bias.calibrated({"mine": bad}, "path")["mine"].status == "biased"


def test_untestable_cells_are_counted_by_reason_and_their_table_named():
    """The findings' bias sentence counts the untestable cells by reason (one count per
    reason, however many cells share it) and names the table of every cell, which the
    report links; no cell is listed by name."""
    from types import SimpleNamespace
    from experiments.lib.studies.suite import bias_report
    cells = {f"m{i}": SimpleNamespace(block_bias=suite_bias.untestable("heavy_tails"))
             for i in range(7)}
    cells["d"] = SimpleNamespace(block_bias=suite_bias.untestable("deterministic"))
    cells["ok"] = SimpleNamespace(block_bias=suite_bias.CellBias("unbiased"))
    results = [SimpleNamespace(name="a", cells=cells, power=None),
               SimpleNamespace(name="b", cells={"m0": cells["m0"]}, power=None)]
    text = bias_report.bias_finding(results)
    assert "untestable: 9 of 10 cells: " in text
    assert f"{bias_report.UNTESTABLE['heavy_tails']}: 8" in text
    assert f"{bias_report.UNTESTABLE['deterministic']}: 1" in text
    assert text.count(bias_report.UNTESTABLE["heavy_tails"]) == 1 and "m3" not in text
    assert f"each cell in {bias_report.BIAS_TABLE}" in text


def test_a_file_named_in_a_finding_is_linked_where_it_exists(tmp_path):
    from experiments.lib import report
    (tmp_path / "suite").mkdir()
    (tmp_path / "suite" / "bias_test.csv").write_text("x\n")
    html = report._linked("see suite/bias_test.csv, not suite/none.csv <b>", str(tmp_path))
    assert '<a href="suite/bias_test.csv">suite/bias_test.csv</a>' in html
    assert "suite/none.csv" in html and 'href="suite/none.csv"' not in html
    assert "&lt;b&gt;" in html


def test_findings_table_rows_follow_each_scenes_verdicts():
    """One row per scene: the winner or the tied set, the best method's equal-time ratio,
    the methods the bias test flags, the count of its untestable cells."""
    from types import SimpleNamespace as NS
    from experiments.lib.studies.suite import words

    def cell(short, status):
        return NS(relative={"equal_time": NS(short=lambda: short)},
                  block_bias=None if status is None else suite_bias.CellBias(status),
                  biased=status == "biased")
    won = NS(name="a", ranking=A.Ranking(("x", "y"), "x", ("x",)),
             cells={"x": cell("2 [1.5, 2.5]", "unbiased"), "y": cell("1", "untestable"),
                    "z": cell("0.5", "biased"), "w": cell("0.9", None)})
    tied = NS(name="b", ranking=A.Ranking(("y", "x"), None, ("y", "x")),
              cells={"x": cell("1.1", "untestable"), "y": cell("1.2 [0.9, 1.6]", "untestable")})
    assert words.findings_table([won, tied]) == [
        ["a", "x", "2 [1.5, 2.5]", "z", 1],
        ["b", "y and x (tied)", "1.2 [0.9, 1.6]", "none", 2]]


def test_blocks_of_few_varying_pixels_do_not_read_as_heavy_tails():
    """A constant background (a directly visible environment) leaves a few varying pixels
    in the blocks along an object's silhouette; with 1 pixel of 3 renders one deviation
    holds most of the block's squares by chance (always, for normal values). Such blocks
    are not read by the heavy-tail check (fewer than bias.TAIL_TERMS terms): light-tailed
    renders with a silhouette of 1 to 3 pixels per block are testable (tail share 0);
    negative control: the same blocks counted (TAIL_TERMS 1) give a tail share of 0.17
    (5 of 30 blocks), over the gate of 0.05, and renders of rare large values over the
    object still read as heavy-tailed blocks (tested by their image sum)."""
    rng = np.random.default_rng(11)
    mu = rng.uniform(0.2, 1.0, (H, W, C))
    varying = np.zeros((H, W, C), bool)
    varying[8:, :] = True                      # the object: rows 8 and below
    for bx in range(W // 8):                   # a silhouette of 1..3 pixels per top block
        varying[3, 8 * bx: 8 * bx + 1 + bx % 3] = True

    def masked(k, spp, rare=False):
        if rare:
            x = mu * rng.binomial(spp, 0.002, (k, H, W, C)) / (0.002 * spp)
        else:
            x = renders(rng, mu, k, spp)
        return np.where(varying, x, mu)
    for rare in (False, True):
        budgets = [[(x, 16) for x in masked(3, 16, rare)], [(x, 64) for x in masked(3, 64, rare)]]
        chunks = masked(8, 128)
        got = suite_bias.check_cell(FakeMethod(), budgets, chunks, True, True,
                                    FakeMethod("path"), ALPHA)
        assert (got.tail_share > suite_bias.TAILS_SHARE) == rare, (rare, got.tail_share)
        assert got.scope == ("image" if rare else "blocks")
        if not rare:
            assert got.tail_share == 0.0, got.tail_share
            halves = [bias.padded(np.stack([x for x, _ in b])) for b in budgets]
            mask = bias.varying_pixels(bias.Renders(np.concatenate(halves)),
                                       bias.Renders(bias.padded(chunks)))
            old = bias.TAIL_TERMS
            try:
                bias.TAIL_TERMS = 1
                share = bias.tail_share(halves, mask)
                assert share > suite_bias.TAILS_SHARE
            finally:
                bias.TAIL_TERMS = old
