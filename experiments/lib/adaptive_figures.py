"""Seeing where adaptive sampling puts its samples: its per-pixel counts beside the errors.

A ``+adaptive`` method (``vr_adaptive``, :mod:`integrators.adaptive`) decides each pixel's
count from its neighbours' pilot samples. :func:`allocation` renders it once and reads the
counts it chose (``last_counts``); :func:`draw` puts that map beside per-pixel relMSE maps
(the suite passes the adaptive method's and its plain twin's, at equal time): samples
should go where the plain method's error is, and the adaptive method's error should be
flatter. The render is a figure's, not a measurement: it is not timed.
"""
from __future__ import annotations

import dataclasses

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import figure_pool  # noqa: E402
from .methods import Depth, Method  # noqa: E402


@dataclasses.dataclass(frozen=True)
class Allocation:
    """Where one render of an adaptive method put its samples."""
    counts: np.ndarray      # every pixel's samples (H, W), pilot and final pass
    gain: float             # the allocation's gain its pilot predicted (``last_gain``)
    allocated: bool         # whether it allocated (else every pixel the same count)


def allocation(scene_path: str, width: int, height: int, method: Method, spp: int,
               seed: int = 1, depth: Depth = Depth()) -> Allocation:
    """Where one render of the adaptive ``method`` at ``spp`` put its samples."""
    import mitsuba as mi
    from .scenes import load_scene
    spec = method.integrator_dict(depth)
    if spec.get("type") != "vr_adaptive":
        raise ValueError(f"allocation figure: the method {method} is not adaptive "
                         f"(integrator {spec.get('type')}, not vr_adaptive)")
    # the scene with the plain twin's integrator (a scene description cannot nest one);
    # the render takes the adaptive one
    scene = load_scene(scene_path, width, height, dataclasses.replace(method, adaptive=False),
                       depth)
    integ = mi.load_dict(spec)
    mi.render(scene, integrator=integ, spp=spp, seed=seed)
    return Allocation(np.array(integ.last_counts, dtype=np.float64).reshape(height, width),
                      float(integ.last_gain), bool(integ.last_allocated))


def draw(stem: str, counts: np.ndarray, maps: list[tuple[str, np.ndarray]],
         title: str) -> tuple[str, str]:
    """``stem``.png/.pdf: the samples per pixel, then each (label, per-pixel relMSE map) on
    one log scale."""
    fig, axes = plt.subplots(1, 1 + len(maps), figsize=(3.2 * (1 + len(maps)), 2.9),
                             squeeze=False)
    axes = axes[0]
    im = axes[0].imshow(counts, cmap="viridis", interpolation="nearest")
    axes[0].set_title("samples per pixel", fontsize=8)
    fig.colorbar(im, ax=axes[0], fraction=0.046, pad=0.03)
    logs = [np.log10(np.maximum(m, 1e-12)) for _, m in maps]
    # the colour scale from the pixels with an error (a black background has none)
    seen = np.concatenate([x[x > -11].ravel() for x in logs]) if logs else np.zeros(0)
    lo, hi = np.percentile(seen, [2, 99.5]) if seen.size else (-12.0, 0.0)
    for ax, (label, _), x in zip(axes[1:], maps, logs):
        im = ax.imshow(x, cmap="magma", vmin=lo, vmax=hi, interpolation="nearest")
        ax.set_title(f"{label}: log10 relMSE", fontsize=8)
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    figure_pool.save(fig, [(f"{stem}.{ext}", ext, 130) for ext in ("png", "pdf")])
    return stem + ".png", stem + ".pdf"
