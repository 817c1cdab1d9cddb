"""``benchmarks.adaptive`` (make bench, rows 8): the oracle's ceilings on known fields, and
the bench at tiny settings: it runs and its rows say what was measured."""
import numpy as np
import pytest

from benchmarks import adaptive


def test_the_ceilings_of_known_fields():
    """Pixels of alike variance: no allocation by their deviation gains; one by
    sqrt(v / c) still gains where they differ in cost, mean(c) / mean(sqrt c)^2. Pixels of relative variance 4
    and 1 (deviations 2 and 1) costing 4 and 1: at equal samples (2.5) / (1.5)^2 = 1.111;
    at equal time allocated by the deviation its samples cost (2 x 4 + 1) / 3 = 3 against
    a uniform render's 2.5, 0.926, under 1: allocating loses; allocated by sqrt(v / c) (the
    optimum at equal time) 2.5 x 2.5 / 2.5^2 = 1, no loss."""
    cost = np.array([1.0, 2.0, 3.0, 4.0])
    alike = adaptive.ceilings(np.full(4, 3.0), cost)
    assert alike == pytest.approx({"samples": 1.0, "time": 1.0, "time_cost_aware":
                                   np.mean(cost) / np.mean(np.sqrt(cost)) ** 2})
    known = adaptive.ceilings(np.array([4.0, 1.0]), np.array([4.0, 1.0]))
    assert known["samples"] == pytest.approx(2.5 / 1.5 ** 2)
    assert known["time"] == pytest.approx(2.5 / 1.5 ** 2 * 2.5 / 3.0)
    assert known["time_cost_aware"] == pytest.approx(1.0)
    # a pixel of no variance and cheap samples: the allocation's samples all cost 3
    cheap = adaptive.ceilings(np.array([4.0, 0.0]), np.array([3.0, 1.0]))
    assert cheap["samples"] == pytest.approx(2.0) and cheap["time"] == pytest.approx(4 / 3)


def test_quick_measure_gives_rows(monkeypatch):
    monkeypatch.setattr(adaptive, "ORACLE_SPP", 1024)
    monkeypatch.setattr(adaptive, "COST_REPS", 2)
    res = adaptive.measure(**adaptive.quick_settings(True))
    r = res["grazing"]
    # Cauchy-Schwarz: the oracle never loses at equal samples, nor cost-aware at equal time
    assert r["samples"] >= 1.0 and r["time_cost_aware"] >= 1.0 - 1e-9
    assert r["time_cost_aware"] >= r["time"] - 1e-9
    assert r["measured"]["efficiency"] > 0 and r["measured"]["cost"] > 0
    (row,) = adaptive.rows(res)
    assert row[0].startswith("8. bsdf+nee+adaptive / bsdf+nee on grazing (48x36, 64 spp)")
    assert row[2] == ">= 1.3 (issue 43)" and row[3] in ("yes", "no", "no (over the ceiling)")
