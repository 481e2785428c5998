"""Rendering on a Dask distributed cluster (``--scheduler ADDRESS``; the ``cluster`` extra).

``Cluster(address)`` connects to a running ``dask scheduler``. What travels to the workers is
the parsed scene: the ``wrt.scene.Scene`` the client loaded (TOML or Mitsuba XML), with its
meshes' vertices, faces and normals and its environment map's pixels as numpy arrays, pickled
and scattered once per render. A worker reads no scene, mesh or image file and needs none of
the client's paths: only the same wrt version installed (and a CUDA device for ``device="cuda"``).

Each task renders one range of consecutive pixels (a tile: ``render``) or a whole image (one
seed of ``images``) with one launch on its worker thread. A pixel's value depends only on
(scene, seed, pixel, sample): random numbers are a counter-based hash of (seed, pixel, sample,
dimension), and the kernel continues each pixel's float32 sum in sample order, so an image
assembled from tiles is bit-identical to a local render, with any tiling, worker count or pass
sizes. Passes work as in ``wrt.renderer.render``: a tile's running sums travel with its next
task (5 values a pixel), so progress, checkpoints and a stop after a pass behave as locally.

Per worker process, the device scene (BVH, uploads) of a scene is built once and kept for later
tasks (``PREPARED_SCENES`` scenes, keyed by the SHA-256 of the pickled scene and the device),
and each kernel module is loaded (compiled, or read from Warp's kernel cache) once:
``worker_stats`` counts both. Films are per task (several tasks of one scene may run at once on
a worker with several threads), reused from a pool.

Dask is imported only here, and this module only when a scheduler is given: a local render
needs neither.
"""

from __future__ import annotations

import hashlib
import math
import pickle
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import warp as wp

from wrt.kernels.features import ALL
from wrt.kernels.variants import render_kernel

from .device import init_warp, resolve_device
from .errors import WrtError
from .loader import override_render
from .renderer import SPECIALIZE_MIN_SAMPLES, RenderResult, check_memory, new_film, pass_size, prepare, scene_features
from .scene import Scene

CONNECT_TIMEOUT_S = 10  # seconds to wait for the scheduler before giving up
TILES_PER_THREAD = 4  # tiles per worker thread and pass: enough to balance uneven tiles
MIN_TILE_PIXELS = 256  # smaller tiles cost more in task overhead than they balance
STOP_POLL_S = 0.05  # how often a render with a stop event checks it while a pass is in flight
PREPARED_SCENES = 2  # device scenes a worker keeps (the BVH and uploads of a large scene are big)
STATE = ("rgb_sum", "luminance_sq_sum", "rejected")  # what a pass continues from the previous one
AOVS = ("depth", "normal", "object_id", "position")  # written by the first pass


def _dask():
    try:
        import distributed
    except ImportError:
        raise WrtError(
            "--scheduler needs Dask distributed, which is not installed: pip install 'wrt[cluster]'"
        ) from None
    return distributed


class Cluster:
    """A connection to the Dask scheduler at ``address`` (``tcp://host:8786``, or ``host:port``),
    waiting at most ``timeout`` seconds for it (default ``CONNECT_TIMEOUT_S``); a context manager.
    A malformed address, an unreachable scheduler or one without workers is a ``WrtError``."""

    def __init__(self, address: str, timeout: float | None = None):
        distributed = _dask()
        timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
        self.address = address
        try:
            scheme, location = distributed.comm.parse_address(address)
            distributed.comm.registry.get_backend(scheme)
            if scheme != "inproc":
                distributed.comm.parse_host_port(location)
        except ValueError as e:
            raise WrtError(f"--scheduler {address}: not a scheduler address like tcp://host:8786 ({e})") from None
        try:
            self.client = distributed.Client(address, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as e:
            raise WrtError(f"--scheduler {address}: cannot connect to a Dask scheduler there ({e})") from None
        if not self.threads():
            self.client.close()
            raise WrtError(f"--scheduler {address}: the scheduler has no workers (start some: dask worker {address})")

    def __enter__(self) -> Cluster:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.client.close()

    def threads(self) -> int:
        """Worker threads of the cluster: the tasks it runs at once."""
        return sum(self.client.nthreads().values())

    def submit(self, fn: Callable, *args):
        """Run ``fn(*args)`` as one task on a worker (``on_worker``); a future (``result()``
        re-raises the task's error)."""
        return self.client.submit(on_worker, fn, *args, pure=False)

    def _scatter(self, scene: Scene):
        """``scene`` on the cluster (a future workers resolve to it) and its key: the SHA-256 of
        its pickle with ``spp`` and ``seed`` left out, which its device scene does not depend on."""
        data = pickle.dumps(replace(scene, render=replace(scene.render, spp=1, seed=0)))
        return self.client.scatter(scene, hash=False), hashlib.sha256(data).hexdigest()

    def images(
        self,
        scene: Scene,
        seeds: list[int],
        *,
        spp: int | None = None,
        device: str = "cpu",
        specialize: bool | None = None,
    ) -> list[np.ndarray]:
        """The RGB image (H, W, 3) of ``scene`` for each of ``seeds``, one task each: bit-identical
        to ``wrt.render(scene, spp=spp, seed=seed, device=device).rgb``."""
        scene = override_render(scene, source="wrt.render", spp=spp)
        w, h, spp = scene.render.width, scene.render.height, scene.render.spp
        specialize = _specialize(scene, specialize)
        shipped, key = self._scatter(scene)
        futures = [
            self.submit(render_tile, shipped, key, device, specialize, spp, seed, 0, w * h, 0, spp, None)
            for seed in seeds
        ]
        return [future.result()["rgb"].reshape(h, w, 3) for future in futures]

    def render(
        self,
        scene: Scene,
        *,
        spp: int | None = None,
        seed: int | None = None,
        device: str = "cpu",
        progress=None,
        progress_every: int | None = None,
        specialize: bool | None = None,
        stop: threading.Event | None = None,
    ) -> RenderResult:
        """``wrt.render`` on the cluster, in pixel tiles: the same arguments (but no adaptive
        sampling, and no ``threads``: each worker thread runs one tile at a time) and a
        bit-identical ``RenderResult``. ``stop`` cancels the pass in flight; the result holds the
        passes done. ``threads`` in the result: the cluster's worker threads."""
        scene = override_render(scene, source="wrt.render", spp=spp, seed=seed)
        w, h, spp, seed = scene.render.width, scene.render.height, scene.render.spp, scene.render.seed
        if progress_every is not None and progress_every < 1:
            raise WrtError(f"progress_every must be >= 1, got {progress_every}")
        check_memory(scene, resolve_device("cpu"))  # the image is assembled here
        specialize = _specialize(scene, specialize)
        threads = self.threads()
        n = w * h
        size = max(MIN_TILE_PIXELS, math.ceil(n / (TILES_PER_THREAD * max(1, threads))))
        tiles = [(first, min(size, n - first)) for first in range(0, n, size)]
        film = {
            "rgb": np.zeros((n, 3), np.float32),
            "rgb_sum": np.zeros((n, 3), np.float32),
            "luminance_sq_sum": np.zeros(n, np.float32),
            "rejected": np.zeros(n, np.int32),
            "depth": np.zeros(n, np.float32),
            "normal": np.zeros((n, 3), np.float32),
            "object_id": np.zeros(n, np.int32),
            "position": np.zeros((n, 3), np.float32),
        }
        shipped, key = self._scatter(scene)
        times = {"build_time_s": 0.0, "compile_time_s": 0.0}

        def run_pass(first_sample: int, pass_spp: int) -> bool:
            futures = []
            for first, count in tiles:
                state = {k: film[k][first : first + count] for k in STATE} if first_sample else None
                task = (shipped, key, device, specialize, spp, seed, first, count, first_sample, pass_spp, state)
                futures.append(self.submit(render_tile, *task))
            while stop is not None and not all(future.done() for future in futures):
                if stop.is_set():
                    self.client.cancel(futures)
                    return False
                time.sleep(STOP_POLL_S)
            parts = [future.result() for future in futures]  # all, before the film changes
            for (first, count), part in zip(tiles, parts):
                for name, values in part.items():
                    if name in film:
                        film[name][first : first + count] = values
                for name in times:
                    times[name] = max(times[name], part[name])
            return True

        def result(done: int, elapsed: float, copy: bool) -> RenderResult:
            take = np.copy if copy else np.asarray
            shapes = {"depth": (h, w), "normal": (h, w, 3), "object_id": (h, w), "position": (h, w, 3)}
            return RenderResult(
                rgb=take(film["rgb"].reshape(h, w, 3)),
                aovs={name: take(film[name].reshape(shape)) for name, shape in shapes.items()},
                spp=done,
                seed=seed,
                integrator=scene.render.integrator,
                device=device,
                threads=threads,
                render_time_s=elapsed,
                rejected_samples=int(film["rejected"].sum()),
                **times,
            )

        done, busy = 0, 0.0
        while done < spp:
            count = spp - done if progress is None else pass_size(spp, done, busy, progress_every)
            t0 = time.perf_counter()
            finished = run_pass(done, count)
            busy += time.perf_counter() - t0
            if not finished:
                break
            done += count
            if progress is not None and progress(done, spp, busy, lambda: result(done, busy, True)) is False:
                break
        return result(done, busy, copy=False)


def _specialize(scene: Scene, specialize: bool | None) -> bool:
    """Whether a render of ``scene`` takes its specialised kernel: ``wrt.renderer.render``'s rule."""
    if specialize is not None:
        return specialize
    return scene.render.width * scene.render.height * scene.render.spp >= SPECIALIZE_MIN_SAMPLES


# ---- On the workers ------------------------------------------------------------------------

_lock = threading.Lock()
_prepared: OrderedDict = OrderedDict()  # (scene key, device) -> (DeviceScene, free films)
_loaded: set = set()  # (kernel module name, device) loaded in this process
_stats = {"scenes_prepared": 0, "kernel_loads": 0, "kernel_load_s": 0.0}
_warp_ready = threading.Event()


def on_worker(fn: Callable, *args):
    """A task: ``fn(*args)`` after initialising Warp in this worker process (once)."""
    if not _warp_ready.is_set():
        with _lock:
            init_warp()
            _warp_ready.set()
    return fn(*args)


def worker_stats() -> dict:
    """This process's counts: ``scenes_prepared`` (device scenes built), ``kernel_loads`` (kernel
    modules loaded), ``kernel_load_s`` (wall seconds spent loading them). Run it on every worker
    with ``Cluster.client.run(worker_stats)``."""
    return dict(_stats)


def _device_scene(scene: Scene, key: str, dev: wp.Device, kernel) -> tuple:
    """The device scene of ``scene`` on ``dev`` and its pool of free films, built on first use;
    ``kernel``'s module loaded. Also: the seconds this call spent building and loading."""
    build_s = load_s = 0.0
    with _lock:
        module = (kernel.module.name, str(dev))
        if module not in _loaded:
            t0 = time.perf_counter()
            wp.load_module(kernel.module, device=dev)
            load_s = time.perf_counter() - t0
            _loaded.add(module)
            _stats["kernel_loads"] += 1
            _stats["kernel_load_s"] += load_s
        entry = _prepared.get((key, str(dev)))
        if entry is None:
            device_scene = prepare(scene, dev)
            build_s = device_scene.build_time_s
            entry = _prepared[(key, str(dev))] = (device_scene, [])
            _stats["scenes_prepared"] += 1
            while len(_prepared) > PREPARED_SCENES:
                _prepared.popitem(last=False)
        _prepared.move_to_end((key, str(dev)))
    return entry, build_s, load_s


def render_tile(
    scene: Scene,
    key: str,
    device: str,
    specialize: bool,
    spp: int,
    seed: int,
    first: int,
    count: int,
    first_sample: int,
    pass_spp: int,
    state: dict | None,
) -> dict:
    """A task: samples ``first_sample .. first_sample + pass_spp - 1`` of pixels ``first .. first
    + count - 1`` of a render of ``scene`` with ``spp`` samples and ``seed``, continuing the
    running sums ``state`` (``STATE`` arrays of the tile; None for the first pass).

    Returns the tile's ``rgb`` and ``STATE`` arrays (and ``AOVS`` after a first pass) as numpy,
    and ``build_time_s``, ``compile_time_s``: what this task spent building the device scene and
    loading the kernel (0 once the worker has them).
    """
    dev = resolve_device(device)
    kernel = render_kernel(scene.render.integrator, scene_features(scene) if specialize else ALL)
    (device_scene, films), build_s, load_s = _device_scene(scene, key, dev, kernel)
    with _lock:
        film = films.pop() if films else new_film(device_scene.width * device_scene.height, dev)
    try:
        if state is not None:
            for name, values in state.items():
                target = getattr(film, name)
                wp.copy(target, wp.array(values, dtype=target.dtype, device=dev), dest_offset=first, count=count)
        replace(device_scene, film=film).launch(kernel, first, count, spp, seed, None, first_sample, pass_spp)
        names = ("rgb", *STATE, *(AOVS if first_sample == 0 else ()))
        out = {name: np.array(getattr(film, name)[first : first + count].numpy()) for name in names}
    finally:
        with _lock:
            films.append(film)
    return {**out, "build_time_s": build_s, "compile_time_s": load_s}
