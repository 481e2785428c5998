"""The ``wrt`` command under hostile conditions: signals at the worst moments, standard output that
cannot be written, options that are not numbers, and ``--half`` radiance beyond half floats.

The promises (README, "Using it"): a signal never throws away the samples done, never leaves a
temporary file and never prints a traceback; output the user cannot read does not fail the work;
a bad option is one line and exit code 2; no Inf is ever written.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from wrt.cli import main
from wrt.console import Terminated, held_signals, terminate
from wrt.imageio import read_image

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "examples" / "raycast" / "raycast_sphere.toml"
SPHERES = ROOT / "examples" / "spheres.toml"
WRT = [sys.executable, "-m", "wrt"]


def one_error_line(capsys) -> str:
    """The one error line on stderr: ``wrt: error: ...``, or argparse's ``wrt VERB: error: ...``."""
    err = capsys.readouterr().err
    assert re.match(r"wrt( \w+)?: error: ", err) and err.count("\n") == 1 and "Traceback" not in err, err
    return err


# --- signals -------------------------------------------------------------------------------------


def run_patched(tmp_path, patch: str, args: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    """``wrt ARGS`` in a process of its own, the console entry point, after the Python ``patch``."""
    script = tmp_path / "run.py"
    script.write_text(
        "import os, signal, sys, time\n"
        + textwrap.dedent(patch)
        + "\nfrom wrt.cli import console\n"
        + f"sys.argv = ['wrt', *{args!r}]\nsys.exit(console())\n"
    )
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=timeout)


WRITE_WITH_SIGNALS = """
import wrt.imageio as imageio
real = imageio.write_image
def write_image(*args, **kwargs):
    for delay in {delays}:
        time.sleep(delay)
        os.kill(os.getpid(), signal.{sig})
    time.sleep(0.05)
    real(*args, **kwargs)
imageio.write_image = write_image
"""


@pytest.mark.parametrize(
    "sig, delays, code",
    [
        ("SIGTERM", (0,), 143),
        ("SIGINT", (0,), 130),
        ("SIGINT", (0, 0.001), 130),  # one Ctrl-C delivered twice (a terminal and `timeout`)
        ("SIGINT", (0, 1.2), 130),  # a second Ctrl-C while the image is being written: it waits
    ],
    ids=["sigterm", "ctrl-c", "ctrl-c-twice-at-once", "second-ctrl-c"],
)
def test_a_signal_while_the_image_is_written_keeps_it(tmp_path, sig, delays, code):
    out = tmp_path / "out" / "image.exr"
    out.parent.mkdir()
    done = run_patched(
        tmp_path,
        WRITE_WITH_SIGNALS.format(delays=delays, sig=sig),
        ["render", str(SCENE), "-o", str(out), "--width", "32", "--height", "24", "--spp", "2"],
    )
    assert done.returncode == code, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert read_image(out).metadata["spp"] == 2
    assert sorted(os.listdir(out.parent)) == ["image.exr"]  # no temporary file


def test_sigterm_during_any_write_removes_its_temporary_file(tmp_path):
    """SIGTERM is raised like Ctrl-C (``Terminated``), so an interrupted write cleans up after
    itself and leaves the old file; exit code 143."""
    target = tmp_path / "out" / "results.json"
    target.parent.mkdir()
    target.write_text("old\n")
    patch = f"""
    import wrt.cli, wrt.console, wrt.files
    real = wrt.files._fsync
    def fsync(path):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)
        real(path)
    wrt.files._fsync = fsync
    signal.signal(signal.SIGTERM, wrt.console.terminate)
    try:
        wrt.files.write_json({str(target)!r}, {{"new": 1}})
    except wrt.cli.Terminated:
        sys.exit(143)
    sys.exit(0)
    """
    done = run_patched(tmp_path, patch, [])
    assert done.returncode == 143, done.stderr
    assert target.read_text() == "old\n" and os.listdir(target.parent) == ["results.json"]


@pytest.mark.parametrize(
    ("sig", "handler", "raised"),
    [(signal.SIGTERM, terminate, Terminated), (signal.SIGINT, signal.default_int_handler, KeyboardInterrupt)],
    ids=["sigterm", "ctrl-c"],
)
def test_a_signal_while_a_native_module_loads_is_held_until_it_has_loaded(sig, handler, raised):
    """OpenImageIO's nanobind module aborted a ``wrt render`` (SIGABRT, "Critical nanobind
    error") when SIGTERM's exception reached it while it registered its enums: its import holds
    the signals, and delivers them, to the handlers it found, once the block is done."""
    saved = signal.signal(sig, handler)
    try:
        done = []
        with pytest.raises(raised), held_signals():
            os.kill(os.getpid(), sig)
            time.sleep(0.05)  # where the handler's exception would have been raised
            done.append("the block ran to its end")
        assert done and signal.getsignal(sig) is handler
    finally:
        signal.signal(sig, saved)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
@pytest.mark.parametrize("after", [0.15, 0.4, 0.8])
def test_a_signal_during_start_up_is_one_line(tmp_path, sig, after):
    """While Python, Warp and the kernels load (or, on a warm machine, already rendering or
    shutting down): exit code 130 (143), or killed by the signal before Python installed a
    handler or after it removed its own; at most one line, never a traceback, and an output file
    only when it is complete. One outcome is CPython's, not wrt's: a signal while the interpreter
    still imports its ``site`` module (before any of wrt's code runs, a window a loaded machine
    widens) ends it with "Fatal Python error: init_import_site" and exit code 1."""
    out = tmp_path / "x.png"
    proc = subprocess.Popen(
        [*WRT, "render", str(SCENE), "-o", str(out), "--width", "8", "--height", "6"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(after)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=300)
    if proc.returncode == 1 and stderr.startswith("Fatal Python error: init_import_site"):
        assert not out.exists() and not list(tmp_path.iterdir()), stderr
        return
    assert proc.returncode in (0, 128 + sig, -sig), (proc.returncode, stderr)
    assert "Traceback" not in stderr and len(stderr.splitlines()) <= 1, stderr
    assert proc.returncode != 0 or out.exists()
    if out.exists():
        assert read_image(out).rgb.shape == (6, 8, 3)
    assert [p.name for p in tmp_path.iterdir()] in ([], ["x.png"])  # no temporary file


# --- standard output -----------------------------------------------------------------------------


def test_a_closed_stdout_does_not_fail_the_render(tmp_path):
    """``wrt render ... | head -0``: the image is written, nothing is printed on stderr."""
    out = tmp_path / "x.png"
    proc = subprocess.Popen(
        [*WRT, "render", str(SCENE), "-o", str(out), "--width", "16", "--height", "12"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    proc.stdout.close()  # the reader is gone before the first line
    stderr = proc.stderr.read().decode()
    proc.wait(timeout=300)
    assert proc.returncode == 0 and stderr == "", stderr
    assert read_image(out).rgb.shape == (12, 16, 3)


def test_a_full_stdout_is_one_line_after_the_work(tmp_path):
    """``wrt render ... > /dev/full``: the image is written; one line says what was lost; exit 1."""
    out = tmp_path / "x.png"
    with open("/dev/full", "w") as full:
        done = subprocess.run(
            [*WRT, "render", str(SCENE), "-o", str(out), "--width", "16", "--height", "12"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=300,
        )
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.splitlines() == ["wrt: error: cannot write to standard output (No space left on device)"]
    assert read_image(out).rgb.shape == (12, 16, 3)


# --- options -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["render", str(SCENE), "-o", "x.exr", "--device", ""], "invalid device ''"),
        (["render", str(SCENE), "-o", "x.exr", "--device", "gpu"], "invalid device 'gpu'"),
        (["render", str(SCENE), "-o", "x.exr", "--target-error", "nan"], "--target-error nan"),
        (["render", str(SCENE), "-o", "x.exr", "--target-error", "inf"], "--target-error inf"),
        (["rays", str(SCENE), "--pixel", "1", "1", "-o", "v.png", "--view", "nan", "nan"], "--view nan"),
        (["rays", str(SCENE), "--pixel", "1", "1", "-o", "v.png", "--view", "inf", "1e308"], "--view inf"),
        (["rays", str(SCENE), "--pixel", "1", "1", "-o", "v.png", "--view", "0", "1e308"], "--view 1e308"),
        (["rays", str(SCENE), "--pixel", "1", "1", "-o", "v.png", "--device", ""], "invalid device ''"),
        (["render", str(SCENE), "-o", "x.png", "--half"], "--half needs an .exr output"),
    ],
)
def test_bad_options_are_one_line(tmp_path, monkeypatch, capsys, args, fragment):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(args)
    except SystemExit as e:  # argparse's own errors (an invalid --device) exit from the parser
        code = e.code
    assert code == 2
    assert fragment in one_error_line(capsys)
    assert os.listdir(tmp_path) == []


# --- half floats ---------------------------------------------------------------------------------

BRIGHT_SCENE = """
[render]
width = 8
height = 6
integrator = "raycast"

[camera]
origin = [0, 0, 5]
look_at = [0, 0, 0]

[[material]]
name = "sun"
albedo = [0, 0, 0]
emission = [1e6, 1e6, 1e6]

[[shape]]
type = "sphere"
center = [0, 0, 0]
radius = 3.0
material = "sun"
"""


@pytest.mark.parametrize("aov", [[], ["--aov", "depth"]], ids=["rgb", "with-aovs"])
def test_half_stores_half_floats_and_never_inf(tmp_path, capsys, aov):
    scene = tmp_path / "bright.toml"
    scene.write_text(BRIGHT_SCENE.replace('"raycast"', '"path"'))
    out = tmp_path / "h.exr"
    assert main(["render", str(scene), "-o", str(out), "--half", *aov]) == 0
    err = capsys.readouterr().err
    assert "exceed 65504" in err, err
    inp = oiio.ImageInput.open(str(out))
    spec = inp.spec()
    inp.close()
    formats = [str(f) for f in spec.channelformats] or [str(spec.format)] * spec.nchannels
    names = list(spec.channelnames)
    assert [formats[names.index(c)] for c in "RGB"] == ["half"] * 3
    if aov:
        assert formats[names.index("Z")] == "float"
    rgb = read_image(out).rgb
    assert np.isfinite(rgb).all() and rgb.max() == 65504.0


# --- images too large to read -------------------------------------------------------------------


def zero_png(path: Path, width: int, height: int) -> None:
    """A valid 8-bit grey PNG of ``width x height`` black pixels: a small file (zeros compress
    about 1000:1) whose pixels fill ``width * height`` bytes once decoded."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    compressor, row = zlib.compressobj(9), b"\0" * (width + 1)  # filter byte 0, then the row
    body = b"".join(compressor.compress(row) for _ in range(height)) + compressor.flush()
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", body) + chunk(b"IEND", b""))


def test_compare_refuses_a_huge_image_before_allocating_it(tmp_path, capsys):
    """``wrt compare`` of a 20000 x 20000 PNG (a small compressed file) tried to allocate 8.9 GiB."""
    big = tmp_path / "big.png"
    zero_png(big, 20000, 20000)
    assert big.stat().st_size < 1 << 20
    code = main(["compare", str(big), str(big)])
    assert code == 2
    assert "20000 x 20000 pixels" in one_error_line(capsys)


def test_an_empty_device_name_is_refused_by_the_library_too():
    import wrt
    from wrt.errors import WrtError

    scene = wrt.load_scene(SCENE)
    with pytest.raises(WrtError, match="device ''"):
        wrt.render(scene, device="")


def test_a_corrupt_png_is_one_line_with_nothing_of_libpng(tmp_path):
    """libpng prints its own "libpng error: ..." on file descriptor 2 before OpenImageIO reports
    the error: a second line, outside Python, unless the read keeps it off the console."""
    from wrt.imageio import write_image

    good = tmp_path / "good.png"
    write_image(good, np.random.default_rng(3).random((64, 64, 3)).astype(np.float32))
    data = good.read_bytes()
    bad = tmp_path / "bad.png"
    bad.write_bytes(data[:200] + b"x" * 50 + data[250:])
    done = subprocess.run([*WRT, "compare", str(bad), str(good)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and done.stderr.startswith("wrt: error: "), done.stderr
