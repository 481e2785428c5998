"""Samplers: each random number is a pure function of (seed, pixel, sample, dimension).

No state is carried between threads or launches, so an image is bit-identical whatever the
tiling, launch order or thread count, and a progressive render (several launches, each a range of
sample indices) equals a one-pass render. Three samplers (``[render] sampler``), all unbiased:
every sample, taken alone, is uniformly distributed.

- ``independent``: a counter-based hash of the four counters (PCG, Jarzynski and Olano 2020).
- ``stratified``: for each dimension (1D) or pair of dimensions (2D) the render's ``spp`` samples
  of a pixel fall one in each stratum: ``spp`` intervals in 1D, a ``strata_x`` x ``strata_y`` grid
  in 2D (the factorisation of ``spp`` nearest to a square; a prime ``spp`` gives 1 x spp), jittered
  inside; which sample takes which stratum is a hash-keyed permutation (Kensler 2013) per pixel and
  dimension, so dimensions are not correlated with one another (pbrt-v4's StratifiedSampler).
- ``sobol``: the first two dimensions of the Sobol sequence, a (0, 2)-sequence in base 2, for each
  pair of dimensions, Owen-scrambled (nested uniform scrambling by the Laine-Karras hash) and
  shuffled by scrambling the sample index, with a hash of (seed, pixel, dimension) as the key
  (Burley 2020); any power of two of consecutive samples is a stratified (0, m, 2)-net.

A 1D request of the stratified and Sobol samplers uses the first coordinate of its pair.

References
----------
M. Jarzynski and M. Olano, "Hash Functions for GPU Rendering", JCGT 9(3), 2020.
A. Kensler, "Correlated Multi-Jittered Sampling", Pixar technical memo 13-01, 2013.
B. Burley, "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020.
"""

import warp as wp

INDEPENDENT = wp.constant(0)
STRATIFIED = wp.constant(1)
SOBOL = wp.constant(2)

PCG_MULTIPLIER = wp.constant(wp.uint32(747796405))
PCG_INCREMENT = wp.constant(wp.uint32(2891336453))
PCG_MIX = wp.constant(wp.uint32(277803737))
TO_UNIT = wp.constant(5.9604645e-08)  # 2^-24: the top 24 bits of a uint32 as a float in [0, 1)
ONE_MINUS_EPSILON = wp.constant(0.99999994)  # the largest float32 below 1
# 32-bit constants of the hashes below, as typed module constants: a literal of 2^31 or more
# written inside a Warp function is emitted as a (wrapping) int32, which compilers warn about
KENSLER_1 = wp.constant(wp.uint32(0xE170893D))
KENSLER_5 = wp.constant(wp.uint32(0x9E501CC3))
KENSLER_6 = wp.constant(wp.uint32(0xC860A3DF))
LAINE_KARRAS_2 = wp.constant(wp.uint32(0xB82F1E52))
LAINE_KARRAS_3 = wp.constant(wp.uint32(0xC7AFE638))
LAINE_KARRAS_4 = wp.constant(wp.uint32(0x8D22F6E6))
TOP_BIT = wp.constant(wp.uint32(0x80000000))


@wp.struct
class Sampler:
    """The render's sampler: its kind, its seed and the sample count strata are made for."""

    kind: wp.int32  # INDEPENDENT, STRATIFIED or SOBOL
    seed: wp.int32
    spp: wp.int32  # samples per pixel of the whole render (all passes)
    strata_x: wp.int32  # stratified 2D grid: strata_x * strata_y == spp


@wp.func
def pcg_hash(x: wp.uint32) -> wp.uint32:
    """One round of the PCG permutation of a 32-bit integer (Jarzynski & Olano 2020)."""
    state = x * PCG_MULTIPLIER + PCG_INCREMENT
    word = ((state >> ((state >> wp.uint32(28)) + wp.uint32(4))) ^ state) * PCG_MIX
    return (word >> wp.uint32(22)) ^ word


@wp.func
def hash_counters(seed: wp.int32, pixel: wp.int32, sample: wp.int32, dim: wp.int32) -> wp.uint32:
    """32 random bits chained from the four counters: changing any one gives independent bits."""
    h = pcg_hash(wp.uint32(dim))
    h = pcg_hash(h ^ wp.uint32(sample))
    h = pcg_hash(h ^ wp.uint32(pixel))
    return pcg_hash(h ^ wp.uint32(seed))


@wp.func
def to_unit(bits: wp.uint32) -> float:
    """The top 24 bits as a float in [0, 1) (exact in float32)."""
    return float(bits >> wp.uint32(8)) * TO_UNIT


@wp.func
def independent_1d(seed: wp.int32, pixel: wp.int32, sample: wp.int32, dim: wp.int32) -> float:
    """A uniform number in [0, 1) from the counters alone (the ``independent`` sampler)."""
    return to_unit(hash_counters(seed, pixel, sample, dim))


@wp.func
def permutation_element(i: wp.uint32, n: wp.uint32, key: wp.uint32) -> wp.uint32:
    """Element ``i`` of a pseudo-random permutation of ``0 .. n-1`` chosen by ``key`` (Kensler 2013)."""
    w = n - wp.uint32(1)
    w = w | (w >> wp.uint32(1))
    w = w | (w >> wp.uint32(2))
    w = w | (w >> wp.uint32(4))
    w = w | (w >> wp.uint32(8))
    w = w | (w >> wp.uint32(16))
    while True:
        i = i ^ key
        i = i * KENSLER_1
        i = i ^ (key >> wp.uint32(16))
        i = i ^ ((i & w) >> wp.uint32(4))
        i = i ^ (key >> wp.uint32(8))
        i = i * wp.uint32(0x0929EB3F)
        i = i ^ (key >> wp.uint32(23))
        i = i ^ ((i & w) >> wp.uint32(1))
        i = i * (wp.uint32(1) | (key >> wp.uint32(27)))
        i = i * wp.uint32(0x6935FA69)
        i = i ^ ((i & w) >> wp.uint32(11))
        i = i * wp.uint32(0x74DCB303)
        i = i ^ ((i & w) >> wp.uint32(2))
        i = i * KENSLER_5
        i = i ^ ((i & w) >> wp.uint32(2))
        i = i * KENSLER_6
        i = i & w
        i = i ^ (i >> wp.uint32(5))
        if i < n:
            break
    return (i + key) % n


@wp.func
def reverse_bits(x: wp.uint32) -> wp.uint32:
    x = ((x >> wp.uint32(1)) & wp.uint32(0x55555555)) | ((x & wp.uint32(0x55555555)) << wp.uint32(1))
    x = ((x >> wp.uint32(2)) & wp.uint32(0x33333333)) | ((x & wp.uint32(0x33333333)) << wp.uint32(2))
    x = ((x >> wp.uint32(4)) & wp.uint32(0x0F0F0F0F)) | ((x & wp.uint32(0x0F0F0F0F)) << wp.uint32(4))
    x = ((x >> wp.uint32(8)) & wp.uint32(0x00FF00FF)) | ((x & wp.uint32(0x00FF00FF)) << wp.uint32(8))
    return (x >> wp.uint32(16)) | (x << wp.uint32(16))


@wp.func
def owen_scramble(x: wp.uint32, key: wp.uint32) -> wp.uint32:
    """Nested uniform (Owen) scrambling in base 2: bit k of ``x`` flips by a hash of ``key`` and the
    bits above it (the Laine-Karras permutation on the reversed bits, Burley's constants)."""
    x = reverse_bits(x)
    x = x + key
    x = x ^ (x * wp.uint32(0x6C50B47C))
    x = x ^ (x * LAINE_KARRAS_2)
    x = x ^ (x * LAINE_KARRAS_3)
    x = x ^ (x * LAINE_KARRAS_4)
    return reverse_bits(x)


@wp.func
def sobol_second(i: wp.uint32) -> wp.uint32:
    """The second Sobol dimension (primitive polynomial x + 1) of index ``i``, as 32 bits."""
    v = TOP_BIT
    x = wp.uint32(0)
    while i != wp.uint32(0):
        if (i & wp.uint32(1)) != wp.uint32(0):
            x = x ^ v
        v = v ^ (v >> wp.uint32(1))
        i = i >> wp.uint32(1)
    return x


@wp.func
def sample_2d(sampler: Sampler, pixel: wp.int32, sample: wp.int32, dim: wp.int32) -> wp.vec2:
    """A uniform point of [0, 1)^2 for the pixel, the sample and the dimensions ``dim, dim + 1``."""
    if sampler.kind == INDEPENDENT:
        return wp.vec2(
            independent_1d(sampler.seed, pixel, sample, dim), independent_1d(sampler.seed, pixel, sample, dim + 1)
        )
    key = hash_counters(sampler.seed, pixel, -1, dim)
    if sampler.kind == STRATIFIED:
        stratum = wp.int32(permutation_element(wp.uint32(sample), wp.uint32(sampler.spp), key))
        strata_y = sampler.spp / sampler.strata_x
        jitter_x = independent_1d(sampler.seed, pixel, sample, dim)
        jitter_y = independent_1d(sampler.seed, pixel, sample, dim + 1)
        return wp.vec2(
            wp.min((float(stratum % sampler.strata_x) + jitter_x) / float(sampler.strata_x), ONE_MINUS_EPSILON),
            wp.min((float(stratum / sampler.strata_x) + jitter_y) / float(strata_y), ONE_MINUS_EPSILON),
        )
    index = owen_scramble(wp.uint32(sample), key)
    x = owen_scramble(reverse_bits(index), pcg_hash(key ^ wp.uint32(1)))
    y = owen_scramble(sobol_second(index), pcg_hash(key ^ wp.uint32(2)))
    return wp.vec2(to_unit(x), to_unit(y))


@wp.func
def sample_1d(sampler: Sampler, pixel: wp.int32, sample: wp.int32, dim: wp.int32) -> float:
    """A uniform number in [0, 1) for the pixel, the sample and dimension ``dim``."""
    if sampler.kind == INDEPENDENT:
        return independent_1d(sampler.seed, pixel, sample, dim)
    if sampler.kind == STRATIFIED:
        key = hash_counters(sampler.seed, pixel, -1, dim)
        stratum = permutation_element(wp.uint32(sample), wp.uint32(sampler.spp), key)
        return wp.min(
            (float(stratum) + independent_1d(sampler.seed, pixel, sample, dim)) / float(sampler.spp), ONE_MINUS_EPSILON
        )
    return sample_2d(sampler, pixel, sample, dim)[0]
