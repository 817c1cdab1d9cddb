"""The sampling lab (``lab``): every vr_path strategy as a warp, every sampler's point sets,
and each sampler's screen-space error, measured; one concern per module.

The measurements, each pure numbers in and out or cached on disk:

* :mod:`.mass`           the mass and albedo checks of a warp panel and their verdicts
* :mod:`.warps`          a warp panel (histogram, density, chi-square, weights) computed and
                         cached; the warps' conclusion (mass)
* :mod:`.guide`          the panels of a trained, frozen guide at scene points (warps)
* :mod:`.points`         a sampler's point sets drawn as a render draws them: discrepancy,
                         spectra, cache, conclusion

The presentation:

* :mod:`.figures`        the lab's figures (mosaics, point grids, spectra; matplotlib)
* :mod:`.checks_report`  the mass and albedo checks in the report: table and sentences (mass)

The study, one module per part of its report:

* :mod:`.config`         what one run computes (``Config``), the full and the quick run
                         (warps, points, guide; the sampler study's screen-space defaults)
* :mod:`.warp_part`      the warps and the frozen guide: plan, measure, report
* :mod:`.point_part`     the point sets: plan, measure, analyse, report
* :mod:`.screen_part`    the screen-space error images: the sampler study's screen-space
                         pass declared at one repeat, measured, reported
* :mod:`.study`          the entry point: the command line, the three parts in turn, the
                         section and summary.json, the study's registration

Data flows one way, down this list: mass -> warps -> guide; points; figures;
checks_report -> config -> warp_part, point_part, screen_part -> study. Each module imports
only modules above it. The lab declares the sampler study's screen-space pass
(:mod:`experiments.lib.studies.sampler_comparison.plan`) to read that study's renders from
the job store. This ``__init__`` imports nothing: importing one module of the lab does not
load the others.
"""
