"""Render orchestration: scene -> primitives + BVH -> device arrays -> integrator kernel -> numpy.

On the CPU a Warp launch runs on one thread but releases the GIL, so the image is cut into
tiles of consecutive pixels launched from a thread pool. Every pixel's value depends only on
(scene, seed, pixel, sample), never on the tiling or thread count: results are bit-identical
for any ``threads``. On CUDA the whole image is one launch.
"""
from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import warp as wp

from kernels.film import Film
from kernels.raycast import raycast
from kernels.whitted import whitted

from .device import camera_data, integrator_settings, resolve_device, upload_geometry, upload_lights, upload_materials
from .errors import WrtError
from .geometry import build
from .scene import Scene

INTEGRATOR_KERNELS = {"raycast": raycast, "whitted": whitted}
TILE_PIXELS = 4096  # pixels per CPU launch: small enough to balance two threads, large enough to amortise a launch
AOV_NAMES = ("depth", "normal", "object_id", "position")


@dataclass
class RenderResult:
    """A rendered image (linear float32 RGB, row 0 at the top) and its AOVs.

    ``aovs``: ``depth`` (H, W) float32, distance along the unit camera ray, inf on a miss;
    ``normal`` (H, W, 3) world space, facing the camera; ``object_id`` (H, W) int32, -1 on a miss;
    ``position`` (H, W, 3) world space. Times are wall seconds: ``build_time_s`` for the BVH,
    ``compile_time_s`` for loading kernels (near 0 with a warm cache), ``render_time_s`` for the launches.
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


def default_threads() -> int:
    """CPU threads available to this process."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def render(scene: Scene, spp: int | None = None, seed: int | None = None, device: str | None = "cpu", threads: int | None = None) -> RenderResult:
    """Render ``scene`` with its integrator.

    Parameters
    ----------
    scene : Scene
        From ``wrt.load_scene``.
    spp, seed : int, optional
        Override ``[render] spp`` and ``seed``.
    device : str
        Warp device: "cpu" or "cuda" (or "cuda:N").
    threads : int, optional
        CPU threads launching tiles (default: all available cores). Ignored on CUDA.
    """
    spp = scene.render.spp if spp is None else int(spp)
    seed = scene.render.seed if seed is None else int(seed)
    if spp < 1:
        raise WrtError(f"spp must be >= 1, got {spp}")
    dev = resolve_device(device)
    threads = 1 if dev.is_cuda else max(1, threads or default_threads())
    kernel = INTEGRATOR_KERNELS[scene.render.integrator]
    w, h = scene.render.width, scene.render.height

    t0 = time.perf_counter()
    prims = build(scene)
    t1 = time.perf_counter()
    wp.load_module(kernel.module, device=dev)
    t2 = time.perf_counter()
    with wp.ScopedDevice(dev):
        geometry = upload_geometry(prims, dev)
        materials = upload_materials(scene, dev)
        lights = upload_lights(scene, dev)
        settings = integrator_settings(scene.render)
        cam = camera_data(scene.camera, w, h)
        film = Film()
        film.rgb = wp.zeros(w * h, dtype=wp.vec3, device=dev)
        film.depth = wp.zeros(w * h, dtype=wp.float32, device=dev)
        film.normal = wp.zeros(w * h, dtype=wp.vec3, device=dev)
        film.object_id = wp.zeros(w * h, dtype=wp.int32, device=dev)
        film.position = wp.zeros(w * h, dtype=wp.vec3, device=dev)

        def launch(first: int, count: int) -> None:
            wp.launch(kernel, dim=count, inputs=[geometry, materials, lights, settings, cam, spp, seed, first, film], device=dev)

        t3 = time.perf_counter()
        if dev.is_cuda:
            launch(0, w * h)
            wp.synchronize_device(dev)
        else:
            tiles = [(first, min(TILE_PIXELS, w * h - first)) for first in range(0, w * h, TILE_PIXELS)]
            with ThreadPoolExecutor(max_workers=threads) as pool:
                for future in [pool.submit(launch, *tile) for tile in tiles]:
                    future.result()
        t4 = time.perf_counter()
    aovs = {
        "depth": film.depth.numpy().reshape(h, w),
        "normal": film.normal.numpy().reshape(h, w, 3),
        "object_id": film.object_id.numpy().reshape(h, w),
        "position": film.position.numpy().reshape(h, w, 3),
    }
    return RenderResult(
        rgb=film.rgb.numpy().reshape(h, w, 3),
        aovs=aovs,
        spp=spp,
        seed=seed,
        integrator=scene.render.integrator,
        device=str(dev),
        threads=threads,
        build_time_s=t1 - t0,
        compile_time_s=t2 - t1,
        render_time_s=t4 - t3,
    )
