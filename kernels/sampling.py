"""Counter-based random numbers: each value is a pure function of (seed, pixel, sample, dimension).

No state is carried between threads or launches, so an image is bit-identical whatever the
tiling, launch order or thread count.

References
----------
M. Jarzynski and M. Olano, "Hash Functions for GPU Rendering", JCGT 9(3), 2020 (the PCG hash).
"""
import warp as wp

PCG_MULTIPLIER = wp.constant(wp.uint32(747796405))
PCG_INCREMENT = wp.constant(wp.uint32(2891336453))
PCG_MIX = wp.constant(wp.uint32(277803737))


@wp.func
def pcg_hash(x: wp.uint32) -> wp.uint32:
    """One round of the PCG permutation of a 32-bit integer (Jarzynski & Olano 2020)."""
    state = x * PCG_MULTIPLIER + PCG_INCREMENT
    word = ((state >> ((state >> wp.uint32(28)) + wp.uint32(4))) ^ state) * PCG_MIX
    return (word >> wp.uint32(22)) ^ word


@wp.func
def sample_1d(seed: wp.int32, pixel: wp.int32, sample: wp.int32, dim: wp.int32) -> float:
    """A uniform number in [0, 1) for the given seed, pixel index, sample index and dimension.

    The four counters are chained through the hash, so changing any one of them gives an
    independent-looking value. The result has 24 random bits (exact in float32).
    """
    h = pcg_hash(wp.uint32(dim))
    h = pcg_hash(h ^ wp.uint32(sample))
    h = pcg_hash(h ^ wp.uint32(pixel))
    h = pcg_hash(h ^ wp.uint32(seed))
    return float(h >> wp.uint32(8)) * 5.9604645e-08
