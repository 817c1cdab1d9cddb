"""The guide's directional model (integrators/guide_quadtree.py, the pooling of
integrators/sdtree.py): the adaptive quadtree against a recursive oracle and on known
fields, the records of every iteration pooled into a unit's histogram, and the radiance
learned times the cosine to the unit's normal class (exact values on a known field; its
gain per sample on door_room)."""
import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from integrators import guide_quadtree, guide_warps, sdtree


def oracle(energy: np.ndarray, res: int, share: float) -> tuple[np.ndarray, int]:
    """PPG's quadtree written as a recursion over nodes: (the density per bin, leaves)."""
    grid = energy.reshape(res, res)
    total, out, leaves = grid.sum(), np.zeros((res, res)), 0

    def visit(i, j, side):
        nonlocal leaves
        block = grid[i:i + side, j:j + side]
        if side == 1 or block.sum() <= share * total:
            out[i:i + side, j:j + side] = block.sum() / (side * side)
            leaves += 1
            return
        half = side // 2
        for di in (0, half):
            for dj in (0, half):
                visit(i + di, j + dj, half)
    visit(0, 0, res)
    return out.ravel(), leaves


def lumpy(rng, rows, res):
    """Rows of energies with a few bright lumps over a dim, partly empty background."""
    e = rng.exponential(0.01, (rows, res * res)) * (rng.random((rows, res * res)) < 0.7)
    for r in range(rows):
        e[r, rng.integers(0, res * res, 3)] += rng.exponential(5.0, 3)
    return e


@pytest.mark.parametrize("res,share", [(16, 0.01), (32, 0.01), (32, 0.05), (8, 0.2)])
def test_quadtree_matches_a_recursive_oracle(res, share):
    rng = np.random.default_rng(res)
    energy = lumpy(rng, 6, res)
    got = guide_quadtree.density(energy, res, share)
    counts = guide_quadtree.leaf_count(energy, res, share)
    for r in range(len(energy)):
        want, leaves = oracle(energy[r], res, share)
        np.testing.assert_allclose(got[r], want, rtol=1e-12, atol=1e-15)
        assert counts[r] == leaves
    # each row keeps its total; share 0 is the raw histogram
    np.testing.assert_allclose(got.sum(axis=1), energy.sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(guide_quadtree.density(energy, res, 0.0), energy)


def test_quadtree_refines_where_the_energy_is():
    """All the energy in one bin: the tree descends to it alone (3 leaves per level and
    the bin), which keeps all of it; a uniform field at share 0.01 stops at the first level
    whose nodes hold at most 1% (4^-4 = 0.4%: 256 leaves of 4 bins), uniform."""
    res = 32
    one = np.zeros((1, res * res))
    one[0, 17 * res + 5] = 2.0
    d = guide_quadtree.density(one, res, 0.01)
    assert d[0, 17 * res + 5] == 2.0 and d.sum() == 2.0
    assert guide_quadtree.leaf_count(one, res, 0.01)[0] == 3 * 5 + 1
    flat = np.ones((1, res * res))
    assert guide_quadtree.leaf_count(flat, res, 0.01)[0] == 256
    np.testing.assert_allclose(guide_quadtree.density(flat, res, 0.01), flat)


def test_quadtree_pools_a_noisy_dim_region_and_keeps_a_bright_one():
    """Records of a field with a bright lobe: in the dim region the tree averages the
    noisy bins (its error against the field's own bin shares is well below the raw
    bins'), in the lobe it keeps the bins (its error there within 10% of theirs: a few
    merged bins at the lobe's edge)."""
    res, n = 32, 20_000
    rng = np.random.default_rng(3)
    z, phi = rng.uniform(-1, 1, n), rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.sqrt(1 - z ** 2) * np.cos(phi), np.sqrt(1 - z ** 2) * np.sin(phi), z], 1)
    axis = np.array([0.0, 0.6, 0.8])
    field = 1 + 400 * np.maximum(d @ axis, 0) ** 64
    records = np.bincount(guide_warps.direction_to_bin_np(d, res), field, res * res)[None]
    m = 8 * res         # the field's bin shares by a fine midpoint quadrature
    zz = np.repeat((np.arange(m) + 0.5) / m * 2 - 1, m)
    pp = np.tile((np.arange(m) + 0.5) / m * 2 * np.pi, m)
    q = np.stack([np.sqrt(1 - zz ** 2) * np.cos(pp), np.sqrt(1 - zz ** 2) * np.sin(pp), zz], 1)
    truth = np.bincount(guide_warps.direction_to_bin_np(q, res), 1 + 400 * np.maximum(
        q @ axis, 0) ** 64, res * res)
    truth /= truth.sum()
    raw = records[0] / records.sum()
    fitted = guide_quadtree.density(records, res, 0.01)[0] / records.sum()
    dim = truth < 2.0 / (res * res)
    assert np.abs(fitted - truth)[dim].sum() < 0.6 * np.abs(raw - truth)[dim].sum()
    assert np.abs(fitted - truth)[~dim].sum() <= 1.1 * np.abs(raw - truth)[~dim].sum()


def test_quadtree_needs_a_power_of_two():
    with pytest.raises(ValueError, match="power-of-two resolution, got 24"):
        guide_quadtree.density(np.ones((1, 24 * 24)), 24)


def add_records(tree, unit, bins, values, count):
    """``count`` records of ``values`` (per bin of ``bins``) in ``unit``."""
    dr.scatter_add(tree.energy, mi.Float(values), mi.UInt32(unit * tree.bins + bins))
    dr.scatter_add(tree.counts, mi.UInt32(count), mi.UInt32([unit]))


@pytest.mark.parametrize("pooled", [True, False])
def test_every_iteration_s_records_are_pooled(pooled, monkeypatch):
    """Two iterations' records in a unit: with pooling its histogram is fitted to both
    (A + B), without it to the last (B); a leaf that splits hands each child half of its
    sums, so a child with few new records still learns from the old ones."""
    monkeypatch.setattr(sdtree, "POOLED", pooled)
    res = 4
    tree = sdtree.SDTree(res, 4, split_share=0.0)
    a, b = np.zeros(res * res), np.zeros(res * res)
    a[3], b[3], b[9] = 6.0, 2.0, 4.0
    add_records(tree, 0, np.arange(res * res), a, 100)
    tree.refine(threshold=1e12)
    add_records(tree, 0, np.arange(res * res), b, 100)
    tree.refine(threshold=50)                    # leaf 0 splits: 100 records > 50
    cos = sdtree.class_cosines(res)[0]          # unit 0: class +x (the cosine product)
    want = (a + b) * cos / ((a + b) * cos).sum() if pooled else b * cos / (b * cos).sum()
    np.testing.assert_allclose(tree.prob[0], want, rtol=1e-12)
    assert tree.leaves == 2
    # the new leaf's unit 0 (leaf 1, class 0): 10 new records of c, too few alone
    c = np.zeros(res * res)
    c[0] = 1.0
    add_records(tree, sdtree.CLASSES, np.arange(res * res), c, 10)
    tree.refine(threshold=1e12)
    got = tree.prob[sdtree.CLASSES]
    if pooled:       # half of the pooled sums and the new records: 110 >= MIN_RECORDS
        mixed = (0.5 * (a + b) + c) * cos
        np.testing.assert_allclose(got, mixed / mixed.sum())
    else:            # 10 records: the parent's histogram kept
        np.testing.assert_allclose(got, want)


def test_the_integrator_fits_its_quadtree_to_the_pooled_records():
    """``directional_split`` > 0: every learned histogram is the quadtree fitted to the
    unit's pooled energies (its raw sums are kept, the fit is the table); a resolution that
    is not a power of two is refused, naming both parameters."""
    import integrators  # noqa: F401
    scene = mi.load_dict({
        "type": "scene", "sky": {"type": "constant"},
        "floor": {"type": "rectangle", "bsdf": {"type": "diffuse"}},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 3], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 16, "height": 16}}})
    integ = mi.load_dict({"type": "vr_guided_path", "max_depth": 3, "min_train_spp": 2,
                          "min_train_samples": 1, "directional_resolution": 16,
                          "directional_split": 0.05, "bsdf_fraction": 1.0})
    schedule = integ.pass_schedule(30, 256)
    for i, spp in enumerate(schedule):
        integ.after_pass(i, mi.render(scene, integrator=integ, spp=spp, seed=i), spp)
    tree = integ.guide.tree
    units = np.flatnonzero(tree.learned)
    assert len(units) > 0 and tree.split_share == 0.05
    product = tree.kept_energy[units] * sdtree.class_cosines(16)[units % sdtree.CLASSES]
    fitted = guide_quadtree.density(product, 16, 0.05)
    np.testing.assert_allclose(tree.prob[units], fitted / fitted.sum(axis=1, keepdims=True),
                               rtol=1e-9, atol=1e-12)
    raw = product / product.sum(axis=1, keepdims=True)
    assert np.abs(tree.prob[units] - raw).max() > 1e-3     # the fit is not the raw bins
    with pytest.raises(Exception, match="'directional_split' 0.05 needs a power-of-two "
                                         "'directional_resolution'.*got 12"):
        mi.load_dict({"type": "vr_guided_path", "directional_resolution": 12,
                      "directional_split": 0.05})


def test_class_cosines_are_the_axes_dot_the_bin_centres():
    """Exact values: per normal class (+x, -x, +y, -y, +z, -z) the |cos| between its axis and
    each bin's centre direction (cos theta = (i + 1/2) 2 / res - 1, phi = (j + 1/2) 2 pi /
    res), the two signs of an axis alike."""
    res = 4
    c = sdtree.class_cosines(res)
    cos_t = (np.arange(res) + 0.5) * 2 / res - 1
    phi = (np.arange(res) + 0.5) * 2 * np.pi / res
    sin_t = np.sqrt(1 - cos_t ** 2)
    want = {0: np.abs(np.outer(sin_t, np.cos(phi))), 2: np.abs(np.outer(sin_t, np.sin(phi))),
            4: np.abs(np.outer(cos_t, np.ones(res)))}
    for axis, w in want.items():
        np.testing.assert_allclose(c[axis].reshape(res, res), w, atol=1e-12)
        np.testing.assert_allclose(c[axis + 1], c[axis])


@pytest.mark.parametrize("product", [True, False])
def test_a_unit_learns_its_radiance_times_the_cosine_to_its_normal(product, monkeypatch):
    """A unit of class +z (a floor) whose records carry the same radiance from every bin
    of the upper hemisphere learns a histogram proportional to each bin's cos theta (the
    product a diffuse surface's integrand has, docs/guiding.md); with COSINE_PRODUCT off,
    the radiance alone: uniform over those bins (the negative control). A unit of class
    +x under the same records learns |cos| to x instead."""
    monkeypatch.setattr(sdtree, "COSINE_PRODUCT", product)
    res = 8
    tree = sdtree.SDTree(res, 4, split_share=0.0)
    up = np.zeros(res * res)
    up[(np.arange(res * res) // res) >= res // 2] = 1.0        # cos theta > 0
    for unit in (4, 0):                                          # classes +z and +x
        add_records(tree, unit, np.arange(res * res), up, 1000)
    tree.refine(threshold=1e12)
    for unit in (4, 0):
        want = up * (sdtree.class_cosines(res)[unit] if product else 1.0)
        np.testing.assert_allclose(tree.prob[unit], want / want.sum(), rtol=1e-12)
    if product:
        assert not np.allclose(tree.prob[4], tree.prob[0])


def test_the_cosine_product_lowers_the_error_per_sample_where_light_arrives_indirectly(
        monkeypatch):
    """door_room (48x36, guided+nee at 1024 spp: it trains), two seeds, each job's expected
    relMSE from its stated per-pixel variance: learning the radiance times the cosine lowers
    it by over 1.15 times against the radiance alone on the same seeds (measured: 1.37 over
    six seeds, 1.23 to 1.38 per seed; docs/guiding.md), at the same cost per sample."""
    import scenes
    from experiments.lib import execute, plan
    from experiments.lib.jobs import Accumulator
    from experiments.lib.methods import parse_method
    from experiments.lib.scenes import effective_depth, read_scene
    info = read_scene(scenes.path("suite/door_room.xml"))
    runs = {}
    for product in (False, True):
        monkeypatch.setattr(sdtree, "COSINE_PRODUCT", product)
        for seed in (4000, 4001):
            job = plan.make_job(f"cos/{product}/{seed}", info, parse_method("guided+nee"), 48,
                                36, 1024, seed, effective_depth(info), "llvm_ad_rgb")
            acc = Accumulator.empty(36, 48)
            acc.add_result(execute.run_job(job, "llvm_ad_rgb"))
            runs.setdefault(product, []).append((acc.mean, acc.variance_of_mean()))
    ref = np.mean([m for v in runs.values() for m, _ in v], axis=0)
    error = {p: np.mean([np.mean(var / (ref ** 2 + 0.01)) for _, var in v])
             for p, v in runs.items()}
    assert error[False] / error[True] > 1.15, error


def test_each_job_learns_from_its_own_samples_alone():
    """A second ``mi.render`` with one ``vr_guided_path`` starts from a new guide: the
    first job's tree, histograms, shares and box are gone when the next job's schedule is
    made (a guide that has not rendered is kept: a new one is 20 ms of host work), and a
    job on another scene puts the guide's box round that scene (a guide kept from the
    first job would train the second on the first's samples, its training not counted,
    and look up another scene's leaves)."""
    import integrators  # noqa: F401

    def room(size):
        return mi.load_dict({
            "type": "scene", "light": {"type": "constant"},
            "floor": {"type": "rectangle", "bsdf": {"type": "diffuse"},
                      "to_world": mi.ScalarTransform4f().scale(size)},
            "sensor": {"type": "perspective", "fov": 40,
                       "to_world": mi.ScalarTransform4f().look_at([0, 0, 3 * size],
                                                                  [0, 0, 0], [0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 16, "height": 16}}})
    integ = mi.load_dict({"type": "vr_guided_path", "max_depth": 3, "min_train_spp": 2,
                          "min_train_samples": 1, "spatial_threshold": 10})
    new = mi.load_dict({"type": "vr_guided_path"})
    untouched = new.guide.tree
    new.pass_schedule(64, 256)          # a guide that has not rendered is new: kept
    assert new.guide.tree is untouched
    mi.render(room(1.0), integrator=integ, spp=64, seed=1)
    tree = integ.guide.tree
    assert tree.learned.any() and tree.leaves > 1 and tree.has_bbox
    integ.pass_schedule(64, 256)
    fresh = integ.guide.tree
    assert fresh is not tree and fresh.leaves == 1 and fresh.nodes == 1
    assert not fresh.learned.any() and not fresh.has_bbox
    assert (fresh.share == 1).all() and (np.array(integ.guide.share) == 1).all()
    mi.render(room(10.0), integrator=integ, spp=64, seed=2)
    lower = np.array([dr.slice(c) for c in (integ.guide.tree.lower.x,
                                            integ.guide.tree.lower.y)])
    np.testing.assert_allclose(lower, [-10.2, -10.2], rtol=0.01)
