"""Parameter choices of the plugins that other code lists (experiments, benchmarks,
tests), defined once and importable before any Mitsuba variant is set.

The plugin modules themselves (``path.py``...) define classes that derive from
the current variant's ``mi.SamplingIntegrator``, so they need a variant.
"""

#: Valid values of ``vr_path``'s ``strategy`` parameter (the one definition of the list).
STRATEGIES = ("uniform", "cosine", "bsdf", "mis")

#: Mitsuba variant prefixes (Dr.Jit JIT backends) the plugins run on, the one definition
#: (``integrators.supported_variant`` and the scripts' ``--variant`` check): the two JIT
#: backends Mitsuba 3.9 documents, LLVM (CPU; the tests run there) and CUDA. Its Linux
#: wheel has no ``metal_*`` variants and the plugins are untried there, so ``metal`` is
#: not listed.
JIT_VARIANT_PREFIXES = ("llvm", "cuda")
