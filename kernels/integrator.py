"""The pixel loop shared by every integrator, and the settings they read.

``make_render_kernel(radiance)`` builds a kernel that, for each pixel of a tile, traces the
pixel-centre camera ray, writes the AOVs (``kernels.film``), and averages ``radiance(...)`` over
``spp`` samples: the centre ray itself when ``spp == 1``, uniform positions over the pixel (box
filter) otherwise. ``radiance`` receives the camera ray and its first hit already found, so a
one-sample render traces each primary ray once.

``make_render_kernel(radiance, record=True)`` builds the recording variant of the same loop: it
also appends every camera ray of a sample to a ``kernels.record.RayRecord`` and hands its index
to ``radiance`` as the parent of what follows (the pixel-centre AOV ray of a render with
``spp > 1`` is not a sample and is not recorded). The rendering variant compiles the recording
out. Recording variants go to their own Warp module, ``RECORD_MODULE``, so that loading a render
kernel never compiles them; build every variant at import, before the first launch, or Warp
recompiles the module.
"""
import warp as wp

from .camera import CameraData, camera_ray_direction
from .film import Film, write_aovs
from .lights import LightData
from .materials import MaterialData
from .record import CAMERA, RayRecord, record_ray
from .sampling import sample_1d
from .traverse import SceneData, closest_hit

RECORD_MODULE = "kernels.record_variants"


@wp.struct
class IntegratorSettings:
    """``[render]`` values the integrators read (see docs/scene-format.md)."""

    max_depth: wp.int32  # ray segments per path, the camera ray included
    ambient: wp.vec3
    background: wp.vec3  # radiance, W/(m^2 sr)
    exterior_ior: float
    filtered_shadows: wp.int32  # 1: shadow rays pass dielectrics with Beer-Lambert attenuation
    min_throughput: float


def make_render_kernel(radiance, record: bool = False):
    """A render kernel around the ``@wp.func``
    ``radiance(scene, materials, lights, settings, o, d, t, prim, rec, seed, pixel, sample, parent) -> vec3``.

    ``seed``, ``pixel`` and ``sample`` also key the random numbers of integrators that sample
    (``kernels.sampling.sample_1d``; dimensions 0 and 1 are the position in the pixel).

    ``rec``, ``pixel``, ``sample`` and ``parent`` (the record index of the camera ray) are for
    recording: with ``record=False`` the kernel passes an empty ``rec`` and ``radiance`` must not
    touch it (build it with recording compiled out).
    """

    @wp.kernel(module=RECORD_MODULE if record else None)
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
        rec: RayRecord,
    ):
        pixel = first_pixel + wp.tid()
        x = pixel % cam.width
        y = pixel // cam.width
        d = camera_ray_direction(cam, x, y, 0.5, 0.5)
        t, prim = closest_hit(scene, cam.origin, d, 0.0, wp.inf)
        write_aovs(film, scene, pixel, cam.origin, d, t, prim)
        parent = int(-1)
        if spp == 1:
            if wp.static(record):
                parent = record_ray(rec, scene, pixel, 0, CAMERA, cam.origin, d, t, prim, wp.vec3(1.0), 1, -1)
            film.rgb[pixel] = radiance(scene, materials, lights, settings, cam.origin, d, t, prim, rec, seed, pixel, 0, parent)
            return
        total = wp.vec3(0.0)
        for s in range(spp):
            ds = camera_ray_direction(cam, x, y, sample_1d(seed, pixel, s, 0), sample_1d(seed, pixel, s, 1))
            ts, prim_s = closest_hit(scene, cam.origin, ds, 0.0, wp.inf)
            if wp.static(record):
                parent = record_ray(rec, scene, pixel, s, CAMERA, cam.origin, ds, ts, prim_s, wp.vec3(1.0), 1, -1)
            total += radiance(scene, materials, lights, settings, cam.origin, ds, ts, prim_s, rec, seed, pixel, s, parent)
        film.rgb[pixel] = total / float(spp)

    return render_pixels
