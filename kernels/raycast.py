"""The "raycast" integrator: primary rays only, flat shading.

Radiance of a pixel sample is ``base_color * |cos theta|`` of the first surface hit, theta between
its normal and the ray (a readable picture, not a physical one; lights are ignored), and 0 on a
miss. ``base_color`` is the albedo of diffuse and Phong materials, the reflectance of mirrors and
the transmittance of dielectrics. Recording (``raycast_record``) sees only the camera rays,
which the shared pixel loop records.
"""

import warp as wp

from .film import facing_normal
from .integrator import IntegratorSettings, make_render_kernel
from .lights import LightData
from .materials import MaterialData
from .record import RayRecord
from .sampling import Sampler
from .traverse import NO_HIT, GeometryData, prim_shape


@wp.func
def raycast_radiance(
    geometry: GeometryData,
    materials: MaterialData,
    lights: LightData,
    settings: IntegratorSettings,
    o: wp.vec3,
    d: wp.vec3,
    t: float,
    prim: wp.int32,
    time: float,
    rec: RayRecord,
    sampler: Sampler,
    pixel: wp.int32,
    sample: wp.int32,
    parent: wp.int32,
) -> wp.vec3:
    """``base_color * |dot(n, d)|`` at the hit of unit ray ``o + t d``, black on a miss."""
    if prim == NO_HIT:
        return wp.vec3(0.0)
    n = facing_normal(geometry, prim, o + t * d, d, time)
    color = materials.base_color[materials.shape_material[prim_shape(geometry, prim)]]
    return color * wp.abs(wp.dot(n, d))


raycast = make_render_kernel(raycast_radiance)
raycast_record = make_render_kernel(raycast_radiance, record=True)
