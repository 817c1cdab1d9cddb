"""The sampling lab's figures (matplotlib, Agg backend), each written atomically as PNG.

Warp panels are drawn as one mosaic image per BSDF (tiles composed in numpy,
one ``imshow``), which keeps 72 panels cheap to draw; point sets and spectra
are ordinary matplotlib charts.
"""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.lib import figure_pool  # noqa: E402

#: Standardized residual shown at full colour in the difference tiles.
Z_RANGE = 5.0
TILE = 101          # pixels per tile side (the grid is upsampled to it)
PAD = 6


def _save(fig, path: str, dpi: int = 100) -> str:
    figure_pool.save(fig, [(path, "png", dpi)])
    return path


def _resize(grid: np.ndarray, size: int) -> np.ndarray:
    """Nearest-neighbour resize of a 2-D grid to size x size (rows flipped: up = +cos)."""
    rows = (np.arange(size) * grid.shape[0] // size)
    cols = (np.arange(size) * grid.shape[1] // size)
    return grid[rows][:, cols][::-1]


#: Densities are drawn as (value / max)^GAMMA, so that narrow peaks and the flat
#: parts around them are both visible.
GAMMA = 0.3


def _colour(grid: np.ndarray, cmap: str, lo: float, hi: float, gamma: float = 1.0) -> np.ndarray:
    x = np.clip((grid - lo) / (hi - lo if hi > lo else 1.0), 0.0, 1.0)
    return plt.get_cmap(cmap)(x ** gamma)[..., :3]


def scatter_tile(xy: np.ndarray, cos_min: float, size: int = TILE,
                 shift: bool = False) -> np.ndarray:
    """The directions as dark dots on white, in the panel's equal-area coordinates
    (``shift``: phi = pi in the middle, as :func:`panel_tiles` draws the grids)."""
    img = np.ones((size, size, 3))
    if len(xy):
        u = (xy[:, 0] + math.pi) / (2 * math.pi)
        if shift:
            u = (u + 0.5) % 1.0
        cx = np.clip((u * size).astype(int), 0, size - 1)
        cy = np.clip(((xy[:, 1] - cos_min) / (1 - cos_min) * size).astype(int), 0, size - 1)
        img[size - 1 - cy, cx] = (0.1, 0.2, 0.5)
    return img


def panel_tiles(panel: dict) -> list[np.ndarray]:
    """Scatter, histogram, expected, difference (z-scores), f cos: five RGB tiles.

    Grids over the whole sphere are drawn with phi = pi (the mirror direction of
    an incident direction at phi = 0) in the middle."""
    hist, exp, fcos = panel["histogram"], panel["expected"], panel["fcos"]
    shift = float(panel["cos_min"]) <= -1.0
    if shift:
        hist, exp, fcos = (np.roll(g, g.shape[1] // 2, axis=1) for g in (hist, exp, fcos))
    hi = float(max(hist.max(), exp.max(), 1e-12))
    z = (hist - exp) / np.sqrt(np.maximum(exp, 1.0))
    return [scatter_tile(panel["scatter"], float(panel["cos_min"]), shift=shift),
            _colour(_resize(hist, TILE), "viridis", 0.0, hi, GAMMA),
            _colour(_resize(exp, TILE), "viridis", 0.0, hi, GAMMA),
            _colour(_resize(z, TILE), "RdBu_r", -Z_RANGE, Z_RANGE),
            _colour(_resize(fcos, TILE), "magma", 0.0, float(max(fcos.max(), 1e-12)), GAMMA)]


COLUMNS = ("directions", "histogram", "strategy's density", "difference (z)", "f·cos")


def warp_mosaic(path: str, title: str, rows: list[tuple[str, dict]]) -> str:
    """One row per panel ((label, panel) pairs), the five tiles of :func:`panel_tiles`."""
    step = TILE + PAD
    height = len(rows) * step
    width = len(COLUMNS) * step
    canvas = np.ones((height, width, 3))
    for r, (_, panel) in enumerate(rows):
        for c, tile in enumerate(panel_tiles(panel)):
            canvas[r * step:r * step + TILE, c * step:c * step + TILE] = tile
    inches = width / 100.0
    fig = plt.figure(figsize=(inches + 3.2, height / 100.0 + 0.6))
    ax = fig.add_axes([3.2 / (inches + 3.2), 0.0, inches / (inches + 3.2),
                       height / 100.0 / (height / 100.0 + 0.6)])
    ax.imshow(canvas, interpolation="nearest")
    ax.set_axis_off()
    for c, name in enumerate(COLUMNS):
        ax.text(c * step + TILE / 2, -4, name, ha="center", va="bottom", fontsize=8)
    for r, (label, _) in enumerate(rows):
        ax.text(-6, r * step + TILE / 2, label, ha="right", va="center", fontsize=7,
                family="monospace")
    fig.suptitle(title, fontsize=10, y=1.0)
    return _save(fig, path)


def rel_variance_chart(path: str, row_labels: list[str], strategies: list[str],
                       values: np.ndarray) -> str:
    """log10 of Var[w]/E[w]^2 per (BSDF and incidence, strategy), annotated."""
    fig, ax = plt.subplots(figsize=(1.2 * len(strategies) + 2.8, 0.28 * len(row_labels) + 1.2))
    logv = np.log10(np.clip(values, 1e-4, 1e6))
    im = ax.imshow(logv, cmap="RdYlGn_r", vmin=-2, vmax=3, aspect="auto")
    for i in range(values.shape[0]):
        for j in range(values.shape[1]):
            ax.text(j, i, f"{values[i, j]:.2g}", ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(strategies)), strategies)
    ax.set_yticks(range(len(row_labels)), row_labels, fontsize=7)
    fig.colorbar(im, ax=ax, label="log10 Var[w] / E[w]^2")
    ax.set_title("Relative variance of the weight f·cos/pdf", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def point_grid(path: str, title: str, samplers: list[str], pairs: list[tuple[int, int]],
               points: dict, counts: dict) -> str:
    """Rows = samplers, columns = dimension pairs: one pixel's points (``points[(sampler,
    pair)]``, (N, 2)). One axes with every unit square offset on a grid (cheap to draw)."""
    gap = 0.12
    fig = plt.figure(figsize=(1.5 * len(pairs) + 1.3, 1.5 * len(samplers) + 0.5))
    ax = fig.add_axes([0.0, 0.0, 1.0, 1.0])
    xs, ys = [], []
    for r, s in enumerate(samplers):
        y0 = -(r + 1) * (1 + gap)
        ax.text(-0.06, y0 + 0.5, f"{s}\n({counts[s]} pts)", ha="right", va="center", fontsize=7)
        for c, pair in enumerate(pairs):
            x0 = c * (1 + gap)
            xy = points[(s, pair)]
            xs.append(x0 + xy[:, 0])
            ys.append(y0 + xy[:, 1])
            ax.add_patch(plt.Rectangle((x0, y0), 1, 1, fill=False, lw=0.6, ec="0.3"))
    for c, (a, b) in enumerate(pairs):
        ax.text(c * (1 + gap) + 0.5, -gap / 2, f"dims ({a}, {b})", ha="center", va="bottom",
                fontsize=8)
    ax.scatter(np.concatenate(xs), np.concatenate(ys), s=1.5, c="#1f3b73", linewidths=0)
    ax.set_xlim(-1.25, len(pairs) * (1 + gap))
    ax.set_ylim(-len(samplers) * (1 + gap) - gap, 0.35)
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.text(len(pairs) * (1 + gap) / 2 - 0.6, 0.3, title, ha="center", va="top", fontsize=9)
    return _save(fig, path, dpi=90)


def spectra(path: str, title: str, samplers: list[str], pairs: list[tuple[int, int]],
            power: dict, counts: dict) -> str:
    """Radially averaged power spectrum per pair (one axes each), a line per sampler;
    ``power[(sampler, pair)]`` = (frequencies, power)."""
    fig, axes = plt.subplots(1, len(pairs), squeeze=False, sharey=True,
                             figsize=(2.9 * len(pairs), 2.8))
    cmap = plt.get_cmap("tab10")
    for c, (a, b) in enumerate(pairs):
        ax = axes[0][c]
        for i, s in enumerate(samplers):
            freqs, values = power[(s, (a, b))]
            ax.plot(freqs, values, color=cmap(i % 10), lw=1.0,
                    label=f"{s} ({counts[s]})")
        ax.axhline(1.0, color="0.5", lw=0.6, ls=":")
        ax.set_yscale("log")
        ax.set_ylim(1e-3, 10)
        ax.set_yticks([1e-3, 1e-2, 1e-1, 1, 10])
        ax.minorticks_off()
        ax.set_title(f"dims ({a}, {b})", fontsize=9)
        ax.set_xlabel("frequency |k|", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0][0].set_ylabel("power", fontsize=8)
    axes[0][-1].legend(fontsize=6, loc="lower right")
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.16, top=0.84, wspace=0.06)
    return _save(fig, path)


# ------------------------------------------------------------ screen-space error

#: Error images are drawn from -ERROR_RANGE to +ERROR_RANGE times the median standard
#: deviation of the row's errors at that count (one scale per count, so that the samplers'
#: error levels compare); spectra as log10 of the power over white noise's, +-SPECTRUM_RANGE.
ERROR_RANGE = 3.0
SPECTRUM_RANGE = 1.0
#: Box filter (pixels) that smooths one render's 2-D periodogram for display.
SMOOTH = 5


def smoothed(power: np.ndarray, size: int = SMOOTH) -> np.ndarray:
    """A size x size periodic box average (the periodogram of one render is noisy)."""
    out = np.zeros_like(power, dtype=float)
    for dy in range(-(size // 2), size // 2 + 1):
        for dx in range(-(size // 2), size // 2 + 1):
            out += np.roll(power, (dy, dx), axis=(0, 1))
    return out / size ** 2


def _upscale(tile: np.ndarray, size: int) -> np.ndarray:
    factor = max(1, size // max(tile.shape[:2]))
    return np.repeat(np.repeat(tile, factor, 0), factor, 1)


def error_tiles(fields: list[np.ndarray], spectra: list[np.ndarray],
                size: int = 128) -> list[tuple[np.ndarray, np.ndarray]]:
    """(error image, spectrum image) RGB tiles of one count's ``fields`` (luminance errors)
    and ``spectra`` (periodograms relative to white noise, FFT order): the errors on one
    common scale, the spectra centred (frequency 0 in the middle), smoothed, log10."""
    scale = ERROR_RANGE * float(np.median([np.std(f) for f in fields])) or 1.0
    out = []
    for f, p in zip(fields, spectra):
        err = _colour(np.asarray(f), "RdBu_r", -scale, scale)
        spec = np.log10(np.maximum(np.fft.fftshift(smoothed(np.asarray(p))), 1e-6))
        out.append((_upscale(err, size), _upscale(_colour(spec, "magma", -SPECTRUM_RANGE,
                                                          SPECTRUM_RANGE), size)))
    return out


def error_mosaic(path: str, title: str, labels: list[str], columns: list[str],
                 tiles: list[list[np.ndarray]]) -> str:
    """One row per label, one tile per column (``tiles[row][column]``, RGB arrays of one
    size), composed in numpy and drawn with one ``imshow``."""
    h, w = tiles[0][0].shape[:2]
    pad = PAD
    canvas = np.ones((len(labels) * (h + pad), len(columns) * (w + pad), 3))
    for r, row in enumerate(tiles):
        for c, tile in enumerate(row):
            canvas[r * (h + pad):r * (h + pad) + h, c * (w + pad):c * (w + pad) + w] = tile
    inches = canvas.shape[1] / 100.0
    fig = plt.figure(figsize=(inches + 1.8, canvas.shape[0] / 100.0 + 0.7))
    ax = fig.add_axes([1.8 / (inches + 1.8), 0.0, inches / (inches + 1.8),
                       canvas.shape[0] / 100.0 / (canvas.shape[0] / 100.0 + 0.7)])
    ax.imshow(canvas, interpolation="nearest")
    ax.set_axis_off()
    for c, name in enumerate(columns):
        ax.text(c * (w + pad) + w / 2, -4, name, ha="center", va="bottom", fontsize=8)
    for r, label in enumerate(labels):
        ax.text(-6, r * (h + pad) + h / 2, label, ha="right", va="center", fontsize=8,
                family="monospace")
    fig.suptitle(title, fontsize=10, y=1.0)
    return _save(fig, path)
