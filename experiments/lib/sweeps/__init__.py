"""The stability sweeps: where each sampling method breaks down (one module per sweep).

Each sweep follows the protocol of :class:`.base.Sweep`: ``declare`` (a
:class:`~..engine.Declaration`: the experiment engine plans, renders and measures it),
``measure`` (numbers from the engine's :class:`~..engine.Measurements`),
``analyse`` (pure, tested on synthetic numbers in ``tests/test_sweeps.py``),
``report`` (charts with interval bands, tables with ``*_lo``/``*_hi``
columns, prose). :data:`REGISTRY` lists them all; ``experiments.stability``
offers exactly these as ``--sweeps``.

* :mod:`.exponent`: the Phong exponent of the glossy object, every ``vr_path`` strategy;
* :mod:`.light`: the light's size at constant power, with and without NEE;
* :mod:`.grazing`: grazing incidence on the scene's Phong material (no rendering);
* :mod:`.halton_randomization`: Halton without and with randomization at low and high depth;
* :mod:`.adaptive_pilot`: adaptive sampling against its plain twin where the pilot can mislead it.

Sweep points are scene variants (:func:`~..methods.scene_variant`) written to
``<out>/stability/scenes``. Outliers (largest pixel, fireflies, NaN/Inf) are
counted over every render (:class:`.base.Outliers`).
"""
from __future__ import annotations

from . import adaptive_pilot, exponent, grazing, halton_randomization, light
from .base import (BREAK_FACTOR, NAME, NORMAL, QUICK, Config, Context, Outliers, Skip, Sweep,
                   SweepReport)

#: Every stability sweep by name, in report order.
REGISTRY: dict[str, Sweep] = {s.name: s for s in (exponent.SWEEP, light.SWEEP, grazing.SWEEP,
                                                  halton_randomization.SWEEP,
                                                  adaptive_pilot.SWEEP)}
SWEEPS = tuple(REGISTRY)

__all__ = ["BREAK_FACTOR", "NAME", "NORMAL", "QUICK", "REGISTRY", "SWEEPS", "Config", "Context",
           "Outliers", "Skip", "Sweep", "SweepReport"]
