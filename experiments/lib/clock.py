"""The one clock: what a method's image costs, for every efficiency of every study.

The cost of an image is the work the method did to make it:

* the **kernel execution time** of every render pass that made it (Dr.Jit's kernel history,
  :attr:`~.jobs.JobResult.kernel_seconds`): the sample work itself, including a method's
  training or pilot passes, whose images may or may not enter the result;
* plus the **CPU time of the host-side work between passes** that the method does itself
  (building a table from a training pass, combining its passes:
  :attr:`~.jobs.JobResult.host_seconds`, the rendering thread's CPU time in the method's
  own hooks, :mod:`.execute`).

Not counted, and reported beside it (:func:`overhead`): the per-call cost of tracing the
integrator and launching its kernels, which depends on the Python version, on the kernel
cache and on how many calls a film is split into, not on the method's sampling. Nor the
wall-clock time other processes on a shared machine stretch: kernel time is measured per
kernel. Every study and sweep takes a render's cost from :func:`cost` (and a sequence of
renders' from :func:`total`); only this module reads a render's ``wall_seconds``,
``cpu_seconds``, ``kernel_seconds`` or ``host_seconds`` (``tests/test_clock.py`` checks).
See docs/methodology.md ("The clock").
"""
from __future__ import annotations

import contextlib
import time
from typing import Iterable

#: How the reports name the clock (one phrase, used in every table caption that divides by it).
NAME = "kernel time"
DESCRIPTION = ("the kernel execution time of every render pass that makes an image (training "
               "and pilot passes included) plus the CPU time of the method's host-side work "
               "between passes; the per-call cost of tracing and launching kernels is not "
               "counted")


class ClockError(ValueError):
    """A stored result has no kernel time (it predates the clock): it cannot be costed."""


def cost(result) -> float:
    """Seconds an image cost (:class:`~.jobs.JobResult`): its passes' kernel execution time
    plus the method's host work between passes."""
    if result.kernel_seconds <= 0 and result.wall_seconds > 0:
        raise ClockError(
            f"a stored render of {result.spp} spp has no kernel time (it was stored by an "
            f"older version, which did not record it): delete the job store (OUT/store) and "
            f"the reference store (OUT/references) and run again")
    return float(result.kernel_seconds + result.host_seconds)


def total(results: Iterable) -> float:
    """The cost of the image that ``results`` make together (a ladder's stretches, chunks)."""
    return float(sum(cost(r) for r in results))


def fixed(result) -> float:
    """The part of an image's cost (:func:`cost`) that does not grow with its samples: the
    method's host work between passes (reading records, refining and uploading a guide),
    about the same per job whatever its count. A count that fits a time budget is
    extrapolated from the rest (:meth:`.engine.Engine.equal_time_spp`)."""
    return float(result.host_seconds)


def kernels(result) -> float:
    """The kernel execution seconds of a render's passes: its :func:`cost` without the
    method's host work (a method's passes costed apart, as the guiding bench's frozen and
    recording passes are, split by their wall time)."""
    return float(result.kernel_seconds)


def overhead(result) -> float:
    """Seconds of a render that the clock does not count: tracing, launching, waiting (its
    wall-clock time less its cost; never negative)."""
    return max(0.0, float(result.wall_seconds) - cost(result))


def wall(result) -> float:
    """The wall-clock seconds of a render's timed passes (for 'how long it took', never for
    an efficiency)."""
    return float(result.wall_seconds)


class Timer:
    """How long a study and its named parts took: wall-clock and CPU seconds of this
    process, for the reports' "how long it took" lines (never for an efficiency, which
    divides by :func:`cost`). One per study run, started when it is made::

        timer = clock.Timer()
        images = timer.time("renders", render, ...)
        with timer.part("figures"):
            ...
        timer.elapsed()         # wall seconds since the study began
    """

    def __init__(self):
        self.parts: dict[str, list[float]] = {}
        self._start = time.perf_counter()

    def add(self, part: str, wall: float, cpu: float) -> None:
        w, c = self.parts.get(part, [0.0, 0.0])
        self.parts[part] = [w + wall, c + cpu]

    @contextlib.contextmanager
    def part(self, name: str):
        """Time the block under ``name`` (added to what that part took before)."""
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - wall, time.process_time() - cpu)

    def time(self, part: str, fn, *a, **k):
        """``fn(*a, **k)``, timed under ``part``."""
        with self.part(part):
            return fn(*a, **k)

    def elapsed(self) -> float:
        """Wall-clock seconds since the timer was made."""
        return time.perf_counter() - self._start

    def seconds(self, part: str) -> float:
        """Wall-clock seconds of ``part`` so far (0 before it ran)."""
        return self.parts.get(part, [0.0, 0.0])[0]
