"""Experiment suite: convergence, the writeup's figures, samplers, stability, one report.

Scripts (each ``python -m experiments.<name> --help``), thin layers over :mod:`experiments.lib`:

* ``convergence``  progressive renders 1, 2, 4, ... --spp per method (``bsdf+nee`` and
  Mitsuba's ``path`` among the defaults), errors against a reference, error-vs-spp/time
  plots with slopes, equal-time panel, efficiency table;
* ``writeup``      the writeup's figures with numbers (``--full``: 1024x512, 1000-spp bias checks);
* ``samplers``     halton (each randomization) against Mitsuba's five samplers, by efficiency;
* ``stability``    where each method breaks down (Phong exponent, light size, grazing, Halton);
* ``run_all``      all of them, then ``<out>/index.html`` (``make run``; ``make full``
  adds ``--full``).

Each script plans its render jobs (:mod:`.lib.plan`), executes the ones the store lacks
(:mod:`.lib.execute`, results in ``<out>/store``), then analyses and presents them: a
rerun resumes without redoing finished jobs. A new experiment adds its part of the
report by calling :func:`experiments.lib.report.write_section` (it writes
``<out>/<name>/section.json``) and then :func:`experiments.lib.report.build_report`.

``integrators`` is imported first so that it can choose libLLVM before drjit loads.
"""
import integrators  # noqa: F401  (must precede any mitsuba/drjit import)
