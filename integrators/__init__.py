"""Variance-reduction plugins for Mitsuba 3.

Usage::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    import integrators        # registers vr_path, phong and halton for this variant

``integrators.register_strategy(name, strategy)`` adds a direction-sampling strategy
that ``vr_path``'s ``strategy`` parameter then takes by name (see
:mod:`integrators.strategies`; usable before a variant is set).

Importing registers every plugin for the current Mitsuba variant. A later
``mi.set_variant(...)`` to another JIT variant (``llvm_*``, ``cuda_*``)
registers them there too. Imported before any variant is set, the package
registers the plugins as soon as one is (this order also lets it choose
libLLVM, see below). Scalar variants are not supported: the plugins are
vectorised Dr.Jit code with symbolic loops; importing under one raises
ImportError and switching to one warns.

The first thing this package does is choose a libLLVM >= 17 for Dr.Jit (see
:mod:`integrators.llvm`); that only helps when ``integrators`` is imported
before mitsuba/drjit, otherwise it checks what drjit loaded and explains.
"""
from __future__ import annotations

import importlib
import sys
import warnings

from . import llvm as _llvm
from .choices import JIT_VARIANT_PREFIXES

_llvm.configure()

import mitsuba as mi  # noqa: E402  (must come after choosing libLLVM)

from . import strategies  # noqa: E402  (variant-free: the strategy registry)
from .strategies import register as register_strategy  # noqa: E402

__all__ = ["register", "register_strategy", "strategies", "PLUGIN_MODULES",
           "supported_variant"]

#: Modules that each define and register one plugin for the current variant.
#: (``guided`` registers the strategy ``guided``, ``guided_path`` the integrator that
#: trains it; the recorder, roulette and pass maths it imports define nothing per variant.)
PLUGIN_MODULES = ("phong", "path", "guided", "guided_path", "moments", "adaptive", "halton",
                  "zsobol")
#: Modules of per-variant base classes, defined again before the plugins that derive from them.
BASE_MODULES = ("sequence_sampler",)

#: Per registered variant, the namespaces its modules had: switching back to a variant
#: registered before restores them, so that ``integrators.sequence_sampler.SequenceSampler``
#: (which a user's sampler derives from) is the class of the current variant's ``mi.Sampler``.
_registered: dict[str, dict[str, dict]] = {}


def supported_variant(variant: str | None) -> bool:
    """True for the JIT variants the plugins run on (``llvm_*``, ``cuda_*``)."""
    return variant is not None and variant.split("_")[0] in JIT_VARIANT_PREFIXES


def _check_variant(variant: str | None) -> None:
    if not supported_variant(variant):
        raise ImportError(
            f"integrators: variant '{variant}' is not supported; the plugins need a JIT "
            f"variant (llvm_* or cuda_*), e.g. mi.set_variant('llvm_ad_rgb').")


def register() -> None:
    """Define and register every plugin for the current variant (idempotent)."""
    variant = mi.variant()
    _check_variant(variant)
    if variant in _registered:
        for name, namespace in _registered[variant].items():
            vars(sys.modules[f"{__name__}.{name}"]).update(namespace)
        return
    for name in BASE_MODULES + PLUGIN_MODULES:
        qualified = f"{__name__}.{name}"
        module = sys.modules.get(qualified)
        if module is None:
            importlib.import_module(qualified)
        else:
            # Plugin classes derive from the variant's mi.BSDF / mi.Sampler /
            # mi.SamplingIntegrator (or a base class that does): define them
            # again for the new variant, base classes first.
            importlib.reload(module)
    _registered[variant] = {name: dict(vars(sys.modules[f"{__name__}.{name}"]))
                            for name in BASE_MODULES + PLUGIN_MODULES}


def _on_variant_change(old: str | None, new: str | None) -> None:
    if supported_variant(new):
        register()
    elif new is not None:
        warnings.warn(f"integrators: variant '{new}' is not supported, the plugins "
                      f"(vr_path, phong, halton) are not available in it; use a JIT "
                      f"variant such as 'llvm_ad_rgb'.", stacklevel=2)


class _VariantStrategy:
    """The registry's entry for a strategy whose class a plugin module defines per variant
    (``guided``, in :mod:`.guided`), until a variant is set and that module registers the
    class in its place: its name and its integrator are known before, so that method names
    such as ``guided+nee`` parse (and a suite's default methods are the same) whether or
    not a variant is set yet."""

    def __init__(self, name: str, module: str, integrator_type: str):
        self.name, self.module, self.integrator_type = name, module, integrator_type

    def __call__(self):
        raise RuntimeError(f"strategy {self.name!r} is defined in integrators.{self.module} "
                           f"when a Mitsuba variant is set: call mi.set_variant(...) first")

    def __repr__(self) -> str:
        return f"<strategy {self.name!r} of integrators.{self.module}, defined per variant>"


#: Strategies defined by a plugin module per variant: (name, module, integrator type).
VARIANT_STRATEGIES = (("guided", "guided", "vr_guided_path"),)
for _name, _module, _integrator in VARIANT_STRATEGIES:
    if _name not in strategies.names():
        strategies.register(_name, _VariantStrategy(_name, _module, _integrator))

if mi.variant() is not None:
    register()
mi.detail.add_variant_callback(_on_variant_change)
