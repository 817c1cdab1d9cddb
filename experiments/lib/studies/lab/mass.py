"""The lab's mass and albedo checks: what a chi-square test of a warp cannot see.

A chi-square test compares the shape of a strategy's histogram with its density. A
strategy whose density is off by a constant factor, the writeup's "pixels get darker with
more samples" class of bug, can pass it (on a cap grid, or where the factor is in the
density the weights use and not in the one the test reads). Two checks see it:

* **mass**: the density's integral over the sphere equals the share of directions the
  strategy draws (a failed sample has weight 0). ``mass`` = the quadrature of the
  strategy's ``pdf`` over the sphere, times the mean over the drawn samples of the density
  reported with each sample over ``pdf`` at its direction (1 for a consistent strategy;
  a strategy that weights its samples by another density than it reports is caught here).
* **albedo**: the expected weight E[f cos / pdf] over the strategy's samples equals the
  BSDF's albedo, the quadrature of ``bsdf.eval`` (f cos) over the sphere.

Quadrature: the trapezoid tabulation of the panel's grid (:func:`.lab.warps.tabulate`),
over the panel's domain and, for a cap, over the rest of the sphere about the same axis
(:class:`Band`); its error is bounded by the difference with the same rule at half the
points per cell (a trapezoid rule's error falls at least linearly with the spacing, so
the difference bounds the finer rule's error).

Intervals: each ratio (estimate over target) gets the interval ratio x (1 +- h), with
h = z x the relative standard error of the sampled side plus the relative quadrature
bound; z is the normal quantile of a two-sided test at the Sidak level of the family (all
checks of one lab run, :func:`z_value`). A check **fails** when its interval lies outside
1 +- :data:`TOLERANCE` (a relative tolerance floor: errors below it are not flagged);
it **cannot decide** (never a silent pass) when h exceeds :data:`WIDE`, or when the
weights' tails are too heavy for the normal approximation of their mean (Cochran's rule:
fewer than :data:`SKEW_SAMPLES` x skewness^2 samples, applied where the sampling error
z x se exceeds a quarter of the tolerance: below that the tails cannot move the
verdict); it **passes** otherwise.
Analysis only: the report layer words it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from integrators.chi2 import EqualAreaDomain

#: Relative tolerance floor: a ratio within 1 +- TOLERANCE (beyond its interval) passes.
TOLERANCE = 0.02
#: A check whose relative half-width exceeds WIDE cannot decide (a 10% error might hide).
WIDE = 0.05
#: Cochran's rule for the normal approximation of a skewed mean: n >= SKEW_SAMPLES g^2.
SKEW_SAMPLES = 25.0
#: Family level of the checks of one lab run (Sidak over them).
LEVEL = 0.01
#: The verdicts.
PASS, FAIL, UNDECIDED = "pass", "fail", "cannot decide"


class Band(EqualAreaDomain):
    """The sphere about ``axis`` outside the cap cos alpha >= ``cos_max``: (phi, cos alpha)
    with cos alpha in [-1, ``cos_max``] (the complement of a cap domain)."""

    def __init__(self, axis, cos_max: float):
        super().__init__(axis, -1.0)
        self.cos_max = float(cos_max)

    def bounds(self):
        import mitsuba as mi
        return mi.ScalarBoundingBox2f([-math.pi, -1.0], [math.pi, self.cos_max])


def sphere_integral(tabulate, domain, func, res: int, ires: int,
                    inside=None) -> tuple[float, float]:
    """(integral of ``func`` over the whole sphere, bound on its quadrature error):
    ``domain``'s tabulation by ``tabulate`` (:func:`.lab.warps.tabulate`; ``inside``: its
    sum at ``ires``, when already computed) plus, for a cap, the band outside it; the
    bound is the difference with ``ires // 2`` points per cell and axis."""
    parts = [domain] if domain.cos_min <= -1.0 else [domain, Band(domain.axis, domain.cos_min)]
    fine = coarse = 0.0
    for k, part in enumerate(parts):
        fine += (float(inside) if k == 0 and inside is not None
                 else float(np.sum(tabulate(part, func, 1, res, ires))))
        coarse += float(np.sum(tabulate(part, func, 1, res, max(2, ires // 2))))
    return fine, abs(fine - coarse)


def sample_moments(weight: np.ndarray, ratio: np.ndarray) -> dict:
    """The sampled sides of both checks, from the per-sample weights (0 where nothing was
    drawn) and the drawn samples' reported-over-``pdf`` density ratios."""
    w = np.asarray(weight, np.float64)
    n = max(1, w.size)
    mean = float(np.mean(w)) if w.size else 0.0
    sd = float(np.std(w)) if w.size else 0.0
    skew = float(np.mean((w - mean) ** 3) / sd ** 3) if sd > 0 else 0.0
    r = np.asarray(ratio, np.float64)
    return {"albedo_se": sd / math.sqrt(n), "weight_skewness": skew,
            "pdf_ratio": float(np.mean(r)) if r.size else 1.0,
            "pdf_ratio_se": float(np.std(r)) / math.sqrt(r.size) if r.size else 0.0}


#: The panel scalars these checks add (:func:`.lab.warps.compute`).
SCALARS = ("mass", "mass_error", "pdf_ratio", "pdf_ratio_se", "albedo_quadrature",
           "albedo_error", "albedo_se", "weight_skewness")


# -------------------------------------------------------------- the checks

@dataclass(frozen=True)
class Check:
    """One check of one panel: the ratio estimate / target, its interval and verdict."""
    ratio: float
    low: float
    high: float
    half_width: float            # relative: the interval is ratio x (1 +- half_width)
    verdict: str                 # PASS, FAIL or UNDECIDED
    reason: str                  # why it cannot decide ('' otherwise): 'wide', 'heavy tails',
                                 # 'nothing to compare'


def z_value(tests: int, level: float = LEVEL) -> float:
    """Two-sided normal quantile at the Sidak level of ``tests`` tests at family ``level``."""
    from scipy import stats
    alpha = 1.0 - (1.0 - level) ** (1.0 / max(1, tests))
    return float(stats.norm.isf(alpha / 2))


def check(estimate: float, target: float, rel_se: float, rel_quadrature: float, z: float,
          samples: int = 0, skewness: float = 0.0) -> Check:
    """The verdict on ``estimate`` against ``target`` (see the module docs)."""
    if not (target > 0 and math.isfinite(estimate) and math.isfinite(target)):
        return Check(math.nan, math.nan, math.nan, math.inf, UNDECIDED, "nothing to compare")
    ratio = estimate / target
    h = z * rel_se + rel_quadrature
    low, high = ratio * (1 - h), ratio * (1 + h)
    if samples and z * rel_se > TOLERANCE / 4 and samples < SKEW_SAMPLES * skewness ** 2:
        return Check(ratio, low, high, h, UNDECIDED, "heavy tails")
    if low > 1 + TOLERANCE or high < 1 - TOLERANCE:
        return Check(ratio, low, high, h, FAIL, "")
    if h > WIDE:
        return Check(ratio, low, high, h, UNDECIDED, "wide")
    return Check(ratio, low, high, h, PASS, "")


def mass_check(panel: dict, samples: int, z: float) -> Check:
    """mass (quadrature of pdf x reported/pdf ratio) against the share drawn."""
    share = panel["drawn"]
    share_se = math.sqrt(max(share * (1 - share), 1.0 / samples) / samples)
    mass = panel["mass"] * panel["pdf_ratio"]
    rel = math.hypot(share_se / share if share > 0 else math.inf,
                     panel["pdf_ratio_se"] / panel["pdf_ratio"] if panel["pdf_ratio"] else 0)
    quad = panel["mass_error"] / panel["mass"] if panel["mass"] > 0 else math.inf
    return check(mass, share, rel, quad, z)


def albedo_check(panel: dict, samples: int, z: float) -> Check:
    """E[f cos / pdf] over the samples against the quadrature of f cos."""
    mean = panel["albedo"]
    rel = panel["albedo_se"] / mean if mean > 0 else math.inf
    target = panel["albedo_quadrature"]
    quad = panel["albedo_error"] / target if target > 0 else math.inf
    return check(mean, target, rel, quad, z, samples, panel["weight_skewness"])


def checks(panel: dict, samples: int, z: float) -> tuple[Check, Check]:
    """(mass check, albedo check) of one panel (:func:`.lab.warps.compute`'s dict)."""
    return mass_check(panel, samples, z), albedo_check(panel, samples, z)


# ------------------------------------------------------------- analysis

@dataclass(frozen=True)
class CheckRow:
    """One panel's two checks (a row of the report's table)."""
    bsdf: str
    incidence_deg: float
    strategy: str
    mass: Check
    albedo: Check

    @property
    def failed(self) -> bool:
        return FAIL in (self.mass.verdict, self.albedo.verdict)

    @property
    def undecided(self) -> bool:
        return not self.failed and UNDECIDED in (self.mass.verdict, self.albedo.verdict)


@dataclass(frozen=True)
class Findings:
    """The checks of one lab run: the family's z, every panel's row, per strategy the
    counts (panels, failed, undecided)."""
    z: float
    tests: int
    rows: list                  # CheckRow per panel
    per_strategy: list          # (strategy, panels, failed, undecided)
    failed: list                # the CheckRows that fail
    undecided: list             # the CheckRows that cannot decide (and do not fail)


def analyse(rows: list[dict]) -> Findings:
    """Both checks of every panel row (dicts with bsdf, incidence_deg, strategy, samples,
    drawn, albedo and :data:`SCALARS`), one family at :data:`LEVEL` (Sidak over all of
    them). Pure: numbers in, data out."""
    tests = 2 * len(rows)
    z = z_value(tests)
    out = [CheckRow(r["bsdf"], r["incidence_deg"], r["strategy"],
                    *checks(r, int(r["samples"]), z)) for r in rows]
    per = []
    for s in dict.fromkeys(r.strategy for r in out):
        mine = [r for r in out if r.strategy == s]
        per.append((s, len(mine), sum(r.failed for r in mine), sum(r.undecided for r in mine)))
    return Findings(z, tests, out, per, [r for r in out if r.failed],
                    [r for r in out if r.undecided])
