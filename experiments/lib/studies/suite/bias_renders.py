"""More renders where a cell's bias test is void: one more round for heavy-tailed cells.

A cell whose rare large samples void its bias test (:mod:`.bias_test`: reason
``heavy_tails``: its image sum's variance rests on too few degrees of freedom, the sum is
skewed, or one render's pixel rules it) renders :data:`MORE` times the run's repeats again
at its equal-time count, and is tested again with them beside its equal-time renders (the
same count, the same estimator: only more samples, so that one sample rules less). They are
a declaration of their own over the engine (job keys ``suite-bias/SCENE/METHOD/bias``:
their seeds differ from every other render's), in no comparison: the equal-time errors and
efficiencies read the suite's renders alone. One round, and not for a cell it cannot help
(:func:`hopeless`: an estimator of infinite variance, rough_glass sampled by the cosine):
a cell whose tails stay heavy stays untestable. What the round cost is the suite's "bias
renders" wall time (its timing line); each cell's extra renders are in summary.json
(``bias_extra_renders``).
"""
from __future__ import annotations

import dataclasses
import math

from ... import bias_image
from ...declaration import Budget, Cell, Declaration
from . import declare, precision

#: More renders of a void cell, in multiples of the run's repeats (three cold default runs:
#: 7, 7 and 8 cells rendered again, 2, 1 and 3 of them testable then; 3 x the repeats cleared
#: no more in 6 draws of veach_mis, grazing and environment: docs/methodology.md).
MORE = 2
#: The declaration's name (the first part of its job keys).
NAME = "suite-bias"
#: The budget's name.
BUDGET = "bias"


def hopeless(test) -> bool:
    """Whether a cell's test, read from its renders' own moments, stays void after the
    round however its draws fall: its image sum's skewness, which falls as one over the
    square root of the samples, would still be over twice :data:`.bias_image.MAX_SKEW`,
    or its degrees of freedom, which grow with them, under half :data:`.bias_image.MIN_DOF`
    (the equal-time renders hold almost all of a cell's samples: the round multiplies
    them by about 1 + :data:`MORE`). An estimator of infinite variance (rough glass sampled
    by the cosine: 2 to 9 degrees of freedom, skewness 0.6 to 1) is left as it is."""
    gain = 1.0 + MORE
    return test.variance == "moments" and (
        test.own_skew / math.sqrt(gain) > 2.0 * bias_image.MAX_SKEW or
        test.own_dof * gain < 0.5 * bias_image.MIN_DOF)


def void(tests: dict) -> dict:
    """{scene: [method]} of the cells whose test ``tests`` ({scene: {method: CellBias}})
    found heavy tails, but those the round cannot help (:func:`hopeless`)."""
    out = {}
    for scene, cells in tests.items():
        methods = [m for m, t in cells.items()
                   if t.reason == "heavy_tails" and not hopeless(t)]
        if methods:
            out[scene] = methods
    return out


def declarations(cfg: declare.Settings, plans: list, measured, cells: dict) -> list:
    """One declaration per scene and equal-time count of the void ``cells`` ({scene:
    [method]}): its methods at that count, :data:`MORE` x the run's repeats, the suite's
    per-pixel moments where the suite keeps them."""
    out = []
    boxes = frozenset(sp.name for sp in plans if sp.box)
    for sp in plans:
        by_count = {}
        for name in cells.get(sp.name, ()):
            runs = measured.final(Cell(sp.name, name, declare.TIME))
            by_count.setdefault(runs[0].spp, []).append(name)
        for spp, names in sorted(by_count.items()):
            methods = tuple(m for m in cfg.methods if m.name in names)
            setup = dataclasses.replace(sp.setup(), left_out=())
            out.append(Declaration(
                NAME, methods, (setup,), (Budget.equal_spp(spp, BUDGET),),
                MORE * cfg.repeats, reference_spp=cfg.reference_spp,
                reference_method=cfg.reference_method,
                reference_typical_spp=cfg.reference_typical_spp,
                sample_moments=lambda method, scene: precision.precise(method,
                                                                       scene.name in boxes),
                isolate_failures=True))
    return out


def render(engine, cfg: declare.Settings, plans: list, measured, cells: dict) -> dict:
    """Render the void ``cells`` again (:func:`declarations`); returns {scene: {method:
    [Run]}} of those that rendered (a cell that fails here keeps its first test)."""
    out = {}
    for declaration in declarations(cfg, plans, measured, cells):
        more = engine.run(declaration)
        scene = declaration.scenes[0].name
        for method in declaration.methods:
            cell = Cell(scene, method.name, BUDGET)
            if cell in more.runs:
                out.setdefault(scene, {})[method.name] = more.final(cell)
    return out
