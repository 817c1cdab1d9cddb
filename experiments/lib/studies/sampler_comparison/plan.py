"""The sampler study's settings and declarations: what a run measures, as the engine plans it.

:class:`Settings` (and the screen-space pass's :class:`ScreenSettings`), built once from the
command line by :func:`.sampler_comparison.study.settings_of`; the two passes as declarations on
the experiment engine (:mod:`experiments.lib.engine`): :func:`declare` (the efficiency
pass: every label at every depth, each count of the ladder an equal-spp budget, a fresh
render) and :func:`declare_screen` (the screen-space pass, which the lab declares too, so
that it finds the same jobs in the store). Their ``key`` functions give the jobs the names
(hence the seeds) they always had: ``samplers/depthD/LABEL/sppNNNNN[/rR]`` and
``samplers/screen-WxH-depthD/LABEL/sppNNNNN[/rR]``. :class:`Planned` is a declaration's jobs
(:meth:`.engine.Engine.jobs` per budget) and reference chunks, which the reports name; the
engine renders them (:meth:`.engine.Engine.run`: every label at one count before the next,
repeat by repeat, so that drifting machine load affects every sampler alike); the
:class:`Pass` protocol every measurement pass follows: declare -> render and measure (the
engine) -> pure analysis -> report.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

from experiments.lib import samplers
from experiments.lib.engine import Budget, Cell, Declaration, Engine, Measurements, SceneSetup
from experiments.lib.jobs import Job
from experiments.lib.methods import Depth, Method, parse_method
from experiments.lib.methods import method_name as _method_name
from experiments.lib.scenes import SceneInfo
from experiments.lib.study import Study

#: The study's registered name: its report section, ``run_all --samplers``, its job keys.
NAME = "samplers"
#: The method every sampler drives, by default.
BASE = "bsdf+nee"

#: The screen-space pass's defaults: small enough for ``make run`` (every FLIP of a
#: 128x128 image costs a few tenths of a CPU second, each native sampler compiles a kernel
#: per count); larger settings through the --screen-* options.
SCREEN_RESOLUTION = "128x128"
SCREEN_COUNTS = (1, 4, 16)
SCREEN_DEPTHS = (2,)
SCREEN_REPEATS = 2
SCREEN_REFERENCE_SPP = 512
#: Native samplers of the default pass besides the baseline: the two with the lowest FLIP
#: in the zsobol sampler's calibration (issue 25); --screen-samplers all adds the others.
SCREEN_NATIVES = ("multijitter", "ldsampler")


def default_screen_labels() -> list[str]:
    """The default pass's labels, from the sampler table: the baseline, the natives of
    :data:`SCREEN_NATIVES`, and every sampler that is not native (bundled, or a
    ``--plugin`` file's) at its last randomization (the table lists them weakest first)."""
    out = [samplers.DEFAULT] + [n for n in SCREEN_NATIVES if n in samplers.names()]
    out += [samplers.get(n).labels()[-1] for n in samplers.names() if not samplers.get(n).native]
    return list(dict.fromkeys(out))


@dataclass(frozen=True)
class ScreenSettings:
    """What the screen-space pass measures."""
    resolution: tuple             # (width, height)
    counts: tuple                 # sample counts, each a fresh render
    depths: tuple                 # max_depth values
    samplers: tuple               # sampler labels
    repeats: int                  # independent randomizations (1 for a deterministic label)
    reference_spp: int
    reference: Method             # the reference's method (independent sampler)


@dataclass(frozen=True)
class Settings:
    """What one run of the study measures (typed; the Namespace stays in :func:`run`)."""
    base: Method                  # the method every sampler drives
    depths: tuple                 # max_depth values
    targets: tuple                # the ladder's requested counts
    samplers: tuple               # sampler labels, from the sampler table
    depth: Depth                  # the scene's path settings (max_depth set per depth)
    scene: str
    resolution: tuple             # (width, height)
    screen: ScreenSettings | None = None     # None: no screen-space pass

    def at(self, max_depth: int) -> Depth:
        return Depth(max_depth, self.depth.rr_depth, self.depth.hide_emitters)


def method(base: Method, sampler: str) -> Method:
    """``base`` driven by the sampler label ``sampler``."""
    return parse_method(_method_name(base, sampler))


def _declaration(name: str, root, cfg: Settings, labels, scenes, counts,
                 repeats: int) -> Declaration:
    """Every label (a method: ``cfg.base`` driven by it) on ``scenes``, each count an
    equal-spp budget named ``sppNNNNN``; jobs named ``root(scene)/LABEL/sppNNNNN``."""
    methods = tuple(method(cfg.base, s) for s in labels)
    label_of = {m.name: s for m, s in zip(methods, labels)}
    if len(label_of) != len(methods):
        raise ValueError(f"sampler labels {', '.join(labels)} name one method twice")
    return Declaration(
        name, methods, tuple(scenes),
        tuple(Budget.equal_spp(n, name=f"spp{n:05d}") for n in counts), repeats,
        key=lambda declaration, cell: f"{root(cell.scene)}/{label_of[cell.method]}/"
                                      f"{cell.budget}")


def declare(cfg: Settings, info: SceneInfo, repeats: int) -> Declaration:
    """The efficiency pass: every label at every depth (a scene ``depthD`` each, the
    timing group ``samplers/depthD``), every count of the ladder a fresh render, against
    the study's reference (--reference-spp of --reference-method)."""
    scenes = [SceneSetup(f"depth{d}", info, tuple(cfg.resolution), cfg.at(d))
              for d in cfg.depths]
    return _declaration(NAME, lambda scene: f"{NAME}/{scene}", cfg, cfg.samplers, scenes,
                        cfg.targets, repeats)


def declare_screen(cfg: Settings, sc: ScreenSettings, info: SceneInfo) -> Declaration:
    """The screen-space pass at ``sc`` (the lab declares it too, at one repeat), named by its resolution (``samplers/screen-128x128-depth2/...``, the timing group
    ``samplers/screen/depth2``), against ``sc.reference_spp`` of ``sc.reference``."""
    width, height = sc.resolution
    scenes = [SceneSetup(f"depth{d}", info, tuple(sc.resolution), cfg.at(d))
              for d in sc.depths]
    declared = _declaration(
        f"{NAME}/screen", lambda scene: f"{NAME}/screen-{width}x{height}-{scene}", cfg,
        sc.samplers, scenes, sc.counts, sc.repeats)
    return replace(declared, reference_spp=sc.reference_spp, reference_method=sc.reference,
                   reference_typical_spp=SCREEN_REFERENCE_SPP)


@dataclass(frozen=True)
class Planned:
    """A declaration's jobs: ``cells`` ``{budget: {cell: [repeat: [job]]}}``
    (:meth:`.engine.Engine.jobs`; one repeat for a deterministic label) and ``refs``
    ``{(scene, point): reference chunks}`` (:meth:`.engine.Engine.reference_jobs`)."""
    declaration: Declaration
    cells: dict
    refs: dict

    def renders(self) -> list[Job]:
        return [j for by_cell in self.cells.values() for reps in by_cell.values()
                for jobs in reps for j in jobs]


def plan(engine: Engine, declaration: Declaration) -> Planned:
    return Planned(declaration, {b.name: engine.jobs(declaration, b)
                                 for b in declaration.budgets},
                   engine.reference_jobs(declaration))


@dataclass
class PassReport:
    blocks: list                  # report blocks, in order
    summary: dict                 # entries of summary.json
    jobs: list                    # the timed jobs (for "render times measured on")


class Pass(Protocol):
    """One measurement pass: declare -> render and measure (the engine) -> analyse (pure)
    -> report."""
    name: str

    def declare(self, st: Study, cfg: Settings) -> Declaration | None: ...

    def measure(self, st: Study, cfg: Settings, planned: Planned,
                measurements: Measurements): ...

    def analyse(self, measured): ...

    def report(self, st: Study, cfg: Settings, planned: Planned, measured,
               result) -> PassReport: ...
