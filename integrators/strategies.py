"""Direction-sampling strategies of ``vr_path`` as objects, and their registry.

A strategy is a :class:`Strategy` object: it draws the next direction of a path at a
surface vertex, gives its density at any direction, and both at once for next-event
estimation. The built-in ones are the objects :data:`uniform`, :data:`cosine`,
:data:`bsdf` and :data:`mis` (a :class:`Mixture` of cosine and bsdf), registered under
those names; ``vr_path``'s ``strategy`` parameter takes any registered name.

A strategy of one's own is one file::

    import integrators
    from integrators import strategies, warps

    class MirrorLobe(strategies.Strategy):
        def sample(self, bsdf, ctx, si, sample1, sample2, active):
            wo = ...                                 # a warp of warps.py
            return strategies.weighted_direction(bsdf, ctx, si, wo,
                                                 self.pdf(bsdf, ctx, si, wo, active), active)
        def pdf(self, bsdf, ctx, si, wo, active):
            return ...                               # its density (solid angle)

    integrators.register_strategy("mirror_lobe", MirrorLobe)   # a factory: one per vr_path

This module is importable, and its registry listable, before any Mitsuba variant is
set (scripts check method names first): nothing here derives from a variant's types,
``mi.*`` types are used only when a strategy is called. It is not reloaded on a
variant switch, so the registry survives it. The sampling maths is in :mod:`.warps`;
the delta-lobe fallback and the dispatch over BSDFs are :mod:`.path`'s.
"""
from __future__ import annotations

import re
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from . import warps

#: Probability with which the ``mis`` strategy draws from the cosine strategy (else from
#: the BSDF's own sampling). Why 0.25: see ``vr_path``'s docstring.
MIS_COSINE_WEIGHT = 0.25


class DirectionSample(NamedTuple):
    """The next direction of a path, as drawn by a strategy at one vertex."""
    wo: mi.Vector3f       # local direction
    pdf: mi.Float         # density of the strategy at wo (solid angle; Dirac lobes: as
                          # sampled); 0 where no direction was drawn (failed BSDF sample)
    weight: mi.Spectrum   # bsdf.eval(wo) / pdf  (the BSDF's own weight on delta lobes)
    delta: mi.Bool        # sampled from a Dirac delta lobe
    eta: mi.Float         # relative index of refraction crossed (1 for reflection)
    null: mi.Bool         # passed straight through a ``null`` component
    guide: object = None  # what a strategy that learns drew, for its recorder and roulette
                          # (``guided``: a :class:`.guided.GuideDraw`); None for the others
                          # (not carried through a dispatch: such strategies take none)


class VertexSample(NamedTuple):
    """The next direction and the BSDF at an emitter sample's direction (for NEE)."""
    direction: DirectionSample
    em_value: mi.Spectrum  # bsdf.eval(wo_em) (f * cos)
    em_pdf: mi.Float       # density of the strategy at wo_em (for the MIS weight)


class Strategy:
    """How ``vr_path`` draws the next direction at a surface vertex: subclass this.

    Write :meth:`sample` and :meth:`pdf`; :meth:`eval_pdf` and :meth:`sample_and_eval`
    have correct defaults built from them (override them only to share work, e.g. one
    BSDF call for both). Every method is vectorised Dr.Jit code, called inside
    ``vr_path``'s symbolic loop (so: no Python branches on array values, no
    ``dr.eval``), and also outside it by the warp tests and the lab. Arguments, always
    all passed, positionally:

    * ``bsdf``: one ``mi.BSDF`` (when :attr:`dispatch` is True, the default) or a
      ``mi.BSDFPtr`` (when False);
    * ``ctx``: ``mi.BSDFContext``; ``si``: ``mi.SurfaceInteraction3f`` (``si.wi`` is the
      local incident direction);
    * ``sample1``: ``mi.Float``, ``sample2``: ``mi.Point2f``: uniform samples in [0, 1)
      (one 1-D and one 2-D dimension of the sampler per vertex, as ``bsdf.sample``);
    * ``wo``, ``wo_em``: local directions (``mi.Vector3f``); ``active``: ``mi.Bool``.

    Directions are local (z along the shading normal); densities are in solid angle.
    For an unbiased render a strategy's density must be > 0 wherever the BSDF's
    ``f cos`` is (a lobe about one axis alone is not; mix it with :data:`cosine`:
    :class:`Mixture`), and :meth:`pdf` must be the density :meth:`sample` draws with
    (the chi-square tests check that).

    ``dispatch`` (class attribute, default True): ``vr_path`` calls the methods once
    per BSDF instance of the scene (a ``dr.dispatch`` over the ``mi.BSDFPtr``), so
    ``bsdf`` is one BSDF whose ``flags()`` is a Python int, and BSDFs with a Dirac delta
    lobe (mirrors, smooth glass, ``plastic``, ``null``) never reach the strategy: they
    use their own sampling. False: the methods get the ``mi.BSDFPtr`` itself and call
    only its vectorised methods (no dispatch of one's own), and must treat every BSDF,
    delta lobes included, themselves (:data:`bsdf` does: it is the BSDF's own
    sampling).

    State: a strategy object may keep state (a guided sampler's tables). Register a
    class or a zero-argument callable (a factory) to get one object per ``vr_path``
    instance, an object to share it; see :func:`register`.
    """

    dispatch: bool = True

    def sample(self, bsdf, ctx, si, sample1, sample2, active) -> DirectionSample:
        """The next direction, its density and its weight ``bsdf.eval(wo) / pdf``
        (build it with :func:`weighted_direction`)."""
        raise NotImplementedError(f"{type(self).__name__}.sample")

    def pdf(self, bsdf, ctx, si, wo, active) -> mi.Float:
        """The density with which :meth:`sample` draws the local direction ``wo``."""
        raise NotImplementedError(f"{type(self).__name__}.pdf")

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        """``(bsdf.eval(wo), self.pdf(wo))``: the BSDF value (f cos) and this density."""
        return bsdf.eval(ctx, si, wo, active), self.pdf(bsdf, ctx, si, wo, active)

    def sample_and_eval(self, bsdf, ctx, si, sample1, sample2, wo_em,
                        active) -> VertexSample:
        """:meth:`sample`, and at ``wo_em`` (an emitter sample's direction) the BSDF
        value and this strategy's density (:meth:`eval_pdf`), for NEE and its MIS weight."""
        direction = self.sample(bsdf, ctx, si, sample1, sample2, active)
        return VertexSample(direction, *self.eval_pdf(bsdf, ctx, si, wo_em, active))


# ------------------------------------------------- helpers for strategies

def transmits(bsdf):
    """Does ``bsdf`` have a transmission lobe? (a Python bool for one BSDF, a
    ``mi.Bool`` for a ``mi.BSDFPtr``)"""
    return mi.has_flag(bsdf.flags(), mi.BSDFFlags.Transmission)


def crossing_eta(bsdf, ctx, si, wo, active) -> mi.Float:
    """Relative index of refraction for a direction ``wo`` (1 unless it crosses the surface).

    Mitsuba's interface gives eta only with a sample, so the BSDF is sampled once with
    its transmission lobes alone (its eta does not depend on the sample). Only BSDFs
    that transmit pay for this call. ``vr_path`` tracks eta as Mitsuba's ``path`` does
    for sampled refractions, so that Russian roulette treats paths inside glass the
    same for every strategy.
    """
    crossing_possible = transmits(bsdf)
    if crossing_possible is False:
        return mi.Float(1.0)
    if crossing_possible is not True:        # a mi.BSDFPtr: per lane
        active = active & crossing_possible
    ctx_t = mi.BSDFContext(ctx.mode, mi.BSDFFlags.Transmission)
    bs, _ = bsdf.sample(ctx_t, si, mi.Float(0.5), mi.Point2f(0.5, 0.5), active)
    crosses = (si.wi.z * wo.z) < 0
    return dr.select(crosses & (bs.eta > 0), bs.eta, 1.0)


def direction_weight(value, pdf):
    """``value / pdf`` where ``pdf > 0``, else 0 (the weight of a drawn direction)."""
    return dr.select(pdf > 0, value / dr.maximum(pdf, warps.PDF_EPSILON), 0.0)


def weighted_direction(bsdf, ctx, si, wo, pdf, active) -> DirectionSample:
    """The :class:`DirectionSample` of a direction ``wo`` drawn with density ``pdf`` (not
    from a delta lobe): weight ``bsdf.eval(wo) / pdf`` (0 where ``pdf`` is 0) and the
    index of refraction crossed (:func:`crossing_eta`)."""
    value = bsdf.eval(ctx, si, wo, active)
    eta = crossing_eta(bsdf, ctx, si, wo, active)
    return DirectionSample(wo, pdf, direction_weight(value, pdf), mi.Bool(False), eta,
                           mi.Bool(False))


def _drawn(bsdf_weight):
    """Did ``bsdf.sample`` draw a direction? Mitsuba marks a failed sample (e.g.
    below the horizon of a one-sided BSDF) by a zero weight, its pdf may be > 0."""
    return dr.any(mi.unpolarized_spectrum(bsdf_weight) != 0)


def _bsdf_direction(bs, weight) -> DirectionSample:
    """A :class:`DirectionSample` from the BSDF's own sample and weight."""
    return DirectionSample(bs.wo, dr.select(_drawn(weight), bs.pdf, 0.0), weight,
                           mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta), bs.eta,
                           mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null))


# ------------------------------------------------------ built-in strategies

class HemisphereSampling(Strategy):
    """A hemisphere warp of :mod:`.warps` (``uniform`` or ``cosine``), ignoring the BSDF:
    on the side of the incident direction; for a BSDF that transmits, on either side
    (``sample1 < 0.5``: z < 0), each with probability 1/2."""

    def __init__(self, kind: str):
        self.kind = kind
        self.warp = warps.hemisphere_warp(kind)

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        wo = warps.square_to_sided_hemisphere(self.warp.warp, sample1, sample2, si.wi.z,
                                              transmits(bsdf))
        return weighted_direction(bsdf, ctx, si, wo, self.pdf(bsdf, ctx, si, wo, active),
                                  active)

    def pdf(self, bsdf, ctx, si, wo, active):
        return warps.square_to_sided_hemisphere_pdf(self.warp.pdf, wo, si.wi.z,
                                                    transmits(bsdf))

    def __repr__(self):
        return f"HemisphereSampling({self.kind!r})"


class BSDFSampling(Strategy):
    """The BSDF's own importance sampling (``bsdf.sample``), delta lobes included; the
    NEE form is one ``eval_pdf_sample`` call, as Mitsuba's ``path``. Needs no dispatch."""

    dispatch = False

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        return _bsdf_direction(*bsdf.sample(ctx, si, sample1, sample2, active))

    def pdf(self, bsdf, ctx, si, wo, active):
        return bsdf.pdf(ctx, si, wo, active)

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        return bsdf.eval_pdf(ctx, si, wo, active)

    def sample_and_eval(self, bsdf, ctx, si, sample1, sample2, wo_em, active):
        em_value, em_pdf, bs, weight = bsdf.eval_pdf_sample(ctx, si, wo_em, sample1,
                                                            sample2, active)
        return VertexSample(_bsdf_direction(bs, weight), em_value, em_pdf)

    def __repr__(self):
        return "BSDFSampling()"


class Mixture(Strategy):
    """One-sample mixture of two strategies: ``a`` with probability ``weight``, else ``b``.

    Every direction, whichever technique drew it, is weighted by
    ``f / (weight p_a + (1 - weight) p_b)`` and reports that mixture density
    (:func:`.warps.mixture_pdf`; Veach's one-sample model with the balance heuristic),
    in the NEE MIS weight too. ``sample1`` picks the technique and, rescaled, is that
    technique's own 1-D sample (:func:`.warps.split_mixture_sample`). Always dispatched
    per BSDF instance: both densities at a Dirac lobe's direction mean nothing, so BSDFs
    with one take their own sampling (``vr_path``'s delta-lobe fallback).
    """

    dispatch = True

    def __init__(self, a: Strategy, b: Strategy, weight: float):
        for name, s in (("a", a), ("b", b)):
            if not isinstance(s, Strategy):
                raise TypeError(f"Mixture: '{name}' must be a Strategy object, got {s!r}")
        if not isinstance(weight, (int, float)) or not 0 < weight < 1:
            raise ValueError(f"Mixture: 'weight' (the probability of drawing from a) must "
                             f"be a number in (0, 1), got {weight!r}")
        self.a, self.b, self.weight = a, b, float(weight)

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        split = warps.split_mixture_sample(sample1, self.weight)
        ds_b = self.b.sample(bsdf, ctx, si, split.u_b, sample2, active & ~split.use_a)
        ds_a = self.a.sample(bsdf, ctx, si, split.u_a, sample2, active & split.use_a)
        wo = dr.select(split.use_a, ds_a.wo, ds_b.wo)
        drawn = dr.select(split.use_a, ds_a.pdf > 0, ds_b.pdf > 0)
        value, pdf = self.eval_pdf(bsdf, ctx, si, wo, active & drawn)
        pdf = dr.select(drawn, pdf, 0.0)
        # Only BSDFs without a delta lobe get here (``dispatch``: they take their own
        # sampling), so neither a Dirac lobe nor a null pass-through was drawn.
        return DirectionSample(wo, pdf, direction_weight(value, pdf), mi.Bool(False),
                               dr.select(split.use_a, ds_a.eta, ds_b.eta), mi.Bool(False))

    def pdf(self, bsdf, ctx, si, wo, active):
        return warps.mixture_pdf(self.weight, self.a.pdf(bsdf, ctx, si, wo, active),
                                 self.b.pdf(bsdf, ctx, si, wo, active))

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        # The BSDF value comes with b's density (for mis: one eval_pdf call of the BSDF).
        value, pdf_b = self.b.eval_pdf(bsdf, ctx, si, wo, active)
        return value, warps.mixture_pdf(self.weight, self.a.pdf(bsdf, ctx, si, wo, active),
                                        pdf_b)

    def __repr__(self):
        return f"Mixture({self.a!r}, {self.b!r}, {self.weight!r})"


#: The built-in strategies (also registered below under these names).
uniform = HemisphereSampling("uniform")
cosine = HemisphereSampling("cosine")
bsdf = BSDFSampling()
mis = Mixture(cosine, bsdf, MIS_COSINE_WEIGHT)


# ----------------------------------------------------------------- registry

class UnknownStrategyError(ValueError):
    """A strategy name that is not registered (the message lists the registered ones)."""


_registry: dict = {}            # name -> a Strategy (shared) or a factory
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")


def register(name: str, strategy, replace: bool = False) -> None:
    """Register ``strategy`` under ``name`` (``integrators.register_strategy``).

    ``strategy``: a :class:`Strategy` object, shared by every ``vr_path`` that names it
    (and by :func:`get`), or a factory (a :class:`Strategy` subclass or any zero-argument
    callable returning a Strategy), called once per ``vr_path`` instance (and per
    :func:`get`) so that each gets its own state. ``name``: a letter then letters, digits
    or ``_`` (it appears in method names such as ``name+nee+halton`` and in file names).
    An existing name is an error unless ``replace`` is True.
    """
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"register_strategy: invalid name {name!r}: a letter, then "
                         f"letters, digits or '_'")
    if not (isinstance(strategy, Strategy) or callable(strategy)):
        raise TypeError(f"register_strategy: {name!r} must be a Strategy object, a Strategy "
                        f"subclass or a zero-argument factory, got {strategy!r}")
    if name in _registry and not replace:
        raise ValueError(f"register_strategy: a strategy {name!r} is already registered "
                         f"({_registry[name]!r}); pass replace=True to replace it")
    _registry[name] = strategy


def unregister(name: str) -> None:
    """Remove a strategy registered by :func:`register` (built-in ones stay)."""
    if name in BUILTIN:
        raise ValueError(f"unregister: {name!r} is a built-in strategy "
                         f"({', '.join(BUILTIN)}); register(..., replace=True) replaces it")
    _lookup(name)
    del _registry[name]


def names() -> tuple[str, ...]:
    """The registered names: the built-in ones (uniform, cosine, bsdf, mis), then the
    others in the order of registration."""
    return tuple(_registry)


def _lookup(name):
    try:
        return _registry[name]
    except (KeyError, TypeError):
        raise UnknownStrategyError(f"unknown strategy {name!r}; valid choices are "
                                   f"{', '.join(_registry)}") from None


def get(name: str) -> Strategy:
    """The strategy registered as ``name``: the shared object, or a new one made by the
    registered factory (each call makes one). Unknown name: :class:`UnknownStrategyError`
    (a ValueError) listing the registered names."""
    entry = _lookup(name)
    if isinstance(entry, Strategy):
        return entry
    made = entry()
    if not isinstance(made, Strategy):
        raise TypeError(f"strategy {name!r}: its factory {entry!r} returned {made!r}, "
                        f"not a Strategy object")
    return made


def integrator_type(name: str) -> str:
    """The integrator plugin that renders the registered strategy ``name``: ``vr_path``,
    or the one a strategy that learns names in its ``integrator_type`` attribute (the
    ``guided`` strategy: ``vr_guided_path``, which trains it between passes)."""
    return getattr(_lookup(name), "integrator_type", "vr_path")


def resolve(strategy) -> Strategy:
    """A :class:`Strategy` from a registered name (:func:`get`) or a Strategy object."""
    if isinstance(strategy, Strategy):
        return strategy
    if isinstance(strategy, str):
        return get(strategy)
    raise TypeError(f"expected a strategy name ({', '.join(_registry)}) or a Strategy "
                    f"object, got {strategy!r}")


register("uniform", uniform)
register("cosine", cosine)
register("bsdf", bsdf)
register("mis", mis)

#: The names of the built-in strategies, in their order (``integrators.choices.STRATEGIES``).
BUILTIN = names()
