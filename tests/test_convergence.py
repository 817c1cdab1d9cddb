"""The convergence study's analysis is computed from its numbers (no rendering here).

Synthetic measurements whose answer is known: per-repeat errors are a known expected error
times a fixed zero-mean jitter (so the mean over the repeats is exactly that error), plus
the reference's own expected error (the floor) that the analysis must subtract. Each
direction of a verdict has its mirror as a negative control, and a tie must read "not
distinguishable".
"""
import dataclasses
import json
import types

import pytest

from experiments.lib import counts, stats
from experiments.lib.engine import Cell
from experiments.lib.methods import Depth, parse_method
from experiments.lib.studies import conclusion as C
from experiments.lib.studies import convergence
from experiments.lib.studies import convergence_analysis as A
from experiments.lib.studies.convergence_report import best_text

JITTER = (0.94, 0.98, 1.02, 1.06)            # four repeats, mean exactly 1
COUNTS = (1, 2, 4, 8, 16, 32, 64)
FLOOR = A.Floor(mse=2e-4, relmse=1e-3)

SETTINGS = convergence.ConvergenceSettings(
    out="", scene="cbox.xml", info=None, resolution=(128, 64), depth=Depth(8), methods=(),
    repeats=len(JITTER), variant="llvm_ad_rgb", seed=0, reference_spp=2048,
    reference_method=parse_method("path"), executor=None, spp=COUNTS[-1], time_budget=0.25,
    best=None)


def rung(spp, relmse, mse=None, seconds=None, jitter=JITTER, floor=FLOOR):
    """A method at ``spp`` whose expected errors are ``relmse`` (and ``mse``, default the
    same) over the reference's, taking ``seconds`` (default 1 ms per spp)."""
    mse = relmse if mse is None else mse
    seconds = spp * 1e-3 if seconds is None else seconds
    return A.Rung(spp, len(jitter), tuple(seconds for _ in jitter),
                  tuple(mse * k + floor.mse for k in jitter),
                  tuple(relmse * k + floor.relmse for k in jitter))


def ladder(c, power=-1.0, mse_c=None, **kw):
    """Rungs with relMSE c x spp^power (MSE mse_c x spp^power)."""
    return [rung(n, c * n ** power, None if mse_c is None else mse_c * n ** power, **kw)
            for n in COUNTS]


def measured(ladders: dict, equal: dict | None = None, floor=FLOOR) -> A.Measured:
    """``equal`` defaults to each ladder's last rung (the same speed and error)."""
    equal = equal or {m: rs[-1] for m, rs in ladders.items()}
    return A.Measured(ladders, equal, floor, len(JITTER), COUNTS)


def first_row(result) -> C.Comparison:
    return result.conclusion[0]


# ------------------------------------------------------------ direction of the verdicts

def test_a_known_better_method_is_named_more_efficient_and_the_mirror_the_other_way():
    better = A.analyse(measured({"uniform": ladder(1.0), "bsdf": ladder(0.1)}), SETTINGS)
    row = first_row(better)
    assert (row.a, row.b, row.better) == ("bsdf", "uniform", "bsdf")
    assert row.ratio.value == pytest.approx(10.0) and row.ratio.lo > 1
    assert row.verdict() == "bsdf is more efficient"
    assert better.sentences[0].startswith("The most efficient after 64 spp is bsdf: bsdf is "
                                          "more efficient than uniform by 10")
    eff = {r.method: r.relative for r in better.efficiency}
    assert eff["uniform"].value == 1 and eff["bsdf"].value == pytest.approx(10.0)
    # negative control: the same numbers with the methods swapped name the other one
    worse = A.analyse(measured({"uniform": ladder(0.1), "bsdf": ladder(1.0)}), SETTINGS)
    row = first_row(worse)
    assert row.better == "uniform" and row.verdict() == "uniform is more efficient"
    assert "uniform is more efficient than bsdf" in worse.sentences[0]
    assert {r.method: r.relative for r in worse.efficiency}["bsdf"].value == \
        pytest.approx(0.1)


def test_a_tie_reads_not_distinguishable():
    tie = A.analyse(measured({"uniform": ladder(1.0),
                              "bsdf": ladder(1.0, jitter=tuple(reversed(JITTER)))}), SETTINGS)
    row = first_row(tie)
    assert row.better is None and row.verdict() == "not distinguishable"
    assert "not distinguishable" in tie.sentences[0]
    assert row.ratio.lo < 1 < row.ratio.hi


def test_time_enters_the_efficiency_both_ways():
    """Half the error at three times the cost is less efficient (and the mirror more)."""
    slow = [rung(n, 0.5 / n, seconds=3e-3 * n) for n in COUNTS]
    result = A.analyse(measured({"uniform": ladder(1.0), "bsdf": slow}), SETTINGS)
    assert first_row(result).better == "uniform"
    assert {r.method: r.relative for r in result.efficiency}["bsdf"].value == \
        pytest.approx(1 / (0.5 * 3))
    fast = [rung(n, 2.0 / n, seconds=0.25e-3 * n) for n in COUNTS]
    result = A.analyse(measured({"uniform": ladder(1.0), "bsdf": fast}), SETTINGS)
    assert first_row(result).better == "bsdf"


def test_verdicts_use_relmse_where_mse_would_rank_the_other_way():
    """The Veach MIS scene's case: bsdf+nee has 10x the MSE of bsdf (the edges of a
    directly visible light) but a 20x lower relMSE: the verdict follows relMSE."""
    ladders = {"uniform": ladder(1.0), "bsdf": ladder(0.2, mse_c=0.01),
               "bsdf+nee": ladder(0.01, mse_c=0.1)}
    result = A.analyse(measured(ladders), SETTINGS)
    assert result.ranking[0] == "bsdf+nee"
    nxt = result.conclusion[1]
    assert (nxt.a, nxt.b, nxt.better) == ("bsdf+nee", "bsdf", "bsdf+nee")
    assert nxt.ratio.value == pytest.approx(20.0)
    # negative control: the same numbers by MSE name bsdf the more efficient one
    nee, bsdf = ladders["bsdf+nee"][-1], ladders["bsdf"][-1]
    by_mse = stats.efficiency_ratio([v - FLOOR.mse for v in nee.mse], nee.seconds,
                                    [v - FLOOR.mse for v in bsdf.mse], bsdf.seconds)
    assert by_mse.hi < 1
    row = next(r for r in result.efficiency if r.method == "bsdf+nee")
    assert row.mse.value == pytest.approx(0.1 / 64)          # MSE stays in the table


# ------------------------------------------------------------ the reference's floor

def test_the_reference_floor_is_subtracted_from_every_expected_error():
    """Raw errors = true error + a floor five times larger: the reported expected errors
    recover the true ones (their intervals contain them), the raw means do not."""
    floor = A.Floor(mse=5e-3, relmse=5e-2)
    true = 1e-2 / 64
    result = A.analyse(measured({"uniform": ladder(1e-2, floor=floor)}, floor=floor),
                       SETTINGS)
    last = result.lines["uniform"][-1]
    for est in (last.mse, last.relmse):
        assert est.value == pytest.approx(true) and est.lo < true < est.hi
        assert not est.bound
    raw = stats.mean_interval([true * k + floor.relmse for k in JITTER])
    assert raw.lo > 10 * true                                 # negative control: not subtracted


def test_an_error_below_the_floor_is_a_bound_and_its_verdict_cannot_be_told():
    """bsdf+nee+halton:owen as noisy as the reference: its excess over the floor is not
    resolved, so it is an upper bound (never NaN or negative) and its comparison with
    bsdf+nee cannot be told; bsdf+nee itself is resolved."""
    wide = (0.2, 1.8, 0.4, 1.6)                               # mean 1, a wide spread
    tiny = [rung(n, 1e-4 * FLOOR.relmse, jitter=wide) for n in COUNTS]
    best = convergence.Best(parse_method("bsdf+nee+halton:owen"), "halton:owen")
    settings = dataclasses.replace(SETTINGS, best=best)
    result = A.analyse(measured({"uniform": ladder(1.0), "bsdf+nee": ladder(0.01),
                                 "bsdf+nee+halton:owen": tiny}), settings)
    line = result.lines["bsdf+nee+halton:owen"][-1]
    assert line.relmse.bound and line.mse.bound
    assert line.relmse.value >= 0 and line.relmse.hi == line.relmse.value
    assert "below the reference's own noise" in line.relmse.text()
    resolved = result.lines["bsdf+nee"][-1].relmse
    assert not resolved.bound and resolved.value == pytest.approx(0.01 / 64)   # control
    row = next(r for r in result.efficiency if r.method == "bsdf+nee+halton:owen")
    assert C.ratio_cells(row.relative) == ["n/a"] * 3 and "relMSE" in row.bounds()
    assert "bsdf+nee+halton:owen" not in result.ranking
    combo = next(c for c in result.conclusion if c.a == "bsdf+nee+halton:owen")
    assert combo.verdict() == C.UNTOLD
    assert "cannot be told" in combo.sentence()


# ------------------------------------------------------------ equal time, slopes, ladder

def test_the_declaration_ladders_then_equal_time_at_the_ladders_cost_per_sample():
    """The study as the engine runs it: a doubling ladder to --spp, then as many samples as
    fit in --time-budget at the cost per sample measured on each method's ladders (the
    engine's rule), under the job names the study always had."""
    decl = convergence.declare(dataclasses.replace(SETTINGS, methods=(
        parse_method("bsdf"), parse_method("uniform+halton"))))
    ladder_budget, equal = decl.budgets
    assert ladder_budget.ladder == COUNTS and equal.timed and equal.after == ladder_budget.name
    assert equal.seconds == 0.25 and not equal.power_of_two and not equal.max_spp
    cell = Cell("scene", "bsdf", ladder_budget.name)
    assert decl.key(decl, cell) == "convergence/bsdf"
    assert decl.key(decl, dataclasses.replace(cell, budget=equal.name)) == "equal_time/bsdf"
    per_sample = 1 / 1024                                     # exact in binary

    def ran(seconds, spp):
        return [types.SimpleNamespace(spp=spp, kernel_seconds=seconds, host_seconds=0.0,
                                      wall_seconds=seconds)]
    def count(measured):             # the engine's rule for this budget (Engine.count)
        return counts.equal_time_spp(equal.seconds, measured, equal.power_of_two,
                                     equal.max_spp)
    assert count([ran(512 * per_sample, 512)] * 2) == 256
    assert count([ran(1024 * per_sample, 512)] * 2) == 128  # 2x slower
    assert count([ran(1.0, 1)]) == 1      # less than a sample: one


def test_slopes_of_synthetic_power_laws():
    zero = A.Floor(0.0, 0.0)
    ladders = {"uniform": [rung(n, 0.3 * n ** -2.0, 0.5 / n, seconds=0.01 * n, floor=zero)
                           for n in COUNTS],
               "flat": [rung(n, 0.1, 0.1, seconds=0.01 * n, floor=zero) for n in COUNTS]}
    result = A.analyse(measured(ladders, floor=zero), SETTINGS)
    assert result.slopes["uniform"] == pytest.approx((-1.0, -1.0, -2.0, -2.0))
    assert result.slopes["flat"] == pytest.approx((0.0, 0.0, 0.0, 0.0), abs=1e-9)


def test_order_changes_where_the_interval_decides_another_leader():
    up, down = stats.Estimate(2.0, 1.5, 2.5, 4), stats.Estimate(0.5, 0.4, 0.6, 4)
    open_ = stats.Estimate(1.0, 0.5, 2.0, 4)
    assert C.order_changes([1, 2, 4], [up, open_, up]) == ()
    assert C.order_changes([1, 2, 4, 8], [up, open_, down, down]) == ((4, -1),)
    assert C.order_changes([1, 2], [open_, down]) == ()      # the first decision: no change
    # along a study's ladder: bsdf worse than uniform up to 4 spp, better from 8
    bsdf = [rung(n, (4.0 if n < 8 else 0.1) / n) for n in COUNTS]
    result = A.analyse(measured({"uniform": ladder(1.0), "bsdf": bsdf}), SETTINGS)
    row = first_row(result)
    assert (row.a, row.better, row.changes) == ("bsdf", "bsdf", ((8, 1),))
    assert row.changes_text() == "8 spp (bsdf ahead from there)"
    assert "the order changes along the ladder at 8 spp" in result.sentences[0]
    steady = A.analyse(measured({"uniform": ladder(1.0), "bsdf": ladder(0.1)}), SETTINGS)
    assert first_row(steady).changes == () and first_row(steady).changes_text() == "none"


# ------------------------------------------------------------ the conclusion and best pick

def _four_methods(best_spp, best_depth=8, resolution="128x64"):
    best = convergence.Best(parse_method("bsdf+nee+multijitter"), "multijitter", best_depth,
                            best_spp, resolution)
    ladders = {"uniform": ladder(1.0), "cosine": ladder(0.5), "bsdf+nee": ladder(0.02),
               "bsdf+nee+multijitter": ladder(0.01)}
    equal = {m: rs[-1] for m, rs in ladders.items()}
    equal["cosine"] = rung(128, 0.5 / 128, seconds=0.064)     # at equal time: no longer
    return A.analyse(measured(ladders, equal), dataclasses.replace(SETTINGS, best=best))


def test_the_conclusion_is_a_short_table_and_at_most_three_sentences_from_it():
    result = _four_methods(best_spp=4)
    pairs = [(c.a, c.b) for c in result.conclusion]
    assert pairs == [("bsdf+nee+multijitter", "uniform"), ("bsdf+nee+multijitter", "bsdf+nee"),
                     ("bsdf+nee+multijitter", "uniform")]          # the best pick: no twice
    assert len(result.sentences) == 3
    cells = C.rows(result.conclusion)
    assert [len(r) for r in cells] == [len(C.HEADER)] * 3
    # every sentence is one of the table's rows, with the table's numbers
    for sentence in result.sentences:
        row = next(c for c in result.conclusion if c.sentence() == sentence)
        assert stats.g(row.ratio.value) in sentence
    assert result.conclusion[-1].changes is None and cells[-1][-1] == "(no ladder)"
    assert C.long_paragraphs([{"kind": "text", "text": " ".join(result.sentences)}]) == []


def test_a_best_combination_that_does_not_lead_gets_its_own_row_and_sentence():
    """Picked at 4 spp, the combination is less efficient than bsdf+nee at this count: the
    conclusion says so (and its mirror, where it leads, is the lead row itself)."""
    best = convergence.Best(parse_method("bsdf+nee+multijitter"), "multijitter", 8, 4)
    ladders = {"uniform": ladder(1.0), "path": ladder(0.015), "bsdf+nee": ladder(0.01),
               "bsdf+nee+multijitter": ladder(0.02)}
    result = A.analyse(measured(ladders), dataclasses.replace(SETTINGS, best=best))
    assert [(c.a, c.b) for c in result.conclusion] == [
        ("bsdf+nee", "uniform"), ("bsdf+nee", "path"), ("bsdf+nee+multijitter", "bsdf+nee"),
        ("bsdf+nee", "uniform")]                                  # the last: at equal time
    combo = result.conclusion[2]
    assert combo.better == "bsdf+nee" and combo.ratio.value == pytest.approx(0.5)
    assert result.sentences[1] == combo.sentence()
    assert "bsdf+nee is more efficient than bsdf+nee+multijitter by 2" in combo.sentence()


def test_paragraph_checker_finds_a_long_paragraph():
    long = {"kind": "text", "text": "short.\n\n" + "word " * 81}
    assert C.long_paragraphs([long]) == ["word " * 81]
    assert C.long_paragraphs([{"kind": "image", "caption": "a " * 80}]) == []
    assert len(C.long_paragraphs([{"kind": "table", "caption": "a " * 81}])) == 1


def test_the_best_combination_says_where_it_was_chosen_and_that_it_differs():
    note = best_text(_four_methods(best_spp=4, resolution="16x8").best_note)
    assert "chosen at max_depth 8, 4 spp, 16x8" in note
    assert "this study runs at max_depth 8, 64 spp, 128x64" in note
    assert "not claimed to be the best here" in note
    # negative control: chosen at this study's own count, depth and resolution
    same = best_text(_four_methods(best_spp=64).best_note)
    assert "chosen at max_depth 8, 64 spp, 128x64" in same and "not claimed" not in same
    assert "not claimed" in best_text(_four_methods(best_spp=64, best_depth=2).best_note)
    assert _four_methods(best_spp=64, best_depth=2).best_note.differs        # as data


def test_settings_read_where_the_sampler_study_made_its_pick(tmp_path):
    out = tmp_path / "r"
    (out / "samplers").mkdir(parents=True)
    pick = {"2": {"sampler": "multijitter", "spp": 4, "requested_spp": 4,
                  "most_efficient": "multijitter", "tied": ["multijitter"]},
            "8": {"sampler": "halton:owen", "spp": 9, "requested_spp": 8,
                  "most_efficient": "zsobol:owen", "tied": ["zsobol:owen", "halton:owen"]}}
    (out / "samplers" / "summary.json").write_text(json.dumps({
        "best": {"2": "multijitter", "8": "zsobol:none"}, "pick": pick}))
    (out / "samplers" / "section.json").write_text(json.dumps(
        {"settings": {"resolution": "16x8"}}))
    args = convergence.cli.parse_args(convergence.build_parser(),
                                      ["--resolution", "16x8", "--out", str(out)])
    best = convergence.settings_from(args).best
    # the pick, not the most efficient label (zsobol:none, deterministic), nor the largest
    # randomized estimate among those the study could not tell apart
    assert (best.method.name, best.depth, best.spp, best.resolution) == \
        ("bsdf+nee+halton:owen", 8, 8, "16x8")
    # negative control: a summary without a pick adds nothing
    (out / "samplers" / "summary.json").write_text(json.dumps({"best": {"8": "zsobol:none"}}))
    assert convergence.settings_from(args).best is None


def test_the_suite_adds_the_sampler_studys_pick_and_says_how_it_was_made(tmp_path):
    from experiments.lib.studies.suite import study as suite
    out = tmp_path / "r"
    (out / "samplers").mkdir(parents=True)
    record = {"sampler": "zsobol:owen", "spp": 64, "requested_spp": 64,
              "most_efficient": "orthogonal", "tied": ["orthogonal", "zsobol:owen"]}
    (out / "samplers" / "summary.json").write_text(json.dumps(
        {"best": {"2": "zsobol:none"}, "pick": {"2": record}}))
    method, note = suite._best_sampler("auto", str(out), [])
    assert method == "bsdf+nee+zsobol:owen"
    assert "could not tell its most efficient randomized sampler (orthogonal)" in note
    record["tied"] = ["zsobol:owen"]
    record["most_efficient"] = "zsobol:owen"
    (out / "samplers" / "summary.json").write_text(json.dumps({"pick": {"2": record}}))
    assert "ahead of every other by its interval" in suite._best_sampler("auto", str(out), [])[1]
    (out / "samplers" / "summary.json").write_text(json.dumps({"best": {"2": "zsobol:none"}}))
    assert suite._best_sampler("auto", str(out), [])[0] is None


def test_a_ratio_untold_for_the_baselines_bound_names_it():
    """An efficiency that cannot be told because the baseline's equal-time error is below
    the reference's noise says so in the method's row (not an unexplained n/a); negative
    control: with the baseline's error above the noise, nothing is named."""
    ladders = {"uniform": ladder(1.0), "bsdf": ladder(0.1)}

    def rows(baseline_excess):
        equal = {"uniform": rung(64, baseline_excess), "bsdf": rung(64, 0.1 / 64)}
        return {r.method: r for r in A.efficiency_rows(measured(ladders, equal), "uniform")}
    below = rows(-FLOOR.relmse / 2)             # the baseline under the reference's noise
    assert below["bsdf"].equal_relative.value != below["bsdf"].equal_relative.value   # NaN
    assert "uniform's equal-time relMSE" in below["bsdf"].bounds()
    above = rows(1.0 / 64)
    assert above["bsdf"].bounds() == [] and above["bsdf"].equal_relative.value > 0
