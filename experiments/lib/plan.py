"""Render jobs planned as plain data: what to render, with which seed and sample offset.

Data flows one way: plan -> execute -> store -> analyse -> present. The job
types live in :mod:`.jobs`; this module fixes their fields: :func:`make_job`
gives a job its key (a hash of everything its image depends on),
:func:`ladder` plans a progressive render as one job per stretch between two
sample counts: samplers that reseed get a new seed per stretch, samplers that
continue one sequence (``halton``: :attr:`.samplers.SamplerSpec.continues_sequence`)
keep their seed and continue the sequence (``sample_offset`` = samples already
taken), so the stretches together are exactly one render of all their samples.
The analysis adds them up (:func:`.jobs.accumulate` of their results,
:meth:`.study.Study.accumulate`).
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os

import integrators
import mitsuba as mi

from .jobs import Job, derive_seed
from .methods import Depth, Method
from .scenes import SceneInfo


@functools.lru_cache(maxsize=None)
def plugins_version() -> str:
    """Hash of the plugin sources (``integrators/*.py``) and Mitsuba's version.

    Part of every render job's key, so renders made with other plugin code are
    made again rather than reused. Read once per process (the code it imported: a
    suite run makes thousands of keys, and reading the files each time took 5 s).
    """
    digest = hashlib.sha256(mi.__version__.encode())
    directory = os.path.dirname(os.path.abspath(integrators.__file__))
    for name in sorted(os.listdir(directory)):
        if name.endswith(".py"):
            with open(os.path.join(directory, name), "rb") as f:
                digest.update(name.encode() + f.read())
    return digest.hexdigest()[:16]


def check_terminates(method: Method, depth: Depth) -> None:
    """A deterministic sampler (plain Halton, zsobol:none) gives the point 0 in every
    dimension to the first sample of every pixel; Russian roulette's survival test
    (``u < p``, as Mitsuba's ``path``) then never ends that path, which with an unbounded
    ``max_depth`` in a closed scene loops forever. Refuse the combination with the reason,
    instead of a render that never finishes."""
    if method.deterministic and depth.max_depth in (None, -1):
        raise ValueError(
            f"method '{method}' uses a deterministic sampler at unbounded max_depth "
            f"({'the integrator default' if depth.max_depth is None else -1}): its first "
            f"sample is 0 in every dimension, so Russian roulette never ends that path and "
            f"a closed scene never finishes rendering; give a bounded --max-depth (e.g. 8) "
            f"or a randomized sampler (e.g. {method.sampler}:owen)")


def job_name(prefix: str) -> str:
    """The name part of a job key: its prefix, spelt safely as a path (the key appends a
    hash of everything the image depends on)."""
    return prefix.replace(":", "-").replace("+", "_")


def make_job(prefix: str, info: SceneInfo, method: Method, width: int, height: int, spp: int,
             seed: int, depth: Depth, variant: str, sample_offset: int = 0, pass_spp: int = 0,
             timing_group: str | None = None, sequence_spp: int = 0,
             sample_moments: bool = False, pilot: bool = False) -> Job:
    """A :class:`Job` whose key is ``prefix`` + a hash of everything its image depends on
    (the plugin sources and the variant included; the method by its name; the sequence's
    length only where a sampler needs it and ``sample_moments`` only where set, so other
    keys are as they always were).

    ValueError for a deterministic sampler at unbounded depth (:func:`check_terminates`).
    """
    check_terminates(method, depth)
    fields = dict(scene=info.path, scene_sha256=info.sha256, method=method.name, width=width,
                  height=height, spp=spp, seed=seed, sample_offset=sample_offset,
                  pass_spp=pass_spp, **dataclasses.asdict(depth))
    if sequence_spp:
        fields["sequence_spp"] = sequence_spp
    if sample_moments:
        fields["sample_moments"] = True
    digest = hashlib.sha256(json.dumps([fields, variant, plugins_version()],
                                       sort_keys=True).encode()).hexdigest()[:12]
    safe = job_name(prefix)
    fields["method"] = method
    return Job(key=f"{safe}-{digest}", timing_group=timing_group, pilot=pilot, **fields)


def ladder(prefix: str, info: SceneInfo, method: Method, width: int, height: int,
           targets, base_seed: int, depth: Depth, variant: str, pass_spp: int = 0,
           timing_group: str | None = None) -> list[Job]:
    """Jobs rendering ``method`` progressively to every sample count in ``targets``.

    Job ``i`` renders the samples between targets ``i-1`` and ``i``; the
    images at each target accumulate the results of the first jobs (:func:`.jobs.accumulate`).
    """
    continues = method.continues_sequence
    targets = sorted(set(int(t) for t in targets))
    total = targets[-1] if continues and method.sampler_spec.sequence_length else 0
    jobs, done = [], 0
    for i, target in enumerate(targets):
        seed = derive_seed(base_seed, prefix, 0 if continues else i)
        jobs.append(make_job(f"{prefix}/spp{done:05d}-{target:05d}", info, method, width,
                             height, target - done, seed, depth, variant,
                             sample_offset=done if continues else 0,
                             pass_spp=pass_spp, timing_group=timing_group,
                             sequence_spp=total))
        done = target
    return jobs


def doubling_targets(max_spp: int, factor: int = 2) -> list[int]:
    """1, 2, 4, ... (or another factor) up to ``max_spp`` (always ending with ``max_spp``)."""
    targets, t = [], 1
    while t < max_spp:
        targets.append(t)
        t *= factor
    return targets + [max_spp]
