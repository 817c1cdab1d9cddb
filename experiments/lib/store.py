"""The resumable job store: one atomically written entry per finished render job.

:class:`JobStore` keeps one entry per finished render job
(``<root>/<job key>.npz``: the image, the per-pixel sum of squares of its
passes, the job and the result's metadata). A job whose entry exists is
finished; :func:`experiments.lib.execute.execute` skips it.

The file helpers (atomic writes, EXR/PNG/JSON/CSV) are :mod:`.files`.
"""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from .files import read_npz, write_npz
from .jobs import Job, JobResult

#: Directory of the job store under an experiment's ``--out``.
STORE_DIR = "store"


class JobStore:
    """One atomically written ``.npz`` entry per finished job, named by the job's key."""

    def __init__(self, root: str):
        self.root = root

    def path(self, key: str) -> str:
        return os.path.join(self.root, key + ".npz")

    def has(self, key: str) -> bool:
        return os.path.exists(self.path(key))

    def put(self, job: Job, result: JobResult) -> None:
        """Store ``result`` of ``job``."""
        meta = {"job": dataclasses.asdict(job), "result": result.metadata()}
        arrays = {"image": np.asarray(result.image, np.float32),
                  "meta": np.array(json.dumps(meta))}
        if result.sq is not None:
            arrays["sq"] = np.asarray(result.sq, np.float64)
        write_npz(self.path(job.key), **arrays)

    def get(self, key: str) -> JobResult:
        """The :class:`~.jobs.JobResult` stored under ``key`` (KeyError if there is none)."""
        data = read_npz(self.path(key))
        if data is None:
            raise KeyError(f"no finished job '{key}' in {self.root}")
        meta = json.loads(str(data["meta"]))["result"]
        return JobResult(image=data["image"], sq=data.get("sq"), **meta)

    def results(self, jobs) -> list[JobResult]:
        """The results of ``jobs`` (any iterable of :class:`~.jobs.Job`), in order."""
        return [self.get(job.key) for job in jobs]
