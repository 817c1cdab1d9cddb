"""What every stability sweep shares: the protocol, the declaration's shape, the context,
outliers.

A sweep (one module each, listed in :data:`experiments.lib.sweeps.REGISTRY`)
is an object with four steps, data flowing one way::

    declare(ctx)           -> Declaration | None  what it renders, on the experiment engine
                                                 (:mod:`..engine`; None: nothing to render)
    measure(ctx, measured) -> measurements       numbers from the engine's Measurements
    analyse(measured)      -> result dataclass   pure: numbers in, numbers and verdicts out
    report(ctx, result)    -> SweepReport        charts, tables, prose (the words: each
                                                 module's sentences(result), templates)

Each sweep point is a scene variant or a depth (the declaration's :class:`~..engine.Sweep`),
rendered per method and repeat, with the reference of that point; the engine plans,
renders (resuming from the stores), costs with the one clock and measures.
``analyse`` takes and returns plain numbers, so tests feed it synthetic
measurements whose conclusion is known (``tests/test_sweeps.py``); each module's
``sentences(result)`` turns a result into words (:func:`..prose.say` over its templates).

Every comparison is measured over R independent randomizations (``--repeats``):
each (point, method) has R runs whose seeds derive from the repeat index
(job key prefix ``.../r{r}``; repeat 0 keeps the prefix of a single run, so
results stored before repeats existed are reused; a deterministic method renders once,
which stands for every repeat). Errors are means over the
repeats with a 95% interval (:mod:`experiments.lib.stats`); a breakdown or a
difference is claimed only where the interval says so (:func:`exceeds`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .. import metrics, report, stats
from .. import engine
from ..engine import Budget, Cell, Declaration, Engine, Measurements, SceneSetup
from ..methods import Depth, parse_method
from ..scenes import Needs
from ..study import Study, StudySettings

NAME = "stability"
#: relMSE ratio at which a method counts as broken down against the robust one.
BREAK_FACTOR = 10.0
g = stats.g


@dataclass(frozen=True)
class Config:
    exponents: tuple
    light_sizes: tuple
    angles: tuple             # incidence angles (degrees) of the grazing sweep
    grazing_exponents: tuple
    grazing_samples: int
    halton_spp: int


NORMAL = Config((1, 10, 100, 1000, 10000), (2, 0.2, 0.05, 0.02),
                (0, 60, 85, 88, 89), (10, 100, 1000), 2 ** 16, 64)
QUICK = Config((1, 10000), (2, 0.02), (0, 60, 89), (10, 1000), 2 ** 12, 2)


@dataclass(frozen=True)
class StabilitySettings(StudySettings):
    """The stability study's typed settings (made from the command line in one place,
    :func:`experiments.lib.studies.stability.settings_from`)."""
    spp: int                  # the budget per point and method, split over the repeats
    sweeps: tuple             # names of the sweeps to run, in order
    quick: bool
    config: Config            # the sweep points (NORMAL, or QUICK with --quick)


class Skip(Exception):
    """The scene lacks what a sweep varies (its message: the missing parameter(s))."""


@dataclass
class SweepReport:
    blocks: list[dict]
    notes: list[str]                                  # closing-note sentences
    rows: list[dict] = field(default_factory=list)    # summary.json rows (with *_lo/_hi)


class Sweep(Protocol):
    name: str
    needs: Needs                      # what it needs of the scene (checked before declare)

    def declare(self, ctx: "Context") -> Declaration | None: ...

    def measure(self, ctx: "Context", measured: Measurements | None): ...

    def analyse(self, measured): ...

    def report(self, ctx: "Context", result) -> SweepReport: ...


# ------------------------------------------------------------------ helpers

def onset(quantity: str, value, fmt) -> str:
    """'from <quantity> <value>' for the first sweep point where a condition holds, or
    'nowhere in the sweep' when it never does."""
    if value is None:
        return "nowhere in the sweep"
    return " ".join(p for p in ("from", quantity, fmt(value)) if p)


def exceeds(est: stats.Estimate, threshold: float) -> bool:
    """Is the quantity above ``threshold``? With an interval: its lower bound is; with
    one run (no interval): the point estimate is (the prose then says so)."""
    return est.lo > threshold if est.known else est.value > threshold


def below(est: stats.Estimate, threshold: float) -> bool:
    """Is the quantity below ``threshold`` (upper bound, or the point estimate)?"""
    return est.hi < threshold if est.known else est.value < threshold


def basis(repeats: int) -> str:
    """How the onsets of a sweep were decided, for the prose."""
    if repeats > 1:
        return (f"decided on the {stats.LEVEL:.0%} interval over {repeats} repeats")
    return "one run: no interval, decided on the point estimate alone"


def mean_interval(values) -> stats.Estimate:
    """:func:`stats.mean_interval`, but an all-zero or empty list gives 0 (no log)."""
    values = [float(v) for v in values]
    if values and all(v == 0 for v in values):
        return stats.Estimate(0.0, 0.0, 0.0, len(values))
    return stats.mean_interval(values)


def ratio(a, b) -> stats.Estimate:
    """mean(a) / mean(b) over repeats, with its interval."""
    return stats.ratio_interval([list(a)], [list(b)])


def per_repeat(spp: int, repeats: int) -> int:
    """Samples per pixel of each of ``repeats`` runs sharing a budget of ``spp``."""
    return max(1, round(spp / repeats))


def budget(spp: int, repeats: int) -> str:
    """'32 spp' or '16 spp x 2 independent repeats (budget split over the repeats)'."""
    if repeats == 1:
        return f"{spp} spp (one run)"
    return f"{spp} spp x {repeats} independent repeats (the --spp budget split over them)"


def label(method: str) -> str:
    return method.replace("+nee", " + NEE").replace("+adaptive", " + adaptive")


class Outliers:
    """Largest pixel, fireflies and non-finite pixels per method over every sweep render."""

    def __init__(self):
        self.rows: dict[str, dict] = {}

    def add(self, label: str, image, reference) -> dict:
        o = metrics.outliers(image, reference)
        r = self.rows.setdefault(label, {"images": 0, "max": 0.0, "fireflies": 0,
                                         "nonfinite": 0})
        r["images"] += 1
        r["max"] = max(r["max"], o["max"])
        r["fireflies"] += o["fireflies"]
        r["nonfinite"] += o["nonfinite"]
        return o

    def report(self, out: str) -> SweepReport:
        rows = [[k, v["images"], g(v["max"]), v["fireflies"], v["nonfinite"]]
                for k, v in self.rows.items()]
        total_nan = sum(v["nonfinite"] for v in self.rows.values())
        worst = max(self.rows.items(), key=lambda kv: kv[1]["fireflies"], default=None)
        sentence = (f"Outliers over all sweep renders: {total_nan} NaN/Inf pixels in total"
                    + (f"; most fireflies: {worst[0]} ({worst[1]['fireflies']} in "
                       f"{worst[1]['images']} images, largest pixel {g(worst[1]['max'])})"
                       if worst else "") + ".")
        table = report.write_table(
            out, f"{NAME}/outliers", ["method", "images", "largest pixel", "fireflies",
                                      "NaN/Inf pixels"], rows,
            f"6. Outliers per method over every sweep render (every repeat). Firefly: a pixel "
            f"whose luminance error exceeds the image's median error by "
            f"{metrics.FIREFLY_MADS:g} median absolute deviations. NaN/Inf: non-finite pixels "
            f"of the accumulated image (one non-finite sample makes its pixel non-finite).")
        return SweepReport([table, report.text(sentence)], [sentence])


@dataclass(frozen=True)
class Run:
    """One repeat of one method at one point, as numbers."""
    relmse: float            # whole image
    relmse_mask: float       # on the mask's pixels (the whole image without a mask)
    level: float             # mean of the image / mean of the reference (on the mask)
    seconds: float           # warm render time
    max: float = 0.0         # largest pixel value
    fireflies: int = 0
    nonfinite: int = 0       # NaN/Inf pixels


def worst(runs: list[Run]) -> tuple:
    """(largest pixel, fireflies, NaN/Inf pixels) over the repeats of one point."""
    return (max(r.max for r in runs), sum(r.fireflies for r in runs),
            sum(r.nonfinite for r in runs))


# ------------------------------------------------------------------ the context

class Context:
    """What the sweeps of one run share: the settings, the :class:`~.study.Study` (store,
    executor), the strategies of --methods, the Halton depths, the repeats, the outliers."""

    def __init__(self, settings: StabilitySettings):
        self.settings = settings
        self.cfg = settings.config
        self.st = Study(settings)
        self.engine = Engine(self.st)
        self.jobs: list = []          # every sweep job rendered (for timed_on)
        self.out = settings.out
        self.width, self.height = settings.resolution
        self.repeats = max(1, int(settings.repeats or 1))
        #: samples per pixel of each repeat: --spp (and the Halton ladder's top) is the budget
        #: per point and method, split over the repeats (the same total cost for any R)
        self.spp = per_repeat(settings.spp, self.repeats)
        self.halton_spp = per_repeat(self.cfg.halton_spp, self.repeats)
        self.grazing_samples = per_repeat(self.cfg.grazing_samples, self.repeats)
        self.outliers = Outliers()
        #: strategies of --methods (their vr_path strategy; path has none)
        self.strategies = list(dict.fromkeys(m.strategy for m in settings.methods
                                             if m.strategy is not None)) or ["bsdf"]
        self.scene_dir = os.path.join(self.out, NAME, "scenes")
        high = settings.depth.max_depth
        # unbounded (-1) becomes 8: plain Halton's all-zero first sample would never end its
        # path under Russian roulette (plan.check_terminates)
        self.halton_depths = [2, high if high is not None and high > 2 else 8]
        self._probe = None

    def path(self, name: str) -> str:
        return os.path.join(self.out, NAME, name)

    def probe(self):
        """The scene loaded for probing its surfaces (loaded once per run)."""
        if self._probe is None:
            from ..scene_probes import probe_scene
            self._probe = probe_scene(self.settings.scene, self.width, self.height)
        return self._probe

    def depth(self, max_depth: int) -> Depth:
        d = self.settings.depth
        return Depth(max_depth, d.rr_depth, d.hide_emitters)

    def declare(self, sweep: str, values, apply, methods, budget: Budget,
                point=lambda x: f"{x:g}") -> Declaration:
        """A sweep over ``values`` (``apply(value, scene)``: the scene at that point, a scene
        variant or a depth), every method of ``methods`` at ``budget``, :attr:`repeats` runs
        each, against the reference of each point. Job keys ``stability/<sweep>/<point(x)>/
        <method>[/r<r>]``, as before the engine; timed in the group ``stability/<sweep>``."""
        scene = SceneSetup(sweep, self.settings.info, (self.width, self.height),
                           self.settings.depth)
        return Declaration(NAME, tuple(parse_method(m) for m in methods), (scene,), (budget,),
                           self.repeats, engine.Sweep(sweep, tuple(values), apply),
                           key=lambda decl, cell: f"{NAME}/{cell.scene}/{point(cell.point)}/"
                                                  f"{cell.method}")

    def measure(self, declaration: Declaration) -> Measurements:
        """Render (what the stores lack) and measure ``declaration`` on the engine; keeps its
        jobs for :meth:`timed_on`."""
        measured = self.engine.run(declaration)
        self.jobs += measured.all_jobs()
        return measured

    def timed_on(self) -> str:
        return self.st.timed_on(self.jobs)

    def read_run(self, run: engine.Run, method: str, ref, mask=None,
                 floor=None) -> tuple[Run, np.ndarray]:
        """The numbers of one run (the engine's: its image and cost) and its image; counts
        outliers. ``floor``: the reference's own relMSE per pixel and channel
        (``Study.reference``'s ``relmse_floor_map``), subtracted from both errors."""
        image = run.image
        o = self.outliers.add(label(method), image, ref)
        sel = mask if mask is not None else np.ones(image.shape[:2], bool)
        level = metrics.ratio(float(np.mean(image[sel])), float(np.mean(ref[sel])))
        whole, masked = metrics.relmse(image, ref), metrics.relmse(image, ref, mask)
        if floor is not None:
            whole -= float(np.mean(floor))
            masked -= float(np.mean(floor[mask] if mask is not None else floor))
        return Run(whole, masked, level, run.cost,
                   o["max"], o["fireflies"], o["nonfinite"]), image


def cells(measured: Measurements, method: str):
    """(value, cell) of ``method`` at every point of a one-scene, one-budget sweep."""
    decl = measured.declaration
    return [(x, Cell(decl.scenes[0].name, method, decl.budgets[0].name, x))
            for x in decl.sweep.values]
