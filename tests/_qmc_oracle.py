"""The (scrambled) Halton points computed from their definition, in numpy: the tests' oracle.

An independent, straightforward implementation of the definitions in
:mod:`integrators.qmc`'s docstring, one digit at a time in exact integer
arithmetic and float64 sums; it shares only data with the plugin (the prime
table, the digit-permutation table and its per-base offsets and counts, and the
hash functions that turn a seed into per-dimension and per-pixel seeds), none of
its radical-inverse code:

* ``none``: the radical inverse, ``a = sum_k d_k b^k`` -> ``sum_k d_k b^(-k-1)``;
* ``permute_digits`` (odd ``b``): digit position ``k`` has a node fraction
  ``z_k`` (``z_0`` the dimension's seed, ``z_(k+1) = z_k b mod 2^32``); its digit
  ``d`` becomes ``(c + T(d)) mod b``, ``c`` the top base-``b`` digit of ``z_k``,
  ``T`` the table permutation picked by a hash of ``z_k``; every position down to
  float precision, the index's leading zeros included;
* ``owen`` (odd ``b``): the same, but the child node of a digit ``d != 0`` takes a
  fresh fraction (a hash of the parent's and ``d``), so each digit's permutation
  depends on the digits below it;
* base 2: ``permute_digits`` flips each bit of the reversed index by a bit of
  the seed (an XOR mask), ``owen`` is pbrt-v4's ``FastOwenScrambler`` on the
  reversed bits.

Every value is clamped to ``1 - 2^-24`` as the plugin's outputs are. The plugin
computes in float32: compare with an absolute tolerance of :data:`TOLERANCE`.

:func:`halton` gives a component of a point for a sequence seed (as
``qmc.halton_sample``); :func:`sampler_values` what the ``halton`` sampler
returns for a render's lanes (pixel ``lane // spp``, sample ``lane % spp``, the
per-pixel sequence seed from the render's seed).
"""
from __future__ import annotations

import numpy as np

from integrators import qmc

#: Float32 rounding of the plugin's sums (a few ulps of 1) and its 24-bit tail.
TOLERANCE = 5e-7
_M32 = np.uint64(0xFFFFFFFF)
_ONE_MINUS_EPSILON = 1.0 - 2.0 ** -24


def _u32(x) -> np.ndarray:
    return np.asarray(x, dtype=np.uint64) & _M32


def bit_reverse(a) -> np.ndarray:
    """32-bit bit reversal, one bit at a time."""
    a = _u32(a)
    out = np.zeros_like(a)
    for bit in range(32):
        out |= ((a >> np.uint64(bit)) & np.uint64(1)) << np.uint64(31 - bit)
    return out


def fast_owen_scrambler(v, seed) -> np.ndarray:
    """pbrt-v4's ``FastOwenScrambler`` (``util/lowdiscrepancy.h``) of 32-bit ``v``."""
    v, seed = bit_reverse(v), _u32(seed)
    v = v ^ ((v * np.uint64(0x3D20ADEA)) & _M32)
    v = (v + seed) & _M32
    v = (v * ((seed >> np.uint64(16)) | np.uint64(1))) & _M32
    v = v ^ ((v * np.uint64(0x05526C56)) & _M32)
    v = v ^ ((v * np.uint64(0x53A22864)) & _M32)
    return bit_reverse(v)


def _table(b: int):
    """(base b's permutations as a (count, b) array, count) from the plugin's table (data)."""
    index = int(np.nonzero(qmc.PRIMES == b)[0][0])
    offset = ((int(qmc._NP_TABLES["packed"][index]) >> 17) & 0x7FFF) * qmc.PERM_ALIGN
    count = qmc.permutations_per_base(b)
    perms = qmc._NP_TABLES["perms"][offset:offset + count * b].reshape(count, b)
    return perms.astype(np.uint64), count


def _odd(b: int, index: np.ndarray, seed: np.ndarray, randomization: str) -> np.ndarray:
    perms, count = _table(b)
    a = np.asarray(index, dtype=np.uint64).copy()
    z = _u32(seed).copy()
    bb = np.uint64(b)
    value = np.zeros(a.shape, dtype=np.float64)
    scale = 1.0 / b
    # every digit position down to 2^-40, the index's leading zeros included
    while scale > 2.0 ** -40 or np.any(a > 0):
        d = a % bb
        a = a // bb
        if randomization == "none":
            digit = d
        else:
            c = (z * bb) >> np.uint64(32)
            h = ((z ^ (z >> np.uint64(15))) * np.uint64(0x2C9277B5)) & _M32
            pick = (h * np.uint64(count)) >> np.uint64(32)
            digit = (c + perms[pick, d]) % bb
            if randomization == "owen":
                x = ((z ^ ((d * np.uint64(0x9E3779B1)) & _M32)) * np.uint64(0x7FEB352D)) & _M32
                z = np.where(d == 0, (z * bb) & _M32, x ^ (x >> np.uint64(15)))
            else:
                z = (z * bb) & _M32
        value += digit.astype(np.float64) * scale
        scale /= b
        if randomization == "none" and not np.any(a > 0):
            break
    return value


def _base2(index: np.ndarray, seed: np.ndarray, randomization: str) -> np.ndarray:
    rev = bit_reverse(index)
    if randomization == "permute_digits":
        rev = rev ^ _u32(seed)
    elif randomization == "owen":
        rev = fast_owen_scrambler(rev, seed)
    return rev.astype(np.float64) * 2.0 ** -32


def radical_inverse(dimension: int, index, seed, randomization: str) -> np.ndarray:
    """Randomized radical inverse in base ``PRIMES[dimension % 1000]`` of ``index``
    (arrays), scrambled by ``seed`` (the dimension's own seed), clamped below 1."""
    if randomization not in qmc.RANDOMIZATIONS:
        raise ValueError(f"unknown randomization {randomization!r}")
    b = int(qmc.PRIMES[dimension % qmc.PRIME_TABLE_SIZE])
    index, seed = np.broadcast_arrays(np.asarray(index), np.asarray(seed))
    value = _base2(index, seed, randomization) if b == 2 else _odd(b, index, seed,
                                                                    randomization)
    return np.minimum(value, _ONE_MINUS_EPSILON)


def halton(dimension: int, index, sequence_seed, randomization: str) -> np.ndarray:
    """Component ``dimension`` of the Halton points ``index`` of a sequence seed (as
    ``qmc.halton_sample``): the dimension's seed hashes the unwrapped dimension."""
    sequence_seed = np.atleast_1d(np.asarray(sequence_seed, dtype=np.uint32))
    seed = qmc.dimension_seed(sequence_seed, np.full(sequence_seed.shape, dimension,
                                                     dtype=np.uint32))
    return radical_inverse(dimension, index, np.asarray(seed, dtype=np.uint32),
                           randomization)


def sampler_values(dimension: int, lanes: int, spp: int, seed: int, randomization: str,
                   base_seed: int = 0, sample_offset: int = 0) -> np.ndarray:
    """Dimension ``dimension`` of every lane of a ``halton`` sampler seeded with
    ``seed(seed, lanes)`` for ``spp`` samples per pixel: lane ``l`` is sample
    ``sample_offset + l % spp`` of pixel ``l // spp``, whose sequence seed is
    ``qmc.pixel_seed(seed + base_seed, pixel)``."""
    lane = np.arange(lanes, dtype=np.uint32)
    pixel, sample = lane // np.uint32(spp), lane % np.uint32(spp)
    render_seed = np.uint32((seed + base_seed) & 0xFFFFFFFF)
    pixel_seed = qmc.pixel_seed(np.full(lanes, render_seed, dtype=np.uint32), pixel)
    return halton(dimension, sample.astype(np.uint64) + np.uint64(sample_offset),
                  np.asarray(pixel_seed, dtype=np.uint32), randomization)
