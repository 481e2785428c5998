"""The device-side scene (``SceneData``) and its BVH traversal: closest hit and any hit.

Primitives are referred to by a packed id ``(index << 2) | kind`` with ``kind`` one of
``SPHERE``, ``TRIANGLE``, ``POLYGON`` (bounded, in the BVH) and ``PLANE`` (unbounded, tested
outside the tree); ``index`` counts within that kind's arrays. ``NO_HIT`` (-1) marks a miss.

BVH layout (built on the host by ``wrt.bvh``): ``nodes[0]`` is the root. An inner node has
``count == 0`` and its children at ``start`` and ``start + 1``; a leaf has ``count > 0``
primitives ``prims[start : start + count]``. Traversal visits the nearer child first, keeps the
farther one on a fixed-size stack with its entry distance, and skips popped nodes that lie beyond
the closest hit found so far.
"""
import warp as wp

from .intersect import intersect_box, intersect_plane, intersect_polygon, intersect_sphere, intersect_triangle, safe_inverse

SPHERE = wp.constant(0)
TRIANGLE = wp.constant(1)
POLYGON = wp.constant(2)
PLANE = wp.constant(3)
NO_HIT = wp.constant(-1)
# The host builder limits the tree depth so that the stack never overflows.
STACK_SIZE = 64
StackInt = wp.types.vector(length=STACK_SIZE, dtype=wp.int32)
StackFloat = wp.types.vector(length=STACK_SIZE, dtype=wp.float32)


@wp.struct
class BvhNode:
    """Axis-aligned bounds and either two children (``count == 0``) or a leaf's primitive range."""

    lo: wp.vec3
    hi: wp.vec3
    start: wp.int32
    count: wp.int32


@wp.struct
class SceneData:
    """All geometry of a scene on one device, world space, float32."""

    nodes: wp.array(dtype=BvhNode)
    prims: wp.array(dtype=wp.int32)  # packed ids in leaf order
    sphere_center: wp.array(dtype=wp.vec3)
    sphere_radius: wp.array(dtype=float)
    sphere_shape: wp.array(dtype=wp.int32)
    tri_verts: wp.array(dtype=wp.vec3)  # 3 per triangle
    tri_shape: wp.array(dtype=wp.int32)
    poly_normal: wp.array(dtype=wp.vec3)  # unit
    poly_offset: wp.array(dtype=float)  # dot(normal, x) = offset on the polygon's plane
    poly_axis: wp.array(dtype=wp.int32)  # dominant axis of the normal, dropped in projection
    poly_start: wp.array(dtype=wp.int32)
    poly_count: wp.array(dtype=wp.int32)
    poly_uv: wp.array(dtype=wp.vec2)  # projected vertices of all polygons
    poly_shape: wp.array(dtype=wp.int32)
    plane_point: wp.array(dtype=wp.vec3)
    plane_normal: wp.array(dtype=wp.vec3)  # unit
    plane_shape: wp.array(dtype=wp.int32)
    num_shapes: wp.int32  # surfaces from here on are the surfaces of lights (see wrt.geometry)
    surface_velocity: wp.array(dtype=wp.vec3)  # per surface (shapes, then lights); world units per unit time
    moving: wp.int32  # 1 when any surface has a nonzero velocity


@wp.func
def prim_shape(scene: SceneData, prim: wp.int32) -> wp.int32:
    """Surface a primitive belongs to: its ``[[shape]]`` index, or ``num_shapes + k`` on the
    surface of light k (-1 for ``NO_HIT``)."""
    if prim == NO_HIT:
        return -1
    kind = prim & 3
    i = prim >> 2
    if kind == TRIANGLE:
        return scene.tri_shape[i]
    if kind == SPHERE:
        return scene.sphere_shape[i]
    if kind == POLYGON:
        return scene.poly_shape[i]
    return scene.plane_shape[i]


@wp.func
def ray_origin_at(scene: SceneData, prim: wp.int32, o: wp.vec3, time: float) -> wp.vec3:
    """The point ``o`` moved into the frame of primitive ``prim`` at ``time`` (``o`` itself when
    nothing in the scene moves)."""
    if scene.moving == 0:
        return o
    return o - time * scene.surface_velocity[prim_shape(scene, prim)]


@wp.func
def intersect_prim(scene: SceneData, prim: wp.int32, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float) -> float:
    """Dispatch one bounded primitive (packed id) to its intersection test, at ray time ``time``."""
    kind = prim & 3
    i = prim >> 2
    o_rel = ray_origin_at(scene, prim, o, time)
    if kind == TRIANGLE:
        return intersect_triangle(o_rel, d, scene.tri_verts[3 * i], scene.tri_verts[3 * i + 1], scene.tri_verts[3 * i + 2], t_min, t_max)
    if kind == SPHERE:
        return intersect_sphere(o_rel, d, scene.sphere_center[i], scene.sphere_radius[i], t_min, t_max)
    return intersect_polygon(
        o_rel, d, scene.poly_normal[i], scene.poly_offset[i], scene.poly_axis[i], scene.poly_uv, scene.poly_start[i], scene.poly_count[i], t_min, t_max
    )


@wp.func
def closest_plane(scene: SceneData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float):
    """Nearest of the unbounded planes (tested outside the BVH): ``(t, prim)`` as ``closest_hit``."""
    hit = int(NO_HIT)
    for i in range(scene.plane_point.shape[0]):
        t = intersect_plane(ray_origin_at(scene, (i << 2) | PLANE, o, time), d, scene.plane_point[i], scene.plane_normal[i], t_min, t_max)
        if t < t_max:
            t_max = t
            hit = (i << 2) | PLANE
    return t_max, hit


@wp.struct
class VisitLog:
    """BVH nodes a closest-hit query visited, per ray (``wrt rays --show-bvh``)."""

    nodes: wp.array2d(dtype=wp.int32)  # (rays, capacity): node indices in visiting order
    count: wp.array(dtype=wp.int32)  # visits per ray (more than the capacity: the row is cut short)


def make_closest_hit(log_visits: bool):
    """The closest-hit traversal, appending every node it visits to row ``row`` of ``log`` when
    ``log_visits`` (compiled out otherwise)."""

    @wp.func
    def closest_hit_logged(scene: SceneData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float, log: VisitLog, row: wp.int32):
        t_max, hit = closest_plane(scene, o, d, time, t_min, t_max)
        if scene.nodes.shape[0] == 0:
            return t_max, hit
        inv_d = safe_inverse(d)
        root = scene.nodes[0]
        if intersect_box(o, inv_d, root.lo, root.hi, t_max) >= t_max:
            return t_max, hit
        stack = StackInt()
        stack_t = StackFloat()
        sp = int(0)
        node = int(0)
        while True:
            nd = scene.nodes[node]
            if wp.static(log_visits):
                k = log.count[row]
                if k < log.nodes.shape[1]:
                    log.nodes[row, k] = node
                log.count[row] = k + 1
            descend = bool(False)
            if nd.count > 0:
                for k in range(nd.start, nd.start + nd.count):
                    prim = scene.prims[k]
                    t = intersect_prim(scene, prim, o, d, time, t_min, t_max)
                    if t < t_max:
                        t_max = t
                        hit = prim
            else:
                left = scene.nodes[nd.start]
                right = scene.nodes[nd.start + 1]
                t_left = intersect_box(o, inv_d, left.lo, left.hi, t_max)
                t_right = intersect_box(o, inv_d, right.lo, right.hi, t_max)
                if t_left < t_max and t_right < t_max:
                    descend = True
                    if t_left <= t_right:
                        node = nd.start
                        stack[sp] = nd.start + 1
                        stack_t[sp] = t_right
                    else:
                        node = nd.start + 1
                        stack[sp] = nd.start
                        stack_t[sp] = t_left
                    sp += 1
                elif t_left < t_max:
                    descend = True
                    node = nd.start
                elif t_right < t_max:
                    descend = True
                    node = nd.start + 1
            if not descend:
                # pop the nearest pending node that can still hold a closer hit
                found = bool(False)
                while sp > 0 and not found:
                    sp -= 1
                    if stack_t[sp] < t_max:
                        node = stack[sp]
                        found = True
                if not found:
                    break
        return t_max, hit

    return closest_hit_logged


_closest_hit = make_closest_hit(False)


@wp.func
def closest_hit(scene: SceneData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float):
    """Nearest intersection in ``(t_min, t_max)`` at ray time ``time``: returns ``(t, prim)``;
    ``prim == NO_HIT`` on a miss."""
    t, prim = _closest_hit(scene, o, d, time, t_min, t_max, VisitLog(), 0)
    return t, prim


@wp.func
def any_hit(scene: SceneData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float) -> bool:
    """Whether anything lies in ``(t_min, t_max)`` along the ray at ray time ``time`` (for shadow
    rays); stops at the first hit."""
    for i in range(scene.plane_point.shape[0]):
        if intersect_plane(ray_origin_at(scene, (i << 2) | PLANE, o, time), d, scene.plane_point[i], scene.plane_normal[i], t_min, t_max) < t_max:
            return True
    if scene.nodes.shape[0] == 0:
        return False
    inv_d = safe_inverse(d)
    stack = StackInt()
    stack[0] = 0
    sp = int(1)
    while sp > 0:
        sp -= 1
        nd = scene.nodes[stack[sp]]
        if intersect_box(o, inv_d, nd.lo, nd.hi, t_max) < t_max:
            if nd.count > 0:
                for k in range(nd.start, nd.start + nd.count):
                    if intersect_prim(scene, scene.prims[k], o, d, time, t_min, t_max) < t_max:
                        return True
            else:
                stack[sp] = nd.start
                stack[sp + 1] = nd.start + 1
                sp += 2
    return False


@wp.func
def closest_hit_brute_force(scene: SceneData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float):
    """Reference for ``closest_hit``: every primitive tested, no tree. Same return values."""
    t_max, hit = closest_plane(scene, o, d, time, t_min, t_max)
    for k in range(scene.prims.shape[0]):
        prim = scene.prims[k]
        t = intersect_prim(scene, prim, o, d, time, t_min, t_max)
        if t < t_max:
            t_max = t
            hit = prim
    return t_max, hit


@wp.func
def geometric_normal(scene: SceneData, prim: wp.int32, p: wp.vec3, time: float) -> wp.vec3:
    """Unit geometric normal of primitive ``prim`` at surface point ``p`` (world space) at ``time``.

    Spheres: outward. Triangles: ``cross(v1 - v0, v2 - v0)`` (the winding normal). Polygons and
    planes: the normal given in the scene (polygons: by Newell's method from the winding).
    """
    kind = prim & 3
    i = prim >> 2
    if kind == TRIANGLE:
        v0 = scene.tri_verts[3 * i]
        return wp.normalize(wp.cross(scene.tri_verts[3 * i + 1] - v0, scene.tri_verts[3 * i + 2] - v0))
    if kind == SPHERE:
        return wp.normalize(ray_origin_at(scene, prim, p, time) - scene.sphere_center[i])
    if kind == POLYGON:
        return scene.poly_normal[i]
    return scene.plane_normal[i]


@wp.kernel
def trace_closest(
    scene: SceneData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    t_min: float,
    t_max: float,
    brute_force: wp.int32,
    out_t: wp.array(dtype=float),
    out_prim: wp.array(dtype=wp.int32),
):
    """Closest hit of a batch of rays at time 0 (tests, stress suite, benchmarks); ``brute_force != 0``
    skips the BVH."""
    i = wp.tid()
    if brute_force != 0:
        t, prim = closest_hit_brute_force(scene, origins[i], directions[i], 0.0, t_min, t_max)
    else:
        t, prim = closest_hit(scene, origins[i], directions[i], 0.0, t_min, t_max)
    out_t[i] = t
    out_prim[i] = prim


@wp.kernel
def trace_any(
    scene: SceneData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    t_min: float,
    t_max: float,
    out_hit: wp.array(dtype=wp.int32),
):
    """Any-hit (occlusion) query of a batch of rays at time 0: 1 where something lies in (t_min, t_max)."""
    i = wp.tid()
    out_hit[i] = wp.where(any_hit(scene, origins[i], directions[i], 0.0, t_min, t_max), 1, 0)


_closest_hit_visiting = make_closest_hit(True)


@wp.kernel
def trace_visits(scene: SceneData, origins: wp.array(dtype=wp.vec3), directions: wp.array(dtype=wp.vec3), times: wp.array(dtype=float), log: VisitLog):
    """Replay the closest-hit query of recorded rays (``t`` in ``(0, inf)``), logging the BVH nodes
    each visits: the same traversal code as the render kernels'."""
    i = wp.tid()
    _closest_hit_visiting(scene, origins[i], directions[i], times[i], 0.0, wp.inf, log, i)
