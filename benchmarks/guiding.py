"""Path guiding on the door-lit room (issue 41): ``guided+nee`` over ``path`` at path's time.

``python -m benchmarks.guiding [--scene FILE] [--quick]`` prints one table measured in this
process; :func:`rows` returns it in ``benchmarks.run``'s row format
(``[measure, value, target, holds?]``), :func:`measure` everything.

Scene: ``scenes/suite/door_room.xml`` (a closed diffuse room lit only through a door by a
light hidden in an alcove; no baffle) at 64x48, its own max_depth (8). Every render is a
job of the experiments (:func:`experiments.lib.plan.make_job`) rendered by the executor
(:func:`experiments.lib.execute.run_job`: a fresh, untrained integrator per job, timed warm)
and costed by the one clock (:func:`experiments.lib.clock.cost`: the kernel time of every
pass, the guide's training passes included, plus the host work between passes).

1. ``path`` at 1024 spp, ``repeats`` times (5); ``guided+nee`` at path's time: its sample
   count is 1024 x path's cost over its own cost at 1024 spp (the median of three pilot
   rounds, path and it in turn, not counted in the comparison), then ``repeats`` jobs at that count, taking turns with path's. Errors: relMSE against a
   ``path`` reference of ``reference_spp`` (rendered in chunks), less the reference's own
   expected relMSE (estimated from its chunks' spread). Efficiency 1/(relMSE x cost) of
   guided+nee over path, with its 95% interval over the repeats
   (:func:`experiments.lib.stats.efficiency_ratio`). Target (issue 41): >= 6, the
   interval's lower end >= 5.
2. Guided's time per sample after training (its last iteration, which does not record)
   over path's, and the training's share of guided's cost: a job's cost is split over its
   passes in proportion to their wall-clock seconds (``JobResult.pass_seconds``; the
   clock keeps kernel time per job, not per pass), the host work counted as training.
   The last iteration is the job's last render (:func:`integrators.guide_passes.renders`).
3. Issue 41's kernel cost targets (:func:`pass_costs`): a frozen pass's kernel time per
   sample over ``bsdf+nee``'s (rendered at path's time as well, :data:`PLAIN`) at most
   :data:`FROZEN_TARGET`, and a recording pass's over a frozen one's at most
   :data:`RECORDING_TARGET`.

``--methods`` adds other methods at path's time the same way, and
``--scene``/``--path-spp`` measure another scene or budget (how the suite's guiding
scenes' budgets were chosen).
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from . import common
from .common import mi  # noqa: F401  (integrators first: libLLVM)
import scenes
from experiments.lib import clock, metrics, stats
from experiments.lib.execute import run_job
from experiments.lib.jobs import derive_seed
from experiments.lib.methods import parse_method
from experiments.lib.plan import make_job
from experiments.lib.scenes import effective_depth, read_scene
from integrators import guide_passes

SCENE = scenes.path("suite/door_room.xml")
WIDTH, HEIGHT, PATH_SPP, REPEATS = 64, 48, 1024, 5
#: The reference: path at 64 x 1024 spp, in chunks of 4096.
REFERENCE_SPP, CHUNK_SPP = 65536, 4096
GUIDED = "guided+nee"
#: Pilot rounds that size each method's count at path's time.
PILOTS = 3
TARGET = 6.0
#: ... and the interval's lower end at least this.
TARGET_LOWER = 5.0
#: Most share of guided+nee's time that its training may take (issue 41).
TRAINING_SHARE_TARGET = 0.20
#: The plain method whose time per sample a frozen guided pass is held to.
PLAIN = "bsdf+nee"
#: Most kernel time per sample of a frozen guided pass over :data:`PLAIN`'s (issue 41).
FROZEN_TARGET = 1.15
#: Most kernel time per sample of a recording pass over a frozen one's (issue 41).
RECORDING_TARGET = 1.35


def _job(info, method, width, height, spp, seed, depth, tag):
    return make_job(f"bench/guiding/{tag}", info, parse_method(method), width, height, spp,
                    seed, depth, common.VARIANT)


def reference(info, width, height, depth, spp: int, chunk: int) -> tuple[np.ndarray, float]:
    """(path's image of ``spp`` samples, its own expected relMSE): chunks of ``chunk`` spp;
    the mean's variance per pixel is the chunks' spread over (K - 1) K."""
    k = max(2, spp // chunk)
    images = np.stack([run_job(_job(info, "path", width, height, chunk,
                                    derive_seed("reference", i), depth, f"ref{i}"),
                               common.VARIANT).image.astype(np.float64) for i in range(k)])
    mean = images.mean(axis=0)
    var_of_mean = ((images - mean) ** 2).sum(axis=0) / ((k - 1) * k)
    floor = float(np.mean(var_of_mean / (mean ** 2 + 0.01)))
    return mean, floor


def _final_share(result) -> float:
    """The share of a guided job's pass seconds spent in its last iteration: its last
    render (the last iteration, and the rest of a job whose training stopped, are one
    render each: :func:`integrators.guide_passes.renders`, ``merged_rest``)."""
    seconds = np.asarray(result.pass_seconds, float)
    return float(seconds[-1] / seconds.sum())


def pass_costs(kernel_seconds: float, share: float, spp: int) -> tuple[float, float]:
    """(kernel seconds per sample of a guided job's recording passes, of its last, frozen
    one) for a job of ``spp`` samples whose last pass took ``share`` of its passes' wall
    time (:func:`_final_share`): the job's kernel time split over its passes by their wall
    time, the last pass holding the last training iteration's samples
    (:func:`integrators.guide_passes.iterations`), every other pass recording."""
    last = guide_passes.iterations(spp)[-1]
    recording = kernel_seconds * (1.0 - share) / (spp - last) if spp > last else float("nan")
    return recording, kernel_seconds * share / last


def measure(scene: str = SCENE, width: int = WIDTH, height: int = HEIGHT,
            path_spp: int = PATH_SPP, repeats: int = REPEATS, methods=(GUIDED, PLAIN),
            reference_spp: int = REFERENCE_SPP, chunk_spp: int = CHUNK_SPP,
            pilots: int = PILOTS, log=print) -> dict:
    """Every number of the module help, as a dict (see :func:`rows`)."""
    start = time.perf_counter()
    info = read_scene(scene)
    depth = effective_depth(info, None, None)
    ref, floor = reference(info, width, height, depth, reference_spp, chunk_spp)
    log(f"[guiding] reference {reference_spp} spp, own relMSE {floor:.3g} "
        f"({time.perf_counter() - start:.0f} s)")

    def run(method, spp, rep):
        r = run_job(_job(info, method, width, height, spp, derive_seed(method, rep), depth,
                         f"{method}/{spp}/{rep}"), common.VARIANT)
        return r, metrics.relmse(r.image.astype(np.float64), ref) - floor

    # pilots (untimed by the comparison): each method's cost at path's count over path's,
    # the median of ``pilots`` rounds that alternate with path's renders
    ratios = {m: [] for m in methods}
    for k in range(pilots):
        for m in methods:
            path_cost = clock.cost(run("path", path_spp, -1 - k)[0])
            ratios[m].append(path_cost / clock.cost(run(m, path_spp, -1 - k)[0]))
    counts = {m: max(1, round(path_spp * float(np.median(r)))) for m, r in ratios.items()}
    counts["path"] = path_spp
    out = {m: {"spp": counts[m], "relmse": [], "cost": [], "kernel": [], "final_share": [],
               "passes": []}
           for m in ("path",) + tuple(methods)}
    for rep in range(repeats):
        for m in (("path",) + tuple(methods))[::1 if rep % 2 == 0 else -1]:
            r, rel = run(m, counts[m], rep)
            out[m]["relmse"].append(rel)
            out[m]["cost"].append(clock.cost(r))
            out[m]["kernel"].append(clock.kernels(r))
            if parse_method(m).integrator == "vr_guided_path":
                out[m]["final_share"].append(_final_share(r))
                out[m]["passes"].append(pass_costs(clock.kernels(r),
                                                   out[m]["final_share"][-1], counts[m]))
        log(f"[guiding] repeat {rep + 1}/{repeats}: " + ", ".join(
            f"{m} {counts[m]} spp relMSE {out[m]['relmse'][-1]:.3g} cost "
            f"{out[m]['cost'][-1]:.2f} s" for m in out))
    for m in methods:
        _summarise(out, m)
    return {"scene": scene, "width": width, "height": height, "path_spp": path_spp,
            "repeats": repeats, "reference_spp": reference_spp, "reference_relmse": floor,
            "max_depth": depth.max_depth, "methods": out,
            "seconds": time.perf_counter() - start}


def _summarise(out: dict, m: str) -> None:
    """Method ``m``'s efficiency over path's in ``out`` (:func:`measure`'s per-method
    lists), and where it trains its costs per pass: after training over path's per
    sample, the training's share, and issue 41's kernel cost ratios."""
    o, p = out[m], out["path"]
    eff = stats.efficiency_ratio(o["relmse"], o["cost"], p["relmse"], p["cost"])
    o["efficiency"] = [eff.value, eff.lo, eff.hi]
    if not o["final_share"]:
        return
    share = float(np.mean(o["final_share"]))
    last = guide_passes.iterations(o["spp"])[-1]
    per_sample = np.mean(o["cost"]) * share / last
    o["after_training_per_sample_over_path"] = float(per_sample / (np.mean(p["cost"]) / p["spp"]))
    o["training_share"] = 1 - share
    recording, frozen = np.mean(o["passes"], axis=0)
    o["recording_over_frozen"] = float(recording / frozen)
    if PLAIN in out:
        o["frozen_over_plain"] = float(frozen / (np.mean(out[PLAIN]["kernel"]) /
                                                 out[PLAIN]["spp"]))


def rows(res: dict) -> list[list[str]]:
    """The table in ``benchmarks.run``'s row format."""
    out, name = [], res["scene"].replace("\\", "/").rsplit("/", 1)[-1]
    for m, o in res["methods"].items():
        if m == "path":
            continue
        v, lo, hi = o["efficiency"]
        target = f">= {TARGET:g}, lower end >= {TARGET_LOWER:g}" if m == GUIDED else "(info)"
        out.append([f"7. {m} / path, efficiency at path's time ({name}, {res['width']}x"
                    f"{res['height']}, path {res['path_spp']} spp, {m} {o['spp']} spp incl. "
                    f"training, {res['repeats']} repeats)",
                    f"{v:.2f} [{lo:.2f}, {hi:.2f}]", target,
                    ("yes" if v >= TARGET and lo >= TARGET_LOWER else "no")
                    if m == GUIDED else ""])
        if "training_share" in o:
            out.append([f"7. {m} time per sample after training / path's",
                        f"{o['after_training_per_sample_over_path']:.2f}", "(info)", ""])
            share = o["training_share"]
            out.append([f"7. {m} training's share of its time", f"{share:.0%}",
                        f"<= {TRAINING_SHARE_TARGET:.0%}",
                        "yes" if share <= TRAINING_SHARE_TARGET else "no"])
            for key, what, target in (
                    ("frozen_over_plain", f"a frozen pass's kernel time per sample / "
                     f"{PLAIN}'s", FROZEN_TARGET),
                    ("recording_over_frozen", "a recording pass's kernel time per sample / "
                     "a frozen pass's", RECORDING_TARGET)):
                if key in o:
                    out.append([f"7. {m} {what}", f"{o[key]:.2f}", f"<= {target:g}",
                                "yes" if o[key] <= target else "no"])
    return out


def quick_settings(quick: bool) -> dict:
    """:func:`measure`'s settings for ``benchmarks.run`` (``--quick``: a check that it runs)."""
    if not quick:
        return {}
    # guided+nee's count (path's time: about 900 spp, from one timed pilot) stays above its
    # min_train_spp (256) and min_train_samples (2^20: 342 spp here) with room for the
    # machine's load (at path's 768 spp a loaded CI run once gave it 324 spp: no training)
    return {"width": 64, "height": 48, "path_spp": 1536, "repeats": 2, "reference_spp": 768,
            "pilots": 1}


def note(res: dict) -> str:
    """The paragraph under ``benchmarks.run``'s table that says how rows 7 were measured."""
    o = res["methods"].get(GUIDED, {})
    return (f"Rows 7: `{res['scene'].replace(chr(92), '/').rsplit('/', 1)[-1]}` at "
            f"{res['width']}x{res['height']}, max_depth {res['max_depth']}, `path` at "
            f"{res['path_spp']} spp against `{GUIDED}` at {o.get('spp', '-')} spp (its count "
            f"at path's cost from three pilot rounds), {res['repeats']} repeats each, one "
            f"process, jobs rendered and costed as the experiments do (kernel time of every "
            f"pass, training included, plus host work between passes); relMSE against a "
            f"{res['reference_spp']}-spp `path` reference less its own expected relMSE "
            f"({res['reference_relmse']:.2g}); interval 95%, delta method over the repeats. "
            f"After-training cost and training share split each job's cost over its passes "
            f"by their wall-clock seconds, and the frozen and recording passes' kernel time "
            f"per sample its kernel time the same way, against `{PLAIN}`'s kernel time per "
            f"sample at path's cost ({res['seconds']:.0f} s in all; "
            f"`python -m benchmarks.guiding`).")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.guiding",
                                description=__doc__.split("\n")[0])
    p.add_argument("--scene", default=SCENE)
    p.add_argument("--resolution", default=f"{WIDTH}x{HEIGHT}")
    p.add_argument("--path-spp", type=int, default=PATH_SPP)
    p.add_argument("--repeats", type=int, default=REPEATS)
    p.add_argument("--methods", default=f"{GUIDED},{PLAIN}")
    p.add_argument("--reference-spp", type=int, default=REFERENCE_SPP)
    p.add_argument("--quick", action="store_true",
                   help="16x12, path 64 spp, 2 repeats, reference 4096 (checks that it runs)")
    a = p.parse_args(argv)
    width, height = map(int, a.resolution.split("x"))
    if a.quick:
        width, height, a.path_spp, a.repeats, a.reference_spp = 16, 12, 64, 2, 4096
    common.set_variant()
    res = measure(a.scene, width, height, a.path_spp, a.repeats,
                  tuple(m.strip() for m in a.methods.split(",") if m.strip()),
                  a.reference_spp, min(CHUNK_SPP, a.reference_spp))
    for row in rows(res):
        print("| " + " | ".join(row) + " |")
    print()
    print(note(res))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
