"""The lab's point-sets part: every sampler's points for one pixel, planned, measured (or
read from the cache), analysed and reported.

Plan (:func:`plan_points`: a :class:`.lab.points.PointSpec` per count and sampler label)
-> measure (:func:`measure_points`: the point sets, cached under OUT/lab/cache, with their
discrepancy and joint low-frequency power per pair of dimensions) -> pure analysis
(:func:`analyse_points`, at the first count) -> report (:func:`report_points`: the point
grids, the spectra, the discrepancy tables and the conclusion).
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from experiments.lib import report
from experiments.lib.studies.lab import figures, points
from experiments.lib.studies.lab.config import NAME, Config
from experiments.lib.studies.sampler_comparison.analysis import families


@dataclasses.dataclass(frozen=True)
class PointsMeasured:
    names: list                  # sampler labels, in order
    results: dict                # {(spp, label): points.compute's dict}
    cd: dict                     # {(spp, label, pair): mean squared CD over pixels}
    joint: dict                  # {(spp, label, pair): joint low-frequency power}
    counts: dict                 # {spp: {label: points drawn}}


def plan_points(cfg: Config) -> list:
    width, height = cfg.pixels
    return [points.PointSpec(name, spp, seeds=(cfg.seed,), width=width, height=height)
            for spp in cfg.counts for name in cfg.sampler_labels()]


def measure_points(specs: list, cache: str) -> PointsMeasured:
    results, cd, joint, counts = {}, {}, {}, {}
    for spec in specs:
        res = results[(spec.spp, spec.sampler)] = points.cached(spec, cache)
        counts.setdefault(spec.spp, {})[spec.sampler] = int(res["count"])
        for a, b in points.PAIRS:
            cd[(spec.spp, spec.sampler, (a, b))] = float(np.mean(res[f"cd_{a}_{b}"]))
            joint[(spec.spp, spec.sampler, (a, b))] = float(res[f"joint_{a}_{b}"])
    names = list(dict.fromkeys(s.sampler for s in specs))
    return PointsMeasured(names, results, cd, joint, counts)


def analyse_points(m: PointsMeasured, spp: int) -> points.Findings:
    """The conclusion at ``spp`` requested (pure, from the measured numbers)."""
    at = {(n, p): v for (s, n, p), v in m.cd.items() if s == spp}
    joint = {(n, p): v for (s, n, p), v in m.joint.items() if s == spp}
    return points.analyse(at, joint, m.counts[spp], spp, families(m.names))


def report_points(out: str, cfg: Config, m: PointsMeasured,
                  found: points.Findings) -> list:
    out_dir = os.path.join(out, NAME)
    width, height = cfg.pixels
    names, rows, blocks = m.names, [], []
    for spp in cfg.counts:
        scatter, power, counts = {}, {}, m.counts[spp]
        for name in names:
            res = m.results[(spp, name)]
            for a, b in points.PAIRS:
                tag = f"{a}_{b}"
                scatter[(name, (a, b))] = res[f"scatter_{tag}"]
                power[(name, (a, b))] = (res["freqs"], res[f"power_{tag}"])
                cd = res[f"cd_{tag}"]
                expected = points.random_expectation(counts[name])
                rows.append([name, spp, counts[name], f"({a},{b})",
                             points.describe_pair(a, b),
                             float(f"{np.mean(cd):.6g}"), float(f"{np.std(cd):.3g}"),
                             float(f"{np.mean(cd) / expected:.4g}"),
                             float(f"{float(res[f'joint_{tag}']):.4g}"), len(cd)])
        figures.point_grid(os.path.join(out_dir, f"points_{spp}.png"),
                               f"One pixel's points at {spp} spp requested (vr_path bsdf+nee "
                               f"order)", names, list(points.PAIRS), scatter, counts)
        spectrum_points = points.PointSpec('', 0).spectrum_points
        figures.spectra(os.path.join(out_dir, f"spectrum_{spp}.png"),
                            f"Radially averaged power spectrum at {spp} spp, mean over "
                            f"{min(width * height, max(8, spectrum_points // spp))} pixels",
                            names, list(points.PAIRS), power, counts)
        blocks += [report.image(f"{NAME}/points_{spp}.png",
                                f"The points pixel 0 receives at {spp} spp requested (count "
                                f"drawn in brackets), per pair of dimensions."),
                   report.image(f"{NAME}/spectrum_{spp}.png",
                                f"Power spectra at {spp} spp (1 = independent points; below 1 "
                                f"at low frequencies = stratified).")]
    blocks.append(report.write_table(
        out, f"{NAME}/discrepancy",
        ["sampler", "spp", "count", "pair", "dimensions", "discrepancy_cd", "discrepancy_cd_std",
         "ratio_to_independent_expectation", "joint_power", "pixels"], rows,
        "Squared centered L2 discrepancy per sampler, count and pair (mean over pixels)",
        collapsed=True))
    spp = found.spp
    header = ["sampler", "count"] + [f"({a},{b})" for a, b in points.PAIRS]
    wide = [[n, m.counts[spp][n]] + [f"{m.cd[(spp, n, p)]:.3g}" for p in points.PAIRS]
            for n in names]
    wide.append(["(independent points, expected)", ""] + [
        f"{points.random_expectation(spp):.3g}" for _ in points.PAIRS])
    blocks += [
        report.write_table(out, f"{NAME}/discrepancy_{spp}", header, wide,
                           f"discrepancy_cd (squared centered L2) at {spp} spp requested, "
                           f"mean over pixels; columns: dimension pairs"),
        report.write_table(
            out, f"{NAME}/points_conclusion", points.HEADER,
            [r.cells() for r in found.rows],
            f"Point sets at {spp} spp requested: the pairs each sampler stratifies jointly "
            f"(discrepancy below {points.LOST} of independent points' and joint "
            f"low-frequency power below {points.JOINT}), only per coordinate, or not at "
            f"all"),
        report.text("\n\n".join(found.sentences))]
    return blocks

