"""Building blocks of the stability sweeps (:mod:`experiments.stability`).

* scene variants: a copy of the scene XML with some ``<default>`` parameters
  changed (Phong exponent, light size), so every sweep point is an ordinary
  scene file that the render/reference caches key on;
* sweep methods: a :class:`~.methods.Method` with or without next-event
  estimation, rendered as a :class:`~.render.RenderJob`;
* measurements: pixel masks of the Phong surfaces, outliers (largest value,
  fireflies, non-finite pixels), neighbour-pixel error correlation, the
  zero-weight fraction and per-sample variance of direction sampling at a
  given incidence angle, and breakdown points read off the curves.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from . import store
from .methods import (Method, SceneInfo, load_scene, plugins_version, read_scene)
from .render import MAX_LANES, RenderJob

#: A firefly is a pixel whose error exceeds the median error by this many MADs.
FIREFLY_MADS = 10.0


# ------------------------------------------------------------ scene variants

def scene_defaults(path: str) -> dict[str, str]:
    """The ``<default name=... value=...>`` parameters of a scene file."""
    root = ET.parse(path).getroot()
    return {d.get("name"): d.get("value") for d in root.iter("default")}


def scene_variant(info: SceneInfo, directory: str, name: str,
                  overrides: dict[str, object]) -> SceneInfo:
    """``info``'s scene with some ``<default>`` values replaced, written to ``directory/name.xml``.

    KeyError if the scene does not declare one of the parameters. Relative
    paths inside the scene keep resolving against the original file's folder.
    """
    root = copy.deepcopy(ET.parse(info.path).getroot())
    found = set()
    for d in root.iter("default"):
        if d.get("name") in overrides:
            d.set("value", _xml_value(overrides[d.get("name")]))
            found.add(d.get("name"))
    missing = set(overrides) - found
    if missing:
        raise KeyError(", ".join(sorted(missing)))
    path = os.path.join(directory, name + ".xml")
    text = ET.tostring(root, encoding="unicode")
    if _read(path) != text:
        store.write_text(path, text)
    _resolve_from(os.path.dirname(info.path))
    return dataclasses.replace(read_scene(path), max_depth=info.max_depth)


_resolver_dirs: set[str] = set()


def _resolve_from(directory: str) -> None:
    if directory not in _resolver_dirs:
        mi.file_resolver().prepend(directory)
        _resolver_dirs.add(directory)


def _read(path: str) -> str | None:
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except OSError:
        return None


def _xml_value(value) -> str:
    return repr(float(value)) if isinstance(value, float) else str(value)


def with_max_depth(info: SceneInfo, max_depth: int) -> SceneInfo:
    return dataclasses.replace(info, max_depth=max_depth)


# ------------------------------------------------------------ sweep methods

@dataclass(frozen=True)
class SweepMethod:
    """A compared method of a sweep: strategy + sampler, with or without NEE + MIS."""
    method: Method
    nee: bool = False

    @property
    def label(self) -> str:
        return self.method.name + (" + NEE" if self.nee else "")

    @property
    def key(self) -> str:
        return self.method.name.replace(":", "-") + ("+nee" if self.nee else "")

    def integrator(self, max_depth: int) -> dict:
        return {"type": "vr_path", "strategy": self.method.strategy, "max_depth": max_depth,
                "emitter_sampling": self.nee}


def sweep_job(out: str, directory: str, info: SceneInfo, sm: SweepMethod, width: int,
              height: int, variant: str, seed: int) -> RenderJob:
    """The render of ``sm`` on ``info`` in ``<out>/<directory>/<method key>``."""
    m = sm.method
    settings = {"method": m.settings(), "nee": sm.nee, "scene": info.path,
                "scene_sha256": info.sha256, "width": width, "height": height,
                "max_depth": info.max_depth, "variant": variant, "seed": seed,
                "plugins": plugins_version(), "max_lanes": MAX_LANES}
    return RenderJob(
        os.path.join(out, directory, sm.key), f"{directory}/{sm.key}", settings,
        lambda: load_scene(info, width, height, sm.integrator(info.max_depth), m.sampler,
                           m.sampler_params),
        width, height, seed, m, save_images=True, label=f"{directory}: {sm.label}")


# ------------------------------------------------------------ measurements

def luminance(image: np.ndarray) -> np.ndarray:
    return image[..., 0] * 0.2126 + image[..., 1] * 0.7152 + image[..., 2] * 0.0722


def phong_mask(info: SceneInfo, width: int, height: int) -> np.ndarray:
    """(H, W) bool: pixels whose centre sees a surface with a ``phong`` BSDF first."""
    scene = load_scene(info, width, height, {"type": "vr_path", "max_depth": 1})
    sensor = scene.sensors()[0]
    idx = dr.arange(mi.UInt32, width * height)
    pos = mi.Point2f((mi.Float(idx % width) + 0.5) / width,
                     (mi.Float(idx // width) + 0.5) / height)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    mask = np.zeros(width * height, bool)
    for shape in scene.shapes():
        if shape.bsdf() is not None and type(shape.bsdf()).__name__ == "PhongBSDF":
            mask |= np.array(si.is_valid() & (si.shape == mi.ShapePtr(shape)))
    return mask.reshape(height, width)


def masked_relmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None,
                  eps: float = 0.01) -> float:
    """relMSE (as :func:`.metrics.relmse`) over the pixels of ``mask`` (all if None)."""
    err = np.square(image - reference) / (reference * reference + eps)
    if mask is not None:
        err = err[mask]
    return float(np.mean(err)) if err.size else float("nan")


def outliers(image: np.ndarray, reference: np.ndarray) -> dict:
    """Largest pixel value, fireflies and non-finite pixels of one image.

    A firefly is a pixel whose luminance error (image - reference) exceeds the
    median error by :data:`FIREFLY_MADS` median absolute deviations (a robust
    threshold that bright but correct features such as highlights do not
    cross). A non-finite pixel had at least one NaN/Inf sample (one is enough to
    make the pixel mean non-finite), so 0 means none reached the film.
    """
    finite = np.isfinite(image).all(axis=-1)
    err = luminance(np.where(np.isfinite(image), image, 0.0)) - luminance(reference)
    med = float(np.median(err[finite])) if finite.any() else 0.0
    mad = float(np.median(np.abs(err[finite] - med))) if finite.any() else 0.0
    threshold = med + FIREFLY_MADS * mad
    return {"max": float(np.max(np.where(np.isfinite(image), image, -np.inf))),
            "fireflies": int(np.count_nonzero(finite & (err > threshold) & (mad > 0))),
            "nonfinite": int(np.count_nonzero(~finite)), "threshold": threshold}


def neighbour_correlation(image: np.ndarray, reference: np.ndarray) -> float:
    """Pearson correlation of the luminance errors of horizontally adjacent pixels.

    About 0 for independent per-pixel estimates; near 1 when every pixel uses
    the same sample points (structured error).
    """
    err = luminance(image) - luminance(reference)
    a, b = err[:, :-1].ravel(), err[:, 1:].ravel()
    if a.std() == 0 or b.std() == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def direction_sampling_stats(bsdf, cos_theta_i: float, strategy: str, n: int,
                             seed: int = 0) -> dict:
    """Per-sample statistics of estimating the directional albedo at one incidence angle.

    ``strategy`` as in ``vr_path``: ``bsdf`` (the plugin's ``sample``),
    ``cosine`` or ``uniform`` (hemisphere warps weighted by ``eval / pdf``).
    Returns the albedo estimate, the fraction of samples with zero weight
    (wasted: below the horizon or outside the lobe) and the relative variance
    per sample Var[w] / E[w]^2 (the cost of one unit of relative error).
    """
    rng = np.random.default_rng(seed)
    u = rng.random((3, n))
    s = math.sqrt(max(0.0, 1.0 - cos_theta_i ** 2))
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(s, 0.0, cos_theta_i)
    si.uv = mi.Point2f(0.5, 0.5)
    ctx = mi.BSDFContext()
    if strategy == "bsdf":
        _, weight = bsdf.sample(ctx, si, mi.Float(u[0]), mi.Point2f(u[1], u[2]))
    else:
        sample2 = mi.Point2f(u[1], u[2])
        if strategy == "cosine":
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
        else:
            wo = mi.warp.square_to_uniform_hemisphere(sample2)
            pdf = mi.warp.square_to_uniform_hemisphere_pdf(wo)
        weight = bsdf.eval(ctx, si, wo) / dr.maximum(pdf, 1e-20)
    w = luminance(np.array(weight).T)
    mean = float(w.mean())
    return {"albedo": mean, "wasted": float(np.mean(w == 0)),
            "relvar": float(w.var() / mean ** 2) if mean > 0 else float("inf"),
            "nonfinite": int(np.count_nonzero(~np.isfinite(w)))}


# ------------------------------------------------------------ breakdown points

def first_where(xs, condition) -> object | None:
    """The first x (in the given order) whose condition holds, or None."""
    for x, c in zip(xs, condition):
        if c:
            return x
    return None


def ratio(a: float, b: float) -> float:
    return a / b if b > 0 else float("inf")


# ------------------------------------------------------------ figures

def sweep_chart(path: str, xlabel: str, xs: list, series: dict[str, tuple[list, list]],
                ylabel: str, title: str, reverse_x: bool = False) -> str:
    """Two log-log panels against the swept parameter: error, and error x render time.

    ``series[label] = (errors, seconds)`` over ``xs``; non-finite points are dropped.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for label, (err, secs) in series.items():
        e, s = np.asarray(err, float), np.asarray(secs, float)
        axes[0].loglog(xs, np.where(np.isfinite(e) & (e > 0), e, np.nan), "o-", ms=3,
                       label=label)
        axes[1].loglog(xs, np.where(np.isfinite(e * s) & (e > 0), e * s, np.nan), "o-", ms=3,
                       label=label)
    for ax, y in zip(axes, (ylabel, f"{ylabel} x render time (s)")):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(y)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        if reverse_x:
            ax.invert_xaxis()
    axes[0].set_title(f"{title}: error")
    axes[1].set_title(f"{title}: error x time (lower is more efficient)")
    fig.tight_layout()
    with store.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path


def line_chart(path: str, panels: list[tuple[str, str, dict[str, tuple[list, list]]]],
               xlabel: str, logy: tuple[bool, ...]) -> str:
    """Side-by-side panels ``(title, ylabel, {label: (xs, ys)})`` with linear x."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4), squeeze=False)
    for ax, (title, ylabel, lines), log in zip(axes[0], panels, logy):
        for label, (xs, ys) in lines.items():
            style = "--" if "cosine" in label else ":" if "uniform" in label else "-"
            ax.plot(xs, ys, style, marker="o", ms=3, label=label)
        if log:
            ax.set_yscale("log")
        ax.set_title(title)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    with store.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path
