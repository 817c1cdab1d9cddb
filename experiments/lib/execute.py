"""Run a plan: render jobs, store each result as it arrives.

* :func:`run_job` renders one :class:`~.jobs.Job` and returns a
  :class:`~.jobs.JobResult` (plain data: the image as a float32 numpy array, the
  per-pixel sum of squares of its passes, what its passes took, host and CPU). It
  is a module-level function that works in a fresh process (a cluster
  worker): it imports the plugins, sets the variant if another one is set,
  loads the scene (cached per process), renders the job once untimed (JIT
  compilation) the first time, then renders it with a **fresh integrator**
  (:func:`fresh_integrator`: a method that learns starts every job untrained) and
  times every pass with ``dr.eval`` + ``dr.sync_thread``: the kernels' execution time
  (Dr.Jit's kernel history), wall-clock and process CPU seconds. A method whose
  integrator renders in passes of its own (:class:`MultiPass`) has each pass rendered
  here and its hooks between them timed (thread CPU time). What an image costs is
  :mod:`.clock`'s to say, from these.
* Warm timing, in exactly the timed configuration: Mitsuba's ``stratified``,
  ``multijitter``, ``orthogonal`` and ``ldsampler`` bake the sample count into
  the kernel, so the first render at a new count compiles (multijitter, 64x32,
  256 spp after a 1-spp warm-up: 1.6 s, then 0.33 s warm). Every timed pass
  records Dr.Jit's kernel history (:func:`kernels_compiled`); a job during
  which a kernel was compiled or loaded from the disk cache is discarded and
  rendered again, whole, with a fresh integrator and the same seeds (the same
  image), so the time kept is a warm one. ``JobResult.recompiled`` counts the
  discarded tries and ``compiled_passes`` the timed passes that still compiled after
  :data:`WARM_TRIES` tries (0 unless the kernel cache is too small).
* :class:`LocalExecutor` runs jobs one after the other in this process;
  ``map_unordered(jobs)`` yields ``(job, result)`` pairs. Another executor
  (e.g. Dask workers) only has to provide the same method.
* :func:`execute` skips jobs whose entry is already in the store, and writes
  each finished job to the store (atomically) as soon as it arrives, so an
  interrupted run loses no finished job and a rerun resumes.

``JobResult.spp`` is the number of samples actually rendered: Mitsuba's
``stratified``, ``multijitter``, ``orthogonal`` and ``ldsampler`` round a
requested count up to one they support (orthogonal 16 -> 25), and the
analysis uses what was rendered.

Interface for other executors (a cluster): ``run_job(job, variant)`` is
importable as ``experiments.lib.execute.run_job`` and needs nothing but its
arguments; an executor is any object with ``map_unordered(jobs: list[Job])
-> Iterator[tuple[Job, JobResult]]``; pass it as ``execute(jobs, store,
executor)`` (scripts: :class:`~.study.Study` takes ``executor``, or reads
``args.executor``). Jobs of one ``timing_group`` are those whose times one
comparison divides. Beyond the planned interface: :class:`~.jobs.Job` also
has ``pass_spp`` (passes inside a job, for per-pixel variances) and
``hide_emitters``, resolution is ``width``/``height``, and :func:`execute`
takes ``variant`` for the default executor.

Seeds and sample offsets come from the plan, never from the process that
runs a job. Passes inside a job: independent samplers get seed
``derive_seed(job.seed, pass)``; samplers that continue a sequence
(``halton``) keep ``job.seed`` and start pass ``i`` at ``job.sample_offset``
+ the samples of the passes before it.
"""
from __future__ import annotations

import gc
import os
import socket
import time
import warnings
from collections import OrderedDict
from typing import Iterable, Iterator, NamedTuple

import numpy as np

from . import figure_pool
from .jobs import Job, JobResult, cpu_model, derive_seed
from .multipass import MultiPass, replaced_rest, stated, stated_tails
from .methods import Depth, Method
from .scenes import load_scene, load_sensor, scene_hash
from .store import JobStore

#: Scene files kept loaded per process: one. It is loaded once, whatever the methods that
#: render it: a method is an integrator and a sensor (with its sampler and film size)
#: passed to ``mi.render``. A second live scene would change the render kernels of the
#: first (Dr.Jit traces a call over every live shape, BSDF and emitter instance), so that
#: every kernel compiled again, and no kernel would match the disk cache of a run that had
#: other scenes alive; :func:`execute` renders the jobs scene by scene instead.
SCENE_CACHE = 1
#: Methods (integrator + sensor) kept per process, each with its kernels warm: all on the
#: loaded scene, so studies time their methods in groups of at most this many.
VIEW_CACHE = 64
#: Renders of one pass until one ran without compiling (the last one is kept either way).
WARM_TRIES = 3


class View(NamedTuple):
    """What renders a job: the scene loaded once, and the method's sensor (its sampler and
    film). The integrator is made afresh for every job (:func:`fresh_integrator`)."""
    scene: object
    sensor: object


_scenes: OrderedDict = OrderedDict()
_views: OrderedDict = OrderedDict()
#: Views warmed up once in this process (their keys): a view made again (its scene loaded
#: again after another) finds its kernels in Dr.Jit's cache and is not warmed up again.
_warmed: set = set()


def clear_cache() -> None:
    """Forget every loaded scene and method of this process."""
    _views.clear()
    _scenes.clear()
    _warmed.clear()


def job_depth(job: Job) -> Depth:
    """The path-length settings of ``job``."""
    return Depth(job.max_depth, job.rr_depth, job.hide_emitters)


def _check_scene_file(job: Job) -> None:
    """The scene file this process reads must be the one the plan was made from (a
    cluster worker may see another file, or none, at the same path)."""
    if not os.path.isfile(job.scene):
        raise FileNotFoundError(
            f"scene file '{job.scene}' not found on host {socket.gethostname()}: workers "
            f"read scenes at the client's paths; put the scenes and --out on a file system "
            f"every worker sees at the same path")
    sha = scene_hash(job.scene)
    if sha != job.scene_sha256:
        raise ValueError(
            f"scene file '{job.scene}' on host {socket.gethostname()} differs from the one "
            f"the jobs were planned with (sha256 {sha[:12]} instead of "
            f"{job.scene_sha256[:12]}): the scene changed during the run, or workers see "
            f"another file at that path")


def scene_of(job: Job, variant: str):
    """The scene file of ``job``, loaded once per process (cached)."""
    key = (variant, job.scene, job.scene_sha256)
    if key in _scenes:
        _scenes.move_to_end(key)
        return _scenes[key]
    _check_scene_file(job)
    # the old scene goes first: its instances leave Dr.Jit's registry, so that the new
    # scene's take the same ids (a scene loaded beside another gets other ids, and kernels
    # that match no other run's: the sweep points of one scene compiled anew each)
    while _scenes and len(_scenes) >= SCENE_CACHE:
        old = next(iter(_scenes))          # (no local may keep the old scene alive)
        del _scenes[old]
        for k in [k for k in _views if k[0] == old]:
            del _views[k]
        gc.collect()
    _scenes[key] = load_scene(job.scene, job.width, job.height, job.method, job_depth(job))
    return _scenes[key]


def fresh_integrator(job: Job):
    """A new, untrained integrator of ``job``'s method: every job starts from one, so that
    a method that learns over its passes learns from its own job's samples only. A job
    with ``sample_moments`` gets it inside ``vr_moments`` (:mod:`integrators.moments`),
    except a :class:`MultiPass` method, whose variances come from its own passes."""
    import mitsuba as mi
    spec = job.method.integrator_dict(job_depth(job))
    integrator = mi.load_dict(spec)
    if job.sample_moments and not isinstance(integrator, MultiPass):
        integrator = mi.load_dict({"type": "vr_moments", "nested": spec})
    return integrator


def warm_spp(spp: int) -> int:
    """The smallest sample count whose render compiles the kernel a render of ``spp``
    compiles (with a sampler that does not bake its count into the kernel). Mitsuba's
    ``SamplingIntegrator::render`` finds a sample's pixel with a shift where the count is a
    power of two and with a division where it is not, and its image block merges a pixel's
    samples before splatting them (a filter wider than a box) from 4 samples per pass on:
    1 and 2, 3, the powers of two from 4, and the other counts from 5 each share a kernel
    (``tests/test_timing.py`` checks this against Mitsuba). A warm-up at 1 spp would leave a
    16-spp render to compile (and be rendered again) on a Gaussian-filtered film."""
    power_of_two = spp & (spp - 1) == 0
    if spp >= 4:
        return 4 if power_of_two else 5
    return 1 if power_of_two else 3


def _warm_count(method: Method, spp: int) -> int:
    """The count of a warm-up render that compiles the kernels of a render of ``spp``: that
    count where the sampler bakes it into the kernel; for an adaptive method its fewest
    pilot samples and a final pass of the count class of the render's (the class matters
    where the nested integrator renders the final pass itself); else :func:`warm_spp`."""
    if method.sampler_spec.bakes_spp:
        return spp
    if method.adaptive:
        from integrators import adaptive
        return adaptive.MIN_PILOT + warm_spp(adaptive.split(spp)[1])
    return warm_spp(spp)


def _view(job: Job, variant: str) -> View:
    """The warmed-up :class:`View` of ``job`` (cached per process): the first time a kind
    of job meets it (a count's kernel class, :func:`warm_spp`; a method rendering in passes
    of its own: whether it trains), the whole job is rendered once, untimed, with an
    integrator of its own (thrown away), so that the kernels of every pass are compiled
    before a timed render. A view made again in this process (its scene was loaded again
    after another) is not warmed up again: its scene, loaded alone, gives the same kernels,
    already in Dr.Jit's cache, and a timed render that still compiles is rendered again
    (:func:`run_job`). Warming it again cost a whole job of a method that renders in
    passes of its own (a trained guide: 2.6-5.3 s per guiding scene of a cold make run).
    Such a method's job warms those that train as it does (:meth:`.methods.Method.trains`):
    an untrained 16-spp job does not warm a trained one's kernels. A pilot is not warmed
    up (it renders once, its cost the kernels' execution, :func:`run_job`): its render
    warms the jobs after it."""
    scene = scene_of(job, variant)
    key = ((variant, job.scene, job.scene_sha256), job.method, job.width, job.height,
           job_depth(job))
    method: Method = job.method
    spp = _warm_count(method, job.passes()[0])
    if key in _views:
        _views.move_to_end(key)
        view = _views[key]
    else:
        view = View(scene, load_sensor(job.scene, job.width, job.height, method, spp))
        _views[key] = view
        while len(_views) > VIEW_CACHE:
            _views.popitem(last=False)
    # the first compile, at a count of the first pass's kernel (a sampler that bakes its
    # count into the kernel: that count), so that the timed render does not compile again
    warm = fresh_integrator(job)
    multi = isinstance(warm, MultiPass)
    # a whole job warms the kernels of every job that trains as it does (or does not)
    warmed = (key, method.trains(job.spp, job.width * job.height) if multi else spp)
    if warmed in _warmed or job.pilot:      # a pilot renders once, cold: it warms the rest
        _warmed.add(warmed)
        return view
    if multi:
        render_passes(view, warm, job)
    else:
        with warnings.catch_warnings():     # a sampler's note on this count is not the job's
            warnings.simplefilter("ignore")
            _render(view, warm, spp, 0x5EED, sequence_state(job, 0))
    _warmed.add(warmed)
    return view


def sequence_state(job: Job, done: int) -> dict | None:
    """The sampler attributes that make a pass of ``job`` continue its sequence after the
    ``done`` samples its earlier passes took (None: the sampler reseeds instead). The
    sequence's length: the job's ``sequence_spp``, else its own samples (a job split into
    passes for memory is one sequence: zsobol needs its length declared)."""
    spec = job.method.sampler_spec
    if not spec.continues_sequence:
        return None
    return spec.sequence_attributes(job.sample_offset + done,
                                    job.sequence_spp or job.sample_offset + job.spp)


def set_sequence_state(sensor, state: dict) -> None:
    """Set the attributes of the sensor's sampler (``sample_offset``...; no recompilation):
    on the Python sampler object, or through ``mi.traverse`` for a sampler that exposes them
    as parameters."""
    sampler = sensor.sampler()
    params = None
    for name, value in state.items():
        if hasattr(sampler, name):
            setattr(sampler, name, value)
            continue
        import mitsuba as mi
        params = params if params is not None else mi.traverse(sensor)
        key = next(k for k in params.keys() if k.endswith(f"sampler.{name}"))
        params[key] = mi.UInt32(value)
    if params is not None:
        params.update()


def kernels_compiled(history: list[dict]) -> int:
    """How many kernels of a Dr.Jit kernel history were compiled (or loaded from the disk
    cache) rather than found in the in-memory cache: 0 for a warm render."""
    import drjit as dr
    # a kernel loaded from the disk cache reports cache_hit and cache_disk
    return sum(1 for k in history if k.get("type") == dr.KernelType.JIT
               and (not k.get("cache_hit", False) or k.get("cache_disk", False)))


def _render(view, integrator, spp: int, seed: int, sequence: dict | None = None,
            raw: bool = False):
    """One render of a :class:`View` (or of a scene with its own sensor) with
    ``integrator`` (None: the scene's own; ``sequence``: the sampler state it continues,
    :func:`sequence_state`): (image, wall seconds, CPU seconds, kernels compiled during it,
    seconds its kernels executed). ``raw``: the image as Mitsuba's tensor, all channels."""
    import drjit as dr
    import mitsuba as mi
    if not isinstance(view, View):
        integrator = integrator or view.integrator()
        view = View(view, view.sensors()[0])
    if sequence:
        set_sequence_state(view.sensor, sequence)
    figure_pool.wait()                  # no figure is drawn while a render is timed
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    dr.kernel_history_clear()
    cpu, start = time.process_time(), time.perf_counter()
    image = mi.render(view.scene, sensor=view.sensor, integrator=integrator, spp=spp,
                      seed=seed)
    dr.eval(image)
    dr.sync_thread()
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    history = dr.kernel_history()
    kernel = sum(k.get("execution_time", 0.0) for k in history) / 1000   # ms -> s
    image = image if raw else np.array(image, dtype=np.float64)[..., :3]
    return image, seconds, cpu, kernels_compiled(history), kernel


class Timed(NamedTuple):
    """A job's image and what its passes took (before the retries are counted)."""
    image: np.ndarray            # the job's mean image (H, W, 3) float64
    sq: np.ndarray               # sum over passes of k_i m_i^2
    spp: int                     # samples rendered (what the sampler ran)
    passes: int                  # the passes of sq (every sample with ``sample_moments``)
    pass_seconds: list           # wall seconds per pass
    cpu_seconds: float
    kernel_seconds: float
    host_seconds: float          # CPU time of the method's hooks between passes
    compiled: int                # passes during which a kernel compiled
    higher: tuple | None = None  # (sum of x^3, sum of x^4) over the samples, (H, W, 3)
                                 # each: through ``vr_moments`` only
    variance_var: np.ndarray | None = None   # a MultiPass method's: how sure its stated
                                             # variance is (:func:`.multipass.stated_tails`)


def render_pass(view: View, integrator, job: Job, index: int, spp: int, done: int,
                multi: bool, raw: bool) -> tuple:
    """Pass ``index`` of ``job`` (``spp`` samples after ``done``): (its image, the samples the
    sampler ran, wall seconds, CPU seconds, kernel seconds, renders that compiled). A
    :class:`MultiPass` method's pass renders in the renders of :meth:`.jobs.Job.render_parts`
    (over the lane cap; a count a sequence sampler would round), averaged (every channel:
    the image and its AOVs are per-pixel means)."""
    continues = job.method.continues_sequence
    parts, image, k = job.render_parts(spp) if multi else [spp], 0.0, 0
    seconds = cpu = kernel = 0.0
    compiled = 0
    for j, n in enumerate(parts):
        seed = job.seed if continues else \
            derive_seed(job.seed, index) if j == 0 else derive_seed(job.seed, index, j)
        part, *spent = _render(view, integrator, n, seed, sequence_state(job, done + k),
                               raw=raw)
        # Mitsuba's stratified, orthogonal and ldsampler round the count (e.g.
        # orthogonal: 16 -> 25, a prime squared): count what was rendered
        n = view.sensor.sampler().sample_count()
        image = part if len(parts) == 1 else \
            image + np.array(part, dtype=np.float64) * (n / sum(parts))
        k += n
        seconds, cpu, kernel = seconds + spent[0], cpu + spent[1], kernel + spent[3]
        compiled += spent[2] > 0
    return image, k, seconds, cpu, kernel, compiled


def render_passes(view: View, integrator, job: Job) -> Timed:
    """Every pass of ``job`` with ``integrator`` (:func:`render_pass`): the memory-bounded
    passes of :meth:`.jobs.Job.passes`, or a :class:`MultiPass` method's own schedule with
    its hooks between them (their CPU time measured on this thread, the kernels they launch
    synced first so that their time is the hooks' own). Through ``vr_moments`` every sample
    is a pass of ``sq`` (its squares' per-pixel mean times the pass's count), and the sums
    of the samples' cubes and fourth powers come with it (``higher``)."""
    import drjit as dr
    from integrators import moments
    multi = isinstance(integrator, MultiPass)
    per_sample = isinstance(integrator, moments.MomentsIntegrator)
    schedule = integrator.pass_schedule(job.spp, job.width * job.height) if multi \
        else job.passes()
    mean = np.zeros((job.height, job.width, 3))
    sq = np.zeros_like(mean)
    higher = (np.zeros_like(mean), np.zeros_like(mean)) if per_sample else None
    images, spps = [], []
    done, times, cpu, kernels, host, compiled = 0, [], 0.0, 0.0, 0.0, 0
    i = 0
    while i < len(schedule):
        image, k, seconds, cpu_seconds, kernel, c = render_pass(
            view, integrator, job, i, schedule[i], done, multi, multi or per_sample)
        compiled += c
        if multi:
            # the image on the host, as every method's is read (not the method's work)
            image = np.array(image, dtype=np.float64)
            start = time.thread_time()
            rest = integrator.after_pass(i, image, k)
            dr.sync_thread()
            host += time.thread_time() - start
            schedule = schedule if rest is None else replaced_rest(schedule, i, rest)
            image = image[..., :3]
            images.append(image)
            spps.append(k)
        if per_sample:
            image = np.array(image, dtype=np.float64)
            m2, m3, m4 = np.split(image[..., -len(moments.MOMENTS):], 3, axis=-1)
            image = image[..., :3]
            higher = (higher[0] + k * m3, higher[1] + k * m4)
        mean += image * k
        sq += k * (m2 if per_sample else image * image)
        done += k
        times.append(seconds)
        cpu += cpu_seconds
        kernels += kernel
        i += 1
    mean /= done
    variance_var = None
    if multi:
        start = time.thread_time()
        mean = integrator.combine(images, spps)
        host += time.thread_time() - start
        # its per-pixel variance is measurement (as vr_moments' is), not the method's work
        mean, sq, passes = stated(integrator, mean, done)
        variance_var = stated_tails(integrator) if passes > 1 else None
    else:
        passes = done if per_sample else len(times)
    return Timed(mean, sq, done, passes, times, cpu, kernels, host, compiled, higher,
                 variance_var)


def run_job(job: Job, variant: str) -> JobResult:
    """Render ``job`` in this process with the Mitsuba ``variant``: with a fresh
    integrator, its time kept from a try during which nothing compiled (up to
    :data:`WARM_TRIES` tries, each with a fresh integrator and the same seeds)."""
    import integrators  # noqa: F401  (chooses libLLVM before drjit loads; registers plugins)
    import mitsuba as mi
    if mi.variant() != variant:
        mi.set_variant(variant)
    view = _view(job, variant)
    # a pilot is rendered once: its cost is the kernels' execution (a compile is not in
    # it) and the hooks' CPU time (where a compile of their small kernels would only
    # lower the count it gives)
    for attempt in range(1 if job.pilot else WARM_TRIES):
        timed = render_passes(view, fresh_integrator(job), job)
        if not timed.compiled:
            break
    return JobResult(image=timed.image.astype(np.float32), sq=timed.sq,
                     cubes=None if timed.higher is None else timed.higher[0],
                     fourths=None if timed.higher is None else timed.higher[1],
                     variance_var=timed.variance_var, spp=timed.spp,
                     passes=timed.passes,
                     wall_seconds=float(sum(timed.pass_seconds)),
                     pass_seconds=timed.pass_seconds, cpu_seconds=timed.cpu_seconds,
                     host=socket.gethostname(), cpu=f"{cpu_model()} ({os.cpu_count()} cores)",
                     recompiled=attempt, compiled_passes=timed.compiled,
                     kernel_seconds=timed.kernel_seconds, host_seconds=timed.host_seconds)


class LocalExecutor:
    """Runs jobs one after another in this process (the default)."""

    def __init__(self, variant: str):
        self.variant = variant

    def map_unordered(self, jobs: list[Job]) -> Iterator[tuple[Job, JobResult]]:
        for job in jobs:
            yield job, run_job(job, self.variant)


def pending(jobs: Iterable[Job], store: JobStore) -> list[Job]:
    """The jobs (first of each key) that have no entry in ``store`` yet, scene by scene
    (each scene's jobs in their order, the scenes in the order they first appear: a
    process keeps one scene loaded, :data:`SCENE_CACHE`)."""
    seen, by_scene = set(), {}
    for job in jobs:
        if job.key not in seen and not store.has(job.key):
            by_scene.setdefault((job.scene, job.scene_sha256), []).append(job)
        seen.add(job.key)
    return [job for group in by_scene.values() for job in group]


def execute(jobs: Iterable[Job], store: JobStore, executor=None, progress: bool | str = True,
            variant: str | None = None) -> int:
    """Run the jobs that ``store`` lacks, storing each result as it arrives; return how many.

    ``executor`` defaults to a :class:`LocalExecutor` for ``variant`` (default:
    the current Mitsuba variant). ``progress``: a progress bar counting
    finished jobs (a string is its label).
    """
    todo = pending(jobs, store)
    if not todo:
        return 0
    if executor is None:
        import mitsuba as mi
        executor = LocalExecutor(variant or mi.variant())
    figure_pool.wait()                  # nor while another executor's workers render
    from tqdm import tqdm
    label = progress if isinstance(progress, str) else "render jobs"
    with tqdm(total=len(todo), desc=label, unit="job", disable=not progress,
              dynamic_ncols=True, leave=False) as bar:
        for job, result in executor.map_unordered(todo):
            store.put(job, result)
            bar.update(1)
    return len(todo)
