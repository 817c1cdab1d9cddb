"""What a study declares to the experiment engine (:mod:`.engine`): plain, frozen values.

* :class:`SceneSetup`: a scene as a study renders it (film, path settings; the methods it
  leaves out and the factor of every equal-time budget it takes, where a scene says so);
* :class:`Budget`: how much every method renders in a cell: equal spp, equal time (at the
  cost per sample an earlier budget measured, scaled per scene by a declared
  :class:`TimeScale` policy) or a ladder of counts;
* :class:`Sweep`: a swept parameter; :class:`Cell`: one comparison point;
* :class:`ReferenceFloor`: the rule that extends a reference too noisy for its comparison;
* :class:`Declaration`: the methods, scenes, budgets, repeats and policies of a study.

Every count the renders take is the engine's to decide from these (:mod:`.counts`); a study
never plans a budget itself.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

from .methods import Depth, Method
from .scenes import SceneInfo


@dataclass(frozen=True)
class SceneSetup:
    """A scene as a study renders it: its file, film and path settings, and a short name
    (its part of the job keys and of the report). ``time_scale``: the factor of every
    equal-time budget on this scene (a suite scene's header ``budget``); ``left_out``: the
    names of the declaration's methods this scene does not render; ``reference_method``: the
    method of this scene's reference (None: the declaration's)."""
    name: str
    info: SceneInfo
    resolution: tuple            # (width, height)
    depth: Depth = Depth()
    time_scale: float = 1.0
    left_out: tuple = ()
    reference_method: Method | None = None


class TimeScale(Protocol):
    """A policy that sets the factor of an equal-time budget's seconds on one scene, once,
    after the budgets before it rendered there: ``policy(engine, declaration, scene,
    planned, reference)`` -> (factor, note), ``reference`` the image of the scene's
    reference at its smallest size (its first :data:`.references.MIN_CHUNKS` chunks: the
    same in every run, whatever the reference's length; the study's own image where it
    brings one) and
    ``planned`` the engine's :class:`~.engine.Planned` so far. The factor replaces the
    scene's own ``time_scale`` (a policy that keeps it returns it, or more); the note says
    why there is no factor of the policy's own ('' when there is)."""

    def __call__(self, engine, declaration: "Declaration", scene: SceneSetup, planned,
                 reference) -> tuple[float, str]: ...


@dataclass(frozen=True)
class Budget:
    """How much every method renders in a cell. Make one with :meth:`equal_spp`,
    :meth:`equal_time` or :meth:`progressive`."""
    name: str
    spp: int = 0                 # equal spp: the count
    seconds: float = 0.0         # equal time: seconds of cost (the clock) per image ...
    after: str = ""              # ... at the cost per sample measured by this budget's renders
    power_of_two: bool = False   # equal time: the count rounded to the nearest power of two
    max_spp: int = 0             # equal time: at most this count (0: no cap)
    scale: TimeScale | None = None   # equal time: the per-scene factor of ``seconds``
    ladder: tuple = ()           # progressive: the counts, each image all samples up to it

    @classmethod
    def equal_spp(cls, spp: int, name: str = "equal-spp") -> "Budget":
        return cls(name, spp=int(spp))

    @classmethod
    def equal_time(cls, seconds: float, after: str = "equal-spp", name: str = "equal-time",
                   power_of_two: bool = False, max_spp: int = 0,
                   scale: TimeScale | None = None) -> "Budget":
        return cls(name, seconds=float(seconds), after=after, power_of_two=power_of_two,
                   max_spp=int(max_spp), scale=scale)

    @classmethod
    def progressive(cls, targets, name: str = "ladder") -> "Budget":
        return cls(name, ladder=tuple(sorted({int(t) for t in targets})))

    @property
    def timed(self) -> bool:
        return self.seconds > 0


@dataclass(frozen=True)
class Sweep:
    """A swept parameter: ``apply(value, scene)`` gives the scene set up at ``value`` (its
    depth, film or file). ``shared_reference``: the parameter changes the estimator, not
    the image it converges to (rr_depth), so every value is measured against the reference
    of the scene as declared."""
    name: str
    values: tuple
    apply: Callable[[object, SceneSetup], SceneSetup]
    shared_reference: bool = False


@dataclass(frozen=True)
class Cell:
    """One comparison point: a scene, a method, a budget and (in a sweep) a value."""
    scene: str
    method: str
    budget: str
    point: object = None


@dataclass(frozen=True)
class ReferenceFloor:
    """A reference whose own expected relMSE (its floor) is over ``share`` of the smallest
    relMSE measured against it, raw, at any budget, is extended once, after the scene's
    budgets rendered, to the samples that bring the share to half of ``share`` by the
    floor's 1/spp law, at most ``max_spp``, or where the reference is cheap the most that
    costs ``max_seconds`` at its first render's time per sample
    (:func:`.counts.reference_cap`, :func:`.counts.reference_spp`)."""
    share: float
    max_spp: int
    max_seconds: float = 0.0


def default_key(declaration: "Declaration", cell: Cell) -> str:
    """``NAME/scene/method/budget[/sweep=value]``: the prefix of a cell's jobs."""
    point = "" if cell.point is None else f"/{declaration.sweep.name}={cell.point}"
    return f"{declaration.name}/{cell.scene}/{cell.method}/{cell.budget}{point}"


@dataclass(frozen=True)
class Declaration:
    """What a study compares. ``key(declaration, cell)`` names a cell's jobs (their seeds
    derive from it; default :func:`default_key`), the repeat and ladder parts appended."""
    name: str
    methods: tuple               # Method values
    scenes: tuple                # SceneSetup values
    budgets: tuple               # Budget values, in the order they render
    repeats: int = 1
    sweep: Sweep | None = None
    reference_spp: int | None = None        # None: the study's --reference-spp
    reference_method: Method | None = None  # None: the study's --reference-method
    reference_typical_spp: int | None = None  # sizes the reference's chunks (None: the study's)
    key: Callable = default_key
    #: (method, spp, repeat) -> the samples per pass of a cell's jobs (0: as many as memory
    #: allows): passes give per-pixel variances from their spread (a job key field)
    pass_spp: Callable | None = None
    #: (method, scene) -> whether a cell's jobs (of budgets without a ladder) keep their
    #: samples' per-pixel second moments (``vr_moments``: every sample its own pass; for
    #: independent samples under a box filter only; a job key field)
    sample_moments: Callable | None = None
    #: method names that render first on every scene (their equal-spp renders come before
    #: any equal-time render: a :class:`TimeScale` policy may need them)
    lead: tuple = ()
    #: a cell whose renders fail is recorded (:attr:`.engine.Measurements.failed`) and left
    #: out, the others go on; False: the error ends the run
    isolate_failures: bool = False
    #: extend a reference too noisy for the comparison (None: the reference as planned)
    reference_floor: ReferenceFloor | None = None

    def __post_init__(self):
        names = [b.name for b in self.budgets]
        for b in self.budgets:
            if b.timed and b.after not in names[:names.index(b.name)]:
                raise ValueError(f"budget '{b.name}' measures its cost per sample on budget "
                                 f"'{b.after}', which must come before it among "
                                 f"{', '.join(names)}")
        if not self.methods or not self.scenes or not self.budgets or self.repeats < 1:
            raise ValueError(f"declaration '{self.name}': give at least one method, scene "
                             f"and budget, and repeats >= 1 (got {self.repeats})")

    def points(self) -> tuple:
        return self.sweep.values if self.sweep else (None,)

    def setup(self, scene: SceneSetup, point) -> SceneSetup:
        return scene if point is None else self.sweep.apply(point, scene)

    def reference_key(self, scene: str, point) -> tuple:
        """The (scene, point) of the reference the scene named ``scene`` at ``point`` is
        measured against (point None where the sweep's points share the scene's reference)."""
        shared = self.sweep is None or self.sweep.shared_reference
        return (scene, None if shared else point)

    def methods_on(self, scene: SceneSetup) -> tuple:
        """The methods ``scene`` renders, those of :attr:`lead` first."""
        mine = [m for m in self.methods if m.name not in scene.left_out]
        lead = [m for name in dict.fromkeys(self.lead) for m in mine if m.name == name]
        return tuple(lead + [m for m in mine if m not in lead])

    def cells(self, budget: Budget) -> list[tuple[Cell, SceneSetup, Method]]:
        return [(Cell(s.name, m.name, budget.name, p), self.setup(s, p), m)
                for s in self.scenes for p in self.points() for m in self.methods
                if m.name not in s.left_out]

    def method(self, name: str) -> Method:
        return next(m for m in self.methods if m.name == name)

    def moments(self, method: Method, scene: SceneSetup) -> bool:
        return bool(self.sample_moments and self.sample_moments(method, scene))
