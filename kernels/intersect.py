"""Ray-primitive intersection tests, one ``@wp.func`` per primitive (world space, float32).

Every test takes a ray ``o + t d`` (``d`` need not be unit length; ``t`` is then measured in
units of ``|d|``) and an open interval ``(t_min, t_max)``, and returns the parameter ``t`` of the
nearest intersection inside it, or ``t_max`` itself when there is none. A closest-hit loop
therefore reads ``t = intersect_x(..., t_min, t_max); if t < t_max: t_max = t``.
Hits with ``t <= t_min`` (behind the eye, or the surface a ray leaves) are rejected.

References
----------
E. Haines, J. Guenther, T. Akenine-Moller, "Precision Improvements for Ray/Sphere
Intersection", Ray Tracing Gems, ch. 7, 2019 (also the cylinder's quadratic).
S. Woop, C. Benthin, I. Wald, "Watertight Ray/Triangle Intersection", JCGT 2(1), 2013 (also
the frame of the polygon test).
M. Pharr, W. Jakob, G. Humphreys, pbrt-v4, sec. 6.1.2 (conservative slab test).
"""

import warp as wp

# 1 + 2 gamma(3) for float32: widens a slab interval so rounding never culls a box a ray touches.
SLAB_WIDEN = wp.constant(1.0 + 2.0 * 3.0 * 5.9604645e-08 / (1.0 - 3.0 * 5.9604645e-08))
# 1/d of a direction component too small to invert in float32 (0, -0, denormals): the ray does not
# move along that axis (see safe_inverse and the BVH's box test, wrt.kernels.bvh.slab_exact).
INV_ZERO = wp.constant(float("inf"))
FLOAT32_MIN_NORMAL = wp.constant(1.17549435e-38)


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
def ray_to_object(to_object: wp.mat44, o: wp.vec3, d: wp.vec3):
    """The ray ``o + t d`` in the object space of the affine map ``to_object`` (world -> object), in
    float64: ``(o', d') = (M o, M d)``. The float32 inputs are exact in float64, so the map adds
    only float64 rounding, and ``d'`` is not normalised, so ``t`` is the same parameter in both spaces."""
    m = wp.mat44d(to_object)
    return wp.transform_point(m, wp.vec3d(o)), wp.transform_vector(m, wp.vec3d(d))


@wp.func
def intersect_disk(o: wp.vec3, d: wp.vec3, to_object: wp.mat44, t_min: float, t_max: float) -> float:
    """Disk: the unit disk ``x^2 + y^2 <= 1`` in the plane ``z = 0`` of the object space that the
    affine ``to_object`` (world -> object) maps world space to (an ellipse in world space under a
    non-uniform scale); both sides, rim included.

    In float64 object space (``ray_to_object``): ``t = -o'_z / d'_z``, rounded once, and the hit
    ``o' + t d'`` tested against the unit circle with the unrounded ``t``. Every step is float64
    rounding of float32 inputs, so rays from far away and grazing rays lose nothing to
    cancellation; a ray parallel to the plane (``d'_z = 0``) misses.
    """
    o64, d64 = ray_to_object(to_object, o, d)
    zero = wp.float64(0.0)
    if d64[2] == zero:
        return t_max
    t64 = -o64[2] / d64[2]
    t = wp.float32(t64)
    if t <= t_min or t >= t_max:
        return t_max
    x = o64[0] + t64 * d64[0]
    y = o64[1] + t64 * d64[1]
    if x * x + y * y <= wp.float64(1.0):
        return t
    return t_max


@wp.func
def intersect_cylinder(o: wp.vec3, d: wp.vec3, to_object: wp.mat44, t_min: float, t_max: float) -> float:
    """Cylinder: the open tube ``x^2 + y^2 = 1``, ``0 <= z <= 1`` (no caps) of the object space
    that the affine ``to_object`` (world -> object) maps world space to; from outside or inside,
    both sides, end rims included.

    In float64 object space (``ray_to_object``), the quadratic ``a t^2 + 2 beta t + c = 0`` of the
    xy components (``a = |d'_xy|^2``, ``beta = o'_xy . d'_xy``, ``c = |o'_xy|^2 - 1``) is solved
    in the cancellation-free form of ``intersect_sphere`` in 2D (Ray Tracing Gems ch. 7): the
    discriminant is ``a (1 - |o'_xy - (beta/a) d'_xy|^2)``, accurate for rays from far away, and
    the roots are ``c/q`` and ``q/a`` with ``q = -beta - sign(beta) sqrt(disc)``. The nearer root
    in ``(t_min, t_max)`` whose ``z' = o'_z + t d'_z`` lies in [0, 1] is the hit: a ray passing
    beyond an end of the near wall may hit the inside of the far wall. A ray parallel to the axis
    (``a = 0``) misses.
    """
    o64, d64 = ray_to_object(to_object, o, d)
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    fx = o64[0]
    fy = o64[1]
    dx = d64[0]
    dy = d64[1]
    a = dx * dx + dy * dy
    if a == zero:
        return t_max
    beta = fx * dx + fy * dy
    gx = fx - (beta / a) * dx
    gy = fy - (beta / a) * dy
    disc = a * (one - (gx * gx + gy * gy))
    if disc < zero:
        return t_max
    root = wp.sqrt(disc)
    q = -beta - root
    if beta < zero:
        q = -beta + root
    if q == zero:
        return t_max
    t0 = (fx * fx + fy * fy - one) / q
    t1 = q / a
    t_near = wp.min(t0, t1)
    t_far = wp.max(t0, t1)
    z = o64[2] + t_near * d64[2]
    t = wp.float32(t_near)
    if t > t_min and t < t_max and z >= zero and z <= one:
        return t
    z = o64[2] + t_far * d64[2]
    t = wp.float32(t_far)
    if t > t_min and t < t_max and z >= zero and z <= one:
        return t
    return t_max


@wp.func
def shear(a: wp.vec3, kx: wp.int32, ky: wp.int32, kz: wp.int32, sx: float, sy: float) -> wp.vec2:
    """Vertex ``a`` (relative to the ray origin) in the ray's sheared frame: ``a[kx] - sx a[kz]``, ``a[ky] - sy a[kz]``.

    The product of two float32 values is exact in float64, so each coordinate is rounded exactly
    twice whatever the compiler fuses: a vertex shared by several triangles lands on the same
    float32 point for all of them.
    """
    az = wp.float64(a[kz])
    x = wp.float64(a[kx]) - wp.float64(sx) * az
    y = wp.float64(a[ky]) - wp.float64(sy) * az
    return wp.vec2(wp.float32(x), wp.float32(y))


@wp.func
def edge_function(p: wp.vec2, q: wp.vec2) -> wp.float64:
    """``p.x q.y - p.y q.x`` with its exact sign (float32 products are exact in float64, one rounding).

    ``edge_function(q, p)`` is exactly its negation, so the two triangles sharing an edge agree
    on which side of it the ray passes.
    """
    return wp.float64(p[0]) * wp.float64(q[1]) - wp.float64(p[1]) * wp.float64(q[0])


@wp.struct
class RayShear:
    """The per-ray part of the watertight triangle test: the axis ``kz`` of ``d``'s largest
    component, the two others ``kx``, ``ky`` (cyclic), and the shear ``sx = d[kx] / d[kz]``,
    ``sy = d[ky] / d[kz]``. Computed once per ray (``ray_shear``), used for every triangle."""

    kx: wp.int32
    ky: wp.int32
    kz: wp.int32
    sx: float
    sy: float


@wp.func
def ray_shear(d: wp.vec3) -> RayShear:
    """``RayShear`` of direction ``d`` (a zero ``d`` gives ``sx = sy = nan``: every triangle misses)."""
    ad = wp.abs(d)
    kz = int(0)
    if ad[1] > ad[kz]:
        kz = 1
    if ad[2] > ad[kz]:
        kz = 2
    s = RayShear()
    s.kz = kz
    s.kx = (kz + 1) % 3
    s.ky = (s.kx + 1) % 3
    s.sx = d[s.kx] / d[kz]
    s.sy = d[s.ky] / d[kz]
    return s


@wp.func
def intersect_triangle_sheared(
    o: wp.vec3, d: wp.vec3, ray: RayShear, v0: wp.vec3, v1: wp.vec3, v2: wp.vec3, t_min: float, t_max: float
) -> float:
    """``intersect_triangle`` with the ray's shear (``ray_shear(d)``) computed by the caller."""
    if d[ray.kz] == 0.0:
        return t_max
    a = v0 - o
    b = v1 - o
    c = v2 - o
    a2 = shear(a, ray.kx, ray.ky, ray.kz, ray.sx, ray.sy)
    b2 = shear(b, ray.kx, ray.ky, ray.kz, ray.sx, ray.sy)
    c2 = shear(c, ray.kx, ray.ky, ray.kz, ray.sx, ray.sy)
    zero = wp.float64(0.0)
    u = edge_function(c2, b2)
    v = edge_function(a2, c2)
    w = edge_function(b2, a2)
    if (u < zero or v < zero or w < zero) and (u > zero or v > zero or w > zero):
        return t_max
    if u + v + w == zero:
        return t_max
    # t from the triangle's plane in float64 (float32 inputs are exact there): its error is the
    # final rounding only, whatever the triangle's size, as the spawn offset assumes
    o64 = wp.vec3d(wp.float64(o[0]), wp.float64(o[1]), wp.float64(o[2]))
    p0 = wp.vec3d(wp.float64(v0[0]), wp.float64(v0[1]), wp.float64(v0[2]))
    p1 = wp.vec3d(wp.float64(v1[0]), wp.float64(v1[1]), wp.float64(v1[2]))
    p2 = wp.vec3d(wp.float64(v2[0]), wp.float64(v2[1]), wp.float64(v2[2]))
    normal = wp.cross(p1 - p0, p2 - p0)
    denom = wp.dot(normal, wp.vec3d(wp.float64(d[0]), wp.float64(d[1]), wp.float64(d[2])))
    if denom == zero:
        return t_max
    t = wp.float32(wp.dot(normal, p0 - o64) / denom)
    if t > t_min and t < t_max:
        return t
    return t_max


@wp.func
def intersect_triangle(
    o: wp.vec3, d: wp.vec3, v0: wp.vec3, v1: wp.vec3, v2: wp.vec3, t_min: float, t_max: float
) -> float:
    """Triangle (v0, v1, v2), both sides, watertight (Woop, Benthin and Wald 2013).

    The vertices are moved into a frame where the ray starts at the origin and runs along z
    (translate by ``-o``, permute so that z is the largest component of ``d``, shear x and y
    along it: ``ray_shear``); the ray hits the triangle when the origin of the sheared xy-plane is
    inside the projected triangle: the three 2D edge functions ``U, V, W`` share a sign (or are 0;
    either sign, as both sides are hit, so the paper's swap that keeps the winding is not needed).
    Each edge function is evaluated with its exact sign (``edge_function``), from sheared
    vertices that are the same for every triangle sharing them, so two triangles sharing an edge
    or a vertex never both miss a ray through it: a closed mesh has no cracks. Edges are
    inclusive. ``U + V + W == 0`` (ray in the triangle's plane, zero-area triangle) is a miss,
    without a scale-dependent epsilon, and so is a triangle whose float64 normal is 0 or
    perpendicular to the ray. ``t`` is the float64 distance to the triangle's plane, rounded once
    (the sheared values would carry the rounding of the vertices' distances from ``o``, large for
    large triangles).
    """
    return intersect_triangle_sheared(o, d, ray_shear(d), v0, v1, v2, t_min, t_max)


@wp.func
def ray_in_polygon(verts: wp.array(dtype=wp.vec3), start: wp.int32, count: wp.int32, o: wp.vec3, ray: RayShear) -> bool:
    """Whether the ray from ``o`` with shear ``ray`` passes inside the polygon
    ``verts[start:start+count]`` (convex or not; even-odd rule), judged in the ray's sheared
    frame, where the ray is the origin of the xy-plane (as the watertight triangle test does).

    A +x half-line from the origin counts the edges it crosses. An edge crosses y = 0 when its
    ends are on different sides, with y = 0 counted below (half-open), and the crossing is on
    the +x side when its x, ``E(a, b) / (b.y - a.y)`` with ``E`` the exact-sign ``edge_function``,
    is > 0; a crossing exactly at 0 (the ray through the edge) is not counted. Both rules read the
    same whichever way an edge is walked, and vertices are sheared identically for every polygon
    that holds them, so polygons that share an edge or a vertex judge a ray through it as one:
    it lies in exactly one of them when they are on opposite sides (a closed box from inside,
    coplanar neighbours), never in none and never in both (a consistent perturbation of the ray
    to +x, then +y).
    """
    inside = bool(False)
    zero = wp.float64(0.0)
    a = shear(verts[start + count - 1] - o, ray.kx, ray.ky, ray.kz, ray.sx, ray.sy)
    for k in range(start, start + count):
        b = shear(verts[k] - o, ray.kx, ray.ky, ray.kz, ray.sx, ray.sy)
        if (a[1] > 0.0) != (b[1] > 0.0):
            e = edge_function(a, b)
            if (b[1] > 0.0 and e > zero) or (a[1] > 0.0 and e < zero):
                inside = not inside
        a = b
    return inside


@wp.func
def intersect_polygon_sheared(
    o: wp.vec3,
    d: wp.vec3,
    ray: RayShear,
    normal: wp.vec3,
    offset: float,
    verts: wp.array(dtype=wp.vec3),
    start: wp.int32,
    count: wp.int32,
    t_min: float,
    t_max: float,
) -> float:
    """Planar polygon ``verts[start:start+count]`` on the plane ``dot(normal, x) = offset``, both
    sides, watertight (``ray_in_polygon``); ``ray`` is ``ray_shear(d)``. ``t`` is the float64
    distance to the plane, rounded once."""
    if d[ray.kz] == 0.0:
        return t_max
    n64 = wp.vec3d(wp.float64(normal[0]), wp.float64(normal[1]), wp.float64(normal[2]))
    denom = wp.dot(n64, wp.vec3d(wp.float64(d[0]), wp.float64(d[1]), wp.float64(d[2])))
    if denom == wp.float64(0.0):
        return t_max
    o64 = wp.vec3d(wp.float64(o[0]), wp.float64(o[1]), wp.float64(o[2]))
    t = wp.float32((wp.float64(offset) - wp.dot(n64, o64)) / denom)
    if t <= t_min or t >= t_max:
        return t_max
    if ray_in_polygon(verts, start, count, o, ray):
        return t
    return t_max


@wp.func
def safe_inverse(d: wp.vec3) -> wp.vec3:
    """Componentwise 1/d for the slab test: finite where ``|d[k]|`` is a normal float32, else
    ``INV_ZERO`` (+0.0, -0.0 and denormals, whose inverse overflows): "does not move along k".

    The BVH's box test (``wrt.kernels.bvh.slab_exact``) handles those axes apart, so
    ``(lo - o) * inv_d`` never reaches ``0 * inf = NaN`` (which would cull a box the ray starts on).
    """
    inv = wp.vec3(INV_ZERO, INV_ZERO, INV_ZERO)
    for k in range(3):
        if wp.abs(d[k]) >= FLOAT32_MIN_NORMAL:
            inv[k] = 1.0 / d[k]
    return inv
