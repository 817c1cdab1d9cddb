"""The sweeps' charts: lines of means over the repeats with their 95% interval as a band.

(The band drawing lives here, not in :mod:`experiments.lib.figures`; an
Estimate without an interval, one repeat, draws the line alone.)
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import store  # noqa: E402
from ..metrics import loglog_slope  # noqa: E402


def _save(fig, path: str) -> str:
    with store.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


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


def ladder_chart(path: str, series: dict, metric: str) -> str:
    """Log-log error against spp and against mean time, ``series[method] = (spp list,
    mean seconds list, Estimate list)``; the legend gives each line's fitted slope."""
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
