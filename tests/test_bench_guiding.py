"""``benchmarks.guiding`` (make bench, rows 7) at tiny settings: it runs, its counts follow
from the pilot costs, and its rows and note say what was measured."""
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
        "7. guided+nee training's share of its time", "7. bsdf+nee / path"]
    assert rows[0][2] == ">= 6, lower end >= 5" and rows[0][3] in ("yes", "no")
    assert rows[2][2] == "<= 20%" and rows[2][3] in ("yes", "no") and rows[3][3] == ""
    assert "door_room.xml at 64x48" in guiding.note(res).replace("`", "")
