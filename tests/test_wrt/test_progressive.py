"""Progressive rendering (wrt/renderer.py passes, the integrator's sample offset, `wrt render`'s
progress bar, --checkpoint-every and Ctrl-C)."""

import fcntl
import os
import pty
import re
import select
import signal
import struct
import subprocess
import sys
import termios
import time

import numpy as np
import pytest
from conftest import ROOT, make_scene

import wrt
import wrt.imageio
import wrt.renderer
from wrt.cli import main
from wrt.device import resolve_device
from wrt.imageio import read_image
from wrt.loader import override_render
from wrt.renderer import new_film, pass_size, render_passes


def path_scene(spp=13, width=24, height=16):
    """Soft shadow and glossy bounce under an area light: every sample differs."""
    shapes = [
        {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "grey"},
        {"type": "sphere", "center": [-0.6, -0.2, 0], "radius": 0.8, "material": "red"},
        {"type": "sphere", "center": [0.9, -0.5, 0.5], "radius": 0.5, "material": "metal"},
    ]
    materials = [
        {"name": "grey", "albedo": [0.5, 0.5, 0.5]},
        {"name": "red", "albedo": [0.9, 0.2, 0.1]},
        {"name": "metal", "type": "glossy", "roughness": 0.3, "reflectance": [0.9, 0.9, 0.9]},
    ]
    lights = [{"type": "area", "corner": [-1, 3, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2], "radiance": [4, 4, 4]}]
    render = {"width": width, "height": height, "spp": spp, "seed": 5, "integrator": "path", "max_depth": 5}
    return make_scene(shapes, materials=materials, lights=lights, render=render)


@pytest.mark.parametrize("every, pass_seconds", [(1, 1.0), (5, 1.0), (None, 1e-5)])
def test_passes_are_bit_identical_to_one_pass(monkeypatch, every, pass_seconds):
    scene = path_scene()
    one = wrt.render(scene, threads=1)
    monkeypatch.setattr(wrt.renderer, "PASS_SECONDS", pass_seconds)
    monkeypatch.setattr(wrt.renderer, "TILE_PIXELS", 97)  # tiles that cut rows anywhere
    for threads in (1, 2, 3):
        passes = []
        progressive = wrt.render(
            scene, threads=threads, progress=lambda done, *_: passes.append(done), progress_every=every
        )
        assert len(passes) > 3 and passes[-1] == 13 and progressive.spp == 13
        assert np.array_equal(one.rgb, progressive.rgb)
        for name in one.aovs:
            assert np.array_equal(one.aovs[name], progressive.aovs[name])


def test_progress_reports_every_pass_and_stops_when_asked():
    scene = path_scene(spp=16)
    calls = []

    def progress(done, spp, elapsed, snapshot):
        calls.append((done, spp, elapsed, snapshot() if done in (2, 4) else None))
        return done < 4

    stopped = wrt.render(scene, progress=progress, progress_every=2)
    done = [c[0] for c in calls]
    assert done == [1, 2, 4] and all(c[1] == 16 for c in calls)
    assert 0 < calls[0][2] <= calls[1][2] <= calls[2][2]
    assert stopped.spp == 4 and stopped.render_time_s == calls[-1][2]
    # k > 1 samples of a longer render are exactly the render with spp = k; snapshots are copies
    for k, snapshot in ((2, calls[1][3]), (4, calls[2][3]), (4, stopped)):
        assert snapshot.spp == k
        assert np.array_equal(snapshot.rgb, wrt.render(scene, spp=k).rgb)


def test_first_pass_of_a_many_sample_render_is_not_the_pixel_centre():
    """spp = 1 renders the pixel centre; a render of more samples never does, even one stopped
    after its first sample."""
    scene = path_scene(spp=8)
    first = wrt.render(scene, progress=lambda *_: False)
    centre = wrt.render(scene, spp=1)
    assert first.spp == 1
    assert not np.array_equal(first.rgb, centre.rgb)
    for name in centre.aovs:
        assert np.array_equal(first.aovs[name], centre.aovs[name])


def test_pass_size():
    assert pass_size(1024, 0, 0.0, None) == 1  # the first pass measures the rate
    assert pass_size(1024, 10, 0.5, None) == 20  # then about PASS_SECONDS at the rate so far
    assert pass_size(1024, 10, 0.5, 16) == 6  # ending at the next multiple of `every`
    assert pass_size(1024, 1020, 0.5, None) == 4  # and at spp
    assert pass_size(1024, 10, 100.0, None) == 1


class RecordingTiles:
    """A tile executor that draws no samples: it records the passes asked of it and abandons the
    one starting at ``abandon`` (as a stop would)."""

    def __init__(self, scene, abandon):
        self.film = new_film(scene.render.width * scene.render.height, resolve_device("cpu"))
        self.device, self.threads, self.build_time_s, self.compile_time_s = "recording", 7, 0.5, 0.25
        self.passes, self.abandon = [], abandon

    def run_pass(self, first_sample, pass_spp, active):
        if first_sample == self.abandon:
            return False
        self.passes.append((first_sample, pass_spp, active))
        return True


def test_the_pass_loop_drives_any_tile_executor():
    """One pass loop for every executor (local threads, a Dask cluster): it sizes the passes,
    reports them, ends at an abandoned pass, and assembles the result from the executor's film."""
    started, reported = [], []

    def start(scene):
        started.append(RecordingTiles(scene, abandon=4))
        return started[-1]

    result = render_passes(
        path_scene(spp=13), start, spp=9, seed=2, progress=lambda done, *_: reported.append(done), progress_every=2
    )
    (tiles,) = started
    assert tiles.passes == [(0, 1, None), (1, 1, None), (2, 2, None)]  # one sample, then to every multiple of 2
    assert reported == [1, 2, 4]  # the pass from 4 on was abandoned
    assert (result.spp, result.seed, result.device, result.threads) == (4, 2, "recording", 7)
    assert (result.build_time_s, result.compile_time_s) == (0.5, 0.25) and result.render_time_s > 0
    assert result.rgb.shape == (16, 24, 3) and sorted(result.aovs) == ["depth", "normal", "object_id", "position"]
    with pytest.raises(wrt.WrtError, match="progress_every must be >= 1, got 0"):
        render_passes(path_scene(), start, spp=None, seed=None, progress=None, progress_every=0)
    assert len(started) == 1  # refused before the executor started


def test_checkpoints_are_written_every_n_samples(tmp_path, monkeypatch, capsys):
    out = tmp_path / "c.exr"
    written = []

    def write_and_read(path, *args, **kwargs):
        write_image(path, *args, **kwargs)
        written.append(read_image(path))

    write_image = wrt.imageio.write_image
    monkeypatch.setattr(wrt.imageio, "write_image", write_and_read)
    scene_file = str(ROOT / "examples/spheres.toml")
    args = [
        "render",
        scene_file,
        "-o",
        str(out),
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "7",
        "--checkpoint-every",
        "2",
        "--aov",
        "depth",
    ]
    assert main(args) == 0
    assert [image.metadata["spp"] for image in written] == [2, 4, 6, 7]
    scene = override_render(wrt.load_scene(scene_file), width=40, height=30)
    for image in written:
        assert np.array_equal(image.rgb, wrt.render(scene, spp=image.metadata["spp"]).rgb) and "depth" in image.aovs
    assert [p.name for p in tmp_path.iterdir()] == ["c.exr"]
    captured = capsys.readouterr()
    assert "7 spp" in captured.out and "M samples/s" in captured.out
    assert "spp" not in captured.err  # no progress bar when stderr is not a terminal
    assert main(args[:-4] + ["--checkpoint-every", "0"]) == 2


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["ctrl-c", "sigterm"])
def test_a_signal_writes_the_samples_done_and_exits_128_plus_it(tmp_path, sig, code):
    """`wrt render` on a terminal: a progress bar; SIGINT (Ctrl-C) or SIGTERM mid-render stops
    after the running pass and writes it (issue 13: SIGTERM used to exit 143 writing nothing)."""
    out = tmp_path / "spheres.exr"
    spp = 10**6
    controller, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # tqdm draws nothing on 0 columns
    cmd = [
        sys.executable,
        "-m",
        "wrt",
        "render",
        str(ROOT / "examples/spheres.toml"),
        "-o",
        str(out),
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        str(spp),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=terminal, text=True)
    os.close(terminal)
    shown, sent, deadline = b"", None, time.monotonic() + 300  # a cold Warp kernel cache compiles first
    while proc.poll() is None and time.monotonic() < deadline:
        if select.select([controller], [], [], 0.1)[0]:
            try:
                shown += os.read(controller, 4096)
            except OSError:  # the render ended and closed the terminal
                break
        if sent is None and re.search(rb"\b[1-9]\d*/1000000 spp, .*M samples/s", shown):
            proc.send_signal(sig)  # at least one pass done: the bar shows samples/s and an ETA
            sent = time.monotonic()
    if proc.poll() is None:
        proc.kill()
    stdout = proc.communicate()[0]
    os.close(controller)
    assert sent is not None, shown.decode(errors="replace")
    assert proc.returncode == code and time.monotonic() - sent < 10
    assert re.search(rb"\d+:\d\d<\d+:\d\d", shown)  # elapsed < ETA
    image = read_image(out)
    assert image.rgb.shape == (48, 64, 3) and np.isfinite(image.rgb).all() and image.rgb.max() > 0
    assert 1 <= image.metadata["spp"] < spp
    assert f"{image.metadata['spp']} spp" in stdout and f"wrote {out}" in stdout


def test_stop_mid_pass_rolls_the_pass_back(monkeypatch):
    """A stop request inside a pass ends the render at the next tile, without waiting for the
    pass (issue 13: one Ctrl-C in a long pass waited for its end): the tiles of that pass already
    done are rolled back, so the image is exactly the render with the samples of the passes
    completed; a stop in the first pass gives 0 samples."""
    import threading

    monkeypatch.setattr(wrt.renderer, "TILE_PIXELS", 64)
    scene = path_scene(spp=6)
    launch = wrt.renderer.DeviceScene.launch
    for stop_in_pass, samples in ((2, 2), (0, 0)):
        stop, calls = threading.Event(), []

        def counted(self, kernel, first, count, spp, seed, rec=None, first_sample=0, *args):
            calls.append(first_sample)
            if calls.count(stop_in_pass) == 2:  # the second tile of that pass is under way
                stop.set()
            return launch(self, kernel, first, count, spp, seed, rec, first_sample, *args)

        monkeypatch.setattr(wrt.renderer.DeviceScene, "launch", counted)
        result = wrt.render(scene, threads=1, progress=lambda *a: True, progress_every=2, stop=stop)
        monkeypatch.setattr(wrt.renderer.DeviceScene, "launch", launch)
        assert result.spp == samples and calls.count(stop_in_pass) == 2
        if samples:
            assert np.array_equal(result.rgb, wrt.render(scene, spp=samples).rgb)
        else:
            assert not result.rgb.any() and (result.aovs["object_id"] == 0).all()
