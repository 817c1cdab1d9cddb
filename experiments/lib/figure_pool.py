"""Figures written by worker processes while the run goes on, never while it renders.

Writing a figure (matplotlib's ``savefig``: layout, drawing, PNG and PDF encoding) takes one
core, about a tenth of a default ``make run``. Inside :func:`parallel` (what ``run_all``
opens), :func:`save` pickles the finished figure, hands it to one of the pool's worker
processes and returns at once; :func:`drain` waits for every figure handed over (each
within :data:`DEADLINE` seconds) and raises one error naming every figure that could not
be written. Every render waits for them first (:func:`wait`, in :func:`.execute._render`)
and ``run_all`` drains after each study, so no figure is drawn while a render's kernels
are timed (the clock's kernel time would count the other process's load) and every figure
of a study is on disk when the study returns. Outside :func:`parallel`, or for a figure
that cannot be pickled, :func:`save` writes in this process: the same file either way
(each written atomically, :func:`.files.atomic_path`).
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
from concurrent.futures import Future, ProcessPoolExecutor

from . import files

#: Seconds :func:`drain` waits for one figure before it gives up on it.
DEADLINE = 300.0

_pool: ProcessPoolExecutor | None = None
_pending: list[tuple[str, Future]] = []
_failed: list[str] = []
_stuck: list[str] = []             # figures past their deadline: their workers are ended


@contextlib.contextmanager
def parallel(workers: int | None = None):
    """Write figures in ``workers`` processes (default: the cores, at most 2; one core:
    in this process) until the block ends; then wait for them all."""
    global _pool
    workers = min(2, os.cpu_count() or 1) if workers is None else workers
    if workers < 2 or _pool is not None:
        yield
        return
    # spawn: a forked child would inherit Dr.Jit's threads and locks mid-flight
    _pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    try:
        yield
        drain()
    finally:
        pool, _pool = _pool, None
        _pending.clear()
        _failed.clear()
        if _stuck:              # a worker past its deadline is ended, not waited for
            _end_workers(pool, list(_stuck))
            _stuck.clear()
        pool.shutdown(wait=True, cancel_futures=True)


def _end_workers(pool: ProcessPoolExecutor, paths: list[str]) -> None:
    """Kill the pool's workers and remove the temporary files they left beside ``paths``
    (:func:`.files.atomic_path` names them ``.tmp-<pid>-<name>``)."""
    for process in list(getattr(pool, "_processes", {}).values()):
        process.kill()
        process.join(5)
        for path in paths:
            directory, name = os.path.split(os.path.abspath(path))
            tmp = os.path.join(directory, f".tmp-{process.pid}-{name}")
            if os.path.exists(tmp):
                os.remove(tmp)


def save(fig, outputs: list[tuple[str, str, int]]) -> None:
    """Write ``fig`` to every ``(path, format, dpi)`` of ``outputs`` (tight bounding box),
    then close it: in a worker inside :func:`parallel`, else here."""
    import matplotlib.pyplot as plt
    payload = None
    if _pool is not None:
        try:
            payload = pickle.dumps(fig)
        except (pickle.PicklingError, TypeError, AttributeError):
            payload = None                          # written here instead: same file
    if payload is None:
        _write(fig, outputs)
    else:
        _pending.append((outputs[0][0], _pool.submit(_write_pickled, payload, outputs)))
    plt.close(fig)


def wait() -> None:
    """Wait for every figure handed to the pool (each within :data:`DEADLINE` seconds),
    keeping what failed for :func:`drain` (a render waits here: a figure's error is not
    the render's)."""
    pending, _pending[:] = list(_pending), []
    for path, future in pending:
        try:
            future.result(timeout=DEADLINE)
        except TimeoutError:
            _stuck.append(path)
            _failed.append(f"{path}: not written within {DEADLINE:.0f} s")
        except Exception as error:                  # the worker's own, re-raised here
            _failed.append(f"{path}: {type(error).__name__}: {error}")


def drain() -> None:
    """:func:`wait`, then raise a RuntimeError naming each figure that failed or missed its
    deadline (the others are written)."""
    wait()
    failed, _failed[:] = list(_failed), []
    if failed:
        raise RuntimeError("figures not written: " + "; ".join(failed))


def _write(fig, outputs) -> None:
    for path, fmt, dpi in outputs:
        with files.atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=dpi, bbox_inches="tight")


def _write_pickled(payload: bytes, outputs) -> None:
    """A worker's task: the pickled figure written to ``outputs``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = pickle.loads(payload)
    try:
        _write(fig, outputs)
    finally:
        plt.close(fig)
