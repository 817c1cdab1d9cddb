"""Which reference each suite scene's errors are measured against, and why.

Every scene has a reference of the suite's ``--reference-method`` (``path``: Mitsuba's own
estimator), whose chunks every cell's bias test reads (:mod:`.bias_test`). Where the run
has a more efficient method (its best sampler's, ``bsdf+nee+zsobol:owen``: several times
``path``'s efficiency at reference counts) and the scene renders it, that method's
reference is the candidate: its own error is a few times smaller at the same samples, which
the comparison of the most efficient methods needs (their errors are the smallest measured
against the reference, :data:`.analysis.FLOOR_SHARE`). It stands in only where it is
proven on the scene: its chunks pass the bias test against ``path``'s chunks (per block
and pooled, at :data:`LEVEL` per scene, not heavy-tailed). Otherwise the scene keeps
``path``'s reference, and the reason is reported. A wrong stand-in would move every error
of the scene; a wrong rejection only keeps the noisier reference, so the level is loose.

:func:`choose` renders both references before the engine runs (the candidate at the
suite's reference count, ``path``'s at :data:`AGAINST_GROWTH` times it, which every cell's
bias test then reads), so that the engine measures, and extends, the chosen one.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ... import bias_image
from ...names import one_line
from . import bias_test
from .declare import ScenePlan, Settings

#: Level of one scene's test of a candidate reference (a rejection keeps ``path``'s).
LEVEL = 0.99
#: ``path``'s reference that a candidate is tested against, and that every cell's bias test
#: reads on its scene: this many times ``--reference-spp`` (at most the extension cap).
AGAINST_GROWTH = 8
#: ... rendered on, doubling, while one pixel of one chunk holds more than
#: :data:`.bias_image.MAX_TERM_SHARE` of its spread (every image test on the scene would be
#: void), as far as the reference's own extension budget goes (``--reference`` settings'
#: ``reference_max_seconds``; at least this many seconds of its rendering in all): where
#: the candidate is not proven, the engine extends ``path``'s reference that far anyway,
#: so rendering it on first costs nothing more there; where it is, a stand-in reference
#: stops the engine extending ``path``'s, which the cells' bias tests still read. At most
#: :data:`AGAINST_DOUBLINGS` times.
AGAINST_SECONDS = 1.5
AGAINST_DOUBLINGS = 4


def top_share(chunks: np.ndarray) -> float:
    """The largest share of a reference's spread over its ``chunks`` (k, H, W, C), per
    channel, that one pixel of one chunk holds (:func:`.bias_image.side_sums`)."""
    sums = bias_image.side_sums([chunks], [1], np.ones(chunks.shape[1:3] + (1,), bool),
                                "pixels")
    return float(np.max(sums.top / np.maximum(sums.terms, 1e-300)))


def _render_on(study, cfg: Settings, refs, spec) -> None:
    """Double ``path``'s reference ``spec`` while :func:`top_share` of its chunks is over
    the gate and the whole costs at most the reference's extension budget (at least
    :data:`AGAINST_SECONDS`; at most :data:`AGAINST_DOUBLINGS` times)."""
    for _ in range(AGAINST_DOUBLINGS):
        if top_share(bias_test.reference_chunks(refs, spec)) <= bias_image.MAX_TERM_SHARE \
                or not _doubled(study, cfg, refs, spec):
            return


def _doubled(study, cfg: Settings, refs, spec) -> bool:
    """Render the reference ``spec`` to twice its samples where the whole then costs at
    most the reference's extension budget (``reference_max_seconds``, at least
    :data:`AGAINST_SECONDS`); whether it did."""
    ref = refs.read(spec, None)
    if 2 * ref.seconds > max(AGAINST_SECONDS, cfg.reference_max_seconds):
        return False
    study.run(study.reference_jobs(spec.info, spec.depth, (spec.width, spec.height),
                                   2 * ref.spp, spec.method, cfg.reference_typical_spp),
              "suite: references")
    return True


def candidate(cfg: Settings, sp: ScenePlan):
    """The candidate reference of ``sp`` (a :class:`~...references.RefSpec`), or None: no
    precise method in the run, the scene's header leaves it out, or a user's reference."""
    method, header = cfg.precise_reference, sp.header
    if method is None or sp.ref is None or sp.user_ref is not None \
            or method.name == sp.ref.method.name:
        return None
    if header is not None and header.methods and not header.renders(method.name):
        return None
    return replace(sp.ref, method=method)


def choose(study, cfg: Settings, plans: list[ScenePlan], refs) -> None:
    """Render every candidate and the ``path`` reference it is tested against, test, and
    set each scene's ``ref`` (its errors' reference) and ``reference_note`` (why)."""
    tried = [(sp, c) for sp in plans if not sp.error for c in [candidate(cfg, sp)] if c]
    if not tried:
        return
    jobs, against_spp = {}, min(cfg.reference_max_spp, AGAINST_GROWTH * cfg.reference_spp)
    for sp, spec in tried:
        for s, spp in ((spec, cfg.reference_spp), (sp.bias_ref, against_spp)):
            jobs[s.key] = study.reference_jobs(s.info, s.depth, (s.width, s.height), spp,
                                               s.method, cfg.reference_typical_spp)
    try:
        study.run([j for js in jobs.values() for j in js], "suite: references")
    except Exception as e:  # noqa: BLE001  (every scene keeps path's, and says why)
        for sp, _ in tried:
            sp.reference_note = f"{cfg.precise_reference}'s reference failed: {one_line(e)}"
        return
    for sp, spec in tried:
        _render_on(study, cfg, refs, sp.bias_ref)
        paths = bias_test.reference_chunks(refs, sp.bias_ref)    # every chunk cached
        test = _tested(study, cfg, refs, spec, paths, sp)
        sp.reference_test = test
        against = f"{sp.bias_ref.method}'s {len(paths) * sp.bias_ref.chunk}-spp reference"
        if test.status == "unbiased":
            sp.ref = spec
            sp.reference_note = f"agrees with {against}: {test_words(test)}"
        else:
            why = ("heavy tails, the test's size is void" if test.reason == "heavy_tails"
                   else test.reason or "it differs")
            sp.reference_note = (f"{spec.method}'s is not proven against {against} ({why}: "
                                 f"{test_words(test)})")


def _tested(study, cfg: Settings, refs, spec, paths: np.ndarray, sp: ScenePlan):
    """The bias test of the candidate ``spec`` against ``path``'s chunks ``paths``; while
    its own chunks' heavy tails void it, the candidate doubled and tested again, as far as
    the reference's extension budget goes (at least :data:`AGAINST_SECONDS`, at most
    :data:`AGAINST_DOUBLINGS` times): an efficient method's few chunks can hold one rare
    bright path (veach_mis' small lights on its glossy plates), and the candidate, once
    adopted, is extended towards its floor anyway. Only a void test renders on, never a
    failed one."""
    for k in range(AGAINST_DOUBLINGS + 1):
        test = bias_test.check_reference(bias_test.reference_chunks(refs, spec), paths,
                                         spec.method, sp.bias_ref.method, sp.box, 1.0 - LEVEL)
        if test.reason != "heavy_tails" or k == AGAINST_DOUBLINGS or \
                not _doubled(study, cfg, refs, spec):
            return test
    return test


def test_words(test: bias_test.CellBias) -> str:
    """The reference test's numbers in words."""
    return (f"smallest block p {test.p_blocks:.2g}, pooled p {test.p_pooled:.2g}, "
            f"detectable {test.detectable:.2%}")
