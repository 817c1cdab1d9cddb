"""Seeing the learned path guide: where its units lie in the image, what each learned.

The ``guided`` strategy (:mod:`integrators.guided`) keeps its learned state in an
:class:`integrators.sdtree.SDTree`: spatial leaves, one directional histogram per *unit*
(leaf x normal class of the geometric normal) and a BSDF share per unit. This module
trains one (a ``vr_guided_path`` job rendered in its own passes, as the executor renders
it: :func:`train`), finds each pixel's unit (the unit of its camera ray's first hit:
:func:`unit_map`, -1 where the ray leaves the scene), picks a few units to show
(:func:`pick_units`) and draws them (:func:`draw`): the rendered image, the units in false
colour with their outlines, the learned BSDF share per pixel, and per picked unit its
histogram as a density over the sphere (equal-area: cos theta of the world z axis against
phi), each unit marked on the image. Reads only the tree's public attributes
(``prob``, ``share``, ``learned``, ``leaves``, ``res``, ``lookup``).

Also used by the lab's frozen-guide warp panels (:mod:`.studies.lab.guide`): the trained
strategy and the surface points under the picked pixels.
"""
from __future__ import annotations

import dataclasses
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import clock, figure_pool, files  # noqa: E402
from .methods import Depth, Method, parse_method  # noqa: E402

#: What the suite's report trains per guiding scene: samples per pixel of the job.
TRAIN_SPP = 256
#: Units drawn with their histograms.
PICKS = 4
#: Normal classes (``sdtree.CLASSES``'s order: dominant axis of the normal, then its sign).
CLASS_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")
#: Pixels a unit needs in the image to be picked (a unit of one pixel is hard to see).
MIN_PIXELS = 2
MARKERS = ("#e8a33d", "#3dc1e8", "#e83d8f", "#7be83d")


@dataclasses.dataclass
class Trained:
    """A trained guide: the integrator (its ``guide`` the frozen strategy), the scene, the
    sensor, the job's combined image and the wall seconds the training took."""
    integrator: object
    scene: object
    sensor: object
    image: np.ndarray
    seconds: float
    spp: int
    method: str

    @property
    def strategy(self):
        return self.integrator.guide

    @property
    def tree(self):
        return self.integrator.guide.tree


def train(scene_path: str, width: int, height: int, method: str | Method = "guided+nee",
          spp: int = TRAIN_SPP, seed: int = 1, depth: Depth = Depth()) -> Trained:
    """Render ``scene_path`` with ``method`` (a ``vr_guided_path`` method) at ``spp`` on a
    ``width`` x ``height`` film in the integrator's own passes (``pass_schedule``,
    ``after_pass``, ``combine``): the guide trains as in a suite job, then is frozen (the
    last iteration records nothing)."""
    import mitsuba as mi
    from . import execute, plan
    from .scenes import load_sensor, read_scene
    method = parse_method(method) if isinstance(method, str) else method
    timer = clock.Timer()
    spec = method.integrator_dict(depth)
    if spec.get("type") != "vr_guided_path":
        raise ValueError(f"guide figure: the method {method} does not train a guide "
                         f"(integrator {spec.get('type')}, not vr_guided_path)")
    job = plan.make_job("guide-figure", read_scene(scene_path), method, width, height, spp,
                        seed, depth, mi.variant())
    # the executor's cached scene, loaded alone as for the suite's renders, and a sensor of
    # this film as the executor makes one: their kernels are theirs (a scene loaded beside
    # another compiles its own)
    scene = execute.scene_of(job, mi.variant())
    sensor = load_sensor(scene_path, width, height, method, spp)
    # a figure of the guide trains whatever its count
    integ = mi.load_dict({**spec, "min_train_spp": 2, "min_train_samples": 1})
    # the executor's own multi-pass loop (its seeds, hooks and combination)
    timed = execute.render_passes(execute.View(scene, sensor), integ, job)
    return Trained(integ, scene, sensor, timed.image, timer.elapsed(), spp,
                   method.name)


def camera_hits(scene, sensor):
    """The first hit of the camera ray through every pixel centre: a
    ``mi.SurfaceInteraction3f`` of ``width x height`` lanes, row-major."""
    import drjit as dr
    import mitsuba as mi
    w, h = sensor.film().crop_size()
    idx = dr.arange(mi.UInt32, w * h)
    pos = mi.Point2f((mi.Float(idx % w) + 0.5) / w, (mi.Float(idx // w) + 0.5) / h)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    return scene.ray_intersect(ray)


def unit_map(tree, scene, sensor) -> np.ndarray:
    """(H, W) int64: the unit (leaf x normal class) of each pixel's camera ray's first hit,
    -1 where the ray leaves the scene."""
    import drjit as dr
    si = camera_hits(scene, sensor)
    valid = si.is_valid()
    unit = tree.lookup(si.p, si.n, valid)
    dr.eval(unit, valid)
    w, h = sensor.film().crop_size()
    out = np.where(np.asarray(valid), np.asarray(unit).astype(np.int64), -1)
    return out.reshape(h, w)


def pick_units(units: np.ndarray, tree, count: int = PICKS,
               pixels: list | None = None) -> list[tuple[int, tuple[int, int]]]:
    """``count`` (unit, (x, y)) to show: the units under ``pixels`` if given, else the
    learned units seen in at least :data:`MIN_PIXELS` pixels, those the guide is used
    most in first (lowest BSDF share, then most pixels), one per normal class before a
    second of any; each at its pixel nearest the unit's pixels' centroid."""
    if pixels:
        return [(int(units[y, x]), (int(x), int(y))) for x, y in pixels
                if units[y, x] >= 0][:count]
    seen, n = np.unique(units[units >= 0], return_counts=True)
    ok = [(u, c) for u, c in zip(seen, n) if c >= MIN_PIXELS and tree.learned[u]]
    if not ok:      # nothing learned: the largest units
        ok = [(u, c) for u, c in zip(seen, n)]
    ok.sort(key=lambda uc: (round(float(tree.share[uc[0]]), 3), -uc[1]))
    chosen, classes = [], set()
    for second in (False, True):
        for u, _ in ok:
            if len(chosen) == count:
                break
            cls = int(u) % len(CLASS_NAMES)
            if u in chosen or (cls in classes and not second):
                continue
            chosen.append(u)
            classes.add(cls)
    out = []
    for u in chosen:
        ys, xs = np.nonzero(units == u)
        k = int(np.argmin((ys - ys.mean()) ** 2 + (xs - xs.mean()) ** 2))
        out.append((int(u), (int(xs[k]), int(ys[k]))))
    return out


def histogram_density(tree, unit: int) -> np.ndarray:
    """(res, res) density in sr^-1 of ``unit``'s histogram, rows cos theta from -1 up,
    columns phi from 0 (the equal-area bins of ``integrators.guide_warps``)."""
    res = tree.res
    return np.asarray(tree.prob[unit], np.float64).reshape(res, res) * res * res / (4 * math.pi)


def describe(tree, unit: int) -> str:
    leaf, cls = divmod(int(unit), len(CLASS_NAMES))
    state = "learned" if tree.learned[unit] else "not learned (uniform)"
    return (f"unit {unit}: leaf {leaf}, normal {CLASS_NAMES[cls]}, {state}, "
            f"BSDF share {float(tree.share[unit]):.1f}")


def _unit_colours(units: np.ndarray) -> np.ndarray:
    """False colour per unit (a fixed pseudo-random colour per unit id), black outlines
    where neighbouring pixels lie in different units, grey for misses."""
    rng = np.random.default_rng(12345)
    top = int(units.max()) + 1 if units.size and units.max() >= 0 else 1
    palette = 0.25 + 0.7 * rng.random((top, 3))
    img = np.where(units[..., None] >= 0, palette[np.maximum(units, 0)], 0.5)
    edge = np.zeros(units.shape, bool)
    edge[:, 1:] |= units[:, 1:] != units[:, :-1]
    edge[1:, :] |= units[1:, :] != units[:-1, :]
    img[edge] *= 0.35
    return img


def draw(stem: str, image: np.ndarray, units: np.ndarray, tree,
         picks: list[tuple[int, tuple[int, int]]], title: str) -> tuple[str, str]:
    """The figure (``stem``.png and .pdf, written atomically): top the image, the units,
    the BSDF share per pixel, each picked unit marked by its number (:func:`_draw_top`);
    beneath, per picked unit its learned directional density (equal-area, world z up)
    with its normal class's direction marked (:func:`_draw_density`)."""
    cols = max(3, len(picks))
    h, w = units.shape
    fig = plt.figure(figsize=(2.6 * cols, 2.6 * cols / 3 * h / w + 2.9), layout="constrained")
    grid = fig.add_gridspec(2, 3 * cols, height_ratios=[cols / 3 * h / w * 1.1, 1.0])
    share = np.where(units >= 0, np.asarray(tree.share)[np.maximum(units, 0)], np.nan)
    tops = [("image (guided, training job)", files.tonemap(image)),
            (f"units (leaf x normal class): {len(np.unique(units[units >= 0]))} seen, "
             f"{tree.leaves} leaves", _unit_colours(units)),
            ("BSDF share per pixel (1: guide unused)", share)]
    for c, (name, img) in enumerate(tops):
        _draw_top(fig, fig.add_subplot(grid[0, c * cols:(c + 1) * cols]), name, img, picks)
    densities = [histogram_density(tree, unit) for unit, _ in picks]
    top = max([float(d.max()) for d in densities] + [1e-12])
    bottom = [fig.add_subplot(grid[1, 3 * k:3 * (k + 1)]) for k in range(len(picks))]
    for k, (ax, pick, density) in enumerate(zip(bottom, picks, densities)):
        im = _draw_density(ax, k, pick, density, top, tree)
    if bottom:
        fig.colorbar(im, ax=bottom, fraction=0.02, label="density (1/sr)")
    fig.suptitle(title, fontsize=9)
    figure_pool.save(fig, [(f"{stem}.{ext}", ext, 130) for ext in ("png", "pdf")])
    return stem + ".png", stem + ".pdf"


def _draw_top(fig, ax, name: str, img: np.ndarray, picks: list) -> None:
    """One of the top panels (an image, or a scalar map with its colour bar), the picked
    pixels marked by their numbers."""
    if img.ndim == 2:
        im = ax.imshow(img, cmap="viridis", vmin=0.1, vmax=1.0, interpolation="nearest")
        fig.colorbar(im, ax=ax, fraction=0.04)
    else:
        ax.imshow(img, interpolation="nearest")
    for k, (_, (x, y)) in enumerate(picks):
        ax.plot(x, y, "o", ms=7, mfc="none", mec=MARKERS[k % len(MARKERS)], mew=1.8)
        ax.text(x + 1.2, y - 1.2, str(k + 1), color=MARKERS[k % len(MARKERS)],
                fontsize=8, weight="bold")
    ax.set_title(name, fontsize=7)
    ax.set_xticks([])
    ax.set_yticks([])


def _draw_density(ax, k: int, pick: tuple, density: np.ndarray, top: float, tree):
    """Picked unit ``k``'s learned density over (phi, cos theta), its normal class's
    direction marked in cyan; returns the image (for the shared colour bar)."""
    unit, (x, y) = pick
    im = ax.imshow(density, origin="lower", extent=[0, 2 * math.pi, -1, 1],
                   aspect="auto", cmap="magma", vmin=0.0, vmax=top, interpolation="nearest")
    cls = unit % len(CLASS_NAMES)
    axis = cls // 2
    sign = 1.0 if cls % 2 == 0 else -1.0
    if axis == 2:
        ax.axhline(sign * 0.98, color="cyan", lw=1.2)
    else:
        phi = (0.0 if sign > 0 else math.pi) + (0.5 * math.pi if axis == 1 else 0.0)
        ax.plot(phi, 0.0, "x", color="cyan", ms=8, mew=2)
    leaf, _ = divmod(unit, len(CLASS_NAMES))
    ax.set_title(f"{k + 1} (pixel {x},{y}): leaf {leaf}, normal {CLASS_NAMES[cls]}\n"
                 f"BSDF share {float(tree.share[unit]):.1f}"
                 + ("" if tree.learned[unit] else ", not learned"),
                 fontsize=7, color=MARKERS[k % len(MARKERS)])
    ax.set_xlabel("phi (world, about z)", fontsize=6)
    if k == 0:
        ax.set_ylabel("cos theta (world z)", fontsize=6)
    ax.tick_params(labelsize=6)
    return im


@dataclasses.dataclass
class GuideFigure:
    """What :func:`guide_figure` made: its files, the units map, the picks, the seconds."""
    png: str
    pdf: str
    units: np.ndarray
    picks: list
    train_seconds: float
    seconds: float               # training, the units map and drawing
    leaves: int
    learned: int                 # units with a learned histogram
    guided_share: float          # share of the image's pixels whose unit's BSDF share < 1

    def caption(self, name: str, width: int, height: int, spp: int, method: str) -> str:
        return (f"{name}: the guide {method} learned in one job of {spp} spp at {width}x"
                f"{height} (trained for this figure, {self.train_seconds:.1f} s; figure "
                f"{self.seconds:.1f} s in all). Top: the job's image; each pixel's unit (the "
                f"spatial leaf x the normal class of its camera ray's first hit; {self.leaves} "
                f"leaves, {self.learned} units learned a histogram), in false colour with "
                f"outlines; the learned BSDF share of that unit ({self.guided_share:.0%} of "
                f"the pixels use the guide, share < 1). Beneath: the picked units' learned "
                f"directional densities over the sphere of world directions (equal-area: "
                f"azimuth about z, cos theta to z; cyan: the unit's normal class direction).")


def guide_figure(stem: str, scene_path: str, width: int, height: int,
                 method: str | Method = "guided+nee", spp: int = TRAIN_SPP, seed: int = 1,
                 depth: Depth = Depth(), pixels: list | None = None,
                 title: str | None = None) -> GuideFigure:
    """Train a guide on ``scene_path`` (:func:`train`) and draw it (:func:`draw`) to
    ``stem``.png/.pdf; ``pixels``: (x, y) whose units to show (default :func:`pick_units`)."""
    timer = clock.Timer()
    t = train(scene_path, width, height, method, spp, seed, depth)
    units = unit_map(t.tree, t.scene, t.sensor)
    picks = pick_units(units, t.tree, PICKS, pixels)
    seen = units[units >= 0]
    guided = float(np.mean(np.asarray(t.tree.share)[seen] < 1.0)) if seen.size else 0.0
    png, pdf = draw(stem, t.image, units, t.tree, picks,
                    title or f"{t.method}: the learned guide ({spp} spp, {width}x{height})")
    return GuideFigure(png, pdf, units, picks, t.seconds, timer.elapsed(),
                       int(t.tree.leaves), int(np.count_nonzero(t.tree.learned)), guided)
