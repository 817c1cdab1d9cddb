"""The lab's warp panels of a frozen, trained guide.

Every registered strategy gets its panels on the lab's BSDFs (:mod:`.lab.warps`); there
``guided`` is untrained (every BSDF share 1: plain BSDF sampling), since a guide is learned
state. Here a guide is trained on a scene (``vr_guided_path`` renders a job of its own
passes: :func:`.guide_figures.train`), frozen (its last iteration records nothing; the
tables do not change after it), and its strategy object, :class:`integrators.guided.
GuidedStrategy` with the learned tree and shares, is checked as a warp at a few surface
points of that scene: the camera rays' first hits under the pixels
:func:`.guide_figures.pick_units` chooses (the learned units the guide is used most in), with
the scene's own BSDF there and the camera direction as the incident direction. Each panel
is :func:`.lab.warps.compute` with that strategy, BSDF and interaction (point, geometric
normal, shading frame, uv): the same chi-square test against the strategy's reported
density, the same mass and albedo checks (:mod:`.lab.mass`), over the local sphere of
directions.

Cache: the panels are stored in the lab's warp cache under a key of every setting (the
scene file's hash, film, training spp and seed, sites, samples); a rerun with the same
settings neither trains nor recomputes.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os

import numpy as np

from experiments.lib import clock, files
from experiments.lib.studies.lab import warps

#: The scene a guide is trained on, its film and samples per pixel.
SCENE = "scenes/suite/door_room.xml"
FILM = (48, 36)
SPP = 256
#: Surface points (picked units) per trained guide.
SITES = 3
#: Integration points per cell and axis of the frozen guide's panels (the lab's other
#: panels: 16). The guide's density is piecewise constant over its world bins and jumps
#: at their edges, which cross the lab's cells; the trapezoid rule misplaces up to 1/ires
#: of a cell's jump there. At 16, a learned histogram with a 14x jump was rejected in
#: 1M-sample panels (p ~ 1e-9; the cells along the edge 35% over their tabulated counts)
#: while its own bins (sampled in world space) passed.
IRES = 64
VERSION = 1


@dataclasses.dataclass(frozen=True)
class GuideConfig:
    """One frozen guide's panels: where and how long it trains, how many points."""
    scene: str = SCENE
    width: int = FILM[0]
    height: int = FILM[1]
    spp: int = SPP
    seed: int = 0
    sites: int = SITES
    samples: int = 250_000
    method: str = "guided+nee"
    ires: int = IRES

    @property
    def name(self) -> str:
        return os.path.splitext(os.path.basename(self.scene))[0]

    def label(self) -> str:
        """The strategy's label in the lab's tables."""
        return f"guided (frozen, trained on {self.name})"

    def key(self) -> str:
        from experiments.lib.scenes import scene_hash
        text = json.dumps({"v": VERSION, "panel": warps.VERSION,
                           "scene": scene_hash(self.scene), "film": [self.width, self.height],
                           "spp": self.spp, "seed": self.seed, "sites": self.sites,
                           "samples": self.samples, "method": self.method,
                           "ires": self.ires}, sort_keys=True)
        return f"frozen_guide-{self.name}-{hashlib.sha1(text.encode()).hexdigest()[:10]}"


@dataclasses.dataclass
class Site:
    """A surface point of the scene: the pixel whose camera ray hit it, its unit, and what
    an interaction there needs (world point, geometric and shading normals, uv, local
    incident direction), with the BSDF there."""
    pixel: tuple
    unit: int
    p: np.ndarray
    n: np.ndarray
    sh_n: np.ndarray
    uv: np.ndarray
    wi: np.ndarray
    bsdf: object
    bsdf_id: str
    share: float

    @property
    def incidence_deg(self) -> float:
        return math.degrees(math.acos(max(-1.0, min(1.0, float(self.wi[2])))))

    def interaction(self, count: int):
        """``count`` copies of the interaction at this point (for the warp's functions)."""
        import drjit as dr
        import mitsuba as mi
        si = dr.zeros(mi.SurfaceInteraction3f, count)
        si.p = mi.Point3f(*map(float, self.p))
        si.n = mi.Normal3f(*map(float, self.n))
        si.sh_frame = mi.Frame3f(mi.Vector3f(*map(float, self.sh_n)))
        si.uv = mi.Point2f(*map(float, self.uv))
        si.wi = mi.Vector3f(*map(float, self.wi))
        return si


def sites(trained, count: int) -> list[Site]:
    """The surface points under the pixels of :func:`.guide_figures.pick_units` (misses and
    BSDFs with a Dirac lobe left out: the strategy uses the BSDF's own sampling there)."""
    import mitsuba as mi
    from experiments.lib import guide_figures
    tree = trained.tree
    units = guide_figures.unit_map(tree, trained.scene, trained.sensor)
    si = guide_figures.camera_hits(trained.scene, trained.sensor)
    width = units.shape[1]
    bsdfs = si.bsdf()

    def at(v, i):
        return np.array([float(v[k][i]) for k in range(len(v))])
    out = []
    for unit, (x, y) in guide_figures.pick_units(units, tree, 4 * count):
        i = y * width + x
        bsdf = bsdfs[i]
        if mi.has_flag(bsdf.flags(), mi.BSDFFlags.Delta):
            continue
        out.append(Site((x, y), unit, at(si.p, i), at(si.n, i), at(si.sh_frame.n, i),
                        at(si.uv, i), at(si.wi, i), bsdf, bsdf.id() or type(bsdf).__name__,
                        float(tree.share[unit])))
        if len(out) == count:
            break
    return out


def spec_of(cfg: GuideConfig, site: Site, index: int) -> warps.PanelSpec:
    """The panel's settings (its label, incidence, samples, seed) as a lab PanelSpec; its
    ``bsdf`` holds what identifies the site (no Mitsuba dict: the BSDF is the scene's)."""
    from experiments.lib.guide_figures import CLASS_NAMES
    leaf, cls = divmod(site.unit, len(CLASS_NAMES))
    label = (f"{cfg.name} px {site.pixel[0]},{site.pixel[1]} ({site.bsdf_id}, leaf {leaf} "
             f"{CLASS_NAMES[cls]}, share {site.share:.1f})")
    return warps.PanelSpec(label, {"scene": cfg.name, "pixel": list(site.pixel),
                                       "unit": site.unit}, cfg.label(),
                               round(site.incidence_deg, 1), cfg.samples,
                               cfg.seed * 7919 + 100_003 + index, ires=cfg.ires)


@dataclasses.dataclass
class Measured:
    """The frozen guide's panels: specs, panels by spec key, the warp rows, and seconds."""
    specs: list
    panels: dict
    rows: list
    train_seconds: float
    seconds: float
    cached: bool


def compute(cfg: GuideConfig, trained=None, strategy=None) -> tuple[list, dict, float]:
    """Train (unless ``trained`` is given), freeze, and compute the panels: (specs, panels,
    training seconds). ``strategy``: another strategy object to check at the same sites
    (the tests' wrong-density control); default the trained guide."""
    from experiments.lib import guide_figures
    if trained is None:
        trained = guide_figures.train(cfg.scene, cfg.width, cfg.height, cfg.method, cfg.spp,
                                      cfg.seed + 1)
    strategy = trained.strategy if strategy is None else strategy
    specs, panels = [], {}
    for k, site in enumerate(sites(trained, cfg.sites)):
        spec = spec_of(cfg, site, k)
        panels[spec.key()] = warps.compute(spec, strategy=strategy, bsdf=site.bsdf,
                                               site=site.interaction)
        specs.append(spec)
    return specs, panels, trained.seconds


def rows_of(specs: list, panels: dict) -> list[dict]:
    """The lab's warp rows (:func:`.lab.warp_part.measure_warps`'s)."""
    return [{"bsdf": s.bsdf_label, "incidence_deg": s.incidence_deg, "strategy": s.strategy,
             "samples": s.samples, "seed": s.seed, "grid": warps.domain_for(s).describe(),
             **{k: panels[s.key()][k] for k in warps.SCALARS}} for s in specs]


def measure(cfg: GuideConfig, cache: str) -> Measured:
    """:func:`compute`, or its panels from ``cache`` (one file per setting, atomic)."""
    timer = clock.Timer()
    path = os.path.join(cache, cfg.key() + ".npz")
    data = files.read_npz(path)
    if data is not None:
        meta = json.loads(str(data["meta"]))
        specs = [warps.PanelSpec(**m) for m in meta["specs"]]
        panels = {}
        for k, s in enumerate(specs):
            panel = {name[len(f"p{k}__"):]: v for name, v in data.items()
                     if name.startswith(f"p{k}__")}
            panels[s.key()] = {n: (int(v) if n in warps.INTEGERS else float(v)
                                   if n in warps.SCALARS else v) for n, v in panel.items()}
        return Measured(specs, panels, rows_of(specs, panels), meta["train_seconds"],
                        timer.elapsed(), True)
    specs, panels, train_seconds = compute(cfg)
    arrays = {f"p{k}__{n}": np.asarray(v) for k, s in enumerate(specs)
              for n, v in panels[s.key()].items()}
    meta = {"specs": [dataclasses.asdict(s) for s in specs], "train_seconds": train_seconds}
    files.write_npz(path, meta=np.asarray(json.dumps(meta)), **arrays)
    return Measured(specs, panels, rows_of(specs, panels), train_seconds,
                    timer.elapsed(), False)
