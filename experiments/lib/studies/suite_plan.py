"""The scene suite's plan and measurements: scenes, its declarations on the engine, numbers.

Data flows one way: :func:`plan_scenes` reads every scene file (or records why it cannot)
and declares each readable scene to the experiment engine (:func:`declaration`: every
method, R repeats, equal spp then equal time at the cost per sample the equal-spp renders
measured, rounded to a power of two but for a learning method's, and capped);
:func:`plan_budget` plans a budget's jobs through :class:`~..engine.Engine` (job keys and
seeds from the engine's plan), :func:`run_cells` renders them through the study's executor
(cell by cell where a batch fails, so one broken scene or method stops nothing else), and :func:`measure_scene` turns
the engine's :class:`~..engine.Measurements` (against the suite's own reference: extended
where too noisy, or the user's EXR) into the numbers of the pure analysis
(:mod:`.suite_analysis`).
"""
from __future__ import annotations

import fnmatch
import math
import os
from dataclasses import dataclass, field, replace

import numpy as np

import scenes as bundled
from .. import clock, files, metrics
from .. import references
from .. import scenes
from ..engine import Budget, Cell, Declaration, Engine, Measurements, SceneSetup
from ..jobs import Accumulator
from ..methods import Depth, Method
from ..study import Study, repeat_prefix
from . import suite_analysis, suite_bias, suite_errors

NAME = "suite"
ORDER = 50
TITLE = "Scene suite: every method on scenes that each isolate one phenomenon"
#: Largest equal-time sample count (a very cheap scene would otherwise render thousands).
MAX_EQUAL_TIME_SPP = 4096
#: Relative standard error of the expected relMSE (pooled over the repeats) of the baseline
#: and the timed pair that the equal-time budget of a scene aims for (:func:`precision_scale`):
#: two such errors give an A/A efficiency interval of hi/lo ~1.2 before the costs' spread.
PRECISION = 0.035
#: Largest factor of ``--time-budget`` :func:`precision_scale` may give a scene.
MAX_PRECISION_SCALE = 32
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


# ------------------------------------------------------------------ the plan

@dataclass
class ScenePlan:
    """One scene of the suite: read (or why not), its header, film, depth and reference."""
    name: str
    path: str
    info: scenes.SceneInfo | None = None
    error: str = ""
    header: object = None
    header_note: str = ""
    width: int = 0
    height: int = 0
    depth: Depth = Depth()
    ref: references.RefSpec | None = None
    user_ref: str | None = None
    box: bool = False                             # every filter a box (suite_bias.box_filter)
    declaration: Declaration | None = None
    precision: float | None = None                # the equal-time factor :func:`precision_scale`
    precision_note: str = ""                      # why there is none
    jobs: dict = field(default_factory=dict)      # {budget: {Cell: [per repeat: [Job]]}}
    failed: dict = field(default_factory=dict)    # {method name: error}
    left_out: dict = field(default_factory=dict)  # {method name: why} (header ``methods``)

    @property
    def methods(self) -> list[str]:
        return [m.name for m in self.declaration.methods] if self.declaration else []

    def cell(self, method: str, budget: str) -> Cell:
        return Cell(self.name, method, budget)

    def cell_jobs(self, method: str, budget: str) -> list:
        """The jobs of a method's repeats at ``budget`` (none where it was not planned)."""
        reps = self.jobs.get(budget, {}).get(self.cell(method, budget), [])
        return [j for jobs in reps for j in jobs]

    def all_jobs(self) -> list:
        return [j for cells in self.jobs.values() for reps in cells.values()
                for jobs in reps for j in jobs]


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


def one_line(error: BaseException) -> str:
    """The innermost cause of an error, first line (mi.render wraps a plugin's error)."""
    while error.__cause__ is not None:
        error = error.__cause__
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}"


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
        sp.box = suite_bias.box_filter(path)
        if sp.user_ref is None:
            chunk = references.chunk_spp_for(sp.width, sp.height, cfg.reference_typical_spp)
            sp.ref = references.RefSpec(sp.info, sp.width, sp.height, sp.depth,
                                        cfg.reference_method, cfg.variant, chunk)
        sp.left_out = left_out(cfg, sp.header)
        sp.declaration = declaration(cfg, sp)
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


def declaration(cfg: Settings, sp: ScenePlan) -> Declaration:
    """The scene as the engine's declaration: every method (but those its header's
    ``methods`` leave out, :func:`left_out`), R repeats, equal spp, then equal
    time at the cost per sample the equal-spp renders measured (the count rounded to the
    nearest power of two: Mitsuba renders a power-of-two count with another kernel than any
    other count, this keeps one kernel per cell; a learning method's count, from its pilot,
    is not rounded, :meth:`.Engine.piloted_spp`; at most :data:`MAX_EQUAL_TIME_SPP`). Job
    keys: the engine's ``suite/SCENE/METHOD/BUDGET``, timed in the group ``suite/SCENE``.
    A cell whose error comes from its pixels' variances (:func:`precise`) renders each job
    with its samples' per-pixel second moments (``sample_moments``: spp - 1 degrees of
    freedom per pixel for its variance, :mod:`.suite_errors`)."""
    return Declaration(
        NAME, tuple(m for m in cfg.methods if m.name not in sp.left_out),
        (SceneSetup(sp.name, sp.info, (sp.width, sp.height), sp.depth),),
        (Budget.equal_spp(cfg.spp, SPP),
         Budget.equal_time(cfg.time_budget, SPP, TIME, power_of_two=True,
                           max_spp=MAX_EQUAL_TIME_SPP)), cfg.repeats,
        sample_moments=lambda method: precise(method, sp.box))


def time_scale(sp: ScenePlan) -> float:
    """The factor of ``--time-budget`` a scene's equal-time renders get: the larger of its
    header's ``budget`` (1 without) and its :func:`precision_scale` (1 before it is known)."""
    return max(sp.header.budget if sp.header is not None else 1.0, sp.precision or 1.0)


def precision_scale(cfg: Settings, engine: Engine, sp: ScenePlan,
                    ref: np.ndarray) -> tuple[float | None, str]:
    """The factor of ``--time-budget`` that the scene's equal-time renders need for the
    expected relMSE of the baseline and of the timed pair (:data:`.suite_analysis.TIMED_PAIR`,
    those of them in the run) to be known to :data:`PRECISION` (relative standard error,
    pooled over the repeats), predicted from their equal-spp renders (their pixels'
    variances over ``ref``'s squares, :mod:`.suite_errors`; ``ref``: the reference's first
    chunk, the same in every run, so that a rerun or a longer reference plans the same
    counts; not the renders' own mean, whose fireflies would shrink their own weights):
    the standard error falls as 1/sqrt(samples), so the factor is :func:`scale_for` of the
    largest one predicted at the unscaled equal-time count. (None, why) where the baseline's pixels are not
    independent estimates or it has no equal-spp renders."""
    baseline = cfg.baseline
    if not precise(baseline, sp.box):
        return None, (f"the baseline {baseline.name} has no pixel variances here (a QMC "
                      f"sampler or a filter other than a box)")
    names = [m.name for m in sp.declaration.methods
             if m.name in (baseline.name,) + suite_analysis.TIMED_PAIR and precise(m, sp.box)]
    errors = [e for e in (_equal_time_error(engine, sp, name, ref) for name in names)
              if e is not None]
    if baseline.name in sp.failed or not errors:
        return None, f"the baseline {baseline.name} has no equal-spp error"
    return scale_for(max(errors)), ""


def scale_for(error: float, precision: float = PRECISION,
              cap: float = MAX_PRECISION_SCALE) -> float:
    """The power-of-two factor (1 to ``cap``) of samples that brings a relative standard
    error ``error`` (falling as 1/sqrt(samples)) to ``precision`` or below."""
    scale = (error / precision) ** 2
    return float(min(cap, 2 ** max(0, math.ceil(math.log2(max(scale, 1.0))))))


def _equal_time_error(engine: Engine, sp: ScenePlan, method: str,
                      ref: np.ndarray) -> float | None:
    """The relative standard error of a cell's pooled expected relMSE predicted at its
    unscaled equal-time count from its equal-spp renders (None: no usable renders)."""
    runs = [engine.study.results(jobs)
            for jobs in sp.jobs.get(SPP, {}).get(sp.cell(method, SPP), [])]
    if method in sp.failed or not runs:
        return None
    maps = []
    for results in runs:
        acc = Accumulator.empty(*results[0].image.shape[:2])
        for r in results:
            acc.add_result(r)
        maps.append(suite_errors.pixel_map(acc.variance_of_mean(), ref))
    value, var = suite_errors.pooled(maps)
    if not (value > 0 and math.isfinite(var)):
        return None
    base = next(b for b in sp.declaration.budgets if b.name == TIME)
    spp = sum(r.spp for r in runs[0])
    return math.sqrt(var) / value * math.sqrt(spp / engine.equal_time_spp(base, runs))


def plan_budget(engine: Engine, sp: ScenePlan, budget: str, methods: list[str]) -> None:
    """Plan the jobs of ``methods`` at ``budget`` (:meth:`.Engine.jobs`); an equal-time
    budget (its seconds times :func:`time_scale`) takes each cell's count from its
    equal-spp renders (or ``--replay-counts``), a learning method's from a pilot render at
    that count (:meth:`.Engine.piloted_spp`)."""
    decl = sp.declaration
    chosen = replace(decl, methods=tuple(m for m in decl.methods if m.name in methods))
    b = next(x for x in decl.budgets if x.name == budget)
    if b.timed:
        b = replace(b, seconds=b.seconds * time_scale(sp))
    spp = None
    if b.timed:
        spp = {}
        for m in chosen.methods:
            cell = sp.cell(m.name, budget)
            spp[cell] = engine.replayed(decl, cell)
            if spp[cell] is None:
                spp[cell] = engine.equal_time_spp(b, [engine.study.results(jobs) for jobs in
                                                      sp.jobs[b.after][sp.cell(m.name, b.after)]])
                if m.learns:
                    spp[cell] = engine.piloted_spp(chosen, cell, b, spp[cell])
    sp.jobs.setdefault(budget, {}).update(engine.jobs(chosen, b, spp))


def precise(method: Method, box: bool) -> bool:
    """Whether a cell's error comes from its pixels' variances (:mod:`.suite_errors`): the
    independent sampler under a box filter, whose pixels are independent estimates."""
    return suite_bias.variance_kind(method, box) == "pixels"


def overhead(st: Study, sp: ScenePlan, method: str) -> float:
    """The mean per-call seconds of a cell's renders at both budgets
    (:func:`.clock.overhead`: tracing, launching)."""
    jobs = sp.cell_jobs(method, SPP) + sp.cell_jobs(method, TIME)
    return float(np.mean([clock.overhead(r) for r in st.results(jobs)]))


# ------------------------------------------------------------------ running, robustly

def live_cells(plans: list[ScenePlan]) -> list[tuple]:
    """(scene plan, method name) of every cell not failed yet."""
    return [(sp, name) for sp in plans for name in sp.methods if name not in sp.failed]


def timing_groups(sp: ScenePlan, first: tuple, size: int) -> list[list[tuple]]:
    """A scene's cells in groups of at most ``size`` (the methods a process keeps warm on
    its one loaded scene, :data:`.execute.VIEW_CACHE`: a method set up again compiles
    its kernels again). The methods of ``first`` (the baseline, the timed pair) lead the
    first group: the baseline is then still loaded from its reference, and its equal-spp
    renders come before any equal-time render (:func:`precision_scale` needs them)."""
    cells = live_cells([sp])
    head = [c for m in dict.fromkeys(first) for c in cells if c[1] == m]
    rest = head + [c for c in cells if c not in head]
    return [rest[i:i + size] for i in range(0, len(rest), max(1, size))]


def interleaved(lists: list[list]) -> list:
    """The first item of every list, then every second item, ...: the timed renders of a
    group's methods take turns, so that a drifting machine load affects them alike."""
    return [x[k] for k in range(max(map(len, lists), default=0)) for x in lists if k < len(x)]


def run_budget(engine: Engine, groups: list[list[tuple]], budget: str, label: str) -> None:
    """Plan (:func:`plan_budget`) and render the jobs at ``budget`` of the cells of
    ``groups`` (lists of (scene plan, method name) pairs; interleaved within each group) in
    one executor call; where that fails, cell by cell, recording each failing cell's error
    in its scene plan (finished jobs are in the store either way)."""
    groups = [[c for c in g if c[1] not in c[0].failed] for g in groups]
    cells = [c for g in groups for c in g]
    for sp in {id(sp): sp for sp, _ in cells}.values():
        plan_budget(engine, sp, budget, [m for s, m in cells if s is sp])
    try:
        engine.study.run([j for g in groups for j in interleaved(
            [sp.cell_jobs(m, budget) for sp, m in g])], label)
        return
    except Exception:  # noqa: BLE001  (found cell by cell below)
        pass
    for sp, name in cells:
        try:
            engine.study.run(sp.cell_jobs(name, budget), f"{label} ({sp.name}, {name})")
        except Exception as e:  # noqa: BLE001  (listed in the report, the others go on)
            sp.failed[name] = one_line(e)


def render_references(refs: references.ReferenceStore, cfg: Settings, plans: list[ScenePlan],
                      spp: dict) -> int:
    """Render (or extend) the references of ``plans`` to ``spp[name]``; a scene whose
    reference fails gets the error. Returns the chunks rendered."""
    todo = [sp for sp in plans if sp.ref is not None and not sp.error]
    pairs = [(sp.ref, refs.plan(sp.ref, spp[sp.name])) for sp in todo]
    try:
        return refs.render(pairs, cfg.executor, cfg.variant, f"{NAME}: references")
    except Exception:  # noqa: BLE001
        pass
    done = 0
    for sp, pair in zip(todo, pairs):
        try:
            done += refs.render([pair], cfg.executor, cfg.variant, f"{NAME}: {sp.name}")
        except Exception as e:  # noqa: BLE001
            sp.error = f"its reference failed to render: {one_line(e)}"
    return done


def first_chunk(refs: references.ReferenceStore, sp: ScenePlan) -> np.ndarray:
    """The image of the scene's reference's first chunk (the user's EXR where given): the
    same in every run of the scene, whatever its reference's length."""
    return reference_of(refs, sp, sp.ref.chunk if sp.user_ref is None else None).image


def reference_of(refs: references.ReferenceStore, sp: ScenePlan,
                 spp: int | None) -> references.Reference:
    """The scene's reference: the user's EXR, or the store's (``spp``: enough chunks for
    it; None: every chunk cached)."""
    if sp.user_ref is not None:
        return references.Reference.from_exr(sp.user_ref)
    return refs.read(sp.ref, spp)


# ------------------------------------------------------------------ measuring

def measurements(engine: Engine, sp: ScenePlan, ref: references.Reference) -> Measurements:
    """The engine's measurements of the scene's cells not failed, against ``ref``."""
    planned = {budget: {cell: reps for cell, reps in cells.items()
                        if cell.method not in sp.failed} for budget, cells in sp.jobs.items()}
    return engine.measure(sp.declaration, planned, {(sp.name, None): (ref.image, ref.meta())})


def _runs(cfg: Settings, runs: list, ref: references.Reference, b: list[float],
          flip: str, costs: tuple = ()) -> tuple[suite_analysis.Runs, float]:
    """The numbers of one budget's repeats (the engine's :class:`~..engine.Run` values;
    ``costs``: the cell's cost per sample of every render, per budget), and the
    reference's own expected relMSE over the pixels the rejected relMSE kept."""
    fmap = ref.floor_map()
    rel, rej, rej_floor, mse, secs, means, mvars, flips = ([] for _ in range(8))
    for run, per_spp in zip(runs, b):
        image = run.image
        rel.append(run.relmse)
        raw = metrics.relmse_rejected(image, ref.image)
        rej.append(raw)
        rej_floor.append(raw - metrics.relmse_rejected(image, ref.image, floor_map=fmap))
        mse.append(run.mse)
        secs.append(run.spp * per_spp)
        lum = image.mean(axis=-1).ravel()
        means.append(float(lum.mean()))
        mvars.append(float(lum.var(ddof=1) / lum.size) if lum.size > 1 else math.inf)
    if flip == "all":
        flips = [metrics.flip_mean(x.image, ref.image) for x in runs]
    elif flip == "first":
        flips = [metrics.flip_mean(runs[0].image, ref.image)]
    maps = [suite_errors.pixel_map(x.variance, ref.image) for x in runs]
    expected = suite_errors.pooled(maps) if all(m is not None for m in maps) else ()
    return suite_analysis.Runs(runs[0].spp, tuple(rel), tuple(rej), tuple(mse), tuple(secs),
                               tuple(flips), tuple(means), tuple(mvars), expected, costs), \
        float(np.mean(rej_floor))


def measure_scene(cfg: Settings, st: Study, sp: ScenePlan, measured: Measurements,
                  ref: references.Reference, flip: bool, chunks: np.ndarray | None = None,
                  alpha: float | None = None) -> suite_analysis.SceneNumbers:
    """The numbers of one scene from the engine's ``measured`` (FLIP only when ``flip``: it
    costs the most); with a level ``alpha`` per cell, each cell's bias test
    (:func:`.suite_bias.check_cell`) against the reference's ``chunks`` (None: the user's
    EXR). Time per sample per repeat: the cost (:func:`.clock.cost`, in the
    engine's runs) of the repeat's renders at both budgets over their samples."""
    cells, rej_floors = {}, []
    methods = {m.name: m for m in sp.declaration.methods}
    for name in sp.methods:
        if name in sp.failed:
            continue
        finals = {budget: measured.final(sp.cell(name, budget)) for budget in (TIME, SPP)}
        b = [(x.cost + y.cost) / (x.spp + y.spp) for x, y in zip(finals[SPP], finals[TIME])]
        costs = tuple((finals[budget][0].spp, tuple(x.cost / x.spp for x in finals[budget]))
                      for budget in (SPP, TIME))
        runs = {}
        for budget, key in ((TIME, "equal_time"), (SPP, "equal_spp")):
            mode = ("none" if not flip else cfg.flip if budget == TIME or
                    cfg.flip == "all" else "none")
            runs[key], fl = _runs(cfg, finals[budget], ref, b, mode, costs)
            rej_floors.append(fl)
        px = sp.width * sp.height
        tested = None
        if alpha is not None:
            box = sp.box
            tested = suite_bias.check_cell(
                methods[name], [[(x.image, x.spp) for x in finals[budget]] for budget in
                                (SPP, TIME)], chunks, box, box, cfg.reference_method, alpha)
        cells[name] = suite_analysis.Cell(name, runs, tuple(x / px * 1e9 for x in b),
                                          overhead(st, sp, name), methods[name].deterministic,
                                          tested)
    if alpha is not None and sp.user_ref is None:
        checked = suite_bias.calibrated({n: c.block_bias for n, c in cells.items()},
                                        cfg.reference_method.name)
        cells = {n: replace(c, block_bias=checked[n]) for n, c in cells.items()}
    floor = suite_analysis.Floor(ref.relmse_floor or 0.0,
                                 float(np.mean(rej_floors)) if rej_floors else 0.0,
                                 ref.mse_floor or 0.0, ref.floor_known)
    header = sp.header
    exact, failed = None, dict(sp.failed)
    if header is not None and header.exact is not None and cfg.max_depth is None \
            and cfg.rr_depth is None:
        exact = header.exact
    return suite_analysis.SceneNumbers(sp.name, cells, floor, cfg.baseline.name,
                          header.favours if header else (), header.over if header else (),
                          header.hypothesis if header else "", exact, failed,
                          cfg.reference_method.name if sp.user_ref is None else "")


def needed_spp(numbers: suite_analysis.SceneNumbers, spp: int, cap: int) -> int:
    """Reference spp for a reference whose own relMSE exceeds FLOOR_SHARE of the smallest
    measured: enough to bring it to half that (so that the spread of the new measurement
    keeps it under), at most ``cap`` (a power of two times ``spp``); ``spp`` where it is
    under already. The measured error is the method's plus the floor f, and f falls as
    1/spp: a share s = f / (e + f) becomes F after k = s (1 - F) / ((1 - s) F) times the
    samples."""
    share, target = suite_analysis.floor_share(numbers), suite_analysis.FLOOR_SHARE / 2
    if not numbers.floor.known or share <= suite_analysis.FLOOR_SHARE:
        return spp
    if share >= 1:
        return cap
    k = share * (1 - target) / ((1 - share) * target)
    return int(min(cap, spp * 2 ** math.ceil(math.log2(k))))


