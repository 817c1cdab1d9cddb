"""The sampler study's settings and plan: what a run measures, and the jobs it renders.

:class:`Settings` (and the screen-space pass's :class:`ScreenSettings`), built once from the
command line by :func:`.sampler_comparison.settings_of`; the jobs of a ladder
(:func:`ladder_job`, named ``samplers/...``, their seeds derived from the name), the
screen-space pass's reference and ladders (which the lab plans too, so that it finds them in
the store), and the :class:`Pass` protocol every measurement pass follows: plan -> measure
-> pure analysis -> report.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from experiments.lib import clock, samplers
from experiments.lib.jobs import Job
from experiments.lib.methods import Depth, Method, parse_method
from experiments.lib.methods import method_name as _method_name
from experiments.lib.study import Study, repeat_prefix

#: The study's registered name: its report section, ``run_all --samplers``, its job keys.
NAME = "samplers"
#: The method every sampler drives, by default.
BASE = "bsdf+nee"

#: The screen-space pass's defaults: small enough for ``make run`` (every FLIP of a
#: 128x128 image costs a few tenths of a CPU second, each native sampler compiles a kernel
#: per count); larger settings through the --screen-* options.
SCREEN_RESOLUTION = "128x128"
SCREEN_COUNTS = (1, 4, 16)
SCREEN_DEPTHS = (2,)
SCREEN_REPEATS = 2
SCREEN_REFERENCE_SPP = 512
#: Native samplers of the default pass besides the baseline: the two with the lowest FLIP
#: in the zsobol sampler's calibration (issue 25); --screen-samplers all adds the others.
SCREEN_NATIVES = ("multijitter", "ldsampler")


def default_screen_labels() -> list[str]:
    """The default pass's labels, from the sampler table: the baseline, the natives of
    :data:`SCREEN_NATIVES`, and every sampler that is not native (bundled, or a
    ``--plugin`` file's) at its last randomization (the table lists them weakest first)."""
    out = [samplers.DEFAULT] + [n for n in SCREEN_NATIVES if n in samplers.names()]
    out += [samplers.get(n).labels()[-1] for n in samplers.names() if not samplers.get(n).native]
    return list(dict.fromkeys(out))


@dataclass(frozen=True)
class ScreenSettings:
    """What the screen-space pass measures."""
    resolution: tuple             # (width, height)
    counts: tuple                 # sample counts, each a fresh render
    depths: tuple                 # max_depth values
    samplers: tuple               # sampler labels
    repeats: int                  # independent randomizations (1 for a deterministic label)
    reference_spp: int
    reference: Method             # the reference's method (independent sampler)


@dataclass(frozen=True)
class Settings:
    """What one run of the study measures (typed; the Namespace stays in :func:`run`)."""
    base: Method                  # the method every sampler drives
    depths: tuple                 # max_depth values
    targets: tuple                # the ladder's requested counts
    samplers: tuple               # sampler labels, from the sampler table
    depth: Depth                  # the scene's path settings (max_depth set per depth)
    scene: str
    resolution: tuple             # (width, height)
    screen: ScreenSettings | None = None     # None: no screen-space pass

    def at(self, max_depth: int) -> Depth:
        return Depth(max_depth, self.depth.rr_depth, self.depth.hide_emitters)


def method(base: Method, sampler: str) -> Method:
    """``base`` driven by the sampler label ``sampler``."""
    return parse_method(_method_name(base, sampler))


def ladder_job(st: Study, cfg: Settings, root: str, d: int, label: str, count: int,
               repeat: int, resolution: tuple, group: str) -> Job:
    """Repeat ``repeat`` of ``label`` at ``count`` spp and max_depth ``d``, a fresh render,
    named ``root/label/sppNNNNN[/rR]`` (its seed derives from the name)."""
    return st.job(repeat_prefix(f"{root}/{label}/spp{count:05d}", repeat),
                  method(cfg.base, label), count, depth=cfg.at(d), resolution=resolution,
                  timing_group=group)


def timing(st: Study, result) -> float:
    """Render time compared: the one clock (:func:`.clock.cost`)."""
    return clock.cost(result)


# ------------------------------------------------------------------ passes

@dataclass
class PassReport:
    blocks: list                  # report blocks, in order
    summary: dict                 # entries of summary.json
    jobs: list                    # the timed jobs (for "render times measured on")


class Pass(Protocol):
    """One measurement pass: plan -> measure -> analyse (pure) -> report."""
    name: str

    def plan(self, st: Study, cfg: Settings): ...

    def jobs(self, planned) -> list[Job]: ...

    def measure(self, st: Study, cfg: Settings, planned): ...

    def analyse(self, measured): ...

    def report(self, st: Study, cfg: Settings, planned, measured, result) -> PassReport: ...


def rungs(st: Study, reps: list):
    """Per rung of a label's ladders (``reps``: one ladder per repeat): its job in the first
    repeat, the stored results of every repeat and their images (float64)."""
    for i, target in enumerate(reps[0]):
        results = [st.store.get(rep[i].key) for rep in reps]
        yield target, results, [r.image.astype(float) for r in results]


def screen_reference_jobs(st: Study, sc: ScreenSettings, depth: Depth) -> list[Job]:
    """The pass's reference: ``sc.reference_spp`` of ``sc.reference`` at its resolution."""
    return st.reference_jobs(st.info, depth, resolution=sc.resolution, spp=sc.reference_spp,
                             method=sc.reference, typical_spp=SCREEN_REFERENCE_SPP)


def screen_ladders(st: Study, cfg: Settings, sc: ScreenSettings, d: int, labels,
                   counts, repeats: int) -> dict:
    """``{label: [repeat: [job per count]]}`` (one repeat for a deterministic label), named
    by the pass's resolution (``samplers/screen-128x128-depth2/...``), so that the lab,
    planning the same jobs, finds them in the store."""
    root = "{}/screen-{}x{}-depth{}".format(NAME, *sc.resolution, d)
    return {s: [[ladder_job(st, cfg, root, d, s, t, r, sc.resolution, f"{NAME}/screen/depth{d}")
                 for t in counts]
                for r in range(1 if method(cfg.base, s).deterministic else repeats)]
            for s in labels}
