"""The ``phong`` BSDF: energy-conserving modified Phong (Lafortune & Willems 1994)."""
from __future__ import annotations

import math
import warnings

import drjit as dr
import mitsuba as mi
import numpy as np

from . import warps


#: Sums kd + ks within this of 1 count as 1 (float32 rounding of e.g. 0.3 + 0.7).
SUM_TOLERANCE = 1e-6


def texture_range(texture: mi.Texture, resolution: int = 64):
    """Smallest and largest channel value of ``texture``, or None where unknown.

    Mitsuba's ``Texture::max()`` is not implemented by most textures
    (``bitmap``, ``checkerboard``...), so it is not used. A ``bitmap`` is
    bounded by its texels (its filters interpolate them); textures driven by
    mesh data (``mesh_attribute``) are unknown until rendered (None); any
    other texture is evaluated on a ``resolution`` x ``resolution`` grid of uv
    coordinates, exact for constant and piecewise-constant (``checkerboard``)
    ones.
    """
    kind = _kind(texture)
    if kind == "MeshAttribute":
        return None
    if kind == "BitmapTexture":
        values = np.array(mi.traverse(texture)["data"], dtype=np.float64)
    else:
        values = uv_grid_values(texture, resolution)
    if np.isnan(values).any():
        return math.nan, math.nan
    return float(values.min()), float(values.max())


def uv_grid_values(texture: mi.Texture, resolution: int) -> np.ndarray:
    """(channels, resolution^2) values of ``texture`` at the centres of a uv grid."""
    n = resolution * resolution
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    idx = dr.arange(mi.UInt32, n)
    si.uv = mi.Point2f((mi.Float(idx % resolution) + 0.5) / resolution,
                       (mi.Float(idx // resolution) + 0.5) / resolution)
    return np.atleast_2d(np.array(texture.eval(si), dtype=np.float64))


def _kind(texture: mi.Texture) -> str:
    return str(texture).split("[")[0].strip()


def _grid_resolution(*textures) -> int:
    """64, or the finest bitmap's resolution (grid points then hit its texel centres)."""
    res = [64] + [max(texture.resolution()) for texture in textures
                  if _kind(texture) == "BitmapTexture"]
    return int(min(max(res), 2048))


class PhongBSDF(mi.BSDF):
    r"""
    .. _bsdf-phong:

    Modified Phong BRDF (:monosp:`phong`)
    -------------------------------------

    .. pluginparameters::

     * - diffuse_reflectance
       - |spectrum| or |texture|
       - Diffuse reflectance :math:`k_d` in [0, 1]. (Default: 0.5)

     * - specular_reflectance
       - |spectrum| or |texture|
       - Specular reflectance :math:`k_s` in [0, 1]. (Default: 0.2)

     * - exponent
       - |float|
       - Phong exponent :math:`n \ge 0`; larger is shinier, 0 makes the glossy
         lobe a uniform :math:`k_s/\pi`. (Default: 30)

    The energy-conserving modified Phong model of Lafortune and Willems (1994):

    .. math::

        f(\omega_i, \omega_o) = \frac{k_d}{\pi}
            + k_s \frac{n + 2}{2\pi} \cos^n\alpha,

    where :math:`\alpha` is the angle between :math:`\omega_o` and the mirror
    direction of :math:`\omega_i`, and :math:`\cos\alpha` is clamped at 0. It
    reflects at most :math:`k_d + k_s` of the incident energy, so
    :math:`k_d + k_s \le 1` per channel. Wherever the largest channel of the
    sum exceeds 1, both reflectances are scaled down there by the same factor
    so that it is 1 (at every shading point, so any texture is safe), and a
    warning is issued at load when the textures' values show it. Any Mitsuba
    texture works for both reflectances (``bitmap``, ``checkerboard``,
    ``mesh_attribute``, ...): their range is read from the texels, or
    evaluated over the uv square (``mesh_attribute`` values are only known
    when rendering, so they get no load-time check). Negative or NaN values,
    values above 1 and a negative or NaN exponent raise ``ValueError``.

    Importance sampling picks the specular lobe with probability
    :math:`P_s = \bar k_s / (\bar k_d + \bar k_s)` (channel means at the shading
    point) and samples either the cosine-weighted hemisphere or the
    :math:`\cos^n` lobe about the mirror direction (``integrators.warps``). The
    returned pdf is that of the whole mixture,
    :math:`(1 - P_s)\cos\theta_o/\pi + P_s (n+1)/(2\pi)\cos^n\alpha`, whichever
    lobe produced the sample, and the weight is ``eval / pdf``; directions
    below the horizon get weight 0. Component 0 is the diffuse lobe, component
    1 the glossy one (``BSDFContext.component`` selects one of them).

    The BRDF is one-sided like Mitsuba's ``diffuse``: wrap it in ``twosided``
    for surfaces seen from both sides. It works with Mitsuba's ``path``
    integrator as well as with ``vr_path``.

    .. tabs::

        .. code-tab:: xml

            <bsdf type="phong">
                <rgb name="diffuse_reflectance" value="0.4, 0.3, 0.2"/>
                <float name="specular_reflectance" value="0.3"/>
                <float name="exponent" value="100"/>
            </bsdf>

        .. code-tab:: python

            'type': 'phong',
            'diffuse_reflectance': {'type': 'rgb', 'value': [0.4, 0.3, 0.2]},
            'specular_reflectance': 0.3,
            'exponent': 100
    """

    def __init__(self, props: mi.Properties):
        mi.BSDF.__init__(self, props)
        self.diffuse_reflectance = props.get_texture("diffuse_reflectance", 0.5)
        self.specular_reflectance = props.get_texture("specular_reflectance", 0.2)
        exponent = props.get("exponent", 30.0)
        self._check_exponent(exponent)
        self.exponent = dr.opaque(mi.Float, float(exponent))
        self._check_reflectances()

        diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
        self.m_components = [diffuse, glossy]
        self.m_flags = diffuse | glossy

    # ------------------------------------------------------------ parameters

    @staticmethod
    def _check_exponent(exponent) -> None:
        try:
            value = float(exponent)
        except (TypeError, ValueError):
            raise ValueError(f"phong: 'exponent' must be a number >= 0, got {exponent!r}") from None
        if not value >= 0 or math.isinf(value):
            raise ValueError(f"phong: 'exponent' must be a finite number >= 0, got {value}")

    def _check_reflectances(self) -> None:
        ranges = {}
        for name in ("diffuse_reflectance", "specular_reflectance"):
            rng = texture_range(getattr(self, name))
            if rng is not None:
                lo, hi = rng
                if not (0.0 <= lo and hi <= 1.0 + SUM_TOLERANCE):
                    bad = lo if not 0.0 <= lo else hi
                    raise ValueError(f"phong: '{name}' must lie in [0, 1], got a value of {bad}")
            ranges[name] = rng
        if None in ranges.values():
            return
        # Largest channel of kd + ks at the same point (not max kd + max ks).
        kd, ks = self.diffuse_reflectance, self.specular_reflectance
        res = _grid_resolution(kd, ks)
        total = float(np.max(uv_grid_values(kd, res) + uv_grid_values(ks, res)))
        if total > 1.0 + SUM_TOLERANCE:
            warnings.warn(
                f"phong: diffuse_reflectance + specular_reflectance reaches {total:.4g} > 1, "
                f"which would create energy; both are scaled by {1.0 / total:.4g} where "
                f"their sum reaches that value (down to a sum of 1 wherever it exceeds 1).",
                RuntimeWarning, stacklevel=3)

    def traverse(self, callback):
        callback.put("diffuse_reflectance", self.diffuse_reflectance,
                     mi.ParamFlags.Differentiable)
        callback.put("specular_reflectance", self.specular_reflectance,
                     mi.ParamFlags.Differentiable)
        callback.put("exponent", self.exponent, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=[]):
        if dr.width(self.exponent) != 1:
            raise ValueError(f"phong: 'exponent' must be a single number, got "
                             f"{dr.width(self.exponent)} values")
        self._check_exponent(dr.slice(self.exponent, 0))
        dr.make_opaque(self.exponent)   # edits must not recompile render kernels
        self._check_reflectances()

    # --------------------------------------------------------------- helpers

    def _reflectances(self, si, active):
        """kd and ks at ``si``, both scaled down where the largest channel of
        kd + ks exceeds 1 (energy conservation for any texture)."""
        kd = self.diffuse_reflectance.eval(si, active)
        ks = self.specular_reflectance.eval(si, active)
        scale = dr.rcp(dr.maximum(dr.max(mi.unpolarized_spectrum(kd + ks)), 1.0))
        return kd * scale, ks * scale

    def _lobes(self, ctx, si, active):
        """Scaled reflectances and the probability of sampling the glossy lobe."""
        kd, ks = self._reflectances(si, active)
        has_diffuse = ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0)
        has_glossy = ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 1)
        if not has_diffuse:
            kd = dr.zeros(mi.Spectrum)
        if not has_glossy:
            ks = dr.zeros(mi.Spectrum)
        md, ms = dr.mean(kd), dr.mean(ks)
        p_glossy = dr.select(md + ms > 0, ms / dr.maximum(md + ms, warps.PDF_EPSILON), 0.0)
        return kd, ks, p_glossy

    def _lobe_frame(self, wi):
        """Frame whose z axis is the mirror direction of ``wi``."""
        return mi.Frame3f(mi.Vector3f(-wi.x, -wi.y, wi.z))

    def _glossy_pdf(self, wi, wo):
        """Density of the cos^n lobe about the mirror direction."""
        return warps.square_to_phong_lobe_pdf(self._lobe_frame(wi).to_local(wo), self.exponent)

    def _eval(self, kd, ks, wi, wo, glossy_pdf):
        # ks (n+2)/(2 pi) cos^n(alpha) = ks (n+2)/(n+1) * lobe pdf: same cos^n term.
        n = self.exponent
        f = kd * dr.inv_pi + ks * ((n + 2.0) / (n + 1.0)) * glossy_pdf
        return f * mi.Frame3f.cos_theta(wo)

    def _pdf(self, p_glossy, wo, glossy_pdf):
        return dr.lerp(warps.square_to_cosine_hemisphere_pdf(wo), glossy_pdf, p_glossy)

    # ------------------------------------------------------------ interface

    def sample(self, ctx, si, sample1, sample2, active=True):
        wi = si.wi
        active = mi.Bool(active) & (mi.Frame3f.cos_theta(wi) > 0)
        kd, ks, p_glossy = self._lobes(ctx, si, active)

        glossy = sample1 < p_glossy
        wo_diffuse = warps.square_to_cosine_hemisphere(sample2)
        wo_glossy = self._lobe_frame(wi).to_world(warps.square_to_phong_lobe(sample2, self.exponent))
        wo = dr.select(glossy, wo_glossy, wo_diffuse)

        glossy_pdf = self._glossy_pdf(wi, wo)
        pdf = self._pdf(p_glossy, wo, glossy_pdf)
        active &= (mi.Frame3f.cos_theta(wo) > 0) & (pdf > 0)

        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = wo
        bs.pdf = dr.select(active, pdf, 0.0)
        bs.eta = 1.0
        bs.sampled_component = dr.select(glossy, mi.UInt32(1), mi.UInt32(0))
        bs.sampled_type = dr.select(glossy, mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                                    mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
        value = self._eval(kd, ks, wi, wo, glossy_pdf) / dr.maximum(pdf, warps.PDF_EPSILON)
        return bs, dr.select(active, value, 0.0)

    def eval(self, ctx, si, wo, active=True):
        return self.eval_pdf(ctx, si, wo, active)[0]

    def pdf(self, ctx, si, wo, active=True):
        return self.eval_pdf(ctx, si, wo, active)[1]

    def eval_pdf(self, ctx, si, wo, active=True):
        wi = si.wi
        active = (mi.Bool(active) & (mi.Frame3f.cos_theta(wi) > 0)
                  & (mi.Frame3f.cos_theta(wo) > 0))
        kd, ks, p_glossy = self._lobes(ctx, si, active)
        glossy_pdf = self._glossy_pdf(wi, wo)
        value = self._eval(kd, ks, wi, wo, glossy_pdf)
        pdf = self._pdf(p_glossy, wo, glossy_pdf)
        return dr.select(active, value, 0.0), dr.select(active, pdf, 0.0)

    def eval_diffuse_reflectance(self, si, active=True):
        return self._reflectances(si, active)[0]

    def to_string(self):
        return (f"PhongBSDF[\n  diffuse_reflectance = {self.diffuse_reflectance},\n"
                f"  specular_reflectance = {self.specular_reflectance},\n"
                f"  exponent = {dr.slice(self.exponent, 0)}\n]")


mi.register_bsdf("phong", PhongBSDF)  # the class of this variant, bound now
