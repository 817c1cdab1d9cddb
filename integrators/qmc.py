"""Quasi-Monte Carlo maths for the ``halton`` sampler: primes, radical inverses
and their randomizations, as vectorised Dr.Jit code.

Everything here is plain Dr.Jit arithmetic on ``mi.UInt32`` / ``mi.Float``
arrays and works inside symbolic loops (``@dr.syntax`` / ``dr.while_loop``):
the dimension, the sample index and the scramble seed may all be Dr.Jit
arrays whose values change from one loop iteration to the next. The only
Python-side decision is the randomization (a string), which selects the code
that is traced.

Radical inverse of index ``a`` in base ``b``: with ``a = sum_k d_k b^k``,
:math:`\\Phi_b(a) = \\sum_k d_k b^{-k-1}`. Base 2 uses a bit reversal
(``dr.brev``). Other bases peel off one digit per iteration of a Dr.Jit loop;
the division by ``b`` is a multiplication by a 32-bit reciprocal
(``dr.mul_hi`` and a shift, exact for indices below 2^31), so no integer
division is ever executed.

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
per pixel) instead of stored tables. Digit permutations are random affine maps
``d -> (A d + c) mod b`` (permutations since ``b`` is prime). Each tree node
(``permute_digits``: each digit position; ``owen``: each prefix of digits)
carries a 32-bit fixed-point fraction ``z``: ``c`` is the top base-``b``
digit of ``z`` and ``A`` is hashed from it; the child reached by digit 0
takes the fraction ``z * b mod 2^32`` (the remaining digits of ``z``), any
other digit a fresh hash. The permuted leading zeros of an index that has run
out of digits are then exactly the remaining digits of ``z``, added in one
step, so the loop only runs over the index's own digits (about
``log_b(spp)``), and the result is the same as scrambling all digits down to
precision ``2^-32``. Every point is uniform on [0, 1) and the first ``b^m``
indices keep their stratification into ``b^m`` intervals. Base 2: the
permutations are bit flips, an XOR with a random 32-bit mask
(``permute_digits``), and pbrt's ``FastOwenScrambler`` (``owen``).

Dimensions map to primes: dimension ``j`` uses ``PRIMES[j % PRIME_TABLE_SIZE]``
(the table holds the first 1000 primes, 2 .. 7919). Past the table the bases
wrap around, as in pbrt; the scrambled variants still differ between
dimension ``j`` and ``j + 1000`` because their seed hashes the unwrapped
dimension, while ``none`` repeats exactly. All outputs lie in [0, 1), clamped
to ``1 - 2^-24`` at most.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

#: Valid randomizations (pbrt-v4's ``RandomizeStrategy``).
RANDOMIZATIONS = ("none", "permute_digits", "owen")

#: Number of primes in :data:`PRIMES`; dimension ``j`` uses ``PRIMES[j % PRIME_TABLE_SIZE]``.
PRIME_TABLE_SIZE = 1000

#: Largest index for which the radical inverses are exact (``dr.mul_hi`` reciprocals).
MAX_INDEX = 2**31 - 1

#: Largest float32 below 1 (``0x1.fffffep-1``).
ONE_MINUS_EPSILON = float(np.float32(1.0) - np.float32(2.0**-24))


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


def _build_tables():
    primes = [int(p) for p in PRIMES]
    magic = [division_magic(p) for p in primes]
    return {
        "base": np.array(primes, dtype=np.uint32),
        "magic": np.array([m for m, _ in magic], dtype=np.uint32),
        "shift": np.array([s for _, s in magic], dtype=np.uint32),
        "inv_base": np.array([1.0 / p for p in primes], dtype=np.float32),
    }


_NP_TABLES = _build_tables()
_JIT_TABLES: dict = {}


def _tables():
    """The per-base tables as Dr.Jit arrays of the current variant (cached)."""
    key = (mi.variant(), mi.UInt32)
    tables = _JIT_TABLES.get(key)
    if tables is None:
        tables = {name: (mi.Float if arr.dtype == np.float32 else mi.UInt32)(arr)
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
    return mix32(seed + dimension * 0x9E3779B9)


def _fast_owen_base2(v, seed):
    """pbrt-v4's ``FastOwenScrambler`` on reversed bits ``v`` (input and output reversed)."""
    v = dr.brev(v)
    v ^= v * 0x3D20ADEA
    v += seed
    v *= (seed >> 16) | 1
    v ^= v * 0x05526C56
    v ^= v * 0x53A22864
    return dr.brev(v)


def _to_unit(v):
    """UInt32 fixed point (``v / 2^32``) to a float in [0, 1)."""
    return dr.minimum(mi.Float(v) * (2.0**-32), ONE_MINUS_EPSILON)


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
    t = _tables()
    base_index = mi.UInt32(base_index) % PRIME_TABLE_SIZE
    a = mi.UInt32(a)
    seed = mi.UInt32(seed)

    b = dr.gather(mi.UInt32, t["base"], base_index)
    m = dr.gather(mi.UInt32, t["magic"], base_index)
    s = dr.gather(mi.UInt32, t["shift"], base_index)
    inv_b = dr.gather(mi.Float, t["inv_base"], base_index)
    is_base2 = b == 2

    # ---- base 2: bit reversal
    rev = dr.brev(a)
    if randomization == "permute_digits":
        rev ^= seed
    elif randomization == "owen":
        rev = _fast_owen_base2(rev, seed)
    value2 = _to_unit(rev)

    # ---- other bases: one digit per iteration, while the index has digits left
    n = dr.select(is_base2, mi.UInt32(0), mi.UInt32(0xFFFFFFFF))
    bm1 = b - 1

    def cond(a, k, v, w, z):
        return (k < n) & (a > 0)

    def body(a, k, v, w, z):
        q = dr.mul_hi(a, m) >> s
        d = a - q * b
        if randomization != "none":
            # Affine permutation d -> (A d + c) mod b of this node, with
            # c = the top base-b digit of the node's fraction z (so that the
            # permuted zero digits continue z) and A in [1, b) from z.
            c = dr.mul_hi(z, b)
            g = 1 + dr.mul_hi(z * 0x2C9277B5, bm1)
            t_ = g * d + c                           # < b^2 < 2^31
            d_new = t_ - (dr.mul_hi(t_, m) >> s) * b
            if randomization == "owen":
                # Child node: digit 0 continues the fraction, other digits
                # start a fresh one (hash of the parent and the digit).
                x = (z ^ (d * 0x9E3779B1)) * 0x7FEB352D
                z = dr.select(d == 0, z * b, x ^ (x >> 15))
            else:
                z = z * b
            d = d_new
        v = dr.fma(mi.Float(d), w, v)
        w = w * inv_b
        return q, k + 1, v, w, z

    z0 = seed
    _, _, v, w, z = dr.while_loop(
        state=(a, mi.UInt32(0), mi.Float(0.0), inv_b, mi.UInt32(z0)),
        cond=cond, body=body, labels=("a", "k", "v", "w", "z"), label="radical_inverse")
    if randomization != "none":
        # The index's leading zeros, permuted down to float precision: the
        # remaining base-b digits of the node fraction z.
        v = dr.fma(mi.Float(z) * (2.0**-32), w * mi.Float(b), v)
    value = dr.minimum(v, ONE_MINUS_EPSILON)
    return dr.select(is_base2, value2, value)


def halton_sample(dimension, index, seed, randomization: str = "owen"):
    """Component ``dimension`` of Halton point ``index`` (randomized by ``seed``).

    ``dimension``, ``index`` and ``seed`` are ``mi.UInt32`` arrays (or ints);
    ``seed`` is a per-sequence seed (e.g. per pixel), combined with the
    unwrapped dimension by :func:`dimension_seed`.
    """
    dimension = mi.UInt32(dimension)
    return scrambled_radical_inverse(dimension, index, dimension_seed(mi.UInt32(seed), dimension),
                                     randomization)
