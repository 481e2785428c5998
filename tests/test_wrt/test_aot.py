"""Modules compiled ahead of time (``wrt.aot``): the shipped ones match the kernel sources, are
installed into Warp's kernel cache and loaded without compiling; an edited kernel compiles (and
says so) instead of running a stale object; the CPU target is portable where the CPU allows."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import types
import zipfile

import pytest
import warp as wp
from conftest import EXAMPLES
from wrt.kernels.cpu_target import PORTABLE_FLAGS, WARP_FLAGS, X86_64_V3, cpu_compiler_flags

from wrt import aot

PORTABLE_CPU = wp.config.cpu_compiler_flags == PORTABLE_FLAGS


@pytest.mark.skipif(not PORTABLE_CPU, reason="this CPU lacks x86-64-v3: nothing shipped applies to it")
def test_the_shipped_modules_are_those_the_kernel_sources_make():
    """Fails after a kernel edit (or a new example scene) until the shipped modules are rebuilt."""
    manifest = aot.read_manifest()
    rebuild = f"rebuild them with `{aot.SHIP_COMMAND}`"
    assert manifest is not None, f"no shipped modules in {aot.SHIPPED_DIR}: {rebuild}"
    assert aot.usable(manifest), f"the shipped modules were built for another Warp or CPU target: {rebuild}"
    assert manifest["scenes"] == aot.example_scenes(), f"the example scenes changed: {rebuild}"
    assert manifest["variants"] == aot.read_variants(), f"the listed variants changed: {rebuild}"
    modules = aot.needed_modules([aot.example_path(s) for s in manifest["scenes"]]) | aot.listed_variants()
    expected = {name: aot.cache_entry(m, "cpu").identifier for name, m in modules.items()}
    stale = _stale(expected, manifest, "cpu")
    assert not stale, f"the kernels changed since the shipped modules were built ({', '.join(stale)}): {rebuild}"


def _stale(expected: dict[str, str], manifest: dict, kind: str) -> list[str]:
    """The modules whose shipped identifier of ``kind`` is not the one ``expected`` (by name) gives,
    or that only one side has; the archive must hold exactly the manifest's entries."""
    rows = aot.shipped_entries(manifest, kind)
    shipped = {m["name"]: m["identifier"] for m in rows}
    with zipfile.ZipFile(os.path.join(aot.SHIPPED_DIR, aot.ARCHIVES[kind])) as archive:
        assert {f"{m['identifier']}/{m[k]}" for m in rows for k in ("binary", "meta")} == set(archive.namelist())
    return sorted(n for n in expected.keys() | shipped.keys() if expected.get(n) != shipped.get(n))


@pytest.mark.skipif(not PORTABLE_CPU, reason="this CPU lacks x86-64-v3: nothing shipped applies to it")
def test_the_shipped_ptx_is_what_the_kernel_sources_make_for_cuda():
    """The CUDA half of the test above: the PTX shipped for the core modules."""
    manifest = aot.read_manifest()
    rebuild = f"rebuild them with `{aot.SHIP_COMMAND}`"
    assert "cuda" in manifest and manifest["cuda"]["arch"] == aot.CUDA_ARCH, f"no shipped PTX: {rebuild}"
    expected = {name: aot.cuda_cache_entry(m).identifier for name, m in aot.cuda_modules().items()}
    stale = _stale(expected, manifest, "cuda")
    assert not stale, f"the kernels changed since the shipped PTX was built ({', '.join(stale)}): {rebuild}"
    assert all(m["binary"].endswith(f".sm{aot.CUDA_ARCH}.ptx") for m in aot.shipped_entries(manifest, "cuda"))


def test_the_cpu_target_is_portable_where_the_cpu_has_x86_64_v3(tmp_path, monkeypatch):
    monkeypatch.setattr("platform.machine", lambda: "x86_64")
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nflags\t\t: " + " ".join(sorted(X86_64_V3 | {"avx512f"})) + "\n")
    assert cpu_compiler_flags(str(info)) == PORTABLE_FLAGS
    assert "x86-64-v3" in PORTABLE_FLAGS.split() and "-march=native" not in PORTABLE_FLAGS.split()
    info.write_text("flags\t\t: " + " ".join(sorted(X86_64_V3 - {"avx2"})) + "\n")  # an older CPU
    assert cpu_compiler_flags(str(info)) == WARP_FLAGS
    assert cpu_compiler_flags(str(tmp_path / "missing")) == WARP_FLAGS
    monkeypatch.setattr("platform.machine", lambda: "aarch64")
    assert cpu_compiler_flags(str(info)) == WARP_FLAGS
    monkeypatch.setattr("platform.machine", lambda: "x86_64")
    info.write_text("flags\t\t: " + " ".join(sorted(X86_64_V3)) + "\n")
    monkeypatch.setenv("WRT_CPU_TARGET", "native")  # asked for: this CPU's own instruction set
    assert cpu_compiler_flags(str(info)) == WARP_FLAGS


EDITABLE = """\
import warp as wp


@wp.kernel
def fill(out: wp.array(dtype=float)):
    out[wp.tid()] = VALUE
"""


def _import_probe(folder, value: float):
    """The module ``wrt_aot_probe`` from a source file whose kernel writes ``value``: an edit of
    the same module, as a developer makes one."""
    folder.mkdir()
    path = folder / "wrt_aot_probe.py"
    path.write_text(EDITABLE.replace("VALUE", repr(value)))
    spec = importlib.util.spec_from_file_location("wrt_aot_probe", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.fill


def _launch(kernel) -> float:
    out = wp.zeros(1, dtype=float, device="cpu")
    wp.launch(kernel, dim=1, inputs=[out], device="cpu")
    return float(out.numpy()[0])


def test_an_edited_kernel_compiles_and_says_so_instead_of_loading_the_shipped_object(tmp_path, monkeypatch, capsys):
    shipped = str(tmp_path / "shipped")
    kernel = _import_probe(tmp_path / "v1", 1.0)
    manifest = aot.ship_modules({kernel.module.name: kernel.module}, shipped, jobs=1)
    assert [m["name"] for m in manifest["modules"]] == ["wrt_aot_probe"] and aot.usable(manifest)
    capsys.readouterr()

    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path / "cache"))  # a fresh install's
    assert aot.install(shipped) == 1 and aot.cache_entry(kernel.module, "cpu").cached()
    kernel.module.unload()
    aot.load(kernel.module, "cpu")
    assert capsys.readouterr().err == "" and _launch(kernel) == 1.0  # shipped: loaded, not compiled

    edited = _import_probe(tmp_path / "v2", 2.0)
    assert edited.module is kernel.module  # the same Warp module, new source: a new hash
    aot._install.cache_clear()  # as a new process would
    assert aot.install(shipped) == 0 and not aot.cache_entry(edited.module, "cpu").cached()
    aot.load(edited.module, "cpu")
    err = capsys.readouterr().err
    assert "wrt: compiling Warp module wrt_aot_probe for cpu" in err and "wrt: compiled wrt_aot_probe for cpu in" in err
    assert _launch(edited) == 2.0  # the edit runs, not the shipped object


def _gpu(arch: int, output_format: str):
    """A stand-in for a CUDA ``wp.Device`` of compute capability ``arch`` on whose driver Warp would
    build ``output_format`` ("ptx" or "cubin"): what Warp's own choice of architecture reads."""
    from warp._src.context import runtime

    return types.SimpleNamespace(
        is_cuda=True, is_cpu=False, arch=arch, alias="cuda:0", runtime=runtime,
        get_cuda_output_format=lambda preferred=None: output_format,
    )  # fmt: skip


def test_shipped_ptx_lies_where_warp_looks_for_it_on_a_gpu(tmp_path, monkeypatch):
    """A GPU's first use installs the shipped PTX, and Warp's own lookup (the architecture it
    chooses for the device, then its kernel cache) finds it instead of compiling."""
    kernel = _import_probe(tmp_path / "v1", 4.0)
    shipped = str(tmp_path / "shipped")
    modules = {kernel.module.name: kernel.module}
    manifest = aot.ship_modules(modules, shipped, jobs=1, cuda=modules)
    assert [m["binary"] for m in manifest["cuda"]["modules"]] == [aot.cuda_cache_entry(kernel.module).binary]
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path / "cache"))
    monkeypatch.setattr(wp.config, "ptx_target_arch", None)

    assert aot.install_cuda(_gpu(90, "cubin"), shipped) == 0  # Warp would build a CUBIN for sm_90
    assert aot.install_cuda(_gpu(70, "ptx"), shipped) == 0  # older than the shipped PTX
    assert wp.config.ptx_target_arch is None
    gpu = _gpu(90, "ptx")
    assert aot.install_cuda(gpu, shipped) == 1 and wp.config.ptx_target_arch == aot.CUDA_ARCH
    arch = wp.Device.get_cuda_compile_arch(gpu)  # Warp's choice: min(90, ptx_target_arch)
    assert arch == aot.CUDA_ARCH
    assert kernel.module._compile(None, output_arch=arch, use_ptx=True) is False  # found: not compiled

    monkeypatch.setattr(wp.config, "ptx_target_arch", 90)  # the user's own choice is kept
    aot._install.cache_clear()
    assert aot.install_cuda(gpu, shipped) == 0 and wp.config.ptx_target_arch == 90


def test_install_writes_every_shipped_entry_once(tmp_path, monkeypatch):
    manifest = aot.read_manifest()
    if not aot.usable(manifest):
        pytest.skip("no shipped modules for this Warp and CPU")
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    assert aot.install() == len(manifest["modules"])
    with zipfile.ZipFile(os.path.join(aot.SHIPPED_DIR, "cpu.zip")) as archive:
        for name in archive.namelist():
            assert (tmp_path / name).read_bytes() == archive.read(name)
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]  # no temporary files left
    aot._install.cache_clear()
    assert aot.install() == 0  # all there already


def test_a_rebuild_compiles_only_the_modules_that_changed(tmp_path):
    kernel = _import_probe(tmp_path / "v1", 5.0)
    shipped = str(tmp_path / "shipped")
    first = aot.ship_modules({kernel.module.name: kernel.module}, shipped, jobs=1)
    again = aot.ship_modules({kernel.module.name: kernel.module}, shipped, jobs=1)
    assert (first["compiled"], again["compiled"], again["reused"]) == (1, 0, 1)
    assert again["modules"] == first["modules"]  # the same entry, its figures kept
    edited = _import_probe(tmp_path / "v2", 6.0)
    third = aot.ship_modules({edited.module.name: edited.module}, shipped, jobs=1)
    assert (third["compiled"], third["reused"]) == (1, 0)
    assert third["modules"][0]["identifier"] != first["modules"][0]["identifier"]


def test_a_damaged_archive_is_a_warning_and_modules_compile_instead(tmp_path, monkeypatch, capsys):
    kernel = _import_probe(tmp_path / "v1", 3.0)
    shipped = tmp_path / "shipped"
    aot.ship_modules({kernel.module.name: kernel.module}, str(shipped), jobs=1)
    (shipped / "cpu.zip").write_bytes(b"not a zip")
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path / "cache"))
    assert aot.install(str(shipped)) == 0
    assert "wrt: warning: shipped kernels not installed" in capsys.readouterr().err


@pytest.mark.skipif(not PORTABLE_CPU, reason="this CPU lacks x86-64-v3: nothing shipped applies to it")
@pytest.mark.parametrize(
    "scene",
    ["path/cornell_box.toml", "whitted/refraction.toml", "raycast/raycast_mesh.toml", "mitsuba/cornell_box.xml"],
)
def test_a_fresh_kernel_cache_renders_the_examples_without_compiling(tmp_path, scene):
    """What a new user's first render does: every module it loads comes from the package."""
    out = tmp_path / "out.exr"
    env = dict(os.environ, WARP_CACHE_PATH=str(tmp_path / "cache"))
    args = [sys.executable, "-m", "wrt", "render", str(EXAMPLES / scene), "-o", str(out), "--spp", "1"]
    run = subprocess.run([*args, "--width", "32", "--height", "24"], capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr
    assert "compiling" not in run.stderr and out.stat().st_size > 0
    cached = {p.name for p in (tmp_path / "cache").glob("*/wp_*")}
    assert not [name for name in cached if name.endswith(".cpp")]  # nothing was generated, let alone compiled


def test_kernels_lists_the_modules_of_a_scene(tmp_path):
    run = subprocess.run(
        [sys.executable, "-m", "wrt", "kernels", str(EXAMPLES / "path" / "cornell_box.toml")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines[0].split() == ["module", "state", "source", "KB", "object", "KB", "compile", "s"]
    names = {line.split()[0] for line in lines[1:-1]}
    assert {"wrt_path_all", "wrt_path_record", "wrt.kernels.bvh_build"} <= names
    assert lines[-1].startswith(f"{len(names)} modules: ")
    missing = subprocess.run([sys.executable, "-m", "wrt", "kernels", str(tmp_path / "nope.toml")], capture_output=True)
    assert missing.returncode == 2 and b"nope.toml: no such scene file" in missing.stderr


def test_a_module_compiles_for_cuda_where_no_gpu_is(tmp_path):
    """The CUDA path compiled on this (GPU-less) machine: the BVH build's kernels to PTX for
    sm_75 with Warp's NVRTC, every kernel of the module an entry point of the PTX."""
    import wrt.kernels.bvh_build  # noqa: F401  (defines the module)

    module = aot.library_modules()["wrt.kernels.bvh_build"]
    (ptx,) = wp.compile_aot_module(module, arch=75, module_dir=str(tmp_path), use_ptx=True)
    text = ptx.read_text(errors="replace")
    assert ptx.name.endswith(".sm75.ptx") and ".target sm_75" in text
    entries = [line.split()[-1] for line in text.splitlines() if line.startswith(".visible .entry")]
    kernels = [k.get_mangled_name() for k in module.kernels.values()]
    assert sorted(e.split("(")[0] for e in entries) == sorted(f"{k}_cuda_kernel_forward" for k in kernels)
