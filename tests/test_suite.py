"""The scene suite (experiments/lib/studies/suite/): end to end on two bundled scenes at
tiny settings (report, matrix, viewers, crops, findings, the furnace's exact value inside
every method's interval), resuming and extending its references, scenes that fail to load
or that vr_path refuses, a folder of scenes written here, bad arguments; and its analysis
on synthetic numbers (winner and ties, the hypothesis, bounds below the reference's noise,
relMSE with outliers rejected), each with a negative control."""
from __future__ import annotations

import html
import json
import shutil
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import scenes
from experiments.lib import counts, methods, metrics, stats
from experiments.lib import engine as engine_module
from experiments.lib.studies.suite import analysis as A
from experiments.lib.studies.suite import bias_report
from experiments.lib.studies.suite import declare
from experiments.lib.studies.suite import study as S
from _suite_engine import engine_at

QUICK = ["--quick", "--seed", "3"]
FURNACE = scenes.path("suite/furnace.xml")


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """The suite's quick run (2 bundled scenes, 3 methods, tiny films), once."""
    out = tmp_path_factory.mktemp("suite") / "r"
    S.STUDY.main(QUICK + ["--out", str(out)])
    return out


def _summary(out):
    return json.loads((out / "suite" / "summary.json").read_text())


# ------------------------------------------------------------------ end to end

def test_quick_run_writes_the_report(quick_run):
    out, summary = quick_run, _summary(quick_run)
    assert [s["name"] for s in summary["scenes"]] == ["furnace", "veach_mis"]
    for name in ("matrix.png", "matrix.pdf", "matrix.csv", "matrix.md", "cells.csv",
                 "scenes.csv", "crops/furnace.png", "crops/veach_mis.pdf"):
        assert (out / "suite" / name).exists(), name
    assert (out / "suite" / "crops" / "furnace.pdf").read_bytes()[:4] == b"%PDF"
    section = json.loads((out / "suite" / "section.json").read_text())
    viewers = [b for b in section["blocks"] if b["kind"] == "viewer"]
    assert [v["manifest"]["title"] for v in viewers] == ["furnace: equal time",
                                                         "veach_mis: equal time"]
    assert [i["label"] for i in viewers[0]["manifest"]["images"]] == \
        ["bsdf", "bsdf+nee", "path", "reference"]
    # the findings box at the top of the page, from summary.json
    page = (out / "index.html").read_text()
    assert page.index('class="findings"') < page.index("<nav>")
    assert html.escape(summary["findings"][0]) in page
    # per scene at most three sentences, at most 80 words
    for s in summary["scenes"]:
        assert 1 <= len(s["sentences"]) <= 3 and len(" ".join(s["sentences"]).split()) <= 80


def test_the_findings_open_with_a_table_of_every_scene(quick_run):
    """The findings box opens with one row per scene (winner or tied set, the best
    method's efficiency over the baseline, flagged methods, untestable cells), each
    following from the scene's own verdicts and cells in summary.json and bias_test.csv,
    and the matrix figure beneath it. (The counts per reason and the link:
    tests/test_suite_bias.py, on cells that are untestable.)"""
    out, summary = quick_run, _summary(quick_run)
    table = summary["findings_table"]
    assert table["header"][0] == "scene" and table["figure"] == "suite/matrix.png"
    cells = {(c["scene"], c["method"]): c for c in summary["cells"]
             if c["budget"] == "equal_time"}
    tested = [line.split(",") for line in
              (out / "suite" / "bias_test.csv").read_text().splitlines()[1:]]
    assert [row[0] for row in table["rows"]] == [s["name"] for s in summary["scenes"]]
    for (name, best, ratio, flagged, untestable), scene in zip(table["rows"],
                                                                summary["scenes"]):
        winner, ties = scene["winner"], scene["ties"]
        assert best == (winner or f"{bias_report.names(ties)} (tied)")
        c = cells[(name, winner or ties[0])]
        if not c["efficiency_bound"]:      # the value, 3 significant digits
            assert float(ratio.split()[0]) == pytest.approx(c["efficiency"], rel=5e-3)
        assert flagged == (", ".join(scene["biased"]) or "none")
        assert untestable == sum(t[0] == name and t[2] == "untestable" for t in tested)
    page = (out / "index.html").read_text()
    box = page[page.index('class="findings"'):page.index("<nav>")]
    assert box.index("<table>") < box.index("<ul>") and 'src="suite/matrix.png"' in box


def test_quick_run_numbers_follow_from_each_other(quick_run):
    summary = _summary(quick_run)
    cells = {(c["scene"], c["method"], c["budget"]): c for c in summary["cells"]}
    for (scene, method, budget), c in cells.items():
        for k in ("relmse", "mse", "efficiency", "ns_per_sample"):
            if c.get(f"{k}_lo") is not None and not c.get(f"{k}_bound"):
                assert c[f"{k}_lo"] <= c[k] <= c[f"{k}_hi"], (scene, method, k)
        base = cells[(scene, "path", budget)]
        if not (c["relmse_bound"] or base["relmse_bound"] or c["efficiency_bound"]):
            # efficiency over the baseline = (relMSE x seconds of samples) of path over its
            expected = (base["relmse"] * base["spp"] * base["ns_per_sample"]) / \
                       (c["relmse"] * c["spp"] * c["ns_per_sample"])
            assert c["efficiency"] == pytest.approx(expected, rel=1e-6)
    assert all(c["ns_per_sample"] > 0 and c["per_call_seconds"] > 0 for c in cells.values())
    assert cells[("furnace", "path", "equal_time")]["efficiency"] == pytest.approx(1.0)


def test_furnace_exact_value_inside_every_methods_interval(quick_run):
    rows = (quick_run / "suite" / "bias.csv").read_text().splitlines()[1:]
    checks = [r.split(",") for r in rows]
    assert {c[1] for c in checks} == {"bsdf", "bsdf+nee", "path"}
    for scene, method, mean, lo, hi, exact, level, inside in checks:
        assert float(lo) <= 2.0 <= float(hi) and inside == "yes", method
        # negative control: the check would see a 4% bias (an albedo of 0.52 for 0.5)
        assert float(hi) < 2.0 * 1.04 and float(lo) > 2.0 / 1.04, method


def test_a_second_run_renders_nothing_and_more_spp_extend_the_reference(quick_run, tmp_path,
                                                                       count_jobs):
    out = tmp_path / "r"
    shutil.copytree(quick_run, out)
    S.STUDY.main(QUICK + ["--out", str(out)])
    assert count_jobs == []
    made = {p.parent.name: json.loads(p.read_text())
            for p in (out / "references").glob("*/reference.json")}
    assert len(made) == 2
    more = 2 * max(m["spp"] for m in made.values())
    S.STUDY.main(QUICK + ["--out", str(out), "--reference-spp", str(more)])
    after = {p.parent.name: json.loads(p.read_text())
             for p in (out / "references").glob("*/reference.json")}
    expected = sorted(f"{key}/chunk-{i:05d}" for key, m in made.items()
                      for i in range(m["chunks"], after[key]["chunks"]))
    assert expected and sorted(count_jobs) == expected          # only the new chunks
    assert all(after[k]["spp"] >= more for k in after)
    assert {s["reference_spp"] for s in _summary(out)["scenes"]} == \
        {m["spp"] for m in after.values()}


def test_a_users_reference_is_used_with_its_error_unknown(quick_run, tmp_path):
    exr = next((quick_run / "references").glob("furnace-*/reference.exr"))
    mine = tmp_path / "mine"
    mine.mkdir()
    shutil.copy(exr, mine / "furnace.exr")
    out = tmp_path / "r"
    S.STUDY.main(QUICK + ["--out", str(out), "--scenes", "furnace", "--methods", "bsdf,path",
                          "--references", str(mine)])
    assert not (out / "references").exists()               # nothing rendered for it
    row = (out / "suite" / "scenes.csv").read_text().splitlines()[1]
    assert "user's EXR (own error unknown)" in row


# ------------------------------------------------------------------ robustness

MEDIUM = """
    <shape type="sphere">
        <point name="center" x="0" y="0" z="-0.5"/>
        <float name="radius" value="0.1"/>
        <bsdf type="null"/>
        <medium type="homogeneous" name="interior">
            <rgb name="albedo" value="0.5"/>
            <float name="sigma_t" value="1"/>
        </medium>
    </shape>
</scene>"""
MISSING = """
    <shape type="obj"><string name="filename" value="nope_missing.obj"/></shape>
</scene>"""


def test_broken_scenes_do_not_stop_the_others(tmp_path):
    text = open(FURNACE).read()
    (tmp_path / "medium.xml").write_text(text.replace("</scene>", MEDIUM))
    (tmp_path / "missing.xml").write_text(text.replace("</scene>", MISSING))
    (tmp_path / "broken.xml").write_text(text[:len(text) // 2])
    shutil.copy(FURNACE, tmp_path / "furnace.xml")
    out = tmp_path / "r"
    S.STUDY.main(QUICK + ["--out", str(out), "--scenes", str(tmp_path),
                          "--methods", "bsdf,path"])
    summary = _summary(out)
    assert [s["name"] for s in summary["scenes"]] == ["furnace"]
    failed = summary["failed_scenes"]
    assert set(failed) == {"broken", "medium", "missing"}
    assert "does not parse" in failed["broken"]
    assert "participating medium" in failed["medium"]
    assert "nope_missing.obj" in failed["missing"]
    table = (out / "suite" / "failures.csv").read_text()
    assert all(name in table for name in failed)


def test_scenes_folder_with_include_and_path(tmp_path):
    """Two scenes written here: one takes its sensor from a fragment found through <path>."""
    folder = tmp_path / "mine"
    (folder / "parts").mkdir(parents=True)
    text = open(FURNACE).read()
    start, end = text.index("<sensor"), text.index("</sensor>") + len("</sensor>")
    defaults = "".join(line + "\n" for line in text.splitlines() if "<default " in line)
    (folder / "parts" / "camera.xml").write_text(
        f'<scene version="3.0.0">\n{defaults}{text[start:end]}\n</scene>\n')
    (folder / "split.xml").write_text(
        text[:start] + '<path value="parts"/>\n<include filename="camera.xml"/>\n' + text[end:])
    shutil.copy(FURNACE, folder / "plain.xml")
    out = tmp_path / "r"
    S.STUDY.main(QUICK + ["--out", str(out), "--scenes", str(folder),
                          "--methods", "bsdf,path"])
    summary = _summary(out)
    assert [s["name"] for s in summary["scenes"]] == ["plain", "split"]
    assert summary["failed_scenes"] == {}


def test_a_scenes_header_methods_leave_the_others_out(tmp_path):
    """A scene whose header says ``methods: bsdf`` renders bsdf and the baseline alone; the
    report says which methods it left out and why; a scene without it renders them all."""
    text = open(FURNACE).read()
    (tmp_path / "only.xml").write_text(text.replace("  over:", "  methods: bsdf\n  over:", 1))
    shutil.copy(FURNACE, tmp_path / "all.xml")
    out = tmp_path / "r"
    S.STUDY.main(QUICK + ["--out", str(out), "--scenes", str(tmp_path),
                          "--methods", "bsdf,bsdf+nee,path"])
    summary = _summary(out)
    cells = {(c["scene"], c["method"]) for c in summary["cells"]}
    assert {m for s, m in cells if s == "only"} == {"bsdf", "path"}
    assert {m for s, m in cells if s == "all"} == {"bsdf", "bsdf+nee", "path"}
    scene = {s["name"]: s for s in summary["scenes"]}
    assert list(scene["only"]["left_out"]) == ["bsdf+nee"]
    assert "header methods (bsdf)" in scene["only"]["left_out"]["bsdf+nee"]
    assert scene["all"]["left_out"] == {}
    rows = {r.split(",")[0]: r for r in (out / "suite" / "matrix.csv").read_text().splitlines()}
    assert "left out" in rows["only"] and "left out" not in rows["all"]
    page = json.loads((out / "suite" / "section.json").read_text())
    assert any("left out here are bsdf+nee" in b.get("text", "") for b in page["blocks"])


@pytest.mark.parametrize("argv, message", [
    (["--scenes", "/no/such/folder"], "neither a folder nor a scene file"),
    (["--scenes", "EMPTY"], "holds no *.xml"),
    (["--methods", "bsdf,nosuch"], "unknown method 'nosuch'"),
    (["--baseline", "cosine", "--methods", "bsdf,path"], "is not one of the methods"),
])
def test_bad_arguments_exit_2_with_one_line(tmp_path, capsys, argv, message):
    argv = [str(tmp_path) if a == "EMPTY" else a for a in argv]
    with pytest.raises(SystemExit) as e:
        S.parse(argv + ["--out", str(tmp_path / "r")])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


# ------------------------------------------------------------------ analysis

def runs(err, secs=(1.0, 1.0, 1.0), spp=16):
    return A.Runs(spp, tuple(err), tuple(err), tuple(err), tuple(secs))


def numbers(errors: dict, floor=0.0, favours=(), over=()) -> A.SceneNumbers:
    cells = {m: A.Cell(m, {b: runs(e) for b in A.BUDGETS}, (100.0, 101.0, 99.0))
             for m, e in errors.items()}
    return A.SceneNumbers("s", cells, A.Floor(floor, floor, floor), "path", favours, over)


TIGHT = (1.0, 1.1, 0.9)            # 10% spread over three repeats


def test_winner_only_where_its_interval_excludes_the_others():
    r = A.analyse_scene(numbers({"path": [2 * x for x in TIGHT], "bsdf": [4 * x for x in TIGHT],
                                 "bsdf+nee": list(TIGHT)}))
    assert r.ranking.winner == "bsdf+nee" and r.ranking.ties == ("bsdf+nee",)
    assert r.cells["bsdf+nee"].relative["equal_time"].value == pytest.approx(2.0)
    # negative control: a runner-up within 5% cannot be told apart, so no winner
    r = A.analyse_scene(numbers({"path": [1.05 * x for x in TIGHT], "bsdf": [4 * x for x in TIGHT],
                                 "bsdf+nee": list(TIGHT)}))
    assert r.ranking.winner is None and set(r.ranking.ties) == {"bsdf+nee", "path"}
    # and a wide spread (few repeats, heavy tails) cannot be told apart either
    r = A.analyse_scene(numbers({"path": [0.2, 2.0, 6.0], "bsdf+nee": list(TIGHT)}))
    assert r.ranking.winner is None


def test_hypothesis_held_failed_or_undecided():
    errors = {"path": [2 * x for x in TIGHT], "uniform": [8 * x for x in TIGHT],
              "bsdf+nee": list(TIGHT)}
    held = A.analyse_scene(numbers(errors, favours=("bsdf+nee*",), over=("uniform",)))
    assert held.verdict.status == "held" and held.verdict.favoured == "bsdf+nee"
    failed = A.analyse_scene(numbers(errors, favours=("uniform",), over=("bsdf*", "path")))
    assert failed.verdict.status == "failed"
    close = dict(errors, uniform=[1.03 * x for x in TIGHT])
    undecided = A.analyse_scene(numbers(close, favours=("bsdf+nee",), over=("uniform",)))
    assert undecided.verdict.status == "undecided"
    assert A.analyse_scene(numbers(errors)).verdict.status == "none"
    assert A.analyse_scene(numbers(errors, favours=("zsobol*",), over=("uniform",))) \
        .verdict.status == "untestable"


def test_a_learning_method_is_compared_with_its_plain_counterpart():
    """guided+nee against bsdf+nee (the same method without learning), per scene, pooled
    (geometric mean) over the scenes whose header does not favour it only: on one scene
    half of bsdf+nee's efficiency (twice its error at the same time), on another twice;
    the favoured scene is left out of the mean. A scene without bsdf+nee has no ratio."""
    from experiments.lib.methods import parse_method
    assert parse_method("guided+nee+zsobol:owen").plain == "bsdf+nee+zsobol:owen"
    assert parse_method("bsdf+nee").plain is None and parse_method("path").plain is None
    worse = A.analyse_scene(numbers({"path": list(TIGHT), "bsdf+nee": list(TIGHT),
                                     "guided+nee": [2 * x for x in TIGHT]}))
    better = A.analyse_scene(numbers({"path": list(TIGHT), "bsdf+nee": list(TIGHT),
                                      "guided+nee": [0.5 * x for x in TIGHT]}))
    favoured = A.analyse_scene(numbers({"path": list(TIGHT), "bsdf+nee": list(TIGHT),
                                        "guided+nee": [0.01 * x for x in TIGHT]},
                                       favours=("guided+nee*",), over=("path",)))
    alone = A.analyse_scene(numbers({"path": list(TIGHT), "guided+nee": list(TIGHT)}))
    assert worse.learned["guided+nee"][0].value == pytest.approx(0.5)
    assert favoured.learned["guided+nee"][1] and not worse.learned["guided+nee"][1]
    assert alone.learned == {}
    rows, mean, n, untrained = A.learned_over_plain([worse, better, favoured, alone])["guided+nee"]
    assert [s for s, _ in rows] == ["s", "s"] and n == 2 and mean == pytest.approx(1.0)
    assert untrained == []
    rows, mean, n, _ = A.learned_over_plain([worse, favoured])["guided+nee"]
    assert mean == pytest.approx(0.5) and n == 1


def test_an_adaptive_method_is_compared_with_its_twin_on_every_scene():
    """bsdf+nee+adaptive against bsdf+nee (the same estimator, its samples alike in every
    pixel) on every scene that renders both, favoured or not: a third of the error at equal
    time is 3 times the efficiency, twice the error a half; the finding names the scene
    where it loses at the interval's level and none where it does not (negative control);
    a scene without the twin has no ratio."""
    from experiments.lib.methods import parse_method
    from experiments.lib.studies.suite import words
    assert parse_method("bsdf+nee+adaptive").unadapted == "bsdf+nee"
    assert parse_method("path+adaptive").unadapted == "path"
    assert parse_method("bsdf+nee").unadapted is None
    # path (the baseline) at twice bsdf+nee's error: a ratio over it would read 6, not 3
    better = A.analyse_scene(replace(numbers({"path": [2 * x for x in TIGHT],
                                              "bsdf+nee": list(TIGHT),
                                              "bsdf+nee+adaptive": [x / 3 for x in TIGHT]},
                                             favours=("bsdf+nee+adaptive",), over=("path",)),
                                     name="better"))
    worse = A.analyse_scene(replace(numbers({"path": list(TIGHT), "bsdf+nee": list(TIGHT),
                                             "bsdf+nee+adaptive": [2 * x for x in TIGHT]}),
                                    name="worse"))
    alone = A.analyse_scene(numbers({"path": list(TIGHT), "bsdf+nee+adaptive": list(TIGHT)}))
    assert better.adapted["bsdf+nee+adaptive"].value == pytest.approx(3.0)
    assert alone.adapted == {}
    rows, mean, n = A.adapted_over_plain([better, worse, alone])["bsdf+nee+adaptive"]
    assert [s for s, _ in rows] == ["better", "worse"] and n == 2
    assert mean == pytest.approx(math.sqrt(1.5))
    text = " ".join(words.findings([better, worse], {}))
    assert "bsdf+nee+adaptive over bsdf+nee (equal-time efficiency): better 3" in text
    assert "it loses on worse." in text
    assert "it loses on no scene." in " ".join(words.findings([better], {}))


def test_the_learner_finding_names_the_scenes_where_it_did_not_train():
    """Where a learner's equal-time renders stayed under its training thresholds it is its
    plain counterpart's estimator: the finding names those scenes (their ratio is noise),
    and names none where every cell trained (the negative control)."""
    from experiments.lib.studies.suite import words
    errors = {"path": list(TIGHT), "bsdf+nee": list(TIGHT), "guided+nee": [2 * x for x in TIGHT]}
    plain = A.analyse_scene(numbers(errors))
    n = numbers(errors)
    cells = dict(n.cells, **{"guided+nee": replace(n.cells["guided+nee"], learns=True,
                                                    trained=False)})
    untrained = A.analyse_scene(replace(n, name="cheap", cells=cells))
    assert untrained.learned["guided+nee"][2] is False and plain.learned["guided+nee"][2]
    rows, _, _, names = A.learned_over_plain([plain, untrained])["guided+nee"]
    assert len(rows) == 2 and names == ["cheap"]
    text = " ".join(words.findings([plain, untrained], {}))
    assert "did not train at its equal-time count on 1 of the 2 (cheap)" in text
    assert "bsdf+nee's estimator" in text
    assert "did not train" not in " ".join(words.findings([plain], {}))


def test_a_learner_trained_where_its_equal_time_renders_did():
    """A cell's learner trained where its equal-time count reaches the guide's thresholds
    (2^20 samples and 256 spp on a 48x36 film: 607 spp), whatever its short equal-spp
    renders; never below them, nor for a method that does not learn."""
    from experiments.lib.methods import parse_method
    from experiments.lib.studies.suite import measure
    px, guided = 48 * 36, parse_method("guided+nee")

    def finals(time_spp):
        return {measure.TIME: [SimpleNamespace(spp=n) for n in time_spp],
                measure.SPP: [SimpleNamespace(spp=16)] * len(time_spp)}
    assert measure.trained(guided, finals([1587, 1600, 1590]), px)
    assert not measure.trained(guided, finals([29, 30, 29]), px)
    assert not measure.trained(guided, finals([600, 600, 600]), px)   # 1,036,800 < 2^20
    assert not measure.trained(parse_method("bsdf+nee"), finals([1587] * 3), px)


def test_an_error_below_the_references_noise_is_a_bound_not_nan():
    floor = 0.5
    below = [0.45, 0.52, 0.49]                      # raw errors: no more than the floor
    e = stats.excess_interval(below, floor)
    assert e.bound and e.lo == 0 and np.isfinite(e.value) and e.value >= 0
    assert "below the reference's own noise" in e.text()
    r = A.analyse_scene(numbers({"path": [2.0, 2.1, 1.9], "bsdf+nee": below}, floor=floor))
    ratio = r.cells["bsdf+nee"].relative["equal_time"]
    assert ratio.side == ">" and np.isfinite(ratio.value) and ratio.value > 1
    assert r.cells["bsdf+nee"].errors["equal_time"]["relmse"].bound
    assert r.bounds() == ["bsdf+nee"] and r.ranking.order[0] == "bsdf+nee"
    # the reference is then too noisy for the comparison, and the suite asks for more
    assert not r.reference_adequate
    def needed(nums, spp, cap):            # the engine's rule (declaration.ReferenceFloor)
        return counts.reference_spp(A.floor_share(nums), A.FLOOR_SHARE, spp, cap)
    assert needed(numbers({"path": [2.0] * 3, "bsdf+nee": below}, floor=floor),
                  256, 8192) == 8192                                # all it may: the cap
    # a floor half the smallest measured error: 19 times the samples bring it to 5%
    assert needed(numbers({"path": [2.0] * 3, "bsdf+nee": [1.0] * 3}, floor=0.5),
                  256, 10 ** 6) == 256 * 32
    # negative control: errors well above the floor are intervals, with no bound
    r = A.analyse_scene(numbers({"path": [2.0, 2.1, 1.9], "bsdf+nee": [1.0, 1.05, 0.95]},
                                floor=0.01))
    assert r.cells["bsdf+nee"].relative["equal_time"].side == "" and r.reference_adequate


def test_a_cheap_reference_is_extended_past_its_cap_as_far_as_its_seconds_go():
    """counts.reference_cap: the cap of the floor's extension is --reference-max-spp, or
    where the reference costs little the largest power of two times its samples whose
    render stays within the seconds allowed (veach_mis' path at 48x36: 256 spp in 0.039 s,
    2.5 s allow 64 times: 16384 spp); an expensive one keeps its cap (negative control),
    and no seconds (0, --reference-max-spp given) none beyond it; nor where the cap already
    brings the floor's share to the wanted one."""
    assert counts.reference_cap(256, 0.039, 4096, 2.5) == 16384
    assert counts.reference_cap(256, 0.039, 32768, 2.5) == 32768     # the larger of both
    assert counts.reference_cap(256, 2.0, 4096, 2.5) == 4096         # expensive: the cap
    assert counts.reference_cap(256, 0.039, 4096, 0.0) == 4096       # none allowed
    assert counts.reference_cap(256, 0.0, 4096, 2.5) == 4096         # no time measured
    assert counts.reference_cap(8192, 0.039, 4096, 0.0) == 8192      # never below spp
    # only where the floor's share would still be over the wanted one at the cap: a share
    # of 0.5 at 256 spp is 1/17 at 4096 (adequate at 0.1: the cap stands), 0.9 is 0.36
    assert counts.share_at(0.5, 256, 4096) == pytest.approx(1 / 17)
    assert counts.reference_cap(256, 0.039, 4096, 2.5, 0.5, 0.1) == 4096
    assert counts.reference_cap(256, 0.039, 4096, 2.5, 0.9, 0.1) == 16384


def test_relmse_rejected_against_a_hand_computed_case():
    ref = np.ones((25, 40, 3))                      # 1000 pixels: the top 1 is rejected
    image = ref + 0.1
    image[3, 7] = 50.0                              # one firefly
    kept = 0.1 ** 2 / (1 + metrics.RELMSE_EPS)      # every other pixel's relMSE
    assert metrics.relmse_rejected(image, ref) == pytest.approx(kept, rel=1e-12)
    firefly = 49.0 ** 2 / (1 + metrics.RELMSE_EPS)
    assert metrics.relmse(image, ref) == pytest.approx((999 * kept + firefly) / 1000)
    # the floor is subtracted over the kept pixels only
    floor = np.full_like(ref, 0.001)
    floor[3, 7] = 7.0
    assert metrics.relmse_rejected(image, ref, floor_map=floor) == \
        pytest.approx(kept - 0.001, rel=1e-9)
    # negative control: nothing rejected, the firefly rules
    assert metrics.relmse_rejected(image, ref, share=0.0) > 10 * kept


def test_equal_time_count_is_the_budgets_power_of_two(tmp_path):
    """The suite declares equal time to the engine: the count from the equal-spp renders'
    cost per sample (the repeats' mean), rounded to the nearest power of two, capped."""
    cfg = S.settings(S.parse(["--quick", "--spp", "16", "--time-budget", "0.1",
                              "--out", str(tmp_path)]))
    budget = declare.declaration(cfg, declare.plan_scenes(cfg)).budgets[1]

    def equal_time(measured):
        return counts.equal_time_spp(budget.seconds, measured, budget.power_of_two,
                                     budget.max_spp)

    def count(*per_sample):         # one render of 16 spp per repeat at these s per spp
        return equal_time([[SimpleNamespace(
            spp=16, kernel_seconds=16 * b, host_seconds=0.0, wall_seconds=0.0)]
            for b in per_sample])
    assert (budget.name, budget.after) == ("equal-time", "equal-spp")
    assert count(0.1 / 45) == 32                                     # 45 spp: nearest power 32
    assert count(0.1 / 46, 0.1 / 100) == 64                          # the repeats' mean
    assert count(0.1 / 17) == 16
    assert count(10.0) == 1
    assert count(1e-9) == declare.MAX_EQUAL_TIME_SPP
    # a learning method's host work between passes is a fixed cost per job: taken off the
    # budget, not spread over the 16 samples (which would give it a quarter of the count)
    learned = equal_time([[SimpleNamespace(
        spp=16, kernel_seconds=16 * 0.05 / 64, host_seconds=0.05, wall_seconds=0.0)]])
    assert learned == 64                       # (0.1 - 0.05) / (0.05 / 64 per sample)
    spread = equal_time([[SimpleNamespace(
        spp=16, kernel_seconds=16 * 0.05 / 64 + 0.05, host_seconds=0.0, wall_seconds=0.0)]])
    assert spread == 32                        # negative control: the same cost as kernel time


def test_a_learning_methods_equal_time_count_comes_from_its_pilot(tmp_path, monkeypatch):
    """guided+nee's equal-spp renders are too short to train and cost what BSDF sampling
    costs; its equal-time count comes from one pilot render (stored, in no comparison) at
    the count they give over LEARNER_COST (the same training decision at both counts),
    which costs 2.5 times as much per sample here: 0.4 of the count, not rounded to a power
    of two. A method that does not learn renders no pilot. The engine decides it
    (:meth:`.Engine.count`), for the suite as for every study. Where the smaller count
    would not train and the count would, the pilot renders the count itself (exact, not
    the power of two: tests/test_learner_counts.py)."""
    decl, engine, planned, time_budget = engine_at(tmp_path, "0.1",
                                                   "path,bsdf+nee,guided+nee")
    spp_budget = decl.budgets[0]
    per_sample, rendered, scale = 0.1 / 64, [], 2.0
    for slot in engine.slots(decl):
        planned.scales[(slot.scene.name, None, time_budget.name)] = (scale, "")

    def results(jobs):               # a pilot (its key) costs 2.5 times as much per sample
        return [SimpleNamespace(spp=j.spp, host_seconds=0.0, wall_seconds=0.0,
                                kernel_seconds=j.spp * per_sample *
                                (2.5 if "/pilot" in j.key else 1)) for j in jobs]
    monkeypatch.setattr(engine.study, "results", results)
    monkeypatch.setattr(engine.study, "run", lambda jobs, label="": rendered.extend(jobs))
    # a learner without thresholds (the guide trains only from 607 spp on a 48x36 film:
    # below them it renders no pilot, tests/test_learner_counts.py)
    monkeypatch.setattr(methods.Method, "trains", lambda self, spp, pixels: self.learns)
    got = {slot.method.name: engine.count(decl, time_budget, slot, planned)
           for slot in engine.slots(decl) if slot.method.name in ("bsdf+nee", "guided+nee")}
    assert got["bsdf+nee"] == 64 * scale
    assert got["guided+nee"] == int(0.1 * scale / (per_sample * 2.5)) != 32 * scale
    plain = counts.equal_time_spp(0.1 * scale, [results(jobs) for jobs in planned.runs(
        next(s for s in engine.slots(decl) if s.method.name == "guided+nee")
        .cell(spp_budget.name))])               # exact: 0.2 s at the short renders' cost
    assert plain in (127, 128)
    assert [(j.method.name, j.spp) for j in rendered] == \
        [("guided+nee", int(plain / engine_module.LEARNER_COST))]
    assert rendered[0].key.startswith("suite/cbox/guided_nee/equal-time/pilot-")
    assert rendered[0].pilot
    # the training thresholds between the two counts: the pilot at the count itself
    monkeypatch.setattr(methods.Method, "trains",
                        lambda self, spp, pixels: self.learns and spp >= 100)
    rendered.clear()
    slot = next(s for s in engine.slots(decl) if s.method.name == "guided+nee")
    engine.count(decl, time_budget, slot, planned)
    assert [j.spp for j in rendered] == [plain]


def test_a_learning_methods_equal_time_count_is_not_rounded_to_a_power_of_two(tmp_path):
    """A learning method's efficiency grows with its count: rounded to the nearest power of
    two, a pilot costing 1.4 or 1.45 times the equal-spp renders per sample would give it
    1.41 or 0.71 of the budget, and two runs would measure it at counts a factor of two
    apart. Its count from the pilot is the budget's own; a plain method's is still rounded."""
    cfg = S.settings(S.parse(["--quick", "--spp", "16", "--time-budget", "0.1",
                              "--out", str(tmp_path)]))
    budget = declare.declaration(cfg, declare.plan_scenes(cfg)).budgets[1]
    assert budget.power_of_two

    def count(per_sample, exact):   # exact: what Engine.pilot asks of the rule
        return counts.equal_time_spp(budget.seconds, [[SimpleNamespace(
            spp=16, kernel_seconds=16 * per_sample, host_seconds=0.0, wall_seconds=0.0)]],
            budget.power_of_two and not exact, budget.max_spp)
    for factor, exact_count in ((1.40, 45), (1.45, 44)):
        assert count(0.1 / 64 * factor, exact=True) == exact_count
    # negative control: rounded, the two pilots' counts are a factor of two apart
    assert [count(0.1 / 64 * f, exact=False) for f in (1.40, 1.45)] == [64, 32]


def test_crop_boxes_follow_the_data():
    base = np.full((24, 32), 1e-3)
    a, b = base.copy(), base.copy()
    a[2:8, 20:26] = 1.0                             # the methods differ here
    b[14:22, 2:10] = a[14:22, 2:10] = 5.0           # both are worst here
    (x0, y0, s, _), (x1, y1, _, _) = A.crop_boxes([a, b], 6)
    assert 2 <= x0 <= 4 and 14 <= y0 <= 16 and s == 6       # the largest errors
    assert (x1, y1) == (20, 2)                              # where the methods differ


def test_methods_without_nee_are_said_to_miss_a_scenes_delta_lights(tmp_path):
    """A point light (a delta emitter) is reached by next-event estimation only: on a scene
    with one the report names the methods that sample no emitter; on one without, and for
    methods with NEE (and Mitsuba's path), nothing."""
    from experiments.lib import scenes as lib_scenes
    from experiments.lib.studies.suite import words
    body = ('<sensor type="perspective"><film type="hdrfilm"><integer name="width" '
            'value="8"/><integer name="height" value="8"/></film></sensor>'
            '<shape type="sphere"><bsdf type="diffuse"/></shape>')
    lit = tmp_path / "lit.xml"
    lit.write_text(f'<scene version="3.0.0">{body}<emitter type="point">'
                   f'<point name="position" x="0" y="4" z="0"/></emitter>'
                   f'<emitter type="constant"/></scene>')
    plain = tmp_path / "plain.xml"
    plain.write_text(f'<scene version="3.0.0">{body}<emitter type="constant"/></scene>')
    cfg = SimpleNamespace(methods=tuple(methods.parse_method(m) for m in
                                        ("bsdf", "cosine", "bsdf+nee", "path")))
    got = words.unreachable(cfg, SimpleNamespace(path=str(lit), left_out={"cosine": "x"}))
    assert got == {"methods": ["bsdf"], "emitters": ["point"]}
    assert "bsdf sample no emitter" in words.unreachable_words(
        cfg, SimpleNamespace(path=str(lit), left_out={"cosine": "x"}))[0]
    assert words.unreachable(cfg, SimpleNamespace(path=str(plain), left_out={})) == {}
    assert lib_scenes.delta_emitters(str(FURNACE)) == ()
