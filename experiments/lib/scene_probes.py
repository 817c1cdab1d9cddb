"""Measurements taken on a scene's objects directly, without rendering an image.

* :func:`probe_scene`: the scene loaded for probing (``vr_path``, max_depth 1);
* :func:`phong_mask`: which pixels see a ``phong`` surface first;
* :func:`phong_bsdf`: the scene's first ``phong`` BSDF and its shape;
* :func:`direction_sampling_stats`: per-sample statistics of estimating the
  directional albedo of a BSDF with one ``vr_path`` strategy (drawn by the
  plugin's own ``sample_direction``) at one incidence angle;
* :func:`first_hit_sampling`: incidence angles of the camera's first hits on
  the Phong object and which of the BSDF's samples there have zero weight.
"""
from __future__ import annotations


import drjit as dr
import mitsuba as mi
import numpy as np

from .methods import Depth, parse_method
from .scenes import load_scene
from .metrics import luminance


def probe_scene(path: str, width: int, height: int):
    """The scene file loaded for probing its surfaces (any integrator would do)."""
    return load_scene(path, width, height, parse_method("bsdf"), Depth(max_depth=1))


def _is_phong(bsdf) -> bool:
    return bsdf is not None and type(bsdf).__name__ == "PhongBSDF"


def phong_bsdf(scene):
    """(BSDF, shape) of the scene's first ``phong`` surface, or (None, None)."""
    for shape in scene.shapes():
        if _is_phong(shape.bsdf()):
            return shape.bsdf(), shape
    return None, None


def phong_mask(scene) -> np.ndarray:
    """(H, W) bool: pixels whose centre sees a surface with a ``phong`` BSDF first."""
    width, height = scene.sensors()[0].film().crop_size()
    sensor = scene.sensors()[0]
    idx = dr.arange(mi.UInt32, width * height)
    pos = mi.Point2f((mi.Float(idx % width) + 0.5) / width,
                     (mi.Float(idx // width) + 0.5) / height)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    mask = np.zeros(width * height, bool)
    for shape in scene.shapes():
        if _is_phong(shape.bsdf()):
            mask |= np.array(si.is_valid() & (si.shape == mi.ShapePtr(shape)))
    return mask.reshape(height, width)


def _sample_direction():
    """The plugin's own strategies (imported late: the plugin module needs a variant)."""
    from integrators.path import sample_direction
    return sample_direction


def check_strategy(strategy: str) -> str:
    """``strategy`` if it is registered (:func:`integrators.strategies.get` names the
    registered ones otherwise)."""
    from integrators import strategies
    strategies.get(strategy)
    return strategy


def direction_sampling_stats(bsdf, cos_theta_i: float, strategy: str, n: int,
                             seed: int = 0) -> dict:
    """Per-sample statistics of estimating the directional albedo at one incidence angle.

    ``strategy``: any registered ``vr_path`` strategy (``integrators.strategies.names()``),
    drawn by the plugin itself (``integrators.path.sample_direction``, the
    function ``vr_path`` calls at every vertex), whose weight is
    ``f cos / pdf``; another name raises ValueError. Returns the albedo
    estimate, the fraction of samples with zero weight (wasted: below the
    horizon or outside the lobe), the relative variance per sample
    Var[w] / E[w]^2 (the cost of one unit of relative error) and the number
    of non-finite weights.
    """
    return direction_sampling_table(bsdf, [cos_theta_i], strategy, n, [seed])[0][0]


def direction_sampling_table(bsdf, cosines, strategy: str, n: int, seeds) -> list[list[dict]]:
    """:func:`direction_sampling_stats` at every incidence cosine and seed, in one call of
    the plugin (one kernel): ``[angle][seed]``. The ``n`` samples of a seed are the same
    at every angle, and the same as a single call with that seed draws."""
    check_strategy(strategy)
    u = np.concatenate([np.random.default_rng(seed).random((3, n)) for seed in seeds], axis=1)
    cos = np.repeat(np.asarray(cosines, np.float64), n * len(seeds))
    u = np.tile(u, len(cosines))
    sin = np.sqrt(np.maximum(0.0, 1.0 - cos ** 2))
    si = dr.zeros(mi.SurfaceInteraction3f, cos.size)
    si.wi = mi.Vector3f(mi.Float(sin), 0.0, mi.Float(cos))
    si.uv = mi.Point2f(0.5, 0.5)
    ds = _sample_direction()(strategy, bsdf, mi.BSDFContext(), si, mi.Float(u[0]),
                             mi.Point2f(u[1], u[2]))
    w = luminance(np.array(ds.weight).T).reshape(len(cosines), len(seeds), n)
    return [[_weight_stats(block) for block in per_angle] for per_angle in w]


def _weight_stats(w: np.ndarray) -> dict:
    finite = np.isfinite(w)
    mean = float(w[finite].mean()) if finite.any() else float("nan")
    return {"albedo": mean, "wasted": float(np.mean(w == 0)),
            "relvar": float(w[finite].var() / mean ** 2) if mean > 0 else float("inf"),
            "nonfinite": int(np.count_nonzero(~finite))}


def first_hit_sampling(scene, bsdf, shape, k: int = 16, seed: int = 0,
                       strategy: str = "bsdf"):
    """Cosines of incidence of the camera's first hits on ``shape`` (``k`` rays through each
    pixel centre), and per hit whether the plugin's ``strategy`` (lobe sampling by default)
    drew a zero-weight sample there."""
    check_strategy(strategy)
    sensor = scene.sensors()[0]
    w, h = sensor.film().crop_size()
    idx = dr.arange(mi.UInt32, w * h * k) // k
    pos = mi.Point2f((mi.Float(idx % w) + 0.5) / w, (mi.Float(idx // w) + 0.5) / h)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    hit = si.is_valid() & (si.shape == mi.ShapePtr(shape))
    rng = np.random.default_rng(seed)
    u = rng.random((3, w * h * k))
    ds = _sample_direction()(strategy, bsdf, mi.BSDFContext(), si, mi.Float(u[0]),
                             mi.Point2f(u[1], u[2]), hit)
    hit_np = np.array(hit)
    return np.array(si.wi.z)[hit_np], (np.array(ds.weight) == 0).all(axis=0)[hit_np]


#: Incidence cosines at which :func:`core_reach` probes a BSDF (the largest reach counts).
REACH_COSINES = (1.0, 0.7, 0.4, 0.1)
#: The share of a BSDF's albedo that its core carries (:func:`core_reach`).
CORE_SHARE = 0.5


def core_reach(bsdf, strategy: str, n: int = 1 << 16, seed: int = 0) -> float:
    """The probability that ``strategy`` (a registered ``vr_path`` strategy, by its own
    ``pdf``) draws a direction in the *core* of ``bsdf``'s non-delta lobes at one vertex:
    the directions of highest BSDF density that carry :data:`CORE_SHARE` of its albedo
    (found among ``n`` draws of the BSDF's own sampling, as ``E_bsdf[1_core p / p_bsdf]``),
    the largest over the incidence cosines :data:`REACH_COSINES`. The BSDF's own sampling
    reaches about 0.5, uniform sampling on a diffuse BSDF 1 - 1/sqrt(2) = 0.293, on a rough
    dielectric of GGX roughness 0.1 about 2.6e-3, on one of Beckmann 0.02 about 5e-5. 1
    where the BSDF has no non-delta lobe (every strategy samples a delta lobe by the
    BSDF's own sampling)."""
    from integrators import strategies
    pdf = strategies.get(check_strategy(strategy)).pdf
    u = np.random.default_rng(seed).random((3, n))
    ctx, best = mi.BSDFContext(), 0.0
    for cos in REACH_COSINES:
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.wi = mi.Vector3f(dr.full(mi.Float, np.sqrt(1.0 - cos * cos), n), 0.0,
                            dr.full(mi.Float, cos, n))
        si.uv = mi.Point2f(0.5, 0.5)
        bs, weight = bsdf.sample(ctx, si, mi.Float(u[0]), mi.Point2f(u[1], u[2]))
        p = np.array(pdf(bsdf, ctx, si, bs.wo, True))
        p_bsdf, w = np.array(bs.pdf), luminance(np.array(weight).T)
        lobe = (p_bsdf > 0) & (w > 0) & ~np.array(
            mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta), bool)
        if not lobe.any():
            continue
        order = np.argsort(-p_bsdf[lobe])
        carried = np.cumsum(w[lobe][order])
        core = order[:np.searchsorted(carried, CORE_SHARE * carried[-1]) + 1]
        best = max(best, float(np.sum(p[lobe][core] / p_bsdf[lobe][core]) / n))
    return best if best > 0 else 1.0


def path_reach(scene, strategy: str) -> float:
    """The least probability, over ``scene``'s BSDFs, that a path drawn by ``strategy``
    passes through a BSDF's core (:func:`core_reach`): squared for a BSDF that transmits
    (a path through a closed glass object crosses two of its surfaces). An upper bound
    on the share of samples that reach the light that BSDF's narrowest lobe carries."""
    from integrators import strategies
    reach = 1.0
    for bsdf in dict.fromkeys(s.bsdf() for s in scene.shapes() if s.bsdf() is not None):
        r = core_reach(bsdf, strategy)
        reach = min(reach, r * r if strategies.transmits(bsdf) else r)
    return reach
