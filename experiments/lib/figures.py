"""Figures (matplotlib, Agg backend), each written atomically as PNG."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import store  # noqa: E402
from .metrics import loglog_slope  # noqa: E402

TILE_INCHES = 2.4


def _save(fig, path: str) -> str:
    with store.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _show(ax, image: np.ndarray) -> None:
    ax.imshow(store.tonemap(image), interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])


def image_grid(path: str, images: list[list], row_labels: list[str], col_labels: list[str],
               captions: list[list[str]], title: str = "") -> str:
    """Rows x columns of tone-mapped images, a caption (the errors) under each tile.

    ``images[r][c]`` may be None for an empty tile.
    """
    rows, cols = len(images), max(len(r) for r in images)
    h, w = next(im for r in images for im in r if im is not None).shape[:2]
    tile_h = TILE_INCHES * h / w + 0.45
    fig, axes = plt.subplots(rows, cols, figsize=(TILE_INCHES * cols + 0.6, tile_h * rows + 0.6),
                             squeeze=False)
    for r in range(rows):
        for c in range(cols):
            ax = axes[r][c]
            image = images[r][c] if c < len(images[r]) else None
            if image is None:
                ax.axis("off")
                continue
            _show(ax, image)
            ax.set_xlabel(captions[r][c], fontsize=8)
            if r == 0:
                ax.set_title(col_labels[c], fontsize=10)
            if c == 0:
                ax.set_ylabel(row_labels[r], fontsize=10)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def zscore_map(path: str, diff: np.ndarray, var: np.ndarray, title: str) -> str:
    """Per-pixel z-score |A - B| / sqrt(var) (largest over channels), pixels >= 2.576 marked."""
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(var > 0, np.abs(diff) / np.sqrt(var), 0.0).max(axis=-1)
    fig, ax = plt.subplots(figsize=(6, 6 * diff.shape[0] / diff.shape[1] + 0.8))
    im = ax.imshow(z, cmap="magma", vmin=0, vmax=4, interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=10)
    fig.colorbar(im, ax=ax, fraction=0.03, label="|z| (max over RGB)")
    return _save(fig, path)


def sweep_chart(path: str, xlabel: str, xs: list, series: dict[str, tuple[list, list]],
                ylabel: str, title: str, reverse_x: bool = False) -> str:
    """Two log-log panels against the swept parameter: error, and error x render time.

    ``series[label] = (errors, seconds)`` over ``xs``; non-finite points are dropped.
    """
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
    return _save(fig, path)


def line_chart(path: str, panels: list[tuple[str, str, dict[str, tuple[list, list]]]],
               xlabel: str, logy: tuple[bool, ...]) -> str:
    """Side-by-side panels ``(title, ylabel, {label: (xs, ys)})`` with linear x."""
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
    return _save(fig, path)


def _band(values):
    """(mean, lo, hi) over the repeats of each point (:func:`.stats.mean_interval`)."""
    from . import stats
    est = [stats.mean_interval(v) for v in values]
    return ([e.value for e in est], [e.lo if e.known else e.value for e in est],
            [e.hi if e.known else e.value for e in est])


def error_bands(path: str, series: dict, metric: str) -> str:
    """Log-log expected error against spp and against seconds, one line per method, with a
    95% band over the repeats.

    ``series[method] = (spp list, [seconds per repeat] per point, [error per repeat] per
    point)``; the legend gives the least-squares slope of the mean.
    """
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for name, (spp, seconds, err) in series.items():
        mean, lo, hi = _band(err)
        secs = [float(np.mean(s)) for s in seconds]
        for ax, x in zip(axes, (spp, secs)):
            line, = ax.loglog(x, mean, "o-", ms=3,
                              label=f"{name} (slope {loglog_slope(x, mean):.2f})")
            ax.fill_between(x, np.maximum(lo, 1e-300), hi, color=line.get_color(), alpha=0.2,
                            linewidth=0)
    for ax, xlabel in zip(axes, ("samples per pixel", "render time (s)")):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"expected {metric}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title(f"{metric} against spp (95% bands over repeats)")
    axes[1].set_title(f"{metric} against time")
    fig.tight_layout()
    return _save(fig, path)


def ratio_bands(path: str, curves: dict, ylabel: str, title: str) -> str:
    """A ratio (efficiency relative to a baseline) against spp, one line per method with its
    interval as a band; ``curves[method] = [(spp, Estimate)]``; a dashed line at 1."""
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for name, pts in curves.items():
        spp = [p for p, _ in pts]
        est = [e for _, e in pts]
        line, = ax.semilogx(spp, [e.value for e in est], "o-", ms=3, label=name)
        ax.fill_between(spp, [e.lo if e.known else e.value for e in est],
                        [e.hi if e.known else e.value for e in est], color=line.get_color(),
                        alpha=0.18, linewidth=0)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set_xlabel("samples per pixel (rendered)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return _save(fig, path)
