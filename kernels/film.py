"""The film: per-pixel output arrays written by every integrator, and the AOV convention.

Pixels are stored row-major, index ``y * width + x`` with row 0 at the top of the image.
AOVs (arbitrary output variables) describe the primary ray through the pixel CENTRE
(u = v = 0.5), whatever the spp, so they are exact and deterministic:

- ``depth``     distance t along the unit camera ray to the first hit (world units), +inf on a miss
- ``normal``    unit shading normal at the hit (the geometric normal, or on a smooth-shaded mesh the
  interpolated one), world space, on the side of the surface the camera sees; 0 on a miss
- ``object_id`` index of the hit shape in the scene file's ``[[shape]]`` list, -1 on a miss,
  ``-2 - k`` on the surface of light k (area and sphere lights are not shapes)
- ``position``  world-space hit point; 0 on a miss
"""

import warp as wp

from .traverse import NO_HIT, GeometryData, RayHit, hit_point, hit_shape, shading_normal

LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)  # Y of linear Rec. 709 RGB (host code reads them too)


@wp.func
def luminance(rgb: wp.vec3) -> float:
    """Luminance Y of linear Rec. 709 RGB (``LUMINANCE_WEIGHTS``)."""
    return (
        wp.static(LUMINANCE_WEIGHTS[0]) * rgb[0]
        + wp.static(LUMINANCE_WEIGHTS[1]) * rgb[1]
        + wp.static(LUMINANCE_WEIGHTS[2]) * rgb[2]
    )


@wp.struct
class Film:
    rgb: wp.array(dtype=wp.vec3)  # linear radiance, W/(m^2 sr): rgb_sum / samples so far
    rgb_sum: wp.array(dtype=wp.vec3)  # running float32 sum of the samples so far, in sample order
    luminance_sq_sum: wp.array(dtype=float)  # running sum of the samples' squared luminance (error estimates)
    rejected: wp.array(dtype=wp.int32)  # samples so far whose radiance was NaN or Inf (taken as 0)
    depth: wp.array(dtype=float)
    normal: wp.array(dtype=wp.vec3)
    object_id: wp.array(dtype=wp.int32)
    position: wp.array(dtype=wp.vec3)


@wp.func
def write_aovs(
    film: Film,
    geometry: GeometryData,
    pixel: wp.int32,
    found: RayHit,
):
    """Record the AOVs of the pixel-centre ray and what it hit (or that it missed), ``found``."""
    prim = found.prim
    inst = found.inst
    if prim == NO_HIT:
        film.depth[pixel] = wp.inf
        film.normal[pixel] = wp.vec3(0.0)
        film.object_id[pixel] = -1
        film.position[pixel] = wp.vec3(0.0)
    else:
        p, n, _err = hit_point(geometry, found)
        ns = shading_normal(geometry, prim, inst, p, n, found.time)
        film.depth[pixel] = found.t
        film.normal[pixel] = wp.where(wp.dot(n, found.d) > 0.0, -ns, ns)  # on the side the camera sees
        surface = hit_shape(geometry, prim, inst)
        if surface >= geometry.num_shapes:  # the surface of light k is not a shape: -2 - k
            surface = geometry.num_shapes - 2 - surface
        film.object_id[pixel] = surface
        film.position[pixel] = p
