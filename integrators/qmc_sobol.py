"""Quasi-Monte Carlo maths for the ``zsobol`` sampler: the 2-D Sobol' (0,2)-sequence in
Morton order across pixels and its randomizations, as vectorised Dr.Jit code (the hashing
and the Halton sequences are :mod:`.qmc`'s).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import qmc

# The ``zsobol`` sampler (Ahmed and Wonka 2020; pbrt-v4's ``ZSobolSampler``):
# sample ``i`` of pixel ``p`` is point ``P_d(morton(p) * L + i)`` of the 2-D
# Sobol' (0,2)-sequence, ``L`` the (power-of-two) length of every pixel's
# sequence and ``P_d`` a nested permutation of the index per dimension pair
# ``d``. The 32 index bits, from the top: the Morton digits of the pixel (two
# bits each, y above x), then ``log2 L`` bits of the sample. The permutation
# works on the bit-reversed index, where "the digits above" become "the bits
# below" and a few multiplications hash them for every digit at once: no loop
# over the digits, no table.

#: Bits of a zsobol index (Morton index of the pixel and sample in its sequence).
ZSOBOL_INDEX_BITS = 32

#: Constants that separate the scramble seeds drawn from one dimension seed.
_SEED_X, _SEED_Y, _SEED_PAIRING = 0x68E31DA4, 0xB5297A4D, 0x1B56C4E9


def morton_encode(x, y):
    """Morton (Z-order) index of pixel ``(x, y)`` (``mi.UInt32``, each < 2^16):
    the bits of ``y`` and ``x`` interleaved, y above x (pbrt's ``EncodeMorton2``)."""
    def spread(v):
        v = v & 0x0000FFFF
        v = (v | (v << 8)) & 0x00FF00FF
        v = (v | (v << 4)) & 0x0F0F0F0F
        v = (v | (v << 2)) & 0x33333333
        return (v | (v << 1)) & 0x55555555
    return (spread(y) << 1) | spread(x)


def sobol_pascal(index):
    """The second Sobol' generator matrix (the binary Pascal matrix) applied to
    ``index``, bit-reversed: bit ``k`` of the result is digit ``k + 1`` of the
    coordinate, the XOR of the index bits ``j`` with ``j & k == k`` (Lucas:
    ``binom(j, k)`` odd). The matrix is the Kronecker power of ``[[1, 1],
    [0, 1]]``, so five shift-and-XOR steps replace the 32-column product."""
    v = index ^ ((index >> 1) & 0x55555555)
    v = v ^ ((v >> 2) & 0x33333333)
    v = v ^ ((v >> 4) & 0x0F0F0F0F)
    v = v ^ ((v >> 8) & 0x00FF00FF)
    return v ^ (v >> 16)


def sobol_2d(index):
    """Point ``index`` of the unscrambled 2-D Sobol' sequence, as 32-bit fixed
    point ``(x, y)`` (``value / 2^32``): ``x`` the van der Corput radical
    inverse (the bit reversal of the index), ``y`` the Pascal matrix's."""
    return dr.brev(index), dr.brev(sobol_pascal(index))


def morton_x_mask(log2_length: int) -> int:
    """The x bits of the Morton digits of a bit-reversed zsobol index whose
    lowest ``log2_length`` bits are the sample's (a digit whose y bit would
    fall beyond bit 31 is left out)."""
    if not 0 <= log2_length < ZSOBOL_INDEX_BITS:
        raise ValueError(f"qmc: log2 of the sequence length must lie in [0, 32), got "
                         f"{log2_length}")
    return (0xAAAAAAAA >> log2_length) & 0xFFFFFFFE


def zsobol_permute_index(index, seed, x_mask):
    """The nested permutation of a zsobol index (``mi.UInt32`` arrays), per ``seed``.

    Each Morton digit (the quad of pixels it selects) goes through a
    permutation of its four values that depends only on the digits above it,
    so every aligned ``2^k x 2^k`` block of pixels keeps an aligned block of
    ``4^k L`` indices and neighbouring pixels keep complementary parts of one
    (0,2)-net. The permutation is one of the 24 of the quad, in two steps:
    an invertible linear map of the digit's bits (y, x) over GF(2), which
    chooses the pairing of the quad's pixels into the two halves of its
    block (horizontal pairs with probability 1/4, vertical 1/4, diagonal
    1/2: symmetric under transposition), then the nested bit flips of
    :func:`qmc.laine_karras` (which pixel of a pair, and which pair, go first).
    The sample bits (``x_mask`` leaves them out) get only the flips, so the
    first ``2^j`` samples of a pixel (and every aligned run of ``2^j``)
    still form an aligned block of the sequence: a (0, j, 2)-net. The
    pairing choice of every digit comes from one hash of the digits above
    it; no loop runs over the digits.
    """
    r = dr.brev(index)                               # digits above = bits below
    g = qmc.laine_karras(r << 2, seed ^ _SEED_PAIRING)   # per digit: bits of the digits above
    swap = g & x_mask                                # the x bit of each digit ...
    shear = (g << 1) & x_mask                        # ... and the y bit, at the x position
    t = (r ^ (r << 1)) & swap                        # (x ^ y) where swapped
    r = r ^ t ^ (t >> 1)                             # swap x and y
    r = r ^ ((r & shear) >> 1)                       # y ^= x
    return dr.brev(qmc.laine_karras(r, seed))


def zsobol_seeds(seed, dimension, randomization: str):
    """Scramble seeds ``(index, x, y)`` of the pair drawn at ``dimension``.

    From a hash of the sampler's seed and the dimension; ``none`` ignores the
    seed (the index permutation then depends on the dimension only and the
    sequence is deterministic, as in pbrt).
    """
    if randomization == "none":
        seed = 0
    h = qmc.dimension_seed(mi.UInt32(seed), dimension)
    return h, qmc.mix32(h ^ _SEED_X), qmc.mix32(h ^ _SEED_Y)


def zsobol_sample(index, dimension, seed, x_mask, randomization: str = "owen",
                  components: int = 2):
    """Coordinates of zsobol index ``index`` in the pair drawn at ``dimension``.

    ``index``, ``dimension``, ``seed`` and ``x_mask`` (from
    :func:`morton_x_mask`) are ``mi.UInt32`` arrays (or ints). Returns
    ``components`` (1 or 2) ``mi.Float`` values in [0, 1): Sobol' dimension
    0 (van der Corput) and 1 of the permuted index, randomized as chosen:
    ``none`` (plain), ``permute_digits`` (a random digital shift: an XOR of
    32 random bits, per coordinate) or ``owen`` (:func:`qmc.laine_karras` on the
    reversed coordinate, pbrt's ``FastOwenScrambler``).
    """
    if randomization not in qmc.RANDOMIZATIONS:
        raise ValueError(f"qmc: unknown randomization {randomization!r}; "
                         f"valid choices are {', '.join(qmc.RANDOMIZATIONS)}")
    s_index, s_x, s_y = zsobol_seeds(seed, dimension, randomization)
    i = zsobol_permute_index(mi.UInt32(index), s_index, x_mask)
    # Reversed coordinates (bit 0 = the most significant digit): x's is the
    # index itself, y's the Pascal product.
    coords = [(i, s_x), (sobol_pascal(i), s_y)][:components]
    out = []
    for rev, s in coords:
        if randomization == "owen":
            v = dr.brev(qmc.laine_karras(rev, s))
        elif randomization == "permute_digits":
            v = dr.brev(rev) ^ s
        else:
            v = dr.brev(rev)
        out.append(qmc._to_unit_fast(v))
    return out
