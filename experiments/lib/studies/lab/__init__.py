"""The sampling lab (``lab``): every vr_path strategy as a warp, every sampler's point sets,
and each sampler's screen-space error, measured; one concern per module.

* :mod:`.mass`           the mass and albedo checks of a warp panel (pure numbers)
* :mod:`.warps`          a warp panel (histogram, density, chi-square, weights) computed and
                         cached; the warps' conclusion (mass)
* :mod:`.guide`          the panels of a trained, frozen guide at scene points (warps)
* :mod:`.points`         a sampler's point sets: drawn as a render draws them, discrepancy,
                         spectra, cached; their conclusion
* :mod:`.figures`        the lab's figures (mosaics, point grids, spectra; matplotlib)
* :mod:`.checks_report`  the mass and albedo checks in the report: table and sentences (mass)
* :mod:`.study`          the entry point: settings, each part planned, measured, analysed
                         and reported, the study's registration

Data flows one way: mass -> warps -> guide; points; figures; checks_report -> study, which
also declares the sampler study's screen-space pass
(:mod:`experiments.lib.studies.sampler_comparison.plan`) to read its renders from the job
store. Each module imports only modules before it in this list. This ``__init__`` imports
nothing: importing one module of the lab does not load the others.
"""
