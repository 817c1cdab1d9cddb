"""The engine's pilot renders: a render at a first guess of a count, kept in the store and in
no comparison, whose cost per sample decides the count (:meth:`.engine.Engine.count`).

A learning method's pilot is :meth:`.engine.Engine.pilot` (its training regimes decide
around it); an adaptive method's is :func:`adaptive_count`.
"""
from __future__ import annotations

from . import counts
from .declaration import Budget, Declaration


def adaptive_count(engine, declaration: Declaration, budget: Budget, slot,
                   measured: list, seconds: float) -> int:
    """An adaptive method's equal-time count (:attr:`.methods.Method.adaptive`) in ``slot``
    (an :class:`~.engine.Slot`; ``engine`` its :class:`~.engine.Engine`): the count
    that costs ``seconds`` at the cost per sample of a pilot render, exact. Never rounded
    to a power of two: its per-pixel counts are neither equal nor powers of two, so the
    rounding buys nothing, and rounded it rendered half its twin's count on four of nine
    scenes (its pilot pass, a share of the count, then half as long). The pilot renders
    the count the ``measured`` renders give: their few samples spread its fixed work per
    job (two passes, the allocation's kernels) over too few samples, so their count is
    short."""
    spp = counts.equal_time_spp(seconds, measured, False, budget.max_spp)
    piloted = [render(engine, declaration, budget, slot, spp)]
    return counts.equal_time_spp(seconds, piloted, False, budget.max_spp)


def render(engine, declaration: Declaration, budget: Budget, slot, spp: int) -> list:
    """The results of a pilot render of ``slot``'s method at ``spp`` for ``budget``
    (``engine`` an :class:`~.engine.Engine`): kept in the store (:attr:`.jobs.Job.pilot`)
    and in no comparison."""
    cell = slot.cell(budget.name)
    job = engine.study.job(f"{declaration.key(declaration, cell)}/pilot", slot.method, spp,
                           pilot=True,
                           sample_moments=declaration.moments(slot.method, slot.setup),
                           **engine._options(declaration, cell, slot.setup))
    engine.study.run([job], f"{declaration.name}: pilot")
    return engine.study.results([job])
