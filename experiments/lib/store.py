"""The resumable job store: one atomically written entry per finished render job.

:class:`JobStore` keeps one entry per finished render job
(``<root>/<job key>.npz``: the image, the per-pixel sum of squares of its
passes, for a job with its samples' moments the sums of their cubes and fourth powers,
the job and the result's metadata). A job whose entry exists is
finished; :func:`experiments.lib.execute.execute` skips it.

The file helpers (atomic writes, EXR/PNG/JSON/CSV) are :mod:`.files`.
"""
from __future__ import annotations

import dataclasses
import json
import os
from collections import OrderedDict

import numpy as np

from .files import read_npz, write_npz
from .jobs import Job, JobResult

#: Directory of the job store under an experiment's ``--out``.
STORE_DIR = "store"
#: Bytes of images a store keeps after reading them: a study reads each result several
#: times (a first measurement, then the final one; references chunk by chunk), and an
#: entry never changes once written (its key hashes all it depends on).
READ_CACHE_BYTES = 64 * 2**20


class ReplayError(LookupError):
    """An earlier run (``--replay-counts``) lacks a job whose count this run replays."""


class JobStore:
    """One atomically written ``.npz`` entry per finished job, named by the job's key."""

    def __init__(self, root: str):
        self.root = root
        self._read: OrderedDict = OrderedDict()      # key -> (JobResult, bytes)
        self._read_bytes = 0

    def path(self, key: str) -> str:
        return os.path.join(self.root, key + ".npz")

    def has(self, key: str) -> bool:
        return os.path.exists(self.path(key))

    def put(self, job: Job, result: JobResult) -> None:
        """Store ``result`` of ``job``."""
        meta = {"job": dataclasses.asdict(job), "result": result.metadata()}
        arrays = {"image": np.asarray(result.image, np.float32),
                  "meta": np.array(json.dumps(meta))}
        for name in ("sq", "cubes", "fourths", "variance_var"):
            if getattr(result, name) is not None:
                arrays[name] = np.asarray(getattr(result, name), np.float64)
        write_npz(self.path(job.key), **arrays)
        self._forget(job.key)

    def get(self, key: str) -> JobResult:
        """The :class:`~.jobs.JobResult` stored under ``key`` (KeyError if there is none);
        its arrays are read-only (shared with later reads of the same entry)."""
        if key in self._read:
            self._read.move_to_end(key)
            return self._read[key][0]
        data = read_npz(self.path(key))
        if data is None:
            raise KeyError(f"no finished job '{key}' in {self.root}")
        meta = json.loads(str(data["meta"]))["result"]
        if "seconds" in meta:                   # entries stored before the field's rename
            meta["wall_seconds"] = meta.pop("seconds")
        result = JobResult(image=data["image"], sq=data.get("sq"), cubes=data.get("cubes"),
                           fourths=data.get("fourths"), variance_var=data.get("variance_var"),
                           **meta)
        size = 0
        for array in (result.image, result.sq, result.cubes, result.fourths,
                      result.variance_var):
            if isinstance(array, np.ndarray):
                array.flags.writeable = False
                size += array.nbytes
        self._read[key] = (result, size)
        self._read_bytes += size
        while self._read_bytes > READ_CACHE_BYTES and len(self._read) > 1:
            self._forget(next(iter(self._read)))
        return result

    def _forget(self, key: str) -> None:
        entry = self._read.pop(key, None)
        if entry is not None:
            self._read_bytes -= entry[1]

    def counts(self) -> dict[str, int]:
        """{job name: samples per pixel} of every finished job (the name: the key without
        its hash, which changes with the plugin sources), for ``--replay-counts``."""
        if not os.path.isdir(self.root):
            raise FileNotFoundError(f"no job store at '{self.root}': give the --out of an "
                                    f"earlier run (its store/ folder holds the jobs)")
        out = {}
        for directory, _, names in os.walk(self.root):
            for name in names:
                if name.endswith(".npz"):
                    key = os.path.relpath(os.path.join(directory, name), self.root)[:-4]
                    job = json.loads(str(read_npz(self.path(key))["meta"]))["job"]
                    out[key.rsplit("-", 1)[0]] = int(job["spp"])
        return out

    def results(self, jobs) -> list[JobResult]:
        """The results of ``jobs`` (any iterable of :class:`~.jobs.Job`), in order."""
        return [self.get(job.key) for job in jobs]
