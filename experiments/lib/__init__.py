"""Shared library of the experiment scripts, one concern per module.

Data flows one way: plan -> execute -> store -> analyse -> present.

* :mod:`.methods`        the method grammar (strategies, samplers, randomizations read from
                         the plugins), plugin dicts, scene reading/loading/variants
* :mod:`.plan`           render jobs as plain data (seeds, sample offsets, ladders), accumulation
* :mod:`.execute`        runs jobs (``run_job``, ``LocalExecutor``) and stores each result
* :mod:`.store`          atomic file writes, EXR/PNG/JSON/CSV, the resumable job store
* :mod:`.study`          what a script shares: store, executor, reference image
* :mod:`.metrics`        MSE, relMSE, slopes, efficiency, bias and convergence checks, outliers
* :mod:`.figures`        every chart (matplotlib, Agg)
* :mod:`.report`         per-experiment sections and ``results/index.html``
* :mod:`.cli`            the argument parser shared by every script
* :mod:`.sweeps`         the stability sweeps (plan, analysis, prose)
* :mod:`.sampler_study`  the sampler study's table and conclusion
* :mod:`.scene_probes`   measurements on a scene's objects without rendering (Phong mask, ...)
"""
import integrators  # noqa: F401  (chooses libLLVM before drjit is imported)
