"""Spawning secondary rays without self-intersection: the one origin offset used everywhere.

A hit point computed in float32 is off the true surface by rounding in the ray origin, the
intersection's ``t`` and ``o + t d``: at most a few ulps of the magnitudes involved. The origin of
a ray leaving the surface is pushed along the geometric normal, to the side the new ray goes,
by a bound on that error: ``SPAWN_ULPS * 2^-24 * (max|o| + max|p| + t)``, not a fixed epsilon, so
it holds at any scale and distance from the world origin.
"""

import warp as wp

# error bound in float32 ulps (2^-24 relative) of the magnitudes that make up a hit point
SPAWN_ULPS = wp.constant(16.0)
FLOAT32_HALF_ULP = wp.constant(5.9604645e-08)


@wp.func
def max_abs(v: wp.vec3) -> float:
    return wp.max(wp.max(wp.abs(v[0]), wp.abs(v[1])), wp.abs(v[2]))


@wp.func
def hit_error(o: wp.vec3, p: wp.vec3, t: float) -> float:
    """Bound on the distance of the computed hit ``p = o + t d`` (unit ``d``) from the true surface."""
    return SPAWN_ULPS * FLOAT32_HALF_ULP * (max_abs(o) + max_abs(p) + t)


@wp.func
def spawn_origin(p: wp.vec3, n: wp.vec3, err: float, w: wp.vec3) -> wp.vec3:
    """Origin for a ray leaving ``p`` in direction ``w``: offset by ``err`` along ``n`` toward ``w``'s side."""
    if wp.dot(w, n) < 0.0:
        return p - err * n
    return p + err * n
