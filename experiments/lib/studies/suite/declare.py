"""The scene suite's declaration: its settings, its scenes as read, one declaration for the engine.

:func:`plan_scenes` reads every scene file (or records why it cannot: the scene is then left
out of the run and listed with its error) with its suite header, film, path settings and
reference; :func:`declaration` declares every readable scene to the experiment engine
(:mod:`experiments.lib.engine`): every method but those a scene's header leaves out, the
repeats, equal spp, then equal time at the cost per sample the equal-spp renders measured
(rounded to a power of two, but a learning method's count, from its pilot; capped), each
scene's header budget and the precision rule (:mod:`.precision`) as the equal-time factor,
the baseline and the timed pair leading every scene, a failing cell recorded and left out,
and a reference too noisy for the comparison extended. The engine decides every count and
renders; :mod:`.measure` turns what it measured into the analysis's numbers.
"""
from __future__ import annotations

import fnmatch
import os
from dataclasses import dataclass, field

import scenes as bundled
from ... import files, references, scenes
from ...declaration import Budget, Declaration, ReferenceFloor, SceneSetup
from ...names import one_line
from ...methods import Depth, Method
from . import analysis, bias_test, precision

NAME = "suite"
ORDER = 50
TITLE = "Scene suite: every method on scenes that each isolate one phenomenon"
#: Largest equal-time sample count (a very cheap scene would otherwise render thousands).
MAX_EQUAL_TIME_SPP = 4096
#: The budgets' names (their part of the job keys).
SPP, TIME = "equal-spp", "equal-time"


@dataclass(frozen=True)
class Settings:
    """The suite's typed settings (the field names :class:`Study` reads, and the suite's)."""
    out: str
    variant: str
    seed: int
    repeats: int
    executor: object
    info: scenes.SceneInfo                  # not used: Study wants one
    depth: Depth
    scenes: tuple                       # scene files
    methods: tuple                      # Method values
    baseline: Method
    spp: int                            # equal-spp count
    time_budget: float                  # seconds of sample work per equal-time render
    forced_resolution: tuple | None     # --resolution; None: each scene's film, <= max_size
    max_size: int
    max_depth: int | None
    rr_depth: int | None
    reference_spp: int
    reference_max_spp: int
    reference_method: Method
    reference_root: str
    user_references: dict               # {scene name: EXR path}
    flip: str = "first"
    best_note: str = ""
    reference_typical_spp: int | None = None     # the default cap (chunk_spp_for)
    resolution: tuple = (1, 1)          # Study's film: unused (every job names its own)
    reference_cache: str | None = None  # Study's reference store (--reference-cache)
    reference_spp_default: int | None = None     # the parser's default --reference-spp
    replay_counts: str | None = None    # an earlier run's --out (--replay-counts)
    min_size: int = 0                   # --min-size: a film's long side scaled up to it
    #: a method whose reference stands in for reference_method's where it is proven
    #: (:mod:`.reference_choice`); None: reference_method's everywhere
    precise_reference: Method | None = None
    #: beyond reference_max_spp, a cheap reference is extended as far as this many seconds
    #: of its rendering go (:func:`.counts.reference_cap`; 0: never)
    reference_max_seconds: float = 0.0


# ------------------------------------------------------------------ the scenes

@dataclass
class ScenePlan:
    """One scene of the suite as read (or why not): its header, film, depth and reference."""
    name: str
    path: str
    info: scenes.SceneInfo | None = None
    error: str = ""
    header: object = None
    header_note: str = ""
    width: int = 0
    height: int = 0
    depth: Depth = Depth()
    ref: references.RefSpec | None = None         # the reference errors are measured against
    bias_ref: references.RefSpec | None = None    # the one the bias test reads (the suite's)
    reference_note: str = ""                      # why ref is the one it is (reference_choice)
    reference_test: object = None                 # the candidate's bias test (bias_test.CellBias)
    user_ref: str | None = None
    box: bool = False                             # every filter a box (scenes.box_filter)
    left_out: dict = field(default_factory=dict)  # {method name: why} (header ``methods``)

    def setup(self) -> SceneSetup:
        """The scene as the engine renders it (the header's budget its equal-time factor)."""
        return SceneSetup(self.name, self.info, (self.width, self.height), self.depth,
                          self.header.budget if self.header is not None else 1.0,
                          tuple(self.left_out or ()), self.ref.method if self.ref else None)


def film(cfg: Settings, info: scenes.SceneInfo, user_exr: str | None) -> tuple[int, int]:
    """The film a scene is rendered at (see the module help)."""
    if cfg.forced_resolution is not None:
        return cfg.forced_resolution
    if user_exr is not None:
        h, w = files.read_exr(user_exr).shape[:2]
        return w, h
    long = max(info.width, info.height)
    scale = min(1.0, cfg.max_size / long)
    if cfg.min_size and long < cfg.min_size:
        scale = min(cfg.min_size, cfg.max_size) / long
    return max(1, round(info.width * scale)), max(1, round(info.height * scale))


def plan_scenes(cfg: Settings) -> list[ScenePlan]:
    plans, names = [], set()
    for path in cfg.scenes:
        name = base = os.path.splitext(os.path.basename(path))[0]
        k = 2
        while name in names:
            name, k = f"{base}-{k}", k + 1
        names.add(name)
        sp = ScenePlan(name, path)
        plans.append(sp)
        try:
            sp.info = scenes.read_scene(path)
            sp.header = bundled.header(path)
        except ValueError as e:
            if sp.info is None:
                sp.error = str(e)
                continue
            sp.header_note = f"its suite header is malformed ({e}): no hypothesis"
        except OSError as e:
            sp.error = one_line(e)
            continue
        sp.user_ref = cfg.user_references.get(sp.info.name)
        try:
            sp.width, sp.height = film(cfg, sp.info, sp.user_ref)
        except (OSError, ValueError, KeyError) as e:
            sp.error = f"its reference {sp.user_ref} cannot be read: {one_line(e)}"
            continue
        if sp.user_ref is not None and cfg.forced_resolution is not None:
            h, w = files.read_exr(sp.user_ref).shape[:2]
            if (w, h) != tuple(cfg.forced_resolution):
                sp.error = (f"its reference {sp.user_ref} is {w}x{h}, not the "
                            f"--resolution {cfg.forced_resolution[0]}x"
                            f"{cfg.forced_resolution[1]}")
                continue
        sp.depth = scenes.effective_depth(sp.info, cfg.max_depth, cfg.rr_depth)
        sp.box = scenes.box_filter(path)
        if sp.user_ref is None:
            chunk = references.chunk_spp_for(sp.width, sp.height, cfg.reference_typical_spp)
            sp.ref = sp.bias_ref = references.RefSpec(sp.info, sp.width, sp.height, sp.depth,
                                                      cfg.reference_method, cfg.variant, chunk)
        sp.left_out = left_out(cfg, sp.header)
    return plans


def left_out(cfg: Settings, header) -> dict:
    """{method name: why} of the run's methods that the scene's header ``methods`` leaves
    out (the baseline is always kept: every efficiency is relative to it)."""
    if header is None or not header.methods:
        return {}
    why = f"not among the scene's header methods ({', '.join(header.methods)})"
    return {m.name: why for m in cfg.methods
            if m.name != cfg.baseline.name and not header.renders(m.name)}


def unmatched(cfg: Settings, header) -> list[str]:
    """The header's ``methods`` patterns that match none of the run's methods."""
    if header is None:
        return []
    return [p for p in header.methods
            if not any(fnmatch.fnmatchcase(m.name, p) for m in cfg.methods)]


def declaration(cfg: Settings, plans: list[ScenePlan]) -> Declaration:
    """Every readable scene of ``plans`` as one declaration (see the module). Job keys: the
    engine's ``suite/SCENE/METHOD/BUDGET``, timed in the group ``suite/SCENE``. A cell whose
    error comes from its pixels' variances renders each job with its
    samples' per-pixel second moments (``sample_moments``: spp - 1 degrees of freedom per
    pixel for its variance, :mod:`.errors`; :func:`.precision.precise`)."""
    live = [sp for sp in plans if not sp.error]
    boxes = frozenset(sp.name for sp in live if sp.box)
    rule = precision.Precision(cfg.baseline, boxes, TIME)
    return Declaration(
        NAME, tuple(cfg.methods), tuple(sp.setup() for sp in live),
        (Budget.equal_spp(cfg.spp, SPP),
         Budget.equal_time(cfg.time_budget, SPP, TIME, power_of_two=True,
                           max_spp=MAX_EQUAL_TIME_SPP, scale=rule)), cfg.repeats,
        reference_spp=cfg.reference_spp, reference_method=cfg.reference_method,
        reference_typical_spp=cfg.reference_typical_spp,
        sample_moments=lambda method, scene: precision.precise(method, scene.name in boxes),
        lead=(cfg.baseline.name,) + analysis.TIMED_PAIR, isolate_failures=True,
        reference_floor=ReferenceFloor(analysis.FLOOR_SHARE, cfg.reference_max_spp,
                                       cfg.reference_max_seconds))


def reference_of(refs: references.ReferenceStore, sp: ScenePlan,
                 smallest: bool = False) -> references.Reference:
    """The scene's reference: the user's EXR, or every chunk the store holds (``smallest``:
    its first :data:`~...references.MIN_CHUNKS`, the same in every run, as the precision
    rule reads it)."""
    if sp.user_ref is not None:
        return references.Reference.from_exr(sp.user_ref)
    return refs.read(sp.ref, references.MIN_CHUNKS * sp.ref.chunk if smallest else None)
