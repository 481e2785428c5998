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
sizes. ``Cluster.render`` is ``wrt.renderer.render_passes`` (the one pass loop) with
``ClusterTiles`` as its tile executor: a tile's running sums travel with its next task (5 values
a pixel), so progress, checkpoints and a stop after a pass behave as locally.

Per worker process, the device scene (BVH, uploads) of a scene is built once and kept for later
tasks (``PREPARED_SCENES`` scenes, keyed by the SHA-256 of the pickled scene and the device),
and each kernel module is loaded (compiled, or read from Warp's kernel cache) once:
``worker_stats`` counts both. Films are per task (several tasks of one scene may run at once on
a worker with several threads), reused from a pool.

No wait for the cluster is without a bound (``Cluster``): a scheduler, a worker or a listener
that stops answering, or workers that die for good, end the wait with one ``WrtError``, and
Dask's log lines are kept by the cluster (``Cluster.dask_log``), not printed.

Dask is imported only here, and this module only when a scheduler is given: a local render
needs neither.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import hashlib
import logging
import math
import pickle
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import replace
from functools import partial

import numpy as np
import warp as wp

from .aot import load
from .device import init_warp, resolve_device
from .errors import WrtError, foreign
from .loader import override_render
from .renderer import (
    PASS_STATE,
    RenderResult,
    check_memory,
    new_film,
    pass_outputs,
    prepare,
    render_kernel_for,
    render_passes,
)
from .scene import Scene

CONNECT_TIMEOUT_S = 10  # seconds the scheduler has to answer: the connection, and every request after it
WORKER_TIMEOUT_S = 30  # seconds a worker running a task may go without a heartbeat (Dask sends one every 0.5-5 s)
TRANSFER_BYTES_PER_S = 1e6  # the slowest network a transfer is given time for: 1 s more per MB it carries
WATCH_EVERY_S = 1.0  # how often a wait for tasks asks the scheduler how they are going
DASK_LOG_LINES = 200  # of Dask's log lines while a cluster is open, how many it keeps (``Cluster.dask_log``)
TILES_PER_THREAD = 4  # tiles per worker thread and pass: enough to balance uneven tiles
MIN_TILE_PIXELS = 256  # smaller tiles cost more in task overhead than they balance
STOP_POLL_S = 0.05  # how often a wait for tasks checks its stop event and the watch
PREPARED_SCENES = 2  # device scenes a worker keeps (the BVH and uploads of a large scene are big)


def _dask():
    try:
        import distributed
    except ImportError:
        raise WrtError(
            "--scheduler needs Dask distributed, which is not installed: pip install 'wrt[cluster]'"
        ) from None
    return distributed


@functools.cache
def _bounded_client():
    """``distributed.Client`` whose connection (TCP or TLS, Dask's handshake, the client's
    registration) ends within its ``timeout``: Dask bounds the TCP connection by it but waits for
    the handshake without end, so a listener that never speaks would hang the constructor. On any
    failure the client closes itself, so that no half-made client waits again when collected."""
    distributed = _dask()

    class BoundedClient(distributed.Client):
        def start(self, **kwargs):
            try:
                super().start(callback_timeout=self._timeout, **kwargs)
            except BaseException:
                with contextlib.suppress(Exception):
                    self.close(timeout=self._timeout)
                raise

    return BoundedClient


class _Dropped(WrtError):
    """A request whose connection closed before it was answered."""


def _reason(error: BaseException) -> str:
    """A library's exception as a message shows it: its first line, escaped and cut (its type
    when it has no message)."""
    return foreign(str(error)) if str(error).strip() else type(error).__name__


# ---- Dask's log lines: kept by the open clusters, not printed ----------------------------------


class _DaskLog(logging.Handler):
    """While a ``Cluster`` is open, the one handler of Dask's loggers (``distributed``, ``tornado``,
    ``bokeh``, and those below them that have handlers of their own): each record goes to every open
    cluster's ``dask_log``, none to stderr, where the failure it tells of is one line, the
    cluster's ``WrtError``. The loggers' own handlers come back when the last cluster closes."""

    ROOTS = ("distributed", "tornado", "bokeh")

    def __init__(self):
        super().__init__()
        self.setFormatter(logging.Formatter("%(name)s - %(levelname)s - %(message)s"))
        self.clusters: list[Cluster] = []
        self.saved: dict[logging.Logger, tuple[list, bool]] = {}
        self.lock = threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        line = self.format(record)
        for cluster in list(self.clusters):
            cluster._dask_log.append(line)

    def _loggers(self) -> list[logging.Logger]:
        names = [n for n in logging.root.manager.loggerDict if n.split(".")[0] in self.ROOTS] + list(self.ROOTS)
        loggers = {logging.getLogger(name) for name in names}
        return [logger for logger in loggers if logger.handlers or logger.name in self.ROOTS]

    def attach(self, cluster: Cluster) -> None:
        with self.lock:
            if not self.clusters:
                for logger in self._loggers():
                    self.saved[logger] = (list(logger.handlers), logger.propagate)
                    logger.handlers, logger.propagate = [self], False
            self.clusters.append(cluster)

    def detach(self, cluster: Cluster) -> None:
        with self.lock:
            if cluster not in self.clusters:
                return
            self.clusters.remove(cluster)
            if not self.clusters:
                for logger, (handlers, propagate) in self.saved.items():
                    logger.handlers, logger.propagate = handlers, propagate
                self.saved.clear()


_dask_log = _DaskLog()


class Cluster:
    """A connection to the Dask scheduler at ``address`` (``tcp://host:8786``, or ``host:port``);
    a context manager. A malformed address, a transport that cannot work here, an unreachable
    scheduler or one without workers is a ``WrtError``.

    No wait ends without a bound. The scheduler must answer the connection and every request
    (the cluster's size, the scene's upload, the results' download, the watch below) within
    ``timeout`` seconds (default ``CONNECT_TIMEOUT_S``), plus 1 s per MB a transfer carries
    (``TRANSFER_BYTES_PER_S``); when a worker holds a transfer up, the error names it. A wait
    for tasks, however long they run, asks the scheduler every ``WATCH_EVERY_S`` how they are
    going, and ends with a ``WrtError`` when the scheduler does not answer, when a worker running
    one of them has sent no heartbeat for ``worker_timeout`` seconds (default
    ``WORKER_TIMEOUT_S``), or when the cluster has had no worker for that long. A task whose
    worker dies is run again on another by Dask (bit-identical: a task's result depends on its
    arguments only), until Dask gives up (its ``allowed-failures``: a ``WrtError``); when the
    workers holding the scene all die, the scene is shipped again and the tasks run again, once.
    While the cluster is open, Dask's log lines go to ``dask_log`` instead of stderr.
    """

    def __init__(self, address: str, timeout: float | None = None, *, worker_timeout: float | None = None):
        distributed = _dask()
        self.address = address
        self.timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
        self.worker_timeout = WORKER_TIMEOUT_S if worker_timeout is None else worker_timeout
        self._check_address(distributed)
        self._dask_log: deque[str] = deque(maxlen=DASK_LOG_LINES)
        self._watch_lock = threading.Lock()
        self._watched_at = -math.inf
        self._heard: dict[str, tuple[float, float]] = {}  # worker -> (its last heartbeat, when we saw it change)
        self._running: dict[str, str] = {}  # task key -> the worker running it
        self._workerless_since: float | None = None
        self.client = None
        _dask_log.attach(self)
        try:
            try:
                self.client = _bounded_client()(address, timeout=self.timeout, set_as_default=False)
            except (TimeoutError, asyncio.TimeoutError):
                raise self._error(
                    f"cannot connect to a Dask scheduler there: no answer within {self.timeout:g} s"
                ) from None
            except Exception as e:
                raise self._error(f"cannot connect to a Dask scheduler there ({_reason(e)})") from None
            if not self.threads():
                raise self._error(f"the scheduler has no workers (start some: dask worker {address})")
        except BaseException:
            self.close()
            raise

    def _error(self, problem: str, kind: type[WrtError] = WrtError) -> WrtError:
        return kind(f"--scheduler {self.address}: {problem}")

    def _check_address(self, distributed) -> None:
        """Refuse an address Dask would fail on with a traceback: malformed, a transport whose
        connector cannot be made here (``ucx://`` without distributed-ucxx), ``tls://`` without
        certificates."""
        try:
            scheme, location = distributed.comm.parse_address(self.address)
            backend = distributed.comm.registry.get_backend(scheme)
            if scheme == "inproc":
                if len(location.split("/")) != 3:
                    raise ValueError("an inproc:// address is inproc://HOST/PID/N")
            elif not 0 < distributed.comm.parse_host_port(location)[1] < 65536:
                raise ValueError("a port is 1 to 65535")
        except ValueError as e:
            raise self._error(f"not a scheduler address like tcp://host:8786 ({foreign(str(e))})") from None
        try:
            backend.get_connector()
        except Exception as e:
            raise self._error(f"Dask's {scheme}:// transport cannot be used here ({_reason(e)})") from None
        if scheme not in ("tls", "wss"):
            return
        import dask

        try:  # a security loader would find the certificates
            loader = dask.config.get("distributed.client.security-loader", None)
            certificates = loader or distributed.Security().get_connection_args("client")["ssl_context"]
        except Exception as e:  # a certificate file that cannot be read
            raise self._error(f"Dask's TLS configuration cannot be used ({_reason(e)})") from None
        if not certificates:
            raise self._error(
                f"{scheme}:// needs TLS certificates in Dask's configuration (distributed.comm.tls.ca-file, "
                "distributed.comm.tls.client.cert and .key: docs/cluster.md)"
            )

    def __enter__(self) -> Cluster:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect, waiting at most ``timeout`` for the scheduler; Dask logs to stderr again
        once no cluster is open."""
        try:
            if self.client is not None:
                with contextlib.suppress(Exception):
                    self.client.close(timeout=self.timeout)
        finally:
            _dask_log.detach(self)

    def dask_log(self) -> list[str]:
        """The last ``DASK_LOG_LINES`` lines Dask logged (in this process) while this cluster was
        open: its own account of what went wrong, which stderr does not show."""
        return list(self._dask_log)

    def _ask(self, what: str, method: Callable, *args, seconds: float | None = None, **kwargs):
        """``method(*args, **kwargs)``, a method of the client, its answer awaited at most
        ``seconds`` (default ``timeout``): run on the client's event loop, where a Dask client
        method returns its coroutine, which ``Client.sync`` awaits with that bound. ``what`` (the
        request) names it in the ``WrtError`` of a failure."""
        seconds = self.timeout if seconds is None else seconds
        try:
            return self.client.sync(method, *args, callback_timeout=seconds, **kwargs)
        except (TimeoutError, asyncio.TimeoutError):
            raise self._error(f"the scheduler did not answer within {seconds:.3g} s ({what})") from None
        except OSError as e:  # Dask's CommClosedError among them
            raise self._error(f"{what} failed ({_reason(e)})", _Dropped) from None
        except Exception as e:
            raise self._error(f"{what} failed ({_reason(e)})") from None

    def threads(self) -> int:
        """Worker threads of the cluster: the tasks it runs at once."""
        return sum(self._ask("the count of its worker threads", self.client.nthreads).values())

    def submit(self, fn: Callable, *args) -> Task:
        """Run ``fn(*args)`` as one task on a worker (``on_worker``); its ``Task`` (``result()``
        waits for it as every wait of the cluster is bounded, and re-raises the task's error)."""
        return Task(self, self._submit(fn, *args))

    def _submit(self, fn: Callable, *args):
        return self.client.submit(on_worker, fn, *args, pure=False)

    def _scatter(self, scene: Scene):
        """``scene`` on every worker of the cluster (a future workers resolve to it: each of them
        runs tasks of it, and a worker that dies takes no copy the others need) and its key: the
        SHA-256 of its pickle with ``spp`` and ``seed`` left out, which its device scene does not
        depend on. The upload is given 1 s per MB for each of the rounds in which Dask copies it
        from worker to worker (each holder to two more); a cluster without workers, ``worker_timeout``
        seconds for one to come (a worker's nanny starts a new one when it dies). An upload that a
        dying worker broke is sent again, for as long."""
        data = pickle.dumps(replace(scene, render=replace(scene.render, spp=1, seed=0)))
        what = f"the upload of the scene, {len(data) / 1e6:.2g} MB"
        since = time.monotonic()
        while True:
            while not (workers := self._ask("the count of its worker threads", self.client.nthreads)):
                if time.monotonic() - since >= self.worker_timeout:
                    raise self._workerless(time.monotonic() - since)
                time.sleep(WATCH_EVERY_S)
            rounds = 1 + math.ceil(math.log(len(workers), 3))
            seconds = self.timeout + 2 * rounds * len(data) / TRANSFER_BYTES_PER_S
            try:
                shipped = self._transfer(what, self.client.scatter, scene, hash=False, broadcast=True, seconds=seconds)
                return shipped, hashlib.sha256(data).hexdigest()
            except _Dropped:
                # a worker it was sent to died during it (the scheduler, failing to reach it, drops
                # the request's connection): sent again to the workers there are now
                if time.monotonic() - since >= self.worker_timeout:
                    raise

    def _scene_results(self, scene: Scene, shipment: list, submit: Callable, stop: threading.Event | None = None):
        """``_results`` of the tasks ``submit(shipped, key)`` submits for ``scene``, shipped as
        ``shipment`` (``[shipped, key]``, from ``_scatter``). When the cluster loses the scene
        meanwhile (the workers holding it died: Dask cannot compute scattered data again), it is
        shipped again (``shipment`` updated) and the tasks run again, once: bit-identical, as
        their results depend on their arguments only."""
        for again in (False, True):
            futures = submit(*shipment)
            try:
                return self._results(futures, stop)
            except WrtError:
                if again or shipment[0].status == "finished":
                    raise
            shipment[:] = self._scatter(scene)

    def _workerless(self, seconds: float) -> WrtError:
        return self._error(f"the scheduler has had no workers for {seconds:.3g} s: they died or left")

    def _results(self, futures: list, stop: threading.Event | None = None) -> list | None:
        """The values of ``futures``, in order, once all have run (a watched wait: ``_wait``), or
        None when ``stop`` was set first (they are cancelled). A task's error is raised as it was
        (its traceback with it); the cluster's failures are each a ``WrtError``."""
        if not self._wait(futures, stop):
            return None
        for future in futures:
            if future.status != "finished":
                self._raise_failure(future)
        keys = [future.key for future in futures]
        size = sum(self._ask("the sizes of the results", self.client.nbytes, keys, summary=False).values())
        what = f"the download of the results, {size / 1e6:.2g} MB"
        holders = functools.partial(self.client.who_has, futures)
        return self._transfer(
            what, self.client.gather, futures, seconds=self.timeout + size / TRANSFER_BYTES_PER_S, holders=holders
        )

    def _transfer(self, what: str, method: Callable, *args, seconds: float, holders: Callable | None = None, **kwargs):
        """``_ask`` for a request the scheduler answers once workers have sent or taken the data
        (the scene's upload, the results' download): when it was asked in vain, the error names a
        worker (one of ``holders()``, the workers holding the data, or any) that has sent no
        heartbeat since it was asked, if the scheduler says so in time."""
        with self._watch_lock:
            self._refresh()  # the heartbeats before the request
        try:
            return self._ask(what, method, *args, seconds=seconds, **kwargs)
        except WrtError as e:
            failure = e
        try:
            workers = None if holders is None else {w for ws in self._ask("its workers", holders).values() for w in ws}
            with self._watch_lock:
                self._refresh()
        except WrtError:
            raise failure from None  # it is the scheduler that does not answer
        now = time.monotonic()
        for worker, (_, heard) in sorted(self._heard.items()):
            if (workers is None or worker in workers) and now - heard >= seconds:
                raise self._error(f"worker {worker} stopped answering: no heartbeat for {now - heard:.3g} s ({what})")
        raise failure from None

    def _raise_failure(self, future) -> None:
        """Raise what ended ``future`` (erred or cancelled): the task's own error, or a
        ``WrtError`` when the cluster lost it (its workers died, the scheduler went away)."""
        from concurrent.futures import CancelledError

        distributed = _dask()
        try:
            future.result(timeout=self.timeout)  # erred or cancelled: raises what the client holds
        except distributed.KilledWorker as e:
            worker = getattr(e.last_worker, "address", e.last_worker)
            raise self._error(
                f"{e.allowed_failures + 1} workers died running one task (the last: {worker}); their logs may say "
                "why: it may crash them or exhaust their memory"
            ) from None
        except CancelledError as e:
            reason = getattr(e, "reason", None) or "cancelled"
            if reason == "scheduler-connection-lost":
                raise self._error("lost the connection to the scheduler while its tasks ran") from None
            raise self._error(
                f"the cluster dropped a task ({reason}): the workers holding its data died or left"
            ) from None
        raise self._error(f"a task ended {future.status} without an error")  # "lost": no value and no error

    def _wait(self, futures: list, stop: threading.Event | None = None) -> bool:
        """Wait until ``futures`` have all run (or failed): True; False when ``stop`` was set first
        (they are cancelled then). Raises ``WrtError`` when the cluster stops working on them
        (``_watch``), after cancelling them."""
        finished = threading.Event()

        def one_done(_) -> None:
            if all(future.done() for future in futures):
                finished.set()

        for future in futures:
            future.add_done_callback(one_done)
        try:
            while not finished.wait(STOP_POLL_S):
                if stop is not None and stop.is_set():
                    self._cancel(futures)
                    return False
                self._watch(futures)
        except WrtError:
            self._cancel(futures)
            raise
        return True

    def _cancel(self, futures: list) -> None:
        """Cancel ``futures``, as far as the scheduler answers (the client drops them anyway)."""
        with contextlib.suppress(WrtError):
            self._ask("the cancellation of its tasks", self.client.cancel, futures)

    def _watch(self, futures: list) -> None:
        """Raise ``WrtError`` when the cluster has stopped working on ``futures`` (those not done):
        the scheduler does not answer, a worker running one of them has sent no heartbeat for
        ``worker_timeout`` seconds, or there has been no worker for that long. The scheduler is
        asked at most every ``WATCH_EVERY_S`` (once for all the waits of the cluster at a time);
        a heartbeat is a change of the worker's ``last_seen``, timed by this machine's clock."""
        with self._watch_lock:
            fresh = time.monotonic() - self._watched_at >= WATCH_EVERY_S
            if fresh:
                self._refresh()
            silent = self._silent(futures)
            if silent and not fresh:  # judged on the scheduler's present state, not one up to WATCH_EVERY_S old
                self._refresh()
                silent = self._silent(futures)
            if silent:
                worker, seconds = silent
                raise self._error(
                    f"worker {worker} stopped answering: no heartbeat for {seconds:.3g} s while it ran a task"
                )
            now = time.monotonic()
            if self._workerless_since is not None and now - self._workerless_since >= self.worker_timeout:
                raise self._workerless(now - self._workerless_since)

    def _silent(self, futures: list) -> tuple[str, float] | None:
        """A worker running one of ``futures`` (not done) that has sent no heartbeat for
        ``worker_timeout`` seconds, and for how long, by the state of the last ``_refresh``."""
        now = time.monotonic()
        for future in futures:
            worker = self._running.get(future.key)
            if worker is not None and not future.done():
                seconds = now - self._heard.get(worker, (None, now))[1]
                if seconds >= self.worker_timeout:
                    return worker, seconds
        return None

    def _refresh(self) -> None:
        """Ask the scheduler about its workers (when each last sent a heartbeat) and what each is
        running: the state ``_watch`` judges by."""
        what = "the state of its workers and tasks"
        workers = self._ask(what, self.client.scheduler.identity)["workers"]
        running = self._ask(what, self.client.processing)
        now = self._watched_at = time.monotonic()
        for worker, info in workers.items():
            if self._heard.get(worker, (None,))[0] != info["last_seen"]:
                self._heard[worker] = (info["last_seen"], now)
        self._heard = {worker: heard for worker, heard in self._heard.items() if worker in workers}
        self._running = {key: worker for worker, keys in running.items() for key in keys}
        if workers:
            self._workerless_since = None
        elif self._workerless_since is None:
            self._workerless_since = now

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

        def submit(shipped, key) -> list:
            return [
                self._submit(render_tile, shipped, key, device, specialize, spp, seed, 0, w * h, 0, spp, None)
                for seed in seeds
            ]

        parts = self._scene_results(scene, list(self._scatter(scene)), submit)
        return [part["rgb"].reshape(h, w, 3) for part in parts]

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
        passes done. ``threads`` in the result: the cluster's worker threads. The light tracer
        (``ptracer``) is refused: its light paths splat anywhere, not into their tile."""
        if scene.render.integrator == "ptracer":
            raise WrtError(
                f"{scene.path}: render.integrator = ptracer: a cluster renders pixel tiles, and a light path splats "
                "anywhere on the film (render it on this machine)"
            )
        start = partial(ClusterTiles, self, device=device, specialize=specialize, stop=stop)
        return render_passes(scene, start, spp=spp, seed=seed, progress=progress, progress_every=progress_every)


class Task:
    """A task on a ``Cluster`` (``Cluster.submit``)."""

    def __init__(self, cluster: Cluster, future):
        self.cluster, self.future = cluster, future

    def result(self):
        """The task's value once it has run, waited for as every wait of the cluster is (bounded by
        the watch: see ``Cluster``); the task's error re-raised, the cluster's a ``WrtError``."""
        return self.cluster._results([self.future])[0]


class ClusterTiles:
    """The tile executor of ``Cluster.render`` (a ``wrt.renderer.TileExecutor``): ``scene`` shipped
    to the workers of ``cluster``, a pass one task per tile of consecutive pixels (about
    ``TILES_PER_THREAD`` per worker thread, at least ``MIN_TILE_PIXELS``), each continuing its
    tile's running sums; the film is on this machine. ``stop`` cancels the pass in flight."""

    def __init__(
        self, cluster: Cluster, scene: Scene, *, device: str, specialize: bool | None, stop: threading.Event | None
    ):
        host = resolve_device("cpu")
        check_memory(scene, host)  # the image is assembled here
        self.cluster, self.scene, self.device, self.specialize, self.stop = cluster, scene, device, specialize, stop
        self.threads = cluster.threads()
        n = scene.render.width * scene.render.height
        size = max(MIN_TILE_PIXELS, math.ceil(n / (TILES_PER_THREAD * max(1, self.threads))))
        self.tiles = [(first, min(size, n - first)) for first in range(0, n, size)]
        self.film = new_film(n, host)
        self.shipment = list(cluster._scatter(scene))
        self.build_time_s = self.compile_time_s = 0.0  # the most a task of a pass spent on them

    def run_pass(self, first_sample: int, pass_spp: int, active: np.ndarray | None) -> bool:
        """See ``wrt.renderer.TileExecutor.run_pass``; ``active`` is None (no adaptive sampling on a cluster)."""
        spp, seed = self.scene.render.spp, self.scene.render.seed

        def submit(shipped, key) -> list:
            futures = []
            for first, count in self.tiles:
                tile = slice(first, first + count)
                state = {name: getattr(self.film, name).numpy()[tile] for name in PASS_STATE} if first_sample else None
                samples = (spp, seed, first, count, first_sample, pass_spp, state)
                futures.append(self.cluster._submit(render_tile, shipped, key, self.device, self.specialize, *samples))
            return futures

        # all the tiles' results, before the film changes
        parts = self.cluster._scene_results(self.scene, self.shipment, submit, self.stop)
        if parts is None:
            return False
        for (first, count), part in zip(self.tiles, parts):
            for name in pass_outputs(first_sample):
                getattr(self.film, name).numpy()[first : first + count] = part[name]
            self.build_time_s = max(self.build_time_s, part["build_time_s"])
            self.compile_time_s = max(self.compile_time_s, part["compile_time_s"])
        return True


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
            load_s = load(kernel.module, dev)
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
    specialize: bool | None,
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
    running sums ``state`` (``wrt.renderer.PASS_STATE`` arrays of the tile; None for the first
    pass), with ``wrt.renderer.render_kernel_for(scene, specialize, device)`` (on a worker, its own cache decides).

    Returns the tile's arrays a pass writes (``wrt.renderer.pass_outputs``) as numpy,
    and ``build_time_s``, ``compile_time_s``: what this task spent building the device scene and
    loading the kernel (0 once the worker has them).
    """
    dev = resolve_device(device)
    kernel = render_kernel_for(scene, specialize, dev)
    (device_scene, films), build_s, load_s = _device_scene(scene, key, dev, kernel)
    with _lock:
        film = films.pop() if films else new_film(device_scene.width * device_scene.height, dev)
    try:
        if state is not None:
            for name, values in state.items():
                target = getattr(film, name)
                wp.copy(target, wp.array(values, dtype=target.dtype, device=dev), dest_offset=first, count=count)
        replace(device_scene, film=film).launch(kernel, first, count, spp, seed, None, first_sample, pass_spp)
        names = pass_outputs(first_sample)
        out = {name: np.array(getattr(film, name)[first : first + count].numpy()) for name in names}
    finally:
        with _lock:
            films.append(film)
    return {**out, "build_time_s": build_s, "compile_time_s": load_s}
