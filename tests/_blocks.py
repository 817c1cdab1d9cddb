"""Agreement of two renderers, per pixel block and over the image, with its power.

The statistics live in the library, :mod:`experiments.lib.bias` (one implementation for
the tests and the suite's bias test; its docstring says how the tests work and what they
assume). This module adds what only the tests need: :func:`render` (k renders of a scene
dict as an array) and :func:`render_blocks` (those as :class:`Renders`), and re-exports
:func:`agree`, :func:`summarize`, :func:`sidak`, :class:`Agreement`, :class:`Renders` and
the constants. Each side needs at least 4 renders (2 per half).
"""
from __future__ import annotations

import numpy as np

from experiments.lib.bias import (BLOCK, POWER_Z, ROUNDING, VARIANCES, Agreement,  # noqa: F401
                                  Renders, agree, sidak, summarize, varying_pixels)


def render(scene_dict: dict, integrator_dict: dict, seeds, spp: int,
           sampler_dict: dict | None = None) -> np.ndarray:
    """(k, H, W, C) float64: one ``mi.render`` per seed of the scene with this integrator
    (and sampler, if given; else the scene's own)."""
    import mitsuba as mi
    d = {**scene_dict, "integrator": integrator_dict}
    if sampler_dict is not None:
        d["sensor"] = {**d["sensor"], "sampler": sampler_dict}
    scene = mi.load_dict(d)
    return np.stack([np.array(mi.render(scene, spp=spp, seed=int(s)), dtype=np.float64)
                     for s in seeds])


def render_blocks(scene_dict: dict, integrator_dict: dict, sampler_dict: dict | None, seeds,
                  spp: int, block: int = BLOCK) -> Renders:
    """:func:`summarize` of :func:`render` (``sampler_dict`` None: the scene's sampler)."""
    return summarize(render(scene_dict, integrator_dict, seeds, spp, sampler_dict), block)
