"""The engine's references: planned in the shared reference store, rendered, extended.

Every scene (at every sweep point that changes its image) is measured against a reference
of its own reference method, else the declaration's (:mod:`.references`: keyed by the
scene's content, cached and shared by every study and run). :func:`render` renders what
the store lacks, scene by scene where a failure must not end the run; :func:`extend`
extends a reference too noisy for its comparison, as the declaration's
:class:`~.declaration.ReferenceFloor` says.
"""
from __future__ import annotations

import numpy as np

from . import counts
from .declaration import Declaration
from .names import one_line


def jobs(study, declaration: Declaration, scenes=None, spp: dict | None = None) -> dict:
    """{(scene, point): the chunks of its reference} (``scenes``: [(scene, point)], default
    every one; ``spp``: {key: samples} where more than the declaration's are wanted)."""
    out = {}
    for scene, point in scenes or [(s, p) for s in declaration.scenes
                                   for p in declaration.points()]:
        key = declaration.reference_key(scene.name, point)
        if key in out:
            continue
        setup = scene if key[1] is None else declaration.setup(scene, point)
        out[key] = study.reference_jobs(
            setup.info, setup.depth, setup.resolution,
            (spp or {}).get(key) or declaration.reference_spp,
            setup.reference_method or declaration.reference_method,
            declaration.reference_typical_spp)
    return out


def render(study, declaration: Declaration, unit, given: dict, errors: dict, refs: dict
           ) -> dict:
    """Render the references of ``unit`` ([(scene, point)]) the store lacks, in one
    executor call, and read them into ``refs`` (every cached chunk where the declaration
    may extend them); the study's own images for the keys of ``given``. Returns {key:
    chunks}. Where failures are isolated, a reference that fails to render is its scene's
    error (in ``errors``), the others go on."""
    chunks = {k: v for k, v in jobs(study, declaration, unit).items() if k not in given}
    refs.update((k, v) for k, v in given.items())
    try:
        study.run([j for js in chunks.values() for j in js], f"{declaration.name}: references")
    except Exception:  # noqa: BLE001  (per scene below, or the run ends)
        if not declaration.isolate_failures:
            raise
        for key, js in list(chunks.items()):
            try:
                study.run(js, f"{declaration.name}: {key[0]} reference")
            except Exception as e:  # noqa: BLE001  (the scene's error; the others go on)
                errors[key] = f"its reference failed to render: {one_line(e)}"
                del chunks[key]
    for key, js in chunks.items():
        refs[key] = study.reference(js, every_cached=declaration.reference_floor is not None)
    return chunks


def extend(study, declaration: Declaration, chunks: dict, refs: dict, measured) -> None:
    """Extend every reference of ``chunks`` whose own expected relMSE is too large a share
    of the smallest relMSE ``measured`` against it (the declaration's
    :class:`~.declaration.ReferenceFloor`: :func:`.counts.reference_spp`), once, in one
    executor call; ``refs`` and ``chunks`` then hold the extended ones."""
    rule, wanted = declaration.reference_floor, {}
    for key in chunks:
        meta = refs[key][1]
        errors = [float(np.mean([r.relmse for r in measured.final(c)]))
                  for c in measured.runs if measured.reference_key(c) == key]
        share = counts.floor_share(meta["relmse_floor"], errors)
        spp = counts.reference_spp(share, rule.share, meta["spp"], counts.reference_cap(
            meta["spp"], meta["seconds"], rule.max_spp, rule.max_seconds, share, rule.share))
        if meta["floor_known"] and spp > meta["spp"]:
            wanted[key] = spp
    if not wanted:
        return
    scenes = [(s, p) for s in declaration.scenes for p in declaration.points()
              if declaration.reference_key(s.name, p) in wanted]
    more = jobs(study, declaration, scenes, wanted)
    study.run([j for js in more.values() for j in js], f"{declaration.name}: references extended")
    for key, js in more.items():
        chunks[key] = js
        refs[key] = study.reference(js, every_cached=True)
