"""A surface hit as the integrators see it: one struct, built by one function.

``surface_hit`` turns a traversal's ``(t, prim)`` for the unit ray ``o + s d`` into the hit point
(recomputed on the primitive's surface),
its unit geometric normal (outward for spheres and closed meshes, the winding normal for
triangles, the given normal for planes and polygons), that normal flipped to the side the ray
comes from, the shape and material, and the bound on the point's rounding error that offsets
rays leaving it (``wrt.kernels.spawn``).
"""

import warp as wp

from .materials import MaterialData
from .traverse import GeometryData, hit_point, hit_shape, prim_shape


@wp.struct
class Hit:
    p: wp.vec3  # the hit point, on the primitive's surface (surface_point)
    n: wp.vec3  # unit geometric normal, not flipped
    n_facing: wp.vec3  # n flipped to face the incoming ray: dot(n_facing, wo) >= 0
    wo: wp.vec3  # unit direction back along the ray, -d
    err: float  # bound on the distance of p from the true surface (spawn offset)
    shape: wp.int32  # shape index; area and sphere lights follow the [[shape]]s (num_shapes + light)
    material: wp.int32
    entering: bool  # the ray hits the front side (dot(d, n) < 0)


@wp.func
def surface_hit(
    geometry: GeometryData,
    materials: MaterialData,
    o: wp.vec3,
    d: wp.vec3,
    t: float,
    prim: wp.int32,
    inst: wp.int32,
    time: float,
) -> Hit:
    """The hit of unit ray ``o + s d`` (at ray time ``time``) at ``t`` on primitive ``prim`` (not
    ``NO_HIT``), through instance ``inst`` (-1: none), as ``closest_hit`` returns them. The
    material is the primitive's own (a group member's); the shape is the instance's."""
    hit = Hit()
    p, n, err = hit_point(geometry, prim, inst, o, d, t, time)
    hit.p = p
    hit.n = n
    hit.err = err
    hit.wo = -d
    hit.entering = wp.dot(d, hit.n) < 0.0
    hit.n_facing = hit.n
    if not hit.entering:
        hit.n_facing = -hit.n
    hit.material = materials.shape_material[prim_shape(geometry, prim)]
    hit.shape = hit_shape(geometry, prim, inst)
    return hit
