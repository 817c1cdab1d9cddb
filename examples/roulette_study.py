"""A study of one's own, in one file: where should Russian roulette start? (``roulette``)

One method (default ``bsdf+nee``) at several ``rr_depth`` values, R renders each: relMSE
(the reference's floor subtracted), cost (the one clock), efficiency over ``rr_depth`` 5
(Mitsuba's default) with 95% intervals and verdicts. The engine plans, renders, times and
measures; this file declares and tabulates. See docs/extending.md.
"""
import os
from dataclasses import replace

from experiments.lib import cli, clock, report, stats
from experiments.lib.engine import Budget, Cell, Declaration, Engine, SceneSetup, Sweep
from experiments.lib.studies import StudySpec, register_study
from experiments.lib.study import Study, StudySettings

NAME, TITLE, BASELINE = "roulette", "Russian roulette: where to start it", 5
HEADER = ["rr_depth", "relMSE", "relMSE_lo", "relMSE_hi", "seconds", "efficiency",
          "efficiency_lo", "efficiency_hi", "verdict"]


def build_parser() -> cli.Parser:
    p = cli.common_parser("roulette_study", "Russian roulette: efficiency against rr_depth",
                          spp=64, default_resolution="64x32", methods=("bsdf+nee",))
    p.set_defaults(reference_spp=1024, max_depth=-1)
    p.add_argument("--rr-depths", type=cli.int_list("--rr-depths", 1), default="1,2,3,5,8",
                   help="rr_depth values compared (integers > 0)")
    return p


def declare(args) -> Declaration:
    depths = sorted(set(args.rr_depths) | {BASELINE})
    scene = SceneSetup("scene", args.info, tuple(args.resolution), args.depth)
    rr = Sweep("rr_depth", tuple(depths), lambda d, s: replace(s, depth=replace(
        s.depth, rr_depth=d)), shared_reference=True)
    return Declaration(NAME, (args.method_objs[0],), (scene,),
                       (Budget.equal_spp(args.spp),), args.repeats, rr,
                       key=lambda decl, cell: f"{NAME}/rr{cell.point}")


def table(measured, method: str) -> list[list]:
    """One row per rr_depth: relMSE, cost, efficiency over the baseline, verdict."""
    rows, base = [], Cell("scene", method, "equal-spp", BASELINE)
    for d in measured.declaration.sweep.values:
        cell = replace(base, point=d)
        ratio, costs = measured.efficiency(cell, base), [r.cost for r in measured.final(cell)]
        rows.append([d, *measured.error(cell).cells(), stats.g(sum(costs) / len(costs)),
                     *ratio.cells(), "the baseline" if d == BASELINE else
                     stats.verdict(f"rr_depth {d}", f"rr_depth {BASELINE}", ratio)])
    return rows


def run(args) -> None:
    timer, method = clock.Timer(), args.method_objs[0].name
    rows = table(Engine(Study(StudySettings(**cli.common_fields(args)))).run(declare(args)), method)
    caption = f"{method}, efficiency relative to rr_depth {BASELINE}"
    report.write_section(args.out, NAME, TITLE, 60, {
        "method": method, "spp": args.spp, "repeats": args.repeats,
        "scene": os.path.basename(args.scene)},
        [report.write_table(args.out, f"{NAME}/efficiency", HEADER, rows, caption)],
        args.variant, timer.elapsed())


STUDY = register_study(StudySpec(NAME, TITLE, 60, build_parser, run, quick=(
    "--resolution", "16x8", "--spp", "4", "--reference-spp", "32", "--repeats", "2",
    "--rr-depths", "1,5")), replace=True)

if __name__ == "__main__":
    STUDY.script()
