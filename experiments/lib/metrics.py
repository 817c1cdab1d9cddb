"""Error metrics (MSE, relMSE, FLIP), convergence slopes, Veach efficiency, bias checks, outliers.

All functions take linear (H, W, 3) images; the reference is the
high-sample-count image the error is measured against.
"""
from __future__ import annotations

import hashlib
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


def relmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None,
           eps: float = RELMSE_EPS) -> float:
    """Relative MSE: mean of (x - ref)^2 / (ref^2 + eps), over the (H, W) ``mask`` if given."""
    ref = np.asarray(reference, np.float64)
    err = np.square(np.asarray(image, np.float64) - ref) / (ref * ref + eps)
    if mask is not None:
        err = err[mask]
    return float(np.mean(err)) if err.size else float("nan")


def relmse_map(image: np.ndarray, reference: np.ndarray, eps: float = RELMSE_EPS) -> np.ndarray:
    """relMSE per pixel, (H, W): the mean over channels of (x - ref)^2 / (ref^2 + eps)."""
    check_shapes(image, reference)
    ref = np.asarray(reference, np.float64)
    return (np.square(np.asarray(image, np.float64) - ref) / (ref * ref + eps)).mean(axis=-1)


#: Share of the largest per-pixel errors left out by :func:`relmse_rejected` (SeeSharp's
#: ``RelMSE_OutlierRejection`` default).
OUTLIER_SHARE = 0.001


def relmse_rejected(image: np.ndarray, reference: np.ndarray, share: float = OUTLIER_SHARE,
                    floor_map: np.ndarray | None = None) -> float:
    """relMSE with the top ``share`` of the pixels' errors left out (a few fireflies or the
    edges of a directly visible light then do not rule it). ``floor_map``: the reference's
    own expected relMSE per pixel and channel (subtracted over the pixels kept)."""
    err = relmse_map(image, reference).ravel()
    keep = err.size - int(math.floor(share * err.size))
    order = np.argsort(err, kind="stable")[:keep]
    value = float(err[order].mean())
    if floor_map is not None:
        value -= float(np.asarray(floor_map, np.float64).mean(axis=-1).ravel()[order].mean())
    return value


#: Recent FLIP results, keyed by a hash of both images (a report shows an image's FLIP
#: in a table and its FLIP map in the viewer: computed once).
_FLIP_CACHE: dict[bytes, tuple[np.ndarray, float]] = {}
_FLIP_CACHE_SIZE = 32


def flip(image: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, float]:
    """HDR-FLIP of ``image`` against ``reference``: the (H, W) error map and its mean.

    Computed by NVIDIA's ``flip-evaluator`` (default viewing conditions, 67
    pixels per degree; exposure range chosen from the reference). FLIP needs
    finite non-negative radiance: NaN, infinite and negative values count as 0.
    """
    import flip_evaluator
    check_shapes(image, reference)
    test, ref = _finite_nonnegative(image), _finite_nonnegative(reference)
    key = hashlib.sha1(repr(test.shape).encode() + test.tobytes() + ref.tobytes()).digest()
    if key not in _FLIP_CACHE:
        error, mean, _ = flip_evaluator.evaluate(ref, test, "HDR", applyMagma=False)
        if len(_FLIP_CACHE) >= _FLIP_CACHE_SIZE:
            _FLIP_CACHE.pop(next(iter(_FLIP_CACHE)))
        _FLIP_CACHE[key] = (np.asarray(error, np.float32).reshape(test.shape[:2]), float(mean))
    error, mean = _FLIP_CACHE[key]
    return error.copy(), mean


def flip_mean(image: np.ndarray, reference: np.ndarray) -> float:
    """Mean HDR-FLIP (see :func:`flip`)."""
    return flip(image, reference)[1]


def _finite_nonnegative(image) -> np.ndarray:
    """float32 copy with NaN, infinities and negative values set to 0 (FLIP's HDR input)."""
    x = np.asarray(image, np.float32)
    return np.ascontiguousarray(np.where(np.isfinite(x) & (x > 0), x, np.float32(0)))


def check_shapes(image, reference) -> None:
    """Raise ValueError naming both shapes when ``image`` and ``reference`` differ."""
    if np.shape(image) != np.shape(reference):
        raise ValueError(f"image shape {np.shape(image)} differs from the reference's "
                         f"{np.shape(reference)}")


METRICS = {"mse": mse, "relmse": relmse, "rmse": rmse, "flip": flip_mean}


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
    if np.unique(x[keep]).size < 2:          # no slope through one abscissa
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


#: Slope of MSE against spp that a converging deterministic estimator must reach.
CONVERGENCE_SLOPE = -0.5


def deterministic_check(spps, images, reference, ref_var) -> dict:
    """Does a deterministic estimator (plain Halton) converge to the reference?

    Plain Halton uses the same points in every pixel and every run, so its
    passes are not independent and the spread of 1-spp passes says nothing
    about its error: a z-test does not apply. What does apply to a
    deterministic sequence is convergence: its error against the (random,
    unbiased) reference must fall as the sample count grows. Returns, at
    each sample count, MSE and the per-channel image-mean difference, the
    fitted slope of MSE against spp, and ``converges``: the MSE at the
    largest count is below the MSE at the smallest and falls at least as
    fast as spp^-1/2 (slope <= :data:`CONVERGENCE_SLOPE`; random sampling
    gives -1, a working low-discrepancy sequence -1 or steeper, a biased
    estimator flattens out at 0).
    ``floor`` is the reference's own expected MSE (from ``ref_var``), under
    which no error can be resolved.
    """
    mses = [mse(im, reference) for im in images]
    diffs = [(np.asarray(im, np.float64) - reference).reshape(-1, 3).mean(axis=0).tolist()
             for im in images]
    slope = loglog_slope(spps, mses)
    return {"spp": list(spps), "mse": mses, "mean_diff": diffs, "slope": slope,
            "floor": float(np.mean(ref_var)),
            "converges": bool(mses[-1] < mses[0] and slope <= CONVERGENCE_SLOPE)}


# ---------------------------------------------------------------- outliers

#: A firefly is a pixel whose error exceeds the median error by this many MADs.
FIREFLY_MADS = 10.0


def luminance(image: np.ndarray) -> np.ndarray:
    return image[..., 0] * 0.2126 + image[..., 1] * 0.7152 + image[..., 2] * 0.0722


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


# ------------------------------------------------------------ breakdown points

def first_where(xs, condition) -> object | None:
    """The first x (in the given order) whose condition holds, or None."""
    for x, c in zip(xs, condition):
        if c:
            return x
    return None


def ratio(a: float, b: float) -> float:
    return a / b if b > 0 else float("inf")
