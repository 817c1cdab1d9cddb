"""A sampler of one's own, in one file: a randomly shifted rank-1 lattice (``lattice``).

Sample ``i`` of ``n`` in a pixel is, in every pair of dimensions one ``next_2d`` draws,
the Fibonacci-like lattice point ``(i / n, frac(i g / n))`` with ``g`` the integer nearest
``n / phi`` that is coprime with ``n``, shifted modulo 1 by a random vector per pixel and
per dimension (a Cranley-Patterson rotation: every point stays uniform, the pattern keeps
its structure). ``next_1d`` gives the shifted 1-D grid ``i / n``.

Load it with ``--plugin examples/lattice_sampler.py`` (any experiment script): it registers
a Mitsuba plugin ``lattice`` for the current variant (the loader sets ``--variant`` first)
and a descriptor in the experiments' sampler table, so ``bsdf+nee+lattice`` is a method,
and the sampler study and the lab's point sets include it. See docs/extending.md.
"""
import math

import drjit as dr
import mitsuba as mi

from experiments.lib.samplers import SamplerSpec, register_sampler
from integrators import qmc


def generator(n: int) -> int:
    """The lattice's second coordinate step: the integer nearest n / phi coprime with n."""
    g = max(1, round(n / ((1 + 5 ** 0.5) / 2)))
    while n > 1 and math.gcd(g, n) != 1:
        g += 1
    return g


class LatticeSampler(mi.Sampler):
    """Randomly shifted rank-1 lattice; parameters: ``sample_count`` (Default: 4),
    ``seed`` (Default: 0). One pass per ``mi.render`` (a multi-pass render is refused)."""

    def __init__(self, props: mi.Properties):
        mi.Sampler.__init__(self, props)
        self.base_seed = props.get("seed", 0)
        self._reset(mi.UInt32(self.base_seed), 1, 1)

    def _reset(self, seed, lanes: int, spp: int) -> None:
        lane = dr.arange(mi.UInt32, lanes)
        pixel = lane // dr.opaque(mi.UInt32, spp)
        self._index = lane - pixel * spp                 # sample of the lane in its pixel
        self._pixel_seed = qmc.pixel_seed(seed, pixel)
        self._dimension = dr.zeros(mi.UInt32, lanes)
        self._n, self._g = spp, generator(spp)

    def seed(self, seed, wavefront_size: int = 0xFFFFFFFF) -> None:
        mi.Sampler.seed(self, seed, wavefront_size)
        spp, lanes = self.sample_count(), self.wavefront_size()
        self._reset(mi.UInt32(seed) + self.base_seed, lanes, spp if lanes % spp == 0 else 1)

    def advance(self) -> None:
        raise RuntimeError("lattice: render one pass per mi.render call (no samples_per_pass)")

    def schedule_state(self) -> None:
        dr.schedule(self._index, self._pixel_seed, self._dimension)

    def _shift(self) -> mi.Float:
        """A uniform shift in [0, 1) per pixel and dimension; advances the dimension."""
        h = qmc.dimension_seed(self._pixel_seed, self._dimension)
        self._dimension += 1
        return mi.Float(h >> 8) * (1.0 / (1 << 24))

    def _coordinate(self, step: int, shift) -> mi.Float:
        i = mi.UInt32(self._index)
        v = mi.Float((i * step) % self._n) / self._n + shift
        return dr.minimum(v - dr.floor(v), 1.0 - 2.0 ** -24)

    def next_1d(self, active=True) -> mi.Float:
        return self._coordinate(1, self._shift())

    def next_2d(self, active=True) -> mi.Point2f:
        sx, sy = self._shift(), self._shift()
        return mi.Point2f(self._coordinate(1, sx), self._coordinate(self._g, sy))

    def fork(self) -> mi.Sampler:
        props = mi.Properties("lattice")
        props["sample_count"] = self.sample_count()
        props["seed"] = self.base_seed
        return LatticeSampler(props)

    def clone(self) -> mi.Sampler:
        sampler = self.fork()
        if self.wavefront_size() > 1:
            mi.Sampler.seed(sampler, 0, self.wavefront_size())
        sampler._index, sampler._pixel_seed = mi.UInt32(self._index), mi.UInt32(self._pixel_seed)
        sampler._dimension = mi.UInt32(self._dimension)
        sampler._n, sampler._g = self._n, self._g
        return sampler

    def to_string(self) -> str:
        return f"LatticeSampler[sample_count={self.sample_count()}, seed={self.base_seed}]"


mi.register_sampler("lattice", LatticeSampler)
register_sampler(SamplerSpec("lattice", bakes_spp=True, description="a randomly shifted "
                             "rank-1 lattice (its count is compiled into the kernel) "
                             "(examples/lattice_sampler.py)"), replace=True)
