"""Experiment suite: convergence sequences, error against time, the writeup's figures, one report.

Scripts (each ``python -m experiments.<name> --help``), thin layers over :mod:`experiments.lib`:

* ``convergence``  progressive renders 1, 2, 4, ... --spp per method, errors against a cached
  reference, error-vs-spp/time plots with slopes, equal-time panel, efficiency table;
* ``writeup``      the writeup's figures with numbers (``--full``: 1024x512, 1000-spp bias checks);
* ``run_all``      both, then ``<out>/index.html`` (``make run``; ``make full`` adds ``--full``).

Every render is resumable: rerunning a command skips finished work. A new experiment adds
its part of the report by calling :func:`experiments.lib.report.write_section` (it writes
``<out>/<name>/section.json``) and then :func:`experiments.lib.report.build_report`.

``integrators`` is imported first so that it can choose libLLVM before drjit loads.
"""
import integrators  # noqa: F401  (must precede any mitsuba/drjit import)
