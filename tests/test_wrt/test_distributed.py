"""wrt.distributed: renders, references and matrix entries on a Dask ``LocalCluster`` of two
worker processes are bit-identical to local runs, ship everything a worker needs, and build
each scene and load each kernel once per worker. A cluster that cannot be used (nothing or
something silent at the address, a transport that cannot work here, a scheduler or worker that
stops answering, workers that die) is one error line, after a bounded wait, never a hang."""

from __future__ import annotations

import contextlib
import gc
import json
import logging
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("distributed")

from conftest import EXAMPLES  # noqa: E402
from wrt_harness import references  # noqa: E402
from wrt_harness.matrix import load_features, select  # noqa: E402
from wrt_harness.run import evaluate  # noqa: E402

import wrt  # noqa: E402
import wrt.distributed as wd  # noqa: E402
from wrt.cli import main  # noqa: E402
from wrt.errors import WrtError  # noqa: E402
from wrt.imageio import read_image  # noqa: E402
from wrt.loader import override_render  # noqa: E402

SCENE = EXAMPLES / "path" / "emissive_mesh.toml"  # three mesh files: OBJ and STL
# one LocalCluster for the module: under pytest-xdist, with --dist loadgroup, all its tests go to one worker
pytestmark = pytest.mark.xdist_group("dask_local_cluster")


@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster

    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local,
        wd.Cluster(local.scheduler_address) as connected,
    ):
        yield connected


@pytest.fixture
def shipped_scene(tmp_path):
    """The example scene loaded from a copy whose mesh files are deleted once it is parsed: a
    worker that read a file would fail."""
    shutil.copytree(EXAMPLES / "meshes", tmp_path / "meshes")
    (tmp_path / "path").mkdir()
    shutil.copy(SCENE, tmp_path / "path" / SCENE.name)
    scene = wrt.load_scene(str(tmp_path / "path" / SCENE.name))
    shutil.rmtree(tmp_path / "meshes")
    return override_render(scene, width=32, height=24)


def assert_same(a: wrt.RenderResult, b: wrt.RenderResult) -> None:
    assert a.spp == b.spp and a.rejected_samples == b.rejected_samples
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert a.aovs.keys() == b.aovs.keys()
    for name in a.aovs:
        np.testing.assert_array_equal(a.aovs[name], b.aovs[name], err_msg=name)


def test_tiles_and_passes_are_bit_identical_to_a_local_render(cluster, shipped_scene):
    passes = []
    tiled = cluster.render(shipped_scene, spp=5, seed=3, progress=lambda done, *rest: passes.append(done))
    assert len(passes) > 1 and passes[-1] == 5  # several passes, each continuing the tiles' sums
    assert shipped_scene.render.width * shipped_scene.render.height > wd.MIN_TILE_PIXELS  # several tiles
    assert_same(tiled, wrt.render(shipped_scene, spp=5, seed=3))
    assert_same(tiled, wrt.render(shipped_scene, spp=5, seed=3, threads=1))
    assert tiled.rgb.std() > 0.01  # a real image, not two equal blanks


def test_a_worker_builds_a_scene_and_loads_a_kernel_once(cluster, shipped_scene):
    before = cluster.client.run(wd.worker_stats)
    results = [cluster.render(shipped_scene, spp=spp, seed=spp) for spp in (1, 2, 3, 4)]  # 3 tiles each
    after = cluster.client.run(wd.worker_stats)
    assert len(after) == 2
    for worker, stats in after.items():
        assert stats["scenes_prepared"] - before[worker]["scenes_prepared"] <= 1, worker
        assert stats["kernel_loads"] - before[worker]["kernel_loads"] <= 1, worker
    assert results[-1].build_time_s == 0.0 and results[-1].compile_time_s == 0.0


def test_wrt_render_on_the_scheduler_writes_the_local_image(cluster, tmp_path):
    common = [str(SCENE), "--width", "32", "--height", "24", "--spp", "3", "--aov", "all"]
    assert main(["render", *common, "-o", str(tmp_path / "local.exr")]) == 0
    assert main(["render", *common, "-o", str(tmp_path / "cluster.exr"), "--scheduler", cluster.address]) == 0
    local, remote = read_image(str(tmp_path / "local.exr")), read_image(str(tmp_path / "cluster.exr"))
    np.testing.assert_array_equal(remote.rgb, local.rgb)
    assert remote.aovs.keys() == local.aovs.keys()
    for name in local.aovs:
        np.testing.assert_array_equal(remote.aovs[name], local.aovs[name], err_msg=name)


@pytest.mark.parametrize(
    "address, words", [("nonsense", "not a scheduler address"), ("tcp://127.0.0.1:9", "cannot connect")]
)
def test_an_unreachable_scheduler_is_one_error_line(tmp_path, capsys, monkeypatch, address, words):
    monkeypatch.setattr(wd, "CONNECT_TIMEOUT_S", 0.5)
    out = tmp_path / "out.exr"
    assert main(["render", str(SCENE), "--width", "8", "--height", "8", "-o", str(out), "--scheduler", address]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"wrt: error: --scheduler {address}: {words}"), err
    assert not out.exists()


def test_without_dask_the_scheduler_option_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed: ImportError
    out = tmp_path / "out.exr"
    assert main(["render", str(SCENE), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert "pip install 'wrt[cluster]'" in capsys.readouterr().err and not out.exists()


def test_a_reference_and_its_calibration_are_bit_identical(cluster):
    feature = replace(select(load_features(), ["emissive_mesh"])[0], width=32, height=24)
    local = references.render_reference(feature, spp=32)
    remote = references.render_reference(feature, spp=32, cluster=cluster)  # 32 batches, one task each
    np.testing.assert_array_equal(remote.rgb, local.rgb)
    np.testing.assert_array_equal(remote.variance, local.variance)
    assert remote.spp == local.spp == 32 and local.variance.max() > 0.0
    assert references.calibrate(feature, local, cluster=cluster) == references.calibrate(feature, local)


def test_a_matrix_entry_is_one_task_with_the_local_scores(cluster):
    feature = select(load_features(), ["raycast_mesh"])[0]
    local, remote = evaluate(feature), evaluate(feature, cluster=cluster)
    assert local.passed and remote.passed
    for key in ("ssim", "z", "geometry_ssim", "rmse", "max_error", "failures"):
        assert getattr(remote, key) == getattr(local, key), key
    for name, image in local.images.items():
        np.testing.assert_array_equal(remote.images[name], image, err_msg=name)


def test_wrt_refs_regenerate_and_wrt_matrix_on_the_scheduler(cluster, tmp_path, capsys):
    for folder, options in (("local", []), ("cluster", ["--scheduler", cluster.address])):
        assert main(["refs", "regenerate", "raycast_mesh", "--refs", str(tmp_path / folder), *options]) == 0
    local, remote = (read_image(str(tmp_path / folder / "raycast_mesh.exr")) for folder in ("local", "cluster"))
    np.testing.assert_array_equal(remote.rgb, local.rgb)
    np.testing.assert_array_equal(remote.aovs["variance"], local.aovs["variance"])
    assert remote.metadata == local.metadata
    calibrations = [json.loads((tmp_path / f / "raycast_mesh.json").read_text()) for f in ("local", "cluster")]
    for calibration in calibrations:
        calibration.pop("reference_sha256")  # of the EXR file, whose header has a time stamp
    assert calibrations[0] == calibrations[1]
    capsys.readouterr()
    assert main(["matrix", "raycast_mesh", "--refs", str(tmp_path / "cluster"), "--scheduler", cluster.address]) == 0
    assert "1 passed, 0 failed" in capsys.readouterr().out


def test_a_worker_error_reaches_the_client(cluster, shipped_scene):
    with pytest.raises(WrtError, match="no CUDA device|device 'nowhere'"):
        cluster.render(shipped_scene, spp=1, device="nowhere")


def test_an_upload_a_dying_worker_broke_is_sent_again(cluster, shipped_scene, monkeypatch):
    """Dask's scheduler drops the client's connection when a worker it scatters to has died (its
    CommClosedError ends the request's handler): the scene is sent again, the image unchanged."""
    from distributed.comm.core import CommClosedError

    scatter, calls = cluster.client.scatter, []

    def dropped_once(*args, **kwargs):
        calls.append(args)
        if len(calls) == 1:
            raise CommClosedError("in <TCP (closed) ConnectionPool.scatter>: Stream is closed")
        return scatter(*args, **kwargs)

    monkeypatch.setattr(cluster.client, "scatter", dropped_once)
    with deadline(60):
        tiled = cluster.render(shipped_scene, spp=1, seed=11)
    assert len(calls) == 2
    assert_same(tiled, wrt.render(shipped_scene, spp=1, seed=11))


# ---- An unusable cluster: one error line after a bounded wait, never a hang ----------------------


@contextlib.contextmanager
def deadline(seconds: float):
    """Fail a block that is still running after ``seconds`` (SIGALRM): a wait with no end fails its
    test instead of hanging the suite."""

    def expired(signum, frame):
        raise AssertionError(f"still waiting after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def one_error_line(capsys, address: str) -> str:
    """The one line on stderr, ``wrt: error: --scheduler ADDRESS: ...``, without its prefix."""
    err = capsys.readouterr().err.splitlines()
    prefix = f"wrt: error: --scheduler {address}: "
    assert len(err) == 1 and err[0].startswith(prefix), err
    return err[0][len(prefix) :]


class Relay:
    """A TCP listener at ``address`` that passes bytes both ways to and from ``target`` (host,
    port) or, without one, accepts connections and never says a word. ``freeze()`` stops passing
    bytes on, connections held open: a scheduler that stops answering."""

    def __init__(self, target: tuple[str, int] | None = None):
        self.target, self.frozen, self.closed = target, threading.Event(), threading.Event()
        self.server = socket.create_server(("127.0.0.1", 0))
        self.server.settimeout(0.1)
        self.sockets = [self.server]
        self.address = f"tcp://127.0.0.1:{self.server.getsockname()[1]}"
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while not self.closed.is_set():
            try:
                near = self.server.accept()[0]
            except (TimeoutError, OSError):
                continue
            self.sockets.append(near)
            if self.target is not None:
                far = socket.create_connection(self.target)
                self.sockets.append(far)
                for a, b in ((near, far), (far, near)):
                    threading.Thread(target=self._pass, args=(a, b), daemon=True).start()

    def _pass(self, source: socket.socket, sink: socket.socket) -> None:
        with contextlib.suppress(OSError):
            while data := source.recv(1 << 16):
                while self.frozen.is_set() and not self.closed.is_set():
                    time.sleep(0.05)
                sink.sendall(data)

    def freeze(self) -> None:
        self.frozen.set()

    def close(self) -> None:
        self.closed.set()
        for s in self.sockets:
            with contextlib.suppress(OSError):
                s.close()


@pytest.fixture
def silent():
    """The address of a listener that accepts connections and never answers."""
    relay = Relay()
    yield relay.address
    relay.close()


def scheduler_hostport(address: str) -> tuple[str, int]:
    host, port = address.removeprefix("tcp://").rsplit(":", 1)
    return host, int(port)


COMMANDS = {  # every command with --scheduler; each builds its Cluster with the defaults
    "render": ["render", str(SCENE), "--width", "8", "--height", "8", "-o", "{tmp}/out.exr"],
    "matrix": ["matrix", "raycast_mesh"],
    "refs regenerate": ["refs", "regenerate", "raycast_mesh", "--refs", "{tmp}/refs"],
}


@pytest.mark.parametrize("command", COMMANDS)
def test_a_listener_that_never_answers_is_one_error_line_after_the_timeout(
    tmp_path, capsys, monkeypatch, silent, command
):
    monkeypatch.setattr(wd, "CONNECT_TIMEOUT_S", 0.5)  # the default every command uses; 10 s in the product
    args = [arg.format(tmp=tmp_path) for arg in COMMANDS[command]]
    t0 = time.perf_counter()
    with deadline(10):
        assert main([*args, "--scheduler", silent]) == 2
        gc.collect()  # a Client left half made would close itself here, waiting 2 timeouts
    assert time.perf_counter() - t0 < 3
    assert one_error_line(capsys, silent) == "cannot connect to a Dask scheduler there: no answer within 0.5 s"
    assert not [path for path in tmp_path.rglob("*") if path.is_file()]  # no image, no reference


def test_the_bounds_are_the_documented_defaults(cluster):
    assert wd.CONNECT_TIMEOUT_S == 10 and wd.WORKER_TIMEOUT_S == 30
    assert cluster.timeout == wd.CONNECT_TIMEOUT_S and cluster.worker_timeout == wd.WORKER_TIMEOUT_S  # as the CLI's
    with wd.Cluster(cluster.address, timeout=2, worker_timeout=3) as chosen:
        assert (chosen.timeout, chosen.worker_timeout) == (2, 3)


@pytest.mark.parametrize(
    "address, words",
    [
        ("ucx://127.0.0.1:9", "Dask's ucx:// transport cannot be used here"),  # distributed-ucxx not installed
        ("tls://127.0.0.1:9", "tls:// needs TLS certificates in Dask's configuration"),
        ("inproc://127.0.0.1/1/1", "cannot connect to a Dask scheduler there (inproc address"),  # another process
        ("inproc://x", "not a scheduler address like tcp://host:8786"),
    ],
)
def test_a_transport_that_cannot_work_here_is_one_error_line(tmp_path, capsys, monkeypatch, address, words):
    monkeypatch.setattr(wd, "CONNECT_TIMEOUT_S", 0.5)
    out = tmp_path / "out.exr"
    t0 = time.perf_counter()
    with deadline(10):
        assert (
            main(["render", str(SCENE), "--width", "8", "--height", "8", "-o", str(out), "--scheduler", address]) == 2
        )
        gc.collect()
    assert time.perf_counter() - t0 < 3
    assert one_error_line(capsys, address).startswith(words)
    assert not out.exists()


def test_a_connection_that_failed_leaves_nothing_to_wait_for_at_exit(tmp_path):
    """As a user runs it: a Dask client that failed to connect, left half made, used to wait
    2 timeouts (20 s) when the interpreter collected it, and print a traceback."""
    command = [sys.executable, "-m", "wrt", "render", str(SCENE), "--width", "8", "--height", "8"]
    command += ["-o", str(tmp_path / "out.exr"), "--scheduler", "inproc://127.0.0.1/1/1"]  # another process's
    t0 = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, timeout=60)
    assert time.perf_counter() - t0 < 15
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("wrt: error: --scheduler inproc://127.0.0.1/1/1: cannot connect to a Dask scheduler")


def test_a_scheduler_that_stops_answering_ends_every_wait(cluster, shipped_scene):
    relay = Relay(scheduler_hostport(cluster.address))
    try:
        with deadline(30):
            frozen = wd.Cluster(relay.address, timeout=0.5)
            relay.freeze()
            t0 = time.perf_counter()
            silence = rf"^--scheduler {relay.address}: the scheduler did not answer within 0.5 s \("
            with pytest.raises(WrtError, match=silence + "the count of its worker threads"):
                frozen.threads()
            with pytest.raises(WrtError, match=silence):
                frozen.images(shipped_scene, [0], spp=1)  # before the scene's upload (bounded too: see below)
            with pytest.raises(WrtError, match=silence + "the state of its workers and tasks"):
                frozen.submit(sum, [1, 2]).result()  # the wait for a result
            frozen.close()
            assert time.perf_counter() - t0 < 8
    finally:
        relay.close()


@pytest.fixture(scope="module")
def fragile():
    """A LocalCluster whose workers the tests stop and kill (their nannies start new ones); a task
    is run again once after its worker died."""
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        scheduler_kwargs={"allowed_failures": 1},
    ) as local:
        yield local


def worker_pids(local, n: int = 2) -> dict[str, int]:
    """The process id of each of ``n`` workers of ``local``, once it has them."""
    local.wait_for_workers(n, timeout=60)
    with wd.Cluster(local.scheduler_address) as connected:
        return connected.client.run(os.getpid)


def die_once(marker: str) -> int:
    """A task that kills its worker the first time it runs (``marker`` does not exist), then returns 7."""
    if not os.path.exists(marker):
        open(marker, "w").close()
        os.kill(os.getpid(), signal.SIGKILL)
    return 7


def test_a_worker_that_stops_answering_is_one_error_line(fragile, monkeypatch):
    monkeypatch.setattr(wd, "WORKER_TIMEOUT_S", 1.5, raising=False)  # the default; 30 s in the product
    pids = worker_pids(fragile)
    for pid in pids.values():
        os.kill(pid, signal.SIGSTOP)
    try:
        with deadline(30), wd.Cluster(fragile.scheduler_address) as cluster:
            t0 = time.perf_counter()
            with pytest.raises(WrtError) as stopped:
                cluster.submit(sum, [1, 2]).result()
            assert 1.5 < time.perf_counter() - t0 < 6
    finally:
        for pid in pids.values():
            os.kill(pid, signal.SIGCONT)
    message = str(stopped.value)
    assert message.startswith(f"--scheduler {fragile.scheduler_address}: worker ") and "\n" not in message
    assert any(f"worker {worker} stopped answering: no heartbeat for " in message for worker in pids), message


def test_a_worker_that_stops_answering_with_a_result_is_one_error_line(fragile):
    pids = worker_pids(fragile)
    with deadline(30), wd.Cluster(fragile.scheduler_address, timeout=1) as cluster:
        task = cluster.submit(sum, [1, 2])
        while not task.future.done():
            time.sleep(0.05)
        holder = cluster.client.who_has([task.future])[task.future.key][0]
        os.kill(pids[holder], signal.SIGSTOP)
        try:
            t0 = time.perf_counter()
            with pytest.raises(
                WrtError, match=rf"^--scheduler \S+: worker {holder} stopped answering: no heartbeat for "
            ):
                task.result()  # the download of its value
            assert time.perf_counter() - t0 < 5
        finally:
            os.kill(pids[holder], signal.SIGCONT)


def test_workers_that_stop_answering_before_the_scene_is_shipped_are_one_error_line(fragile, shipped_scene):
    pids = worker_pids(fragile)
    for pid in pids.values():
        os.kill(pid, signal.SIGSTOP)
    try:
        with deadline(30), wd.Cluster(fragile.scheduler_address, timeout=1) as cluster:
            t0 = time.perf_counter()
            with pytest.raises(WrtError) as stopped:
                cluster.images(shipped_scene, [0], spp=1)
            assert time.perf_counter() - t0 < 5
    finally:
        for pid in pids.values():
            os.kill(pid, signal.SIGCONT)
    upload = r" stopped answering: no heartbeat for [\d.]+ s \(the upload of the scene, [\d.]+ MB\)$"
    assert any(re.search(f"worker {worker}{upload}", str(stopped.value)) for worker in pids), stopped.value


def test_a_worker_killed_mid_render_leaves_the_image_bit_identical(fragile, shipped_scene):
    pids = worker_pids(fragile)
    killed = []

    def kill_one(done, *rest):
        if not killed:  # after the first pass: the next one's tiles lose a worker and run again
            killed.append(next(iter(pids.values())))
            os.kill(killed[0], signal.SIGKILL)

    with deadline(60), wd.Cluster(fragile.scheduler_address) as cluster:
        tiled = cluster.render(shipped_scene, spp=3, seed=5, progress=kill_one, progress_every=1)
    assert killed and tiled.spp == 3
    assert_same(tiled, wrt.render(shipped_scene, spp=3, seed=5))


def test_a_task_run_again_after_its_worker_died_returns_its_result(fragile, tmp_path, capsys):
    worker_pids(fragile)
    with deadline(60), wd.Cluster(fragile.scheduler_address) as cluster:
        assert cluster.submit(die_once, str(tmp_path / "died")).result() == 7
    assert capsys.readouterr().err == ""


def test_a_task_that_kills_every_worker_is_one_error_line(fragile, capsys):
    worker_pids(fragile)
    with deadline(60), wd.Cluster(fragile.scheduler_address) as cluster:
        with pytest.raises(WrtError) as killed:
            cluster.submit(os._exit, 1).result()  # each worker it runs on dies
        assert cluster.dask_log(), "Dask's own account of the deaths: kept, not printed"
    prefix = f"--scheduler {fragile.scheduler_address}: "
    message = str(killed.value)
    assert message.startswith(prefix) and "\n" not in message
    assert "died" in message and "tcp://127.0.0.1:" in message.removeprefix(prefix), message  # the last worker
    assert capsys.readouterr().err == ""


def test_workers_that_all_die_mid_render_and_come_back_leave_the_image_bit_identical(fragile, shipped_scene):
    pids = worker_pids(fragile)

    def kill_all(done, *rest):
        if done == 1:  # the scene dies with them: it is shipped again to the workers the nannies start
            for pid in pids.values():
                os.kill(pid, signal.SIGKILL)

    with deadline(60), wd.Cluster(fragile.scheduler_address) as cluster:
        tiled = cluster.render(shipped_scene, spp=3, seed=5, progress=kill_all, progress_every=1)
    assert_same(tiled, wrt.render(shipped_scene, spp=3, seed=5))


def test_workers_that_all_die_mid_render_for_good_are_one_error_line(shipped_scene, capsys, monkeypatch):
    monkeypatch.setattr(wd, "WORKER_TIMEOUT_S", 1.5, raising=False)
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as local:
        command = [sys.executable, "-m", "distributed.cli.dask_worker", local.scheduler_address, "--no-nanny"]
        worker = subprocess.Popen([*command, "--nthreads", "1", "--no-dashboard"], stderr=subprocess.DEVNULL)
        try:
            local.wait_for_workers(1, timeout=60)
            with deadline(60), wd.Cluster(local.scheduler_address) as cluster:
                t0 = time.perf_counter()
                with pytest.raises(WrtError) as died:
                    cluster.render(shipped_scene, spp=3, progress=lambda *args: worker.kill(), progress_every=1)
                assert time.perf_counter() - t0 < 30
        finally:
            worker.kill()
            worker.wait()
    # Which of the two lines comes first is a race: the scheduler drops the killed worker when it sees
    # its connection close, which a loaded machine may delay past the heartbeat timeout. Both are true.
    gone = (
        rf"--scheduler {local.scheduler_address}: (the scheduler has had no workers for [\d.]+ s: they died or left"
        rf"|worker \S+ stopped answering: no heartbeat for [\d.]+ s while it ran a task)"
    )
    assert re.fullmatch(gone, str(died.value)) and capsys.readouterr().err == "", died.value


def test_a_cluster_left_without_workers_is_one_error_line(fragile, monkeypatch):
    monkeypatch.setattr(wd, "WORKER_TIMEOUT_S", 1.5, raising=False)
    worker_pids(fragile)
    with deadline(60), wd.Cluster(fragile.scheduler_address) as cluster:
        fragile.scale(0)
        try:
            while cluster.client.nthreads():
                time.sleep(0.1)
            t0 = time.perf_counter()
            with pytest.raises(WrtError, match=rf"^--scheduler {fragile.scheduler_address}: the scheduler has had no "):
                cluster.submit(sum, [1, 2]).result()
            assert time.perf_counter() - t0 < 6
        finally:
            fragile.scale(2)


def test_dask_logs_only_to_the_cluster_while_one_is_open(cluster):
    names = ("distributed", "distributed.client", "tornado")
    before = {name: list(logging.getLogger(name).handlers) for name in names}
    with wd.Cluster(cluster.address) as connected:
        logging.getLogger("distributed.client").warning("a warning of Dask's")
        assert any("a warning of Dask's" in line for line in connected.dask_log())
        for name in names:
            assert not any(isinstance(h, logging.StreamHandler) for h in logging.getLogger(name).handlers), name
    assert {name: list(logging.getLogger(name).handlers) for name in names} == before
