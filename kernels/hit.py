"""A surface hit as the integrators see it: one struct, built by one function.

``surface_hit`` turns a traversal's ``(t, prim)`` for the unit ray ``o + s d`` into the hit point
(recomputed on the primitive's surface),
its unit geometric normal (outward for spheres and closed meshes, the winding normal for
triangles, the given normal for planes and polygons), its shading normal turned to the side the
ray comes from, the shape and material, and the bound on the point's rounding error that offsets
rays leaving it (``wrt.kernels.spawn``).

Two normals, as in Mitsuba 3 and pbrt: the shading normal (``shading_normal``: interpolated from
the vertex normals on smooth-shaded meshes, the geometric normal everywhere else) is the BSDF's:
its local frame, its cosines and which side of a one-sided material the ray is on (``front``),
and the side emission leaves from. The geometric normal decides where rays leaving the surface
start (``spawn_origin``) and whether the ray enters or leaves a dielectric's medium
(``entering``). Where the two disagree about a direction's side (near a smooth mesh's silhouette
and terminator) nothing else is checked, as in Mitsuba 3: a direction above the shading surface
but below the geometric one is scattered into and lit from; a closed mesh then blocks it itself,
an open one lets light from behind reach its front.
"""

import functools

import warp as wp

from .materials import MaterialData
from .traverse import (
    GeometryData,
    hit_point,
    hit_shape,
    make_surface_point,
    make_surface_uv,
    prim_shape,
    shading_normal,
)


@wp.struct
class Hit:
    p: wp.vec3  # the hit point, on the primitive's surface (surface_point)
    n: wp.vec3  # unit geometric normal, not flipped
    n_facing: wp.vec3  # unit shading normal flipped to face the incoming ray: dot(n_facing, wo) >= 0
    wo: wp.vec3  # unit direction back along the ray, -d
    err: float  # bound on the distance of p from the true surface (spawn offset)
    shape: wp.int32  # shape index; area and sphere lights follow the [[shape]]s (num_shapes + light)
    material: wp.int32
    entering: bool  # the ray hits the geometric front side (dot(d, n) < 0): media, dielectric interfaces
    front: bool  # the ray hits the shading front side (dot(d, shading normal) < 0): the BSDF's side, emission
    uv: wp.vec2  # texture coordinates (surface_uv); (0, 0) where the scene has no textures


@functools.cache
def make_surface_hit(smooth: bool, instances: bool, quadrics: bool, textures: bool):
    """``surface_hit``; without ``smooth`` (no smooth-shaded mesh in the scene) the shading normal
    is the geometric one, and its interpolation is compiled out; without ``textures`` so is the
    texture coordinates' computation (``uv`` stays (0, 0)); without ``instances`` no hit goes
    through an instance, and ``hit_point``'s transforms are compiled out; without ``quadrics`` (no
    disk or cylinder) neither is their surface point nor uv (compiled in, each costs a path tracer a fifth
    to a quarter of its time on the CPU, even when not taken)."""
    surface_point = make_surface_point(quadrics)
    surface_uv = make_surface_uv(quadrics)

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
        if wp.static(instances):
            p, n, err = hit_point(geometry, prim, inst, o, d, t, time)
        else:
            p, n, err = surface_point(geometry, prim, o, d, t, time)
        hit.p = p
        hit.n = n
        hit.err = err
        hit.wo = -d
        hit.entering = wp.dot(d, n) < 0.0
        ns = n
        if wp.static(smooth):
            ns = shading_normal(geometry, prim, inst, p, n, time)
        hit.front = wp.dot(d, ns) < 0.0
        hit.n_facing = wp.where(hit.front, ns, -ns)
        hit.material = materials.shape_material[prim_shape(geometry, prim)]
        hit.shape = hit_shape(geometry, prim, inst)
        hit.uv = wp.vec2(0.0)
        if wp.static(textures):
            if materials.textures.kind.shape[0] > 0:  # the uv arrays are empty in a scene without textures
                hit.uv = surface_uv(geometry, prim, inst, p, time)
        return hit

    return surface_hit


surface_hit = make_surface_hit(True, True, True, True)
