"""The lab's screen-space part: each sampler's error image and its power spectrum, from
the sampler study's screen-space renders.

Plan (:func:`plan_screen`: the sampler study's own screen-space declaration,
:func:`.sampler_comparison.plan.declare_screen`, at one repeat, so that the jobs are its
first repeat's and the job store has them where that study ran) -> measure
(:func:`measure_screen`: the engine renders what the store lacks; each render's error
field, spectrum and low-frequency share) -> report (:func:`report_screen`: the mosaic of
error images and spectra, the radial spectra, the table).
"""
from __future__ import annotations

import dataclasses
import os

from experiments.lib import report, screen_space
from experiments.lib.engine import Cell, Engine
from experiments.lib.figures import spectrum_panels
from experiments.lib.methods import parse_method
from experiments.lib.studies.lab import figures
from experiments.lib.studies.lab.config import NAME, Config
from experiments.lib.studies.sampler_comparison import plan
from experiments.lib.studies.sampler_comparison.screen import screen_floor


@dataclasses.dataclass(frozen=True)
class ScreenMeasured:
    labels: list
    counts: tuple
    fields: dict                 # {(label, count): (H, W) luminance error, mean subtracted}
    spectra: dict                # {(label, count): periodogram / its mean (white noise 1)}
    radial: dict                 # {(label, count): (frequencies, radially averaged power)}
    shares: dict                 # {(label, count): low-frequency share}
    rendered: dict               # {(label, count): spp rendered}
    found: int                   # of the renders, found in the store before the lab ran
    total: int


def plan_screen(engine: Engine, cfg: Config, reference) -> plan.Planned:
    """The sampler study's screen-space declaration at ``cfg``'s settings, one repeat (the
    same jobs as the study's first repeat: :func:`.sampler_comparison.plan.declare_screen`)."""
    st, labels, depth = engine.study, cfg.screen_labels(), cfg.screen_depth
    screen = plan.ScreenSettings(
        tuple(cfg.screen_resolution), tuple(cfg.screen_counts), (depth,), tuple(labels), 1,
        cfg.screen_reference_spp, reference)
    study = plan.Settings(
        parse_method(plan.BASE), (depth,), (), tuple(labels), st.depth,
        st.info.path, (st.width, st.height), screen)
    return plan.plan(engine, plan.declare_screen(study, screen, st.info))


def measure_screen(engine: Engine, cfg: Config, planned: plan.Planned) -> ScreenMeasured:
    """Render what the stores lack (the engine), then each render's error field and
    spectrum."""
    st, decl = engine.study, planned.declaration
    refs, renders = [j for chunks in planned.refs.values() for j in chunks], planned.renders()
    found = sum(st.store.has(j.key) for j in refs + renders)
    measured = engine.run(decl)
    (scene, ref_jobs), = planned.refs.items()
    ref = measured.references[scene][0]
    floor = screen_floor(st, ref_jobs)
    fields, spectra, radial, shares, rendered = {}, {}, {}, {}, {}
    labels = cfg.screen_labels()
    for label, method in zip(labels, decl.methods):
        for budget, count in zip(decl.budgets, cfg.screen_counts):
            run = measured.runs[Cell(scene[0], method.name, budget.name)][0][-1]
            field = screen_space.error_field(run.image, ref)
            power = screen_space.periodogram(field)
            key = (label, count)
            fields[key] = field
            spectra[key] = screen_space.normalized(power, floor)
            radial[key] = screen_space.spectrum(spectra[key])
            shares[key] = screen_space.low_share(power, floor)
            rendered[key] = run.spp
    return ScreenMeasured(labels, tuple(cfg.screen_counts), fields, spectra, radial, shares,
                          rendered, found, len(refs) + len(renders))


def screen_source(m: ScreenMeasured) -> str:
    """Where the renders came from."""
    if m.found == m.total:
        return (f"all {m.total} renders found in the job store (the sampler study's "
                f"screen-space jobs)")
    if m.found == 0:
        return (f"all {m.total} renders made by the lab (the sampler study's screen-space "
                f"jobs, stored for it to reuse)")
    return (f"{m.found} of {m.total} renders found in the job store (the sampler study's "
            f"screen-space jobs), {m.total - m.found} made by the lab")


def report_screen(out: str, cfg: Config, m: ScreenMeasured) -> list:
    out_dir = os.path.join(out, NAME)
    width, height = cfg.screen_resolution
    by_count = {c: figures.error_tiles([m.fields[(s, c)] for s in m.labels],
                                           [m.spectra[(s, c)] for s in m.labels])
                for c in m.counts}
    tiles = [[t for c in m.counts for t in by_count[c][r]] for r in range(len(m.labels))]
    columns = [f"{what}, {c} spp" for c in m.counts for what in ("error", "spectrum")]
    figures.error_mosaic(os.path.join(out_dir, "screen_errors.png"),
                             f"Error images and their power spectra, {width}x{height}, "
                             f"max_depth {cfg.screen_depth}", m.labels, columns, tiles)
    spectrum_panels(os.path.join(out_dir, "screen_spectra.png"),
                    {f"{c} spp requested": {s: m.radial[(s, c)] for s in m.labels}
                     for c in m.counts}, screen_space.LOW,
                    "Radially averaged power spectra of the error images above")
    rows = [[s, c, m.rendered[(s, c)], f"{m.shares[(s, c)]:.4g}"] for s in m.labels
            for c in m.counts]
    white = screen_space.white_share((height, width))
    return [
        report.image(f"{NAME}/screen_errors.png",
                     f"Per sampler: the error (render minus reference, luminance; red too "
                     f"bright, blue too dark, one scale per count) and its power spectrum "
                     f"(frequency 0 in the middle, the Nyquist frequency at the edges; log "
                     f"of the power over white noise's, smoothed over {figures.SMOOTH}x"
                     f"{figures.SMOOTH} bins; dark centre: blue noise) at "
                     f"{' and '.join(map(str, m.counts))} spp; {screen_source(m)}."),
        report.image(f"{NAME}/screen_spectra.png",
                     f"The same spectra radially averaged (white noise: 1); the low-"
                     f"frequency share is the power left of the dashed line. One render "
                     f"each: the sampler study gives intervals over repeats."),
        report.write_table(out, f"{NAME}/screen", ["sampler", "spp requested",
                                                   "spp rendered", "low-frequency share"],
                           rows, f"Low-frequency share of each error image above (one "
                                 f"render; white noise {white:.4f})")]

