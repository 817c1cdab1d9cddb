"""The sampling lab's point sets: what each sampler gives one pixel, as a render draws it.

:func:`draw` drives a sampler as Mitsuba's render loop does in a JIT variant:
``set_sample_count(spp)`` (Mitsuba's samplers round some counts up: the count
actually drawn is ``sample_count()`` afterwards), ``set_samples_per_wavefront``
(C++ samplers only: Mitsuba's C++ render loop calls it, a Python sampler
never sees that call), ``seed(seed, width * height * spp)``, then the calls a
path tracer makes in their order, lane ``l`` being sample ``l % spp`` of pixel
``l // spp``. The tests compare these points with what an instrumented
``mi.render`` receives.

"Dimension k" is the k-th float a sample draws, counting 2 per ``next_2d``
(as Mitsuba's samplers count calls, and the bundled ``halton`` counts
dimensions: dimension k there is the radical inverse in the k-th prime base).
:data:`PATTERN` is ``vr_path`` with next-event estimation (``bsdf+nee``, the
sampler study's base method): the camera's ``next_2d`` (film position in the
pixel; dimensions 0, 1), then per bounce ``next_2d`` (emitter sample),
``next_1d`` (BSDF lobe choice), ``next_2d`` (direction) and ``next_1d``
(Russian roulette): 6 dimensions per bounce, bounce b starting at 2 + 6 b.
Every lane draws every call (masked lanes too), so dimension k is the same
call in every lane.

Numbers per point set (a pair of dimensions of one pixel's points):
:func:`centered_discrepancy` (Hickernell's centered L2 discrepancy, squared,
as ``scipy.stats.qmc.discrepancy(method="CD")``) and :func:`power_spectrum`
(pbrt-v4's ``pspec``: the periodogram |sum_j exp(-2 pi i k . x_j)|^2 / N on
the integer frequencies k in [-K, K]^2, radially averaged; 1 everywhere for
independent points, near 0 at low frequencies for well-stratified ones) and
:func:`joint_power` (the periodogram's mean at low frequencies off the axes:
below 1 only where the two dimensions are stratified jointly, which the
discrepancy, dominated by the 1-D projections, hardly tells from a Latin
hypercube).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from experiments.lib import files, screen_space
from experiments.lib.samplers import DEFAULT, label_dict, labels

#: The calls of one sample, in order: ("2d", what) or ("1d", what).
CAMERA = (("2d", "camera: film position"),)
BOUNCE = (("2d", "emitter sample (NEE)"), ("1d", "BSDF lobe choice"),
          ("2d", "BSDF direction"), ("1d", "Russian roulette"))
BOUNCES = 5
PATTERN = CAMERA + BOUNCE * BOUNCES
#: The dimension pairs the lab shows; (1, 2) crosses two calls on purpose.
PAIRS = ((0, 1), (2, 3), (10, 11), (30, 31), (1, 2))
COUNTS = (64, 256)
VERSION = 4


def samplers() -> list[str]:
    """Every registered sampler with each randomization (the sampler study's list)."""
    return labels()


def dimensions(pattern=PATTERN) -> list[tuple[int, str, int]]:
    """(call index, what, component) of every dimension of ``pattern``."""
    dims = []
    for call, (kind, what) in enumerate(pattern):
        for component in range(2 if kind == "2d" else 1):
            dims.append((call, what, component))
    return dims


def describe_pair(a: int, b: int, pattern=PATTERN) -> str:
    """What a pair of dimensions is in ``vr_path`` (bsdf+nee)."""
    dims = dimensions(pattern)

    def where(call):
        if call < len(CAMERA):
            return ""
        return f" (bounce {(call - len(CAMERA)) // len(BOUNCE) + 1})"

    def one(k):
        call, what, comp = dims[k]
        axis = f" {'xy'[comp]}" if pattern[call][0] == "2d" else ""
        return f"{what}{axis}{where(call)}"
    if dims[a][0] == dims[b][0]:
        return f"one next_2d: {dims[a][1]}{where(dims[a][0])}"
    return f"two calls: {one(a)} / {one(b)}"


def is_python_sampler(sampler) -> bool:
    """A sampler class defined in Python (C++ calls to it are not all forwarded)."""
    return not type(sampler).__module__.startswith("mitsuba")


def draw(name: str, spp: int, seed: int, width: int, height: int, pattern=PATTERN):
    """(points (pixels, count, dims) float64, count drawn): every sample of every pixel
    of a width x height render of ``spp`` samples, driven as ``mi.render`` drives it."""
    import drjit as dr
    import mitsuba as mi
    sampler = mi.load_dict(label_dict(name, spp, width, height))
    sampler.set_sample_count(spp)
    count = sampler.sample_count()
    lanes = width * height * count
    if not is_python_sampler(sampler):
        sampler.set_samples_per_wavefront(count)
    sampler.seed(seed, lanes)
    values = []
    for kind, _ in pattern:
        if kind == "2d":
            p = sampler.next_2d()
            values += [p.x, p.y]
        else:
            values.append(sampler.next_1d())
    dr.eval(values)
    pts = np.stack([np.asarray(v, np.float64) for v in values], axis=1)
    return pts.reshape(width * height, count, len(values)), count


# ------------------------------------------------------------------ numbers

def centered_discrepancy(points: np.ndarray) -> np.ndarray:
    """Squared centered L2 discrepancy (Hickernell 1998) of point sets ``points``
    (..., N, d) in [0, 1]^d, as scipy.stats.qmc.discrepancy(method="CD")."""
    x = np.asarray(points, np.float64)
    n, d = x.shape[-2], x.shape[-1]
    c = np.abs(x - 0.5)
    term1 = (13.0 / 12.0) ** d
    term2 = np.prod(1.0 + 0.5 * c - 0.5 * c * c, axis=-1).sum(axis=-1) * (2.0 / n)
    term3 = None
    for k in range(d):       # one (..., N, N) factor per dimension
        ck, xk = c[..., k], x[..., k]
        factor = 1.0 + 0.5 * (ck[..., :, None] + ck[..., None, :]) \
            - 0.5 * np.abs(xk[..., :, None] - xk[..., None, :])
        term3 = factor if term3 is None else term3 * factor
    return term1 - term2 + term3.sum(axis=(-1, -2)) / n ** 2


def periodogram(points: np.ndarray, k_max: int) -> np.ndarray:
    """|sum_j exp(-2 pi i k . x_j)|^2 / N for k in [-k_max, k_max]^2, of point sets
    ``points`` (..., N, 2): (..., 2 k_max + 1, 2 k_max + 1), axis -2 is k_x.

    The sum factors as sum_j e_x(j, k_x) e_y(j, k_y): one real matrix product of
    [cos | sin] of both coordinates gives its real and imaginary parts. Only
    k_x >= 0 is computed; P(-k) = P(k) gives the rest."""
    # float32 throughout: the spectrum is for display and averages (errors ~1e-5);
    # einsum, not a threaded BLAS matmul, whose threads stall on a busy machine
    x = np.asarray(points, np.float32)
    kx = np.arange(0, k_max + 1, dtype=np.float32)
    ky = np.arange(-k_max, k_max + 1, dtype=np.float32)
    ax = np.float32(2.0 * np.pi) * x[..., 0, None] * kx
    ay = np.float32(2.0 * np.pi) * x[..., 1, None] * ky
    a = np.concatenate([np.cos(ax), np.sin(ax)], axis=-1)        # (..., N, 2 (K + 1))
    b = np.concatenate([np.cos(ay), np.sin(ay)], axis=-1)        # (..., N, 2 (2K + 1))
    m = np.einsum("...nk,...nl->...kl", a, b)
    nx, ny = len(kx), len(ky)
    re = m[..., :nx, :ny] - m[..., nx:, ny:]
    im = m[..., :nx, ny:] + m[..., nx:, :ny]
    half = (re.astype(np.float64) ** 2 + im.astype(np.float64) ** 2) / x.shape[-2]
    # k_x < 0: P(-k_x, k_y) = P(k_x, -k_y)
    neg = half[..., :0:-1, ::-1]
    return np.concatenate([neg, half], axis=-2)


def radial_average(spectrum: np.ndarray, k_max: int) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies 1..k_max, mean of ``spectrum`` over |k| in [f - 0.5, f + 0.5)), by
    :func:`.screen_space.radial_average` (the one definition)."""
    k = np.arange(-k_max, k_max + 1)
    r = np.sqrt(k[:, None] ** 2 + k[None, :] ** 2)
    return screen_space.radial_average(spectrum, r, 1, k_max)


def power_spectrum(points: np.ndarray, k_max: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Radially averaged power spectrum of point sets (..., N, 2), averaged over
    every leading axis (pixels, randomizations): (frequencies, power, joint power),
    see :func:`joint_power`."""
    p = periodogram(points, k_max)
    p = p.reshape((-1,) + p.shape[-2:]).mean(axis=0)
    freqs, power = radial_average(p, k_max)
    return freqs, power, joint_power(p, k_max, points.shape[-2])


def joint_power(mean_periodogram: np.ndarray, k_max: int, n: int) -> float:
    """Mean power at the low frequencies off the axes: 0 < |k_x|, 0 < |k_y|, |k| <=
    sqrt(N) / 2. 1-D stratification of either coordinate (a Latin hypercube, two
    stratified calls paired at random) lowers only the axes k_x = 0 or k_y = 0;
    this number falls below 1 only where the pair is stratified jointly."""
    k = np.arange(-k_max, k_max + 1)
    kx, ky = np.meshgrid(k, k, indexing="ij")
    radius = max(1.0, math.sqrt(n) / 2.0)
    sel = (kx != 0) & (ky != 0) & (kx ** 2 + ky ** 2 <= radius ** 2)
    return float(mean_periodogram[sel].mean())


# --------------------------------------------------------------- a point set

@dataclass(frozen=True)
class PointSpec:
    sampler: str
    spp: int
    seeds: tuple = (0,)
    width: int = 8
    height: int = 8
    k_max: float = 1.5      # frequencies up to k_max * sqrt(count) (a stratified set's
                            # dip lies below sqrt(count))
    cd_pixels: int = 16     # pixels whose discrepancy is computed (O(N^2) each)
    spectrum_points: int = 2048  # spectra averaged over this many points' pixels (>= 8)
    scatter_pixel: int = 0

    def key(self) -> str:
        text = json.dumps({"v": VERSION, **self.__dict__, "pattern": PATTERN, "pairs": PAIRS},
                          sort_keys=True, default=list)
        slug = self.sampler.replace(":", "-")
        return f"{slug}-{self.spp}-{hashlib.sha1(text.encode()).hexdigest()[:10]}"


def compute(spec: PointSpec) -> dict:
    """Per pair: the scatter (the points of one pixel, first seed), the discrepancy of
    every pixel and seed, and the power spectrum averaged over them."""
    sets = []
    count = None
    for seed in spec.seeds:
        pts, count = draw(spec.sampler, spec.spp, seed, spec.width, spec.height)
        sets.append(pts)
    pts = np.stack(sets)                         # (seeds, pixels, count, dims)
    out = {"count": count}
    for a, b in PAIRS:
        pair = pts[..., [a, b]]
        tag = f"{a}_{b}"
        out[f"scatter_{tag}"] = pair[0, spec.scatter_pixel].astype(np.float32)
        out[f"cd_{tag}"] = centered_discrepancy(pair[:, :spec.cd_pixels]).ravel()
        sets = max(8, spec.spectrum_points // count)
        freqs, power, joint = power_spectrum(pair[:, :sets],
                                             int(math.ceil(spec.k_max * math.sqrt(count))))
        out[f"power_{tag}"] = power
        out[f"joint_{tag}"] = joint
        out["freqs"] = freqs
    return out


def cached(spec: PointSpec, cache_dir: str) -> dict:
    """:func:`compute`, or the result an earlier run stored for the same settings."""
    import os
    path = os.path.join(cache_dir, spec.key() + ".npz")
    data = files.read_npz(path)
    if data is not None:
        data["count"] = int(data["count"])
        return data
    result = compute(spec)
    files.write_npz(path, **{k: np.asarray(v) for k, v in result.items()})
    return result


def random_expectation(count: int, d: int = 2) -> float:
    """E[squared CD] of ``count`` independent uniform points in d dimensions:
    ((5/4)^d - (13/12)^d) / count (the kernel's mean on the diagonal minus its mean)."""
    return ((5.0 / 4.0) ** d - (13.0 / 12.0) ** d) / count


#: Ratio of a pair's discrepancy to independent points' expectation above which
#: the lab says the pair has lost its stratification.
LOST = 0.5
#: Joint low-frequency power (see joint_power) below which a pair is stratified in 2-D.
JOINT = 0.8


#: The pair of the first bounce's emitter sample (NEE), which sets the direct light.
NEE = (2, 3)
#: Pairs of deeper bounces (they matter only at larger max_depth).
DEEP = ((10, 11), (30, 31))


@dataclass(frozen=True)
class PointRow:
    """One label's point set at one count: a row of the point sets' conclusion table."""
    sampler: str
    family: str                 # its sampler (SamplerSpec.name)
    native: bool                # one of Mitsuba's own samplers
    count: int                  # points drawn
    joint: tuple                # pairs stratified jointly (2-D)
    coordinate: tuple           # pairs stratified only per coordinate (1-D)
    lost: tuple                 # pairs whose discrepancy is that of independent points
    nee: float                  # discrepancy / independent points' at NEE (nan: not drawn)
    nee_joint: float            # joint low-frequency power at NEE
    deep: float                 # the largest ratio over the DEEP pairs (nan: none drawn)

    def cells(self) -> list:
        def pairs(ps):
            return " ".join(f"({a},{b})" for a, b in ps) or "-"
        return [self.sampler, "native" if self.native else "bundled", self.count,
                pairs(self.joint), pairs(self.coordinate), pairs(self.lost),
                f"{self.nee:.3g}", f"{self.nee_joint:.2f}", f"{self.deep:.3g}"]


HEADER = ["sampler", "kind", "points", "stratified jointly (2-D)",
          "only per coordinate (1-D)", "lost", f"discrepancy / independent at {NEE}",
          f"joint power at {NEE}", "largest discrepancy / independent, deeper bounces"]


@dataclass(frozen=True)
class Findings:
    spp: int                    # the count requested
    rows: list                  # PointRow per label (the baseline left out)
    sentences: list


def analyse(cd: dict, joint: dict, counts: dict, spp: int, kinds: dict,
            baseline: str = DEFAULT) -> Findings:
    """The point sets' conclusion from ``cd[(label, pair)]`` (mean squared CD) and
    ``joint[(label, pair)]`` (:func:`joint_power`) at ``spp`` requested (``counts[label]``
    drawn); ``kinds[label]`` has the label's sampler ``name`` and whether it is ``native``
    (the sampler table's). Pure: a table (which pairs each label stratifies) and at most
    three sentences computed from it."""
    names = [s for s in dict.fromkeys(s for s, _ in cd) if s != baseline]
    pairs = sorted({p for _, p in cd}, key=PAIRS.index)

    def ratio(s, pair):
        return cd[(s, pair)] / random_expectation(counts[s])
    rows = []
    for s in names:
        two = tuple(p for p in pairs if ratio(s, p) < LOST and joint[(s, p)] < JOINT)
        one = tuple(p for p in pairs if ratio(s, p) < LOST and p not in two)
        lost = tuple(p for p in pairs if ratio(s, p) >= LOST)
        deep = [ratio(s, p) for p in DEEP if p in pairs]
        rows.append(PointRow(s, kinds[s].name, kinds[s].native, counts[s], two, one, lost,
                             ratio(s, NEE) if NEE in pairs else math.nan,
                             joint[(s, NEE)] if NEE in pairs else math.nan,
                             max(deep) if deep else math.nan))
    within = tuple(p for p in pairs if describe_pair(*p).startswith("one next_2d"))
    return Findings(spp, rows, sentences(rows, within, spp))


def sentences(rows: list[PointRow], within: tuple, spp: int) -> list[str]:
    """At most three sentences, from the table's rows alone: what the native samplers
    stratify, what each bundled family's best does to the NEE sample against the best
    native one (a prediction for the sampler study), and the deeper bounces."""
    native = [r for r in rows if r.native]
    bundled = [r for r in rows if not r.native]
    out = []
    if native:
        common = [p for p in within if all(p in r.joint for r in native)]
        shown = native[0].joint + native[0].coordinate + native[0].lost
        crossing = [p for p in shown if p not in within]
        across = [r.sampler for r in native
                  if crossing and all(p in r.joint for p in crossing)]
        out.append(
            f"At {spp} spp the native samplers stratify jointly (2-D) "
            + (", ".join(map(str, common)) if common else "no pair that all of them share")
            + (f"; {', '.join(across)} also every pair across calls (an orthogonal array)"
               if across else "")
            + f" (ratio {LOST} or more of independent points' discrepancy: lost; joint "
              f"power below {JOINT}: 2-D).")
    if native and bundled and not math.isnan(native[0].nee):
        top = min(native, key=lambda r: r.nee)
        best = {}
        for r in bundled:
            if r.family not in best or r.nee < best[r.family].nee:
                best[r.family] = r
        parts = [f"{r.sampler} {r.nee:.3g} (joint power {r.nee_joint:.2f}: expect "
                 f"{'higher' if r.nee > top.nee else 'lower'} MSE than {top.sampler} at "
                 f"max_depth 2)" for r in best.values()]
        out.append(f"Dims {NEE}, the first bounce's emitter sample, set the direct light: "
                   f"the best native sampler, {top.sampler}, reaches {top.nee:.3g} of "
                   f"independent points' discrepancy (joint power {top.nee_joint:.2f}); "
                   f"the best of each bundled sampler: " + "; ".join(parts)
                   + " (the sampler study measures it).")
    if rows and not math.isnan(rows[0].deep):
        def span(rs):
            lo, hi = min(r.deep for r in rs), max(r.deep for r in rs)
            return f"{lo:.3g}" if lo == hi else f"{lo:.3g}-{hi:.3g}"
        families = list(dict.fromkeys(r.family for r in bundled))
        parts = [f"{f} {span([r for r in bundled if r.family == f])}" for f in families]
        out.append(f"Deeper bounces ({', '.join(str(p) for p in DEEP)}): discrepancy over "
                   f"independent points' "
                   + (f"for the native samplers {span(native)}" if native else "")
                   + ("; " if native and parts else "") + "; ".join(parts)
                   + f" (near 1: sampled little better than by independent points).")
    return out
