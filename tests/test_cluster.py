"""The Dask executor (experiments/lib/cluster.py): with a toy job, then with the experiment scripts.

One LocalCluster of two worker processes (one thread each) serves the whole
module. The toy job is plain picklable data like a render job: its result
depends only on its seed (fixed by the plan), never on the worker, so a
cluster run must give exactly the numbers of a local loop, also when a worker
is killed mid-run. The end-to-end tests run a tiny convergence study through
the scripts' command line (``--workers 2``, and ``--scheduler`` pointing at the
shared cluster) and compare it with the same study on the local loop.
"""
from __future__ import annotations

import csv
import glob
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest
from distributed import Client

from _paths import ROOT
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
    cluster = C.local_cluster(2, silence_logs=logging.CRITICAL)
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


def _thread_limits() -> dict:
    return {k: v for k, v in os.environ.items() if k.endswith("_NUM_THREADS")}


def test_local_cluster_leaves_the_client_thread_limits_alone():
    """Dask's nannies live in the client and used to write OMP_NUM_THREADS=1 (and MKL,
    OpenBLAS) into its environment at each worker (re)start, making the client's
    OpenMP (FLIP) single-threaded. The worker keeps the limit; the client does not
    get it, also after a killed worker was restarted."""
    before = _thread_limits()
    cluster = C.local_cluster(1, silence_logs=logging.CRITICAL)
    try:
        assert _thread_limits() == before
        with Client(cluster, set_as_default=False) as client:
            (worker_omp,) = client.run(lambda: os.environ.get("OMP_NUM_THREADS")).values()
            assert worker_omp == "1"
            (pid,) = client.run(os.getpid).values()
            os.kill(pid, signal.SIGKILL)
            deadline, pids = time.monotonic() + 30, []
            while time.monotonic() < deadline:
                time.sleep(0.2)
                try:                                  # the dead worker may still be listed
                    pids = list(client.run(os.getpid).values())
                except OSError:                       # CommClosedError: it was
                    continue
                if pids and pids != [pid]:
                    break
            assert pids and pids != [pid], "the nanny did not restart the worker"
            assert _thread_limits() == before
    finally:
        cluster.close()


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


class Peer:
    """A TCP peer on loopback that is not a Dask scheduler, behaving as ``mode`` says:

    * ``silent``: accepts connections and never speaks;
    * ``backlog``: listens and never accepts (the kernel completes the handshake);
    * ``slow``: accepts, then answers with junk only after ``delay`` seconds;
    * ``close``: accepts and closes at once;
    * ``http``: answers at once in another protocol (an HTTP error page).
    """

    def __init__(self, mode: str, delay: float = 5.0):
        self.mode, self.delay = mode, delay
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.sock.settimeout(0.2)
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.held: list[socket.socket] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        if mode != "backlog":
            self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            if self.mode == "close":
                conn.close()
            elif self.mode == "http":
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
                conn.close()
            else:
                self.held.append(conn)
                if self.mode == "slow":
                    threading.Timer(self.delay, self._junk, (conn,)).start()

    def _junk(self, conn) -> None:
        try:
            conn.sendall(b"\x00" * 64)
        except OSError:
            pass

    def close(self) -> None:
        self.stop.set()
        if self.thread.is_alive():
            self.thread.join(2)
        for conn in self.held:
            conn.close()
        self.sock.close()


#: What each peer must be told, and the measured times (printed with -s, for the record).
PEER_MODES = {"silent": "cannot reach", "backlog": "cannot reach", "slow": "cannot reach",
              "close": "cannot reach", "http": "does not answer as a Dask scheduler"}
TIMEOUT = 1.0


@pytest.mark.parametrize("mode", sorted(PEER_MODES))
def test_unanswering_peer_fails_within_the_deadline(mode):
    """However a loopback peer behaves, connect gives up within timeout + margin, with one
    line naming the address (the hang seen before: a silent peer held Client() forever)."""
    peer = Peer(mode)
    try:
        start = time.monotonic()
        with pytest.raises(C.ClusterError) as err:
            C.DaskExecutor.connect(peer.address, VARIANT, timeout=TIMEOUT, run=toy_run,
                                   prepare=toy_prepare)
        elapsed = time.monotonic() - start
    finally:
        peer.close()
    print(f"connect to a {mode} peer: ClusterError after {elapsed:.2f} s")
    assert elapsed < TIMEOUT + C.CONNECT_MARGIN + 0.5, elapsed
    message = str(err.value)
    assert peer.address in message and PEER_MODES[mode] in message and "\n" not in message


@pytest.mark.parametrize("address, timeout, bound", [
    (f"tcp://127.0.0.1:{_closed_port()}", 1.0, 1.0 + C.CONNECT_MARGIN + 0.5),   # refused
    ("not a scheduler::", None, 2.0)],                                         # not an address
    ids=["refused", "not-an-address"])      # the port varies: ids stable across pytest-xdist workers
def test_unreachable_scheduler_fails_fast(address, timeout, bound):
    options = {} if timeout is None else {"timeout": timeout}
    start = time.monotonic()
    with pytest.raises(C.ClusterError) as err:
        C.DaskExecutor.connect(address, VARIANT, run=toy_run, prepare=toy_prepare, **options)
    elapsed = time.monotonic() - start
    print(f"connect to {address!r}: ClusterError after {elapsed:.2f} s")
    assert elapsed < bound, elapsed
    message = str(err.value)
    assert address in message and "\n" not in message


def test_probe_knows_a_real_scheduler(local_cluster):
    """The deadline probe accepts a real scheduler (the shared local cluster) quickly."""
    start = time.monotonic()
    identity = C.probe_scheduler(local_cluster.scheduler_address, TIMEOUT)
    assert identity["type"] == "Scheduler" and time.monotonic() - start < TIMEOUT


def test_local_cluster_listens_on_loopback_only(local_cluster):
    host = local_cluster.scheduler_address.rsplit("://", 1)[-1].rsplit(":", 1)[0]
    assert host == "127.0.0.1"
    for address in local_cluster.scheduler_info["workers"]:
        assert address.startswith("tcp://127.0.0.1:"), address


# ------------------------------------------------- end to end: the experiment scripts
#
# A tiny convergence study (3 methods, ladders to 4 spp, a 16-spp reference in
# jobs, equal-time jobs) run locally once; then on two local workers, on the
# shared cluster with a worker killed mid-run, and interrupted and resumed.
# A time budget far below one sample's time makes every equal-time job 1 spp,
# so the job list does not depend on measured times.

REPEATS = 2
STUDY = ["--resolution", "16x8", "--spp", "4", "--reference-spp", "16",
         "--methods", "bsdf,bsdf+halton,path", "--time-budget", "1e-9",
         "--repeats", str(REPEATS)]


def run_study(out, *extra: str) -> dict:
    """Run the study; return the executor's ``timed_on`` (empty for the local loop)."""
    from experiments.lib.studies import convergence
    from experiments.lib import cli
    timed_on = {}
    try:
        convergence.STUDY.main(STUDY + ["--out", str(out), *extra])
    finally:
        for ex in cli._EXECUTORS:
            timed_on.update(ex.timed_on)
        cli.close_executors()
    return timed_on


#: The stores of a study's --out: its jobs, and the reference store's chunks.
STORES = ("store", "references")


def stored_path(out, key) -> str:
    """The file of a finished job (or reference chunk) of the study in ``out``."""
    from experiments.lib.store import JobStore
    paths = [JobStore(os.path.join(str(out), s)).path(key) for s in STORES]
    return next((p for p in paths if os.path.exists(p)), paths[0])


def read_store(out) -> dict:
    """Every finished job of the study, reference chunks included: key -> JobResult."""
    from experiments.lib.store import JobStore
    found = {}
    for name in STORES:
        root = os.path.join(str(out), name)
        st = JobStore(root)
        for p in glob.glob(os.path.join(root, "**", "*.npz"), recursive=True):
            key = os.path.relpath(p, root)[:-len(".npz")]
            found[key] = st.get(key)
    return found


def error_table(out) -> dict:
    """(method, spp) -> (MSE, relMSE) from the study's table of errors."""
    with open(os.path.join(str(out), "convergence", "errors.csv"), newline="") as f:
        return {(r["method"], r["spp"]): (float(r["MSE"]), float(r["relMSE"]))
                for r in csv.DictReader(f)}


def assert_same_study(a, b) -> float:
    """Same jobs, images equal up to float summation order, same metrics; returns the
    largest absolute difference between two images of the same job."""
    ra, rb = read_store(a), read_store(b)
    assert len(ra) >= 20 and sorted(ra) == sorted(rb)
    largest = 0.0
    for key in ra:
        assert rb[key].spp == ra[key].spp, key
        np.testing.assert_allclose(rb[key].image, ra[key].image, rtol=1e-5, atol=1e-6,
                                   err_msg=key)
        largest = max(largest, float(np.abs(rb[key].image - ra[key].image).max()))
    ea, eb = error_table(a), error_table(b)
    assert len(ea) == 3 * 3 and sorted(ea) == sorted(eb)
    for row in ea:
        np.testing.assert_allclose(eb[row], ea[row], rtol=1e-5, err_msg=str(row))
    return largest


@pytest.fixture(scope="module")
def local_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("local")
    run_study(out)
    return out


def test_study_on_two_workers_equals_local(local_study, tmp_path):
    timed_on = run_study(tmp_path, "--workers", "2")
    largest = assert_same_study(local_study, tmp_path)
    print(f"largest image difference between --workers 2 and the local loop: {largest:.3g}")
    # the jobs whose times the study compares were all timed by one worker
    group = [k for k in timed_on if k.startswith(("convergence/", "equal_time/"))]
    assert len(group) == REPEATS * (3 * 3 + 3)     # 3 methods x (1, 2, 4 spp + equal time)
    assert len({timed_on[k].address for k in group}) == 1
    # negative control: another seed changes the images (the comparison can fail)
    other = tmp_path / "seed1"
    run_study(other, "--seed", "1")
    with pytest.raises(AssertionError):
        assert_same_study(local_study, other)


def test_study_survives_a_killed_worker(local_study, local_cluster, tmp_path, monkeypatch):
    """Kill the worker the compared jobs are pinned to after the second finished job."""
    from experiments.lib import cli
    from experiments.lib.store import JobStore
    put, killed = JobStore.put, []

    def put_then_kill(self, job, result):
        put(self, job, result)
        if len(killed) == 0 and job.key.startswith("convergence/"):
            ex = cli._EXECUTORS[-1]
            victim = ex._pins[job.timing_group]
            pid = ex.client.run(os.getpid)[victim]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
    monkeypatch.setattr(JobStore, "put", put_then_kill)
    timed_on = run_study(tmp_path, "--scheduler", local_cluster.scheduler_address)
    assert killed
    assert_same_study(local_study, tmp_path)
    pids = Client(local_cluster, set_as_default=False).run(os.getpid).values()
    assert killed[0] not in pids                  # it really died (and was replaced)
    assert any(info.pid != killed[0] for info in timed_on.values())


def test_interrupted_study_resumes_without_rendering_again(local_study, local_cluster,
                                                          tmp_path, monkeypatch):
    from experiments.lib.cluster import DaskExecutor
    from experiments.lib.store import JobStore
    put = JobStore.put
    finished = []

    def put_then_interrupt(self, job, result):
        put(self, job, result)
        finished.append(job.key)
        if len(finished) == 5:
            raise KeyboardInterrupt
    monkeypatch.setattr(JobStore, "put", put_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        run_study(tmp_path, "--scheduler", local_cluster.scheduler_address)
    assert sorted(read_store(tmp_path)) == sorted(finished)
    stamps = {k: os.stat(stored_path(tmp_path, k)).st_mtime_ns for k in finished}

    monkeypatch.setattr(JobStore, "put", put)
    submitted = []
    map_unordered = DaskExecutor.map_unordered

    def spy(self, jobs):
        jobs = list(jobs)
        submitted.extend(j.key for j in jobs)
        return map_unordered(self, jobs)
    monkeypatch.setattr(DaskExecutor, "map_unordered", spy)
    run_study(tmp_path, "--scheduler", local_cluster.scheduler_address)
    assert not set(submitted) & set(finished), "finished jobs were rendered again"
    assert sorted(submitted + finished) == sorted(read_store(local_study))
    for k, stamp in stamps.items():
        assert os.stat(stored_path(tmp_path, k)).st_mtime_ns == stamp
    assert_same_study(local_study, tmp_path)


@pytest.fixture(scope="module")
def startup(tmp_path_factory) -> float:
    """Seconds the command takes to start and stop at once (``--help``: the same imports,
    no cluster)."""
    start = time.monotonic()
    subprocess.run([sys.executable, "-m", "experiments.convergence", "--help"], cwd=ROOT,
                   capture_output=True, text=True, timeout=60, check=True)
    return time.monotonic() - start


@pytest.mark.parametrize("options, says", [
    (["--scheduler", f"tcp://127.0.0.1:{_closed_port()}"], "cannot reach the Dask scheduler"),
    (["--scheduler", "not a scheduler::"], "invalid Dask scheduler address"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "not allowed with"),
    (["--workers", "0"], "--workers"),
])
def test_bad_cluster_options_exit_2_with_one_line(tmp_path, options, says, startup):
    """Each bad option ends the command with one line and status 2, within the connect
    timeout and its margin of the command's own start-up (Python and the imports, measured
    beside it: on a loaded machine they alone can take seconds)."""
    out = tmp_path / "results"
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "experiments.convergence", "--out", str(out),
                           *options], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert time.monotonic() - start < startup + C.CONNECT_TIMEOUT + C.CONNECT_MARGIN + 2.0
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0], proc.stderr
    assert not out.exists()
