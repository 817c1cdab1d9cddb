"""The suite's numbers: what the engine measured, as the pure analysis's input.

:func:`measure_scene` turns the engine's :class:`~experiments.lib.measurements.Measurements`
of one scene (against the suite's reference: every chunk the store holds, or the user's
EXR) into :class:`.analysis.SceneNumbers`: per cell and budget the raw errors per repeat,
relMSE with outliers rejected, FLIP, image means, the pixels' pooled expected relMSE
(:mod:`.errors`), the costs per sample, and its bias test (:func:`bias_tests`).
:func:`comparable` says why a rendered scene cannot be compared.
"""
from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from ... import metrics, names, references, scene_probes
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
          flip: str, costs: tuple = (), extra: list = ()) -> tuple[analysis.Runs, float]:
    """The numbers of one budget's repeats (the engine's :class:`~...measurements.Run` values;
    ``costs``: the cell's cost per sample of every render, per budget; ``extra``: more
    renders of the same count whose pixel variances join the expected error alone,
    :func:`.bias_renders.imprecise`), and the reference's own expected relMSE over the
    pixels the rejected relMSE kept."""
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
    maps = [errors.pixel_map(x.variance, ref.image) for x in list(runs) + list(extra)]
    tails = [errors.pixel_map_variance(x.variance_var, ref.image)
             for x in list(runs) + list(extra)]
    expected = errors.pooled(maps, tails) if all(m is not None for m in maps) else ()
    each = tuple(float(m.mean()) for m in maps) if expected else ()
    top = errors.top_share(maps) if expected else 0.0
    rest = errors.without_top(maps, tails) if expected else ()
    return analysis.Runs(runs[0].spp, tuple(rel), tuple(rej), tuple(mse), tuple(secs),
                         tuple(flips), tuple(means), tuple(mvars), expected, costs, each,
                         top, rest), \
        float(np.mean(rej_floor))


def bias_tests(cfg: Settings, sp: ScenePlan, measured: Measurements,
               chunks: np.ndarray | None, alpha: float, more: dict | None = None,
               alone: bool = False) -> dict:
    """{method: :class:`.bias_test.CellBias`} of one scene's cells that rendered: each
    cell's renders at both budgets (and ``more``: {method: [Run]}, more renders at its
    equal-time count, :mod:`.bias_renders`; with ``alone``, the cells of ``more`` tested by
    those renders alone, their even and odd ones the test's halves) against the
    reference's ``chunks`` (None: the user's EXR) at the level ``alpha`` per cell, the
    test's own calibration applied (:func:`.bias_test.calibrated`), and a biased verdict
    kept only where the cell's samples could reach the light of the scene's narrowest
    lobe (:func:`.bias_test.unreached`)."""
    failed = measured.failed_on(sp.name)
    methods = {m.name: m for m in measured.declaration.methods if m.name not in sp.left_out}
    out, samples = {}, {}
    for name in [n for n in methods if n not in failed and (not alone or n in more)]:
        extra = (more or {}).get(name, [])
        runs = [extra[half::2] for half in (0, 1)] if alone else \
            [measured.final(Cell(sp.name, name, budget)) + (extra if budget == TIME else [])
             for budget in (SPP, TIME)]
        renders = [[(x.image, x.spp, x.variance, x.variance_var, x.third)
                    for x in side] for side in runs]
        samples[name] = sum(r[1] * r[0].shape[0] * r[0].shape[1] for b in renders for r in b)
        out[name] = dataclasses.replace(
            bias_test.check_cell(methods[name], renders, chunks, sp.box, sp.box,
                                 cfg.reference_method, alpha), extra=len(extra))
    if sp.user_ref is None:
        out = bias_test.calibrated(out, cfg.reference_method.name)
    return bias_test.unreached(out, samples, lambda name: reach(sp, methods[name]))


def reach(sp: ScenePlan, method) -> float:
    """The share of ``method``'s paths that can pass through the core of the narrowest
    lobe of ``sp``'s scene (:func:`.scene_probes.path_reach`, by the strategy it draws
    directions with: a learning method's plain counterpart's, Mitsuba's path the BSDF's
    own). Where the probe fails (a strategy without a ``pdf``), infinite: the verdict
    stands, and a warning says why."""
    strategy = "bsdf" if method.strategy is None or method.learns else method.strategy
    try:
        return scene_probes.path_reach(scene_probes.probe_scene(sp.path, 16, 12), strategy)
    except Exception as e:  # noqa: BLE001  (the verdict stands, with the reason)
        warnings.warn(f"suite: the reach of {method.name} on {sp.name} could not be probed "
                      f"({names.one_line(e)}): its biased verdict stands")
        return math.inf


def trained(method, finals: dict, pixels: int) -> bool:
    """Whether any of ``method``'s equal-time renders (``finals[TIME]``, each with its
    ``spp``) learned from its samples on a film of ``pixels``: under a guide's training
    thresholds its cell is its plain counterpart's estimator (:meth:`.methods.Method.trains`;
    its equal-spp renders are too short to train anywhere)."""
    return any(method.trains(x.spp, pixels) for x in finals[TIME])


def measure_scene(cfg: Settings, sp: ScenePlan, measured: Measurements,
                  ref: references.Reference, flip: bool, tests: dict | None = None,
                  extra: dict | None = None) -> analysis.SceneNumbers:
    """The numbers of one scene from the engine's ``measured`` (FLIP only when ``flip``: it
    costs the most), each cell's bias test from ``tests`` (:func:`bias_tests`; None: not
    tested), ``extra`` ({method: [Run]}: more renders at a cell's equal-time count that
    join its expected error, :func:`.bias_renders.imprecise`). Time per sample per repeat:
    the cost (:func:`.clock.cost`, in the engine's runs) of the repeat's renders at both
    budgets over their samples."""
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
            runs[key], fl = _runs(finals[budget], ref, b, mode, costs,
                                  (extra or {}).get(name, ()) if budget == TIME else ())
            rej_floors.append(fl)
        px = sp.width * sp.height
        tested = (tests or {}).get(name)
        overhead = float(np.mean([r.overhead for budget in (SPP, TIME) for r in finals[budget]]))
        cells[name] = analysis.Cell(name, runs, tuple(x / px * 1e9 for x in b), overhead,
                                    methods[name].deterministic, tested,
                                    methods[name].learns, trained(methods[name], finals, px))
    floor = analysis.Floor(ref.relmse_floor or 0.0,
                           float(np.mean(rej_floors)) if rej_floors else 0.0,
                           ref.mse_floor or 0.0, ref.floor_known)
    ceiling = next((m for m in analysis.CEILING_METHODS if m in cells), "")
    oracle = (errors.oracle_gain([errors.pixel_map(x.variance, ref.image)
                                  for x in measured.final(Cell(sp.name, ceiling, TIME))])
              if ceiling else math.nan)
    header = sp.header
    exact = None
    if header is not None and header.exact is not None and cfg.max_depth is None \
            and cfg.rr_depth is None:
        exact = header.exact
    return analysis.SceneNumbers(sp.name, cells, floor, cfg.baseline.name,
                                 header.favours if header else (), header.over if header else (),
                                 header.hypothesis if header else "", exact, failed,
                                 cfg.reference_method.name if sp.user_ref is None else "",
                                 oracle, ceiling)


