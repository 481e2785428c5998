"""The pixel loop shared by every integrator, and the settings they read.

``make_render_kernel(radiance)`` builds a kernel that, for each pixel of a tile, traces the
pixel-centre camera ray at mid-shutter, writes the AOVs (``wrt.kernels.film``), and averages
``radiance(...)`` over ``spp`` samples: the centre ray itself when ``spp == 1``; otherwise film
positions drawn from the pixel filter, lens positions and shutter times, from the sampler.
``radiance`` receives the camera ray and its first hit already found, so a one-sample render
traces each primary ray once.

A launch takes the samples ``first_sample .. first_sample + pass_spp - 1`` of a render of ``spp``
samples (a progressive render is several launches, or passes). It continues the pixel's running
float32 sum ``film.rgb_sum`` in sample order and writes ``film.rgb = rgb_sum / samples so far``
(and the sum of squared luminances, for error estimates); the AOVs are written by the pass with
``first_sample == 0``. With a non-empty ``active`` list (adaptive sampling) the launch's threads
take the pixels ``active[first_pixel + tid]`` instead of ``first_pixel + tid``. The additions
happen in the same order however the samples are cut into passes, so the image is bit-identical
to a one-pass render.

``make_render_kernel(radiance, record=True)`` builds the recording variant of the same loop: it
also appends every camera ray of a sample to a ``wrt.kernels.record.RayRecord`` and hands its index
to ``radiance`` as the parent of what follows (the pixel-centre AOV ray of a render with
``spp > 1`` is not a sample and is not recorded). The rendering variant compiles the recording
out. Recording variants go to their own Warp module, ``RECORD_MODULE``, so that loading a render
kernel never compiles them; build every variant at import, before the first launch, or Warp
recompiles the module.
"""

import warp as wp

from .camera import CameraData, camera_ray_direction, film_position, shutter_time, thin_lens_ray
from .features import ALL, Features
from .film import Film, luminance, write_aovs
from .lights import LightData
from .materials import MaterialData
from .record import CAMERA, RayRecord, record_ray
from .sample_warps import concentric_disk
from .sampling import Sampler, sample_1d, sample_2d
from .traverse import GeometryData, traversal

RECORD_MODULE = "wrt.kernels.record_variants"


@wp.struct
class IntegratorSettings:
    """``[render]`` values the integrators read (see docs/scene-format.md)."""

    max_depth: wp.int32  # ray segments per path, the camera ray included
    ambient: wp.vec3
    background: wp.vec3  # radiance, W/(m^2 sr)
    exterior_ior: float
    filtered_shadows: wp.int32  # 1: shadow rays pass dielectrics with Beer-Lambert attenuation
    min_throughput: float


def make_render_kernel(radiance, record: bool = False, features: Features = ALL, module: str | None = None):
    """A render kernel around the ``@wp.func``
    ``radiance(scene, materials, lights, settings, o, d, t, prim, time, rec, sampler, pixel, sample, parent) -> vec3``.

    ``sampler``, ``pixel`` and ``sample`` key the random numbers of integrators that sample
    (``wrt.kernels.sampling``); the pixel loop uses dimensions 0-1 (position in the pixel), 2-3 (lens)
    and 4 (time in the shutter interval); ``time`` is the ray time of the camera ray.

    ``rec``, ``pixel``, ``sample`` and ``parent`` (the record index of the camera ray) are for
    recording: with ``record=False`` the kernel passes an empty ``rec`` and ``radiance`` must not
    touch it (build it with recording compiled out).

    ``features``: without ``lens`` the camera is taken to be a pinhole and without ``motion``
    every sample is at mid-shutter (no lens or time sampling); ``module``: the Warp module to put
    the kernel in (default: this file's, or ``RECORD_MODULE`` for recording variants).
    """

    trace = traversal(features)

    @wp.kernel(module=module or (RECORD_MODULE if record else None))
    def render_pixels(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        cam: CameraData,
        sampler: Sampler,
        first_sample: wp.int32,
        pass_spp: wp.int32,
        first_pixel: wp.int32,
        active: wp.array(dtype=wp.int32),
        film: Film,
        rec: RayRecord,
    ):
        pixel = first_pixel + wp.tid()
        if active.shape[0] > 0:  # adaptive sampling: only the pixels still sampled
            pixel = active[first_pixel + wp.tid()]
        x = pixel % cam.width
        y = pixel // cam.width
        parent = int(-1)
        total = wp.vec3(0.0)
        total_sq = float(0.0)
        time = shutter_time(cam, 0.5)
        if first_sample == 0:
            d = camera_ray_direction(cam, x, y, 0.5, 0.5)
            t, prim = trace.closest_hit(geometry, cam.origin, d, time, 0.0, wp.inf)
            write_aovs(film, geometry, pixel, cam.origin, d, t, prim, time)
            if sampler.spp == 1:
                if wp.static(record):
                    parent = record_ray(
                        rec, geometry, pixel, 0, CAMERA, cam.origin, d, t, prim, time, wp.vec3(1.0), 1, -1
                    )
                total = radiance(
                    geometry, materials, lights, settings, cam.origin, d, t, prim, time, rec, sampler, pixel, 0, parent
                )
                film.rgb_sum[pixel] = total
                film.luminance_sq_sum[pixel] = luminance(total) * luminance(total)
                film.rgb[pixel] = total
                return
        else:
            total = film.rgb_sum[pixel]
            total_sq = film.luminance_sq_sum[pixel]
        for s in range(first_sample, first_sample + pass_spp):
            uv = film_position(cam, sample_2d(sampler, pixel, s, 0))
            pinhole = camera_ray_direction(cam, x, y, uv[0], uv[1])
            o_s = cam.origin
            ds = pinhole
            if wp.static(features.lens):
                lens = sample_2d(sampler, pixel, s, 2)
                o_s, ds = thin_lens_ray(cam, pinhole, concentric_disk(lens[0], lens[1]))
            time_s = time
            if wp.static(features.motion):
                time_s = shutter_time(cam, sample_1d(sampler, pixel, s, 4))
            ts, prim_s = trace.closest_hit(geometry, o_s, ds, time_s, 0.0, wp.inf)
            if wp.static(record):
                parent = record_ray(rec, geometry, pixel, s, CAMERA, o_s, ds, ts, prim_s, time_s, wp.vec3(1.0), 1, -1)
            value = radiance(
                geometry, materials, lights, settings, o_s, ds, ts, prim_s, time_s, rec, sampler, pixel, s, parent
            )
            total += value
            total_sq += luminance(value) * luminance(value)
        film.rgb_sum[pixel] = total
        film.luminance_sq_sum[pixel] = total_sq
        film.rgb[pixel] = total / float(first_sample + pass_spp)

    return render_pixels
