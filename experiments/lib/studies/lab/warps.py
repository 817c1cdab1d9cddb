"""The sampling lab's warp panels: each ``vr_path`` strategy as a warp on one BSDF.

A panel is one strategy (``integrators.choices.STRATEGIES``) on one BSDF at
one incidence angle. Everything comes from the plugin itself:
``integrators.path.sample_direction`` draws the directions (through
``dr.dispatch``, as the render loop does) and ``integrators.path.direction_pdf``
is the density the strategy reports; nothing here re-derives a density.

The grid is the equal-area (Lambert cylindrical) projection of the sphere:
x = phi in [-pi, pi], y = cos(theta) in [-1, 1], so equal areas in the
picture are equal solid angles (d omega = d phi d cos theta). On it a panel
holds:

- ``histogram``: weighted counts of ``samples`` directions (weight 0 for
  draws the strategy did not make, e.g. a failed BSDF sample);
- ``expected``: the strategy's density integrated over every cell, times
  ``samples`` (tabulated by ``mitsuba.chi2.ChiSquareTest.tabulate_pdf``, the
  trapezoid rule with ``ires`` x ``ires`` points per cell);
- ``fcos``: the integrand f * cos integrated over every cell (same rule);
- ``p_value``: Pearson's chi-square test of ``histogram`` against
  ``expected``, cells with expected count below 5 pooled in increasing order
  of expected count as ``mitsuba.chi2`` does (computed here in numpy; the
  tests check it equals ``ChiSquareTest``'s for the same seed and grid);
- ``max_z``: the largest standardized residual (histogram - expected) /
  sqrt(expected) over the cells: about 4-5 for a correct density at this grid
  size, far more where the reported density is wrong;
- ``rel_variance``: Var[w] / E[w]^2 of the per-sample weight w = f cos / pdf
  (the ``weight`` the render loop multiplies its throughput by, mean over RGB),
  estimated from the same samples: the relative variance of a one-sample
  estimate of the BSDF's albedo, which sets how many samples a bounce needs;
- what the chi-square cannot see (a density off by a constant factor): the
  density's integral over the sphere and the albedo from a quadrature of f cos,
  with the sampled sides' standard errors (:mod:`.lab.mass`, which checks them).

The uniform variates are Mitsuba's chi-square test's own (TEA-hashed PCG32
streams, see :func:`variates`), so a panel and ``ChiSquareTest`` with the same
seed draw the same directions.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from integrators.chi2 import EqualAreaDomain, cap_cos_min, interaction

from experiments.lib.studies.lab import mass

#: Pool threshold of the chi-square test (expected count per cell), as mitsuba.chi2.
POOL_THRESHOLD = 5.0
#: Incidence angles of the lab (degrees from the normal).
INCIDENCES = (0.0, 60.0, 85.0)
#: The BSDFs of the lab: (label, Mitsuba dict). Phong with the bundled scene's
#: glossy sphere's specular reflectance (0.7) and a small diffuse part.
BSDFS = tuple(
    [(f"phong n={n:g}", {"type": "phong", "diffuse_reflectance": 0.2,
                         "specular_reflectance": 0.7, "exponent": float(n)})
     for n in (1, 10, 100, 1000)]
    + [("roughconductor a=0.1", {"type": "roughconductor", "alpha": 0.1}),
       ("roughdielectric a=0.3", {"type": "roughdielectric", "alpha": 0.3, "int_ior": 1.5})])
#: Version of the panel computation; part of every cache key.
VERSION = 2
#: Phong exponents from which a panel's grid is a cap about the lobe (see domain_for).
CAP_EXPONENT = 100


@dataclass(frozen=True)
class PanelSpec:
    """One panel: a strategy on one BSDF at one incidence, and the grid."""
    bsdf_label: str
    bsdf: dict
    strategy: str
    incidence_deg: float
    samples: int = 1_000_000
    seed: int = 0
    res: int = 101          # cells along each axis of the equal-area grid
    ires: int = 16          # integration points per cell and axis (>= 2)
    scatter: int = 3000     # directions kept for the scatter plot

    def key(self) -> str:
        """Cache key: a hash of every setting (and of VERSION)."""
        text = json.dumps({"v": VERSION, "bsdf": self.bsdf, "strategy": self.strategy,
                           "incidence": self.incidence_deg, "samples": self.samples,
                           "seed": self.seed, "res": self.res, "ires": self.ires,
                           "scatter": self.scatter}, sort_keys=True)
        slug = f"{self.bsdf_label}-{self.strategy}-{self.incidence_deg:g}".replace(" ", "_")
        slug = "".join(c if c.isalnum() or c in "-_." else "_" for c in slug)
        return f"{slug}-{hashlib.sha1(text.encode()).hexdigest()[:10]}"


def plan(strategies, samples: int, seed: int, bsdfs=BSDFS, incidences=INCIDENCES,
         **grid) -> list[PanelSpec]:
    """Every (BSDF, incidence, strategy) panel, each with its own seed (correlated
    p-values otherwise: every panel would draw the same variates)."""
    specs = []
    for label, bsdf in bsdfs:
        for inc in incidences:
            for strategy in strategies:
                specs.append(PanelSpec(label, bsdf, strategy, float(inc), samples,
                                       seed * 7919 + len(specs), **grid))
    return specs


# ------------------------------------------------------------------ domain

def domain_for(spec: "PanelSpec") -> EqualAreaDomain:
    """The grid of a panel: the whole sphere, except for Phong lobes of exponent
    >= CAP_EXPONENT, which would fall into a row or two of cells of a sphere
    grid (the tabulated density is then not accurate enough for 10^6 samples):
    for those a cap of CAP_LOBE_WIDTHS lobe widths about the mirror direction
    (as tests/_chi2.py's CapDomain)."""
    n = spec.bsdf.get("exponent") if spec.bsdf.get("type") == "phong" else None
    if n is None or n < CAP_EXPONENT:
        return EqualAreaDomain()
    t = math.radians(spec.incidence_deg)
    return EqualAreaDomain((-math.sin(t), 0.0, math.cos(t)), cap_cos_min(n))


# ----------------------------------------------------------- the plugin

def incident(incidence_deg: float):
    """Local incident direction in the xz plane, ``incidence_deg`` from the normal (opaque:
    the panels of every incidence share their kernels)."""
    import drjit as dr
    import mitsuba as mi
    t = math.radians(incidence_deg)
    return mi.Vector3f(*(dr.opaque(mi.Float, v) for v in (math.sin(t), 0.0, math.cos(t))))


def variates(count: int, seed: int, dim: int = 3):
    """The uniform variates mitsuba.chi2.ChiSquareTest draws for ``seed``: one
    PCG32 stream per sample, state and sequence hashed by TEA from the index."""
    import drjit as dr
    import mitsuba as mi
    idx = dr.arange(mi.UInt64, count)
    v0, v1 = mi.sample_tea_32(idx, dr.opaque(mi.UInt32, seed))   # opaque: one kernel for all seeds
    rng = mi.PCG32(initstate=v0, initseq=v1)
    out = mi.Vector3f() if dim == 3 else getattr(mi, f"Vector{dim}f")()
    for i in range(dim):
        out[i] = rng.next_float32() if mi.Float is mi.Float32 else rng.next_float64()
    return out


def sample_func(strategy, bsdf, wi, domain=None, path_module=None, site=None):
    """``u -> (wo, weight)`` for mitsuba.chi2: ``vr_path``'s own direction sampling,
    weight 1 where a direction was drawn (inside ``domain``), 0 elsewhere (parked
    at the domain's axis). ``strategy``: a name or a strategy object; ``site``:
    ``n -> n`` surface interactions (default :func:`interaction` with ``wi``)."""
    import drjit as dr
    import mitsuba as mi
    path = path_module or _path()
    domain = domain or EqualAreaDomain()
    ctx = mi.BSDFContext()
    ptr = mi.BSDFPtr(bsdf)
    site = site or (lambda n: interaction(wi, n))

    def sample(u):
        ds = path.sample_direction(strategy, ptr, ctx, site(dr.width(u)), u.x,
                                   mi.Point2f(u.y, u.z))
        wo = dr.select(ds.pdf > 0, ds.wo, dr.normalize(mi.Vector3f(*domain.axis)))
        return domain.restrict(wo, dr.select(ds.pdf > 0, 1.0, 0.0))
    return sample


def pdf_func(strategy, bsdf, wi, path_module=None, site=None):
    """``wo -> density`` reported by the strategy (``direction_pdf``); ``site`` as in
    :func:`sample_func`."""
    import drjit as dr
    import mitsuba as mi
    path = path_module or _path()
    ctx = mi.BSDFContext()
    site = site or (lambda n: interaction(wi, n))

    def pdf(wo):
        return path.direction_pdf(strategy, bsdf, ctx, site(dr.width(wo)), wo)
    return pdf


def fcos_func(bsdf, wi, site=None):
    """``wo -> f * cos`` (``bsdf.eval``, mean over RGB); ``site`` as in :func:`sample_func`."""
    import drjit as dr
    import mitsuba as mi
    ctx = mi.BSDFContext()
    site = site or (lambda n: interaction(wi, n))

    def fcos(wo):
        value = bsdf.eval(ctx, site(dr.width(wo)), wo)
        return dr.mean(mi.unpolarized_spectrum(value))
    return fcos


def _path():
    import integrators.path
    return integrators.path


def tabulate(domain, func, samples: int, res: int, ires: int) -> np.ndarray:
    """Integral of ``func`` over every cell of ``domain``'s grid, times ``samples``,
    (res, res), rows in increasing cos: mitsuba.chi2's own trapezoid tabulation."""
    import mitsuba as mi
    test = mi.chi2.ChiSquareTest(domain=domain, sample_func=None, pdf_func=func,
                                 sample_dim=3, sample_count=samples, res=res, ires=ires)
    test.tabulate_pdf()
    return np.asarray(test.pdf, np.float64).reshape(res, res)


def cell_index(domain, xy, res: int):
    """Cell of every equal-area point ``xy`` (mi.Vector2f) on ``domain``'s (res, res)
    grid, row-major (mi.UInt32), computed as mitsuba.chi2 bins its samples: in
    float32, cell = floor(normalized position * res), clamped."""
    import drjit as dr
    import mitsuba as mi
    bounds = domain.bounds()
    c = (xy - bounds.min) / bounds.extents()
    c = mi.Vector2u(dr.clip(c * mi.Vector2f(res), 0, mi.Vector2f(res - 1)))
    return c.x + c.y * res


def histogram(cells: np.ndarray, weights: np.ndarray, res: int) -> np.ndarray:
    """Weighted counts per cell (``cells`` from :func:`cell_index`), (res, res)."""
    flat = np.bincount(np.asarray(cells, np.int64), weights=weights, minlength=res * res)
    return flat.reshape(res, res)


def chi2_test(observed: np.ndarray, expected: np.ndarray, order=None) -> tuple[float, int, float]:
    """Pearson's chi-square statistic, degrees of freedom and p-value of ``observed``
    against ``expected`` counts, as mitsuba.chi2.ChiSquareTest.run computes them: cells
    in increasing expected count (``order``: that permutation, else :func:`drjit_order`),
    low cells pooled by Mitsuba's own ``mi.math.chi2`` (threshold POOL_THRESHOLD). A
    sample in a cell of expected count 0 gives p = 0."""
    import mitsuba as mi
    from scipy import stats
    obs = np.asarray(observed, np.float64).ravel()
    exp = np.asarray(expected, np.float64).ravel()
    if np.any((exp == 0) & (obs != 0)):
        return math.inf, 0, 0.0
    order = drjit_order(exp) if order is None else np.asarray(order)
    stat, dof, _, _ = mi.math.chi2(mi.Float64(obs[order]), mi.Float64(exp[order]),
                                   POOL_THRESHOLD)
    stat, dof = float(stat[0] if hasattr(stat, "__len__") else stat), int(dof)
    if dof < 1:
        return stat, dof, 0.0
    return stat, dof, float(stats.chi2.sf(stat, dof))


def drjit_order(expected: np.ndarray) -> np.ndarray:
    """The cell order mitsuba.chi2 uses (``dr.argsort`` of the expected counts):
    ties among pooled cells are then grouped exactly as there."""
    import drjit as dr
    import mitsuba as mi
    return np.asarray(dr.argsort(mi.Float(np.asarray(expected, np.float32).ravel())))


# ----------------------------------------------------------------- panel

def compute(spec: PanelSpec, path_module=None, strategy=None, bsdf=None, site=None) -> dict:
    """Every array and number of one panel (see the module docs). By default the
    strategy named ``spec.strategy`` on ``spec.bsdf`` at the z-up interaction of
    ``spec.incidence_deg``; ``strategy`` (an object: its state, e.g. a trained guide),
    ``bsdf`` (an instantiated BSDF) and ``site`` (``n -> n`` surface interactions, e.g. at a
    scene point: :mod:`.lab.guide`) replace them."""
    import drjit as dr
    import mitsuba as mi
    path = path_module or _path()
    strategy = spec.strategy if strategy is None else strategy
    bsdf = mi.load_dict(spec.bsdf) if bsdf is None else bsdf
    wi = incident(spec.incidence_deg)
    site = site or (lambda count: interaction(wi, count))
    u = variates(spec.samples, spec.seed)
    n = spec.samples
    ctx = mi.BSDFContext()
    ds = path.sample_direction(strategy, mi.BSDFPtr(bsdf), ctx, site(n),
                               u.x, mi.Point2f(u.y, u.z))
    drawn = ds.pdf > 0
    domain = domain_for(spec)
    wo = dr.select(drawn, ds.wo, mi.Vector3f(0, 0, 1))
    counted = drawn & domain.inside(wo)
    weight = dr.select(drawn, dr.mean(mi.unpolarized_spectrum(ds.weight)), 0.0)
    xy_dr = domain.map_backward(wo)
    cells = cell_index(domain, xy_dr, spec.res)
    dr.eval(xy_dr, cells, weight, drawn, counted)
    drawn_np = np.asarray(drawn)
    counted_np = np.asarray(counted)
    w = np.asarray(weight, np.float64)
    hist = histogram(np.asarray(cells), counted_np.astype(np.float64), spec.res)
    pdf = pdf_func(strategy, bsdf, wi, path, site)
    expected = tabulate(domain, pdf, n, spec.res, spec.ires)
    fcos = tabulate(domain, fcos_func(bsdf, wi, site), 1, spec.res, spec.ires)
    stat, dof, p = chi2_test(hist, expected, drjit_order(expected))
    pdf_at = pdf(wo)                                           # pdf where each was drawn
    ratio = dr.select(drawn, ds.pdf / dr.maximum(pdf_at, 1e-30), 1.0)
    pdf_mass, mass_error = mass.sphere_integral(
        tabulate, domain, pdf, spec.res, spec.ires,
        float(np.sum(expected, dtype=np.float64)) / n)
    albedo, albedo_error = mass.sphere_integral(
        tabulate, domain, fcos_func(bsdf, wi, site), spec.res, spec.ires,
        np.sum(fcos, dtype=np.float64))
    mean_w = float(np.mean(w))
    second = float(np.mean(w * w))
    rel_var = second / mean_w ** 2 - 1.0 if mean_w > 0 else math.inf
    keep = np.flatnonzero(counted_np)[:spec.scatter]
    xy = np.stack([np.asarray(xy_dr.x)[keep], np.asarray(xy_dr.y)[keep]], axis=1)
    return {"histogram": hist.astype(np.float32), "expected": expected.astype(np.float32),
            "fcos": fcos.astype(np.float32), "scatter": xy.astype(np.float32),
            "p_value": p, "chi2": stat, "dof": dof, "rel_variance": rel_var,
            "albedo": mean_w, "drawn": float(np.mean(drawn_np)),
            "in_grid": float(np.mean(counted_np)), "cos_min": domain.cos_min,
            "max_weight": float(np.max(w)) if n else 0.0,
            "max_z": float(np.max(np.abs(hist - expected) / np.sqrt(np.maximum(expected, 1.0)))),
            "mass": pdf_mass, "mass_error": mass_error, "albedo_quadrature": albedo,
            "albedo_error": albedo_error,
            **mass.sample_moments(w, np.asarray(ratio, np.float64)[drawn_np])}


SCALARS = ("p_value", "chi2", "dof", "rel_variance", "albedo", "drawn", "in_grid", "cos_min",
           "max_weight", "max_z") + mass.SCALARS
#: The scalars that are counts (a panel read back from the cache gives them as ints, as
#: :func:`compute` does, so a rerun writes the same tables).
INTEGERS = ("dof",)


def cached(spec: PanelSpec, cache_dir: str) -> dict:
    """:func:`compute`, or the panel stored under ``cache_dir`` by an earlier run with
    the same settings (written atomically, so an interrupted run loses only the
    panel it was computing)."""
    import os
    from experiments.lib import files
    path = os.path.join(cache_dir, spec.key() + ".npz")
    data = files.read_npz(path)
    if data is not None:
        return {k: (int(v) if k in INTEGERS else float(v) if k in SCALARS else v)
                for k, v in data.items()}
    panel = compute(spec)
    files.write_npz(path, **{k: np.asarray(v) for k, v in panel.items()})
    return panel


#: Relative variance of the weight above which the lab says it explodes: one
#: bounce then needs that many samples for a 100% relative error (one sample of
#: a perfectly matched strategy has 0), and a path multiplies the factors.
EXPLODES = 10.0


def significance(panels: int, level: float = 0.01) -> float:
    """Sidak-corrected significance level for ``panels`` tests at family level ``level``."""
    return 1.0 - (1.0 - level) ** (1.0 / max(1, panels))


@dataclass(frozen=True)
class StrategyRow:
    """One strategy over every panel: a row of the warps' conclusion table."""
    strategy: str
    panels: int
    rejected: int               # panels whose chi-square test rejects the density
    lowest_p: float
    lowest_p_at: str            # 'bsdf at incidence' of the lowest p-value
    exploding: int              # configurations with Var[w]/E[w]^2 above EXPLODES
    largest: float              # the largest Var[w]/E[w]^2
    largest_at: str
    lowest_in: int              # configurations where its Var[w]/E[w]^2 is the lowest

    def cells(self) -> list:
        return [self.strategy, self.panels, self.rejected, f"{self.lowest_p:.3g}",
                self.lowest_p_at, self.exploding, f"{self.largest:.3g}", self.largest_at,
                self.lowest_in]


HEADER = ["strategy", "panels", "rejected at 1% (Sidak)", "lowest p", "lowest p at",
          f"Var[w]/E[w]^2 > {EXPLODES:g} in", "largest Var[w]/E[w]^2", "largest at",
          "lowest Var[w]/E[w]^2 in"]


@dataclass(frozen=True)
class Findings:
    """The warps' conclusion: the table (one row per strategy) and sentences from it."""
    alpha: float                # Sidak-corrected level of one panel's test
    configurations: int         # (BSDF, incidence) pairs
    rows: list                  # StrategyRow per strategy
    rejected: list              # the panels (rows) that reject their density
    sentences: list


def _where(r: dict) -> str:
    return f"{r['bsdf']} at {r['incidence_deg']:g} deg"


def analyse(rows: list[dict]) -> Findings:
    """The conclusion from the panel rows (dicts with bsdf, incidence_deg, strategy,
    p_value, rel_variance): do the densities hold, and where does the weight's relative
    variance explode. Pure: numbers in, a table and at most three sentences out."""
    alpha = significance(len(rows))
    failed = [r for r in rows if not r["p_value"] >= alpha]
    by: dict = {}
    for r in rows:
        by.setdefault((r["bsdf"], r["incidence_deg"]), {})[r["strategy"]] = r["rel_variance"]
    wins: dict = {}
    for vals in by.values():
        best = min(vals, key=vals.get)
        wins[best] = wins.get(best, 0) + 1
    table = []
    for s in dict.fromkeys(r["strategy"] for r in rows):
        mine = [r for r in rows if r["strategy"] == s]
        low = min(mine, key=lambda r: r["p_value"])
        worst = max(mine, key=lambda r: r["rel_variance"])
        table.append(StrategyRow(s, len(mine), sum(r in failed for r in mine), low["p_value"],
                                 _where(low), sum(r["rel_variance"] > EXPLODES for r in mine),
                                 worst["rel_variance"], _where(worst), wins.get(s, 0)))
    return Findings(alpha, len(by), table, failed, sentences(table, failed, alpha, len(by)))


def sentences(table: list[StrategyRow], failed: list[dict], alpha: float,
              configurations: int) -> list[str]:
    """At most three sentences computed from the table (and the rejected panels)."""
    panels = sum(r.panels for r in table)
    if failed:
        shown = "; ".join(f"{r['strategy']} on {_where(r)} (p = {r['p_value']:.1e})"
                          for r in failed[:3])
        more = f" and {len(failed) - 3} more (table)" if len(failed) > 3 else ""
        out = [f"{len(failed)} of {panels} panels reject their strategy's density at 1% "
               f"(Sidak: p < {alpha:.1e}): {shown}{more}."]
    else:
        low = min(table, key=lambda r: r.lowest_p)
        out = [f"Every one of the {panels} panels accepts its strategy's density at 1% "
               f"(Sidak: p >= {alpha:.1e}; lowest p = {low.lowest_p:.3g}, {low.strategy} on "
               f"{low.lowest_p_at}): the directions vr_path draws follow the density it "
               f"weights them by."]
    ranked = sorted((r for r in table if r.lowest_in), key=lambda r: -r.lowest_in)
    out.append("Lowest relative variance Var[w]/E[w]^2 per configuration: " + ", ".join(
        f"{r.strategy} in {r.lowest_in}" for r in ranked) + f" of {configurations}.")
    bad = [r for r in table if r.exploding]
    if bad:
        worst = max(bad, key=lambda r: r.largest)
        out.append(f"Var[w]/E[w]^2 exceeds {EXPLODES:g} for " + ", ".join(
            f"{r.strategy} in {r.exploding}" for r in bad) + f" of {configurations} "
            f"configurations (largest {worst.largest:.3g}, {worst.strategy} on "
            f"{worst.largest_at}): there one bounce needs that many times the samples of a "
            f"matched strategy, and a path multiplies the factors.")
    else:
        out.append(f"No strategy's Var[w]/E[w]^2 exceeds {EXPLODES:g} in any configuration.")
    return out
