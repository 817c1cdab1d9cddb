"""A study of one's own, in one file: where should Russian roulette start? (``roulette``)

For one method (default ``bsdf+nee``) at several ``rr_depth`` values, R independent renders
of the same sample count each; expected relMSE against a reference (its own expected error
subtracted), warm render time, and efficiency 1/(relMSE x time) relative to ``rr_depth`` 5
(Mitsuba's default), with 95% intervals and a verdict only where the interval excludes 1.

It registers itself with the study registry, so ``run_all`` runs it with the built-in studies
(``--roulette default|quick|off``)::

    python -m experiments.run_all --plugin examples/roulette_study.py
    python examples/roulette_study.py --out results      # alone

plan -> measure -> pure analyse -> report, as every study. See docs/extending.md.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass

from experiments.lib import cli, clock, metrics, report, stats
from experiments.lib.methods import Depth
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.studies.settings import StudySettings, common_fields
from experiments.lib.study import Study, repeat_prefix

NAME = "roulette"
BASELINE = 5


def build_parser() -> cli.Parser:
    p = cli.common_parser("roulette_study", "Russian roulette: efficiency against rr_depth",
                          spp=64, default_resolution="64x32", methods=("bsdf+nee",))
    p.set_defaults(reference_spp=1024, max_depth=-1)
    p.add_argument("--rr-depths", type=depth_list, default="1,2,3,5,8",
                   help="rr_depth values compared (integers > 0)")
    return p


def depth_list(text: str) -> list[int]:
    try:
        depths = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        depths = []
    if not depths or min(depths) < 1:
        raise cli.argparse.ArgumentTypeError(
            f"invalid --rr-depths '{text}': expected comma-separated integers > 0, e.g. 1,5")
    return list(dict.fromkeys(depths))


@dataclass(frozen=True)
class Measured:
    """Per rr_depth: relMSE per repeat (floor not yet subtracted) and seconds per repeat."""
    relmse: dict
    seconds: dict
    floor: float


def plan(st: Study, method, depths: list[int], spp: int) -> tuple[list, dict]:
    """(reference jobs, {rr_depth: [one job per repeat]})."""
    base = st.depth
    jobs = {d: [st.job(repeat_prefix(f"{NAME}/rr{d}", r), method, spp,
                       depth=Depth(base.max_depth, d, base.hide_emitters), timing_group=NAME)
                for r in range(st.repeats)] for d in depths}
    return st.reference_jobs(), jobs


def measure(st: Study, ref_jobs, jobs) -> Measured:
    ref, meta = st.reference(ref_jobs)
    results = {d: [st.store.get(j.key) for j in reps] for d, reps in jobs.items()}
    return Measured({d: [metrics.relmse(r.image, ref) for r in rs] for d, rs in results.items()},
                    {d: [clock.cost(r) for r in rs] for d, rs in results.items()},
                    meta["relmse_floor"])


def analyse(m: Measured) -> list[list]:
    """Pure: one row per rr_depth (relMSE, time, efficiency over the baseline, verdict)."""
    base = BASELINE if BASELINE in m.relmse else min(m.relmse)
    excess = {d: [v - m.floor for v in values] for d, values in m.relmse.items()}
    rows = []
    for d in m.relmse:
        error = stats.excess_interval(m.relmse[d], m.floor)
        if d == base:
            ratio, verdict = stats.Estimate(1.0, 1.0, 1.0, len(excess[d])), "the baseline"
        else:
            ratio = stats.efficiency_ratio(excess[d], m.seconds[d], excess[base],
                                           m.seconds[base])
            verdict = stats.verdict(f"rr_depth {d}", f"rr_depth {base}", ratio)
        rows.append([d, *error.cells(), stats.g(sum(m.seconds[d]) / len(m.seconds[d])),
                     *ratio.cells(), verdict])
    return rows


HEADER = ["rr_depth", "relMSE", "relMSE_lo", "relMSE_hi", "seconds", "efficiency",
          "efficiency_lo", "efficiency_hi", "verdict"]


def run(args) -> None:
    start = time.perf_counter()
    st = Study(StudySettings(**common_fields(args)))     # typed settings, not the Namespace
    method = args.method_objs[0]
    ref_jobs, jobs = plan(st, method, args.rr_depths, args.spp)
    st.run(ref_jobs + [j for reps in jobs.values() for j in reps], f"{NAME}: renders")
    rows = analyse(measure(st, ref_jobs, jobs))
    report.write_section(args.out, NAME, "Russian roulette: where to start it", 60,
                         {"method": method.name, "spp": args.spp, "repeats": st.repeats,
                          "scene": os.path.basename(args.scene)},
                         [report.write_table(args.out, f"{NAME}/efficiency", HEADER, rows,
                                             f"{method.name}, efficiency relative to "
                                             f"rr_depth {BASELINE}")], args.variant,
                         time.perf_counter() - start)


STUDY = register_study(StudySpec(
    NAME, "Russian roulette: where to start it", 60, build_parser, run,
    quick=("--resolution", "16x8", "--spp", "4", "--reference-spp", "32", "--repeats", "2",
           "--rr-depths", "1,5")), replace=True)

if __name__ == "__main__":
    STUDY.script()
