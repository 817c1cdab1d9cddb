"""Shared library of the experiment scripts, one concern per module.

Data flows one way: plan -> execute -> store -> analyse -> present. Listed so
that each module imports only modules above it (``tests/test_layout.py`` checks
that the import graph has no cycle):

* :mod:`.files`          atomic file writes, EXR/PNG/JSON/CSV/NPZ, tone mapping (no lib imports)
* :mod:`.figure_pool`    figures written by worker processes, never while a render runs
                         (files)
* :mod:`.clock`          the one clock: what an image costs (kernel time of every pass plus
                         the method's host work between passes), and the one ``Timer`` of
                         how long a study's parts took (no lib imports)
* :mod:`.names`          an error named in one line (no lib imports)
* :mod:`.jobs`           jobs and results as plain data (``Job``, ``JobResult``, ``derive_seed``,
                         ``MAX_LANES``), ``Accumulator``/``accumulate`` over results,
                         ``cpu_model`` (the clock)
* :mod:`.metrics`        MSE, relMSE (with outlier rejection), slopes, efficiency, bias checks
* :mod:`.stats`          intervals, errors over the reference's floor, verdicts over repeats
* :mod:`.samplers`       the sampler table: one descriptor per sampler, ``register_sampler``
* :mod:`.methods`        the method grammar: names parsed once into ``Method`` values
                         (strategies from :mod:`integrators.strategies`, samplers)
* :mod:`.scenes`         scenes read, loaded and varied through Mitsuba's own parser; the
                         scene contract (``Needs``)
* :mod:`.plan`           render jobs planned: keys, seeds, sample offsets, ladders (jobs,
                         methods, scenes)
* :mod:`.store`          the resumable job store (files, jobs)
* :mod:`.execute`        runs jobs (``run_job``, ``LocalExecutor``) and stores each result
* :mod:`.extensions`     ``--plugin FILE``: a researcher's strategy, sampler or study
* :mod:`.cluster`        the Dask executor (execute, extensions)
* :mod:`.study`          what a study shares: store, executor, reference image, accumulation
* :mod:`.declaration`    what a study declares: scenes, budgets, a sweep, policies (the
                         equal-time factor, the reference floor), repeats
* :mod:`.counts`         the counting rules: equal-time counts, a reference's samples
* :mod:`.measurements`   the runs of every cell against its reference, their intervals
* :mod:`.engine_references`  the engine's references: planned, rendered, extended
* :mod:`.engine`         the experiment engine, the only budget loop: every count decided
                         (a learning method's pilot and ladder included), rendered in turns,
                         costed and measured
* :mod:`.prose`          the report layer's sentences from templates (jinja2)
* :mod:`.figures`        every chart (matplotlib, Agg)
* :mod:`.viewer`         the report's interactive image comparisons (files, metrics)
* :mod:`.report`         per-experiment sections and ``results/index.html``
* :mod:`.cli`            the argument parser shared by every script, ``load_extensions``
* :mod:`.scene_probes`   measurements on a scene's objects without rendering (Phong mask, ...)
* :mod:`.sweeps`         the stability sweeps (plan, analysis, prose), one module each
* :mod:`.studies`        the study registry (``StudySpec``, ``register_study``, the one
                         ``main``) and the built-in studies, a module or a package each
                         (``studies/sampler_comparison/``; ``studies/lab/``, the sampling
                         lab; ``studies/suite/``, the scene suite); the scripts ``experiments/NAME.py`` are their commands

Package data: ``viewer_assets/`` (viewer.js, viewer.css), read with
:mod:`importlib.resources`; the bundled scenes are the :mod:`scenes` package.
"""
import integrators  # noqa: F401  (chooses libLLVM before drjit is imported)
