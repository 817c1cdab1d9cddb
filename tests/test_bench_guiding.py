"""``benchmarks.guiding`` (make bench, rows 7) at tiny settings: it runs, its counts follow
from the pilot costs, and its rows and note say what was measured."""
import pytest

from benchmarks import guiding


def test_quick_measure_gives_rows_and_a_note():
    res = guiding.measure(**guiding.quick_settings(True), methods=("guided+nee", "bsdf+nee"),
                          log=lambda *_: None)
    path, guided = res["methods"]["path"], res["methods"]["guided+nee"]
    assert path["spp"] == 1536 and len(path["relmse"]) == len(guided["relmse"]) == 2
    assert guided["spp"] >= 1 and all(c > 0 for c in guided["cost"] + path["cost"])
    assert guided["spp"] >= 256 and 0 < guided["training_share"] < 1 and guided["after_training_per_sample_over_path"] > 0
    assert "training_share" not in res["methods"]["bsdf+nee"]       # it does not train
    rows = guiding.rows(res)
    assert [r[0].split(",")[0] for r in rows] == [
        "7. guided+nee / path", "7. guided+nee time per sample after training / path's",
        "7. guided+nee training's share of its time",
        "7. guided+nee a frozen pass's kernel time per sample / bsdf+nee's",
        "7. guided+nee a recording pass's kernel time per sample / a frozen pass's",
        "7. bsdf+nee / path"]
    assert rows[0][2] == ">= 6, lower end >= 5" and rows[0][3] in ("yes", "no")
    assert rows[2][2] == "<= 20%" and rows[2][3] in ("yes", "no") and rows[5][3] == ""
    assert [r[2] for r in rows[3:5]] == ["<= 1.15", "<= 1.35"]
    # a frozen pass costs at least about what bsdf+nee's samples do; recording costs more
    assert guided["frozen_over_plain"] > 0.8 and guided["recording_over_frozen"] > 1.0
    assert "door_room.xml at 64x48" in guiding.note(res).replace("`", "")


def test_pass_costs_split_the_kernel_time_by_the_passes_wall_time():
    """A 447-spp job trains in iterations 2, 4, ..., 64 (126 recorded samples) and renders
    its last 321 samples frozen: kernel seconds split by the passes' wall seconds (its last
    pass 2 s of 2.6)."""
    share = 2.0 / 2.6                   # 0.6 s of recording, 2 s frozen: 3 s of kernels
    recording, frozen = guiding.pass_costs(3.0, share, 447)
    assert frozen == pytest.approx(3.0 * 2.0 / 2.6 / 321)
    assert recording == pytest.approx(3.0 * 0.6 / 2.6 / 126)
