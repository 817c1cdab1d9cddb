"""The scene suite: every method on scenes that each isolate one phenomenon.

Data flows one way through its modules:

* :mod:`.declare`      the settings, the scenes as read (header, film, reference) and the
                       one declaration the experiment engine renders;
* :mod:`.reference_choice`  which reference each scene's errors use (path's, or the best
                       sampler's method's where its chunks agree with path's);
* :mod:`.precision`    the precision rule, a policy the declaration gives its equal-time
                       budget (the engine asks it once per scene);
* :mod:`.errors`       expected relMSE from the pixels' variances, paired efficiencies;
* :mod:`.bias_test`    every cell's bias test against the reference's chunks;
* :mod:`.measure`      the engine's measurements as the analysis's numbers;
* :mod:`.analysis`     pure functions of numbers: intervals, winners, verdicts;
* :mod:`.bias_report`, :mod:`.words`, :mod:`.report`  the words, tables and figures;
* :mod:`.study`        the command line (``python -m experiments.suite``) and the run;
                       importing it registers the study.
"""
