"""Shared test helpers: build scenes inline from dicts and trace rays through the real kernels."""

from __future__ import annotations

import contextlib
import errno
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import warp as wp
import wrt.kernels  # noqa: F401  (configures Warp)
import wrt_harness.references as references

from wrt.device import init_warp
from wrt.loader import parse_scene
from wrt.trace import Tracer as PrimitiveTracer

wp.config.enable_backward = False  # the tests' own kernels need no gradients: they compile faster without

init_warp()

ROOT = Path(__file__).resolve().parent.parent  # the source checkout
EXAMPLES = ROOT / "examples"
CAMERA = {"origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0]}
GOOD_SCENE = """\
[render]
width = 24
height = 16

[camera]
origin = [0, 0, 5]
look_at = [0, 0, 0]

[[material]]
name = "red"
albedo = [0.8, 0.1, 0.1]

[[shape]]
type = "sphere"
center = [0, 0, 0]
radius = 1.0
material = "red"
"""  # a small valid scene file that the bad-input tests break one key at a time


def fresnel_dielectric64(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric interface (Hecht 4.6) in float64, the
    reference of the kernels' Fresnel: ``cos_i`` the incident cosine, ``eta = n1 / n2``; 1 beyond
    the critical angle."""
    cos_i = np.asarray(cos_i, dtype=np.float64)
    sin2_t = eta**2 * (1.0 - cos_i**2)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    r_par = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_perp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin2_t >= 1.0, 1.0, 0.5 * (r_par**2 + r_perp**2))


def make_scene(shapes, render=None, camera=None, materials=None, lights=None, scene_dir=".", groups=None):
    """A validated ``Scene`` from inline tables, with a default camera and render settings."""
    doc = {"camera": camera or CAMERA, "shape": shapes, "light": lights or [], "group": groups or []}
    if render:
        doc["render"] = render
    if materials:
        doc["material"] = materials
    return parse_scene(doc, file="<test>", scene_dir=scene_dir)


# Every Warp device the tests can run on, as Warp's own suite does: CUDA is skipped where absent.
DEVICES = [
    pytest.param("cpu", id="cpu"),
    pytest.param("cuda:0", id="cuda", marks=pytest.mark.skipif(not wp.is_cuda_available(), reason="no CUDA device")),
]


ONE_WORKER = re.compile(r"@wp\.kernel|specialize=(True|specialize)|scope=\"module\"")
"""What a test file has when its tests should share one xdist worker: they compile a Warp module
that nothing ships (kernels of their own, or kernel variants, ``specialize``, of their inline
scenes), or share a module-scoped fixture, which each worker would build again (the benchmark's
quick run: 16 s and 14 s, twice)."""


TEST_KERNEL_FLAGS = " ".join(
    flag
    for flag in (wp.config.cpu_compiler_flags or "").split()
    if not flag.startswith(("-mllvm=-inline-threshold=", "-mllvm=-inline-cold-callsite-threshold="))
)
"""The CPU compiler flags of the tests' own kernels: wrt's (``wrt.kernels.cpu_target``) but for
Warp's inlining thresholds, LLVM's own instead. The tests' kernels call the BSDFs and lights a few
hundred thousand times, where the renderer's trace billions of paths: they compile in 40% less
time (test_mask_bsdf and test_plastic, cold: 15.9 s against 25.6 s) and run slower, which they
can afford. wrt's own modules keep their flags, and their shipped objects apply."""


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's, which reads the groups
def pytest_collection_modifyitems(config, items):
    """Under ``--dist loadgroup``, the tests of a file that compiles a module of its own, or shares a
    module-scoped fixture, run in one worker (``ONE_WORKER``): spread over two, each compiled the
    same module at the same time (a cold suite spent 13-17 s twice on each of test_shading_normals'
    variants), where one worker compiles it once and the file's other tests load it. Tests already
    in a group keep theirs. Each test file's own
    kernels (its Warp module) compile with ``TEST_KERNEL_FLAGS``."""
    for name in {item.module.__name__ for item in items if getattr(item, "module", None) is not None}:
        wp.get_module(name).options["cpu_compiler_flags"] = TEST_KERNEL_FLAGS
    sources = {}
    for item in items:
        if item.get_closest_marker("xdist_group") is not None:
            continue
        path = item.path
        if path not in sources:
            sources[path] = bool(ONE_WORKER.search(path.read_text()))
        if sources[path]:
            item.add_marker(pytest.mark.xdist_group(path.stem))


@pytest.fixture(params=DEVICES)
def device(request):
    """Each available Warp device in turn, made the default (``wp.ScopedDevice``) for the test."""
    with wp.ScopedDevice(request.param):
        yield request.param


class Tracer(PrimitiveTracer):
    """``wrt.trace.Tracer`` (closest-hit and any-hit ray batches through the real kernels) on the
    current default Warp device, with closest hits reported by shape: ``(t, shape id)``,
    ``t = t_max`` and -1 on a miss."""

    def __init__(self, scene, **kwargs):
        super().__init__(scene, **{"device": wp.get_device(), **kwargs})

    def closest(self, origins, directions, t_min=0.0, t_max=np.inf, brute_force=False):
        t, prim, inst = super().closest_instanced(origins, directions, t_min, t_max, brute_force)
        return t, self.prims.shape_of(prim, inst)


@pytest.fixture
def rng():
    return np.random.default_rng(20261125)


def copy_references(tmp_path, monkeypatch, names):
    """Copy the named features' reference files to ``tmp_path/refs`` and point the harness there."""
    folder = tmp_path / "refs"
    folder.mkdir()
    for name in names:
        for path in references.paths(name).values():
            shutil.copy(path, folder)
    monkeypatch.setattr(references, "REFERENCE_DIR", str(folder))
    return folder


def one_feature_file(tmp_path, extra: str):
    """A features file of one small raycast feature, with the TOML lines ``extra`` added to it."""
    path = tmp_path / "features.toml"
    path.write_text(
        '[[feature]]\nname = "x"\nscene = "wrt.examples:raycast/raycast_sphere.toml"\nintegrator = "raycast"\n'
        f"width = 16\nheight = 16\n{extra}\n"
    )
    return path


def corner_form_factor(a, b, h):
    """Form factor from a differential floor area to a parallel a x b rectangle at height h above
    one of its corners (Howell's catalogue of configuration factors)."""
    x, y = a / h, b / h
    return (
        x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
        + y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))
    ) / (2 * np.pi)


LAMP_ALBEDO, LAMP_RADIANCE = 0.6, 4.0  # the floor's albedo and the lamps' emitted radiance
LAMP_MATERIALS = [
    {"name": "floor", "albedo": [LAMP_ALBEDO] * 3},
    {"name": "lamp", "albedo": [0, 0, 0], "emission": [LAMP_RADIANCE] * 3},
]


def render_lamp_scene(shapes, camera, size, spp, groups=None, device="cpu", **settings):
    """A path-traced render (max_depth 2: direct light) of ``shapes`` made of ``LAMP_MATERIALS``, on ``device``."""
    settings = {"width": size[0], "height": size[1], "integrator": "path", "spp": spp, "max_depth": 2, **settings}
    scene = make_scene(shapes, materials=LAMP_MATERIALS, camera=camera, render=settings, groups=groups)
    return wrt.render(scene, device=device)


# --- file systems that refuse writes: a small full tmpfs, a read-only one ----------------------
# We run as root, so permission bits do not stop a write; a real file system does. Mounting needs
# root (CAP_SYS_ADMIN): where it is refused, the tests that need one are skipped with the reason.


def _mount_tmpfs(folder: Path, options: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({done.stderr.strip() or 'mount failed'})")


def _unmount(folder: Path) -> None:
    subprocess.run(["umount", "-l", str(folder)], capture_output=True, check=False)


class FullDisk:
    """A small tmpfs (``path``) that ``fill()`` fills to the last byte: every write to it fails
    with ENOSPC until ``free()`` removes the filler."""

    def __init__(self, path: Path):
        self.path = path
        self.filler = path / ".filler"

    def fill(self) -> None:
        with open(self.filler, "ab", buffering=0) as f:
            chunk = b"\0" * 4096
            with contextlib.suppress(OSError):
                while True:
                    f.write(chunk)
            with contextlib.suppress(OSError):
                while True:
                    f.write(b"\0")
        probe = self.path / ".probe"
        try:
            probe.write_bytes(b"x")
        except OSError as e:
            assert e.errno == errno.ENOSPC, e
        else:
            raise AssertionError("the tmpfs took a byte after it was filled")
        finally:
            with contextlib.suppress(OSError):
                probe.unlink()

    def free(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.filler.unlink()


@pytest.fixture
def full_disk(tmp_path):
    """A 1 MiB tmpfs to fill (``FullDisk``): put good files there, ``fill()``, then write."""
    disk = FullDisk(tmp_path / "tmpfs")
    _mount_tmpfs(disk.path, "size=1m,mode=0777")
    try:
        yield disk
    finally:
        _unmount(disk.path)


@pytest.fixture
def read_only_folder(tmp_path):
    """``make(files)``: a read-only tmpfs holding ``files`` (name -> bytes); returns its path."""
    mounted = []

    def make(files: dict | None = None, name: str = "ro") -> Path:
        folder = tmp_path / name
        _mount_tmpfs(folder, "size=16m,mode=0777")
        mounted.append(folder)
        for rel, data in (files or {}).items():
            (folder / rel).parent.mkdir(parents=True, exist_ok=True)
            (folder / rel).write_bytes(data)
        done = subprocess.run(["mount", "-o", "remount,ro", str(folder)], capture_output=True, text=True, check=False)
        if done.returncode != 0:
            pytest.skip(f"cannot remount a tmpfs read-only here ({done.stderr.strip()})")
        return folder

    try:
        yield make
    finally:
        for folder in mounted:
            _unmount(folder)


@pytest.fixture(scope="module")
def own_project(tmp_path_factory):
    """A copy of the example project ``examples/own_matrix`` with the references of its ``balls``
    feature (raycast, 48 x 36, deterministic) made by ``wrt refs regenerate``."""
    from wrt.cli import main

    folder = tmp_path_factory.mktemp("own") / "own"
    shutil.copytree(EXAMPLES / "own_matrix", folder, ignore=shutil.ignore_patterns("refs", "report"))
    options = ["--features", str(folder / "features.toml"), "--refs", str(folder / "refs")]
    assert main(["refs", "regenerate", "balls", *options]) == 0
    return folder
