"""Figures (matplotlib, Agg backend), each written atomically as PNG."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import figure_pool, files  # noqa: E402
from .metrics import loglog_slope  # noqa: E402

TILE_INCHES = 2.4


def _save(fig, path: str) -> str:
    figure_pool.save(fig, [(path, "png", 110)])
    return path


def _show(ax, image: np.ndarray) -> None:
    ax.imshow(files.tonemap(image), interpolation="nearest")
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


# ------------------------------------------------ lines with interval bands

def _positive(values) -> np.ndarray:
    v = np.asarray(values, float)
    return np.where(np.isfinite(v) & (v > 0), v, np.nan)


def _line(ax, xs, estimates, scale=None, style="o-", label=None):
    """A line through the estimates' values and a band between their bounds."""
    k = np.ones(len(estimates)) if scale is None else np.asarray(scale, float)
    value = _positive([e.value for e in estimates]) * k
    (line,) = ax.plot(xs, value, style, ms=3, label=label)
    lo = _positive([e.lo for e in estimates]) * k
    hi = _positive([e.hi for e in estimates]) * k
    if np.isfinite(lo).any():
        ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.2, linewidth=0)
    return line


def sweep_chart(path: str, xlabel: str, xs: list, series: dict, ylabel: str, title: str,
                reverse_x: bool = False) -> str:
    """Two log-log panels against the swept value: error, and error x mean render time.

    ``series[label] = (list of Estimate per point, mean seconds per point)``.
    """
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for name, (err, secs) in series.items():
        _line(axes[0], xs, err, label=name)
        _line(axes[1], xs, err, scale=secs, label=name)
    for ax, y in zip(axes, (ylabel, f"{ylabel} x render time (s)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(y)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        if reverse_x:
            ax.invert_xaxis()
    axes[0].set_title(f"{title}: error (band: 95% interval)")
    axes[1].set_title(f"{title}: error x time (lower is more efficient)")
    fig.tight_layout()
    return _save(fig, path)


STYLES = {"bsdf": "-", "cosine": "--", "uniform": ":", "mis": "-."}


def grazing_chart(path: str, angles: list, wasted: dict, efficiency: dict) -> str:
    """Wasted-sample fraction and efficiency against the incidence angle;
    ``wasted[(strategy, n)]`` a list of fractions, ``efficiency[(strategy, n)]`` Estimates."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for (s, n), fractions in wasted.items():
        axes[0].plot(angles, fractions, STYLES.get(s, "-"), marker="o", ms=3,
                     label=f"{s}, n={n:g}")
    for (s, n), est in efficiency.items():
        _line(axes[1], angles, est, style=STYLES.get(s, "-"), label=f"{s}, n={n:g}")
    axes[1].set_yscale("log")
    axes[0].set_title("Wasted samples (zero weight)")
    axes[0].set_ylabel("fraction of samples")
    axes[1].set_title("Efficiency relative to normal incidence (band: 95% interval)")
    axes[1].set_ylabel("relVar(0) / relVar(angle)")
    for ax in axes:
        ax.set_xlabel("incidence angle (degrees from the normal)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


def error_bands(path: str, series: dict, metric: str) -> str:
    """Log-log expected error against spp and against mean time, one line per method with
    its 95% interval as a band: ``series[method] = (spp list, mean seconds list, Estimate
    list)``; the legend gives the fitted slope of each line's values."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for name, (spp, secs, err) in series.items():
        values = [e.value for e in err]
        _line(axes[0], spp, err, label=f"{name} (slope {loglog_slope(spp, values):.2f})")
        _line(axes[1], secs, err, label=f"{name} (slope {loglog_slope(secs, values):.2f})")
    for ax, xlabel in zip(axes, ("samples per pixel", "render time (s)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(metric)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title(f"{metric} against spp (band: 95% interval)")
    axes[1].set_title(f"{metric} against time")
    fig.tight_layout()
    return _save(fig, path)


def estimate_lines(path: str, curves: dict, xlabel: str, ylabel: str, title: str) -> str:
    """Log-log lines of estimates with their intervals as bands, one per name:
    ``curves[name] = [(x, Estimate)]``."""
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for name, pts in curves.items():
        _line(ax, [x for x, _ in pts], [e for _, e in pts], label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


def spectrum_panels(path: str, panels: dict, cutoff: float, title: str) -> str:
    """Radially averaged power spectra, one axes per panel (``panels[panel title][name] =
    (frequencies, power)``, power relative to white noise's 1), a dotted line at 1 and a
    dashed one at the ``cutoff`` frequency."""
    fig, axes = plt.subplots(1, len(panels), squeeze=False, sharey=True,
                             figsize=(4.2 * len(panels) + 0.6, 3.6))
    for ax, (name, lines) in zip(axes[0], panels.items()):
        for label, (freqs, power) in lines.items():
            ax.plot(freqs, _positive(power), lw=1.0, label=label)
        ax.axhline(1.0, color="0.4", lw=0.7, ls=":")
        ax.axvline(cutoff, color="0.4", lw=0.7, ls="--")
        ax.set_yscale("log")
        ax.set_yticks([0.25, 0.5, 1, 2, 4], ["0.25", "0.5", "1", "2", "4"])
        ax.minorticks_off()
        ax.set_xlim(0, 0.5)
        ax.set_xlabel("frequency |f| (cycles per pixel)", fontsize=8)
        ax.set_title(name, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=7)
    axes[0][0].set_ylabel("power / its mean (white noise: 1)", fontsize=8)
    axes[0][-1].legend(fontsize=6, loc="lower right")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def ratio_bands(path: str, curves: dict, ylabel: str, title: str) -> str:
    """A ratio (efficiency relative to a baseline) against spp, one line per method with its
    interval as a band; ``curves[method] = [(spp, Estimate)]``; a dashed line at 1."""
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for name, pts in curves.items():
        _line(ax, [p for p, _ in pts], [e for _, e in pts], label=name)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("samples per pixel (rendered)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


# ------------------------------------------------ the scene suite

def _save_png_pdf(fig, stem: str) -> tuple[str, str]:
    """Write ``stem.png`` and ``stem.pdf`` (matplotlib's own text, no LaTeX), atomically."""
    figure_pool.save(fig, [(f"{stem}.{ext}", ext, 130) for ext in ("png", "pdf")])
    return stem + ".png", stem + ".pdf"


def matrix_heatmap(stem: str, rows: list[str], cols: list[str], values, texts, marks,
                   title: str, label: str) -> tuple[str, str]:
    """A rows x cols heatmap of log10 ``values`` (NaN: grey) with ``texts`` written in the
    cells; ``marks[r][c]``: 2 outlines the winner, 1 a method tied for best."""
    v = np.log10(np.where(np.asarray(values, float) > 0, np.asarray(values, float), np.nan))
    span = max(1.0, float(np.nanmax(np.abs(v))) if np.isfinite(v).any() else 1.0)
    fig, ax = plt.subplots(figsize=(1.05 * len(cols) + 2.4, 0.62 * len(rows) + 1.6))
    cmap = plt.get_cmap("RdBu").with_extremes(bad="#dddddd")
    im = ax.imshow(np.ma.masked_invalid(v), cmap=cmap, vmin=-span, vmax=span, aspect="auto")
    for r in range(len(rows)):
        for c in range(len(cols)):
            ax.text(c, r, texts[r][c], ha="center", va="center", fontsize=6.2,
                    color="white" if np.isfinite(v[r, c]) and abs(v[r, c]) > 0.6 * span
                    else "black")
            if marks[r][c]:
                ax.add_patch(plt.Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False,
                                           lw=2.4 if marks[r][c] == 2 else 1.0, ec="k"))
    ax.set_xticks(range(len(cols)), cols, rotation=35, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.025, label=label)
    fig.tight_layout()
    return _save_png_pdf(fig, stem)


def crop_figure(stem: str, reference: np.ndarray, boxes: list[tuple[int, int, int, int]],
                crops: list[tuple[str, np.ndarray, list[str]]], title: str) -> tuple[str, str]:
    """The reference with its crop ``boxes`` ((x, y, w, h), drawn in colour) on top, and
    beneath it one row per box of every method's crop with its caption lines:
    ``crops`` = [(method, its (H, W, 3) image, [caption per box])]. The crops are one
    mosaic image (tiles composed in numpy, magnified without interpolation), so a figure of
    many methods stays cheap to draw."""
    colours = ("#e8a33d", "#3dc1e8", "#c13de8")
    n, rows = max(1, len(crops)), len(boxes)
    tile = 96                                            # pixels per crop tile side
    pad, cap = 8, 34                                     # gaps; room for captions
    mosaic = np.full((rows * (tile + cap) + pad, n * (tile + pad) + pad, 3), 255, np.uint8)
    for k, (x, y, bw, bh) in enumerate(boxes):
        scale = max(1, tile // max(bw, bh))
        for c, (_, image, _) in enumerate(crops):
            t = files.tonemap(image[y:y + bh, x:x + bw])
            t = np.repeat(np.repeat(t, scale, 0), scale, 1)[:tile, :tile]
            r0, c0 = pad + k * (tile + cap), pad + c * (tile + pad)
            mosaic[r0 - 2:r0 + t.shape[0] + 2, c0 - 2:c0 + t.shape[1] + 2] = \
                (np.array(matplotlib.colors.to_rgb(colours[k % len(colours)])) * 255)
            mosaic[r0:r0 + t.shape[0], c0:c0 + t.shape[1]] = t
    h, w = reference.shape[:2]
    width = max(4.0, mosaic.shape[1] / 100)
    top = width * 0.5 * h / w
    fig, (ax, bottom) = plt.subplots(2, 1, figsize=(width, top + mosaic.shape[0] / 100 + 0.8),
                                     gridspec_kw={"height_ratios": [top, mosaic.shape[0] / 100]})
    _show(ax, reference)
    ax.set_title(title, fontsize=9)
    for k, (x, y, bw, bh) in enumerate(boxes):
        ax.add_patch(plt.Rectangle((x - 0.5, y - 0.5), bw, bh, fill=False, lw=1.5,
                                   ec=colours[k % len(colours)]))
    bottom.imshow(mosaic, interpolation="nearest")
    bottom.axis("off")
    for c, (name, _, captions) in enumerate(crops):
        x = pad + c * (tile + pad) + tile / 2
        bottom.text(x, pad - 3, name, ha="center", va="bottom", fontsize=7)
        for k, caption in enumerate(captions):
            bottom.text(x, pad + k * (tile + cap) + tile + 3, caption, ha="center", va="top",
                        fontsize=6)
    fig.tight_layout()
    return _save_png_pdf(fig, stem)
