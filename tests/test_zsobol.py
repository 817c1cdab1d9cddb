"""Tests of the ``zsobol`` sampler (``integrators.zsobol``) and its maths (``integrators.qmc``).

Exact properties are checked exactly: the Sobol' points against scipy, the
(0,2)-net property of every pixel's points (each elementary interval of every
shape holds exactly one point), the Morton order and the hierarchy of pixel
blocks. Statistical checks state their significance: chi-square p-values >
1e-3 for the uniformity of the scrambles; the per-block agreement with
Mitsuba's ``path`` at 0.01 for the module, Sidak-corrected over every block,
channel and pooled comparison. The structural and statistical checks have
negative controls of the size of a realistic bug that the same check must
catch: a non-bijective digit permutation, pixels in row-major order, an
off-by-one dimension, a non-nested scramble, flips without the pairing choice,
a seed cut to 8 bits and a frozen dimension counter. Seeds are fixed, so the
tests are deterministic.
"""
import drjit as dr
import mitsuba as mi
import numpy as np
import pytest
from scipy import stats
from scipy.stats import qmc as scipy_qmc

import _blocks as B
from conftest import scene_path
from integrators import qmc, qmc_sobol
from integrators.zsobol import ZSobolSampler

ALPHA = 1e-3                    # chi-square tests of the scrambles
RANDOMIZATIONS = qmc.RANDOMIZATIONS


def make(spp=16, width=8, **kwargs):
    return mi.load_dict({"type": "zsobol", "sample_count": spp, "film_width": width, **kwargs})


def draw(sampler, width, height, spp, calls, seed=3):
    """Seed as a render does (``width * height * spp`` lanes) and draw: one
    (pixels, spp, c) array per call, c = 2 for next_2d and 1 for next_1d, pixels
    in the film's row-major order."""
    sampler.seed(seed, width * height * spp)
    out = []
    for c in calls:
        v = np.array(sampler.next_2d()).T if c == 2 else np.array(sampler.next_1d())[:, None]
        out.append(v.reshape(height * width, spp, c))
    return out


def is_net(points) -> np.ndarray:
    """(..., n, 2) points, n = 2^m -> (...) bool: every elementary interval of
    volume 1/n (all shapes 2^-a x 2^-b, a + b = m) holds exactly one point."""
    n = points.shape[-2]
    m = n.bit_length() - 1
    ok = np.ones(points.shape[:-2], dtype=bool)
    for a in range(m + 1):
        cells = (np.floor(points[..., 0] * 2**a) * 2**(m - a)
                 + np.floor(points[..., 1] * 2**(m - a)))
        ok &= np.all(np.sort(cells, axis=-1) == np.arange(n), axis=-1)
    return ok


def is_stratified_1d(values) -> np.ndarray:
    """(..., n, 1) -> (...): each interval [k/n, (k+1)/n) holds exactly one value."""
    n = values.shape[-2]
    return np.all(np.sort(np.floor(values[..., 0] * n), axis=-1) == np.arange(n), axis=-1)


def quads(points, width, height, k):
    """(pixels, spp, 2) in row-major order -> (blocks, 4^k spp, 2): the points of
    every aligned 2^k x 2^k block of pixels together."""
    s = 2**k
    p = points.reshape(height // s, s, width // s, s, *points.shape[1:])
    return p.transpose(0, 2, 1, 3, 4, 5).reshape((height // s) * (width // s), -1, 2)


# ------------------------------------------------------------- parameters

def test_registered_with_defaults():
    sampler = mi.load_dict({"type": "zsobol"})
    assert isinstance(sampler, ZSobolSampler)
    assert (sampler.sample_count(), sampler.randomization, sampler.film_width,
            sampler.sequence_length, sampler.sample_offset) == (4, "owen", 0, 0, 0)
    scene = mi.load_file(scene_path("cbox.xml"), sampler="zsobol", spp=8, width=8, height=4)
    assert isinstance(scene.sensors()[0].sampler(), ZSobolSampler)
    # a scene file passes its film width through a parameter
    scene = mi.load_string("""<scene version="3.0.0">
        <default name="width" value="8"/>
        <sensor type="perspective">
            <sampler type="zsobol">
                <integer name="sample_count" value="4"/>
                <integer name="film_width" value="$width"/>
            </sampler>
            <film type="hdrfilm">
                <integer name="width" value="$width"/> <integer name="height" value="4"/>
            </film>
        </sensor>
        <integrator type="path"/> <shape type="sphere"/> <emitter type="constant"/>
    </scene>""", width=12)
    assert scene.sensors()[0].sampler().film_width == 12
    assert mi.render(scene).shape == (4, 12, 3)


@pytest.mark.parametrize("props, pattern", [
    ({"randomization": "sobol"}, r"'sobol'.*none, permute_digits, owen"),
    ({"sample_count": 0}, r"sample_count.*>= 1, got 0"),
    ({"film_width": -2}, r"film_width.*>= 0, got -2"),
    ({"sequence_length": -1}, r"sequence_length.*>= 0, got -1"),
    ({"sample_offset": -1}, r"sample_offset.*got -1"),
    ({"seed": -5}, r"seed.*got -5"),
])
def test_bad_parameters_raise(props, pattern):
    with pytest.raises(Exception, match=pattern):
        mi.load_dict({"type": "zsobol", **props})


def test_non_power_of_two_counts_round_up_with_a_warning():
    with pytest.warns(UserWarning, match="'sample_count' 5 is not a power of two; rounded up to 8"):
        sampler = mi.load_dict({"type": "zsobol", "sample_count": 5})
    assert sampler.sample_count() == 8
    with pytest.warns(UserWarning, match="rounded up to 16"):
        sampler.set_sample_count(12)
    assert sampler.sample_count() == 16
    with pytest.warns(UserWarning, match="'sequence_length' 24 .* rounded up to 32"):
        sampler.sequence_length = 24
    assert sampler.sequence_length == 32
    # a render at 3 spp takes 4 (Mitsuba sizes the wavefront by sample_count())
    scene = _cbox(8, 4)
    with pytest.warns(UserWarning, match="rounded up to 4"):
        img = mi.render(scene, spp=3)
    assert scene.sensors()[0].sampler().sample_count() == 4 and np.all(np.isfinite(img))


# ------------------------------------------------------------ the sequence

def test_sobol_points_match_scipy():
    """The first 2^12 unscrambled points equal scipy's Sobol' (which lists them in
    Gray-code order), exactly."""
    n = 2**12
    i = np.arange(n, dtype=np.uint32)
    x, y = qmc_sobol.sobol_2d(mi.UInt32(i ^ (i >> 1)))
    got = np.stack([np.array(x, np.float64), np.array(y, np.float64)], axis=1) / 2**32
    np.testing.assert_array_equal(got, scipy_qmc.Sobol(2, scramble=False).random(n))


def test_pascal_matrix_equals_the_generator_matrix():
    """All 32 columns: the shift-and-XOR product equals the generator matrix of
    Sobol' dimension 1 (column j, digit k set iff binom(j, k) is odd) for random
    32-bit indices."""
    cols = [sum(1 << (31 - k) for k in range(32) if (k & j) == k) for j in range(32)]
    a = np.random.default_rng(1).integers(0, 2**32, 2000, dtype=np.uint64).astype(np.uint32)
    expected = np.zeros_like(a)
    for j in range(32):
        expected ^= np.where((a >> np.uint32(j)) & 1, np.uint32(cols[j]), np.uint32(0))
    np.testing.assert_array_equal(np.array(qmc_sobol.sobol_2d(mi.UInt32(a))[1]), expected)


def test_morton_order_is_a_bijection():
    x, y = np.meshgrid(np.arange(256, dtype=np.uint32), np.arange(256, dtype=np.uint32))
    m = np.array(qmc_sobol.morton_encode(mi.UInt32(x.ravel()), mi.UInt32(y.ravel())))
    np.testing.assert_array_equal(np.sort(m), np.arange(256 * 256))
    # pbrt's EncodeMorton2: x in the even bits, y in the odd ones
    assert list(m[[0, 1, 256, 257, 2]]) == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("width, height, spw, declared", [(12, 5, 4, False), (7, 3, 2, True),
                                                           (1, 1, 8, False)])
def test_lanes_get_their_pixels_morton_index(width, height, spw, declared):
    """Lane l of a render is sample l % k of pixel l // k (row-major): its sequence index
    is morton(x, y) * sequence_length + sample_offset + sample, for widths that are not
    powers of two and for a declared pass of k = 2 of 8 samples."""
    sampler = make(8 if declared else spw, width, sequence_length=16)
    sampler.sample_offset = 5
    if declared:
        sampler.set_samples_per_wavefront(spw)
    sampler.seed(0, width * height * spw)
    lane = np.arange(width * height * spw)
    pixel, sample = lane // spw, lane % spw
    x, y = pixel % width, pixel // width
    morton = sum(((x >> b) & 1) << (2 * b) | ((y >> b) & 1) << (2 * b + 1) for b in range(8))
    np.testing.assert_array_equal(np.array(sampler.current_sample_index()),
                                  morton * 16 + 5 + sample)


@pytest.mark.parametrize("randomization", RANDOMIZATIONS)
@pytest.mark.parametrize("spp", [8, 16])
def test_every_pixel_and_block_is_a_net(randomization, spp):
    """Read through the sampler as a render calls it: in every pair (next_2d at
    dimensions 0, 3 and 5) each pixel's points, their power-of-two prefixes and the
    points of every aligned 2x2 and 4x4 block of pixels are (0,2)-nets; next_1d
    (dimension 2) is stratified."""
    w, h = 8, 4
    pairs = draw(make(spp, w, randomization=randomization), w, h, spp, [2, 1, 2, 2])
    one = pairs.pop(1)
    assert np.all(is_stratified_1d(one))
    for p in pairs:
        for n in (2**j for j in range(spp.bit_length())):
            assert np.all(is_net(p[:, :n])), n
        for k in (1, 2):
            assert np.all(is_net(quads(p, w, h, k))), k
    # different pairs, pixels and seeds differ
    assert not np.array_equal(pairs[0], pairs[1])
    assert len(np.unique(pairs[0][:, 0, 0])) == w * h


def _broken_permutation(index, seed, x_mask):
    """A realistic bug: the digit swap flips y only, so two pixels of a quad share
    an index block (the permutation is not a bijection)."""
    r = dr.brev(index)
    g = qmc.laine_karras(r << 2, seed)
    t = (r ^ (r << 1)) & g & x_mask
    return dr.brev(qmc.laine_karras(r ^ (t >> 1), seed))


class OffByOne(ZSobolSampler):
    """next_2d takes y from the next dimension's pair (an off-by-one)."""

    def next_2d(self, active=True):
        index = self.current_sample_index()
        x = qmc_sobol.zsobol_sample(index, self._dimension, self._seed, self._x_mask,
                              self.randomization, components=1)[0]
        y = qmc_sobol.zsobol_sample(index, self._dimension + 1, self._seed, self._x_mask,
                              self.randomization)[1]
        self._dimension += 2
        return mi.Point2f(x, y)


def _nets_hold(sampler, spp=16, w=8, h=4):
    p = draw(sampler, w, h, spp, [2, 2])[1]
    return bool(np.all(is_net(p)) and np.all(is_net(quads(p, w, h, 1))))


def test_net_check_catches_broken_permutations(monkeypatch):
    """Negative controls for the net test: a non-bijective digit permutation, pixels in
    row-major order instead of Morton order, and an off-by-one in the dimension."""
    assert _nets_hold(make())
    props = mi.Properties("zsobol")
    props["sample_count"], props["film_width"] = 16, 8
    assert not _nets_hold(OffByOne(props))
    with monkeypatch.context() as m:
        m.setattr(qmc_sobol, "zsobol_permute_index", _broken_permutation)
        assert not _nets_hold(make())
    with monkeypatch.context() as m:
        m.setattr(qmc_sobol, "morton_encode", lambda x, y: y * 8 + x)
        assert not _nets_hold(make())


def _permuted(index, seeds, log2_length):
    return np.array(qmc_sobol.zsobol_permute_index(mi.UInt32(index), mi.UInt32(seeds),
                                             qmc_sobol.morton_x_mask(log2_length)), dtype=np.int64)


def hierarchy_holds(permuted, side, length) -> bool:
    """(side * side * length,) permuted indices of a side x side image in row-major order,
    ``length`` per pixel: every aligned 2^k x 2^k block of pixels holds an aligned block
    of 4^k length indices (k = 0 .. log2 side), and the whole is a bijection."""
    p = permuted.reshape(side, side, length)
    for k in range(side.bit_length()):
        s, size = 2**k, 4**k * length
        blocks = p.reshape(side // s, s, side // s, s, length).transpose(0, 2, 1, 3, 4)
        blocks = np.sort(blocks.reshape(-1, size), axis=1)
        if not np.all(blocks - blocks[:, :1] == np.arange(size)) or np.any(blocks[:, 0] % size):
            return False
    return True


@pytest.mark.parametrize("log2_length", [0, 1, 2, 3])
def test_index_permutation_keeps_the_hierarchy_of_blocks(log2_length):
    side, length = 16, 2**log2_length
    y, x, i = np.meshgrid(np.arange(side), np.arange(side), np.arange(length), indexing="ij")
    morton = np.array(qmc_sobol.morton_encode(mi.UInt32(x.ravel()), mi.UInt32(y.ravel())))
    index = (morton.astype(np.int64) << log2_length) + i.ravel()
    for seed in (0, 1, 0xDEADBEEF, 77777):
        seeds = np.full(index.size, seed, np.uint32)
        assert hierarchy_holds(_permuted(index, seeds, log2_length), side, length), seed
    # negative controls: row-major pixels, and flips hashed from the bits below
    # (laine_karras on the index itself, not reversed: not nested)
    row_major = ((y * side + x).ravel().astype(np.int64) << log2_length) + i.ravel()
    assert not hierarchy_holds(_permuted(row_major, seeds, log2_length), side, length)
    not_nested = np.array(qmc.laine_karras(mi.UInt32(index), mi.UInt32(seeds)), np.int64)
    assert not hierarchy_holds(not_nested, side, length)


def test_quad_pairings_are_transpose_symmetric():
    """The pixel that shares its half of a quad's block with pixel (0, 0): the one to its
    right, below or diagonal with probabilities 1/4, 1/4, 1/2 over seeds (chi-square at
    1e-3); the flips alone (no pairing choice) always pair horizontally."""
    n = 4096
    seeds = qmc.mix32(mi.UInt32(np.arange(n)))

    def partner_counts(permute):
        halves = [np.array(permute(mi.UInt32(q), seeds, mi.UInt32(qmc_sobol.morton_x_mask(0)))) >> 1
                  for q in range(4)]                  # Morton 1: right, 2: below, 3: diagonal
        return [int(np.sum(halves[q] == halves[0])) for q in (1, 2, 3)]

    counts = partner_counts(qmc_sobol.zsobol_permute_index)
    assert sum(counts) == n
    assert stats.chisquare(counts, [n / 4, n / 4, n / 2]).pvalue > ALPHA, counts
    flips_only = partner_counts(lambda i, s, m: dr.brev(qmc.laine_karras(dr.brev(i), s)))
    assert flips_only == [n, 0, 0]


# ---------------------------------------------------------- randomization

def _one_point(randomization, seeds, dimension=4, pixel=(3, 5), sample=2, log2_length=4):
    morton = int(np.array(qmc_sobol.morton_encode(mi.UInt32(pixel[0]), mi.UInt32(pixel[1])))[0])
    index = mi.UInt32((morton << log2_length) + sample)
    x, y = qmc_sobol.zsobol_sample(index, mi.UInt32(dimension), mi.UInt32(seeds),
                             qmc_sobol.morton_x_mask(log2_length), randomization)
    return np.array(x, np.float64), np.array(y, np.float64)


def uniform_p_values(randomization, n=2**14):
    """Chi-square p-values of one point over n seeds (consecutive, as renders get them):
    its x in 64 bins, y in 64 bins, and (x, y) jointly in 16 x 16 bins."""
    x, y = _one_point(randomization, np.arange(n, dtype=np.uint32))
    hx = np.bincount(np.floor(x * 64).astype(int), minlength=64)
    hy = np.bincount(np.floor(y * 64).astype(int), minlength=64)
    hxy = np.bincount((np.floor(x * 16) * 16 + np.floor(y * 16)).astype(int), minlength=256)
    return [stats.chisquare(h).pvalue for h in (hx, hy, hxy)]


@pytest.mark.parametrize("randomization", ["permute_digits", "owen"])
def test_each_point_is_uniform_over_seeds(randomization):
    p = uniform_p_values(randomization)
    assert min(p) > ALPHA, p


def test_uniformity_check_catches_a_truncated_seed(monkeypatch):
    """Negative control: a seed cut to 8 bits (a byte cast) gives each point only 256
    positions, which the same chi-square tests reject."""
    original = qmc.dimension_seed
    monkeypatch.setattr(qmc, "dimension_seed", lambda seed, d: original(seed & 0xFF, d))
    assert min(uniform_p_values("owen")) < ALPHA
    assert min(uniform_p_values("permute_digits")) < ALPHA


def test_none_is_deterministic_and_ignores_the_seed():
    a = draw(make(randomization="none"), 8, 4, 16, [2, 2], seed=1)
    b = draw(make(randomization="none", seed=9), 8, 4, 16, [2, 2], seed=5)
    np.testing.assert_array_equal(a, b)
    c = draw(make(randomization="owen"), 8, 4, 16, [2, 2], seed=1)
    d = draw(make(randomization="owen"), 8, 4, 16, [2, 2], seed=2)
    assert np.mean(c[0] == d[0]) < 0.01
    # the 'seed' parameter offsets the render's seed
    e = draw(make(randomization="owen", seed=1), 8, 4, 16, [2, 2], seed=1)
    np.testing.assert_array_equal(d, e)


@dr.syntax
def _draw_in_loop(sampler, steps, lanes):
    out = dr.zeros(mi.Float, lanes * steps)
    lane = dr.arange(mi.UInt32, lanes)
    i = mi.UInt32(0)
    while i < steps:
        dr.scatter(out, sampler.next_1d(), lane * steps + i)
        i += 1
    return out


class FrozenZSobol(ZSobolSampler):
    """The classic bug: a Python int dimension counter (frozen in symbolic loops)."""

    def seed(self, seed, wavefront_size=0xFFFFFFFF):
        super().seed(seed, wavefront_size)
        self._py_dimension = 0

    def _draw(self, components):
        values = qmc_sobol.zsobol_sample(self.current_sample_index(), mi.UInt32(self._py_dimension),
                                   self._seed, self._x_mask, self.randomization, components)
        self._py_dimension += components
        return values

    def next_1d(self, active=True):
        return self._draw(1)[0]

    def next_2d(self, active=True):
        return mi.Point2f(*self._draw(2))


def test_dimension_advances_in_symbolic_loop():
    spp, steps = 16, 12
    sampler = make(spp, 4)
    sampler.seed(3, 4 * spp)
    reference = np.stack([np.array(sampler.clone().next_1d()) for _ in range(1)], axis=1)
    got = np.array(_draw_in_loop(sampler, steps, 4 * spp)).reshape(4 * spp, steps)
    np.testing.assert_array_equal(got[:, :1], reference)
    assert np.all(is_stratified_1d(got.T.reshape(steps, 4, spp, 1)))
    assert len(np.unique(got[0])) == steps
    props = mi.Properties("zsobol")
    props["sample_count"], props["film_width"] = spp, 4
    frozen = FrozenZSobol(props)
    frozen.seed(3, 4 * spp)
    got = np.array(_draw_in_loop(frozen, steps, 4 * spp)).reshape(4 * spp, steps)
    assert np.all(got == got[:, :1])


def test_next_2d_counts_two_dimensions():
    """Exact: a 2D draw takes the dimensions d and d + 1, so the value drawn after it is the
    one drawn at d + 2 after two 1D draws (pbrt's ZSobolSampler::Get2D). Negative control:
    a 2D draw that advanced one dimension would give the draw at d + 1 instead."""
    for randomization in ("none", "owen"):
        a, b = make(16, 4, randomization=randomization), make(16, 4, randomization=randomization)
        a.seed(5, 64)
        b.seed(5, 64)
        a.next_2d()
        after_2d = np.array(a.next_1d())
        b.next_1d()
        at_1 = np.array(b.next_1d())
        at_2 = np.array(b.next_1d())
        np.testing.assert_array_equal(after_2d, at_2)
        assert not np.array_equal(at_1, at_2)        # the control would be told apart


# ------------------------------------------------------- sampler protocol

def test_clone_and_fork():
    sampler = make(8, 4, randomization="permute_digits", seed=4, sequence_length=16)
    sampler.sample_offset = 8
    sampler.seed(9, 4 * 2 * 8)
    sampler.next_2d()
    clone = sampler.clone()
    np.testing.assert_array_equal(np.array(clone.next_2d()), np.array(sampler.next_2d()))
    fork = sampler.fork()
    assert isinstance(fork, ZSobolSampler)
    assert (fork.sample_count(), fork.randomization, fork.base_seed, fork.film_width,
            fork.sequence_length, fork.sample_offset) == (8, "permute_digits", 4, 4, 16, 8)
    fork.seed(9, 64)
    sampler.seed(9, 64)
    np.testing.assert_array_equal(np.array(fork.next_1d()), np.array(sampler.next_1d()))


def test_continued_sequence_equals_one_long_render():
    """Samples 0-3 and 4-7 of an 8-sample sequence (sample_offset, sequence_length),
    and a declared two-pass seeding (set_samples_per_wavefront, advance), give the
    8-sample seeding's points sample for sample; each 4-sample part is a net."""
    w, h = 8, 4
    full = draw(make(8, w), w, h, 8, [2, 2])
    sampler = make(4, w, sequence_length=8)
    first = draw(sampler, w, h, 4, [2, 2])
    sampler.sample_offset = 4
    second = draw(sampler, w, h, 4, [2, 2])
    for f, a, b in zip(full, first, second):
        np.testing.assert_array_equal(np.concatenate([a, b], axis=1), f)
        assert np.all(is_net(a)) and np.all(is_net(b))
    declared = make(8, w)
    declared.set_samples_per_wavefront(4)
    passes = [draw(declared, w, h, 4, [2, 2])[1]]
    np.testing.assert_array_equal(passes[0], full[1][:, :4])
    declared.advance()
    passes.append(np.array(declared.next_2d()).T.reshape(w * h, 4, 2))   # dimension 0 again
    np.testing.assert_array_equal(passes[1], full[0][:, 4:])


# -------------------------------------------------------------- rendering

def _cbox(width, height, spp=4, **sampler):
    scene = mi.load_file(scene_path("cbox.xml"), sampler="zsobol", spp=spp, width=width,
                         height=height)
    s = scene.sensors()[0].sampler()
    s.film_width = width
    for k, v in sampler.items():
        setattr(s, k, v)
    return scene


def _causes(exc):
    while exc is not None:
        yield str(exc)
        exc = exc.__cause__ or exc.__context__


def _render_error(scene, **kwargs) -> str:
    with pytest.raises(RuntimeError) as info:
        mi.render(scene, **kwargs)
    return " ".join(_causes(info.value))


def test_render_errors_are_clear():
    scene = mi.load_file(scene_path("cbox.xml"), sampler="zsobol", spp=4, width=16, height=8)
    assert "'film_width' is not set" in _render_error(scene)
    scene.sensors()[0].sampler().film_width = 12
    assert "not film_width 12 x height x 4" in _render_error(scene)
    scene = _cbox(16, 8, sample_offset=4)
    message = _render_error(scene)
    assert "samples 4 .. 7" in message and "sequence_length" in message, message
    scene.sensors()[0].sampler().sequence_length = 8
    assert np.all(np.isfinite(mi.render(scene)))
    # more index bits than 32: 4096 x 1 pixels (a Morton square of 24 bits), 512 spp
    sampler = make(512, 4096)
    sampler.seed(0, 4096 * 512)
    with pytest.raises(RuntimeError, match="need 33 index bits"):
        sampler.next_1d()


@pytest.mark.parametrize("integrator", ["path", "vr_path"])
def test_samples_per_pass_render_stops_with_clear_error(integrator):
    """Mitsuba's own multi-pass render cannot tell a Python sampler its layout: the render
    stops with the explanation; the sampler renders correctly afterwards."""
    scene = _cbox(8, 8, spp=16)
    reference = np.array(mi.render(scene, seed=3))
    message = _render_error(scene, seed=3,
                            integrator=mi.load_dict({"type": integrator, "samples_per_pass": 4}))
    assert "several passes" in message and "sample_offset" in message, message
    np.testing.assert_allclose(np.array(mi.render(scene, seed=3)), reference, rtol=1e-5,
                               atol=1e-7)


def test_sample_offset_continues_the_sequence_across_renders():
    """Renders of 1, 1, 2 and 4 spp with growing offsets in a sequence of 8 = one 8 spp
    render; reseeding and a new offset do not recompile."""
    scene = _cbox(16, 8, spp=8)
    path = mi.load_dict({"type": "path", "max_depth": 4})
    one_shot = np.array(mi.render(scene, seed=11, integrator=path))
    sampler = scene.sensors()[0].sampler()
    sampler.sequence_length = 8
    acc, done = 0.0, 0
    for k in (1, 1, 2, 4):
        sampler.sample_offset = done
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            acc = acc + k * np.array(mi.render(scene, seed=11, spp=k, integrator=path))
            history = dr.kernel_history()
        if done:
            assert all(h["cache_hit"] for h in history if h["type"] == dr.KernelType.JIT)
        done += k
    np.testing.assert_allclose(acc / done, one_shot, rtol=1e-4, atol=1e-5)
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("sampler.sample_offset"))
    params[key] = 5
    params.update()
    assert sampler.sample_offset == 5


# ------------------------------------------------------- unbiasedness

SIGNIFICANCE = 0.01
SIZE, SPP, SEEDS, MAX_DEPTH = 32, 32, 8, 8
#: (scene, integrator, randomization) cases compared with path + independent, at
#: SIZE x SIZE: Mitsuba's Cornell box and the bundled scene (a glossy phong sphere,
#: a smaller light). vr_path bsdf+nee draws the same dimensions for the same
#: purposes as path (their zsobol renders agree to rounding on both scenes), so
#: each scene runs one of them with owen.
CASES = [("cornell_box", "vr_path", "owen"), ("cornell_box", "vr_path", "permute_digits"),
         ("cbox.xml", "path", "owen")]
#: Blocks and channels per case, and the pooled channels.
COMPARISONS = len(CASES) * ((SIZE // B.BLOCK) ** 2 * 3 + 3)
LEVEL = B.sidak(SIGNIFICANCE, COMPARISONS)
#: The uniform relative bias the test claims to detect (about 90% of the time).
DETECTS = 0.02


def _integrator(name):
    if name == "vr_path":
        return mi.load_dict({"type": "vr_path", "strategy": "bsdf", "emitter_sampling": True,
                             "max_depth": MAX_DEPTH})
    return mi.load_dict({"type": "path", "max_depth": MAX_DEPTH})


def _scene(name, sampler="zsobol", randomization="owen"):
    if name == "cornell_box":
        d = mi.cornell_box()
        d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = SIZE
        d["sensor"]["sampler"] = {"type": sampler}
        scene = mi.load_dict(d)
    else:
        scene = mi.load_file(scene_path(name), width=SIZE, height=SIZE, sampler=sampler)
    if sampler != "independent":
        s = scene.sensors()[0].sampler()
        s.film_width, s.randomization = SIZE, randomization
    return scene


def _renders(scene, integrator, seeds, spp):
    return B.summarize(np.stack([np.array(mi.render(scene, integrator=integrator, spp=spp,
                                                    seed=int(k)), np.float64) for k in seeds]))


_references = {}


def path_reference(name):
    """SEEDS renders of path + independent at 4x the spp, cached per scene."""
    if name not in _references:
        _references[name] = _renders(_scene(name, "independent"), _integrator("path"),
                                     range(1, 1 + SEEDS), 4 * SPP)
    return _references[name]


def _agreement(name, integrator, sampler="zsobol", randomization="owen"):
    zs = _renders(_scene(name, sampler, randomization), _integrator(integrator),
                  range(101, 101 + SEEDS), SPP)
    return B.agree(zs, path_reference(name), LEVEL, LEVEL, variance="renders")


@pytest.mark.parametrize("name, integrator, randomization", CASES)
def test_blocks_agree_with_path(name, integrator, randomization):
    """8x8-pixel blocks (and the pooled image) of zsobol renders agree with path +
    independent (Welch t, the variance from the spread over independent seeds:
    zsobol's pixels are correlated), and the test is powerful enough to see a 2%
    uniform bias."""
    res = _agreement(name, integrator, randomization=randomization)
    assert res.passed, res.describe()
    assert res.detectable < DETECTS, res.describe()


def test_block_test_catches_a_frozen_dimension():
    """Negative control: the Python dimension counter (every bounce draws the same points)."""
    mi.register_sampler("frozen_zsobol", lambda props: FrozenZSobol(props))
    res = _agreement("cbox.xml", "vr_path", "frozen_zsobol")
    assert not res.passed, res.describe()
