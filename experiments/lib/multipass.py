"""Methods that render their own passes: the executor's protocol and what it makes of them.

:class:`MultiPass` is the protocol (a method that learns between passes, or combines
them: ``vr_guided_path``); :func:`replaced_rest` checks the passes a method's hook
returns; :func:`stated` gives the image its ``combine`` returned and its per-pixel
variance, :func:`stated_tails` says how sure that variance is (both measurement,
untimed). The executor (:mod:`.execute`) renders the passes.
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from .jobs import variance_of_variance


@runtime_checkable
class MultiPass(Protocol):
    """An integrator that renders its image in several passes of its own (a method that
    learns between passes, or combines them), declared by having these three methods. The
    executor renders each pass with ``mi.render`` and calls the hooks between them; the
    clock (:mod:`.clock`) counts the kernels of every pass and the CPU time of the hooks.

    * ``pass_schedule(spp, pixels)``: the samples per pixel of each pass for a job of
      ``spp`` on a film of ``pixels`` (a function of the counts alone, never of time),
      summing to ``spp``; a pass over the job's lane cap (:data:`.jobs.MAX_LANES`) is
      rendered in several renders and averaged (:meth:`.jobs.Job.split_lanes`);
    * ``after_pass(index, image, spp)``: host work after pass ``index`` (learning from it;
      ``image`` the pass's mean, every channel, as a numpy (H, W, C) float64 array, read
      on the host before the hook's clock starts, as every method's image is read); it may
      return the passes that follow anew (a list of samples per pixel with the same sum as
      the ones it replaces: e.g. a method whose learning stopped renders its rest in one
      pass), None to keep them;
    * ``combine(images, spps)``: the job's image from every pass's (a numpy (H, W, 3)
      array; e.g. a weighted mean);
    * optionally ``combined_variance()``: the per-pixel variance (H, W, 3) of what
      ``combine`` returned, which the per-pixel errors then use (without it the job is one
      pass: its errors come from its repeats against the reference);
    * optionally ``combined_moments()``: per group of independent samples that ``combine``
      weighted, (weight: a scalar or per pixel (H, W, 1), samples per pixel, the per-pixel
      means of x, x^2, x^3, x^4), from which :func:`stated_tails` says how sure that
      variance is.

    Passes are rendered with seeds ``derive_seed(job.seed, index)`` (a pass split for
    memory: ``derive_seed(job.seed, index, part)`` after its first render)."""

    def pass_schedule(self, spp: int, pixels: int) -> list: ...

    def after_pass(self, index: int, image, spp: int) -> list | None: ...

    def combine(self, images: list, spps: list): ...


def replaced_rest(schedule: list, index: int, rest: list) -> list:
    """``schedule`` with the passes after ``index`` replaced by ``rest``, which a
    :class:`MultiPass` method's ``after_pass`` returned: refused unless it renders the
    same samples (a method must not change its job's count)."""
    if sum(rest) != sum(schedule[index + 1:]) or any(n < 1 for n in rest):
        raise ValueError(f"after_pass({index}) returned the passes {list(rest)} "
                         f"({sum(rest)} spp) for {list(schedule[index + 1:])} "
                         f"({sum(schedule[index + 1:])} spp): the rest must keep its samples")
    return list(schedule[:index + 1]) + list(rest)


def stated(integrator, image, done: int) -> tuple:
    """(image, sq, passes) of a :class:`MultiPass` method's job of ``done`` samples per
    pixel whose ``combine`` returned ``image``. Its passes are not samples of one
    estimator (a guide's untrained and trained passes): one pass of the combined image, so
    that no per-pixel variance comes from their spread, unless the method states its own
    (``combined_variance``), written as every sample a pass of sq so that
    :meth:`.jobs.Accumulator.variance_of_mean` returns it: sq = n mean^2 + V n (n - 1).
    Measurement, not the method's work: the executor does not count its time."""
    mean = np.asarray(image, dtype=np.float64)
    sq, passes = done * mean * mean, 1
    variance = getattr(integrator, "combined_variance", None)
    if variance is not None and done > 1:
        passes = done
        sq = sq + np.asarray(variance(), np.float64) * done * (done - 1)
    return mean, sq, passes


def stated_tails(integrator) -> np.ndarray | None:
    """How sure the variance that a :class:`MultiPass` method states after :func:`stated`
    is, where it also states its groups' moments (``combined_moments``: weight, samples
    and the means of x, x^2, x^3, x^4 per group of independent samples): the sum over the
    groups of weight^4 x :func:`.jobs.variance_of_variance`; None otherwise. Measurement,
    not the method's work: the executor does not count its time."""
    moments = getattr(integrator, "combined_moments", None)
    groups = moments() if moments is not None and hasattr(integrator, "combined_variance") \
        else []
    if not groups or any(n < 2 for _, n, *_ in groups):
        return None
    return sum(w ** 4 * variance_of_variance(m1, m2, m3, m4, n)
               for w, n, m1, m2, m3, m4 in groups)
