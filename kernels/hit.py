"""A surface hit as the integrators see it: one struct, built by one function.

``surface_hit`` turns a traversal's ``(t, prim)`` for the unit ray ``o + s d`` into the hit point
(recomputed on the primitive's surface),
its unit geometric normal (outward for spheres and closed meshes, the winding normal for
triangles, the given normal for planes and polygons), its shading normal turned to the side the
ray comes from, the shape and material, and the bound on the point's rounding error that offsets
rays leaving it (``wrt.kernels.spawn``).

Two normals, as in Mitsuba 3 and pbrt: the shading normal (``shading_normal``: interpolated from
the vertex normals on smooth-shaded meshes, the geometric normal everywhere else; then tilted by
the material's normal map, ``perturbed_normal``, or its bump map, ``bumped_normal``) is the BSDF's:
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

from .materials import BSDF_ANISOTROPIC, MaterialData
from .sample_warps import frame
from .textures import BUMP_MAP, NORMAL_MAP, TextureEvalContext, texture_float_grad, texture_rgb, uv_context
from .traverse import (
    GeometryData,
    RayHit,
    hit_point,
    hit_shape,
    make_surface_derivatives,
    make_surface_point,
    make_texture_context,
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
    tex: TextureEvalContext  # where its textures are looked up (texture_context): uv ((0, 0) where the scene
    # has no textures) and, on a triangle, its index and barycentric coordinates
    n_unmapped: wp.vec3  # the shading normal before its normal map, flipped as n_facing (n_facing without one)
    tangent: wp.vec3  # the shading frame's unit tangent s (shading_tangent); zero at isotropic materials


@wp.func
def shading_tangent(n: wp.vec3, dpdu: wp.vec3) -> wp.vec3:
    """The unit tangent ``s`` of the shading frame of normal ``n``: the surface's ``dpdu``
    (``surface_derivatives``) made orthogonal to ``n`` (Gram-Schmidt) and normalised, Mitsuba 3's
    ``sh_frame.s``; where ``dpdu`` is zero or along ``n``, ``frame(n)``'s (Mitsuba's
    ``coordinate_system``)."""
    s = dpdu - wp.dot(n, dpdu) * n
    if wp.length_sq(s) > 0.0:
        return wp.normalize(s)
    basis = frame(n)
    return wp.vec3(basis[0, 0], basis[1, 0], basis[2, 0])


@wp.func
def perturbed_normal(n: wp.vec3, dpdu: wp.vec3, rgb: wp.vec3) -> wp.vec3:
    """The unit shading normal ``n`` (world space) tilted by a normal map's texel ``rgb`` (raw, in
    [0, 1]), as Mitsuba 3's ``normalmap``: the tangent-space normal ``m = normalize(2 rgb - 1)``
    taken to the world by the shading frame ``(s, t, n)``, ``s = shading_tangent(n, dpdu)`` and
    ``t = n x s`` (Mitsuba's ``sh_frame``). ``n`` itself (bit for bit) for ``m = (0, 0, 1)``, and
    where ``2 rgb - 1`` vanishes."""
    s = shading_tangent(n, dpdu)
    m = 2.0 * rgb - wp.vec3(1.0)
    if not (wp.length_sq(m) > 0.0):
        return n
    m = wp.normalize(m)
    return m[2] * n + (m[0] * s + m[1] * wp.cross(n, s))


@wp.func
def bumped_normal(ns: wp.vec3, n: wp.vec3, dpdu: wp.vec3, dpdv: wp.vec3, grad: wp.vec2) -> wp.vec3:
    """The unit shading normal ``ns`` (world space) of a surface with derivatives ``dpdu``, ``dpdv``
    displaced along ``ns`` by a height field of gradient ``grad`` (d/du, d/dv, times the bump
    map's scale; ``texture_float_grad``), as Mitsuba 3's ``bumpmap``: each derivative's component
    along ``ns`` replaced by the height's, their cross product normalised and turned to the side
    of the geometric normal ``n``."""
    du = dpdu + (grad[0] - wp.dot(ns, dpdu)) * ns
    dv = dpdv + (grad[1] - wp.dot(ns, dpdv)) * ns
    m = wp.cross(du, dv)
    if not (wp.length_sq(m) > 0.0):
        return ns
    m = wp.normalize(m)
    return wp.where(wp.dot(n, m) < 0.0, -m, m)


@wp.func
def normal_map_shadowing(hit: Hit, wi: wp.vec3) -> float:
    """The factor a normal- or bump-mapped BSDF's value and sample weight take for direction ``wi``
    (Mitsuba 3's ``normalmap`` and ``bumpmap``, their shadowing function after Estevez et al., "A
    Microfacet-Based Shadowing Function to Solve the Bump Terminator Problem", Ray Tracing Gems,
    2019): 0 where ``wi`` lies on
    different sides of the mapped and the unmapped shading normal, else the Smith G1 of ``wi``
    against the unmapped normal for a GGX alpha^2 of ``min(tan^2(tilt) / 8, 1)``, ``tilt`` the
    angle between the two normals; exactly 1 where the material has no normal map."""
    if hit.n_unmapped == hit.n_facing:
        return 1.0
    cos_i = wp.dot(hit.n_unmapped, wi)
    if cos_i * wp.dot(hit.n_facing, wi) <= 0.0:
        return 0.0
    cos_d2 = wp.min(wp.dot(hit.n_unmapped, hit.n_facing) ** 2.0, 1.0)
    alpha2 = wp.min(0.125 * (1.0 - cos_d2) / cos_d2, 1.0)
    cos_i2 = cos_i * cos_i
    return 2.0 / (1.0 + wp.sqrt(1.0 + alpha2 * (1.0 - cos_i2) / cos_i2))


@functools.cache
def make_surface_hit(
    smooth: bool, instances: bool, quadrics: bool, textures: bool, normal_map: bool = False, anisotropic: bool = False
):
    """``surface_hit``; without ``smooth`` (no smooth-shaded mesh in the scene) the shading normal
    is the geometric one, and its interpolation is compiled out; without ``textures`` so is the
    texture coordinates' computation (``uv`` stays (0, 0)); without ``normal_map`` (no material with
    a normal or bump map; a scene with one has ``textures``) so are the tangent and the map's lookup
    (raycast shades with the unperturbed normal); without ``anisotropic`` (no anisotropic
    material) so is the shading frame's tangent (``Hit.tangent`` stays zero, as it does at an
    isotropic material's hits); without ``instances`` no hit goes
    through an instance, and ``hit_point``'s transforms are compiled out; without ``quadrics`` (no
    disk or cylinder) neither is their surface point nor uv (compiled in, each costs a path tracer a fifth
    to a quarter of its time on the CPU, even when not taken)."""
    surface_point = make_surface_point(quadrics)
    texture_context = make_texture_context(quadrics)
    surface_derivatives = make_surface_derivatives(quadrics)

    @wp.func
    def surface_hit(
        geometry: GeometryData,
        materials: MaterialData,
        found: RayHit,
    ) -> Hit:
        """The hit of ray ``found`` (not ``NO_HIT``), as ``closest_hit`` returned it. The material
        is the primitive's own (a group member's); the shape is the instance's."""
        hit = Hit()
        prim = found.prim
        inst = found.inst
        time = found.time
        d = found.d
        if wp.static(instances):
            p, n, err = hit_point(geometry, found)
        else:
            p, n, err = surface_point(geometry, prim, found.o, d, found.t, time)
        hit.p = p
        hit.n = n
        hit.err = err
        hit.wo = -d
        hit.entering = wp.dot(d, n) < 0.0
        hit.material = materials.shape_material[prim_shape(geometry, prim)]
        hit.shape = hit_shape(geometry, prim, inst)
        hit.tex = uv_context(wp.vec2(0.0))
        if wp.static(textures):
            if materials.textures.kind.shape[0] > 0:  # the uv arrays are empty in a scene without textures
                hit.tex = texture_context(geometry, prim, inst, p, time)
        ns = n
        if wp.static(smooth):
            ns = shading_normal(geometry, prim, inst, p, n, time)
        ns0 = ns
        if wp.static(normal_map):
            t_map = materials.textures.slot[hit.material, NORMAL_MAP]
            t_bump = materials.textures.slot[hit.material, BUMP_MAP]
            if t_map >= 0 or t_bump >= 0:
                dpdu, dpdv = surface_derivatives(geometry, prim, inst, p, time)
                if t_map >= 0:
                    ns = perturbed_normal(ns, dpdu, texture_rgb(materials.textures, t_map, hit.tex))
                else:
                    grad = materials.bump_scale[hit.material] * texture_float_grad(materials.textures, t_bump, hit.tex)
                    ns = bumped_normal(ns, n, dpdu, dpdv, grad)
                if wp.dot(d, ns) * wp.dot(d, ns0) < 0.0:  # seen from below the mapped surface only
                    ns = 2.0 * wp.dot(ns, ns0) * ns0 - ns  # mirrored about the unmapped normal, as Mitsuba 3's
        hit.front = wp.dot(d, ns) < 0.0
        hit.n_facing = wp.where(hit.front, ns, -ns)
        hit.n_unmapped = hit.n_facing
        if wp.static(normal_map):
            hit.n_unmapped = wp.where(hit.front, ns0, -ns0)
        hit.tangent = wp.vec3(0.0)  # perpendicular to n_facing where set: the frame (s, n_facing x s, n_facing)
        if wp.static(anisotropic):
            if (materials.flags[hit.material] & BSDF_ANISOTROPIC) != 0:  # it, or a material it masks or blends
                dpdu, _dpdv = surface_derivatives(geometry, prim, inst, p, time)
                hit.tangent = shading_tangent(ns, dpdu)
        return hit

    return surface_hit


def make_surface_hit_for(features) -> wp.Function:
    """``make_surface_hit`` for a scene's ``wrt.kernels.features.Features``."""
    quadrics = features.disks or features.cylinders
    return make_surface_hit(
        features.smooth, features.instances, quadrics, features.textures, features.normal_map, features.anisotropic
    )


surface_hit = make_surface_hit(True, True, True, True, True, True)
