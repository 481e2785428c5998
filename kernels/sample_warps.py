"""Sample warps: uniform numbers in [0, 1)^2 to directions and points, with their densities.

Directions are unit vectors; densities are per steradian (solid angle) or per unit area.
``frame`` builds an orthonormal basis around a unit normal for local <-> world changes.

References
----------
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. A.5 (warps); T. Duff et al., "Building an
Orthonormal Basis, Revisited", JCGT 6(1), 2017.
"""

import warp as wp


@wp.func
def frame(n: wp.vec3) -> wp.mat33:
    """Columns (s, t, n): an orthonormal basis with ``n`` as the third axis (Duff et al. 2017)."""
    sign = 1.0
    if n[2] < 0.0:
        sign = -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    s = wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    t = wp.vec3(b, sign + n[1] * n[1] * a, -n[1])
    return wp.matrix_from_cols(s, t, n)


@wp.func
def shading_frame(n: wp.vec3, tangent: wp.vec3) -> wp.mat33:
    """Columns (s, t, n) with ``s = tangent`` (a unit vector perpendicular to ``n``: the hit's
    ``Hit.tangent``) and ``t = n x s``, Mitsuba 3's ``sh_frame``; ``frame(n)`` where ``tangent`` is
    zero (a scene without anisotropic materials computes none)."""
    if wp.length_sq(tangent) > 0.0:
        return wp.matrix_from_cols(tangent, wp.cross(n, tangent), n)
    return frame(n)


@wp.func
def cosine_hemisphere(u1: float, u2: float) -> wp.vec3:
    """Local direction (z up) with density cos(theta) / pi, by Malley's method on a concentric disk."""
    d = concentric_disk(u1, u2)
    return wp.vec3(d[0], d[1], wp.sqrt(wp.max(0.0, 1.0 - d[0] * d[0] - d[1] * d[1])))


@wp.func
def concentric_disk(u1: float, u2: float) -> wp.vec2:
    """Uniform point on the unit disk (Shirley-Chiu concentric map), density 1 / pi."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return wp.vec2(0.0, 0.0)
    r = float(0.0)
    phi = float(0.0)
    if wp.abs(a) > wp.abs(b):
        r = a
        phi = (wp.pi / 4.0) * (b / a)
    else:
        r = b
        phi = wp.pi / 2.0 - (wp.pi / 4.0) * (a / b)
    return wp.vec2(r * wp.cos(phi), r * wp.sin(phi))


@wp.func
def uniform_sphere(u1: float, u2: float) -> wp.vec3:
    """Uniform direction on the unit sphere, density 1 / (4 pi)."""
    z = 1.0 - 2.0 * u1
    r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = 2.0 * wp.pi * u2
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), z)


@wp.func
def cone_one_minus_cos(sin2_max: float) -> float:
    """``1 - cos(theta_max)`` of a cone given ``sin^2(theta_max)`` (for a sphere of radius r seen
    from distance d: ``r^2 / d^2``), without cancellation: ``s / (1 + sqrt(1 - s))``. Exact to a
    few ulps however small the cone (``1 - sqrt(1 - s)`` loses everything below s ~ 1e-7)."""
    s = wp.clamp(sin2_max, 0.0, 1.0)
    return s / (1.0 + wp.sqrt(1.0 - s))


@wp.func
def uniform_cone(u1: float, u2: float, one_minus_cos_max: float) -> wp.vec3:
    """Local direction (z = axis) uniform in the cone with ``1 - cos(theta_max) =
    one_minus_cos_max``, density ``1 / (2 pi one_minus_cos_max)``. Sampled through ``w = 1 -
    cos(theta)`` and ``sin(theta) = sqrt(w (2 - w))``, so a cone of 1e-7 radians still gets
    directions spread over it (``cos(theta)`` alone would round to 1)."""
    w = u1 * one_minus_cos_max
    r = wp.sqrt(wp.max(0.0, w * (2.0 - w)))
    phi = 2.0 * wp.pi * u2
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), 1.0 - w)


@wp.func
def power_heuristic(pdf_a: float, pdf_b: float) -> float:
    """Veach's power heuristic (beta = 2): MIS weight of a sample drawn from strategy a.

    Computed from the ratio of the densities, so that huge densities (a light seen edge-on from far
    away) do not overflow their squares into inf / inf.
    """
    if pdf_a >= pdf_b:
        if pdf_a == 0.0:
            return 0.0
        r = pdf_b / pdf_a
        return 1.0 / (1.0 + r * r)
    r = pdf_a / pdf_b
    return r * r / (1.0 + r * r)


@wp.func
def find_interval(cdf: wp.array(dtype=float), start: wp.int32, n: wp.int32, x: float) -> wp.int32:
    """The interval ``k`` in [0, n - 2] of the ``n`` CDF values from ``cdf[start]`` (0 to 1) holding
    ``x`` in [0, 1): ``cdf[start + k] <= x < cdf[start + k + 1]``, never an empty one."""
    lo = int(0)
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[start + mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo
