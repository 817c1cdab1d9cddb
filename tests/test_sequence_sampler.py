"""integrators.sequence_sampler.SequenceSampler, the state skeleton of halton, zsobol and
the lattice example: they write only their point maths; the base's seeding policy, its
refusals, fork and clone hold for each of them (Mitsuba's own sampler tests,
src/samplers/tests/utils.py, check clone and reseeding the same way)."""
import os

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from conftest import ROOT
from experiments.lib import extensions
from integrators.halton import HaltonSampler
from integrators.sequence_sampler import SequenceSampler
from integrators.zsobol import ZSobolSampler

#: What the base owns: no sampler defines these itself.
SKELETON = ("seed", "advance", "fork", "clone", "schedule_state", "traverse",
            "parameters_changed")
WIDTH, HEIGHT, SPP = 4, 2, 8
PIXELS = WIDTH * HEIGHT


def lattice_class():
    extensions.load(os.path.join(ROOT, "examples", "lattice_sampler.py"))
    return type(mi.load_dict({"type": "lattice"}))


def make(name: str, spp: int = SPP, **params):
    props = {"type": name, "sample_count": spp, **params}
    if name == "zsobol":
        props["film_width"] = WIDTH
    if name == "lattice":
        lattice_class()
    return mi.load_dict(props)


SAMPLERS = ("halton", "zsobol", "lattice")


class IndexSampler(SequenceSampler):
    """The base alone: every draw is the lane's sample index plus 1000 x its dimension."""
    PLUGIN = "index"

    def next_1d(self, active=True):
        value = mi.Float(self.current_sample_index() + 1000 * self._dimension)
        self._dimension += 1
        return value

    def next_2d(self, active=True):
        return mi.Point2f(self.next_1d(active), self.next_1d(active))


def index_sampler(spp=SPP, **params) -> IndexSampler:
    props = mi.Properties("index")
    props["sample_count"] = spp
    for key, value in params.items():
        props[key] = value
    return IndexSampler(props)


def draws(sampler, n: int) -> np.ndarray:
    """``n`` successive next_1d values of every lane, (lanes, n)."""
    return np.stack([np.array(sampler.next_1d()) for _ in range(n)], axis=1)


# ------------------------------------------------------------ structure

def test_samplers_define_none_of_the_skeleton():
    for cls in (HaltonSampler, ZSobolSampler, lattice_class()):
        assert issubclass(cls, SequenceSampler), cls
        own = sorted(set(SKELETON) & set(vars(cls)))
        assert not own, f"{cls.__name__} defines {own} itself"
    assert all(name in vars(SequenceSampler) for name in SKELETON)


# ------------------------------------------------------------ the policy

def test_lanes_take_their_pixels_samples_in_one_pass():
    """A one-pass seeding (width * height * spp lanes): lane l draws sample l % spp,
    shifted by sample_offset; the dimension counts the draws."""
    sampler = index_sampler(sample_offset=5)
    sampler.seed(0, PIXELS * SPP)
    lanes = np.arange(PIXELS * SPP)
    got = draws(sampler, 3)
    for dim in range(3):
        np.testing.assert_array_equal(got[:, dim], 5 + lanes % SPP + 1000 * dim)
    # a wavefront the sample count does not divide: one sequence per lane
    sampler.seed(0, 7)
    np.testing.assert_array_equal(draws(sampler, 1)[:, 0], np.full(7, 5))


def test_declared_passes_continue_the_sequence():
    """set_samples_per_wavefront(k) then seed: lane l is sample l % k of its pass, each
    advance() moves on by k samples and restarts the dimensions."""
    sampler = index_sampler()
    sampler.set_samples_per_wavefront(2)
    sampler.seed(0, PIXELS * 2)
    lanes = np.arange(PIXELS * 2)
    for p in range(4):
        got = draws(sampler, 2)
        np.testing.assert_array_equal(got[:, 0], 2 * p + lanes % 2)
        np.testing.assert_array_equal(got[:, 1], 2 * p + lanes % 2 + 1000)
        sampler.advance()


@pytest.mark.parametrize("name", SAMPLERS)
def test_declared_passes_equal_one_pass(name):
    """Every sampler, seeded in two declared passes of 4, draws the 8-sample pass."""
    full = make(name)
    full.seed(3, PIXELS * SPP)
    reference = np.array(full.next_2d()).T.reshape(PIXELS, SPP, 2)
    sampler = make(name)
    sampler.set_samples_per_wavefront(4)
    sampler.seed(3, PIXELS * 4)
    first = np.array(sampler.next_2d()).T.reshape(PIXELS, 4, 2)
    sampler.advance()
    second = np.array(sampler.next_2d()).T.reshape(PIXELS, 4, 2)
    np.testing.assert_array_equal(np.concatenate([first, second], axis=1), reference)


@pytest.mark.parametrize("name", SAMPLERS + ("index",))
def test_advance_after_an_undeclared_seeding_is_refused(name):
    """One refusal for every sampler, naming the plugin, the seeding's lanes and sample
    count and the way out; a declaration holds for its own seeding only."""
    sampler = index_sampler() if name == "index" else make(name)
    sampler.seed(1, PIXELS * SPP)
    with pytest.raises(RuntimeError) as info:
        sampler.advance()
    message = str(info.value)
    assert message.startswith(f"{name}: advance()"), message
    assert f"seed() of {PIXELS * SPP} lanes (sample_count {SPP})" in message, message
    assert "samples_per_pass" in message and "sample_offset" in message
    assert "set_samples_per_wavefront(k) before seed()" in message
    sampler.set_samples_per_wavefront(4)
    sampler.seed(1, PIXELS * 4)
    sampler.advance()                                  # declared: fine
    sampler.seed(1, PIXELS * SPP)
    with pytest.raises(RuntimeError, match="were not declared"):
        sampler.advance()


@pytest.mark.parametrize("name", SAMPLERS)
def test_bad_values_are_refused_with_their_value(name):
    sampler = make(name)
    with pytest.raises(ValueError, match=f"{name}: samples per wavefront must be > 0, got 0"):
        sampler.set_samples_per_wavefront(0)
    with pytest.raises(ValueError, match=rf"{name}: 'sample_offset' .* got {2**31}"):
        sampler.sample_offset = 2**31
    with pytest.raises(Exception, match=rf"'seed' must be an integer in \[0, 2\^32\), got -1"):
        make(name, seed=-1)


def test_sample_offset_is_a_parameter_that_needs_no_recompile():
    sampler = index_sampler()
    params = mi.traverse(sampler)
    params["sample_offset"] = 3
    params.update()
    assert sampler.sample_offset == 3
    sampler.seed(0, SPP)
    np.testing.assert_array_equal(draws(sampler, 1)[:, 0], 3 + np.arange(SPP))
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        for seed, offset in ((1, 0), (2, 9)):
            sampler.sample_offset = offset
            sampler.seed(seed, SPP)
            dr.kernel_history_clear()
            dr.eval(sampler.next_1d())
            history = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
            if seed > 1:
                assert history and all(k["cache_hit"] for k in history)


# ------------------------------------------------------------ fork and clone

@pytest.mark.parametrize("name", SAMPLERS)
def test_clone_is_an_independent_copy_with_equal_state(name):
    sampler = make(name, seed=4)
    sampler.set_samples_per_wavefront(4)
    sampler.seed(9, PIXELS * 4)
    sampler.next_2d()
    sampler.advance()
    sampler.next_1d()
    clone = sampler.clone()
    assert type(clone) is type(sampler)
    for attr in type(sampler).STATE:
        mine, theirs = getattr(sampler, attr), getattr(clone, attr)
        if isinstance(mine, dr.ArrayBase):
            assert mine is not theirs, attr
            np.testing.assert_array_equal(np.array(theirs), np.array(mine), err_msg=attr)
        else:
            assert theirs == mine, attr
    ahead = draws(clone, 3)                       # the clone moves on, the original not
    np.testing.assert_array_equal(draws(sampler, 3), ahead)
    assert clone.to_string() == sampler.to_string()


@pytest.mark.parametrize("name", SAMPLERS)
def test_fork_has_the_parameters_and_no_state(name):
    offset = 2 if name != "zsobol" else 0
    sampler = make(name, seed=4, sample_offset=offset)
    sampler.set_samples_per_wavefront(4)           # a pending declaration is not passed on
    sampler.seed(5, PIXELS * 4)
    fork = sampler.fork()
    assert type(fork) is type(sampler) and fork.to_string() == sampler.to_string()
    fork.seed(5, PIXELS * SPP)
    fresh = make(name, seed=4, sample_offset=offset)
    fresh.seed(5, PIXELS * SPP)
    np.testing.assert_array_equal(draws(fork, 2), draws(fresh, 2))
    with pytest.raises(RuntimeError, match="were not declared"):
        fork.advance()


def test_a_variant_switch_and_back_keeps_the_base_class_of_the_current_variant():
    """A user's sampler derives from ``integrators.sequence_sampler.SequenceSampler``: after
    another variant was used, and this one again, the base must be this variant's (a class
    deriving from another variant's ``mi.Sampler`` cannot be instantiated here)."""
    from integrators import sequence_sampler
    mi.set_variant("llvm_ad_mono")
    assert issubclass(sequence_sampler.SequenceSampler, mi.Sampler)
    mi.set_variant("llvm_ad_rgb")
    assert issubclass(sequence_sampler.SequenceSampler, mi.Sampler)
    assert issubclass(HaltonSampler, mi.Sampler)
    assert issubclass(lattice_class(), mi.Sampler)
    sampler = make("lattice")
    sampler.seed(1, 4 * SPP)
    assert dr.width(sampler.next_1d()) == 4 * SPP
