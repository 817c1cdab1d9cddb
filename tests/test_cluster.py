"""The Dask executor (experiments/lib/cluster.py) against a toy job function.

One LocalCluster of two worker processes (one thread each) serves the whole
module. The toy job is plain picklable data like a render job: its result
depends only on its seed (fixed by the plan), never on the worker, so a
cluster run must give exactly the numbers of a local loop, also when a worker
is killed mid-run.
"""
from __future__ import annotations

import logging
import os
import signal
import socket
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest
from distributed import Client, LocalCluster

from experiments.lib import cluster as C

VARIANT = "toy_variant"


@dataclass(frozen=True)
class ToyJob:
    key: str
    seed: int
    timing_group: str | None = None
    seconds: float = 0.0               # how long the job "renders"


@dataclass
class ToyResult:
    image: np.ndarray
    variant: str | None                # what the worker set-up left for the job
    pid: int


def toy_prepare(variant: str) -> None:
    os.environ["TOY_VARIANT"] = variant


def toy_run(job: ToyJob, variant: str) -> ToyResult:
    time.sleep(job.seconds)
    rng = np.random.default_rng(job.seed)
    image = rng.random((8, 4, 3), dtype=np.float32)
    return ToyResult(image, os.environ.get("TOY_VARIANT"), os.getpid())


def toy_fail(job: ToyJob, variant: str):
    raise ValueError(f"scene of {job.key} is broken")


def failing_prepare(variant: str) -> None:
    raise RuntimeError(f"variant {variant} needs a CUDA GPU")


def plan(n: int, groups=("a", "b", None), seconds: float = 0.0) -> list[ToyJob]:
    return [ToyJob(f"job{i:02d}", 1000 + 7 * i, groups[i % len(groups)], seconds)
            for i in range(n)]


@pytest.fixture(scope="module")
def local_cluster():
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.CRITICAL)
    yield cluster
    cluster.close()


@pytest.fixture
def executor(local_cluster):
    ex = C.DaskExecutor(Client(local_cluster, set_as_default=False), VARIANT, run=toy_run,
                        prepare=toy_prepare)
    yield ex
    ex.close()


def worker_pids(ex: C.DaskExecutor) -> dict[str, int]:
    return ex.client.run(os.getpid)


def test_same_results_as_local_loop(executor):
    jobs = plan(12)
    local = {job.key: toy_run(job, VARIANT).image for job in jobs}
    got = {}
    for job, result in executor.map_unordered(jobs):
        assert job.key not in got, f"{job.key} yielded twice"
        got[job.key] = result
    assert sorted(got) == sorted(local)
    for key, result in got.items():
        np.testing.assert_array_equal(result.image, local[key])
        assert result.variant == VARIANT              # the worker plugin ran first
    # honest timing: every job of a timing group was timed by one worker process,
    # and the two groups went to different workers
    for group in ("a", "b"):
        keys = [j.key for j in jobs if j.timing_group == group]
        assert len({executor.timed_on[k].address for k in keys}) == 1
        assert len({got[k].pid for k in keys}) == 1
    assert executor.timed_on["job00"].address != executor.timed_on["job01"].address
    info = executor.timed_on["job00"]
    assert info.cpu and info.host and info.address.startswith("tcp://")


def test_killed_worker_same_numbers(executor):
    """Kill the worker that group 'a' is pinned to while its jobs run: the scheduler
    reruns its unpinned jobs, the executor moves group 'a' to the other worker.
    With the move paused, group 'a' stalls (negative control)."""
    jobs = plan(18, seconds=0.15)
    local = {job.key: toy_run(job, VARIANT).image for job in jobs}
    pids = worker_pids(executor)
    executor.check_interval = 1e9                     # pause the re-pinning
    got, timeline = {}, []
    gen = executor.map_unordered(jobs)

    def consume():
        for job, result in gen:
            got[job.key] = result
            timeline.append((time.monotonic(), job))

    first_job, first = next(gen)
    got[first_job.key] = first
    victim = executor._pins["a"]
    os.kill(pids[victim], signal.SIGKILL)
    thread = threading.Thread(target=consume, daemon=True)
    thread.start()
    time.sleep(3.0)                                   # 'a' jobs take 0.15 s each
    resumed = time.monotonic()
    a_during_pause = [j for _, j in timeline if j.timing_group == "a"]
    executor.check_interval = C.CHECK_INTERVAL        # resume: group 'a' moves
    thread.join(timeout=60)
    assert not thread.is_alive(), "the run did not finish after a worker was killed"
    a_total = sum(j.timing_group == "a" for j in jobs)
    assert len(a_during_pause) + 1 < a_total, "negative control: group 'a' did not stall"
    assert sorted(got) == sorted(local)
    for key, result in got.items():
        np.testing.assert_array_equal(result.image, local[key])
        assert result.variant == VARIANT              # also on the restarted worker
    moved = [j for t, j in timeline if t > resumed and j.timing_group == "a"]
    assert moved, "no job of group 'a' ran after the move"
    assert all(executor.timed_on[j.key].pid != pids[victim] for j in moved)
    assert len({executor.timed_on[j.key].address for j in moved}) == 1


def test_interrupted_run_cancels_queued_jobs(executor):
    jobs = plan(10, groups=(None,), seconds=0.2)
    gen = executor.map_unordered(jobs)
    next(gen)
    gen.close()                                       # the client is interrupted
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        left = executor.client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks))
        if left == 0:
            break
        time.sleep(0.1)
    assert left == 0, f"{left} jobs still on the scheduler after the client stopped"


def test_failing_job_names_job(local_cluster):
    with C.DaskExecutor(Client(local_cluster, set_as_default=False), VARIANT, run=toy_fail,
                        prepare=toy_prepare, retries=0) as ex:
        with pytest.raises(C.JobFailed, match=r"job07.*ValueError: scene of job07 is broken"):
            list(ex.map_unordered([ToyJob("job07", 1)]))


def test_worker_setup_failure_is_clear(local_cluster):
    with pytest.raises(C.ClusterError, match=r"cannot set up variant 'cuda_ad_rgb'.*CUDA GPU"):
        C.DaskExecutor(Client(local_cluster, set_as_default=False), "cuda_ad_rgb",
                       run=toy_run, prepare=failing_prepare)
    # the working set-up replaces the failed one on every worker
    with C.DaskExecutor(Client(local_cluster, set_as_default=False), VARIANT, run=toy_run,
                        prepare=toy_prepare) as ex:
        (_, result), = ex.map_unordered([ToyJob("x", 3)])
        assert result.variant == VARIANT


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("address, timeout", [
    (f"tcp://127.0.0.1:{_closed_port()}", 1.0),      # refused (retried until the timeout)
    ("tcp://192.0.2.1:8786", 1.0),                    # no answer
    ("not a scheduler::", None)])                     # not an address
def test_unreachable_scheduler_fails_fast(address, timeout):
    options = {} if timeout is None else {"timeout": timeout}
    start = time.monotonic()
    with pytest.raises(C.ClusterError) as err:
        C.DaskExecutor.connect(address, VARIANT, run=toy_run, prepare=toy_prepare, **options)
    assert time.monotonic() - start < 10
    message = str(err.value)
    assert address in message and "\n" not in message
