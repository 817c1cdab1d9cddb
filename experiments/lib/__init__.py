"""Shared library of the experiment scripts, one concern per module.

Data flows one way: plan -> execute -> store -> analyse -> present. Listed so
that each module imports only modules above it (``tests/test_layout.py`` checks
that the import graph has no cycle):

* :mod:`.files`          atomic file writes, EXR/PNG/JSON/CSV/NPZ, tone mapping (no lib imports)
* :mod:`.jobs`           jobs and results as plain data (``Job``, ``JobResult``, ``derive_seed``,
                         ``MAX_LANES``), ``Accumulator``/``accumulate`` over results,
                         ``cpu_model`` (no lib imports)
* :mod:`.metrics`        MSE, relMSE, slopes, efficiency, bias and convergence checks, outliers
* :mod:`.stats`          intervals and verdicts over repeats
* :mod:`.methods`        the method grammar (strategies, samplers, randomizations read from
                         the plugins), plugin dicts, scene reading/loading/variants (files)
* :mod:`.plan`           render jobs planned: keys, seeds, sample offsets, ladders (jobs, methods)
* :mod:`.store`          the resumable job store (files, jobs)
* :mod:`.execute`        runs jobs (``run_job``, ``LocalExecutor``) and stores each result
                         (jobs, methods, store)
* :mod:`.cluster`        the Dask executor (execute)
* :mod:`.study`          what a script shares: store, executor, reference image, accumulation
                         of stored results (plan, execute, jobs, methods, store)
* :mod:`.figures`        every chart (matplotlib, Agg; store, metrics)
* :mod:`.viewer`         the report's interactive image comparisons (files, metrics)
* :mod:`.report`         per-experiment sections and ``results/index.html`` (files, jobs,
                         store, viewer)
* :mod:`.cli`            the argument parser shared by every script (methods, cluster)
* :mod:`.scene_probes`   measurements on a scene's objects without rendering (Phong mask, ...)
* :mod:`.sweeps`         the stability sweeps (plan, analysis, prose)
* :mod:`.sampler_study`  the sampler study's table and conclusion

Package data: ``viewer_assets/`` (viewer.js, viewer.css), read with
:mod:`importlib.resources`; the bundled scenes are the :mod:`scenes` package.
"""
import integrators  # noqa: F401  (chooses libLLVM before drjit is imported)
