"""Shared library of the experiment scripts, one concern per module.

* :mod:`.store`    atomic writes, EXR/PNG/JSON/CSV I/O, tone mapping
* :mod:`.methods`  the method table and scene loading (any Mitsuba scene)
* :mod:`.render`   rendering in passes, accumulation, resume, references
* :mod:`.metrics`  MSE, relMSE, convergence slopes, efficiency, bias checks
* :mod:`.figures`  matplotlib figures (Agg)
* :mod:`.report`   per-experiment sections and ``results/index.html``
* :mod:`.cli`      the argument parser shared by every script
"""
import integrators  # noqa: F401  (chooses libLLVM before drjit is imported)
