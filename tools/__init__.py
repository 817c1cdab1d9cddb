"""Developer tools: the docs generator (``docs``, its writers ``docs_*``) and checks
(``docs_check``, ``docs_check_*``), the mutation run (``mutants``, ``mutant_list``,
``mutant``), the browser set-up (``ensure_browser``), report statistics (``report_stats``)
and run comparison (``compare_runs``)."""
