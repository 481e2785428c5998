"""The "raycast" integrator: primary rays only, flat shading.

Radiance of a pixel sample is ``base_color * |cos theta|`` of the first surface hit, theta between
its shading normal (a smooth-shaded mesh's interpolated one) and the ray (a readable picture, not
a physical one; lights are ignored), and 0 on a miss. ``base_color`` is the albedo of diffuse
and Phong materials, the reflectance of mirrors and the transmittance of dielectrics; an albedo
texture is shown at the hit's uv (other textured parameters by their mean, ``base_color``).
Recording (``raycast_record``) sees only the camera rays, which the shared pixel loop records.
"""

import functools

import warp as wp

from .hit import make_surface_hit
from .integrator import CameraRay, IntegratorSettings, camera_hit
from .lights import LightData
from .materials import MaterialData
from .record import RayRecord
from .sampling import Sampler
from .textures import ALBEDO, material_rgb
from .traverse import NO_HIT, GeometryData


@functools.cache
def make_raycast_radiance(textures: bool):
    """``raycast_radiance``, with the hit's uv and the albedo texture lookup only when ``textures``."""
    surface_hit = make_surface_hit(True, True, True, textures)

    @wp.func
    def raycast_radiance(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        sampler: Sampler,
        ray: CameraRay,
        rec: RayRecord,
    ) -> wp.vec3:
        """``base_color * |dot(n, d)|`` at the camera ray's hit (``n`` its shading normal), black on a miss."""
        if ray.prim == NO_HIT:
            return wp.vec3(0.0)
        hit = surface_hit(geometry, materials, camera_hit(ray))
        color = materials.base_color[hit.material]
        if wp.static(textures):
            color = material_rgb(materials.textures, hit.material, ALBEDO, hit.tex, color)
        return color * wp.abs(wp.dot(hit.n_facing, ray.d))

    return raycast_radiance
