"""The scene suite's plan and measurements: scenes, cells, jobs, times, numbers.

Data flows one way: :func:`plan_scenes` reads every scene file (or records why it cannot),
:func:`plan_cells` plans phase 1 of every cell (R runs at equal spp),
:func:`plan_equal_time` phase 2 (R runs with the time budget's samples at the time per
sample phase 1 measured), :func:`run_cells` renders them through the study's executor
(cell by cell where a batch fails, so one broken scene or method stops nothing else), and
:func:`measure_scene` reads the numbers back from the store for the pure analysis
(:mod:`.suite_analysis`).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

import scenes as bundled
from .. import clock, files, metrics
from .. import references
from .. import scenes
from ..jobs import Job
from ..methods import Depth, Method
from ..study import Study, repeat_prefix
from . import suite_analysis

NAME = "suite"
ORDER = 50
TITLE = "Scene suite: every method on scenes that each isolate one phenomenon"
#: Largest equal-time sample count (a very cheap scene would otherwise render thousands).
MAX_EQUAL_TIME_SPP = 4096


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
    reference_chunk: int | None = None   # None: references.chunk_spp_for the film
    reference_typical_spp: int | None = None     # the default cap (chunk_spp_for)
    resolution: tuple = (1, 1)          # Study's film: unused (every job names its own)
    reference_cache: str | None = None  # Study's reference store (--reference-cache)
    reference_spp_default: int | None = None     # the parser's default --reference-spp
    replay_counts: str | None = None    # an earlier run's --out (--replay-counts)


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
    cells: dict = field(default_factory=dict)     # {method name: CellJobs}
    failed: dict = field(default_factory=dict)    # {method name: error}


@dataclass
class CellJobs:
    method: Method
    equal_spp: list               # R runs at --spp
    equal_time: list = field(default_factory=list)   # R runs at the time budget's spp

    def all(self) -> list:
        return self.equal_spp + self.equal_time


def film(cfg: Settings, info: scenes.SceneInfo, user_exr: str | None) -> tuple[int, int]:
    """The film a scene is rendered at (see the module help)."""
    if cfg.forced_resolution is not None:
        return cfg.forced_resolution
    if user_exr is not None:
        h, w = files.read_exr(user_exr).shape[:2]
        return w, h
    scale = min(1.0, cfg.max_size / max(info.width, info.height))
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
        if sp.user_ref is None:
            chunk = cfg.reference_chunk or references.chunk_spp_for(
                sp.width, sp.height, cfg.reference_typical_spp)
            sp.ref = references.RefSpec(sp.info, sp.width, sp.height, sp.depth,
                                        cfg.reference_method, cfg.variant, chunk)
    return plans


def plan_cells(st: Study, cfg: Settings, sp: ScenePlan) -> None:
    """Per method: R runs at equal spp (phase 1)."""
    for m in cfg.methods:
        sp.cells[m.name] = CellJobs(m, [st.job(
            repeat_prefix(f"{NAME}/{sp.name}/{m.name}/equal-spp", r), m, cfg.spp,
            info=sp.info, depth=sp.depth, resolution=(sp.width, sp.height),
            timing_group=f"{NAME}/{sp.name}") for r in range(st.repeats_of(m))])


def per_sample(cfg: Settings, st: Study, cell: CellJobs) -> tuple[float, list[float]]:
    """(a, [b per repeat]) of a cell: a the mean per-call seconds of its renders
    (:func:`.clock.overhead`: tracing, launching), b per repeat the cost per spp (whole
    film, :func:`.clock.cost`) of the repeat's renders at both budgets (phase 1 alone before
    phase 2)."""
    results = [st.store.get(j.key) for j in cell.all()]
    a = float(np.mean([clock.overhead(r) for r in results]))
    b = []
    for r in range(len(cell.equal_spp)):
        runs = [st.store.get(j.key) for j in ([cell.equal_spp[r]] + (
            [cell.equal_time[r]] if cell.equal_time else []))]
        b.append(clock.total(runs) / sum(x.spp for x in runs))
    return a, b


def equal_time_spp(cfg: Settings, b: list[float]) -> int:
    """Samples per pixel of an equal-time render: --time-budget seconds of samples at ``b``
    seconds per spp, rounded to the nearest power of two (Mitsuba renders a power-of-two
    count with another kernel than any other count: this keeps one kernel per cell)."""
    spp = cfg.time_budget / max(float(np.mean(b)), 1e-12)
    return int(min(MAX_EQUAL_TIME_SPP, 2 ** max(0, round(math.log2(max(spp, 1.0))))))


def plan_equal_time(st: Study, cfg: Settings, sp: ScenePlan, name: str,
                    cell: CellJobs) -> None:
    """R runs of a cell with --time-budget seconds of samples at the time per sample its
    phase 1 measured (phase 2)."""
    spp = equal_time_spp(cfg, per_sample(cfg, st, cell)[1])
    cell.equal_time = [st.job(repeat_prefix(f"{NAME}/{sp.name}/{name}/equal-time", r),
                              cell.method, spp, info=sp.info, depth=sp.depth,
                              resolution=(sp.width, sp.height),
                              timing_group=f"{NAME}/{sp.name}")
                       for r in range(len(cell.equal_spp))]


# ------------------------------------------------------------------ running, robustly

def live_cells(plans: list[ScenePlan]) -> list[tuple]:
    """(scene plan, method name, cell) of every cell not failed yet."""
    return [(sp, name, cell) for sp in plans for name, cell in sp.cells.items()
            if name not in sp.failed]


def timing_groups(sp: ScenePlan, first: tuple, size: int) -> list[list[tuple]]:
    """A scene's cells in groups of at most ``size`` (the methods a process keeps warm on
    its one loaded scene, :data:`.execute.VIEW_CACHE`: a method set up again compiles
    its kernels again). The
    methods of ``first`` (the baseline, the timed pair) lead the last group: the baseline
    is then still loaded from its reference before it, and after it for an extension."""
    cells = live_cells([sp])
    head = [c for m in dict.fromkeys(first) for c in cells if c[1] == m]
    rest = [c for c in cells if c not in head]
    room = max(0, size - len(head))
    tail, rest = (rest[len(rest) - room:], rest[:len(rest) - room]) if room else ([], rest)
    return [rest[i:i + size] for i in range(0, len(rest), max(1, size))] + [head + tail]


def interleaved(lists: list[list]) -> list:
    """The first item of every list, then every second item, ...: the timed renders of a
    group's methods take turns, so that a drifting machine load affects them alike."""
    return [x[k] for k in range(max(map(len, lists), default=0)) for x in lists if k < len(x)]


def run_cells(st: Study, groups: list[list[tuple]], jobs_of, label: str) -> None:
    """Render the jobs ``jobs_of(cell)`` of the cells of ``groups`` (lists of (scene plan,
    name, cell) triples; interleaved within each group) in one executor call; where that
    fails, cell by cell, recording each failing cell's error in its scene plan (finished
    jobs are in the store either way)."""
    groups = [[c for c in g if c[1] not in c[0].failed] for g in groups]
    cells = [c for g in groups for c in g]
    try:
        st.run([j for g in groups for j in interleaved([jobs_of(c) for _, _, c in g])], label)
        return
    except Exception:  # noqa: BLE001  (found cell by cell below)
        pass
    for sp, name, cell in cells:
        try:
            st.run(jobs_of(cell), f"{label} ({sp.name}, {name})")
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


def reference_of(refs: references.ReferenceStore, sp: ScenePlan,
                 spp: int | None) -> references.Reference:
    """The scene's reference: the user's EXR, or the store's (``spp``: enough chunks for
    it; None: every chunk cached)."""
    if sp.user_ref is not None:
        return references.Reference.from_exr(sp.user_ref)
    return refs.read(sp.ref, spp)


# ------------------------------------------------------------------ measuring

def _runs(cfg: Settings, st: Study, jobs: list[Job], ref: references.Reference, b: list[float],
          flip: str) -> tuple[suite_analysis.Runs, float]:
    """The numbers of one budget's repeats (deterministic: one run stands for all), and
    the reference's own expected relMSE over the pixels the rejected relMSE kept."""
    fmap = ref.floor_map()
    rel, rej, rej_floor, mse, secs, means, mvars, flips = ([] for _ in range(8))
    results = [st.store.get(j.key) for j in jobs]
    for r, (res, per_spp) in enumerate(zip(results, b)):
        image = res.image.astype(np.float64)
        rel.append(metrics.relmse(image, ref.image))
        raw = metrics.relmse_rejected(image, ref.image)
        rej.append(raw)
        rej_floor.append(raw - metrics.relmse_rejected(image, ref.image, floor_map=fmap))
        mse.append(metrics.mse(image, ref.image))
        secs.append(res.spp * per_spp)
        lum = image.mean(axis=-1).ravel()
        means.append(float(lum.mean()))
        mvars.append(float(lum.var(ddof=1) / lum.size) if lum.size > 1 else math.inf)
    if flip == "all":
        flips = [metrics.flip_mean(x.image.astype(np.float64), ref.image) for x in results]
    elif flip == "first":
        flips = [metrics.flip_mean(results[0].image.astype(np.float64), ref.image)]
    k = cfg.repeats if len(results) == 1 else 1
    return suite_analysis.Runs(results[0].spp, tuple(rel) * k, tuple(rej) * k, tuple(mse) * k,
                  tuple(secs) * k, tuple(flips), tuple(means) * k,
                  tuple(mvars) * k), float(np.mean(rej_floor))


def measure_scene(cfg: Settings, st: Study, sp: ScenePlan, ref: references.Reference,
                  flip: bool) -> suite_analysis.SceneNumbers:
    """The numbers of one scene (FLIP only when ``flip``: it costs the most)."""
    cells, rej_floors = {}, []
    for name, cell in sp.cells.items():
        if name in sp.failed:
            continue
        a, b = per_sample(cfg, st, cell)
        px = sp.width * sp.height
        runs = {}
        for budget, jobs in (("equal_time", cell.equal_time), ("equal_spp", cell.equal_spp)):
            mode = ("none" if not flip else cfg.flip if budget == "equal_time" or
                    cfg.flip == "all" else "none")
            runs[budget], fl = _runs(cfg, st, jobs, ref, b, mode)
            rej_floors.append(fl)
        cells[name] = suite_analysis.Cell(name, runs, tuple(x / px * 1e9 for x in b) * (
            cfg.repeats if len(b) == 1 else 1), a, cell.method.deterministic)
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
                          header.hypothesis if header else "", exact, failed)


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


