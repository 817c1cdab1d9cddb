"""A sampler of one's own, in one file: a randomly shifted rank-1 lattice (``lattice``).

Sample ``i`` of ``n`` in a pixel is, in every pair of dimensions one ``next_2d`` draws,
the Fibonacci-like lattice point ``(i / n, frac(i g / n))`` with ``g`` the integer nearest
``n / phi`` that is coprime with ``n``, shifted modulo 1 by a random vector per pixel and
per dimension (a Cranley-Patterson rotation: every point stays uniform, the pattern keeps
its structure). ``next_1d`` gives the shifted 1-D grid ``i / n``. Its state (seeding per
lane, passes, fork, clone) is that of ``SequenceSampler`` (integrators/sequence_sampler.py),
so it also renders in declared passes; Mitsuba's ``samples_per_pass`` renders are refused.

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
from integrators.sequence_sampler import SequenceSampler


def generator(n: int) -> int:
    """The lattice's second coordinate step: the integer nearest n / phi coprime with n."""
    g = max(1, round(n / ((1 + 5 ** 0.5) / 2)))
    while n > 1 and math.gcd(g, n) != 1:
        g += 1
    return g


class LatticeSampler(SequenceSampler):
    """Randomly shifted rank-1 lattice of ``sample_count`` points; parameters:
    ``sample_count`` (Default: 4), ``seed`` (Default: 0). Seeding, fork, clone and passes
    come from the base class: a caller that declares ``set_samples_per_wavefront(k)``
    renders the lattice in passes of ``k`` points (``advance``)."""
    PLUGIN = "lattice"
    STATE = SequenceSampler.STATE + ("_pixel_seed", "_n", "_g")

    def _seed_lanes(self, seed, pixel, wavefront_size: int) -> None:
        self._pixel_seed = qmc.pixel_seed(seed, pixel)
        self._n = self.sample_count()                 # the points of the whole lattice
        self._g = generator(self._n)

    def _shift(self) -> mi.Float:
        """A uniform shift in [0, 1) per pixel and dimension; advances the dimension."""
        h = qmc.dimension_seed(self._pixel_seed, self._dimension)
        self._dimension += 1
        return mi.Float(h >> 8) * (1.0 / (1 << 24))

    def _coordinate(self, step: int, shift) -> mi.Float:
        i = self.current_sample_index()
        v = mi.Float((i * step) % self._n) / self._n + shift
        return dr.minimum(v - dr.floor(v), 1.0 - 2.0 ** -24)

    def next_1d(self, active=True) -> mi.Float:
        return self._coordinate(1, self._shift())

    def next_2d(self, active=True) -> mi.Point2f:
        sx, sy = self._shift(), self._shift()
        return mi.Point2f(self._coordinate(1, sx), self._coordinate(self._g, sy))


mi.register_sampler("lattice", LatticeSampler)
register_sampler(SamplerSpec("lattice", bakes_spp=True, description="a randomly shifted "
                             "rank-1 lattice (its count is compiled into the kernel) "
                             "(examples/lattice_sampler.py)"), replace=True)
