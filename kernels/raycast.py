"""The "raycast" integrator: primary rays only, flat shading, AOVs.

Radiance of a pixel sample is ``albedo * |cos theta|`` of the first surface hit, theta between
its normal and the ray (a readable picture, not a physical one; lights are ignored), and 0 on a
miss. With ``spp == 1`` the single sample is the pixel centre; with ``spp > 1`` samples are
uniform over the pixel (box filter) and averaged.
"""
import warp as wp

from .camera import CameraData, camera_ray_direction
from .film import Film, facing_normal, write_aovs
from .sampling import sample_1d
from .traverse import NO_HIT, SceneData, closest_hit, prim_shape


@wp.struct
class MaterialData:
    """Per-shape material lookup and the diffuse albedo of each material (linear RGB)."""

    shape_material: wp.array(dtype=wp.int32)
    albedo: wp.array(dtype=wp.vec3)


@wp.func
def flat_shade(scene: SceneData, materials: MaterialData, o: wp.vec3, d: wp.vec3, t: float, prim: wp.int32) -> wp.vec3:
    """``albedo * |dot(n, d)|`` at the hit of unit ray ``o + t d``, black on a miss."""
    if prim == NO_HIT:
        return wp.vec3(0.0)
    n = facing_normal(scene, prim, o + t * d, d)
    albedo = materials.albedo[materials.shape_material[prim_shape(scene, prim)]]
    return albedo * wp.abs(wp.dot(n, d))


@wp.kernel
def raycast(
    scene: SceneData,
    materials: MaterialData,
    cam: CameraData,
    spp: wp.int32,
    seed: wp.int32,
    first_pixel: wp.int32,
    film: Film,
):
    """Render pixels ``first_pixel + tid`` (row-major) into ``film``."""
    pixel = first_pixel + wp.tid()
    x = pixel % cam.width
    y = pixel // cam.width
    d = camera_ray_direction(cam, x, y, 0.5, 0.5)
    t, prim = closest_hit(scene, cam.origin, d, 0.0, wp.inf)
    write_aovs(film, scene, pixel, cam.origin, d, t, prim)
    if spp == 1:
        film.rgb[pixel] = flat_shade(scene, materials, cam.origin, d, t, prim)
        return
    radiance = wp.vec3(0.0)
    for s in range(spp):
        ds = camera_ray_direction(cam, x, y, sample_1d(seed, pixel, s, 0), sample_1d(seed, pixel, s, 1))
        ts, prim_s = closest_hit(scene, cam.origin, ds, 0.0, wp.inf)
        radiance += flat_shade(scene, materials, cam.origin, ds, ts, prim_s)
    film.rgb[pixel] = radiance / float(spp)
