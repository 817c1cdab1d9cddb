"""Rendering in passes: accumulation, per-pass timing, resume, and the reference cache.

A render is a :class:`RenderJob` run by :func:`run_progressive`. It renders
passes (``mi.render(scene, spp=k, seed=s)``, a fresh seed per pass), folds
each into a float64 running mean (and a weighted sum of squares, for per-pixel
variances), and writes the image at every target sample count (EXR + PNG) with
its cumulative render time. The whole accumulation state lives in one
atomically written ``state.npz``; a rerun continues from it and skips
finished targets, giving the same images as an uninterrupted run.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
import zlib
from dataclasses import dataclass, field
from typing import Callable

import drjit as dr
import mitsuba as mi
import numpy as np
from tqdm import tqdm

from . import store
from .methods import Method, SceneInfo, load_scene, plugins_version, reference_integrator

#: Largest number of samples (pixels x spp) rendered in one pass; bigger passes
#: are split, which bounds memory (1024x512 -> 8 spp per pass).
MAX_LANES = 2**22
#: Save the accumulation state at least this often (seconds) inside long targets.
SAVE_INTERVAL = 30.0
STATE = "state.npz"


# ------------------------------------------------------------ accumulation

@dataclass
class Accumulator:
    """Running mean of pass images, weighted by their sample counts.

    ``sq`` is sum_i k_i m_i^2 over passes i with k_i samples and mean image m_i,
    from which :meth:`variance_of_mean` estimates per-pixel variances.
    """
    mean: np.ndarray
    sq: np.ndarray
    spp: int = 0
    passes: int = 0
    seconds: float = 0.0

    @classmethod
    def empty(cls, height: int, width: int, channels: int = 3) -> "Accumulator":
        shape = (height, width, channels)
        return cls(np.zeros(shape), np.zeros(shape))

    def add(self, image: np.ndarray, spp: int, seconds: float = 0.0) -> None:
        """Fold in a pass image that averages ``spp`` samples per pixel."""
        image = np.asarray(image, np.float64)
        n = self.spp
        self.mean = (self.mean * n + image * spp) / (n + spp)
        self.sq += spp * image * image
        self.spp += spp
        self.passes += 1
        self.seconds += seconds

    def variance_of_mean(self) -> np.ndarray:
        """Per-pixel variance of :attr:`mean`, from the spread of the pass images.

        Per-sample variance: sum_i k_i (m_i - mean)^2 / (passes - 1)
        = (sq - spp * mean^2) / (passes - 1); divided by spp for the mean.
        """
        if self.passes < 2:
            return np.full_like(self.mean, np.inf)
        s2 = np.maximum(self.sq - self.spp * self.mean ** 2, 0.0) / (self.passes - 1)
        return s2 / self.spp


# -------------------------------------------------------------- one pass

def pass_seed(base_seed: int, key: str, index: int) -> int:
    """Seed of pass ``index`` of the render ``key``: distinct per (seed, key, pass)."""
    return zlib.crc32(f"{base_seed}/{key}/{index}".encode()) & 0x7FFFFFFF


def render_pass(scene, method: Method | None, spp: int, base_seed: int, key: str,
                index: int, spp_done: int) -> tuple[np.ndarray, float]:
    """Render one pass of ``spp`` samples; return (image as float64 (H, W, 3), seconds).

    This is the one place that decides how passes continue each other. Random
    samplers get a new seed per pass (independent passes). A Halton sampler
    keeps one seed and continues its sequence: ``sample_offset`` is set to
    ``spp_done``, the samples already taken (see :mod:`integrators.halton`),
    so the passes together are exactly one render of all their samples and
    keep the QMC convergence rate.
    """
    if method is not None and method.is_halton:
        seed = pass_seed(base_seed, key, 0)
        set_sample_offset(scene, spp_done)
    else:
        seed = pass_seed(base_seed, key, index)
    start = time.perf_counter()
    image = mi.render(scene, spp=spp, seed=seed)
    dr.eval(image)
    dr.sync_thread()
    seconds = time.perf_counter() - start
    return np.array(image, dtype=np.float64)[..., :3], seconds


def set_sample_offset(scene, offset: int) -> None:
    """Make the sensor's Halton sampler start at sample index ``offset`` (no recompilation)."""
    sampler = scene.sensors()[0].sampler()
    if hasattr(sampler, "sample_offset"):
        sampler.sample_offset = offset
        return
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("sampler.sample_offset"))
    params[key] = mi.UInt32(offset)
    params.update()


def warm_up(scene, method: Method | None, base_seed: int, key: str) -> None:
    """Render (and discard) one untimed 1-spp pass so JIT compilation is not timed."""
    render_pass(scene, method, 1, base_seed, key + "/warm-up", 0, 0)


def pass_sizes(spp_from: int, spp_to: int, cap: int) -> list[int]:
    """Passes taking the count from ``spp_from`` to ``spp_to``, none above ``cap`` spp."""
    sizes, spp = [], spp_from
    while spp < spp_to:
        k = min(cap, spp_to - spp)
        sizes.append(k)
        spp += k
    return sizes


def doubling_targets(max_spp: int) -> list[int]:
    """1, 2, 4, ... up to ``max_spp`` (always ending with ``max_spp``)."""
    targets, t = [], 1
    while t < max_spp:
        targets.append(t)
        t *= 2
    return targets + [max_spp]


# ------------------------------------------------------------ progressive

@dataclass
class RenderJob:
    """One progressive render and where it lives on disk."""
    directory: str                    # state, images and manifest.json go here
    key: str                          # seeds derive from (seed, key, pass index)
    settings: dict                    # everything the result depends on (resume key)
    make_scene: Callable[[], object]  # loads the scene (only when work is left)
    width: int
    height: int
    seed: int = 0
    method: Method | None = None
    max_pass_spp: int | None = None   # e.g. 1 for many passes (per-pixel variances)
    save_images: bool = True          # EXR + PNG at every target
    save_variance: bool = False       # also the per-pixel variance of the mean (EXR)
    label: str = ""
    checkpoints: list = field(default_factory=list)

    def cap(self) -> int:
        cap = max(1, MAX_LANES // (self.width * self.height))
        return min(cap, self.max_pass_spp) if self.max_pass_spp else cap


def _save_state(job: RenderJob, acc: Accumulator, done: bool) -> None:
    meta = {"settings": job.settings, "checkpoints": job.checkpoints, "done": done}
    store.write_npz(os.path.join(job.directory, STATE), mean=acc.mean, sq=acc.sq,
                    spp=acc.spp, passes=acc.passes, seconds=acc.seconds,
                    meta=np.array(json.dumps(meta)))
    store.write_json(os.path.join(job.directory, "manifest.json"), meta)


def _load_state(job: RenderJob) -> tuple[Accumulator, bool]:
    """The saved state of ``job`` if it was made with the same settings, else a fresh one."""
    data = store.read_npz(os.path.join(job.directory, STATE))
    if data is not None:
        meta = json.loads(str(data["meta"]))
        if meta["settings"] == json.loads(json.dumps(job.settings)):
            job.checkpoints = meta["checkpoints"]
            acc = Accumulator(data["mean"], data["sq"], int(data["spp"]),
                              int(data["passes"]), float(data["seconds"]))
            return acc, bool(meta["done"])
    if os.path.isdir(job.directory):           # other settings: start over
        shutil.rmtree(job.directory)
    job.checkpoints = []
    return Accumulator.empty(job.height, job.width), False


def _checkpoint(job: RenderJob, acc: Accumulator, stem: str) -> None:
    entry = {"spp": acc.spp, "seconds": acc.seconds, "passes": acc.passes}
    if job.save_images:
        exr, png = store.write_image(os.path.join(job.directory, stem), acc.mean)
        entry.update(exr=os.path.basename(exr), png=os.path.basename(png))
    if job.save_variance:
        store.write_exr(os.path.join(job.directory, stem + "_var.exr"), acc.variance_of_mean())
        entry["var_exr"] = stem + "_var.exr"
    job.checkpoints.append(entry)


def run_progressive(job: RenderJob, targets=(), time_budget: float | None = None,
                    budget_pass_spp: int = 4) -> Accumulator:
    """Render ``job`` up to every sample count in ``targets`` (or for ``time_budget``
    seconds of render time, in passes of ``budget_pass_spp``), resuming saved work.

    Returns the final accumulation; ``job.checkpoints`` lists the written images
    (file names relative to ``job.directory``) with spp, seconds and passes.
    """
    targets = sorted(set(int(t) for t in targets))
    acc, done = _load_state(job)
    have = {c["spp"] for c in job.checkpoints}
    if any(t < acc.spp and t not in have for t in targets):
        shutil.rmtree(job.directory)           # a target below the saved state: start over
        acc, done = _load_state(job)
    todo = [t for t in targets if t > acc.spp or (t == acc.spp and t not in have)]
    if (time_budget is None and not todo) or (time_budget is not None and done):
        return acc

    os.makedirs(job.directory, exist_ok=True)
    scene = job.make_scene()
    warm_up(scene, job.method, job.seed, job.key)
    if time_budget is None:
        _render_targets(job, scene, acc, todo)
    else:
        _render_budget(job, scene, acc, time_budget, min(budget_pass_spp, job.cap()))
    return acc


def _one_pass(job: RenderJob, scene, acc: Accumulator, spp: int) -> None:
    image, seconds = render_pass(scene, job.method, spp, job.seed, job.key,
                                 acc.passes, acc.spp)
    acc.add(image, spp, seconds)


def _render_targets(job: RenderJob, scene, acc: Accumulator, todo: list[int]) -> None:
    last_save = time.monotonic()
    with tqdm(total=todo[-1] - acc.spp, desc=job.label or job.key, unit="spp",
              dynamic_ncols=True, leave=False) as bar:
        for target in todo:
            for k in pass_sizes(acc.spp, target, job.cap()):
                _one_pass(job, scene, acc, k)
                bar.update(k)
                if time.monotonic() - last_save > SAVE_INTERVAL and acc.spp < target:
                    _save_state(job, acc, done=False)
                    last_save = time.monotonic()
            _checkpoint(job, acc, f"spp{target:05d}")
            _save_state(job, acc, done=target == todo[-1])
            last_save = time.monotonic()


def _render_budget(job: RenderJob, scene, acc: Accumulator, budget: float, k: int) -> None:
    with tqdm(total=round(budget, 2), desc=job.label or job.key, unit="s",
              dynamic_ncols=True, leave=False, bar_format="{l_bar}{bar}| {n:.2f}/{total} s") as bar:
        while acc.seconds < budget:
            before = acc.seconds
            _one_pass(job, scene, acc, k)
            bar.update(min(acc.seconds, budget) - min(before, budget))
    _checkpoint(job, acc, "final")
    _save_state(job, acc, done=True)


def read_checkpoint(job: RenderJob, entry: dict, what: str = "exr") -> np.ndarray:
    return store.read_exr(os.path.join(job.directory, entry[what]))


# -------------------------------------------------------------- reference

def settings_key(settings: dict) -> str:
    return hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:12]


def reference(out: str, info: SceneInfo, width: int, height: int, spp: int,
              integrator: str, variant: str, seed: int = 0) -> tuple[np.ndarray, dict]:
    """The high-spp reference image, from ``out/cache`` when it was made with these settings.

    Rendered with next-event estimation + MIS (``integrator``: Mitsuba's
    ``path`` or ``vr_path``), at the scene's max_depth, in passes. The EXR sits
    next to a JSON of the settings it was made with; other settings give another
    file (``reference-<hash of settings>``), so it is re-made when they change.
    """
    settings = {"scene": info.path, "scene_sha256": info.sha256, "width": width,
                "height": height, "spp": spp, "max_depth": info.max_depth,
                "variant": variant, "integrator": integrator, "seed": seed,
                "plugins": plugins_version()}
    stem = os.path.join(out, "cache", f"reference-{settings_key(settings)}")
    meta = store.read_json(stem + ".json")
    if meta is not None and meta.get("settings") == settings and os.path.exists(stem + ".exr"):
        return store.read_exr(stem + ".exr"), meta
    job = RenderJob(stem + ".partial", "reference", settings,
                    lambda: load_scene(info, width, height,
                                       reference_integrator(integrator, info.max_depth)),
                    width, height, seed, save_images=False, label=f"reference {spp} spp")
    acc = run_progressive(job, [spp])
    store.write_image(stem, acc.mean)
    # expected MSE of the reference itself (mean per-pixel variance, from its passes):
    # the floor under every measured MSE
    meta = {"settings": settings, "seconds": acc.seconds, "passes": acc.passes,
            "mse_floor": float(np.mean(acc.variance_of_mean())),
            "exr": os.path.basename(stem) + ".exr", "png": os.path.basename(stem) + ".png"}
    store.write_json(stem + ".json", meta)
    shutil.rmtree(job.directory, ignore_errors=True)
    return acc.mean, meta


# ------------------------------------------------------------ method jobs

def method_job(out: str, experiment: str, info: SceneInfo, method: Method, width: int,
               height: int, variant: str, seed: int, extra_settings: dict | None = None,
               **options) -> RenderJob:
    """The render of ``method`` for ``experiment`` in ``<out>/<experiment>/<method>``.

    ``options`` go to :class:`RenderJob` (``max_pass_spp``, ``save_variance``, ...)
    and, with ``extra_settings``, are part of the settings: changing any of them
    starts the render over.
    """
    from .methods import load_method_scene
    settings = {"experiment": experiment, "method": method.settings(), "scene": info.path,
                "scene_sha256": info.sha256, "width": width, "height": height,
                "max_depth": info.max_depth, "variant": variant, "seed": seed,
                "plugins": plugins_version(), "max_lanes": MAX_LANES, **options,
                **(extra_settings or {})}
    return RenderJob(os.path.join(out, experiment, method.name), method.name, settings,
                     lambda: load_method_scene(info, method, width, height), width, height,
                     seed, method, label=f"{experiment}: {method.name}", **options)
