"""Parameter choices of the plugins that other code lists (experiments, benchmarks,
tests), defined once and importable before any Mitsuba variant is set.

The plugin modules themselves (``path.py``...) define classes that derive from
the current variant's ``mi.SamplingIntegrator``, so they need a variant.
"""

#: Valid values of ``vr_path``'s ``strategy`` parameter (the one definition of the list).
STRATEGIES = ("uniform", "cosine", "bsdf", "mis")
