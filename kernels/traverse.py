"""The device-side scene (``GeometryData``) and its BVH traversal: closest hit and any hit.

Primitives are referred to by a packed id ``(index << KIND_BITS) | kind`` with ``kind`` one of
``SPHERE``, ``TRIANGLE``, ``POLYGON``, ``DISK``, ``CYLINDER`` (bounded, in the BVH) and ``PLANE``
(unbounded, tested outside the tree); ``index`` counts within that kind's arrays (up to 2^28 per
kind; disks and cylinders share the ``quadric_*`` arrays, which hold both). ``NO_HIT`` (-1) marks a miss.

The BVH is the 4-wide tree of ``wrt.kernels.bvh``; a leaf lists entries of ``prims``, the packed ids
in leaf order. Closest hit tests a node's four child boxes together (``child_entry``), descends
into the nearest child hit and keeps the others on a fixed-size stack with their entry distances,
nearest on top; popped entries that lie beyond the closest hit found so far are skipped. Any hit
stops at the first hit, in no particular order.

Instances (two levels, as Embree and OptiX do it): an ``INSTANCE`` leaf entry of the scene's tree
names an instance of a group; the ray is taken into the group's object space (``to_object``, its
direction not renormalised so that ``t`` is unchanged) and the same traversal, without planes or
instances, continues from the group's root node, with a stack of its own. The group's primitives
sit after the scene's in the kind arrays and its tree after the scene's in ``nodes``; a hit through
an instance is ``(t, prim, inst)``, and ``hit_point`` takes it back to world space. A ray and
what ``closest_hit`` found along it travel together as one ``RayHit`` to what turns them into a
surface point (``hit_point``, ``wrt.kernels.hit.surface_hit``), the AOVs and the ray records.

The traversal is compiled per set of geometry features (``traversal``): the leaf test of a
scene with triangles only has no sphere or polygon branch, and rays are moved into the frames of
moving primitives only when something moves. ``closest_hit`` and ``any_hit`` below handle every
scene.
"""

import functools

import warp as wp

from . import MODULE_OPTIONS, hinted_func
from .bvh import STACK_SIZE, WideNode, child_entry, leaf_count, leaf_start
from .features import ALL, Features, geometry_features
from .intersect import (
    INV_ZERO,
    RayShear,
    intersect_cylinder,
    intersect_disk,
    intersect_plane,
    intersect_polygon_sheared,
    intersect_sphere,
    intersect_triangle_sheared,
    ray_shear,
    safe_inverse,
)
from .spawn import max_abs, point_error
from .textures import TextureEvalContext, uv_context

KIND_BITS = wp.constant(3)  # low bits of a packed id that hold its kind
KIND_MASK = wp.constant(7)
SPHERE = wp.constant(0)
TRIANGLE = wp.constant(1)
POLYGON = wp.constant(2)
PLANE = wp.constant(3)
DISK = wp.constant(4)
CYLINDER = wp.constant(5)
INSTANCE = wp.constant(6)  # an instance of a group: its own BVH in the group's object space
NO_HIT = wp.constant(-1)
StackInt = wp.types.vector(length=STACK_SIZE, dtype=wp.int32)
StackFloat = wp.types.vector(length=STACK_SIZE, dtype=wp.float32)
mat24 = wp.types.matrix(shape=(2, 4), dtype=wp.float32)  # an affine map of points to texture coordinates


@wp.struct
class GeometryData:
    """All geometry of a scene on one device, world space, float32."""

    nodes: wp.array(dtype=WideNode)  # the BVH (wrt.kernels.bvh); empty without bounded primitives
    prims: wp.array(dtype=wp.int32)  # packed ids in leaf order
    sphere_center: wp.array(dtype=wp.vec3)
    sphere_radius: wp.array(dtype=float)
    sphere_shape: wp.array(dtype=wp.int32)
    sphere_to_object: wp.array(dtype=wp.mat33)  # world offsets from the centre to the sphere's object axes;
    # empty where no sphere is turned (sphere_axes)
    tri_verts: wp.array(dtype=wp.vec3)  # 3 per triangle
    tri_shape: wp.array(dtype=wp.int32)
    tri_normals: wp.array(dtype=wp.vec3)  # parallel to tri_verts: unit shading normals of smooth triangles, zero
    # for flat ones; empty when no triangle is smooth (shading_normal)
    poly_normal: wp.array(dtype=wp.vec3)  # unit
    poly_offset: wp.array(dtype=float)  # dot(normal, x) = offset on the polygon's plane
    poly_start: wp.array(dtype=wp.int32)
    poly_count: wp.array(dtype=wp.int32)
    poly_verts: wp.array(dtype=wp.vec3)  # vertices of all polygons, poly_start[i] .. + poly_count[i]
    poly_shape: wp.array(dtype=wp.int32)
    plane_point: wp.array(dtype=wp.vec3)
    plane_normal: wp.array(dtype=wp.vec3)  # unit
    plane_shape: wp.array(dtype=wp.int32)
    num_shapes: wp.int32  # surfaces from here on are the surfaces of lights (see wrt.geometry)
    surface_velocity: wp.array(dtype=wp.vec3)  # per surface (shapes, then lights); world units per unit time
    moving: wp.int32  # 1 when any surface has a nonzero velocity
    top_count: wp.int32  # entries of ``prims`` in the scene's own tree; the groups' trees list theirs after
    inst_to_object: wp.array(dtype=wp.mat44)  # per instance: world -> its group's object space (affine)
    inst_to_world: wp.array(dtype=wp.mat44)  # object -> world
    inst_root: wp.array(dtype=wp.int32)  # the node of its group's BVH in ``nodes``
    inst_shape: wp.array(dtype=wp.int32)  # its [[shape]] index (object_id, velocity)
    inst_entries: wp.array(dtype=wp.vec2i)  # (first, count): its group's primitives in ``prims``
    quadric_to_object: wp.array(dtype=wp.mat44)  # per disk or cylinder: world -> object space (affine)
    quadric_to_world: wp.array(dtype=wp.mat44)  # object -> world: the unit disk or tube placed
    quadric_normal: wp.array(dtype=wp.mat33)  # object normal -> world normal (up to length; see wrt.geometry)
    quadric_shape: wp.array(dtype=wp.int32)
    tri_uvs: wp.array(dtype=wp.vec2)  # parallel to tri_verts: texture coordinates; empty without textures
    poly_uv: wp.array(dtype=mat24)  # per polygon: uv = M (p, 1) (wrt.geometry.polygon_uv); empty without textures
    plane_uv: wp.array(dtype=mat24)  # per plane, likewise (wrt.geometry.plane_uv)


@wp.func
def prim_shape(geometry: GeometryData, prim: wp.int32) -> wp.int32:
    """Surface a primitive belongs to: its ``[[shape]]`` index, or ``num_shapes + k`` on the
    surface of light k (-1 for ``NO_HIT``)."""
    if prim == NO_HIT:
        return -1
    kind = prim & KIND_MASK
    i = prim >> KIND_BITS
    if kind == TRIANGLE:
        return geometry.tri_shape[i]
    if kind == SPHERE:
        return geometry.sphere_shape[i]
    if kind == POLYGON:
        return geometry.poly_shape[i]
    if kind == DISK or kind == CYLINDER:
        return geometry.quadric_shape[i]
    if kind == INSTANCE:
        return geometry.inst_shape[i]
    return geometry.plane_shape[i]


@wp.func
def hit_shape(geometry: GeometryData, prim: wp.int32, inst: wp.int32) -> wp.int32:
    """The surface a hit ``(prim, inst)`` of ``closest_hit`` is on, as the scene numbers them
    (``prim_shape``): an instance's own ``[[shape]]`` index for a primitive hit through it."""
    if inst >= 0:
        return geometry.inst_shape[inst]
    return prim_shape(geometry, prim)


@wp.func
def ray_origin_at(geometry: GeometryData, prim: wp.int32, o: wp.vec3, time: float) -> wp.vec3:
    """The point ``o`` moved into the frame of primitive ``prim`` at ``time`` (``o`` itself when
    nothing in the scene moves)."""
    if geometry.moving == 0:
        return o
    return o - time * geometry.surface_velocity[prim_shape(geometry, prim)]


@wp.func
def closest_plane(geometry: GeometryData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float):
    """Nearest of the unbounded planes (tested outside the BVH): ``(t, prim)`` as ``closest_hit``."""
    hit = int(NO_HIT)
    for i in range(geometry.plane_point.shape[0]):
        t = intersect_plane(
            ray_origin_at(geometry, (i << KIND_BITS) | PLANE, o, time),
            d,
            geometry.plane_point[i],
            geometry.plane_normal[i],
            t_min,
            t_max,
        )
        if t < t_max:
            t_max = t
            hit = (i << KIND_BITS) | PLANE
    return t_max, hit


@wp.func
def sort_pair(ea: float, ca: wp.int32, eb: float, cb: wp.int32):
    """``(ea, ca), (eb, cb)`` ordered by entry distance, without a branch."""
    swap = eb < ea
    return wp.where(swap, eb, ea), wp.where(swap, cb, ca), wp.where(swap, ea, eb), wp.where(swap, ca, cb)


@wp.struct
class VisitLog:
    """BVH nodes a closest-hit query visited, per ray (``wrt rays --show-bvh``)."""

    nodes: wp.array2d(dtype=wp.int32)  # (rays, capacity): wide-node indices in visiting order
    count: wp.array(dtype=wp.int32)  # visits per ray (more than the capacity: the row is cut short)


def _leaf_entry(features: Features):
    """``leaf_entry(scene, k)``: the packed id of primitive-list entry ``k``. With a single
    primitive kind the k-th entry is the k-th primitive of that kind (``wrt.geometry.build``
    reorders each kind to leaf order), so the id is computed, not loaded."""
    kinds = [
        (features.spheres, SPHERE),
        (features.triangles, TRIANGLE),
        (features.polygons, POLYGON),
        (features.disks, DISK),
        (features.cylinders, CYLINDER),
        (features.instances, INSTANCE),
    ]
    present = [kind for flag, kind in kinds if flag]
    only = present[0] if len(present) == 1 else -1

    @wp.func
    def leaf_entry(geometry: GeometryData, k: wp.int32) -> wp.int32:
        if wp.static(only >= 0):
            return (k << KIND_BITS) | wp.static(only)
        return geometry.prims[k]

    return leaf_entry


def _intersect_prim(features: Features):
    """``intersect_prim`` compiled for the primitive kinds ``features`` has (and ray motion only
    when something moves)."""
    kinds = [features.spheres, features.triangles, features.polygons, features.disks, features.cylinders]
    single = sum(kinds) == 1

    @wp.func
    def intersect_prim(
        geometry: GeometryData,
        prim: wp.int32,
        o: wp.vec3,
        d: wp.vec3,
        shear: RayShear,
        time: float,
        t_min: float,
        t_max: float,
    ) -> float:
        """Dispatch one bounded primitive (packed id) to its intersection test, at ray time ``time``;
        ``shear`` is ``ray_shear(d)``."""
        kind = prim & KIND_MASK
        i = prim >> KIND_BITS
        o_rel = o
        if wp.static(features.moving):
            o_rel = ray_origin_at(geometry, prim, o, time)
        if wp.static(features.triangles):
            if wp.static(single) or kind == TRIANGLE:
                return intersect_triangle_sheared(
                    o_rel,
                    d,
                    shear,
                    geometry.tri_verts[3 * i],
                    geometry.tri_verts[3 * i + 1],
                    geometry.tri_verts[3 * i + 2],
                    t_min,
                    t_max,
                )
        if wp.static(features.spheres):
            if wp.static(single) or kind == SPHERE:
                return intersect_sphere(o_rel, d, geometry.sphere_center[i], geometry.sphere_radius[i], t_min, t_max)
        if wp.static(features.polygons):
            if wp.static(single) or kind == POLYGON:
                return intersect_polygon_sheared(
                    o_rel,
                    d,
                    shear,
                    geometry.poly_normal[i],
                    geometry.poly_offset[i],
                    geometry.poly_verts,
                    geometry.poly_start[i],
                    geometry.poly_count[i],
                    t_min,
                    t_max,
                )
        if wp.static(features.disks):
            if wp.static(single) or kind == DISK:
                return intersect_disk(o_rel, d, geometry.quadric_to_object[i], t_min, t_max)
        if wp.static(features.cylinders):
            if wp.static(single) or kind == CYLINDER:
                return intersect_cylinder(o_rel, d, geometry.quadric_to_object[i], t_min, t_max)
        return t_max

    return intersect_prim


@wp.func
def to_object(geometry: GeometryData, inst: wp.int32, o: wp.vec3, d: wp.vec3, time: float):
    """The ray ``o + t d`` at ray time ``time`` in the object space of instance ``inst``: ``(o', d')``
    with ``d'`` not renormalised, so that ``t`` measures the same points in both spaces."""
    if geometry.moving != 0:
        o = o - time * geometry.surface_velocity[geometry.inst_shape[inst]]
    m = geometry.inst_to_object[inst]
    return wp.transform_point(m, o), wp.transform_vector(m, d)


def _closest_hit(features: Features, log_visits: bool, top: bool = True):
    """The closest-hit traversal for ``features``' primitive kinds, appending every wide node it
    visits to row ``row`` of ``log`` when ``log_visits`` (compiled out otherwise).

    ``top``: the scene's own tree, with its planes; a leaf entry that is an instance continues in
    its group's tree, built by this factory with ``top=False`` (the group's object space, no
    planes, no instances), with the ray taken into the group's object space."""
    intersect_prim = _intersect_prim(features)
    leaf_entry = _leaf_entry(features)
    instances = top and features.instances
    closest_in_group = _closest_hit(features, log_visits, top=False) if instances else None

    @wp.func
    def closest_hit_logged(
        geometry: GeometryData,
        root: wp.int32,
        o: wp.vec3,
        d: wp.vec3,
        time: float,
        t_min: float,
        t_max: float,
        log: VisitLog,
        row: wp.int32,
    ):
        hit = int(NO_HIT)
        hit_inst = int(-1)
        if wp.static(top):
            t_max, hit = closest_plane(geometry, o, d, time, t_min, t_max)
            if geometry.nodes.shape[0] == 0:
                return t_max, hit, hit_inst
        inv_d = safe_inverse(d)
        moves = inv_d[0] != INV_ZERO and inv_d[1] != INV_ZERO and inv_d[2] != INV_ZERO
        shear = ray_shear(d)
        stack = StackInt()
        stack_t = StackFloat()
        sp = int(0)
        ref = root
        while True:
            if ref >= 0:
                if wp.static(log_visits):
                    k = log.count[row]
                    if k < log.nodes.shape[1]:
                        log.nodes[row, k] = ref
                    log.count[row] = k + 1
                node = geometry.nodes[ref]
                entry = child_entry(node, o, inv_d, moves, t_max)
                # the hit children nearest first: a sorting network on (entry, child) pairs
                e0 = entry[0]
                e1 = entry[1]
                e2 = entry[2]
                e3 = entry[3]
                c0 = node.child[0]
                c1 = node.child[1]
                c2 = node.child[2]
                c3 = node.child[3]
                e0, c0, e1, c1 = sort_pair(e0, c0, e1, c1)
                e2, c2, e3, c3 = sort_pair(e2, c2, e3, c3)
                e0, c0, e2, c2 = sort_pair(e0, c0, e2, c2)
                e1, c1, e3, c3 = sort_pair(e1, c1, e3, c3)
                e1, c1, e2, c2 = sort_pair(e1, c1, e2, c2)
                if e0 < wp.inf:  # descend into the nearest, keep the others nearest on top
                    if e3 < wp.inf:
                        stack[sp] = c3
                        stack_t[sp] = e3
                        sp += 1
                    if e2 < wp.inf:
                        stack[sp] = c2
                        stack_t[sp] = e2
                        sp += 1
                    if e1 < wp.inf:
                        stack[sp] = c1
                        stack_t[sp] = e1
                        sp += 1
                    ref = c0
                    continue
            else:
                start = leaf_start(ref)
                for k in range(start, start + leaf_count(ref)):
                    prim = leaf_entry(geometry, k)
                    if wp.static(instances):
                        if prim & KIND_MASK == INSTANCE:
                            inst = prim >> KIND_BITS
                            o_obj, d_obj = to_object(geometry, inst, o, d, time)
                            t, inner, _none = closest_in_group(
                                geometry, geometry.inst_root[inst], o_obj, d_obj, time, t_min, t_max, log, row
                            )
                            if t < t_max:
                                t_max = t
                                hit = inner
                                hit_inst = inst
                            continue
                    t = intersect_prim(geometry, prim, o, d, shear, time, t_min, t_max)
                    if t < t_max:
                        t_max = t
                        hit = prim
                        hit_inst = -1
            # pop the nearest pending child that can still hold a closer hit
            found = bool(False)
            while sp > 0 and not found:
                sp -= 1
                if stack_t[sp] < t_max:
                    ref = stack[sp]
                    found = True
            if not found:
                break
        return t_max, hit, hit_inst

    return closest_hit_logged


def _any_hit(features: Features, top: bool = True):
    """The any-hit traversal for ``features``' primitive kinds (``top`` as for ``_closest_hit``)."""
    intersect_prim = _intersect_prim(features)
    leaf_entry = _leaf_entry(features)
    instances = top and features.instances
    any_in_group = _any_hit(features, top=False) if instances else None

    @wp.func
    def any_hit_from(
        geometry: GeometryData, root: wp.int32, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float
    ) -> bool:
        if wp.static(top):
            for i in range(geometry.plane_point.shape[0]):
                if (
                    intersect_plane(
                        ray_origin_at(geometry, (i << KIND_BITS) | PLANE, o, time),
                        d,
                        geometry.plane_point[i],
                        geometry.plane_normal[i],
                        t_min,
                        t_max,
                    )
                    < t_max
                ):
                    return True
            if geometry.nodes.shape[0] == 0:
                return False
        inv_d = safe_inverse(d)
        moves = inv_d[0] != INV_ZERO and inv_d[1] != INV_ZERO and inv_d[2] != INV_ZERO
        shear = ray_shear(d)
        stack = StackInt()
        stack[0] = root
        sp = int(1)
        while sp > 0:
            sp -= 1
            ref = stack[sp]
            if ref >= 0:
                node = geometry.nodes[ref]
                entry = child_entry(node, o, inv_d, moves, t_max)
                for k in range(4):
                    if entry[k] < wp.inf:
                        stack[sp] = node.child[k]
                        sp += 1
            else:
                start = leaf_start(ref)
                for k in range(start, start + leaf_count(ref)):
                    prim = leaf_entry(geometry, k)
                    if wp.static(instances):
                        if prim & KIND_MASK == INSTANCE:
                            inst = prim >> KIND_BITS
                            o_obj, d_obj = to_object(geometry, inst, o, d, time)
                            if any_in_group(geometry, geometry.inst_root[inst], o_obj, d_obj, time, t_min, t_max):
                                return True
                            continue
                    if intersect_prim(geometry, prim, o, d, shear, time, t_min, t_max) < t_max:
                        return True
        return False

    return any_hit_from


class Traversal:
    """``closest_hit`` and ``any_hit`` compiled for one set of scene features (``traversal``).

    ``inline``: Warp's inline hint of the two (``wp.func``'s): None leaves it to the compiler (the
    CPU modules'), False keeps each out of line at its call sites (the CUDA modules',
    ``wrt.kernels.variants.CUDA_INLINE``)."""

    def __init__(self, features: Features, inline: bool | None = None):
        self.features = features
        self.inline = inline
        closest_hit_logged = _closest_hit(features, log_visits=True)
        closest_hit_unlogged = _closest_hit(features, log_visits=False)
        any_hit_from = _any_hit(features)
        hinted = hinted_func(inline)

        @wp.func
        def closest_hit_visits(
            geometry: GeometryData,
            o: wp.vec3,
            d: wp.vec3,
            time: float,
            t_min: float,
            t_max: float,
            log: VisitLog,
            row: wp.int32,
        ):
            """``closest_hit``, logging the wide nodes it visits in row ``row`` of ``log``."""
            return closest_hit_logged(geometry, 0, o, d, time, t_min, t_max, log, row)

        @hinted
        def closest_hit(geometry: GeometryData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float):
            """Nearest intersection in ``(t_min, t_max)`` at ray time ``time``: returns
            ``(t, prim, inst)``; ``prim == NO_HIT`` on a miss; ``inst`` the instance the primitive
            was hit through (its group's primitive ``prim``), -1 for the scene's own primitives."""
            return closest_hit_unlogged(geometry, 0, o, d, time, t_min, t_max, VisitLog(), 0)

        @hinted
        def any_hit(geometry: GeometryData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float) -> bool:
            """Whether anything lies in ``(t_min, t_max)`` along the ray at ray time ``time`` (for
            shadow rays); stops at the first hit."""
            return any_hit_from(geometry, 0, o, d, time, t_min, t_max)

        self.closest_hit_logged = closest_hit_visits
        self.closest_hit = closest_hit
        self.any_hit = any_hit


@functools.cache
def traversal(features: Features, inline: bool | None = None) -> Traversal:
    """The traversal functions for the geometry of ``features`` (its primitive kinds and motion),
    with the inline hint ``inline`` (``Traversal``)."""
    return Traversal(geometry_features(features), inline)


_all = traversal(ALL)
closest_hit = _all.closest_hit
any_hit = _all.any_hit


_intersect_any_kind = _intersect_prim(ALL)


@wp.func
def closest_hit_brute_force(geometry: GeometryData, o: wp.vec3, d: wp.vec3, time: float, t_min: float, t_max: float):
    """Reference for ``closest_hit``: every primitive tested, no tree (an instance: every
    primitive of its group, in the group's object space). Same return values."""
    t_max, hit = closest_plane(geometry, o, d, time, t_min, t_max)
    hit_inst = int(-1)
    shear = ray_shear(d)
    for k in range(geometry.top_count):
        prim = geometry.prims[k]
        if prim & KIND_MASK == INSTANCE:
            inst = prim >> KIND_BITS
            o_obj, d_obj = to_object(geometry, inst, o, d, time)
            shear_obj = ray_shear(d_obj)
            entries = geometry.inst_entries[inst]
            for j in range(entries[0], entries[0] + entries[1]):
                t = _intersect_any_kind(geometry, geometry.prims[j], o_obj, d_obj, shear_obj, time, t_min, t_max)
                if t < t_max:
                    t_max = t
                    hit = geometry.prims[j]
                    hit_inst = inst
        else:
            t = _intersect_any_kind(geometry, prim, o, d, shear, time, t_min, t_max)
            if t < t_max:
                t_max = t
                hit = prim
                hit_inst = -1
    return t_max, hit, hit_inst


@functools.cache
def make_surface_point(quadrics: bool):
    """``surface_point``, with the disk and cylinder case compiled in only with ``quadrics`` (unused,
    it still costs a path tracer about a fifth of its time on the CPU)."""

    @wp.func
    def surface_point(geometry: GeometryData, prim: wp.int32, o: wp.vec3, d: wp.vec3, t: float, time: float):
        """The hit of unit ray ``o + s d`` at ``t`` on primitive ``prim`` (at ray time ``time``):
        ``(p, n, err)``, the point recomputed on the primitive's surface, its unit geometric normal
        and a bound on the distance of ``p`` from the float32 surface (``wrt.kernels.spawn``).

        ``o + t d`` carries the rounding of wherever the ray started (1e4 units away, several
        hundredths of a unit), so it is only the first guess: spheres reproject it onto the sphere,
        ``c + r (q - c) / |q - c|``; triangles, polygons and planes project it onto their plane,
        ``q - (n . (q - a)) n`` (pbrt-v4 and Mitsuba 3 do the same); disks and cylinders take it to
        their object space (float64), set ``z' = 0`` (disk) or scale ``(x', y')`` to unit length
        (tube), and map it back with ``quadric_to_world``. What is left is the rounding of that
        recomputation, a few ulps of the point and of the primitive's own coordinates (a quadric's:
        its translation plus the reach of its axes, as the float32 ``quadric_to_world`` is the inverse
        of ``quadric_to_object`` to an ulp of those), however far the ray came from.

        Normals: spheres outward; triangles ``cross(v1 - v0, v2 - v0)`` (the winding normal);
        polygons and planes the normal given in the scene (polygons: by Newell's method from the
        winding); disks and cylinders their object normal (+z; the radial direction, outward) by
        ``quadric_normal``, the inverse transpose of the placement (negated for inward normals).
        """
        kind = prim & KIND_MASK
        i = prim >> KIND_BITS
        shift = wp.vec3(0.0)
        if geometry.moving != 0:  # work in the primitive's frame at ``time``
            shift = time * geometry.surface_velocity[prim_shape(geometry, prim)]
        q = (o - shift) + t * d
        n = wp.vec3(0.0)
        extent = float(0.0)
        if kind == SPHERE:
            c = geometry.sphere_center[i]
            r = geometry.sphere_radius[i]
            n = wp.normalize(q - c)
            q = c + r * n
            extent = max_abs(c) + r
        elif wp.static(quadrics) and (kind == DISK or kind == CYLINDER):
            to_world = geometry.quadric_to_world[i]
            local = wp.transform_point(wp.mat44d(geometry.quadric_to_object[i]), wp.vec3d(q))
            n_local = wp.vec3(0.0, 0.0, 1.0)
            reach = wp.abs(wp.vec3(to_world[0, 0], to_world[1, 0], to_world[2, 0])) + wp.abs(
                wp.vec3(to_world[0, 1], to_world[1, 1], to_world[2, 1])
            )
            if kind == DISK:
                local[2] = wp.float64(0.0)
            else:
                radial = wp.sqrt(local[0] * local[0] + local[1] * local[1])
                local[0] = local[0] / radial
                local[1] = local[1] / radial
                n_local = wp.vec3(wp.float32(local[0]), wp.float32(local[1]), 0.0)
                reach += wp.abs(wp.vec3(to_world[0, 2], to_world[1, 2], to_world[2, 2]))
            q = wp.vec3(wp.transform_point(wp.mat44d(to_world), local))
            n = wp.normalize(geometry.quadric_normal[i] * n_local)
            extent = max_abs(wp.vec3(to_world[0, 3], to_world[1, 3], to_world[2, 3])) + max_abs(reach)
        else:
            if kind == TRIANGLE:
                a = geometry.tri_verts[3 * i]
                n = wp.normalize(wp.cross(geometry.tri_verts[3 * i + 1] - a, geometry.tri_verts[3 * i + 2] - a))
                q = q - wp.dot(n, q - a) * n
                extent = max_abs(a)
            elif kind == POLYGON:
                n = geometry.poly_normal[i]
                offset = geometry.poly_offset[i]
                q = q - (wp.dot(n, q) - offset) * n
                extent = wp.abs(offset)
            else:
                a = geometry.plane_point[i]
                n = geometry.plane_normal[i]
                q = q - wp.dot(n, q - a) * n
                extent = max_abs(a)
        p = q + shift
        return p, n, point_error(p, max_abs(q) + extent)

    return surface_point


surface_point = make_surface_point(True)


@wp.struct
class RayHit:
    """A ray and what ``closest_hit`` found along it (Mitsuba 3's preliminary intersection, with its
    ray): unit ray ``o + s d`` at ray ``time``, its closest hit at ``t`` on primitive ``prim``
    (``NO_HIT``: none) through instance ``inst`` (-1: none)."""

    o: wp.vec3
    d: wp.vec3
    time: float
    t: float
    prim: wp.int32
    inst: wp.int32


@wp.func
def ray_hit(o: wp.vec3, d: wp.vec3, time: float, t: float, prim: wp.int32, inst: wp.int32) -> RayHit:
    """The ``RayHit`` of these fields."""
    found = RayHit()
    found.o = o
    found.d = d
    found.time = time
    found.t = t
    found.prim = prim
    found.inst = inst
    return found


@wp.func
def hit_point(geometry: GeometryData, found: RayHit):
    """``surface_point`` of a hit ``found`` (not ``NO_HIT``): for a primitive hit through an
    instance, found in the group's object space and taken back to the world, the normal by the
    inverse transpose. Its error bound adds the rounding of the two transforms:
    the object-space bound stretched by at most the Frobenius norm of the linear part, plus a few
    ulps of the world point and translation."""
    prim = found.prim
    inst = found.inst
    time = found.time
    if inst < 0:
        return surface_point(geometry, prim, found.o, found.d, found.t, time)
    o_obj, d_obj = to_object(geometry, inst, found.o, found.d, time)
    p_obj, n_obj, err_obj = surface_point(geometry, prim, o_obj, d_obj, found.t, time)
    to_world = geometry.inst_to_world[inst]
    shift = wp.vec3(0.0)
    if geometry.moving != 0:
        shift = time * geometry.surface_velocity[geometry.inst_shape[inst]]
    p = wp.transform_point(to_world, p_obj) + shift
    n = wp.normalize(wp.transform_vector(wp.transpose(geometry.inst_to_object[inst]), n_obj))
    stretch = wp.sqrt(  # the Frobenius norm of the linear part: its columns' squared lengths
        wp.length_sq(wp.transform_vector(to_world, wp.vec3(1.0, 0.0, 0.0)))
        + wp.length_sq(wp.transform_vector(to_world, wp.vec3(0.0, 1.0, 0.0)))
        + wp.length_sq(wp.transform_vector(to_world, wp.vec3(0.0, 0.0, 1.0)))
    )
    translation = wp.vec3(to_world[0, 3], to_world[1, 3], to_world[2, 3])
    return p, n, stretch * err_obj + point_error(p, max_abs(translation) + stretch * max_abs(p_obj))


@wp.func
def shading_normal(geometry: GeometryData, prim: wp.int32, inst: wp.int32, p: wp.vec3, n: wp.vec3, time: float):
    """The unit shading normal at the hit point ``p`` (world space) of ``(prim, inst)`` from
    ``closest_hit``, whose geometric normal ``hit_point`` gave as ``n``: on a smooth triangle the
    barycentric interpolation of its corner normals at ``p``, normalised (Mitsuba 3's and pbrt's
    shading normal), through instance ``inst`` by the inverse transpose as ``hit_point``; ``n``
    itself on anything else, and where the interpolation vanishes (opposite corner normals).
    Not turned toward ``n``'s side: where the file's normals face away from the winding, so does
    the shading normal."""
    if prim & KIND_MASK != TRIANGLE or geometry.tri_normals.shape[0] == 0:
        return n
    i = prim >> KIND_BITS
    n0 = geometry.tri_normals[3 * i]
    if n0[0] == 0.0 and n0[1] == 0.0 and n0[2] == 0.0:  # a flat triangle
        return n
    b1, b2 = barycentric(geometry, i, object_point(geometry, prim, inst, p, time))
    ns = (1.0 - b1 - b2) * n0 + b1 * geometry.tri_normals[3 * i + 1] + b2 * geometry.tri_normals[3 * i + 2]
    if inst >= 0:
        ns = wp.transform_vector(wp.transpose(geometry.inst_to_object[inst]), ns)
    if not (wp.length_sq(ns) > 0.0):  # also NaN (a degenerate triangle)
        return n
    return wp.normalize(ns)


@wp.func
def object_point(geometry: GeometryData, prim: wp.int32, inst: wp.int32, p: wp.vec3, time: float) -> wp.vec3:
    """World point ``p`` of a hit ``(prim, inst)`` at ray time ``time`` in the frame the primitive's
    own coordinates are in: its group's object space through instance ``inst``, the primitive's
    frame at time 0 for a moving one."""
    if inst >= 0:
        q, _d = to_object(geometry, inst, p, p, time)
        return q
    return ray_origin_at(geometry, prim, p, time)


@wp.func
def barycentric(geometry: GeometryData, i: wp.int32, q: wp.vec3):
    """Barycentric coordinates ``(b1, b2)`` of point ``q`` (projected onto the plane) with respect to
    the second and third corners of triangle ``i``."""
    a = geometry.tri_verts[3 * i]
    e1 = geometry.tri_verts[3 * i + 1] - a
    e2 = geometry.tri_verts[3 * i + 2] - a
    w = q - a
    m = wp.cross(e1, e2)
    return wp.dot(wp.cross(w, e2), m) / wp.dot(m, m), wp.dot(wp.cross(e1, w), m) / wp.dot(m, m)


@wp.func
def unit_angle_z(v: wp.vec3) -> float:
    """The angle (radians) between unit vector ``v`` and +z, accurate near both poles (Mitsuba 3's)."""
    if v[2] >= 0.0:
        return 2.0 * wp.asin(wp.min(1.0, 0.5 * wp.length(v - wp.vec3(0.0, 0.0, 1.0))))
    return wp.pi - 2.0 * wp.asin(wp.min(1.0, 0.5 * wp.length(v + wp.vec3(0.0, 0.0, 1.0))))


@wp.func
def turns(y: float, x: float) -> float:
    """The angle of ``(x, y)`` from +x counter-clockwise, in turns in [0, 1)."""
    phi = wp.atan2(y, x) / (2.0 * wp.pi)
    return wp.where(phi < 0.0, phi + 1.0, phi)


@wp.func
def sphere_axes(geometry: GeometryData, i: wp.int32, offset: wp.vec3) -> wp.vec3:
    """World ``offset`` from the centre of sphere ``i`` in the sphere's object axes
    (``sphere_to_object``; ``offset`` itself where no sphere of the scene is turned)."""
    if geometry.sphere_to_object.shape[0] == 0:
        return offset
    return geometry.sphere_to_object[i] * offset


@wp.func
def sphere_world_axes(geometry: GeometryData, i: wp.int32, v: wp.vec3) -> wp.vec3:
    """``v`` in sphere ``i``'s object axes taken back to the world's (``sphere_axes`` inverted)."""
    if geometry.sphere_to_object.shape[0] == 0:
        return v
    return wp.transpose(geometry.sphere_to_object[i]) * v


@functools.cache
def make_texture_context(quadrics: bool):
    """``texture_context``, with the disk and cylinder case compiled in only with ``quadrics``."""

    @wp.func
    def texture_context(
        geometry: GeometryData, prim: wp.int32, inst: wp.int32, p: wp.vec3, time: float
    ) -> TextureEvalContext:
        """Where textures are looked up at the hit point ``p`` (world space) of ``(prim, inst)`` from
        ``closest_hit`` at ray time ``time``: on a triangle its index and barycentric coordinates
        (mesh attributes; ``prim`` -1 elsewhere), and the texture coordinates (u, v), computed in
        the primitive's object space (a group's for a hit through an instance), as Mitsuba 3's
        shapes of the same kind:

        - triangles: the corners' ``tri_uvs`` interpolated (a mesh without texture coordinates, or a
          ``triangle`` shape: ``(b1, b2)``, the barycentric coordinates of the second and third corners);
        - spheres: ``(phi / 2 pi, theta / pi)``, phi the azimuth around +z from +x in [0, 2 pi), theta
          the angle from +z, of the point in the sphere's object axes (``sphere_to_object``);
        - disks: ``(r, phi / 2 pi)`` of the unit disk's point (object space, ``wrt.scene.Disk``);
        - cylinders: ``(phi / 2 pi, z)`` of the unit tube's point;
        - polygons and planes: the affine maps ``poly_uv`` and ``plane_uv`` (``wrt.geometry``).
        """
        q = object_point(geometry, prim, inst, p, time)
        kind = prim & KIND_MASK
        i = prim >> KIND_BITS
        if kind == TRIANGLE:
            b1, b2 = barycentric(geometry, i, q)
            ctx = TextureEvalContext()
            ctx.uv = (
                (1.0 - b1 - b2) * geometry.tri_uvs[3 * i]
                + b1 * geometry.tri_uvs[3 * i + 1]
                + b2 * geometry.tri_uvs[3 * i + 2]
            )
            ctx.prim = i
            ctx.bary = wp.vec2(b1, b2)
            return ctx
        if kind == SPHERE:
            local = wp.normalize(sphere_axes(geometry, i, q - geometry.sphere_center[i]))
            return uv_context(wp.vec2(turns(local[1], local[0]), unit_angle_z(local) / wp.pi))
        if wp.static(quadrics):
            if kind == DISK or kind == CYLINDER:
                local = wp.transform_point(geometry.quadric_to_object[i], q)
                phi = turns(local[1], local[0])
                if kind == DISK:
                    return uv_context(wp.vec2(wp.sqrt(local[0] * local[0] + local[1] * local[1]), phi))
                return uv_context(wp.vec2(phi, local[2]))
        m = mat24()
        if kind == POLYGON:
            m = geometry.poly_uv[i]
        else:
            m = geometry.plane_uv[i]
        return uv_context(m * wp.vec4(q[0], q[1], q[2], 1.0))

    return texture_context


texture_context = make_texture_context(True)


@functools.cache
def make_surface_derivatives(quadrics: bool):
    """``surface_derivatives``, with the disk and cylinder case compiled in only with ``quadrics``."""

    @wp.func
    def surface_derivatives(geometry: GeometryData, prim: wp.int32, inst: wp.int32, p: wp.vec3, time: float):
        """``(dpdu, dpdv)``: the derivatives (world space, scene units per unit u and v) of the
        surface point along the texture coordinates of ``texture_context``, at the hit point ``p`` of
        ``(prim, inst)`` from ``closest_hit``: Mitsuba 3's ``si.dp_du`` and ``si.dp_dv`` on the same
        shapes (a normal map's tangent, a bump map's surface). Triangles: solved per triangle from
        its corners and their ``tri_uvs`` (barycentric for a mesh without texture coordinates: its
        first and second edges, as Mitsuba 3.9's); spheres ``2 pi (-y, x, 0)`` and ``pi (z x / r,
        z y / r, -r)`` of the point relative to the centre in the sphere's object axes, ``r`` its
        distance from their z axis, taken back to world axes;
        disks the unit radial direction and ``2 pi (-y, x, 0)`` of the unit disk's point; cylinders
        ``2 pi (-y, x, 0)`` of the unit tube's point and the axis; polygons and planes the
        in-plane vectors their affine uv map takes to (1, 0) and (0, 1). Zero where undefined (a
        triangle whose uvs are collinear, a sphere's poles, a disk's centre)."""
        q = object_point(geometry, prim, inst, p, time)
        kind = prim & KIND_MASK
        i = prim >> KIND_BITS
        dpdu = wp.vec3(0.0)
        dpdv = wp.vec3(0.0)
        if kind == TRIANGLE:
            a = geometry.tri_verts[3 * i]
            e1 = geometry.tri_verts[3 * i + 1] - a
            e2 = geometry.tri_verts[3 * i + 2] - a
            uv0 = geometry.tri_uvs[3 * i]
            d1 = geometry.tri_uvs[3 * i + 1] - uv0
            d2 = geometry.tri_uvs[3 * i + 2] - uv0
            det = d1[0] * d2[1] - d1[1] * d2[0]
            if det != 0.0:
                dpdu = (d2[1] * e1 - d1[1] * e2) / det
                dpdv = (d1[0] * e2 - d2[0] * e1) / det
        elif kind == SPHERE:
            r = sphere_axes(geometry, i, q - geometry.sphere_center[i])
            dpdu = sphere_world_axes(geometry, i, 2.0 * wp.pi * wp.vec3(-r[1], r[0], 0.0))
            axial = wp.sqrt(r[0] * r[0] + r[1] * r[1])
            if axial > 0.0:
                dpdv = sphere_world_axes(geometry, i, wp.pi * wp.vec3(r[2] * r[0] / axial, r[2] * r[1] / axial, -axial))
        elif wp.static(quadrics) and (kind == DISK or kind == CYLINDER):
            local = wp.transform_point(geometry.quadric_to_object[i], q)
            tangent = 2.0 * wp.pi * wp.vec3(-local[1], local[0], 0.0)
            along = wp.vec3(0.0, 0.0, 1.0)
            if kind == DISK:
                radial = wp.sqrt(local[0] * local[0] + local[1] * local[1])
                along = tangent
                tangent = wp.vec3(0.0)
                if radial > 0.0:
                    tangent = wp.vec3(local[0] / radial, local[1] / radial, 0.0)
            dpdu = wp.transform_vector(geometry.quadric_to_world[i], tangent)
            dpdv = wp.transform_vector(geometry.quadric_to_world[i], along)
        else:
            m = mat24()
            n = wp.vec3(0.0)
            if kind == POLYGON:
                m = geometry.poly_uv[i]
                n = geometry.poly_normal[i]
            else:
                m = geometry.plane_uv[i]
                n = geometry.plane_normal[i]
            grad_u = wp.vec3(m[0, 0], m[0, 1], m[0, 2])
            grad_v = wp.vec3(m[1, 0], m[1, 1], m[1, 2])
            across_v = wp.cross(grad_v, n)  # in the plane, v constant along it
            du = wp.dot(grad_u, across_v)
            if du != 0.0:
                dpdu = across_v / du
            across_u = wp.cross(grad_u, n)  # in the plane, u constant along it
            dv = wp.dot(grad_v, across_u)
            if dv != 0.0:
                dpdv = across_u / dv
        if inst >= 0:
            dpdu = wp.transform_vector(geometry.inst_to_world[inst], dpdu)
            dpdv = wp.transform_vector(geometry.inst_to_world[inst], dpdv)
        return dpdu, dpdv

    return surface_derivatives


surface_derivatives = make_surface_derivatives(True)


def _trace_kernels(trace: Traversal, module: str | None):
    @wp.kernel(module=module)
    def trace_closest(
        geometry: GeometryData,
        origins: wp.array(dtype=wp.vec3),
        directions: wp.array(dtype=wp.vec3),
        t_min: float,
        t_max: float,
        brute_force: wp.int32,
        out_t: wp.array(dtype=float),
        out_prim: wp.array(dtype=wp.int32),
        out_inst: wp.array(dtype=wp.int32),
    ):
        """Closest hit of a batch of rays at time 0 (tests, stress suite, benchmarks); ``brute_force != 0``
        skips the BVH."""
        i = wp.tid()
        if brute_force != 0:
            t, prim, inst = closest_hit_brute_force(geometry, origins[i], directions[i], 0.0, t_min, t_max)
        else:
            t, prim, inst = trace.closest_hit(geometry, origins[i], directions[i], 0.0, t_min, t_max)
        out_t[i] = t
        out_prim[i] = prim
        out_inst[i] = inst

    @wp.kernel(module=module)
    def trace_any(
        geometry: GeometryData,
        origins: wp.array(dtype=wp.vec3),
        directions: wp.array(dtype=wp.vec3),
        t_min: float,
        t_max: float,
        out_hit: wp.array(dtype=wp.int32),
    ):
        """Any-hit (occlusion) query of a batch of rays at time 0: 1 where something lies in (t_min, t_max)."""
        i = wp.tid()
        out_hit[i] = wp.where(trace.any_hit(geometry, origins[i], directions[i], 0.0, t_min, t_max), 1, 0)

    @wp.kernel(module=module)
    def trace_visits(
        geometry: GeometryData,
        origins: wp.array(dtype=wp.vec3),
        directions: wp.array(dtype=wp.vec3),
        times: wp.array(dtype=float),
        log: VisitLog,
    ):
        """Replay the closest-hit query of recorded rays (``t`` in ``(0, inf)``), logging the BVH nodes
        each visits: the same traversal code as the render kernels'."""
        i = wp.tid()
        trace.closest_hit_logged(geometry, origins[i], directions[i], times[i], 0.0, wp.inf, log, i)

    wp.set_module_options(MODULE_OPTIONS, module=module or __name__)
    return trace_closest, trace_any, trace_visits


trace_closest, trace_any, trace_visits = _trace_kernels(_all, None)


@functools.cache
def trace_kernels(features: Features):
    """``(trace_closest, trace_any, trace_visits)`` batch kernels compiled for the geometry of
    ``features``, each variant in a Warp module of its own (the all-features ones in this one)."""
    key = geometry_features(features)
    if key == geometry_features(ALL):
        return trace_closest, trace_any, trace_visits
    return _trace_kernels(traversal(key), f"wrt_trace_{key.key}")
