"""The suite's numbers: what the engine measured, as the pure analysis's input.

:func:`measure_scene` turns the engine's :class:`~experiments.lib.measurements.Measurements`
of one scene (against the suite's reference: every chunk the store holds, or the user's
EXR) into :class:`.analysis.SceneNumbers`: per cell and budget the raw errors per repeat,
relMSE with outliers rejected, FLIP, image means, the pixels' pooled expected relMSE
(:mod:`.errors`), the costs per sample, and with a level its bias test (:mod:`.bias_test`).
:func:`comparable` says why a rendered scene cannot be compared.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ... import metrics, references
from ...declaration import Cell
from ...measurements import Measurements
from . import analysis, bias_test, errors
from .declare import SPP, TIME, ScenePlan, Settings


def comparable(cfg: Settings, sp: ScenePlan, failed: dict) -> str:
    """Why a rendered scene cannot be compared ('' when it can); ``failed``: {method:
    error} of its cells that failed."""
    if sp.error:
        return sp.error
    ok = [m.name for m in cfg.methods if m.name not in sp.left_out and m.name not in failed]
    if cfg.baseline.name not in ok:
        why = failed.get(cfg.baseline.name, "not run")
        return f"the baseline {cfg.baseline} failed: {why}"
    if len(ok) < 2:
        return "only the baseline rendered: " + "; ".join(
            [f"{m}: {e}" for m, e in failed.items()] +
            [f"its header leaves out {', '.join(sp.left_out)}"] * bool(sp.left_out))
    return ""


def _runs(runs: list, ref: references.Reference, b: list[float],
          flip: str, costs: tuple = ()) -> tuple[analysis.Runs, float]:
    """The numbers of one budget's repeats (the engine's :class:`~...measurements.Run` values;
    ``costs``: the cell's cost per sample of every render, per budget), and the
    reference's own expected relMSE over the pixels the rejected relMSE kept."""
    fmap = ref.floor_map()
    rel, rej, rej_floor, mse, secs, means, mvars, flips = ([] for _ in range(8))
    for run, per_spp in zip(runs, b):
        image = run.image
        rel.append(run.relmse)
        raw = metrics.relmse_rejected(image, ref.image)
        rej.append(raw)
        rej_floor.append(raw - metrics.relmse_rejected(image, ref.image, floor_map=fmap))
        mse.append(run.mse)
        secs.append(run.spp * per_spp)
        lum = image.mean(axis=-1).ravel()
        means.append(float(lum.mean()))
        mvars.append(float(lum.var(ddof=1) / lum.size) if lum.size > 1 else math.inf)
    if flip == "all":
        flips = [metrics.flip_mean(x.image, ref.image) for x in runs]
    elif flip == "first":
        flips = [metrics.flip_mean(runs[0].image, ref.image)]
    maps = [errors.pixel_map(x.variance, ref.image) for x in runs]
    tails = [errors.pixel_map_variance(x.variance_var, ref.image) for x in runs]
    expected = errors.pooled(maps, tails) if all(m is not None for m in maps) else ()
    return analysis.Runs(runs[0].spp, tuple(rel), tuple(rej), tuple(mse), tuple(secs),
                         tuple(flips), tuple(means), tuple(mvars), expected, costs), \
        float(np.mean(rej_floor))


def measure_scene(cfg: Settings, sp: ScenePlan, measured: Measurements,
                  ref: references.Reference, flip: bool, chunks: np.ndarray | None = None,
                  alpha: float | None = None) -> analysis.SceneNumbers:
    """The numbers of one scene from the engine's ``measured`` (FLIP only when ``flip``: it
    costs the most); with a level ``alpha`` per cell, each cell's bias test
    (:func:`.bias_test.check_cell`) against the reference's ``chunks`` (None: the user's
    EXR). Time per sample per repeat: the cost (:func:`.clock.cost`, in the
    engine's runs) of the repeat's renders at both budgets over their samples."""
    cells, rej_floors = {}, []
    failed = measured.failed_on(sp.name)
    methods = {m.name: m for m in measured.declaration.methods if m.name not in sp.left_out}
    for name in [n for n in methods if n not in failed]:
        finals = {budget: measured.final(Cell(sp.name, name, budget)) for budget in (TIME, SPP)}
        b = [(x.cost + y.cost) / (x.spp + y.spp) for x, y in zip(finals[SPP], finals[TIME])]
        costs = tuple((finals[budget][0].spp, tuple(x.cost / x.spp for x in finals[budget]))
                      for budget in (SPP, TIME))
        runs = {}
        for budget, key in ((TIME, "equal_time"), (SPP, "equal_spp")):
            mode = ("none" if not flip else cfg.flip if budget == TIME or
                    cfg.flip == "all" else "none")
            runs[key], fl = _runs(finals[budget], ref, b, mode, costs)
            rej_floors.append(fl)
        px = sp.width * sp.height
        tested = None
        if alpha is not None:
            box = sp.box
            renders = [[(x.image, x.spp, x.variance, x.variance_var) for x in finals[budget]]
                       for budget in (SPP, TIME)]
            tested = bias_test.check_cell(methods[name], renders, chunks, box, box,
                                          cfg.reference_method, alpha)
        overhead = float(np.mean([r.overhead for budget in (SPP, TIME) for r in finals[budget]]))
        cells[name] = analysis.Cell(name, runs, tuple(x / px * 1e9 for x in b), overhead,
                                    methods[name].deterministic, tested)
    if alpha is not None and sp.user_ref is None:
        checked = bias_test.calibrated({n: c.block_bias for n, c in cells.items()},
                                        cfg.reference_method.name)
        cells = {n: replace(c, block_bias=checked[n]) for n, c in cells.items()}
    floor = analysis.Floor(ref.relmse_floor or 0.0,
                           float(np.mean(rej_floors)) if rej_floors else 0.0,
                           ref.mse_floor or 0.0, ref.floor_known)
    pair = analysis.TIMED_PAIR[0]
    oracle = (errors.oracle_gain([errors.pixel_map(x.variance, ref.image)
                                  for x in measured.final(Cell(sp.name, pair, TIME))])
              if pair in cells else math.nan)
    header = sp.header
    exact = None
    if header is not None and header.exact is not None and cfg.max_depth is None \
            and cfg.rr_depth is None:
        exact = header.exact
    return analysis.SceneNumbers(sp.name, cells, floor, cfg.baseline.name,
                                 header.favours if header else (), header.over if header else (),
                                 header.hypothesis if header else "", exact, failed,
                                 cfg.reference_method.name if sp.user_ref is None else "",
                                 oracle)


