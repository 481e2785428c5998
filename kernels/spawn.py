"""Spawning secondary rays without self-intersection: the one origin offset used everywhere.

A hit point is recomputed on its primitive's surface (``wrt.kernels.traverse.surface_point``),
so what separates it from the float32 surface is the rounding of that recomputation: a few ulps
of the point and of the primitive's own coordinates, not of where the ray came from. The origin
of a ray leaving the surface is pushed along the geometric normal, to the side the new ray goes,
by a bound on that error: ``SPAWN_ULPS * 2^-24 * (2 max|p| + extent)`` (``extent``: the largest
coordinate of the primitive's anchor, a vertex, centre plus radius or plane point), not a fixed
epsilon, so it holds at any scale, any distance from the world origin and any camera distance.
"""

import warp as wp

# error bound in float32 ulps (2^-24 relative) of the magnitudes that make up a surface point
SPAWN_ULPS = wp.constant(16.0)
FLOAT32_HALF_ULP = wp.constant(5.9604645e-08)


@wp.func
def max_abs(v: wp.vec3) -> float:
    return wp.max(wp.max(wp.abs(v[0]), wp.abs(v[1])), wp.abs(v[2]))


@wp.func
def point_error(p: wp.vec3, extent: float) -> float:
    """Bound on the distance of a recomputed surface point ``p`` from the float32 surface of a
    primitive whose coordinates are at most ``max|p| + extent`` in magnitude (``surface_point``)."""
    return SPAWN_ULPS * FLOAT32_HALF_ULP * (max_abs(p) + extent)


@wp.func
def ray_error(o: wp.vec3, p: wp.vec3, t: float) -> float:
    """Bound on the error of a hit's distance ``t`` along the unit ray from ``o`` (``p`` the hit):
    a ray that goes straight on through the surface (a false or index-matched interface) resumes
    past ``t + ray_error``, on its own line, so the margin is charged with the rounding of
    ``o + t d`` and of the intersection, not only of the surface point."""
    return SPAWN_ULPS * FLOAT32_HALF_ULP * (max_abs(o) + max_abs(p) + t)


@wp.func
def past_hit(o: wp.vec3, p: wp.vec3, t: float) -> float:
    """Where a ray from ``o`` that goes straight on through its hit ``p`` at distance ``t`` resumes
    (its new ``t_from``): ``t + ray_error``."""
    return t + ray_error(o, p, t)


@wp.func
def spawn_origin(p: wp.vec3, n: wp.vec3, err: float, w: wp.vec3) -> wp.vec3:
    """Origin for a ray leaving ``p`` in direction ``w``: offset by ``err`` along ``n`` toward ``w``'s side."""
    if wp.dot(w, n) < 0.0:
        return p - err * n
    return p + err * n
