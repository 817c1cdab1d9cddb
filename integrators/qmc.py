"""Quasi-Monte Carlo maths for the ``halton`` and ``zsobol`` samplers: primes, radical
inverses and their randomizations, the hashing both samplers share, as vectorised Dr.Jit
code (the 2-D Sobol' sequence in Morton order is :mod:`.qmc_sobol`'s).

Everything here is plain Dr.Jit arithmetic on ``mi.UInt32`` / ``mi.Float``
arrays and works inside symbolic loops (``@dr.syntax`` / ``dr.while_loop``):
the dimension, the sample index and the scramble seed may all be Dr.Jit
arrays whose values change from one loop iteration to the next. The only
Python-side decision is the randomization (a string), which selects the code
that is traced.

Radical inverse of index ``a`` in base ``b``: with ``a = sum_k d_k b^k``,
:math:`\\Phi_b(a) = \\sum_k d_k b^{-k-1}`. Base 2 uses a bit reversal
(``dr.brev``). Other bases peel off one digit per step: the first digit
unconditionally, the others in a Dr.Jit loop that runs while the index has
digits left (so most dimensions, whose base exceeds the sample count, never
enter it). The division by ``b`` is a multiplication by a 32-bit reciprocal
(``dr.mul_hi`` and a shift, exact for indices below 2^31), so no integer
division is ever executed. The two cases sit in the branches of a symbolic
``dr.if_stmt`` on ``base == 2``: a packet of lanes (LLVM) or warp (CUDA) in
which no lane takes a branch skips it, and the sampler draws the same
dimension in every lane, so a call pays for one of them only.

Cost notes (the sampler runs a few dozen times per path in the render
megakernel, so every instruction counts): the per-base constants (base,
reciprocal, shift) are packed into one 64-bit table entry, read with a
single gather (AVX2 gathers are slow); ``1/b`` is one float division;
small unsigned integers go to float through a signed conversion (a single
instruction; unsigned ones are emulated on x86). The randomized variants
cost more per sample than ``none`` mostly not for the scramble's arithmetic
but for SIMD coherence: a packet's lanes are consecutive samples of one
pixel, and the plain (or merely rotated) radical inverse gives them
neighbouring values in every base above the sample count, so their rays and
Russian-roulette decisions stay together, while random permutations scatter
them as independent samples do. Probes that add this module's arithmetic
(times 1e-30) to hash-based random values in the odd bases separate the two
(``python -m benchmarks.halton --floor``): any randomized radical inverse
pays that scattering, however cheap its permutation, so cheaper
permutations (gather-free swap-or-not rounds, pbrt's cycle-walking
``PermutationElement``) were no faster than the table lookup. Measured
costs: docs/benchmarks.md.

Randomizations (pbrt-v4's ``RandomizeStrategy``):

``none``
    The plain radical inverse.
``permute_digits``
    Every digit position ``k`` of every dimension goes through its own random
    permutation of ``{0, ..., b-1}`` (pbrt's ``ScrambledRadicalInverse``),
    including the index's leading zeros, down to float precision.
``owen``
    Nested (Owen) scrambling: the permutation of digit ``k`` also depends on
    the digits ``d_0 .. d_{k-1}`` below it (pbrt's
    ``OwenScrambledRadicalInverse``).

Both are driven by a 32-bit scramble seed (per dimension, and in the sampler
per pixel) instead of per-seed tables. Each tree node (``permute_digits``:
each digit position; ``owen``: each prefix of digits) carries a 32-bit
fixed-point fraction ``z`` and permutes its digit as ``d -> (c + T(d)) mod
b``: ``c`` is the top base-``b`` digit of ``z`` and ``T`` (with ``T(0) = 0``)
one of the base's permutations in :data:`_NP_TABLES` (``perms``), chosen by a
hash of ``z``. For ``b <= 7`` (dimensions 1-3, whose many digits matter most)
the table holds all ``(b-1)!`` such permutations, so every node's permutation
is uniform over all ``b!``; above, 64 (4, 1) random ones per base (see
:func:`permutations_per_base`), so every permuted digit is still exactly
uniform (through ``c``) and each 2-D projection of a pixel's points is a
random-looking set rather than the shifted lattice an affine map ``A d + c``
gives. The child reached by digit 0 takes the fraction ``z * b mod 2^32``
(the remaining digits of ``z``), any other digit (``owen``) a fresh hash. The
permuted leading zeros of an index that has run out of digits are then
exactly the remaining digits of ``z``, added in one step, so the loop only
runs over the index's own digits (about ``log_b(spp)``), and the result is
the same as scrambling all digits down to precision ``2^-32``. Every point is
uniform on [0, 1) and the first ``b^m`` indices keep their stratification
into ``b^m`` intervals. Base 2: the permutations are bit flips, an XOR with a
random 32-bit mask (``permute_digits``, exactly uniform), and pbrt's
``FastOwenScrambler`` (``owen``). (pbrt-v4's hashed ``PermutationElement``,
tried first, reaches only 8 of the 24 permutations of 4 elements and 336 of
720 of 6, and cost more.)

Dimensions map to primes: dimension ``j`` uses ``PRIMES[j % PRIME_TABLE_SIZE]``
(the table holds the first 1000 primes, 2 .. 7919). Past the table the bases
wrap around, as in pbrt; the scrambled variants still differ between
dimension ``j`` and ``j + 1000`` because their seed hashes the unwrapped
dimension, while ``none`` repeats exactly. All outputs lie in [0, 1), clamped
to ``1 - 2^-24`` at most.
"""
from __future__ import annotations

import itertools

import drjit as dr
import mitsuba as mi
import numpy as np

from .warps import ONE_MINUS_EPSILON  # the clamp of every output (one definition)

#: Valid randomizations (pbrt-v4's ``RandomizeStrategy``).
RANDOMIZATIONS = ("none", "permute_digits", "owen")

#: Number of primes in :data:`PRIMES`; dimension ``j`` uses ``PRIMES[j % PRIME_TABLE_SIZE]``.
PRIME_TABLE_SIZE = 1000

#: Largest index for which the radical inverses are exact (``dr.mul_hi`` reciprocals).
MAX_INDEX = 2**31 - 1

#: 2^32 / golden ratio (odd): the Weyl-sequence step that spreads an index
#: (dimension, pixel) over 32 bits before it is hashed with :func:`mix32`.
HASH_MULTIPLIER = 0x9E3779B9


def _first_primes(count: int) -> np.ndarray:
    limit = 8000
    while True:
        sieve = np.ones(limit + 1, dtype=bool)
        sieve[:2] = False
        for p in range(2, int(limit**0.5) + 1):
            if sieve[p]:
                sieve[p * p::p] = False
        primes = np.nonzero(sieve)[0]
        if len(primes) >= count:
            return primes[:count].astype(np.uint32)
        limit *= 2


#: The first :data:`PRIME_TABLE_SIZE` primes (numpy uint32 array).
PRIMES = _first_primes(PRIME_TABLE_SIZE)


def division_magic(b: int) -> tuple[int, int]:
    """Reciprocal ``(m, s)`` with ``a // b == mul_hi(a, m) >> s`` for ``0 <= a < 2^31``.

    For ``b`` not a power of two, ``s = floor(log2 b)`` and
    ``m = floor(2^(32+s) / b) + 1 < 2^32``; the error of ``m`` is at most
    ``b / 2^(32+s)``, which keeps the quotient exact while ``a * b < 2^(32+s+1)``,
    i.e. for every ``a < 2^31``. Powers of two use ``m = 2^31``, ``s = log2(b) - 1``.
    """
    if b < 2:
        raise ValueError(f"qmc: divisor must be >= 2, got {b}")
    s = b.bit_length() - 1
    if b == 1 << s:
        return 1 << 31, s - 1
    return (1 << (32 + s)) // b + 1, s


def permutations_per_base(b: int) -> int:
    """How many digit permutations the table (``_NP_TABLES["perms"]``) holds for base ``b``.

    For ``b <= 7``, every permutation with ``0 -> 0``, each repeated
    ``720 / (b-1)!`` times (so the choice is exactly uniform); 64 random ones
    below 128, 4 below 1024 and one above (dimensions >= 172), which bounds
    the table at about 4 M entries. (:func:`_permutation_count` computes the
    same in Dr.Jit.)
    """
    return 720 if b <= 7 else 64 if b < 128 else 4 if b < 1024 else 1


#: Alignment of each base's run in the permutation table (the packed entry
#: stores the offset in units of it).
PERM_ALIGN = 128


def _build_tables():
    primes = [int(p) for p in PRIMES]
    magic = [division_magic(p) for p in primes]
    # Digit permutations T with T(0) = 0, base after base, each a run of b
    # entries, each base's runs starting at a multiple of PERM_ALIGN.
    rng = np.random.default_rng(0x6A09E667)
    runs, offsets, offset = [], [], 0
    for b in primes:
        count = permutations_per_base(b) if b > 2 else 0
        if b <= 7:
            perms = np.array([(0,) + t for t in itertools.permutations(range(1, b))])
            perms = np.tile(perms, (count // len(perms), 1))
        else:
            perms = np.array([np.concatenate([[0], 1 + rng.permutation(b - 1)])
                              for _ in range(count)]).reshape(count, b)
        run = perms.astype(np.uint32).ravel()
        pad = -len(run) % PERM_ALIGN
        runs += [run, np.zeros(pad, dtype=np.uint32)]
        offsets.append(offset // PERM_ALIGN)
        offset += len(run) + pad
    assert offset // PERM_ALIGN < 1 << 15 and max(primes) < 1 << 13
    # One 64-bit entry per base, so that a call needs a single gather:
    # magic multiplier (bits 32..63), permutation offset / PERM_ALIGN (bits
    # 17..31), shift (bits 13..16) and base (bits 0..12).
    packed = [(m << 32) | (o << 17) | (s << 13) | p
              for p, (m, s), o in zip(primes, magic, offsets)]
    return {"packed": np.array(packed, dtype=np.uint64), "perms": np.concatenate(runs)}


def _permutation_count(b):
    """:func:`permutations_per_base` for a ``mi.UInt32`` array of odd primes."""
    return dr.select(b <= 7, 720, dr.select(b < 128, 64, dr.select(b < 1024, 4, mi.UInt32(1))))


_NP_TABLES = _build_tables()
_JIT_TABLES: dict = {}


def _tables():
    """The per-base tables as Dr.Jit arrays of the current variant (cached)."""
    key = (mi.variant(), mi.UInt32)
    tables = _JIT_TABLES.get(key)
    if tables is None:
        tables = {name: (dr.uint64_array_t(mi.UInt32) if arr.dtype == np.uint64 else mi.UInt32)(arr)
                  for name, arr in _NP_TABLES.items()}
        _JIT_TABLES[key] = tables
    return tables


# ----------------------------------------------------------------- hashing

def mix32(x):
    """32-bit integer hash (Wellons' ``lowbias32``); works on ints and Dr.Jit UInt32."""
    x = x ^ (x >> 16)
    x = x * 0x7FEB352D
    x = x ^ (x >> 15)
    x = x * 0x846CA68B
    return x ^ (x >> 16)


def dimension_seed(seed, dimension):
    """Scramble seed of one dimension, from a sequence seed (UInt32 arrays)."""
    return mix32(seed + dimension * HASH_MULTIPLIER)


def pixel_seed(seed, pixel):
    """Per-pixel scramble seed (a sequence seed for :func:`halton_sample`), from
    the render's seed and the pixel index (``mi.UInt32`` arrays)."""
    return mix32(mix32(seed ^ 0x85EBCA6B) + pixel * HASH_MULTIPLIER)


def laine_karras(v, seed):
    """Nested uniform (Owen) scramble of a bit-reversed 32-bit value ``v``.

    Each bit of the result is bit ``k`` of ``v`` flipped by a hash of
    ``seed`` and the bits below ``k`` only (a Laine-Karras permutation, with
    Vegdahl's constants as in pbrt-v4's ``FastOwenScrambler``): a bijection
    for every seed that maps every aligned block of ``2^j`` values onto an
    aligned block. On a reversed binary fraction (bit 0 = the most
    significant digit) this is Owen's nested scrambling, the permutation of
    each digit depending on the digits above it; on a reversed index, the
    nested shuffle of Burley 2020.
    """
    v = v ^ (v * 0x3D20ADEA)            # (no in-place operators: they would
    v = v + seed                        # change the caller's Dr.Jit array)
    v = v * ((seed >> 16) | 1)
    v = v ^ (v * 0x05526C56)
    return v ^ (v * 0x53A22864)


def _fast_owen_base2(v, seed):
    """pbrt-v4's ``FastOwenScrambler`` on reversed bits ``v`` (input and output reversed)."""
    return dr.brev(laine_karras(dr.brev(v), seed))


def _to_float(v):
    """A UInt32 below 2^31 to a float (a signed conversion, one instruction on x86)."""
    return mi.Float(mi.Int32(v))


def _to_unit(v):
    """UInt32 fixed point (``v / 2^32``) to a float in [0, 1) (rounded, then clamped)."""
    return dr.minimum(mi.Float(v) * (2.0**-32), ONE_MINUS_EPSILON)


def _to_unit_fast(v):
    """UInt32 fixed point (``v / 2^32``) truncated to 24 bits, as a float in [0, 1)."""
    return _to_float(v >> 8) * (2.0**-24)


# --------------------------------------------------------- radical inverse

def radical_inverse(base_index, a):
    """Plain radical inverse of index ``a`` in base ``PRIMES[base_index]``.

    ``base_index`` and ``a`` are ``mi.UInt32`` arrays (or ints); ``a < 2^31``.
    """
    return scrambled_radical_inverse(base_index, a, 0, "none")


def scrambled_radical_inverse(base_index, a, seed, randomization: str = "owen"):
    """Randomized radical inverse in base ``PRIMES[base_index % PRIME_TABLE_SIZE]``.

    ``seed`` is the scramble seed of this dimension (``mi.UInt32``, e.g. from
    :func:`dimension_seed`); it is unused for ``randomization="none"``.
    Returns a ``mi.Float`` in [0, 1).
    """
    if randomization not in RANDOMIZATIONS:
        raise ValueError(f"qmc: unknown randomization {randomization!r}; "
                         f"valid choices are {', '.join(RANDOMIZATIONS)}")
    base_index = mi.UInt32(base_index) % PRIME_TABLE_SIZE
    a = mi.UInt32(a)
    seed = mi.UInt32(seed)
    # A symbolic conditional: on both backends, lanes of a packet (LLVM) or
    # warp (CUDA) that all take one side skip the other, and the sampler's
    # dimension is the same in every lane, so each call pays for one path.
    return dr.if_stmt(args=(base_index, a, seed), cond=base_index == 0,
                      true_fn=lambda i, a, seed: _radical_inverse_base2(a, seed, randomization),
                      false_fn=lambda i, a, seed: _radical_inverse_odd(i, a, seed, randomization),
                      label="radical_inverse")


def _radical_inverse_base2(a, seed, randomization):
    """Base 2: a bit reversal, scrambled by an XOR mask or pbrt's ``FastOwenScrambler``."""
    rev = dr.brev(a)
    if randomization == "permute_digits":
        rev ^= seed
    elif randomization == "owen":
        rev = _fast_owen_base2(rev, seed)
    return _to_unit(rev)


def _radical_inverse_odd(base_index, a, seed, randomization):
    """Odd prime bases: one digit per iteration, while the index has digits left."""
    UInt64 = dr.uint64_array_t(mi.UInt32)
    packed = dr.gather(UInt64, _tables()["packed"], base_index)
    m = mi.UInt32(packed >> 32)
    low = mi.UInt32(packed)
    s = (low >> 13) & 0xF
    b = low & 0x1FFF
    inv_b = 1.0 / _to_float(b)
    if randomization != "none":
        perm_offset = (low >> 17) * PERM_ALIGN
        perm_count = _permutation_count(b)

    def cond(a, v, w, z):
        return a > 0

    def body(a, v, w, z):
        q = dr.mul_hi(a, m) >> s
        d = a - q * b
        if randomization != "none":
            # The node's permutation d -> (c + T(d)) mod b: c is the top
            # base-b digit of the node's fraction z (so that the permuted
            # zero digits continue z) and T, with T(0) = 0, one of the
            # base's table permutations, chosen by a hash of z (for b <= 7
            # the table holds all of them: uniform over all b! permutations).
            c = dr.mul_hi(z, b)
            h = (z ^ (z >> 15)) * 0x2C9277B5
            t_ = dr.gather(mi.UInt32, _tables()["perms"],
                           perm_offset + dr.mul_hi(h, perm_count) * b + d) + c
            d_new = dr.select(t_ >= b, t_ - b, t_)
            if randomization == "owen":
                # Child node: digit 0 continues the fraction, other digits
                # start a fresh one (hash of the parent and the digit).
                x = (z ^ (d * 0x9E3779B1)) * 0x7FEB352D
                z = dr.select(d == 0, z * b, x ^ (x >> 15))
            else:
                z = z * b
            d = d_new
        v = dr.fma(_to_float(d), w, v)
        w = w * inv_b
        return q, v, w, z

    # The first digit unconditionally (for a = 0 it is a leading zero, whose
    # permutation continues the fraction z exactly as the tail below would),
    # so that the loop only runs for indices with two or more digits.
    state = body(a, mi.Float(0.0), inv_b, mi.UInt32(seed))
    _, v, w, z = dr.while_loop(
        state=state,
        cond=cond, body=body, labels=("a", "v", "w", "z"), label="radical_inverse_digits")
    if randomization != "none":
        # The index's leading zeros, permuted down to float precision: the
        # remaining base-b digits of the node fraction z.
        v = dr.fma(_to_unit_fast(z), w * _to_float(b), v)
    return dr.minimum(v, ONE_MINUS_EPSILON)


def halton_sample(dimension, index, seed, randomization: str = "owen"):
    """Component ``dimension`` of Halton point ``index`` (randomized by ``seed``).

    ``dimension``, ``index`` and ``seed`` are ``mi.UInt32`` arrays (or ints);
    ``seed`` is a per-sequence seed (e.g. per pixel), combined with the
    unwrapped dimension by :func:`dimension_seed`.
    """
    dimension = mi.UInt32(dimension)
    if randomization == "none":
        return scrambled_radical_inverse(dimension, index, 0, randomization)
    return scrambled_radical_inverse(dimension, index, dimension_seed(mi.UInt32(seed), dimension),
                                     randomization)
