"""The suite's precision rule: a policy that sets a scene's equal-time factor.

:class:`Precision` (a :class:`~experiments.lib.declaration.TimeScale`) gives each scene the
factor of ``--time-budget`` that its equal-time renders need for the expected relMSE of the
baseline and of the timed pair (:data:`.analysis.TIMED_PAIR`, those of them in the run) to
be known to :data:`PRECISION` (relative standard error, pooled over the repeats), predicted
from their equal-spp renders: their pixels' variances over the squares of the reference at
its smallest size (:mod:`.errors`; its first chunks, the same in every run, so that a rerun
or a longer reference plans the same counts; not the renders' own mean, whose fireflies
would shrink their own weights). The standard error falls as 1/sqrt(samples), so the factor is
:func:`scale_for` of the largest one predicted at the unscaled equal-time count. The scene's
own header budget is kept where it is larger. The engine asks it once per scene, after the
scene's equal-spp renders (:meth:`experiments.lib.engine.Engine.run`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import counts
from ...declaration import Cell
from ...jobs import Accumulator
from ...methods import Method
from . import analysis, bias_test, errors

#: Relative standard error of the expected relMSE (pooled over the repeats) of the baseline
#: and the timed pair that the equal-time budget of a scene aims for: two such errors give
#: an A/A efficiency interval of hi/lo ~1.2 before the costs' spread.
PRECISION = 0.035
#: Largest factor of ``--time-budget`` the rule may give a scene (the 5-minute make run:
#: docs/methodology.md).
MAX_PRECISION_SCALE = 16


def scale_for(error: float, precision: float = PRECISION,
              cap: float = MAX_PRECISION_SCALE) -> float:
    """The power-of-two factor (1 to ``cap``) of samples that brings a relative standard
    error ``error`` (falling as 1/sqrt(samples)) to ``precision`` or below."""
    scale = (error / precision) ** 2
    return float(min(cap, 2 ** max(0, math.ceil(math.log2(max(scale, 1.0))))))


def precise(method: Method, box: bool) -> bool:
    """Whether a cell's error comes from its pixels' variances (:mod:`.errors`): the
    independent sampler under a box filter, whose pixels are independent estimates (not an
    adaptive method: its passes are its own, the samples' moments are not kept)."""
    return bias_test.variance_kind(method, box) == "pixels" and not method.adaptive


@dataclass(frozen=True)
class Precision:
    """The precision rule for the equal-time budget named ``budget`` (see the module);
    ``boxes``: the scenes whose every filter is a box."""
    baseline: Method
    boxes: frozenset
    budget: str

    def __call__(self, engine, declaration, scene, planned, reference) -> tuple[float, str]:
        own = scene.time_scale
        box = scene.name in self.boxes
        if not precise(self.baseline, box):
            return own, (f"the baseline {self.baseline.name} has no pixel variances here (a "
                         f"QMC sampler or a filter other than a box)")
        timed = next(b for b in declaration.budgets if b.name == self.budget)
        names = [m.name for m in declaration.methods_on(scene)
                 if m.name in (self.baseline.name,) + analysis.TIMED_PAIR and precise(m, box)]
        errs = [e for e in (self._error(engine, timed, scene, planned, name, reference)
                            for name in names) if e is not None]
        if (scene.name, None, self.baseline.name) in planned.failed or not errs:
            return own, f"the baseline {self.baseline.name} has no equal-spp error"
        return max(own, scale_for(max(errs))), ""

    @staticmethod
    def _error(engine, timed, scene, planned, method: str, ref: np.ndarray) -> float | None:
        """The relative standard error of a cell's pooled expected relMSE predicted at its
        unscaled equal-time count from its equal-spp renders (None: no usable renders)."""
        if (scene.name, None, method) in planned.failed:
            return None
        runs = [engine.study.results(jobs)
                for jobs in planned.runs(Cell(scene.name, method, timed.after))]
        if not runs:
            return None
        maps, tails = [], []
        for results in runs:
            acc = Accumulator.empty(*results[0].image.shape[:2])
            for r in results:
                acc.add_result(r)
            maps.append(errors.pixel_map(acc.variance_of_mean(), ref))
            tails.append(errors.pixel_map_variance(acc.variance_of_variance(), ref))
        count = counts.equal_time_spp(timed.seconds, runs, timed.power_of_two, timed.max_spp)
        return predicted(maps, tails, sum(r.spp for r in runs[0]), count)


def predicted(maps: list, tails: list, spp: int, count: int) -> float | None:
    """The relative standard error of a cell's pooled expected relMSE
    (:func:`.errors.pooled` of its renders' pixel ``maps`` and their ``tails``, each render
    of ``spp`` samples per pixel) at ``count`` samples per pixel: it falls as one over the
    square root of the samples. None without an error."""
    value, var = errors.pooled(maps, tails)
    if not (value > 0 and math.isfinite(var)):
        return None
    return math.sqrt(var) / value * math.sqrt(spp / count)
