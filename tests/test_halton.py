"""Tests of the ``halton`` sampler plugin (``integrators.halton``).

Statistical checks use a significance level of 1e-3: two-sided normal bounds
``|mean_a - mean_b| < z sqrt(var_a/n_a + var_b/n_b)`` with z = 3.29, and
p-values > 1e-3; the error comparisons with ``independent`` a one-sided t-test
on log MSE ratios over seeds at 0.01, with negative controls. Seeds are fixed,
so the tests are deterministic.
"""
import drjit as dr
import mitsuba as mi
import numpy as np
import pytest
from scipy.stats import qmc as scipy_qmc

import _qmc_oracle as oracle
from conftest import scene_path
from integrators import qmc
from integrators.halton import HaltonSampler

Z_1E3 = 3.29  # two-sided normal quantile for significance 1e-3


def make_sampler(spp=4, **kwargs):
    return mi.load_dict({"type": "halton", "sample_count": spp, **kwargs})


def draw(sampler, dims):
    """``dims`` successive next_1d values, as a (lanes, dims) numpy array."""
    return np.stack([np.array(sampler.next_1d()) for _ in range(dims)], axis=1)


class FrozenHalton(HaltonSampler):
    """The classic bug: a Python int dimension counter (frozen in symbolic loops)."""

    def seed(self, seed, wavefront_size=0xFFFFFFFF):
        super().seed(seed, wavefront_size)
        self._py_dimension = 0

    def next_1d(self, active=True):
        value = qmc.halton_sample(mi.UInt32(self._py_dimension), self.current_sample_index(),
                                  self._pixel_seed, self.randomization)
        self._py_dimension += 1
        return value


# ------------------------------------------------------------- parameters

def test_registered_with_defaults():
    sampler = mi.load_dict({"type": "halton"})
    assert isinstance(sampler, HaltonSampler)
    assert sampler.sample_count() == 4
    assert sampler.randomization == "owen"
    assert sampler.sample_offset == 0
    scene = mi.load_file(scene_path("cbox.xml"), sampler="halton", spp=8, width=8, height=4)
    assert isinstance(scene.sensors()[0].sampler(), HaltonSampler)


@pytest.mark.parametrize("props, pattern", [
    ({"randomization": "sobol"}, r"'sobol'.*none, permute_digits, owen"),
    ({"sample_count": 0}, r"sample_count.*> 0, got 0"),
    ({"sample_count": -3}, r"sample_count.*> 0, got -3"),
    ({"sample_offset": -1}, r"sample_offset.*got -1"),
])
def test_bad_parameters_raise(props, pattern):
    with pytest.raises(ValueError, match=pattern):
        HaltonSampler(_props(props))
    with pytest.raises(Exception, match=pattern):
        mi.load_dict({"type": "halton", **props})


def _props(values):
    props = mi.Properties("halton")
    for key, value in values.items():
        props[key] = value
    return props


def test_set_sample_count_validates():
    sampler = make_sampler()
    with pytest.raises(ValueError, match="got 0"):
        sampler.set_sample_count(0)
    sampler.set_sample_count(16)
    assert sampler.sample_count() == 16


# --------------------------------------------------------------- sequence

def test_none_reproduces_plain_halton():
    n, dims = 256, 12
    sampler = make_sampler(spp=n, randomization="none")
    sampler.seed(7, n)                       # one pixel, n samples
    expected = scipy_qmc.Halton(d=dims, scramble=False).random(n)
    np.testing.assert_allclose(draw(sampler, dims), expected, rtol=0, atol=4e-7)


#: A path tracer's calls per sample, as vr_path with NEE makes them: the camera's
#: next_2d, then per bounce next_2d (emitter), next_1d, next_2d (direction), next_1d
#: (roulette); two bounces, dimensions 0-13.
RENDER_CALLS = ("2d",) + ("2d", "1d", "2d", "1d") * 2
#: Dimensions reached in a symbolic loop after RENDER_CALLS: a deep pair and the end of
#: the prime table with its wrap-around (dimension 1000 is base 2 again).
DEEP_DIMENSIONS = (30, 31, 998, 999, 1000, 1001)


def _drive_as_a_render(sampler, spp, lanes, seed):
    """set_sample_count, seed(seed, lanes), then RENDER_CALLS and a symbolic loop up to
    the last of DEEP_DIMENSIONS: {dimension: values of every lane}."""
    sampler.set_sample_count(spp)
    sampler.seed(seed, lanes)
    values = []
    for kind in RENDER_CALLS:
        if kind == "2d":
            p = sampler.next_2d()
            values += [p.x, p.y]
        else:
            values.append(sampler.next_1d())
    got = {d: np.array(v, dtype=np.float64) for d, v in enumerate(values)}
    first = len(values)
    deep = np.array(_draw_in_loop(sampler, DEEP_DIMENSIONS[-1] + 1 - first, lanes))
    deep = deep.reshape(lanes, -1)
    got.update({d: deep[:, d - first] for d in DEEP_DIMENSIONS})
    return got


@pytest.mark.parametrize("randomization,base_seed,offset", [
    ("none", 0, 0), ("permute_digits", 0, 0), ("owen", 0, 0), ("owen", 7, 5)])
def test_values_are_the_halton_points_of_their_lane(randomization, base_seed, offset):
    """Driven as a render drives it, every next_1d and both coordinates of every next_2d
    are the Halton point of the definition (tests/_qmc_oracle.py, scipy's Halton
    sequence for 'none'): dimension j for the j-th value drawn, sample index
    sample_offset + lane % spp, the scramble seed of pixel lane // spp from the render's
    seed plus the 'seed' parameter. Negative controls: the oracle one dimension or one
    sample index off does not match."""
    width, height, spp, seed = 4, 2, 16, 3
    lanes = width * height * spp
    sampler = make_sampler(spp=spp, randomization=randomization, seed=base_seed,
                           sample_offset=offset)
    got = _drive_as_a_render(sampler, spp, lanes, seed)
    sample = np.arange(lanes) % spp + offset
    plain = scipy_qmc.Halton(d=qmc.PRIME_TABLE_SIZE, scramble=False).random(offset + spp + 1)

    def expected(dimension, index_shift=0):
        if randomization == "none":
            return plain[sample + index_shift, dimension % qmc.PRIME_TABLE_SIZE]
        return oracle.sampler_values(dimension, lanes, spp, seed, randomization, base_seed,
                                     offset + index_shift)

    for dimension, values in got.items():
        np.testing.assert_allclose(values, expected(dimension), rtol=0, atol=oracle.TOLERANCE,
                                   err_msg=f"dimension {dimension}")
        for wrong in (expected(dimension + 1), expected(dimension, index_shift=1)):
            assert np.mean(np.abs(values - wrong) > oracle.TOLERANCE) > 0.5, dimension


@dr.syntax
def _draw_in_loop(sampler, steps, lanes):
    out = dr.zeros(mi.Float, lanes * steps)
    lane = dr.arange(mi.UInt32, lanes)
    i = mi.UInt32(0)
    while i < steps:
        dr.scatter(out, sampler.next_1d(), lane * steps + i)
        i += 1
    return out


@pytest.mark.parametrize("randomization", ["none", "owen"])
def test_dimension_advances_in_symbolic_loop(randomization):
    n, steps = 64, 20
    sampler = make_sampler(spp=n, randomization=randomization)
    sampler.seed(3, n)
    reference = draw(sampler.clone(), steps)
    got = np.array(_draw_in_loop(sampler, steps, n)).reshape(n, steps)
    np.testing.assert_array_equal(got, reference)
    assert len(np.unique(got[1])) == steps       # a new dimension every iteration
    # The frozen Python counter repeats one dimension.
    frozen = FrozenHalton(_props({"sample_count": n, "randomization": randomization}))
    frozen.seed(3, n)
    got = np.array(_draw_in_loop(frozen, steps, n)).reshape(n, steps)
    assert np.all(got == got[:, :1])


def test_deep_paths_get_valid_dimensions():
    sampler = make_sampler(spp=16)
    sampler.seed(1, 16 * 4)
    # past the 1000-prime table (drawn in a symbolic loop: one kernel)
    values = np.array(_draw_in_loop(sampler, 1100, 16 * 4)).reshape(16 * 4, 1100)
    assert np.all((values >= 0) & (values < 1))
    # the wrapped dimensions are fresh scrambles of bases 2, 3, ...
    assert not np.array_equal(values[:, 1000], values[:, 0])
    first = values[:16, 1000]                    # base 2 again: one pixel's 16 samples
    np.testing.assert_array_equal(np.sort(np.floor(first * 16)), np.arange(16))


def test_within_pixel_stratification_and_lane_layout():
    spp, pixels = 64, 50
    sampler = make_sampler(spp=spp)
    sampler.seed(0, spp * pixels)                # lane = pixel * spp + sample
    x = draw(sampler, 2).reshape(pixels, spp, 2)
    for p in range(pixels):
        np.testing.assert_array_equal(np.sort(np.floor(x[p, :, 0] * 64)), np.arange(64))
        np.testing.assert_array_equal(np.sort(np.floor(x[p, :27, 1] * 27)), np.arange(27))


def test_neighbouring_pixels_are_decorrelated():
    spp, pixels = 16, 4000
    sampler = make_sampler(spp=spp)
    sampler.seed(0, spp * pixels)
    x = draw(sampler, 4).reshape(pixels, spp, 4)
    bound = Z_1E3 / np.sqrt(pixels - 1)
    for d in range(4):
        first = x[:, 0, d]
        assert abs(np.corrcoef(first[:-1], first[1:])[0, 1]) < bound
        # and no two neighbours share their point set
        assert not np.any(np.all(x[:-1, :, d] == x[1:, :, d], axis=1))


def test_seed_determinism():
    a, b = make_sampler(spp=8), make_sampler(spp=8)
    a.seed(5, 64)
    b.seed(5, 64)
    np.testing.assert_array_equal(draw(a, 6), draw(b, 6))
    b.seed(6, 64)
    a.seed(5, 64)
    assert np.mean(draw(a, 6) == draw(b, 6)) < 0.01
    # the 'seed' parameter offsets the seed given to seed()
    c = make_sampler(spp=8, seed=2)
    c.seed(3, 64)
    a.seed(5, 64)
    np.testing.assert_array_equal(draw(a, 6), draw(c, 6))


# ------------------------------------------------------- sampler protocol

def test_clone_and_fork():
    sampler = make_sampler(spp=8, randomization="permute_digits", seed=4)
    sampler.sample_offset = 3
    sampler.seed(9, 32)
    draw(sampler, 3)
    clone = sampler.clone()
    np.testing.assert_array_equal(draw(clone, 5), draw(sampler, 5))
    fork = sampler.fork()
    assert isinstance(fork, HaltonSampler)
    assert (fork.sample_count(), fork.randomization, fork.base_seed, fork.sample_offset) == \
        (8, "permute_digits", 4, 3)
    fork.seed(9, 32)
    sampler.seed(9, 32)
    np.testing.assert_array_equal(draw(fork, 4), draw(sampler, 4))


@pytest.mark.parametrize("randomization", qmc.RANDOMIZATIONS)
def test_declared_passes_equal_one_pass(randomization):
    """Mitsuba's multi-pass protocol, declared: set_samples_per_wavefront(4), seed,
    advance between passes: two passes of 4 samples = one pass of 8, sample for sample."""
    spp, pixels = 8, 10
    full = make_sampler(spp=spp, randomization=randomization)
    full.seed(3, spp * pixels)
    reference = draw(full, 5).reshape(pixels, spp, 5)
    sampler = make_sampler(spp=spp, randomization=randomization)
    sampler.set_samples_per_wavefront(4)
    sampler.seed(3, 4 * pixels)
    first = draw(sampler, 5).reshape(pixels, 4, 5)
    sampler.advance()
    second = draw(sampler, 5).reshape(pixels, 4, 5)
    np.testing.assert_array_equal(np.concatenate([first, second], axis=1), reference)
    sampler.schedule_state()
    with pytest.raises(ValueError, match="got 0"):
        sampler.set_samples_per_wavefront(0)


def test_declared_layout_does_not_outlive_its_seed():
    spp, pixels = 8, 6
    sampler = make_sampler(spp=spp)
    sampler.set_samples_per_wavefront(2)
    sampler.seed(1, 2 * pixels)
    sampler.advance()                            # declared: fine
    # The next seeding (a one-pass render) infers its own layout again.
    sampler.seed(1, spp * pixels)
    fresh = make_sampler(spp=spp)
    fresh.seed(1, spp * pixels)
    np.testing.assert_array_equal(draw(sampler, 3), draw(fresh, 3))
    with pytest.raises(RuntimeError, match="samples_per_pass.*sample_offset"):
        sampler.advance()                        # undeclared layout: no silent guess
    # nor does a fork inherit a pending declaration
    sampler.set_samples_per_wavefront(2)
    fork = sampler.fork()
    fork.seed(1, spp * pixels)
    fresh.seed(1, spp * pixels)
    np.testing.assert_array_equal(draw(fork, 3), draw(fresh, 3))


class RecordingHalton(HaltonSampler):
    """Records the calls Mitsuba makes on a Python sampler."""

    def __init__(self, props):
        super().__init__(props)
        self.calls = []

    def set_sample_count(self, spp):
        self.calls.append(("set_sample_count", spp))
        super().set_sample_count(spp)

    def set_samples_per_wavefront(self, spw):
        self.calls.append(("set_samples_per_wavefront", spw))
        super().set_samples_per_wavefront(spw)

    def seed(self, seed, wavefront_size=0xFFFFFFFF):
        self.calls.append(("seed", wavefront_size))
        super().seed(seed, wavefront_size)

    def advance(self):
        self.calls.append(("advance", None))
        super().advance()


def test_what_a_multipass_render_tells_a_python_sampler():
    """Instrumented: Mitsuba's samples_per_pass render calls set_sample_count(spp),
    seed(seed, width * height * samples_per_pass) and advance(), but never the
    Python set_samples_per_wavefront, so the sampler cannot know the pass size
    (a one-pass render of width * height * k pixels looks the same). If this
    ever changes, halton can follow multi-pass renders exactly."""
    mi.register_sampler("recording_halton", lambda props: RecordingHalton(props))
    scene_dict = mi.cornell_box()
    scene_dict["sensor"]["film"]["width"] = scene_dict["sensor"]["film"]["height"] = 8
    scene_dict["sensor"]["sampler"] = {"type": "recording_halton", "sample_count": 16}
    scene = mi.load_dict(scene_dict)
    sampler = scene.sensors()[0].sampler()
    with pytest.raises(RuntimeError):
        mi.render(scene, spp=16, integrator=mi.load_dict({"type": "path", "samples_per_pass": 4}))
    names = {name for name, _ in sampler.calls}
    assert ("set_sample_count", 16) in sampler.calls
    assert {size for name, size in sampler.calls if name == "seed"} == {8 * 8 * 4}
    assert "advance" in names and "set_samples_per_wavefront" not in names, sampler.calls


def _causes(exc):
    while exc is not None:
        yield str(exc)
        exc = exc.__cause__ or exc.__context__


@pytest.mark.parametrize("randomization", qmc.RANDOMIZATIONS)
def test_samples_per_pass_render_stops_with_clear_error(randomization):
    """Mitsuba's own multi-pass render (samples_per_pass) cannot tell a Python sampler
    its layout: the render stops with the explanation instead of degrading silently;
    the sampler renders correctly afterwards."""
    scene_dict = mi.cornell_box()
    scene_dict["sensor"]["film"]["width"] = scene_dict["sensor"]["film"]["height"] = 8
    scene_dict["sensor"]["sampler"] = {"type": "halton", "sample_count": 16,
                                       "randomization": randomization}
    scene = mi.load_dict(scene_dict)
    reference = np.array(mi.render(scene, seed=3))
    for name in ("path", "vr_path"):
        integrator = mi.load_dict({"type": name, "samples_per_pass": 4})
        with pytest.raises(RuntimeError) as info:
            mi.render(scene, integrator=integrator, seed=3)
        message = " ".join(_causes(info.value))
        assert "several passes" in message and "sample_offset" in message, message
    # (up to the order of the film's atomic additions)
    np.testing.assert_allclose(np.array(mi.render(scene, seed=3)), reference, rtol=1e-5, atol=1e-7)


def _path(max_depth=8):
    return mi.load_dict({"type": "path", "max_depth": max_depth})


def test_sample_offset_continues_sequence_across_passes():
    """Passes of 1, 1, 2, 4 spp with the same seed and growing offset = one 8 spp render."""
    scene = mi.load_file(scene_path("cbox.xml"), sampler="halton", spp=8, width=16, height=8)
    integrator = _path()
    one_shot = np.array(mi.render(scene, seed=11, spp=8, integrator=integrator))
    sampler = scene.sensors()[0].sampler()
    acc, done = 0.0, 0
    for k in (1, 1, 2, 4):
        sampler.sample_offset = done
        acc = acc + k * np.array(mi.render(scene, seed=11, spp=k, integrator=integrator))
        done += k
    np.testing.assert_allclose(acc / done, one_shot, rtol=1e-4, atol=1e-5)
    # also settable through mi.traverse
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("sampler.sample_offset"))
    params[key] = 5
    params.update()
    assert sampler.sample_offset == 5


def test_reseeding_does_not_recompile():
    scene = mi.load_file(scene_path("cbox.xml"), sampler="halton", spp=4, width=16, height=8)
    sampler = scene.sensors()[0].sampler()
    for integrator in (None, _path()):
        dr.eval(mi.render(scene, seed=1, integrator=integrator))
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            sampler.sample_offset = 4
            dr.eval(mi.render(scene, seed=2, integrator=integrator))
            history = dr.kernel_history()
        jit = [k for k in history if k["type"] == dr.KernelType.JIT]
        assert jit and all(k["cache_hit"] for k in jit)


# ------------------------------------------------------------- rendering

def _pixel_stats(scene, integrator, seeds):
    """Mean of the pixels of several renders and its standard error (i.i.d. pixels)."""
    px = np.concatenate([np.array(mi.render(scene, seed=s, integrator=integrator)).ravel()
                         for s in seeds])
    return px.mean(), px.var(ddof=1) / px.size


@pytest.mark.parametrize("integrator", ["vr_path", "path"])
def test_unbiased_inside_loops(integrator):
    """Furnace at max_depth 8 (Russian roulette from depth 5): halton agrees with
    independent; a frozen dimension counter is detected."""
    mi.register_sampler("frozen_halton", lambda props: FrozenHalton(props))
    integ = None if integrator == "vr_path" else _path(8)
    stats = {}
    for name in ("independent", "halton", "frozen_halton"):
        scene = mi.load_file(scene_path("furnace.xml"), sampler=name, spp=256,
                             width=16, height=16, max_depth=8)
        stats[name] = _pixel_stats(scene, integ, range(4))

    def agrees(a, b):
        (ma, va), (mb, vb) = stats[a], stats[b]
        return abs(ma - mb) < Z_1E3 * np.sqrt(va + vb)

    assert agrees("halton", "independent"), stats
    assert not agrees("frozen_halton", "independent"), stats


def test_unbiased_on_default_scene_with_vr_path():
    """cbox (vr_path, max_depth 8): image means over seeds agree; the frozen counter is dark."""
    mi.register_sampler("frozen_halton", lambda props: FrozenHalton(props))
    means = {}
    for name in ("independent", "halton", "frozen_halton"):
        scene = mi.load_file(scene_path("cbox.xml"), sampler=name, spp=128, width=32, height=16)
        means[name] = np.array([np.mean(mi.render(scene, seed=s)) for s in range(8)])
    # Student t quantile (7 dof) for 1e-3 two-sided, per-render means are i.i.d.
    t = 5.41

    def agrees(a, b):
        ma, mb = means[a], means[b]
        return abs(ma.mean() - mb.mean()) < t * np.sqrt((ma.var(ddof=1) + mb.var(ddof=1)) / 8)

    assert agrees("halton", "independent"), means
    assert not agrees("frozen_halton", "independent"), means


def _mse(scene, reference, spp, seeds, integrator=None):
    return np.mean([np.mean((np.array(mi.render(scene, seed=s, spp=spp, integrator=integrator))
                             - reference) ** 2) for s in seeds])


@pytest.fixture(scope="module")
def cbox_reference():
    scene = mi.load_file(scene_path("cbox.xml"), spp=2048, width=64, height=32)
    return np.array(mi.render(scene, seed=1000))


class ShuffledHalton(HaltonSampler):
    """Negative control: every lane takes a hashed Halton index in [0, 2^20) instead
    of its pixel's next one, so each value is still a (randomized) Halton point but a
    pixel's samples are no longer stratified: no QMC gain is expected."""

    def current_sample_index(self):
        return qmc.mix32(super().current_sample_index() * qmc.HASH_MULTIPLIER
                         ^ self._pixel_seed) >> 12


ALPHA = 0.01           # significance of the one-sided tests below
GAIN_SEEDS = 8         # paired renders per test


def _log_mse_ratios(scene_a, scene_b, reference, spp, seeds_a, seeds_b):
    """log(MSE of a) - log(MSE of b) per seed pair (independent renders)."""
    return np.array([np.log(_mse(scene_a, reference, spp, (sa,)))
                     - np.log(_mse(scene_b, reference, spp, (sb,)))
                     for sa, sb in zip(seeds_a, seeds_b)])


def _lower(log_ratios):
    """One-sided t-test of mean log MSE ratio < 0 at ALPHA: (rejected, p-value)."""
    from scipy import stats
    p = stats.ttest_1samp(log_ratios, 0.0, alternative="less").pvalue
    return bool(p < ALPHA), float(p)


def _cbox(sampler="independent", randomization=None):
    scene = mi.load_file(scene_path("cbox.xml"), sampler=sampler, width=64, height=32)
    if randomization is not None:
        scene.sensors()[0].sampler().randomization = randomization
    return scene


@pytest.mark.parametrize("randomization", ["none", "permute_digits", "owen"])
def test_lower_error_than_independent(cbox_reference, randomization):
    """Halton's MSE is lower than independent's: over GAIN_SEEDS seed pairs, the mean
    log MSE ratio is < 0 by a one-sided t-test at ALPHA = 0.01 (``none`` ignores the
    seed: its spread is independent's alone), at 64 and 256 spp."""
    independent, halton = _cbox(), _cbox("halton", randomization)
    seeds = range(1, 1 + GAIN_SEEDS)
    for spp in (64, 256):
        r = _log_mse_ratios(halton, independent, cbox_reference, spp, seeds, seeds)
        rejected, p = _lower(r)
        assert rejected, (spp, p, np.exp(r))


def test_lower_error_test_rejects_no_gain(cbox_reference):
    """Negative controls: the same test at the same size must not find a gain where
    there is none: independent against independent (other seeds), and a Halton
    sampler whose pixels draw shuffled indices (:class:`ShuffledHalton`)."""
    mi.register_sampler("shuffled_halton", lambda props: ShuffledHalton(props))
    independent, shuffled = _cbox(), _cbox("shuffled_halton", "owen")
    seeds = range(1, 1 + GAIN_SEEDS)
    others = range(101, 101 + GAIN_SEEDS)
    r = _log_mse_ratios(independent, independent, cbox_reference, 64, others, seeds)
    assert not _lower(r)[0], (_lower(r), np.exp(r))
    r = _log_mse_ratios(shuffled, independent, cbox_reference, 64, seeds, seeds)
    assert not _lower(r)[0], (_lower(r), np.exp(r))


def test_qmc_gain_on_cornell_box():
    """With Mitsuba's path tracer (NEE) the QMC gain is large: ~0.1x the MSE at 64 spp."""
    scene_dict = mi.cornell_box()
    scene_dict["sensor"]["film"]["width"] = scene_dict["sensor"]["film"]["height"] = 32
    scene_dict["integrator"]["max_depth"] = 8
    reference = np.array(mi.render(mi.load_dict(scene_dict), spp=2048, seed=99))
    mse = {}
    for name in ("independent", "halton"):
        scene_dict["sensor"]["sampler"] = {"type": name, "sample_count": 64}
        mse[name] = _mse(mi.load_dict(scene_dict), reference, 64, (1, 2))
    assert mse["halton"] < 0.25 * mse["independent"], mse
