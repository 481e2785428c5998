"""The pixel loop shared by every integrator, and the settings they read.

A kernel reads a scene as its geometry, materials, lights, settings and camera (the structs of
``wrt.renderer.DeviceScene``), and takes the pixels and samples of a launch as a ``RenderPass``.
They stay separate kernel arguments: bundled into one nested struct, each access copies it, and
whitted renders took 25% longer (see docs/performance.md). ``make_render_kernel(radiance)``
builds a kernel that, for each pixel of a tile, traces the
pixel-centre camera ray at mid-shutter, writes the AOVs (``wrt.kernels.film``), and averages
``radiance(...)`` over ``spp`` samples: the centre ray itself when ``spp == 1``; otherwise film
positions drawn from the pixel filter, lens positions and shutter times, from the sampler.
``radiance`` receives the camera ray and its first hit already found (a ``CameraRay``), so a
one-sample render traces each primary ray once. ``make_trace_segment`` is the one way every
integrator traces (and, in recording variants, records) a ray segment.

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
out. Every kernel goes to a Warp module of its own (``module``), so that loading a render kernel
never compiles another; ``wrt.kernels.MODULE_OPTIONS`` and the integrator's ``options`` are that
module's Warp options.
"""

import warp as wp

from . import MODULE_OPTIONS
from .camera import CameraData, clip_ray, film_position, make_generate_ray, shutter_time, thin_lens_ray
from .features import ALL, Features
from .film import Film, luminance, write_aovs
from .lights import LightData
from .materials import MaterialData
from .media import Media
from .record import CAMERA, RayRecord, record_ray
from .sample_warps import concentric_disk
from .sampling import Sampler, sample_1d, sample_2d
from .traverse import NO_HIT, GeometryData, RayHit, Traversal, ray_hit, traversal


@wp.struct
class IntegratorSettings:
    """``[render]`` values the integrators read (see docs/scene-format.md)."""

    max_depth: wp.int32  # ray segments per path, the camera ray included
    ambient: wp.vec3
    background: wp.vec3  # radiance, W/(m^2 sr)
    exterior_ior: float
    filtered_shadows: wp.int32  # 1: shadow rays pass dielectrics with Beer-Lambert attenuation
    min_throughput: float
    camera_media: Media  # the dielectrics the camera is inside, outermost first (wrt.bake.camera_media)
    camera_n_media: wp.int32
    camera_medium: wp.int32  # the participating medium the camera is in (wrt.kernels.volumes); -1: vacuum


@wp.struct
class RenderPass:
    """The pixels and samples of one launch: samples ``first_sample .. first_sample + pass_spp - 1``
    of pixels ``first_pixel + tid``, or of ``active[first_pixel + tid]`` when ``active`` is not empty."""

    first_sample: wp.int32
    pass_spp: wp.int32
    first_pixel: wp.int32
    active: wp.array(dtype=wp.int32)


@wp.struct
class CameraRay:
    """A camera ray handed to an integrator: unit ray ``o + s d`` at ray ``time``, its first hit
    ``(t, prim, inst)`` (``NO_HIT`` on a miss), the pixel sample it belongs to (keys the random numbers
    and the records) and its record index (recording variants; -1 otherwise)."""

    o: wp.vec3
    d: wp.vec3
    time: float
    t: float
    prim: wp.int32
    inst: wp.int32  # the instance ``prim`` was hit through; -1: none
    pixel: wp.int32
    sample: wp.int32
    record: wp.int32


@wp.func
def camera_hit(ray: CameraRay) -> RayHit:
    """The camera ray ``ray`` and its first hit, as one ``RayHit``."""
    return ray_hit(ray.o, ray.d, ray.time, ray.t, ray.prim, ray.inst)


def make_trace_segment(record: bool, trace: Traversal):
    """``trace_segment``, recording the segment when ``record`` (compiled out otherwise)."""

    @wp.func
    def trace_segment(
        geometry: GeometryData,
        rec: RayRecord,
        ray: CameraRay,
        kind: wp.int32,
        o: wp.vec3,
        d: wp.vec3,
        t_from: float,
        t_max: float,
        t_last: float,
        throughput: wp.vec3,
        depth: wp.int32,
        parent: wp.int32,
    ):
        """The closest hit of unit ray ``o + s d`` for ``t_from < s < t_max``, at the time of camera ray
        ``ray`` (a ``RayHit``; ``t = inf`` on a miss, ``t_max`` finite or not), and the record index of the
        segment from ``o + t_last d`` to it (of ``kind``, carrying ``throughput``, segment ``depth`` of
        its path, child of record ``parent``; ``parent`` itself when not recording)."""
        t, prim, inst = trace.closest_hit(geometry, o, d, ray.time, t_from, t_max)
        if prim == NO_HIT:  # a camera ray that reaches the far clip plane leaves the scene too
            t = wp.inf
        index = parent
        if wp.static(record):
            index = record_ray(
                rec,
                geometry,
                ray.pixel,
                ray.sample,
                kind,
                ray_hit(o + t_last * d, d, ray.time, t - t_last, prim, inst),
                throughput,
                depth,
                parent,
            )
        return ray_hit(o, d, ray.time, t, prim, inst), index

    return trace_segment


def make_camera_sample(features: Features):
    """``camera_sample(cam, sampler, pixel, x, y, s, centre_o, centre, mid_shutter, dims) -> (o, d,
    time)``: the camera ray of sample ``s`` of the film pixel ``(x, y)``, whose random numbers
    ``pixel`` keys: the pixel-centre ray ``centre_o, centre`` at ``mid_shutter`` when ``spp == 1``;
    otherwise a film position drawn from the pixel filter (dimensions ``dims[0]`` and the next), a
    lens position (``dims[1]`` and the next; with ``features.lens``) and a shutter time (``dims[2]``;
    with ``features.motion``)."""
    generate_ray = make_generate_ray(features.orthographic)

    @wp.func
    def camera_sample(
        cam: CameraData,
        sampler: Sampler,
        pixel: wp.int32,
        x: wp.int32,
        y: wp.int32,
        s: wp.int32,
        centre_o: wp.vec3,
        centre: wp.vec3,
        mid_shutter: float,
        dims: wp.vec3i,
    ):
        o = centre_o
        d = centre
        time = mid_shutter
        if sampler.spp > 1:
            uv = film_position(cam, sample_2d(sampler, pixel, s, dims[0]))
            o, d = generate_ray(cam, x, y, uv[0], uv[1])
            if wp.static(features.lens):
                lens = sample_2d(sampler, pixel, s, dims[1])
                o, d = thin_lens_ray(cam, o, d, concentric_disk(lens[0], lens[1]))
            if wp.static(features.motion):
                time = shutter_time(cam, sample_1d(sampler, pixel, s, dims[2]))
        return o, d, time

    return camera_sample


def make_render_kernel(
    radiance,
    *,
    module: str,
    record: bool = False,
    features: Features = ALL,
    options: dict | None = None,
    inline: bool | None = None,
):
    """A render kernel around the ``@wp.func`` ``radiance(geometry: GeometryData, materials: MaterialData,
    lights: LightData, settings: IntegratorSettings, sampler: Sampler, ray: CameraRay, rec: RayRecord) -> vec3``.

    ``sampler``, ``ray.pixel`` and ``ray.sample`` key the random numbers of integrators that sample
    (``wrt.kernels.sampling``); the pixel loop uses dimensions 0-1 (position in the pixel), 2-3 (lens)
    and 4 (time in the shutter interval).

    ``rec`` and ``ray.record`` (the record index of the camera ray) are for recording: with
    ``record=False`` the kernel passes an empty ``rec`` and ``radiance`` must not touch it (build it
    with recording compiled out).

    ``features``: without ``lens`` the camera is taken to be a pinhole, without ``orthographic``
    a perspective camera, and without ``motion`` every sample is at mid-shutter (no lens or time
    sampling); ``module``: the name of the Warp module to put the kernel in, whose Warp options are
    ``MODULE_OPTIONS`` and ``options``; ``inline``: the camera rays' traversal's inline
    hint (``wrt.kernels.traverse.Traversal``).
    """

    trace = traversal(features, inline)
    trace_segment = make_trace_segment(record, trace)
    generate_ray = make_generate_ray(features.orthographic)
    camera_sample = make_camera_sample(features)

    @wp.func
    def camera_ray(
        geometry: GeometryData,
        rec: RayRecord,
        pixel: wp.int32,
        sample: wp.int32,
        o: wp.vec3,
        d: wp.vec3,
        t_max: float,
        time: float,
    ) -> CameraRay:
        """The camera ray of one pixel sample, clipped (``o`` on the near clip plane, ``t_max`` at the
        far one), traced (and recorded)."""
        ray = CameraRay()
        ray.o = o
        ray.d = d
        ray.time = time
        ray.pixel = pixel
        ray.sample = sample
        found, index = trace_segment(geometry, rec, ray, CAMERA, o, d, 0.0, t_max, 0.0, wp.vec3(1.0), 1, -1)
        ray.t = found.t
        ray.prim = found.prim
        ray.inst = found.inst
        ray.record = index
        return ray

    @wp.kernel(module=module)
    def render_pixels(
        geometry: GeometryData,
        materials: MaterialData,
        lights: LightData,
        settings: IntegratorSettings,
        cam: CameraData,
        sampler: Sampler,
        launch: RenderPass,
        film: Film,
        rec: RayRecord,
    ):
        pixel = launch.first_pixel + wp.tid()
        if launch.active.shape[0] > 0:  # adaptive sampling: only the pixels still sampled
            pixel = launch.active[launch.first_pixel + wp.tid()]
        x = pixel % cam.width
        y = pixel // cam.width
        mid_shutter = shutter_time(cam, 0.5)
        centre_o, centre = generate_ray(cam, x, y, 0.5, 0.5)
        first = launch.first_sample
        total = wp.vec3(0.0)
        total_sq = float(0.0)
        rejected = int(0)
        if first > 0:
            total = film.rgb_sum[pixel]
            total_sq = film.luminance_sq_sum[pixel]
            rejected = film.rejected[pixel]
        elif sampler.spp > 1:  # the AOVs' pixel-centre ray is not a sample
            o, t_max = clip_ray(cam, centre_o, centre)
            t, prim, inst = trace.closest_hit(geometry, o, centre, mid_shutter, 0.0, t_max)
            write_aovs(film, geometry, pixel, ray_hit(o, centre, mid_shutter, t, prim, inst))
        for s in range(first, first + launch.pass_spp):
            o, d, time = camera_sample(cam, sampler, pixel, x, y, s, centre_o, centre, mid_shutter, wp.vec3i(0, 2, 4))
            o, t_max = clip_ray(cam, o, d)
            ray = camera_ray(geometry, rec, pixel, s, o, d, t_max, time)
            if sampler.spp == 1:  # the pixel-centre ray is the sample, and gives the AOVs
                write_aovs(film, geometry, pixel, camera_hit(ray))
            value = radiance(geometry, materials, lights, settings, sampler, ray, rec)
            lum = luminance(value)
            if wp.isfinite(total + value) and wp.isfinite(lum * lum):
                total += value
                total_sq += lum * lum
            else:  # NaN, Inf or an overflowing sum must not poison the pixel: counted, taken as 0
                rejected += 1
        film.rgb_sum[pixel] = total
        film.luminance_sq_sum[pixel] = total_sq
        film.rejected[pixel] = rejected
        film.rgb[pixel] = total / float(first + launch.pass_spp)

    wp.set_module_options({**MODULE_OPTIONS, **(options or {})}, module=module)
    return render_pixels
