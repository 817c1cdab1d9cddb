"""Render jobs on a Dask cluster: :class:`DaskExecutor`, the distributed twin of the local loop.

The plan (:mod:`experiments.lib.plan`) fixes every job's seed and sample
offset, so where a job runs changes nothing in its image. This module only
moves jobs to ``dask.distributed`` workers and results back, through Dask's
own machinery:

- :meth:`DaskExecutor.local` starts a ``LocalCluster`` of N worker processes
  (one thread each) listening on loopback only; :meth:`DaskExecutor.connect`
  joins a running scheduler (``dask scheduler`` + ``dask worker`` on several
  machines, or ``dask-jobqueue`` on SLURM/PBS/SGE). It first asks the address
  for its identity under a hard deadline (:func:`probe_scheduler`), so a peer
  that is silent, slow or not a scheduler gives :class:`ClusterError` within
  the timeout plus a small margin instead of hanging: Dask's own ``timeout``
  bounds the TCP connect, not the handshake that follows.
- A ``WorkerPlugin`` (:class:`WorkerSetup`) runs on every worker, including
  those that join or restart later: it imports the plugins and sets the
  variant (e.g. ``cuda_ad_rgb`` on GPU workers). A worker where that fails
  makes the registration fail with the worker's error.
- Faults: a worker that dies mid-job loses its job to the scheduler, which
  reschedules it elsewhere (``distributed.scheduler.allowed-failures``);
  errors raised inside a job are retried ``retries`` times (``Client.submit``).
- Honest timing: all jobs of one ``timing_group`` (jobs whose render times a
  comparison divides) are pinned to one worker (``workers=[address]``,
  ``allow_other_workers=False``); when that worker disappears its group's
  unfinished jobs move to one other worker, preferably on the same host.
  Each result comes back with a :class:`WorkerInfo` (address, host, CPU
  model) of the worker that timed it: :attr:`DaskExecutor.timed_on`.

``map_unordered(jobs)`` yields ``(job, result)`` as jobs finish, in any
order, like :class:`experiments.lib.execute.LocalExecutor`; the caller writes
each result to the store as it arrives, so an interrupted client loses no
finished job. Closing the generator early cancels the jobs still queued.
"""
from __future__ import annotations

import asyncio
import logging
import os
import platform
import socket
import sys
import time
import threading
import uuid
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

import dask
from distributed import Client, LocalCluster, as_completed, get_worker
from distributed.diagnostics.plugin import WorkerPlugin

from . import extensions

#: Seconds the client waits for a scheduler before giving up (the CLI then exits 2).
CONNECT_TIMEOUT = 5.0
#: Seconds beyond the timeout that :meth:`DaskExecutor.connect` may take to give up
#: (closing the half-open connection, a thread join).
CONNECT_MARGIN = 1.0
#: Where a local cluster listens: this machine only.
LOOPBACK = "127.0.0.1"
#: Seconds between checks that the worker of every pinned timing group is still alive.
CHECK_INTERVAL = 0.5
#: How often a job that raised is resubmitted (a dead worker's job is rescheduled anyway).
RETRIES = 1


class ClusterError(RuntimeError):
    """The cluster cannot be used (unreachable scheduler, worker set-up failed); one line."""


class JobFailed(RuntimeError):
    """A job raised on its worker (after its retries); the message names the job and the worker."""


@dataclass(frozen=True)
class WorkerInfo:
    """Where a job ran (and was timed)."""
    address: str
    host: str
    cpu: str
    pid: int

    @property
    def machine(self) -> str:
        """Host and CPU model: what a report names as the machine that timed a job."""
        return f"{self.host} ({self.cpu})"


def this_worker() -> WorkerInfo:
    """The :class:`WorkerInfo` of the worker process calling it."""
    from .execute import cpu_model
    try:
        address = get_worker().address
    except ValueError:                     # not on a worker: the local process
        address = "local"
    return WorkerInfo(address, socket.gethostname() or platform.node(), cpu_model(), os.getpid())


def prepare_worker(variant: str) -> None:
    """Import the plugins and set ``variant`` in this process (raises if it cannot be used)."""
    import integrators  # noqa: F401  (first: points Dr.Jit at a libLLVM >= 17)
    import mitsuba as mi
    mi.set_variant(variant)
    mi.load_dict({"type": "vr_path"})   # the plugins are registered for this variant
    mi.set_log_level(mi.LogLevel.Error)  # as the scripts: no "rounding to N" per render


class WorkerSetup(WorkerPlugin):
    """Runs ``prepare(variant)`` on every worker when it starts (and when it restarts), then
    imports the client's extension files (``--plugin``, :mod:`.extensions`), so that the
    strategies and samplers they register exist on the worker too.

    ``threads``: Dr.Jit's thread count on each worker (for N workers sharing
    one machine); None keeps Dr.Jit's default (all cores).
    """
    name = "vr-integrators-setup"
    idempotent = False                 # re-registering (new variant) replaces the old one

    def __init__(self, variant: str, prepare: Callable[[str], None] = prepare_worker,
                 threads: int | None = None, plugins: tuple = ()):
        self.variant = variant
        self.prepare = prepare
        self.threads = threads
        self.plugins = tuple(plugins)

    def setup(self, worker) -> None:
        self.prepare(self.variant)
        extensions.load_all(self.plugins)
        if self.threads:
            import drjit as dr
            dr.set_thread_count(self.threads)


def _run_on_worker(run: Callable, job, variant: str):
    """The task every job becomes: ``run(job, variant)`` and where it ran."""
    return run(job, variant), this_worker()


def local_cluster(n_workers: int, silence_logs: int = logging.ERROR) -> LocalCluster:
    """A ``LocalCluster`` of ``n_workers`` processes with one thread each that leaves this
    process's thread limits alone.

    The nannies live in this process and write their workers' environment
    (``distributed.nanny.pre-spawn-environ``: ``OMP_NUM_THREADS=1``, ...) into
    ``os.environ`` at every (re)start of a worker; there it made this
    process's OpenMP (FLIP in the analysis) single-threaded, 1.14x the local
    loop's wall time. The thread limits go to the workers alone (``env``, set
    inside the worker process), and what the nannies write at start-up is undone.
    """
    spawn = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    worker_env = {k: str(spawn.pop(k)) for k in list(spawn) if k.endswith("_NUM_THREADS")}
    environ = dict(os.environ)
    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ": spawn}):
            return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                host=LOOPBACK, dashboard_address=f"{LOOPBACK}:0",
                                silence_logs=silence_logs,
                                env=worker_env)
    finally:
        os.environ.clear()
        os.environ.update(environ)


class DaskExecutor:
    """Runs jobs on ``dask.distributed`` workers; same contract as the local executor.

    ``run(job, variant)`` is the module-level job function the workers call
    (default :func:`experiments.lib.execute.run_job`); ``prepare(variant)``
    runs once per worker (default :func:`prepare_worker`). Use as a context
    manager, or call :meth:`close`; a cluster started by :meth:`local` is shut
    down with it.
    """

    def __init__(self, client: Client, variant: str, *, run: Callable | None = None,
                 prepare: Callable[[str], None] = prepare_worker, retries: int = RETRIES,
                 cluster: LocalCluster | None = None, threads: int | None = None):
        self.client = client
        self.variant = variant
        self.retries = retries
        self._run = run
        self._cluster = cluster
        self._pins: dict[str, str] = {}         # timing group -> worker address
        self.check_interval = CHECK_INTERVAL
        #: job key -> the worker that ran (and timed) it, for every job yielded so far
        self.timed_on: dict[str, WorkerInfo] = {}
        try:
            client.register_plugin(WorkerSetup(variant, prepare, threads,
                                               extensions.loaded()))
        except Exception as e:                   # the worker's own error, e.g. no CUDA GPU
            self.close()
            raise ClusterError(f"Dask workers cannot set up variant '{variant}': "
                               f"{_first_line(e)}") from e

    # ---------------------------------------------------------------- construction

    @classmethod
    def local(cls, n_workers: int, variant: str, **options) -> "DaskExecutor":
        """Start a ``LocalCluster`` of ``n_workers`` processes with one thread each; they
        share this machine's cores (Dr.Jit threads per worker: cores // n_workers)."""
        options.setdefault("threads", max(1, (os.cpu_count() or 1) // n_workers))
        cluster = local_cluster(n_workers)
        try:
            client = Client(cluster, set_as_default=False)
        except BaseException:
            cluster.close()
            raise
        return cls(client, variant, cluster=cluster, **options)

    @classmethod
    def connect(cls, address: str, variant: str, timeout: float = CONNECT_TIMEOUT,
                **options) -> "DaskExecutor":
        """Join the scheduler at ``address``; :class:`ClusterError` within ``timeout`` s
        (plus :data:`CONNECT_MARGIN`) if it cannot be reached or does not answer as one."""
        start = time.monotonic()
        probe_scheduler(address, timeout)
        try:
            remaining = max(0.1, timeout - (time.monotonic() - start))
            client = Client(address, timeout=remaining, set_as_default=False)
        except Exception as e:    # refused, timed out, bad address, not a Dask scheduler
            _close_half_started(e)
            if isinstance(e, OSError):
                why = f"cannot reach the Dask scheduler at '{address}' within {timeout:g} s"
            elif isinstance(e, (ValueError, TypeError)):
                why = f"invalid Dask scheduler address '{address}': {_first_line(e)}"
            else:
                why = (f"'{address}' does not answer as a Dask scheduler "
                       f"({type(e).__name__}: {_first_line(e)})")
            raise ClusterError(why) from None
        return cls(client, variant, **options)

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __enter__(self) -> "DaskExecutor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def describe(self) -> str:
        """One line: the scheduler and its workers."""
        workers = self._workers()
        hosts = sorted({w.get("host", "?") for w in workers.values()})
        return (f"Dask scheduler {self.client.scheduler.address}, {len(workers)} worker(s) on "
                f"{', '.join(hosts) or 'no host yet'}")

    # ---------------------------------------------------------------- execution

    def map_unordered(self, jobs: Iterable) -> Iterator[tuple[object, object]]:
        """Run ``jobs``; yield ``(job, result)`` as each finishes. Raises :class:`JobFailed`."""
        jobs = list(jobs)
        if not jobs:
            return
        run = self._run
        if run is None:
            from .execute import run_job as run
        self._pin(jobs)
        ac = as_completed(loop=self.client.loop, with_results=True, raise_errors=False)
        pending: dict = {}                       # future -> job, only the live futures
        for job in jobs:
            future = self._submit(run, job)
            pending[future] = job
            ac.add(future)
        try:
            last_check = time.monotonic()
            while pending:
                if not ac.has_ready():
                    if time.monotonic() - last_check > self.check_interval:
                        self._repin_lost_groups(run, pending, ac)
                        last_check = time.monotonic()
                    time.sleep(0.02)
                    continue
                future, outcome = next(ac)
                job = pending.pop(future, None)
                if job is None:                  # cancelled when its group moved
                    continue
                if future.status == "error":
                    _, exc, _ = outcome
                    raise JobFailed(f"render job '{job.key}' failed: "
                                    f"{type(exc).__name__}: {_first_line(exc)}") from exc
                result, info = outcome
                self.timed_on[job.key] = info
                yield job, result
        finally:
            if pending:                          # interrupted: drop the queued jobs
                self.client.cancel(list(pending))

    def _submit(self, run: Callable, job):
        pin = {}
        if job.timing_group is not None:
            pin = {"workers": [self._pins[job.timing_group]], "allow_other_workers": False}
        return self.client.submit(_run_on_worker, run, job, self.variant, pure=False,
                                  key=f"{job.key}-{uuid.uuid4().hex[:8]}",
                                  retries=self.retries, **pin)

    # ---------------------------------------------------------------- pinning

    def _workers(self) -> dict[str, dict]:
        return self.client.scheduler_info().get("workers", {})

    def _alive_workers(self) -> dict[str, dict]:
        workers = self._workers()
        if not workers:
            print(f"waiting for a Dask worker to join {self.client.scheduler.address} ...",
                  file=sys.stderr, flush=True)
            self.client.wait_for_workers(1)
            workers = self._workers()
        return workers

    def _pin(self, jobs: list, prefer_host: dict | None = None) -> None:
        """Give every timing group of ``jobs`` without a live worker one: the biggest group
        first, to the worker with the fewest pinned jobs (on ``prefer_host[group]`` if any)."""
        workers = self._alive_workers()
        sizes: dict[str, int] = {}
        for job in jobs:
            if job.timing_group is not None:
                sizes[job.timing_group] = sizes.get(job.timing_group, 0) + 1
        load = {address: 0 for address in workers}
        for group, address in self._pins.items():
            if address in load and group in sizes:
                load[address] += sizes[group]
        for group in sorted(sizes, key=lambda g: (-sizes[g], g)):
            if self._pins.get(group) in workers:
                continue
            host = (prefer_host or {}).get(group)
            address = min(load, key=lambda a: (workers[a].get("host") != host, load[a], a))
            self._pins[group] = address
            load[address] += sizes[group]

    def _repin_lost_groups(self, run: Callable, pending: dict, ac) -> None:
        """Move the unfinished jobs of groups whose worker is gone to another worker."""
        workers = self._workers()
        lost = {g: a for g, a in self._pins.items() if a not in workers}
        if not lost:
            return
        moved = [(f, j) for f, j in pending.items() if j.timing_group in lost]
        hosts = {g: a.rsplit("://", 1)[-1].rsplit(":", 1)[0] for g, a in lost.items()}
        for group in lost:
            del self._pins[group]
        self._pin([j for _, j in moved], prefer_host=hosts)
        self.client.cancel([f for f, _ in moved])
        for future, job in moved:
            del pending[future]
            new = self._submit(run, job)
            pending[new] = job
            ac.add(new)


async def _identity(address: str, timeout: float) -> dict:
    from distributed.comm import connect
    from distributed.security import Security
    comm = await connect(address, timeout=timeout,
                         **Security().get_connection_args("client"))
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def probe_scheduler(address: str, timeout: float) -> dict:
    """The identity of the Dask scheduler at ``address``, or :class:`ClusterError` within
    ``timeout`` + :data:`CONNECT_MARGIN` seconds, however the peer behaves (refuses,
    accepts and never speaks, answers slowly, closes, speaks another protocol).

    The exchange runs on its own event loop in a daemon thread under
    ``asyncio.wait_for``; the join of that thread is bounded too, so not even a
    loop that ignores cancellation can hold the caller.
    """
    outcome: dict = {}

    def run() -> None:
        try:
            outcome["reply"] = asyncio.run(asyncio.wait_for(_identity(address, timeout),
                                                            timeout))
        except BaseException as e:   # noqa: BLE001  (reported to the caller below)
            outcome["error"] = e

    thread = threading.Thread(target=run, name="dask-scheduler-probe", daemon=True)
    thread.start()
    thread.join(timeout + CONNECT_MARGIN)
    error = outcome.get("error")
    if thread.is_alive() or isinstance(error, (asyncio.TimeoutError, TimeoutError, OSError)):
        raise ClusterError(f"cannot reach the Dask scheduler at '{address}' within "
                           f"{timeout:g} s")
    if isinstance(error, (ValueError, TypeError)):
        raise ClusterError(f"invalid Dask scheduler address '{address}': {_first_line(error)}")
    if error is not None:
        raise ClusterError(f"'{address}' does not answer as a Dask scheduler "
                           f"({type(error).__name__}: {_first_line(error)})")
    reply = outcome.get("reply")
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise ClusterError(f"'{address}' does not answer as a Dask scheduler (its identity "
                           f"is {str(reply)[:80]!r})")
    return reply


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _close_half_started(error: BaseException) -> None:
    """Close the ``Client`` whose constructor raised ``error``.

    A client that fails after starting its event loop (bad address, a server
    that is not a Dask scheduler) is otherwise closed by ``Client.__del__`` at
    interpreter exit, which then waits twice the connect timeout.
    """
    tb = error.__traceback__
    while tb is not None:
        client = tb.tb_frame.f_locals.get("self")
        if isinstance(client, Client):
            client.close(timeout=1)
            return
        tb = tb.tb_next
