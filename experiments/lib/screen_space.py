"""Screen-space error: the error image, its power spectrum and its low-frequency share.

Pure numpy, no rendering and no files. The error of a render is a field over the pixels:
:func:`error_field` is the luminance of render minus reference with its mean subtracted
(a constant offset carries no spatial structure). Its power spectrum
(:func:`periodogram`) is ``|FFT|^2 / N`` on the FFT's frequency grid (cycles per pixel,
:func:`radius`), scaled so that white noise of per-pixel variance s^2 has expected power
s^2 at every frequency but 0 (which the mean subtraction sets to 0). Two summaries:

- :func:`radial_average`: the mean over rings of equal |f| (the one definition; the lab's
  point-set spectra use it too);
- :func:`low_share`: the power below :data:`LOW` cycles per pixel (a quarter of the
  Nyquist frequency) over the total. White noise gives the share of the grid's
  frequencies in that disc, :func:`white_share` (about pi 0.125^2 = 0.049); error that
  the sampler pushes to high frequencies (blue noise) gives less, smooth (red) error more.

The reference is itself noisy: its independent pixels add white power, about the mean
over pixels of the variance of its luminance (:func:`reference_floor`, from the spread of
its chunks), to every frequency of the error's expected spectrum. The ``floor`` arguments
subtract it, so that the shares and spectra are the render's own.
"""
from __future__ import annotations

import math

import numpy as np

from .metrics import luminance

#: The low-frequency cutoff: a quarter of the Nyquist frequency, in cycles per pixel.
LOW = 0.125


def error_field(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Luminance of ``image - reference`` ((H, W, 3) linear RGB), mean subtracted: (H, W)."""
    image, reference = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    if image.shape != reference.shape or image.ndim != 3 or image.shape[-1] < 3:
        raise ValueError(f"error_field needs two (H, W, 3) images of one shape, got "
                         f"{image.shape} and {reference.shape}")
    bad = int(np.count_nonzero(~np.isfinite(image[..., :3]).all(axis=-1)))
    if bad:
        raise ValueError(f"the image has {bad} non-finite pixel(s): its error spectrum "
                         f"would be meaningless")
    y = luminance(image[..., :3] - reference[..., :3])
    return y - y.mean()


def periodogram(field: np.ndarray) -> np.ndarray:
    """``|FFT(field - mean)|^2 / N`` of (..., H, W) fields, in FFT order (frequency 0 at
    [0, 0], which is 0)."""
    f = np.asarray(field, np.float64)
    f = f - f.mean(axis=(-2, -1), keepdims=True)
    p = np.abs(np.fft.fft2(f)) ** 2 / (f.shape[-2] * f.shape[-1])
    p[..., 0, 0] = 0.0
    return p


def radius(shape) -> np.ndarray:
    """|f| in cycles per pixel of every bin of an (H, W) FFT grid (FFT order)."""
    h, w = shape[-2:]
    return np.hypot(np.fft.fftfreq(h)[:, None], np.fft.fftfreq(w)[None, :])


def radial_average(power: np.ndarray, radii: np.ndarray, step: float,
                   count: int) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies ``step`` x 1..``count``, mean of ``power`` (..., *radii.shape) over
    the bins whose radius lies within half a ``step`` of each frequency)."""
    bins = np.rint(np.asarray(radii) / step).astype(int).ravel()
    flat = np.asarray(power).reshape(-1, bins.size)
    out = np.stack([flat[:, bins == k].mean(axis=1) for k in range(1, count + 1)], axis=1)
    return np.arange(1, count + 1) * step, out.reshape(np.shape(power)[:-radii.ndim]
                                                        + (count,))


def spectrum(power: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The radial average of an (..., H, W) periodogram in rings 1 / max(H, W) wide, up
    to the Nyquist frequency 0.5: (frequencies in cycles per pixel, power)."""
    h, w = np.shape(power)[-2:]
    n = max(h, w)
    return radial_average(power, radius((h, w)), 1.0 / n, n // 2)


def _masks(shape) -> tuple[np.ndarray, np.ndarray]:
    r = radius(shape)
    return (r > 0) & (r < LOW), r > 0


def low_share(power: np.ndarray, floor: float = 0.0) -> float:
    """Power at 0 < |f| < :data:`LOW` over the power at every |f| > 0, of an (H, W)
    periodogram, ``floor`` (white power of the reference's own noise) subtracted from
    every bin first."""
    p = np.asarray(power, np.float64)
    low, every = _masks(p.shape)
    total = float((p[every] - floor).sum())
    if not total > 0:
        raise ValueError(f"no power above the floor ({floor:.3g}): the error cannot be "
                         f"told from the reference's own noise")
    return float((p[low] - floor).sum()) / total


def white_share(shape) -> float:
    """:func:`low_share` of white noise on an (H, W) grid: the share of its nonzero
    frequencies below :data:`LOW` (tends to pi LOW^2 = 0.049)."""
    low, every = _masks(tuple(shape)[-2:])
    return float(low.sum()) / float(every.sum())


def normalized(power: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """An (..., H, W) periodogram minus ``floor``, divided by its mean over |f| > 0:
    white noise is 1 at every frequency."""
    p = np.asarray(power, np.float64) - floor
    _, every = _masks(p.shape)
    p[..., ~every] = 0.0
    mean = p[..., every].mean(axis=-1)
    return p / np.where(mean > 0, mean, math.nan)[..., None, None]


def reference_floor(images, counts) -> float:
    """The white power a reference adds to an error spectrum: the mean over pixels of the
    variance of its luminance, estimated from the spread of its chunk images (``images``,
    each the mean of ``counts`` samples per pixel; at least two)."""
    k = np.asarray(counts, np.float64)
    if k.size < 2:
        raise ValueError(f"a reference of {k.size} chunk has no spread: its own noise "
                         f"cannot be estimated (render it in at least two chunks)")
    y = np.stack([luminance(np.asarray(im, np.float64)[..., :3]) for im in images])
    mean = np.tensordot(k, y, axes=1) / k.sum()
    s2 = np.tensordot(k, (y - mean) ** 2, axes=1) / (k.size - 1)    # per-sample variance
    return float(np.mean(s2 / k.sum()))
