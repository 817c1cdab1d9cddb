"""The suite's bias test on real scenes, with plugins written here: each wrong one flagged,
its right twin not.

Two pairs, written as a researcher writes plugins outside the project (registered with
Mitsuba and with the experiments' tables, so that they are methods of the suite):

- samplers: ``diagonal_2d`` draws both coordinates of every 2-D sample from one number,
  ``(u, u)`` (every 1-D marginal still uniform: a furnace cannot see it, its integrand is
  constant); its twin ``independent_2d`` draws them from two. Both are the same hash of
  (seed, lane, dimension), so they differ only in that. Method: ``bsdf+nee+<sampler>``.
- strategies: ``bsdf_pdf_high`` is the BSDF's own sampling with its density reported 10%
  high (every weight 10% low: the writeup's "darker with more samples" class); its twin
  ``bsdf_pdf_exact`` reports it exactly (the same code with a factor 1).

The suite runs them with Mitsuba's ``path`` (the reference's own method: the test's
calibration) on bundled scenes, and summary.json must say ``biased: true`` for the wrong
ones and ``false`` for the twins and ``path``.
"""
from __future__ import annotations

import json

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import integrators
import scenes
from experiments.lib import samplers
from experiments.lib.methods import parse_method
from experiments.lib.samplers import SamplerSpec, register_sampler
from experiments.lib.studies.suite import study as S
from experiments.lib.studies.suite import bias_test as suite_bias
from integrators import strategies

#: The wrong strategy's density over the true one.
PDF_FACTOR = 1.1


class HashSampler(mi.Sampler):
    """Independent uniform numbers hashed from (seed, lane, dimension); ``next_2d`` from two
    numbers, or from one (``(u, u)``) where :attr:`DIAGONAL`."""
    PLUGIN = "independent_2d"
    DIAGONAL = False

    def __init__(self, props):
        mi.Sampler.__init__(self, props)
        self._reset(mi.UInt32(0), 1)

    def _reset(self, seed, size):
        self._lane = dr.arange(mi.UInt32, size)
        self._seed = mi.UInt32(seed)
        self._dimension = dr.zeros(mi.UInt32, size)

    def seed(self, seed, wavefront_size=0xFFFFFFFF):
        mi.Sampler.seed(self, seed, wavefront_size)
        seed = dr.opaque(mi.UInt32, seed & 0xFFFFFFFF) if isinstance(seed, int) else \
            mi.UInt32(seed)
        self._reset(seed, self.wavefront_size())

    def next_1d(self, active=True):
        value = mi.sample_tea_float32(self._lane, self._seed * 0x9E3779B9 + self._dimension, 8)
        self._dimension += 1
        return value

    def next_2d(self, active=True):
        u = self.next_1d(active)
        return mi.Point2f(u, u if self.DIAGONAL else self.next_1d(active))

    def schedule_state(self):
        dr.schedule(self._lane, self._seed, self._dimension)

    def fork(self):
        props = mi.Properties(self.PLUGIN)
        props["sample_count"] = self.sample_count()
        return type(self)(props)

    def clone(self):
        other = self.fork()
        if self.wavefront_size() > 1:
            mi.Sampler.seed(other, 0, self.wavefront_size())
        other._lane = mi.UInt32(self._lane)
        other._seed = mi.UInt32(self._seed)
        other._dimension = mi.UInt32(self._dimension)
        return other


class DiagonalSampler(HashSampler):
    """WRONG: both coordinates of a 2-D sample are one number."""
    PLUGIN = "diagonal_2d"
    DIAGONAL = True


class ScaledBSDFSampling(strategies.BSDFSampling):
    """The BSDF's own sampling with its density reported ``factor`` times the true one
    (every weight divided by ``factor``; the MIS weights see the scaled density too)."""

    def __init__(self, factor: float):
        self.factor = factor

    def _scaled(self, ds):
        return ds._replace(pdf=ds.pdf * self.factor, weight=ds.weight / self.factor)

    def sample(self, bsdf, ctx, si, sample1, sample2, active):
        return self._scaled(super().sample(bsdf, ctx, si, sample1, sample2, active))

    def pdf(self, bsdf, ctx, si, wo, active):
        return super().pdf(bsdf, ctx, si, wo, active) * self.factor

    def eval_pdf(self, bsdf, ctx, si, wo, active):
        value, pdf = super().eval_pdf(bsdf, ctx, si, wo, active)
        return value, pdf * self.factor

    def sample_and_eval(self, bsdf, ctx, si, sample1, sample2, wo_em, active):
        v = super().sample_and_eval(bsdf, ctx, si, sample1, sample2, wo_em, active)
        return v._replace(direction=self._scaled(v.direction), em_pdf=v.em_pdf * self.factor)


def register_plugins():
    """Both pairs, for the current variant and in the experiments' tables."""
    for cls in (HashSampler, DiagonalSampler):
        mi.register_sampler(cls.PLUGIN, cls)
        register_sampler(SamplerSpec(cls.PLUGIN, description=cls.__doc__.splitlines()[0]),
                         replace=True)
    integrators.register_strategy("bsdf_pdf_high", lambda: ScaledBSDFSampling(PDF_FACTOR),
                                  replace=True)
    integrators.register_strategy("bsdf_pdf_exact", lambda: ScaledBSDFSampling(1.0),
                                  replace=True)


def unregister_plugins():
    for name in (HashSampler.PLUGIN, DiagonalSampler.PLUGIN):
        samplers.unregister_sampler(name)
    for name in ("bsdf_pdf_high", "bsdf_pdf_exact"):
        strategies.unregister(name)


WRONG_SAMPLER, RIGHT_SAMPLER = "bsdf+nee+diagonal_2d", "bsdf+nee+independent_2d"
WRONG_STRATEGY, RIGHT_STRATEGY = "bsdf_pdf_high+nee", "bsdf_pdf_exact+nee"
METHODS = ["path", WRONG_SAMPLER, RIGHT_SAMPLER, WRONG_STRATEGY, RIGHT_STRATEGY]
#: The default run's budget (films of long side 48, 3 repeats of 16 spp and of 0.02 s,
#: references of 256 spp and up): the smallest that decides reliably. At long side 24,
#: 8 spp and a 128-spp reference (6 seeds) the correlated sampler went unflagged on cbox
#: in one seed and the 10% strategy came out untestable (heavy tails) in another; at this
#: budget every wrong cell below was flagged and no right one in 6 seeds (0-5).
BUDGET = ["--max-size", "48", "--spp", "16", "--time-budget", "0.02", "--reference-spp",
          "256", "--repeats", "3", "--seed", "3"]
#: Scenes with structure, where every method here is testable. The blocks of
#: phong_highlight, veach_mis and rough_glass are ruled by heavy tails (a narrow lobe lit
#: by a small light, small lights reached by BSDF sampling, rough glass: every method's,
#: path's included): their cells are tested by their image sums
#: (experiments/lib/bias_image.py), with the variances of each render's own samples where
#: the pixels are independent. Not the furnace: a constant integrand, the correlated
#: sampler's (u, u) changes nothing there. Not the guiding scenes: their methods are
#: fixed (bsdf+nee, guided+nee, path).
SCENES = ("cbox,textured_phong,environment,grazing,small_light,phong_highlight,veach_mis,"
          "rough_glass")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The suite on :data:`SCENES` with both pairs and path; its summary.json
    cells at equal spp (the bias fields are per cell, the same at both budgets)."""
    out = tmp_path_factory.mktemp("suite_plugins") / "r"
    register_plugins()
    try:
        S.STUDY.main(["--quick", "--out", str(out), "--scenes", SCENES,
                      "--methods", ",".join(METHODS)] + BUDGET)
    finally:
        unregister_plugins()
    summary = json.loads((out / "suite" / "summary.json").read_text())
    cells = {(c["scene"], c["method"]): c for c in summary["cells"]
             if c["budget"] == "equal_spp"}
    return out, summary, cells


def describe(c: dict) -> str:
    def g(x):
        return "-" if x is None else f"{x:.3g}"
    return (f"{c['scene']} {c['method']}: biased {c['biased']} {c['biased_reason']} "
            f"({c['bias_variance']}, tested {c['bias_scope']}), smallest block p "
            f"{g(c['bias_p_blocks'])} (level {g(c['bias_alpha_blocks'])}), pooled p "
            f"{g(c['bias_p_pooled'])} (level {g(c['bias_alpha_pooled'])}), pooled difference "
            f"{c['bias_delta']}, {c['bias_flagged_blocks']} blocks, tail share "
            f"{g(c['bias_tail_share'])}, image variance in one term {g(c['bias_term_share'])}")


def test_the_wrong_plugins_are_flagged_on_real_scenes_and_their_twins_are_not(run):
    """Measured (seeds 3 and 5, this budget): the correlated sampler flagged on five
    scenes (smallest block p 3e-8 on cbox to 9e-223 on grazing, level about 1e-6; pooled
    +2% to +7%, -2.4% to -4.5% on textured_phong and in one seed on grazing) and on
    veach_mis by the image sum (-15%, p 6e-23, level 8e-5) where its renders' spread is
    testable (asserted there: never called unbiased); the 10% density on cbox (pooled -8% to
    -10% per channel), environment (-8.2%), grazing (-4.1% to -4.3%), small_light (-4.3%
    to -4.5%) and by the image sums on phong_highlight (-8.9%, p 1e-87 and below) and
    rough_glass (-6.6%, p 3e-234). Not asserted: the correlated sampler on rough_glass
    (-3.0%, p 2e-4 here against its level of 8e-5; 8e-19 in a run of two scenes, whose
    level is higher) and on phong_highlight (+0.2%: a bias within the image, where the
    blocks that would see it are void); the 10% density on textured_phong (direct light
    only: with NEE and MIS a density reported 10% high changes the image only where BSDF
    sampling has the weight, pooled -0.17% and -0.32%; flagged by its blocks in both seeds
    here, in 4 of 6 seeds of a two-scene run) and on veach_mis (-2.8%, p 0.02, under the
    image test's power there, about 6.5%). The right twins and path: smallest block p
    0.001 to 0.18, pooled p 0.03 to 0.96; by the image sums (phong_highlight, veach_mis,
    rough_glass) p 0.29 to 0.96."""
    _, _, cells = run
    names = SCENES.split(",")
    # a plugin sampler's cells are judged by the renders' spread: on veach_mis one pixel of
    # one render holds 11-16% of its image sum's variance, about the gate (15%), and a
    # sampler pair's cell there is flagged or untestable, as its equal-time count falls
    unsure = {(scene, m) for scene in ("veach_mis",) for m in (WRONG_SAMPLER, RIGHT_SAMPLER)}
    # rough_glass's right sampler twin: its budget is seconds, and on a machine 2-3 times
    # slower (an AVX2 EPYC, 2026-12-07) its renders' spread had no power there (untestable,
    # pooled p 0.57): never called biased, not always tested
    unsure.add(("rough_glass", RIGHT_SAMPLER))
    flagged = {(scene, WRONG_SAMPLER) for scene in names
               if scene not in ("phong_highlight", "rough_glass")} | \
        {(scene, WRONG_STRATEGY) for scene in names
         if scene not in ("textured_phong", "veach_mis")}
    right = {(scene, m) for scene in names for m in ("path", RIGHT_SAMPLER, RIGHT_STRATEGY)}
    for key in flagged - unsure:
        assert cells[key]["biased"] is True, describe(cells[key])
        # each flag tested again on fresh renders alone (bias_renders.confirmed)
        assert cells[key]["bias_retest"] in ("confirmed", "void"), describe(cells[key])
    assert any(cells[key]["bias_retest"] == "confirmed" for key in flagged - unsure)
    for key in right - unsure:
        assert cells[key]["biased"] is False, describe(cells[key])
    assert cells[("veach_mis", WRONG_SAMPLER)]["biased"] is not False
    assert cells[("veach_mis", RIGHT_SAMPLER)]["biased"] is not True
    assert cells[("rough_glass", RIGHT_SAMPLER)]["biased"] is not True
    # the sampler pair is judged with the renders' spread (a plugin sampler), the
    # strategies with the pixels' (the independent sampler and a box filter)
    assert {cells[k]["bias_variance"] for k in cells if "2d" in k[1]} == {"renders"}
    assert cells[("cbox", WRONG_STRATEGY)]["bias_variance"] == "pixels"
    # the 10% density: about 10% darker over the image
    assert -0.13 < min(cells[("cbox", WRONG_STRATEGY)]["bias_delta"]) < -0.05
    # phong_highlight's blocks are heavy-tailed (every method's): its cells are tested by
    # their image sums, which see the 10% density (about -9%)
    assert {cells[("phong_highlight", m)]["bias_scope"] for m in METHODS} == {"image"}
    assert -0.13 < min(cells[("phong_highlight", WRONG_STRATEGY)]["bias_delta"]) < -0.05
    # ... their variances from each render's own samples (vr_moments) where the pixels are
    # independent, with thousands of degrees of freedom (light tails within each pixel)
    for m in ("path", WRONG_STRATEGY, RIGHT_STRATEGY):
        c = cells[("phong_highlight", m)]
        assert c["bias_variance"] == "moments" and c["bias_dof"] > 1000, describe(c)


# ------------------------------------------------------------ power, measured

DRAWS = 20


def path_draws(out, scene: str, cells: dict, draws: int):
    """``draws`` fresh sets of path's renders of ``scene`` as the run made them (its film,
    depth, both budgets' counts and repeats, the reference's chunks), new seeds each."""
    ref = json.loads(next((out / "references").glob(f"{scene}-*/reference.json")).read_text())
    width, height = (int(v) for v in ref["resolution"].split("x"))
    loaded = mi.load_file(scenes.path(f"suite/{scene}.xml"), width=width, height=height)
    from experiments.lib.jobs import Accumulator
    from integrators import moments
    method = parse_method("path")
    spec = method.integrator_dict(S.declare.Depth(max_depth=ref["depth"]["max_depth"]))
    integrator = mi.load_dict(spec)
    # the cells' renders as the run kept them: through vr_moments, each render's per-pixel
    # variance, how sure it is and its third cumulant from its own samples' moments (the
    # image test's variance there); the reference's chunks plain
    sampled = mi.load_dict({"type": "vr_moments", "nested": spec})
    counts = [cells[(scene, "path")]["spp"], cells[(scene, "path", "equal_time")]["spp"]]
    seed = 10_000

    def render(spp, integ=integrator):
        nonlocal seed
        seed += 1
        return np.array(mi.render(loaded, integrator=integ, spp=spp, seed=seed), np.float64)

    def cell_render(spp):
        image = render(spp, sampled)
        m2, m3, m4 = np.split(image[..., -len(moments.MOMENTS):], 3, axis=-1)
        acc = Accumulator.empty(*image.shape[:2])
        acc.add(image[..., :3], spp, sq=spp * m2, passes=spp, higher=(spp * m3, spp * m4))
        return (acc.mean, spp, acc.variance_of_mean(), acc.variance_of_variance(),
                acc.third_of_mean())
    for _ in range(draws):
        budgets = [[cell_render(n) for _ in range(3)] for n in counts]
        chunks = np.stack([render(ref["chunk_spp"])[..., :3] for _ in range(ref["chunks"])])
        yield budgets, chunks


@pytest.mark.parametrize("scene", ["cbox", "phong_highlight"])
def test_the_stated_power_is_met_by_scaled_renders_of_the_calibration_method(run, scene):
    """Power stated per scene (summary.json's ``bias_power``: from path's cell, the
    reference's own method, at the run's level) checked by a negative control: 20 fresh
    draws of path's renders at the run's budgets and of its reference's chunks, path's
    renders scaled by 1 + x and by 1 - x for the stated x, are flagged in about 90% of the
    draws (measured on cbox, x = 0.88% in one run, 0.90% and 1.26% in others, the
    equal-time count following the machine's speed: 37 of 40, 92%; 36 of 40; 37 of 40),
    by half of x in few (a stated x not much larger than it need be: 4, 8 and 1 of 40),
    and unscaled in none (0 of 20 each time). The same on phong_highlight, whose cells
    are tested by their image sums (bias_image): x = 1.12%, 36 of 40 at x, 3 of 40 at x/2,
    0 of 20 unscaled; on an AVX-512 machine, whose counts are larger, x = 0.68% (the
    image test's margin, bias_image.POWER_Z), 38 of 40 at x, 8 of 40 at x/2. The draws
    are tested as the run tests its cells: their renders through vr_moments, each with
    its own samples' variances."""
    out, summary, _ = run
    cells = {(c["scene"], c["method"]) + (() if c["budget"] == "equal_spp" else
                                           (c["budget"],)): c for c in summary["cells"]}
    power = {s["name"]: s["bias_power"] for s in summary["scenes"]}
    alpha = suite_bias.cell_level(len(SCENES.split(",")) * len(METHODS))
    method, box = parse_method("path"), True
    x = power[scene]
    factors = {"1+x": 1 + x, "1-x": 1 - x, "1+x/2": 1 + x / 2, "1-x/2": 1 - x / 2, "1": 1.0}
    flagged = dict.fromkeys(factors, 0)
    for budgets, chunks in path_draws(out, scene, cells, DRAWS):
        for name, factor in factors.items():
            # a uniform relative bias scales a render's mean by the factor, its variances
            # by its square, its variance's variance by its fourth power, its third
            # cumulant by its cube
            scaled = [[(img * factor, n, v * factor ** 2, vv * factor ** 4, k3 * factor ** 3)
                       for img, n, v, vv, k3 in b] for b in budgets]
            got = suite_bias.check_cell(method, scaled, chunks, box, box, method, alpha)
            assert got.status != "untestable", got.reason
            flagged[name] += got.biased is True
    print(f"{scene}: stated power {x:.4f}; flagged of {DRAWS}: {flagged}")
    assert flagged["1"] == 0
    assert flagged["1+x"] + flagged["1-x"] >= 0.8 * 2 * DRAWS, flagged
    assert min(flagged["1+x"], flagged["1-x"]) >= 0.7 * DRAWS, flagged
    assert flagged["1+x/2"] + flagged["1-x/2"] <= 0.5 * 2 * DRAWS, flagged
