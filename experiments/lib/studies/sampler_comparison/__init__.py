"""The sampler study (``samplers``): every sampler of the sampler table, the bundled ones
against Mitsuba's own, one concern per module.

* :mod:`.plan`             settings (``Settings``, ``ScreenSettings``), the two passes'
                           declarations on the experiment engine, the job keys and the
                           ``Pass`` protocol
* :mod:`.analysis`         the efficiency pass's pure analysis: numbers in, numbers and
                           verdicts out (tables, curves, the conclusion rows, the pick)
* :mod:`.screen_analysis`  the screen-space pass's pure analysis (FLIP, the error
                           spectrum's low-frequency share, MSE efficiency)
* :mod:`.words`            the sentences made from both analyses (the report layer)
* :mod:`.efficiency`       the efficiency pass: declare, measure, analyse, report
* :mod:`.screen`           the screen-space pass: declare, measure, analyse, report
* :mod:`.study`            the entry point: the command line, the one place that reads it
                           (``settings_of``), the report's introduction and settings, and
                           the study's registration

Data flows one way: plan -> (the engine renders and measures) -> analysis and
screen_analysis -> words -> efficiency and screen (the passes' reports) -> study; each
module imports only modules before it in this list. The lab
(:mod:`experiments.lib.studies.lab`) declares the screen-space pass too, so that it finds
the study's renders in the job store; the suite and the convergence study read its pick
(:func:`.efficiency.pick_near`). This ``__init__`` imports nothing: importing one module
of the study does not load the others.
"""
