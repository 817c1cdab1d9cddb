"""The sampling lab's settings: what one run computes (:class:`Config`), the full and the
quick run.

Defaults come from the parts' own modules (the BSDFs and incidences of :mod:`.lab.warps`,
the counts of :mod:`.lab.points`, the frozen guide's scene of :mod:`.lab.guide`) and from
the sampler study's screen-space pass (:mod:`.sampler_comparison.plan`), whose renders the
lab reads from the job store.
"""
from __future__ import annotations

import dataclasses

from experiments.lib.methods import strategies as registered_strategies
from experiments.lib.studies.lab import guide, points, warps
from experiments.lib.studies.sampler_comparison import plan

#: The study's registered name: its report section, ``run_all --lab``, its job keys.
NAME = "lab"
SAMPLES = 250_000
QUICK_SAMPLES = 10_000


@dataclasses.dataclass(frozen=True)
class Config:
    """What one run of the lab computes."""
    bsdfs: tuple = warps.BSDFS
    incidences: tuple = warps.INCIDENCES
    samplers: tuple | None = None        # None: every label of the sampler table
    counts: tuple = points.COUNTS
    pixels: tuple = (8, 8)               # width, height of the point-set "render"
    strategies: tuple | None = None      # None: every registered strategy
    samples: int = SAMPLES               # directions per warp panel
    seed: int = 0
    #: screen-space error: the sampler study's renders (first repeat) at these settings
    screen_resolution: tuple = (128, 128)
    screen_counts: tuple = (4, 16)
    screen_depth: int = 2
    screen_samplers: tuple | None = None     # None: the sampler study's default labels
    screen_reference_spp: int = plan.SCREEN_REFERENCE_SPP
    #: the frozen guide's panels (:mod:`.lab.guide`): the scene it trains on (None: none),
    #: film, training spp, surface points
    guide_scene: str | None = guide.SCENE
    guide_film: tuple = guide.FILM
    guide_spp: int = guide.SPP
    guide_sites: int = guide.SITES

    def sampler_labels(self) -> list[str]:
        return list(self.samplers or points.samplers())

    def strategy_names(self) -> list[str]:
        return list(self.strategies or registered_strategies())

    def screen_labels(self) -> list[str]:
        return list(self.screen_samplers or plan.default_screen_labels())


FULL = Config()
#: The screen-space part of --quick matches the sampler study's quick screen-space pass,
#: so that run_all's quick run renders it once.
QUICK = Config(bsdfs=(warps.BSDFS[1], warps.BSDFS[-1]), incidences=(60.0,),
               counts=(64,), pixels=(4, 4), samples=QUICK_SAMPLES, screen_resolution=(16, 8),
               screen_counts=(4,), screen_reference_spp=16, guide_film=(24, 18),
               guide_spp=64, guide_sites=1)

