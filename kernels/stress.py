"""Kernels of the stress suite (``wrt stress``, ``wrt.stress``).

``trace_spawned`` follows a batch of rays to their first hit and, from each hit, spawns the
secondary rays an integrator would spawn there (shadow, mirror reflection, refraction), with the
one origin offset of ``wrt.kernels.spawn`` and the optics of ``wrt.kernels.optics``, then traces them.
The suite checks on the host that none of them falls back onto the surface it leaves.
"""

import warp as wp

from . import MODULE_OPTIONS, traverse
from .optics import reflect, refract
from .sample_warps import frame
from .spawn import spawn_origin
from .traverse import NO_HIT, GeometryData, any_hit, closest_hit

wp.set_module_options(MODULE_OPTIONS)

NOT_TRACED = wp.constant(-2)  # a secondary ray that does not exist (no first hit, or total internal reflection)


@wp.kernel
def trace_spawned(
    geometry: GeometryData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    shadow_local: wp.array(dtype=wp.vec3),
    ior: float,
    offset_scale: float,
    hit_t: wp.array(dtype=float),
    hit_prim: wp.array(dtype=wp.int32),
    hit_point: wp.array(dtype=wp.vec3),
    hit_normal: wp.array(dtype=wp.vec3),
    hit_err: wp.array(dtype=float),
    shadow_origin: wp.array(dtype=wp.vec3),
    shadow_dir: wp.array(dtype=wp.vec3),
    shadow_hit: wp.array(dtype=wp.int32),
    reflect_origin: wp.array(dtype=wp.vec3),
    reflect_dir: wp.array(dtype=wp.vec3),
    reflect_t: wp.array(dtype=float),
    reflect_prim: wp.array(dtype=wp.int32),
    refract_origin: wp.array(dtype=wp.vec3),
    refract_dir: wp.array(dtype=wp.vec3),
    refract_t: wp.array(dtype=float),
    refract_prim: wp.array(dtype=wp.int32),
):
    """First hit of each ray (unit directions), then its three secondary rays, traced to (0, inf).

    The shadow ray's direction is ``shadow_local[i]`` (unit, z >= 0) in a frame whose z axis is the
    normal on the side the ray arrived from, so z near 0 makes it graze the surface; the
    refracted ray enters (or leaves) a dielectric of index ``ior`` in vacuum. ``offset_scale``
    multiplies the spawn offset (``surface_point``'s ``err``) (1 = the renderer's; smaller values measure how
    much of it is needed). Secondary rays that do not exist get prim ``NOT_TRACED``.
    """
    i = wp.tid()
    o = origins[i]
    d = directions[i]
    t, prim, inst = closest_hit(geometry, o, d, 0.0, 0.0, wp.inf)
    hit_t[i] = t
    hit_prim[i] = prim
    shadow_hit[i] = NOT_TRACED
    reflect_prim[i] = NOT_TRACED
    refract_prim[i] = NOT_TRACED
    if prim == NO_HIT:
        return
    p, n, err = traverse.hit_point(geometry, traverse.ray_hit(o, d, 0.0, t, prim, inst))
    entering = wp.dot(d, n) < 0.0
    n_facing = n
    eta = 1.0 / ior
    if not entering:
        n_facing = -n
        eta = ior
    hit_point[i] = p
    hit_normal[i] = n
    hit_err[i] = err  # the renderer's offset; rays below are spawned with offset_scale of it
    err = err * offset_scale
    wi = frame(n_facing) * shadow_local[i]
    o_shadow = spawn_origin(p, n_facing, err, wi)
    shadow_origin[i] = o_shadow
    shadow_dir[i] = wi
    shadow_hit[i] = wp.where(any_hit(geometry, o_shadow, wi, 0.0, 0.0, wp.inf), 1, 0)
    wr = reflect(d, n_facing)
    o_reflect = spawn_origin(p, n, err, wr)
    reflect_origin[i] = o_reflect
    reflect_dir[i] = wr
    tr, pr, _ir = closest_hit(geometry, o_reflect, wr, 0.0, 0.0, wp.inf)
    reflect_t[i] = tr
    reflect_prim[i] = pr
    ok, wt = refract(d, n_facing, eta)
    if ok:
        o_refract = spawn_origin(p, n, err, wt)
        refract_origin[i] = o_refract
        refract_dir[i] = wt
        tt, pt, _it = closest_hit(geometry, o_refract, wt, 0.0, 0.0, wp.inf)
        refract_t[i] = tt
        refract_prim[i] = pt
