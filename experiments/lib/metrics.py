"""Error metrics, convergence slopes, Veach efficiency and the bias checks.

All functions take linear (H, W, 3) images; the reference is the
high-sample-count image the error is measured against.
"""
from __future__ import annotations

import math

import numpy as np

#: Two-sided 99% critical value of the standard normal distribution.
Z99 = 2.5758293035489004
#: Denominator offset of relMSE, so dark pixels do not dominate.
RELMSE_EPS = 0.01


def mse(image: np.ndarray, reference: np.ndarray) -> float:
    """Mean squared error over every pixel and channel."""
    return float(np.mean(np.square(np.asarray(image, np.float64) - reference)))


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    return math.sqrt(mse(image, reference))


def relmse(image: np.ndarray, reference: np.ndarray, eps: float = RELMSE_EPS) -> float:
    """Relative MSE: mean of (x - ref)^2 / (ref^2 + eps)."""
    ref = np.asarray(reference, np.float64)
    return float(np.mean(np.square(np.asarray(image, np.float64) - ref) / (ref * ref + eps)))


METRICS = {"mse": mse, "relmse": relmse, "rmse": rmse}


def errors(image: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Every metric of :data:`METRICS` for one image."""
    return {name: fn(image, reference) for name, fn in METRICS.items()}


def loglog_slope(x, y) -> float:
    """Least-squares slope of log(y) against log(x) (points with x, y <= 0 are dropped).

    Monte Carlo error converges as spp^-1 in MSE, so the slope against spp is
    about -1 (and about -1 against time, which grows linearly with spp).
    """
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    keep = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if keep.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[keep]), np.log(y[keep]), 1)[0])


def efficiency(mse_value: float, seconds: float) -> float:
    """Veach's efficiency 1 / (MSE x time)."""
    return 1.0 / (mse_value * seconds) if mse_value > 0 and seconds > 0 else float("inf")


def bias_check(mean_a, var_a, mean_b, var_b, z: float = Z99) -> dict:
    """Are images A and B (independent renders) estimates of the same image?

    ``var_a``/``var_b`` are per-pixel variances *of the means* (already divided
    by the sample count). Returns the per-channel mean difference A - B with its
    ``z``-level confidence half-width (pixels are independent, so the variance of
    the image mean is sum(var) / npixels^2), and the fraction of pixel values
    whose z-score |A - B| / sqrt(var_a + var_b) is below ``z`` (about 99% when
    there is no bias and the variances are right).
    """
    a, b = np.asarray(mean_a, np.float64), np.asarray(mean_b, np.float64)
    var = np.asarray(var_a, np.float64) + np.asarray(var_b, np.float64)
    diff = a - b
    n = diff.shape[0] * diff.shape[1]
    mean_diff = diff.reshape(n, -1).mean(axis=0)
    half_width = z * np.sqrt(var.reshape(n, -1).sum(axis=0)) / n
    with np.errstate(divide="ignore", invalid="ignore"):
        zscore = np.where(var > 0, np.abs(diff) / np.sqrt(var), np.where(diff == 0, 0.0, np.inf))
    passed = zscore < z
    return {
        "mean_diff": mean_diff.tolist(),
        "ci_half_width": half_width.tolist(),
        "ci_contains_zero": (np.abs(mean_diff) <= half_width).tolist(),
        "pass_fraction": float(passed.mean()),
        "pass_fraction_per_channel": passed.reshape(n, -1).mean(axis=0).tolist(),
        "z": z,
    }
