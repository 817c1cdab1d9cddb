"""A quick suite's engine, planned up to its equal-time budget: the learner-count tests
(tests/test_learner_counts.py, tests/test_suite.py) drive its counts with rendered costs of
their own."""
from __future__ import annotations

import scenes
from experiments.lib.engine import Engine, Planned
from experiments.lib.studies.suite import declare
from experiments.lib.studies.suite import study as S
from experiments.lib.study import Study


def engine_at(tmp_path, budget: str, methods: str):
    """(declaration, engine, planned with the equal-spp jobs, the equal-time budget) of a
    quick suite on cbox at ``budget`` seconds with ``methods``."""
    cfg = S.settings(S.parse(["--quick", "--spp", "16", "--time-budget", budget,
                              "--methods", methods, "--scenes",
                              scenes.path("suite/cbox.xml"), "--out", str(tmp_path)]))
    decl = declare.declaration(cfg, declare.plan_scenes(cfg))
    engine, planned = Engine(Study(cfg)), Planned()
    spp_budget, time_budget = decl.budgets
    planned.add(spp_budget.name, engine.jobs(decl, spp_budget))
    return decl, engine, planned, time_budget
