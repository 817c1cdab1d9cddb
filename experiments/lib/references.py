"""The reference store: one high-spp render per scene and settings, cached, shared by every
study and every run, and extended in place when more samples are asked for.

A reference is identified by a :class:`RefSpec`: the scene's content hash
(:attr:`~.scenes.SceneInfo.sha256`, which covers every included file), the film size, the
path-length settings, the reference method, the Mitsuba variant, the plugin sources hash
(:func:`.plan.plugins_version`) and the chunk size. It is rendered as *chunks* of
:attr:`RefSpec.chunk_spp` samples each, chunk ``i`` with the seed
``derive_seed(key, "chunk", i)``: neither the seed nor the key of a chunk depends on how
many chunks there are, so asking for more samples renders only the chunks not yet there
(:meth:`ReferenceStore.plan` lists them all, the executor skips those in the store).

Layout under the root (``<out>/references`` unless a study is given another one)::

    <root>/<scene name>-<key>/chunk-00000.npz ...   one job-store entry per chunk
    <root>/<scene name>-<key>/reference.json        how it was made (written atomically)
    <root>/<scene name>-<key>/reference.exr         the mean of its chunks (and .png)

The reference's own expected error, the floor under every error measured against it, is
estimated from the spread of its chunks (:meth:`.jobs.Accumulator.variance_of_mean`): per
pixel and channel, its mean (``mse_floor``), and relative to the image (``relmse_floor``,
``relmse_floor_map``). A user's own EXR (:func:`user_references`, matched by scene name)
has no chunks: its own error is unknown (:attr:`Reference.floor_known` is False) and
nothing is subtracted.

The API a study needs: :meth:`ReferenceStore.plan` (the jobs of a reference of N spp),
:meth:`ReferenceStore.render` (execute them through any executor, then record the JSON),
:meth:`ReferenceStore.read` / :meth:`ReferenceStore.read_jobs` (the image with its own
expected error), :meth:`ReferenceStore.ensure` (plan + render: extends a cached one).
"""
from __future__ import annotations

import dataclasses
import datetime
import hashlib
import json
import math
import os
import re
from dataclasses import dataclass

import numpy as np

from . import files
from .execute import execute
from .jobs import MAX_LANES, Accumulator, Job, derive_seed
from .methods import Depth, Method
from .metrics import RELMSE_EPS
from . import plan
from .scenes import SceneInfo
from .store import JobStore

#: Where the store lives under a study's ``--out`` by default.
REFERENCES_DIR = "references"
#: The fewest samples per pixel of a chunk that :func:`chunk_spp_for` picks (fewer only
#: where a chunk would exceed :data:`MAX_LANES`), and the most.
MIN_AUTO_CHUNK_SPP = 32
MAX_AUTO_CHUNK_SPP = 256
#: Samples (pixels x spp) a chunk of :func:`chunk_spp_for` reaches where it can: on a small
#: film a 32-spp chunk is mostly the per-render cost of tracing and launching the kernel
#: (a 48x36 reference of 2048 spp was 64 renders of 55k samples each).
CHUNK_LANES = 131072          # 2**17
#: Fewest chunks of a reference: their spread estimates its own error.
MIN_CHUNKS = 8
#: How a reference is made, in words (for the JSON beside it).
SEED_RULE = ("chunk i renders chunk_spp samples per pixel with seed derive_seed(key, "
             "'chunk', i) and the method's sampler reseeded per chunk; the reference is the "
             "mean of its chunks, its own expected error the spread of their images")
JSON_NAME = "reference.json"


def chunk_spp_for(width: int, height: int, typical_spp: int | None = None) -> int:
    """The samples per pixel of a chunk at ``width`` x ``height`` (the default of
    :attr:`RefSpec.chunk_spp`): the smallest power of two from :data:`MIN_AUTO_CHUNK_SPP`
    whose chunk has :data:`CHUNK_LANES` samples, at most :data:`MAX_AUTO_CHUNK_SPP`, and
    at most ``typical_spp`` (the count a study asks for by default, not the count asked
    for this time) over :data:`MIN_CHUNKS`, so that its usual reference renders no more
    than it asks for. A function of the film and of a default alone, so that asking for
    more samples extends a reference in place."""
    top = MAX_AUTO_CHUNK_SPP
    if typical_spp is not None:
        top = min(top, 1 << max(0, (typical_spp // MIN_CHUNKS).bit_length() - 1))
    chunk = min(MIN_AUTO_CHUNK_SPP, top)
    while chunk * width * height < CHUNK_LANES and chunk < top:
        chunk *= 2
    return chunk


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "scene"


@dataclass(frozen=True)
class RefSpec:
    """Which reference: a scene at a film size and path-length settings, rendered by a
    method in a variant, in chunks of ``chunk_spp``."""
    info: SceneInfo
    width: int
    height: int
    depth: Depth
    method: Method
    variant: str
    chunk_spp: int | None = None      # None: chunk_spp_for(width, height)

    def __post_init__(self):
        if self.method.deterministic:
            raise ValueError(
                f"reference method '{self.method}' is deterministic (every chunk would be "
                f"the same image), so the spread of its chunks would not estimate its own "
                f"error: use a randomized sampler (e.g. path, or zsobol:owen)")
        if self.chunk_spp is not None and self.chunk_spp < 1:
            raise ValueError(f"chunk_spp must be >= 1, got {self.chunk_spp}")

    @property
    def chunk(self) -> int:
        """Samples per pixel of each chunk."""
        spp = self.chunk_spp or chunk_spp_for(self.width, self.height)
        return max(1, min(spp, MAX_LANES // (self.width * self.height)))

    def fields(self) -> dict:
        """Everything the reference's image depends on (its key is their hash)."""
        return {"scene_sha256": self.info.sha256, "width": self.width, "height": self.height,
                **dataclasses.asdict(self.depth), "method": self.method.name,
                "variant": self.variant, "plugins": plan.plugins_version(),
                "chunk_spp": self.chunk}

    @property
    def key(self) -> str:
        digest = hashlib.sha256(json.dumps(self.fields(), sort_keys=True).encode())
        return f"{_safe(self.info.name)}-{digest.hexdigest()[:12]}"

    def chunks_for(self, spp: int) -> int:
        """Chunks that give at least ``spp`` samples per pixel (at least :data:`MIN_CHUNKS`)."""
        return max(MIN_CHUNKS, math.ceil(spp / self.chunk))


@dataclass
class Reference:
    """A reference image and what is known of its own expected error."""
    image: np.ndarray                      # (H, W, 3) float64
    spp: int
    chunks: int
    seconds: float                         # render (wall) seconds of its chunks
    method: str
    source: str                            # its folder in the store, or the user's EXR
    mse_floor: float | None = None         # None: unknown (a user's EXR)
    relmse_floor: float | None = None
    relmse_floor_map: np.ndarray | None = None   # per pixel and channel

    @property
    def floor_known(self) -> bool:
        return self.mse_floor is not None

    def floor_map(self) -> np.ndarray:
        """The relMSE floor per pixel and channel (zeros where it is unknown)."""
        if self.relmse_floor_map is None:
            return np.zeros_like(self.image)
        return self.relmse_floor_map

    def meta(self) -> dict:
        """The metadata :meth:`.study.Study.reference` returns (floors 0 where unknown)."""
        return {"seconds": self.seconds, "passes": self.chunks, "spp": self.spp,
                "method": self.method, "mse_floor": self.mse_floor or 0.0,
                "relmse_floor": self.relmse_floor or 0.0,
                "relmse_floor_map": self.floor_map(), "floor_known": self.floor_known,
                "source": self.source}

    def describe(self) -> str:
        if not self.floor_known:
            return (f"the user's image {self.source} (its own error is unknown: nothing is "
                    f"subtracted, so every error below includes it)")
        return (f"{self.spp} spp of {self.method} in {self.chunks} chunks, {self.seconds:.1f} s; "
                f"its own expected MSE {self.mse_floor:.2e} (relMSE {self.relmse_floor:.2e}), "
                f"estimated from the spread of its chunks and subtracted")

    @classmethod
    def from_exr(cls, path: str) -> "Reference":
        return cls(files.read_exr(path), 0, 0, 0.0, "user's EXR", path)

    @classmethod
    def from_accumulator(cls, acc: Accumulator, method: str, source: str) -> "Reference":
        var = acc.variance_of_mean()
        rel = var / (acc.mean ** 2 + RELMSE_EPS)
        return cls(acc.mean, acc.spp, acc.passes, acc.cost, method, source,
                   float(np.mean(var)), float(np.mean(rel)), rel)


class ReferenceStore:
    """References under ``root``: chunks in a job store, one folder per :class:`RefSpec`."""

    def __init__(self, root: str):
        self.root = root
        self.store = JobStore(root)

    def directory(self, spec: RefSpec) -> str:
        return os.path.join(self.root, spec.key)

    def plan(self, spec: RefSpec, spp: int) -> list[Job]:
        """The chunks of a reference of at least ``spp`` samples per pixel (chunks already
        in the store included: the executor skips them)."""
        method, d = spec.method, spec.depth
        return [Job(key=f"{spec.key}/chunk-{i:05d}", scene=spec.info.path,
                    scene_sha256=spec.info.sha256, method=method, width=spec.width,
                    height=spec.height, spp=spec.chunk, seed=derive_seed(spec.key, "chunk", i),
                    max_depth=d.max_depth, rr_depth=d.rr_depth, hide_emitters=d.hide_emitters)
                for i in range(spec.chunks_for(spp))]

    def cached(self, spec: RefSpec) -> int:
        """Chunks in the store, counted from the first (a gap ends the count)."""
        n = 0
        while self.store.has(f"{spec.key}/chunk-{n:05d}"):
            n += 1
        return n

    def cached_spp(self, spec: RefSpec) -> int:
        return self.cached(spec) * spec.chunk

    def render(self, specs_and_jobs: list[tuple[RefSpec, list[Job]]], executor=None,
               variant: str | None = None, progress: bool | str = "references") -> int:
        """Render the chunks the store lacks (one executor call for all references, so a
        cluster fans them out), then write each reference's JSON and image: of every chunk
        the store holds (a reference an earlier run, or this one, extended is never
        recorded shorter than it is); returns how many chunks were rendered."""
        jobs = [j for _, js in specs_and_jobs for j in js]
        done = execute(jobs, self.store, executor, progress=progress, variant=variant)
        for spec, js in specs_and_jobs:
            self.record(spec, self.read(spec, None) if self.cached(spec) > len(js) else
                        self.read_jobs(js, spec.method.name))
        return done

    def ensure(self, spec: RefSpec, spp: int, executor=None, progress=False) -> int:
        """Make the reference of ``spec`` at least ``spp`` samples per pixel; returns how
        many chunks were rendered (0 when the store has them all)."""
        return self.render([(spec, self.plan(spec, spp))], executor, spec.variant, progress)

    def read_jobs(self, jobs: list[Job], method: str | None = None) -> Reference:
        """The reference that ``jobs`` (chunks from :meth:`plan`, all in the store) make."""
        acc = None
        for job in jobs:
            result = self.store.get(job.key)
            if acc is None:
                acc = Accumulator.empty(*result.image.shape[:2])
            acc.add_result(result)
        if acc is None:
            raise ValueError("a reference needs at least one chunk")
        return Reference.from_accumulator(acc, method or jobs[0].method.name,
                                          os.path.dirname(self.store.path(jobs[0].key)))

    def read(self, spec: RefSpec, spp: int | None = None) -> Reference:
        """The reference of ``spec`` from its first chunks: enough for ``spp`` samples per
        pixel, or every cached one (None). KeyError when the store lacks them."""
        n = self.cached(spec) if spp is None else spec.chunks_for(spp)
        if n == 0 or self.cached(spec) < n:
            raise KeyError(f"reference {spec.key} has {self.cached(spec)} chunks in "
                           f"{self.root}, {n or 'some'} needed")
        return self.read_jobs(self.plan(spec, n * spec.chunk)[:n], spec.method.name)

    def record(self, spec: RefSpec, ref: Reference) -> str:
        """Write the JSON that says how the reference was made, and its image."""
        directory = self.directory(spec)
        previous = files.read_json(os.path.join(directory, JSON_NAME), {}) or {}
        now = datetime.datetime.now().isoformat(timespec="seconds")
        info = {"key": spec.key, "key_fields": spec.fields(), "scene": spec.info.path,
                "scene_name": spec.info.name, "resolution": f"{spec.width}x{spec.height}",
                "depth": dataclasses.asdict(spec.depth), "method": spec.method.name,
                "variant": spec.variant, "chunk_spp": spec.chunk, "chunks": ref.chunks,
                "spp": ref.spp, "render_seconds": round(ref.seconds, 3),
                "mse_floor": ref.mse_floor, "relmse_floor": ref.relmse_floor,
                "seed_rule": SEED_RULE, "created": previous.get("created", now),
                "updated": now}
        files.write_image(os.path.join(directory, "reference"), ref.image)
        path = os.path.join(directory, JSON_NAME)
        files.write_json(path, info)
        return path


# ------------------------------------------------------------------ a user's references

def user_references(directory: str) -> dict[str, str]:
    """``{scene name: EXR path}`` of the ``*.exr`` files in ``directory`` (ValueError if it
    is not a folder or holds none)."""
    if not os.path.isdir(directory):
        raise ValueError(f"--references '{directory}' is not a folder")
    found = {os.path.splitext(n)[0]: os.path.join(directory, n)
             for n in sorted(os.listdir(directory)) if n.lower().endswith(".exr")}
    if not found:
        raise ValueError(f"--references '{directory}' holds no .exr file (name them after "
                         f"the scenes: <scene name>.exr)")
    return found
