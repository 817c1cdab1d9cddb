"""Benchmarks of the plugins against Mitsuba's built-ins (``make bench``).

* :mod:`.common`  set-up, scenes and configurations, timed renders, machine info
* :mod:`.probes`  subprocess probes: JIT compile time, peak RSS of the pass renderer
* :mod:`.run`     the table (``python -m benchmarks.run``), ``results/bench.{md,json}``

Every speed figure is a ratio of two renders timed in the same process after
a warm-up render, interleaved (A, B, A, B, ...) and reduced to the median of
the per-pair ratios, so that load from other processes cancels out.
"""
