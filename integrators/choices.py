"""Parameter choices of the plugins that other code lists (experiments, benchmarks,
tests), defined once and importable before any Mitsuba variant is set.

The plugin modules themselves (``path.py``...) define classes that derive from
the current variant's ``mi.SamplingIntegrator``, so they need a variant.
"""


def __getattr__(name):
    # ``STRATEGIES``: the built-in ``vr_path`` strategies' names, defined once in
    # integrators.strategies (every registered one: integrators.strategies.names()).
    # Looked up lazily: integrators/__init__ imports this module before drjit may be
    # imported (it chooses libLLVM first), and strategies.py imports drjit.
    if name == "STRATEGIES":
        from .strategies import BUILTIN
        return BUILTIN
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: Mitsuba variant prefixes (Dr.Jit JIT backends) the plugins run on, the one definition
#: (``integrators.supported_variant`` and the scripts' ``--variant`` check): the two JIT
#: backends Mitsuba 3.9 documents, LLVM (CPU; the tests run there) and CUDA. Its Linux
#: wheel has no ``metal_*`` variants and the plugins are untried there, so ``metal`` is
#: not listed.
JIT_VARIANT_PREFIXES = ("llvm", "cuda")
