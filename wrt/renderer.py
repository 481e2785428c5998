"""Render orchestration: scene -> primitives + BVH -> device arrays -> integrator kernel -> numpy.

One pass loop (``render_passes``: progressive, adaptive or one pass, and the ``RenderResult``)
serves every render; a tile executor (``TileExecutor``) runs each pass. ``LocalTiles`` is this
machine's: on the CPU a Warp launch runs on one thread but releases the GIL, so the image is cut
into tiles of consecutive pixels launched from a thread pool; on CUDA the whole image is one
launch. ``wrt.distributed`` runs the tiles as tasks on a Dask cluster. Every pixel's value
depends only on (scene, seed, pixel, sample), never on the tiling, threads or executor: results
are bit-identical whatever runs the tiles.

With a ``progress`` callback, ``render`` draws the samples in passes of about ``PASS_SECONDS``
each (samples ``a .. b - 1`` of every pixel per pass) and reports after each; the film keeps a
running sum per pixel that every pass continues in sample order, so the image is bit-identical to
a one-pass render whatever the passes, and a render stopped early holds exactly the image of a
render with the samples done.

``prepare`` is the one set-up path (BVH build, uploads, film) for every launch of an integrator
kernel: ``render`` launches the rendering variants over the image, ``wrt.rays`` the recording
variants over chosen pixels.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from typing import Protocol

import numpy as np
import warp as wp

from wrt.kernels.features import ALL, Features
from wrt.kernels.film import LUMINANCE_WEIGHTS, Film
from wrt.kernels.integrator import RenderPass
from wrt.kernels.materials import FAMILIES, FAMILY_OF
from wrt.kernels.ptracer import FIXED_POINT, LightTracing
from wrt.kernels.record import RayRecord
from wrt.kernels.variants import render_kernel

from .aot import compiled, load
from .device import (
    camera_data,
    integrator_settings,
    resolve_device,
    sampler_data,
    upload_geometry,
    upload_lights,
    upload_materials,
)
from .emitting import emitting_shapes
from .errors import WrtError
from .geometry import build
from .host import default_threads
from .light_tracing import bounding_sphere
from .loader import override_render
from .scene import (
    AreaLight,
    Cylinder,
    Disk,
    EnvironmentLight,
    Instance,
    Mesh,
    Polygon,
    Scene,
    Sphere,
    SphereLight,
    Triangle,
    constituents,
)

TILE_PIXELS = 4096  # pixels per CPU launch: small enough to balance two threads, large enough to amortise a launch
PASS_SECONDS = 1.0  # wall seconds a pass of a progressive render aims at
AOV_NAMES = ("depth", "normal", "object_id", "position")  # film arrays the first pass writes
PASS_STATE = ("rgb_sum", "luminance_sq_sum", "rejected")  # film arrays a pass continues from the previous one
NO_RECORD = RayRecord()  # what the rendering variants get for the record buffer they never touch
SPECIALIZE_MIN_SAMPLES = 1 << 16  # pixel samples from which a render takes its scene's variant when Warp's cache has it
SPECIALIZE_COLD_SAMPLES = 1 << 27  # and from which it compiles the variant when not (docs/performance.md)
ADAPTIVE_FIRST_PASS = 16  # samples every pixel takes before adaptive sampling may stop it
ADAPTIVE_FLOOR = 0.01  # luminance below which an adaptive pixel's error is measured absolutely


def scene_features(scene: Scene) -> Features:
    """The ``wrt.kernels.features.Features`` ``scene`` needs: its kernels are specialised on them."""
    members = [shape for group in scene.groups for shape in group.shapes]
    by_name = {m.name: m for m in scene.materials}
    used = {c for shape in (*scene.shapes, *members) for c in constituents(scene.materials[shape.material], by_name)}
    moving = any(any(shape.velocity) for shape in scene.shapes)
    shapes = {type(shape) for shape in (*scene.shapes, *members)} | {type(light) for light in scene.lights}
    return Features(
        lights=bool(scene.lights),
        environment_map=any(isinstance(light, EnvironmentLight) and light.image is not None for light in scene.lights),
        emissive=bool(emitting_shapes(scene)),
        emissive_shapes=bool(emitting_shapes(scene, (Polygon, Sphere))),
        specular=any(FAMILY_OF[m.type].sends_specular_rays(m) for m in used),
        dielectric=any(FAMILY_OF[m.type].medium for m in used),
        **{family.feature: any(FAMILY_OF[m.type] is family for m in used) for family in FAMILIES if family.feature},
        lens=scene.camera.aperture_radius > 0.0,
        orthographic=scene.camera.type == "orthographic",
        motion=moving and scene.camera.shutter[1] > scene.camera.shutter[0],
        moving=moving,
        spheres=bool(shapes & {Sphere, SphereLight}),
        triangles=bool(shapes & {Triangle, Mesh}),
        polygons=bool(shapes & {Polygon, AreaLight}),
        disks=Disk in shapes,
        cylinders=Cylinder in shapes,
        instances=Instance in shapes,
        smooth=any(isinstance(shape, Mesh) and shape.normals is not None for shape in (*scene.shapes, *members)),
        textures=any(m.textures for m in used),
        normal_map=any(name in ("normal_map", "bump_map") for m in used for name, _ in m.textures),
        media=bool(scene.media),
        beckmann=any(m.distribution == "beckmann" for m in used),
        anisotropic=any(m.anisotropic for m in used),
    )


def render_kernel_for(scene: Scene, specialize: bool | None, dev: wp.context.Device):
    """The rendering kernel of ``scene``'s integrator on ``dev``: specialised on
    ``scene_features(scene)`` for ``specialize=True``, all-features for False. For None
    (``render``'s rule), by the render's pixel samples (width x height x spp): all-features below
    ``SPECIALIZE_MIN_SAMPLES``; from there the variant where Warp's kernel cache has it (a load
    costs milliseconds); from ``SPECIALIZE_COLD_SAMPLES`` on the variant always, as the render is
    then long enough to pay its first compilation (10-30 CPU-seconds against a render 3-26%
    faster). The image is the same either way."""
    integrator, cuda = scene.render.integrator, dev.is_cuda
    if specialize is None:
        samples = scene.render.width * scene.render.height * scene.render.spp
        if samples < SPECIALIZE_MIN_SAMPLES:
            return render_kernel(integrator, ALL, cuda)
        variant = render_kernel(integrator, scene_features(scene), cuda)
        if samples >= SPECIALIZE_COLD_SAMPLES or compiled(variant, dev):
            return variant
        return render_kernel(integrator, ALL, cuda)
    return render_kernel(integrator, scene_features(scene) if specialize else ALL, cuda)


@dataclass
class RenderResult:
    """A rendered image (linear float32 RGB, row 0 at the top) and its AOVs.

    ``aovs``: ``depth`` (H, W) float32, distance along the unit camera ray from where it starts
    (the camera, or its near clip plane), inf on a miss;
    ``normal`` (H, W, 3) world space, facing the camera; ``object_id`` (H, W) int32, -1 on a miss;
    ``position`` (H, W, 3) world space. ``spp``: the samples per pixel in ``rgb`` (fewer than asked
    when a progress callback stopped the render). Times are wall seconds: ``build_time_s`` for the
    BVH, ``compile_time_s`` for loading kernels (near 0 with a warm cache), ``render_time_s`` for the launches.
    ``rejected_samples``: samples whose radiance came out NaN or Inf, taken as 0 (black) so that no
    pixel is poisoned; a correct scene has none (``wrt render`` warns when there are).
    """

    rgb: np.ndarray
    aovs: dict[str, np.ndarray]
    spp: int
    seed: int
    integrator: str
    device: str
    threads: int
    build_time_s: float
    compile_time_s: float
    render_time_s: float
    rejected_samples: int = 0


@dataclass
class DeviceScene:
    """Everything an integrator kernel reads of a scene, on one device, and the film it writes (W x H pixels)."""

    device: wp.context.Device
    width: int
    height: int
    geometry: object  # wrt.kernels.traverse.GeometryData
    materials: object  # wrt.kernels.materials.MaterialData
    lights: object  # wrt.kernels.lights.LightData
    settings: object  # wrt.kernels.integrator.IntegratorSettings
    camera: object  # wrt.kernels.camera.CameraData
    film: Film
    build_time_s: float  # wall seconds of the BVH build
    sampler: str  # [render] sampler
    no_active: wp.array  # empty: every pixel of the launch's range is sampled

    def launch(
        self,
        kernel,
        first: int,
        count: int,
        spp: int,
        seed: int,
        rec: RayRecord | None = None,
        first_sample: int = 0,
        pass_spp: int | None = None,
        active: wp.array | None = None,
        tracing: LightTracing | None = None,
    ) -> None:
        """Run ``kernel`` over pixels ``first .. first + count - 1`` (or, given ``active``, over
        pixels ``active[first .. first + count - 1]``), samples ``first_sample .. first_sample +
        pass_spp - 1`` (default: all ``spp``) of a render of ``spp`` samples; ``rec`` only for a
        recording variant, ``tracing`` only for the light tracer (whose pixels are its slots)."""
        launch = RenderPass()
        launch.first_sample = first_sample
        launch.pass_spp = spp - first_sample if pass_spp is None else pass_spp
        launch.first_pixel = first
        launch.active = self.no_active if active is None else active
        sampler = sampler_data(self.sampler, spp, seed)
        scene = [self.geometry, self.materials, self.lights, self.settings, self.camera]
        record = [NO_RECORD if rec is None else rec]
        if tracing is not None:
            inputs = [*scene, sampler, launch, tracing, self.film, *record]
        else:
            inputs = [*scene, sampler, launch, self.film, *record]
        wp.launch(kernel, dim=count, inputs=inputs, device=self.device)


def new_film(pixels: int, dev: wp.context.Device) -> Film:
    """A film of ``pixels`` pixels on ``dev``, zeroed."""
    film = Film()
    film.rgb = wp.zeros(pixels, dtype=wp.vec3, device=dev)
    film.rgb_sum = wp.zeros(pixels, dtype=wp.vec3, device=dev)
    film.luminance_sq_sum = wp.zeros(pixels, dtype=wp.float32, device=dev)
    film.rejected = wp.zeros(pixels, dtype=wp.int32, device=dev)
    film.depth = wp.zeros(pixels, dtype=wp.float32, device=dev)
    film.normal = wp.zeros(pixels, dtype=wp.vec3, device=dev)
    film.object_id = wp.zeros(pixels, dtype=wp.int32, device=dev)
    film.position = wp.zeros(pixels, dtype=wp.vec3, device=dev)
    return film


def prepare(scene: Scene, dev: wp.context.Device) -> DeviceScene:
    """Build the BVH of ``scene`` and upload it, its materials, lights, settings, camera and a film."""
    w, h = scene.render.width, scene.render.height
    t0 = time.perf_counter()
    prims = build(scene, dev)
    build_time = time.perf_counter() - t0
    with wp.ScopedDevice(dev):
        film = new_film(w * h, dev)
        return DeviceScene(
            device=dev,
            width=w,
            height=h,
            geometry=upload_geometry(prims, dev),
            materials=upload_materials(scene, dev, prims),
            lights=upload_lights(scene, dev, prims),
            settings=integrator_settings(scene),
            camera=camera_data(scene.camera, scene.render, w, h),
            film=film,
            build_time_s=build_time,
            sampler=scene.render.sampler,
            no_active=wp.empty(0, dtype=wp.int32, device=dev),
        )


# Memory per pixel, measured (peak RSS of `wrt render` at 2048^2 and 3072^2, EXR with all AOVs
# and PNG): the film is RGB + RGB sum + luminance^2 sum + rejected count + depth + normal + object id + position
# = 16 4-byte values; writing it to an image file (channel copies, tone mapping in float64) peaks at
# about 100 bytes more.
FILM_BYTES_PER_PIXEL = 64
WRITE_BYTES_PER_PIXEL = 100


def available_memory() -> int | None:
    """Bytes of host memory this process can still use (Linux: MemAvailable, capped by a cgroup
    v2 limit); None where that cannot be read."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            found += [int(line.split()[1]) * 1024 for line in f if line.startswith("MemAvailable:")]
    except (OSError, ValueError, IndexError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f, open("/sys/fs/cgroup/memory.current") as g:
            limit = f.read().strip()
            if limit != "max":
                found.append(int(limit) - int(g.read()))
    except (OSError, ValueError):
        pass
    return min(found) if found else None


def check_memory(scene: Scene, dev) -> None:
    """Refuse up front (``WrtError``) an image whose film, AOVs and written file would not fit in
    the memory available, instead of being killed by the system part way.

    The estimate is ``width * height * (FILM_BYTES_PER_PIXEL + WRITE_BYTES_PER_PIXEL)`` bytes of
    host memory, and the film's share of device memory on CUDA. ``spp`` costs no memory: samples
    are accumulated per pixel in the kernel.
    """
    w, h = scene.render.width, scene.render.height
    need = w * h * (FILM_BYTES_PER_PIXEL + WRITE_BYTES_PER_PIXEL)
    budgets = [("host memory", need, available_memory())]
    if dev.is_cuda:
        budgets.append((f"memory on {dev}", w * h * FILM_BYTES_PER_PIXEL, dev.free_memory))
    for where, bytes_needed, available in budgets:
        if available is not None and bytes_needed > available:
            raise WrtError(
                f"{scene.path}: render.width x height = {w} x {h}: needs about {bytes_needed / 2**30:.1f} GiB of "
                f"{where} "
                f"(film and AOVs {FILM_BYTES_PER_PIXEL} B/pixel, writing the image about {WRITE_BYTES_PER_PIXEL} "
                "B/pixel more), "
                f"only {available / 2**30:.1f} GiB available: render a smaller image"
            )


def pass_size(spp: int, done: int, elapsed: float, every: int | None) -> int:
    """Samples of the next pass of a progressive render of ``spp`` samples, ``done`` of them done
    in ``elapsed`` wall seconds: one first, then about ``PASS_SECONDS`` of work at the rate so far,
    ending at the next multiple of ``every`` (and at ``spp``)."""
    n = 1 if done == 0 else max(1, round(PASS_SECONDS * done / max(elapsed, 1e-9)))
    if every is not None:
        n = min(n, every - done % every)
    return min(n, spp - done)


Progress = Callable[[int, int, float, Callable[[], "RenderResult"]], "bool | None"]


def adaptive_passes(spp: int) -> list[int]:
    """Sample counts at which an adaptive render checks its pixels: ``ADAPTIVE_FIRST_PASS``, then
    doubling, then ``spp``."""
    ends = [min(spp, ADAPTIVE_FIRST_PASS)]
    while ends[-1] < spp:
        ends.append(min(spp, 2 * ends[-1]))
    return ends


def relative_error(rgb_sum: np.ndarray, luminance_sq_sum: np.ndarray, n: int) -> np.ndarray:
    """Estimated standard error of each pixel's mean luminance after ``n >= 2`` samples, relative
    to the mean ``m`` (to ``ADAPTIVE_FLOOR`` where the mean is darker than that).

    The sample variance gets one pseudo-sample at distance ``max(m, ADAPTIVE_FLOOR)`` from the
    mean: a pixel whose few samples agree (all zero in a penumbra that rare paths do reach, say)
    is not taken as converged until ``1 / sqrt(n (n - 1))`` is below the target too.
    """
    mean = (rgb_sum.astype(np.float64) @ np.array(LUMINANCE_WEIGHTS)) / n
    scale = np.maximum(mean, ADAPTIVE_FLOOR)
    squares = np.maximum(luminance_sq_sum - n * mean * mean, 0.0)  # sum of squared deviations
    variance = (squares + scale * scale) / (n - 1)
    return np.sqrt(variance / n) / scale


def pass_outputs(first_sample: int) -> tuple[str, ...]:
    """The ``Film`` arrays a pass starting at ``first_sample`` writes: the image and ``PASS_STATE``,
    the first pass also ``AOV_NAMES``."""
    return ("rgb", *PASS_STATE, *(AOV_NAMES if first_sample == 0 else ()))


# ---- Tile executors: what runs a pass ----------------------------------------------------------


class TileExecutor(Protocol):
    """What draws the passes of a render for ``render_passes``: ``LocalTiles`` (this machine's
    threads, or one CUDA launch), ``wrt.distributed``'s tasks on a Dask cluster.

    ``film``: the film the passes accumulate into (its ``.numpy()`` arrays are the image so far);
    ``device``, ``threads``, ``build_time_s`` and ``compile_time_s``: the ``RenderResult`` fields.
    """

    film: Film
    device: str
    threads: int
    build_time_s: float
    compile_time_s: float

    def run_pass(self, first_sample: int, pass_spp: int, active: np.ndarray | None) -> bool:
        """Samples ``first_sample .. first_sample + pass_spp - 1`` of every pixel (of those whose
        row-major indices are ``active``, int32, if given), continuing the film's running sums.
        False when a stop abandoned the pass: the film is then as it was before it."""
        ...


class LocalTiles:
    """The tile executor of ``render``: ``scene`` prepared on ``device``, every pass launched in
    tiles of ``TILE_PIXELS`` pixels from ``threads`` threads on the CPU (default: all available
    cores), as one launch on CUDA. ``stop``, set from another thread, abandons a CPU pass at the
    next tile and rolls back the tiles of it already done."""

    def __init__(
        self,
        scene: Scene,
        *,
        device: str | None,
        threads: int | None,
        specialize: bool | None,
        stop: threading.Event | None,
    ):
        dev = resolve_device(device)
        check_memory(scene, dev)
        self.device, self.stop = str(dev), stop
        self.threads = 1 if dev.is_cuda else max(1, threads or default_threads())
        self.spp, self.seed = scene.render.spp, scene.render.seed
        self.kernel = render_kernel_for(scene, specialize, dev)
        self.compile_time_s = load(self.kernel.module, dev)
        self.device_scene = prepare(scene, dev)
        self.film, self.build_time_s = self.device_scene.film, self.device_scene.build_time_s

    def run_pass(self, first_sample: int, pass_spp: int, active: np.ndarray | None) -> bool:
        """See ``TileExecutor.run_pass``."""
        device_scene, dev = self.device_scene, self.device_scene.device
        n = device_scene.width * device_scene.height if active is None else len(active)
        on_device = None if active is None else wp.array(active, dtype=wp.int32, device=dev)

        def launch(first: int, count: int) -> None:
            device_scene.launch(self.kernel, first, count, self.spp, self.seed, None, first_sample, pass_spp, on_device)

        if dev.is_cuda:  # one launch: it ends before a stop is looked at
            launch(0, n)
            wp.synchronize_device(dev)
            return True

        def tile(first: int, count: int) -> bool:
            if self.stop is not None and self.stop.is_set():
                return False
            launch(first, count)
            return True

        before = self._saved(first_sample)
        pool = ThreadPoolExecutor(max_workers=self.threads)
        try:
            finished = all([future.result() for future in [pool.submit(tile, *t) for t in tiles_of(n)]])
        finally:
            pool.shutdown(cancel_futures=True)  # interrupted: drop the tiles not started
        if not finished:
            self._restore(before)
        return finished

    def _saved(self, first_sample: int) -> dict[str, np.ndarray]:
        """Copies of the film arrays a CPU pass from ``first_sample`` writes, where a stop may
        abandon it (none without ``stop``)."""
        names = pass_outputs(first_sample) if self.stop is not None else ()
        return {name: np.copy(getattr(self.film, name).numpy()) for name in names}  # CPU: numpy views of the film

    def _restore(self, saved: dict[str, np.ndarray]) -> None:
        """Roll an abandoned CPU pass back to the film arrays ``_saved`` copied."""
        for name, values in saved.items():
            getattr(self.film, name).numpy()[...] = values


def tiles_of(n: int) -> list[tuple[int, int]]:
    """``(first, count)`` of the CPU launches over ``n`` pixels (or slots): ``TILE_PIXELS`` each."""
    return [(first, min(TILE_PIXELS, n - first)) for first in range(0, n, TILE_PIXELS)]


def light_tracing(scene: Scene, pixels: int, dev: wp.context.Device) -> LightTracing:
    """What the light tracer's kernel reads of ``scene`` besides a render kernel's arguments, with a
    zeroed splat buffer of ``pixels`` pixels on ``dev``."""
    center, radius = bounding_sphere(scene)
    tracing = LightTracing()
    tracing.splat = wp.zeros((pixels, 3), dtype=wp.int64, device=dev)
    tracing.center = wp.vec3(*center)
    tracing.radius = radius
    tracing.sky = int(any(isinstance(light, EnvironmentLight) for light in scene.lights))
    return tracing


class LightTracerTiles(LocalTiles):
    """The tile executor of a light-tracer render (``integrator = "ptracer"``): its launches take
    slots (one light path per slot and sample, ``wrt.kernels.ptracer``) instead of pixels, and
    splat anywhere on the film. Each CPU thread splats into a buffer of its own (the CPU's atomics
    are plain additions, so concurrent launches must not share one); the buffers are integer
    sums, added after each pass into the render's, so the image does not depend on the tiling or
    the threads. After each pass the film's ``rgb`` is those sums over the samples done."""

    def __init__(self, scene: Scene, **options):
        super().__init__(scene, **options)
        dev, pixels = self.device_scene.device, self.device_scene.width * self.device_scene.height
        self.tracings = [light_tracing(scene, pixels, dev) for _ in range(self.threads)]
        self.buffers = [tracing.splat for tracing in self.tracings]
        self.sums = np.zeros((pixels, 3), dtype=np.int64)

    def run_pass(self, first_sample: int, pass_spp: int, active: np.ndarray | None) -> bool:
        """See ``TileExecutor.run_pass``; ``active`` must be None (no adaptive sampling)."""
        assert active is None, "the light tracer has no adaptive sampling"
        device_scene, dev = self.device_scene, self.device_scene.device
        n = device_scene.width * device_scene.height
        for buffer in self.buffers:
            buffer.zero_()

        def launch(worker: int, first: int, count: int) -> None:
            tracing = self.tracings[worker]
            device_scene.launch(
                self.kernel, first, count, self.spp, self.seed, None, first_sample, pass_spp, None, tracing
            )

        if dev.is_cuda:  # one launch: it ends before a stop is looked at
            launch(0, 0, n)
            wp.synchronize_device(dev)
        else:
            tiles = tiles_of(n)

            def worker(w: int) -> bool:
                for t in tiles[w :: self.threads]:
                    if self.stop is not None and self.stop.is_set():
                        return False
                    launch(w, *t)
                return True

            before = self._saved(first_sample)
            with ThreadPoolExecutor(max_workers=self.threads) as pool:
                finished = all(pool.map(worker, range(self.threads)))
            if not finished:
                self._restore(before)
                return False
        for buffer in self.buffers:
            self.sums += buffer.numpy()
        rgb = self.sums / (FIXED_POINT * (first_sample + pass_spp))
        self.film.rgb.assign(wp.array(rgb.astype(np.float32), dtype=wp.vec3, device=dev))
        return True


# ---- The pass loop: one for every executor -----------------------------------------------------


def render_passes(
    scene: Scene,
    start: Callable[[Scene], TileExecutor],
    *,
    spp: int | None,
    seed: int | None,
    progress: Progress | None,
    progress_every: int | None,
    target_error: float | None = None,
) -> RenderResult:
    """Render ``scene`` (``spp`` and ``seed`` overridden) in passes drawn by the executor
    ``start(scene)``: progressive with ``progress``, adaptive with ``target_error``, else one
    pass. The arguments and the result are ``render``'s; a pass the executor abandoned (a stop)
    ends the render with the passes done."""
    scene = override_render(scene, source="wrt.render", spp=spp, seed=seed)
    if progress_every is not None and progress_every < 1:
        raise WrtError(f"progress_every must be >= 1, got {progress_every}")
    if target_error is not None and not target_error > 0.0:
        raise WrtError(f"target_error must be > 0, got {target_error}")
    if target_error is not None and scene.render.integrator == "ptracer":
        raise WrtError(
            f"{scene.path}: render.integrator = ptracer: adaptive sampling needs each pixel's own samples, and a "
            "light path splats anywhere (render without a target error)"
        )
    executor = start(scene)
    spp, pixels = scene.render.spp, scene.render.width * scene.render.height
    schedule = None if target_error is None else adaptive_passes(spp)
    counts = None if target_error is None else np.zeros(pixels, dtype=np.int32)  # samples taken by each pixel
    active = None  # adaptive sampling: indices of the pixels still sampled (None: all)
    done, busy = 0, 0.0  # samples per pixel done (the most any pixel took), wall seconds of passes
    while done < spp:
        if schedule is not None:
            n = schedule[schedule.index(done) + 1] - done if done else schedule[0]
        else:
            n = spp - done if progress is None else pass_size(spp, done, busy, progress_every)
        t0 = time.perf_counter()
        if not executor.run_pass(done, n, active):
            busy += time.perf_counter() - t0
            break
        done += n
        if schedule is not None:
            counts[slice(None) if active is None else active] = done
            if done < spp:
                taken = np.arange(pixels) if active is None else active
                sums, squares = executor.film.rgb_sum.numpy(), executor.film.luminance_sq_sum.numpy()
                error = relative_error(sums[taken], squares[taken], done)
                active = taken[error > target_error].astype(np.int32)
        busy += time.perf_counter() - t0
        snapshot = partial(_result, scene, executor, done, busy, counts, copy=True)
        if progress is not None and progress(done, spp, busy, snapshot) is False:
            break
        if active is not None and len(active) == 0:
            break
    return _result(scene, executor, done, busy, counts, copy=False)


def _result(
    scene: Scene, executor: TileExecutor, done: int, elapsed: float, counts: np.ndarray | None, *, copy: bool
) -> RenderResult:
    """The ``RenderResult`` of ``executor.film`` after ``done`` samples per pixel in ``elapsed`` wall
    seconds; ``counts``: each pixel's samples (adaptive; else None). Its arrays are copies, or
    with ``copy=False`` views of a film on the host."""
    w, h = scene.render.width, scene.render.height
    take = np.copy if copy else np.asarray

    def image(name: str) -> np.ndarray:
        values = getattr(executor.film, name).numpy()
        return take(values.reshape(h, w, *values.shape[1:]))

    aovs = {name: image(name) for name in AOV_NAMES}
    if counts is not None:
        aovs["spp"] = counts.reshape(h, w).copy()
    return RenderResult(
        rgb=image("rgb"),
        aovs=aovs,
        spp=done,
        seed=scene.render.seed,
        integrator=scene.render.integrator,
        device=executor.device,
        threads=executor.threads,
        build_time_s=executor.build_time_s,
        compile_time_s=executor.compile_time_s,
        render_time_s=elapsed,
        rejected_samples=int(executor.film.rejected.numpy().sum()),
    )


def render(
    scene: Scene,
    *,
    spp: int | None = None,
    seed: int | None = None,
    device: str | None = "cpu",
    threads: int | None = None,
    progress: Progress | None = None,
    progress_every: int | None = None,
    target_error: float | None = None,
    specialize: bool | None = None,
    stop: threading.Event | None = None,
) -> RenderResult:
    """Render ``scene`` with its integrator.

    Parameters
    ----------
    scene : Scene
        From ``wrt.load_scene``.
    spp, seed : int, optional
        Override ``[render] spp`` and ``seed``, as ``wrt.loader.override_render`` does (the one way
        to change ``[render]`` settings: validated like the file's, errors naming "wrt.render").
    device : str
        Warp device: "cpu" or "cuda" (or "cuda:N").
    threads : int, optional
        CPU threads launching tiles (default: all available cores). Ignored on CUDA.
    progress : callable, optional
        Render progressively: in passes of about ``PASS_SECONDS`` wall seconds (the first pass is
        one sample; later ones are sized from the rate so far), calling
        ``progress(samples_done, spp, elapsed_s, snapshot)`` after each. ``elapsed_s``: wall
        seconds of the passes so far; ``snapshot()``: a ``RenderResult`` of the samples done
        (copies). Returning ``False`` stops the render after that pass: the result then holds
        ``samples_done`` spp. Without it, one pass.
    progress_every : int, optional
        With ``progress``: passes also end at every multiple of this many samples, so the callback
        sees those counts (checkpoints).
    target_error : float, optional
        Adaptive sampling: every pixel takes ``ADAPTIVE_FIRST_PASS`` samples, then the pixels
        whose estimated relative error (``relative_error``) is still above ``target_error`` take
        as many again, and so on up to ``spp`` (passes end at 16, 32, 64, ... samples, whatever
        ``progress_every``). The result's ``aovs["spp"]`` holds each pixel's sample count.
    specialize : bool, optional
        True: render with the kernel specialised on the scene's features (``scene_features``);
        False: with the all-features kernel. Both give the same image. Default
        (``render_kernel_for``): a variant's first compilation takes 10-30 CPU-seconds (then
        Warp's cache serves it), more than most renders could save, so the variant is taken
        where it is already compiled (from ``SPECIALIZE_MIN_SAMPLES`` pixel samples on) or the
        render is long (``SPECIALIZE_COLD_SAMPLES``), else the all-features kernel, compiled
        once for all.
    stop : threading.Event, optional
        Set from another thread (a signal handler) to end the render at the next tile boundary
        on the CPU, without waiting for the pass in flight: that pass is abandoned and its tiles
        already done are rolled back, so the result holds the passes completed (possibly 0
        samples) and is the image of that many spp. On CUDA a pass is one launch: it ends first.

    Notes
    -----
    Passes never change the image: the kernel continues each pixel's float32 running sum in
    sample order, so a render in passes is bit-identical to a one-pass render, and one stopped
    after ``k > 1`` samples to a render with ``spp = k``. With ``spp = 1`` the sample is the pixel
    centre; with ``spp > 1`` every sample, the first pass's included, is uniform over the pixel.
    An adaptive render is deterministic too: a pixel's stopping depends only on its own samples.
    """
    tiles = LightTracerTiles if scene.render.integrator == "ptracer" else LocalTiles
    start = partial(tiles, device=device, threads=threads, specialize=specialize, stop=stop)
    return render_passes(
        scene, start, spp=spp, seed=seed, progress=progress, progress_every=progress_every, target_error=target_error
    )
