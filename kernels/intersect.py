"""Ray-primitive intersection tests, one ``@wp.func`` per primitive (world space, float32).

Every test takes a ray ``o + t d`` (``d`` need not be unit length; ``t`` is then measured in
units of ``|d|``) and an open interval ``(t_min, t_max)``, and returns the parameter ``t`` of the
nearest intersection inside it, or ``t_max`` itself when there is none. A closest-hit loop
therefore reads ``t = intersect_x(..., t_min, t_max); if t < t_max: t_max = t``.
Hits with ``t <= t_min`` (behind the eye, or the surface a ray leaves) are rejected.

References
----------
E. Haines, J. Guenther, T. Akenine-Moller, "Precision Improvements for Ray/Sphere
Intersection", Ray Tracing Gems, ch. 7, 2019.
T. Moller, B. Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection", JGT 2(1), 1997
(Cramer's rule for the barycentric system, as in the ray-casting lecture).
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 6.1.2 (conservative slab test).
"""
import warp as wp

# 1 + 2 gamma(3) for float32: widens a slab interval so rounding never culls a box a ray touches.
SLAB_WIDEN = wp.constant(1.0 + 2.0 * 3.0 * 5.9604645e-08 / (1.0 - 3.0 * 5.9604645e-08))
# Stand-in for 1/0 in the slab test: large but finite, so (lo - o) * inv_d is never 0 * inf = NaN.
INV_ZERO = wp.constant(1.0e30)


@wp.func
def intersect_plane(o: wp.vec3, d: wp.vec3, point: wp.vec3, normal: wp.vec3, t_min: float, t_max: float) -> float:
    """Plane through ``point`` with normal ``normal`` (any length); both sides are hit.

    Solves ``dot(normal, o + t d - point) = 0``; a ray parallel to the plane misses.
    """
    denom = wp.dot(normal, d)
    if denom == 0.0:
        return t_max
    t = wp.dot(normal, point - o) / denom
    if t > t_min and t < t_max:
        return t
    return t_max


@wp.func
def intersect_sphere(o: wp.vec3, d: wp.vec3, center: wp.vec3, radius: float, t_min: float, t_max: float) -> float:
    """Sphere of ``radius`` around ``center``, from outside or inside.

    Cancellation-free form (Ray Tracing Gems ch. 7): the discriminant is computed as
    ``a (r^2 - |f - (beta/a) d|^2)`` with ``f = o - center``, ``beta = dot(f, d)``, which stays
    accurate for rays from far away, and the two roots come from ``q = -beta - sign(beta) sqrt(disc)``
    as ``c/q`` and ``q/a``, avoiding the subtraction of nearly equal numbers.
    """
    f = o - center
    a = wp.dot(d, d)
    beta = wp.dot(f, d)
    g = f - (beta / a) * d
    disc = a * (radius * radius - wp.dot(g, g))
    if disc < 0.0:
        return t_max
    root = wp.sqrt(disc)
    q = -beta - root
    if beta < 0.0:
        q = -beta + root
    if q == 0.0:
        return t_max
    c = wp.dot(f, f) - radius * radius
    t0 = c / q
    t1 = q / a
    t_near = wp.min(t0, t1)
    t_far = wp.max(t0, t1)
    if t_near > t_min and t_near < t_max:
        return t_near
    if t_far > t_min and t_far < t_max:
        return t_far
    return t_max


@wp.func
def intersect_triangle(o: wp.vec3, d: wp.vec3, v0: wp.vec3, v1: wp.vec3, v2: wp.vec3, t_min: float, t_max: float) -> float:
    """Triangle (v0, v1, v2), both sides, by Cramer's rule on ``o + t d = v0 + b1 e1 + b2 e2``.

    The barycentric coordinates ``b1, b2`` and ``t`` are ratios of scalar triple products (the
    lecture's determinants in Moller-Trumbore form). Robustness: a zero determinant (ray in the
    triangle's plane, or a zero-area triangle) is an exact miss, with no scale-dependent
    epsilon; edges are inclusive so a ray through a shared edge hits at least one side.
    """
    e1 = v1 - v0
    e2 = v2 - v0
    pvec = wp.cross(d, e2)
    det = wp.dot(e1, pvec)
    if det == 0.0:
        return t_max
    inv_det = 1.0 / det
    s = o - v0
    b1 = wp.dot(s, pvec) * inv_det
    if b1 < 0.0 or b1 > 1.0:
        return t_max
    qvec = wp.cross(s, e1)
    b2 = wp.dot(d, qvec) * inv_det
    if b2 < 0.0 or b1 + b2 > 1.0:
        return t_max
    t = wp.dot(e2, qvec) * inv_det
    if t > t_min and t < t_max:
        return t
    return t_max


@wp.func
def point_in_polygon(uv: wp.array(dtype=wp.vec2), start: wp.int32, count: wp.int32, p: wp.vec2) -> bool:
    """Even-odd crossing test of 2D point ``p`` against the polygon ``uv[start:start+count]``.

    Casts a ray from ``p`` along +u and counts the edges it crosses (half-open in v, so a vertex
    on the ray is counted once). Works for convex and non-convex polygons.
    """
    inside = bool(False)
    j = int(start + count - 1)
    for i in range(start, start + count):
        a = uv[i]
        b = uv[j]
        if (a[1] > p[1]) != (b[1] > p[1]):
            u_cross = a[0] + (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1])
            if p[0] < u_cross:
                inside = not inside
        j = i
    return inside


@wp.func
def intersect_polygon(
    o: wp.vec3,
    d: wp.vec3,
    normal: wp.vec3,
    offset: float,
    axis: wp.int32,
    uv: wp.array(dtype=wp.vec2),
    start: wp.int32,
    count: wp.int32,
    t_min: float,
    t_max: float,
) -> float:
    """Planar polygon ``dot(normal, x) = offset``: plane hit, then the 2D point-in-polygon test.

    The polygon's vertices are stored projected along the dominant axis ``axis`` of its normal
    (dropping that coordinate keeps the projection well conditioned): ``uv`` holds the two
    remaining coordinates in x, y, z order.
    """
    denom = wp.dot(normal, d)
    if denom == 0.0:
        return t_max
    t = (offset - wp.dot(normal, o)) / denom
    if t <= t_min or t >= t_max:
        return t_max
    p = o + t * d
    p2 = wp.vec2(p[1], p[2])
    if axis == 1:
        p2 = wp.vec2(p[0], p[2])
    elif axis == 2:
        p2 = wp.vec2(p[0], p[1])
    if point_in_polygon(uv, start, count, p2):
        return t
    return t_max


@wp.func
def safe_inverse(d: wp.vec3) -> wp.vec3:
    """Componentwise 1/d for the slab test, with zero components (either sign) mapped to ``INV_ZERO``.

    The sign does not matter there: a ray that does not move along an axis gets slab distances of
    opposite signs when it starts inside the slab and of equal signs when outside.
    """
    inv = wp.vec3(INV_ZERO, INV_ZERO, INV_ZERO)
    for k in range(3):
        if d[k] != 0.0:
            inv[k] = 1.0 / d[k]
    return inv


@wp.func
def intersect_box(o: wp.vec3, inv_d: wp.vec3, lo: wp.vec3, hi: wp.vec3, t_max: float) -> float:
    """Entry distance of the ray into the box [lo, hi] (clamped to >= 0), or ``t_max`` if it misses.

    Slab test with the far distance widened by ``SLAB_WIDEN`` (pbrt-v4) so a box is never culled
    by rounding; ``inv_d`` comes from ``safe_inverse`` so no 0 * inf NaN can arise. A box the ray
    enters exactly at ``t_max`` counts as missed.
    """
    t0 = wp.cw_mul(lo - o, inv_d)
    t1 = wp.cw_mul(hi - o, inv_d)
    t_near = wp.max(wp.max(wp.min(t0[0], t1[0]), wp.min(t0[1], t1[1])), wp.max(wp.min(t0[2], t1[2]), 0.0))
    t_far = wp.min(wp.min(wp.max(t0[0], t1[0]), wp.max(t0[1], t1[1])), wp.max(t0[2], t1[2])) * SLAB_WIDEN
    if t_near <= t_far and t_near < t_max:
        return t_near
    return t_max
