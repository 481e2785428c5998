"""The pixel loop shared by every integrator, and the settings they read.

``make_render_kernel(radiance)`` builds a kernel that, for each pixel of a tile, traces the
pixel-centre camera ray, writes the AOVs (``kernels.film``), and averages ``radiance(...)`` over
``spp`` samples: the centre ray itself when ``spp == 1``, uniform positions over the pixel (box
filter) otherwise. ``radiance`` receives the camera ray and its first hit already found, so a
one-sample render traces each primary ray once.
"""
import warp as wp

from .camera import CameraData, camera_ray_direction
from .film import Film, write_aovs
from .lights import LightData
from .materials import MaterialData
from .sampling import sample_1d
from .traverse import SceneData, closest_hit


@wp.struct
class IntegratorSettings:
    """``[render]`` values the integrators read (see docs/scene-format.md)."""

    max_depth: wp.int32  # ray segments per path, the camera ray included
    ambient: wp.vec3
    background: wp.vec3  # radiance, W/(m^2 sr)
    exterior_ior: float
    filtered_shadows: wp.int32  # 1: shadow rays pass dielectrics with Beer-Lambert attenuation
    min_throughput: float


def make_render_kernel(radiance):
    """A render kernel around the ``@wp.func`` ``radiance(scene, materials, lights, settings, o, d, t, prim) -> vec3``."""

    @wp.kernel
    def render_pixels(
        scene: SceneData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        cam: CameraData,
        spp: wp.int32,
        seed: wp.int32,
        first_pixel: wp.int32,
        film: Film,
    ):
        pixel = first_pixel + wp.tid()
        x = pixel % cam.width
        y = pixel // cam.width
        d = camera_ray_direction(cam, x, y, 0.5, 0.5)
        t, prim = closest_hit(scene, cam.origin, d, 0.0, wp.inf)
        write_aovs(film, scene, pixel, cam.origin, d, t, prim)
        if spp == 1:
            film.rgb[pixel] = radiance(scene, materials, lights, settings, cam.origin, d, t, prim)
            return
        total = wp.vec3(0.0)
        for s in range(spp):
            ds = camera_ray_direction(cam, x, y, sample_1d(seed, pixel, s, 0), sample_1d(seed, pixel, s, 1))
            ts, prim_s = closest_hit(scene, cam.origin, ds, 0.0, wp.inf)
            total += radiance(scene, materials, lights, settings, cam.origin, ds, ts, prim_s)
        film.rgb[pixel] = total / float(spp)

    return render_pixels
