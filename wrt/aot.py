"""Kernels compiled ahead of time: shipped with wrt, installed into Warp's kernel cache.

Warp keeps a compiled module in its kernel cache under the module's content hash: a folder
``<kernel cache>/<identifier>/`` (``identifier`` = ``wp_<module name>_<hash>``) holding the object
(``.o`` on the CPU, ``.smNN.ptx`` for CUDA) and a ``.meta`` file. wrt ships such entries, built for
the portable CPU target of ``wrt.kernels.cpu_target``, for the modules its examples need (the matrix
renders them), in ``wrt/kernels/compiled/``: ``cpu.zip``, ``cuda.zip`` (PTX for ``CUDA_ARCH`` of the
core modules, ``cuda_modules``) and ``manifest.json``. ``install`` copies the CPU entries missing
from the kernel cache before a process's first launch (``wrt.device`` calls it), ``install_cuda``
the CUDA ones when a CUDA device is first used, and Warp loads them as it would its own. A kernel
whose source has changed hashes differently: nothing shipped matches it and it compiles, as any
module does, so an edit never runs a stale object (``load`` prints what a compilation took).
``ship`` (``wrt kernels --ship``) rebuilds the archives.

Everything here that knows Warp's cache layout (1.19) is in ``cache_entry`` and ``cuda_cache_entry``.
"""

from __future__ import annotations

import contextlib
import functools
import glob
import io
import json
import os
import sys
import tempfile
import time
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import warp as wp

import wrt.kernels
from wrt.kernels.cpu_target import PORTABLE_FLAGS

from .errors import WrtError
from .files import atomic_path, write_json
from .host import machine_line

SHIPPED_DIR = os.path.join(os.path.dirname(wrt.kernels.__file__), "compiled")
"""Where the package keeps the shipped modules: ``cpu.zip`` and ``manifest.json``."""
SHIP_COMMAND = "wrt kernels --ship"
"""The command that rebuilds the shipped modules (after a kernel edit)."""
FORMAT = 2
CUDA_ARCH = 75
"""The architecture of the shipped PTX: Warp's lowest, which a CUDA driver compiles (once, into its
own cache) for any newer GPU. ``install_cuda`` points ``wp.config.ptx_target_arch`` at it."""


@dataclass(frozen=True)
class CacheEntry:
    """Where Warp's kernel cache keeps a module for a device: ``<cache>/<identifier>/<binary>``
    and ``<cache>/<identifier>/<meta>``."""

    name: str
    identifier: str
    binary: str
    meta: str

    def paths(self, cache_dir: str) -> tuple[str, str]:
        folder = os.path.join(cache_dir, self.identifier)
        return os.path.join(folder, self.binary), os.path.join(folder, self.meta)

    def cached(self, cache_dir: str | None = None) -> bool:
        """Whether the entry is in ``cache_dir`` (default: Warp's kernel cache)."""
        return all(os.path.exists(p) for p in self.paths(cache_dir or wp.config.kernel_cache_dir))

    @classmethod
    def of(cls, row: dict) -> CacheEntry:
        """The entry a manifest row names."""
        return cls(*(row[k] for k in ("name", "identifier", "binary", "meta")))


def cache_entry(module: wp.context.Module, device) -> CacheEntry:
    """``module``'s entry in Warp's kernel cache for ``device``, for the block size a launch uses
    (Warp 1.19's layout; computing it hashes the module's source)."""
    dev = wp.get_device(device)
    block_dim = _block_dim(dev, module)
    return CacheEntry(
        module.name,
        module.get_module_identifier(block_dim),
        module._get_compile_output_name(dev, block_dim=block_dim),
        module._get_meta_name(block_dim=block_dim),
    )


def cuda_cache_entry(module: wp.context.Module, arch: int = CUDA_ARCH) -> CacheEntry:
    """``module``'s entry in Warp's kernel cache as PTX for ``arch``, for the block size of its
    CUDA launches: where Warp looks for it on a GPU whose PTX target is ``arch`` (no GPU needed)."""
    block_dim = module.options["block_dim"] or 256  # Warp's CUDA default (_resolve_launch_block_dim)
    return CacheEntry(
        module.name,
        module.get_module_identifier(block_dim),
        module._get_compile_output_name(None, output_arch=arch, use_ptx=True, block_dim=block_dim),
        module._get_meta_name(block_dim=block_dim),
    )


def compiled(kernel, device) -> bool:
    """Whether ``kernel``'s module is in Warp's kernel cache for ``device``: using it then costs a
    load (milliseconds), not a compilation (seconds to tens of seconds for an integrator's)."""
    return cache_entry(kernel.module, device).cached()


def load(module: wp.context.Module, device) -> float:
    """Load ``module`` on ``device``; the seconds it took. A compilation (the module is neither
    cached nor shipped: a kernel was edited, or this is a variant no example uses) is announced on
    stderr, and how long it took, so that a wait is never silent."""
    dev = wp.get_device(device)
    t0 = time.perf_counter()
    compiling = not cache_entry(module, dev).cached()
    if compiling:
        print(f"wrt: compiling Warp module {module.name} for {dev.alias} (not in the kernel cache)...", file=sys.stderr)
    wp.load_module(module, device=dev)
    seconds = time.perf_counter() - t0
    if compiling:
        print(f"wrt: compiled {module.name} for {dev.alias} in {seconds:.1f} s (cached from now on)", file=sys.stderr)
    return seconds


def _block_dim(dev, module) -> int:
    """The block size of a launch of ``module``'s kernels on ``dev`` (1 on the CPU)."""
    from warp._src.context import _resolve_launch_block_dim

    return _resolve_launch_block_dim(dev, None if dev.is_cpu else module.options["block_dim"])


def read_manifest(folder: str = SHIPPED_DIR) -> dict | None:
    """The shipped modules' manifest (``manifest.json``), None where there is none."""
    try:
        with open(os.path.join(folder, "manifest.json")) as f:
            return json.load(f)
    except FileNotFoundError:
        return None


def usable(manifest: dict | None) -> bool:
    """Whether ``manifest``'s objects load in this process: the same Warp and the same CPU target
    (``wp.get_cpu_kernel_cache_key``: the toolchain, the system and the flags; a CPU without
    x86-64-v3 compiles with ``-march=native`` and has another key)."""
    return (
        manifest is not None
        and manifest.get("format") == FORMAT
        and manifest.get("warp") == wp.config.version
        and manifest.get("cpu_target") == wp.get_cpu_kernel_cache_key()
    )


def install(folder: str = SHIPPED_DIR) -> int:
    """Copy the shipped CPU modules that Warp's kernel cache lacks into it; how many were copied.

    Each file is written to a temporary name and renamed, the object before its ``.meta``
    (Warp takes an entry as cached when both exist), so that processes installing at once, or one
    killed midway, never leave an entry Warp would misread. Once per process and cache folder."""
    return _install(os.path.abspath(folder), wp.config.kernel_cache_dir, "cpu")


def install_cuda(device, folder: str = SHIPPED_DIR) -> int:
    """Before the first launch on the CUDA ``device`` (a ``wp.Device``): copy the shipped PTX that
    Warp's kernel cache lacks into it, as ``install`` does; how many were copied.

    Warp looks for PTX of ``min(device arch, wp.config.ptx_target_arch)``; where that option is
    unset it is set to the shipped ``CUDA_ARCH``, so that the same files serve every GPU from
    sm_75 on. Nothing is installed where Warp would not load PTX (a driver older than Warp's NVRTC:
    Warp then builds CUBINs for the device's own architecture), for an older GPU, or where the
    user chose another PTX target: the modules then compile on first use, as before."""
    manifest = read_manifest(folder)
    if not (device.is_cuda and usable(manifest) and "cuda" in manifest):
        return 0
    arch = manifest["cuda"]["arch"]
    if device.get_cuda_output_format() != "ptx" or device.arch < arch:
        return 0
    if wp.config.ptx_target_arch is None:
        wp.config.ptx_target_arch = arch
    if wp.config.ptx_target_arch != arch:
        return 0
    return _install(os.path.abspath(folder), wp.config.kernel_cache_dir, "cuda")


ARCHIVES = {"cpu": "cpu.zip", "cuda": "cuda.zip"}


def shipped_entries(manifest: dict, kind: str = "cpu") -> list[dict]:
    """The manifest's rows of the ``kind`` ("cpu" or "cuda") of modules shipped."""
    return manifest["modules"] if kind == "cpu" else manifest.get("cuda", {}).get("modules", [])


@functools.cache
def _install(folder: str, cache_dir: str, kind: str) -> int:
    manifest = read_manifest(folder)
    if not usable(manifest):
        return 0
    missing = [e for e in map(CacheEntry.of, shipped_entries(manifest, kind)) if not e.cached(cache_dir)]
    if not missing:
        return 0
    try:
        _unpack(os.path.join(folder, ARCHIVES[kind]), missing, cache_dir)
    except (OSError, zipfile.BadZipFile, KeyError) as e:  # a damaged package, a full disk: compile
        print(f"wrt: warning: shipped kernels not installed ({e}); modules compile on first use", file=sys.stderr)
        return 0
    return len(missing)


def _unpack(archive_path: str, entries: list[CacheEntry], cache_dir: str) -> None:
    """Write ``entries`` from the zip file ``archive_path`` into the kernel cache ``cache_dir``,
    each file atomically, the object before its ``.meta``."""
    with zipfile.ZipFile(archive_path) as archive:
        for entry in entries:
            os.makedirs(os.path.join(cache_dir, entry.identifier), exist_ok=True)
            for name, path in zip((entry.binary, entry.meta), entry.paths(cache_dir)):
                _write_cache_file(path, archive.read(f"{entry.identifier}/{name}"))


def _write_cache_file(path: str, data: bytes) -> None:
    """Write a file of Warp's kernel cache as Warp does: to a temporary name, then renamed (not
    synced to disk: a cache, which Warp rebuilds where an entry is missing)."""
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".wrt-", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def example_scenes() -> list[str]:
    """Every scene file of ``wrt.examples`` (TOML and Mitsuba XML; the ``fragments`` that Mitsuba
    scenes include are parts, not scenes; ``own_matrix`` is a user's project to copy, not installed),
    relative to its folder, sorted."""
    import wrt.examples

    root = os.path.dirname(wrt.examples.__file__)
    files = glob.glob("**/*.toml", root_dir=root, recursive=True) + glob.glob("**/*.xml", root_dir=root, recursive=True)
    return sorted(f for f in files if not {"fragments", "own_matrix"} & set(f.split(os.sep)))


def example_path(name: str) -> str:
    import wrt.examples

    return os.path.join(os.path.dirname(wrt.examples.__file__), name)


def scene_modules(path: str, cuda: bool = False) -> dict[str, wp.context.Module]:
    """The Warp modules a render or a ray recording of the scene file ``path`` can load, by name:
    its integrator's all-features and recording kernels and its variant (``render_kernel_for``),
    on the CPU or, where ``cuda``, on a CUDA device. A Mitsuba scene counts as imported strictly
    and with ``--approximate``; a scene that neither loads adds nothing."""
    from wrt.kernels.features import ALL
    from wrt.kernels.variants import RECORDING, all_features_kernel, render_kernel

    from .loader import load_scene
    from .renderer import scene_features

    modules = {}
    for approximate in (False, True) if path.lower().endswith(".xml") else (False,):
        try:
            with contextlib.redirect_stderr(io.StringIO()):  # an approximate import's warnings
                scene = load_scene(path, approximate=approximate)
        except WrtError:
            continue
        integrator = scene.render.integrator
        kernels = [render_kernel(integrator, ALL, cuda), render_kernel(integrator, scene_features(scene), cuda)]
        if integrator in RECORDING:
            kernels.append(all_features_kernel(integrator, record=True, cuda=cuda))
        for kernel in kernels:
            modules[kernel.module.name] = kernel.module
    return modules


def library_modules() -> dict[str, wp.context.Module]:
    """The Warp modules of ``wrt.kernels`` that hold kernels of their own (the BVH build, the
    batch traversal kernels, the stress suite's), by name."""
    import importlib
    import pkgutil

    from warp._src.context import user_modules

    for info in pkgutil.iter_modules(wrt.kernels.__path__):
        importlib.import_module(f"wrt.kernels.{info.name}")
    return {n: m for n, m in user_modules.items() if n.startswith("wrt.kernels.") and m.kernels}


def needed_modules(scenes: list[str], cuda: bool = False) -> dict[str, wp.context.Module]:
    """The Warp modules that ``scenes`` (scene files) need, with the library's own, by name (on a
    CUDA device where ``cuda``)."""
    modules = library_modules()
    for path in scenes:
        modules.update(scene_modules(path, cuda))
    return dict(sorted(modules.items()))


VARIANTS_FILE = os.path.join(SHIPPED_DIR, "variants.json")
"""Kernel variants shipped besides the examples' (``listed_variants``)."""


def read_variants(path: str = VARIANTS_FILE) -> list[dict]:
    """The variants listed in ``path``: ``{"kernel": ..., "flags": [...]}`` each."""
    with open(path) as f:
        return json.load(f)["variants"]


def listed_variants(variants: list[dict] | None = None) -> dict[str, wp.context.Module]:
    """The modules of ``variants`` (default: those ``VARIANTS_FILE`` lists), by name: scene kinds
    no example has that the test suite renders specialised (a lit quad, a textured plane, ...). Each is a kernel (an
    integrator, or ``trace``: the batch traversal of ``Tracer(specialize=True)``) and the
    ``Features`` flags it keeps; every other flag is off, so one added later stays off."""
    from wrt.kernels.features import Features
    from wrt.kernels.traverse import trace_kernels
    from wrt.kernels.variants import render_kernel

    modules = {}
    for variant in read_variants() if variants is None else variants:
        features = Features(**{name: name in variant["flags"] for name in Features.__dataclass_fields__})
        kind = variant["kernel"]
        kernel = trace_kernels(features)[0] if kind == "trace" else render_kernel(kind, features)
        modules[kernel.module.name] = kernel.module
    return modules


def cuda_modules() -> dict[str, wp.context.Module]:
    """The modules shipped as PTX, by name: the library's own (``library_modules``) and each
    integrator's all-features and recording kernels in their CUDA forms. A render below
    ``wrt.renderer.SPECIALIZE_COLD_SAMPLES`` pixel samples takes its integrator's all-features
    kernel where its variant is not cached, so these serve the examples and the matrix on a GPU."""
    from wrt.kernels.variants import INTEGRATORS, RECORDING, all_features_kernel

    modules = library_modules()
    for integrator in INTEGRATORS:
        for record in (False, True) if integrator in RECORDING else (False,):
            module = all_features_kernel(integrator, record=record, cuda=True).module
            modules[module.name] = module
    return dict(sorted(modules.items()))


def compile_modules(modules: dict[str, wp.context.Module], jobs: int | None = None, progress=None) -> dict:
    """Compile (or load from the cache) ``modules`` on the CPU, ``jobs`` at a time (default:
    every core; a Warp compilation runs on one core and releases the GIL); the seconds each took,
    by name. ``progress(name, seconds)`` is called as each is done."""
    seconds = _compile_all([(name, module, None) for name, module in modules.items()], jobs, progress)
    return {name: seconds[name, None] for name in modules}


def _compile_all(tasks: list[tuple], jobs: int | None, progress) -> dict:
    """Compile ``(name, module, cuda_arch)`` tasks, ``jobs`` at a time: on the CPU for a
    ``cuda_arch`` of None, else to PTX for that architecture (no GPU needed), the CUDA ones (the
    longest) first; the seconds each took, by ``(name, cuda_arch)``."""
    dev = wp.get_device("cpu")

    def build(task):
        name, module, arch = task
        t0 = time.perf_counter()
        if arch is None:
            module.load(dev, block_dim=_block_dim(dev, module))
        else:
            module._compile(None, output_arch=arch, use_ptx=True)
        seconds = time.perf_counter() - t0
        if progress is not None:
            progress(name if arch is None else f"{name} (sm_{arch})", seconds)
        return (name, arch), seconds

    with ThreadPoolExecutor(max_workers=jobs or os.cpu_count() or 1) as pool:
        return dict(pool.map(build, sorted(tasks, key=lambda t: t[2] is None)))


def ship(scenes: list[str], folder: str = SHIPPED_DIR, jobs: int | None = None, progress=None) -> dict:
    """Compile ``needed_modules(scenes)`` and ``listed_variants()`` for the CPU at the portable
    target, and ``cuda_modules()`` to PTX for ``CUDA_ARCH``, in a kernel cache of their own, and
    write their entries to ``folder`` as ``cpu.zip``, ``cuda.zip`` and ``manifest.json`` (each
    atomically); the manifest. ``scenes`` are recorded relative to ``wrt.examples`` where they lie
    in it. Refused on a CPU without x86-64-v3 (the CUDA modules' hashes include the CPU flags too)."""
    if wp.config.cpu_compiler_flags != PORTABLE_FLAGS:
        raise WrtError(
            f"{SHIP_COMMAND}: this CPU lacks x86-64-v3 (AVX2, FMA), so its objects would not be portable; "
            "build on an x86-64-v3 machine"
        )
    variants = read_variants()
    modules = needed_modules(scenes) | listed_variants(variants)
    scenes_shipped = [_relative(s) for s in scenes]
    return ship_modules(
        dict(sorted(modules.items())),
        folder,
        jobs,
        progress,
        scenes=scenes_shipped,
        cuda=cuda_modules(),
        variants=variants,
    )


def ship_modules(
    modules: dict[str, wp.context.Module],
    folder: str,
    jobs: int | None = None,
    progress=None,
    scenes=(),
    cuda: dict[str, wp.context.Module] | None = None,
    variants=(),
) -> dict:
    """``ship``'s work for any ``modules`` (and ``cuda`` modules, PTX for ``CUDA_ARCH``), at this
    process's CPU flags (the manifest records its ``cpu_target``, and ``install`` uses it only
    where that matches). An entry already in ``folder``'s archives under the same identifier (the
    hash of the same source and options, for the same Warp and CPU target) is kept, not compiled
    again: after an edit, only the modules it changed compile."""
    cuda = cuda or {}
    saved = wp.config.kernel_cache_dir
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="wrt-ship-") as build_cache:
        cpu_entries = {n: cache_entry(m, "cpu") for n, m in modules.items()}
        cuda_entries = {n: cuda_cache_entry(m) for n, m in cuda.items()}
        kept = _reuse(folder, build_cache)
        tasks = [(n, modules[n], None) for n, e in cpu_entries.items() if ("cpu", e.identifier) not in kept]
        tasks += [(n, cuda[n], CUDA_ARCH) for n, e in cuda_entries.items() if ("cuda", e.identifier) not in kept]
        wp.config.kernel_cache_dir = build_cache
        try:
            seconds = _compile_all(tasks, jobs, progress)
        finally:
            wp.config.kernel_cache_dir = saved
        os.makedirs(folder, exist_ok=True)
        rows = _archive(os.path.join(folder, ARCHIVES["cpu"]), cpu_entries, build_cache)
        for row in rows:
            built = kept.get(("cpu", row["identifier"])) or {  # kept: its figures from when it compiled
                "source_bytes": os.path.getsize(_source(cpu_entries[row["name"]], build_cache)),
                "compile_s": round(seconds[row["name"], None], 2),
            }
            row.update(
                source_bytes=built["source_bytes"], object_bytes=row.pop("binary_bytes"), compile_s=built["compile_s"]
            )
        cuda_rows = []
        if cuda:
            cuda_rows = _archive(os.path.join(folder, ARCHIVES["cuda"]), cuda_entries, build_cache)
            for row in cuda_rows:
                old = kept.get(("cuda", row["identifier"]))
                compile_s = old["compile_s"] if old else round(seconds[row["name"], CUDA_ARCH], 2)
                row.update(ptx_bytes=row.pop("binary_bytes"), compile_s=compile_s)
    manifest = {
        "format": FORMAT,
        "warp": wp.config.version,
        "cpu_target": wp.get_cpu_kernel_cache_key(),
        "cpu_compiler_flags": wp.config.cpu_compiler_flags,
        "built": time.strftime("%Y-%m-%d"),
        "machine": machine_line(),
        "jobs": jobs or os.cpu_count() or 1,
        "wall_s": round(time.perf_counter() - started, 1),
        "scenes": list(scenes),
        "variants": list(variants),
        "compiled": len(tasks),
        "reused": len(cpu_entries) + len(cuda_entries) - len(tasks),
        "modules": rows,
    }
    if cuda:
        manifest["cuda"] = {"arch": CUDA_ARCH, "format": "ptx", "modules": cuda_rows}
    write_json(os.path.join(folder, "manifest.json"), manifest)
    return manifest


def _reuse(folder: str, cache_dir: str) -> dict:
    """Unpack the entries of ``folder``'s archives into ``cache_dir`` where its manifest is usable
    here; their manifest rows, by ``(kind, identifier)``."""
    manifest = read_manifest(folder)
    if not usable(manifest):
        return {}
    kept = {}
    try:
        for kind, archive_name in ARCHIVES.items():
            if rows := shipped_entries(manifest, kind):
                _unpack(os.path.join(folder, archive_name), [CacheEntry.of(row) for row in rows], cache_dir)
                kept.update({(kind, row["identifier"]): row for row in rows})
    except (OSError, zipfile.BadZipFile, KeyError):  # a damaged archive: compile everything
        return {}
    return kept


def _archive(path: str, entries: dict[str, CacheEntry], cache_dir: str) -> list[dict]:
    """Write ``entries`` (by module name) from ``cache_dir`` to the zip file ``path``, atomically;
    one manifest row per entry (``binary_bytes``: the object's or the PTX's size)."""
    rows = []
    with atomic_path(path) as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, entry in entries.items():
            binary, meta = entry.paths(cache_dir)
            zf.write(binary, f"{entry.identifier}/{entry.binary}")
            zf.write(meta, f"{entry.identifier}/{entry.meta}")
            rows.append(
                {
                    "name": name,
                    "identifier": entry.identifier,
                    "binary": entry.binary,
                    "meta": entry.meta,
                    "binary_bytes": os.path.getsize(binary),
                }
            )
    return rows


def _source(entry: CacheEntry, cache_dir: str) -> str:
    """The generated C++ source Warp keeps beside a CPU module's object."""
    return os.path.join(cache_dir, entry.identifier, entry.identifier + ".cpp")


def table(modules: dict[str, wp.context.Module], folder: str = SHIPPED_DIR) -> list[dict]:
    """One row per module of ``modules``: ``name``, ``state`` ("shipped": in the package's
    archive, for this CPU; "cached": in Warp's kernel cache; "to compile": neither), and where known
    (the manifest for shipped modules, the cache's files for cached ones) ``source_bytes``,
    ``object_bytes`` and ``compile_s`` (seconds, at build)."""
    manifest = read_manifest(folder)
    shipped = {m["identifier"]: m for m in manifest["modules"]} if usable(manifest) else {}
    rows = []
    for name, module in modules.items():
        entry = cache_entry(module, "cpu")
        row = {"name": name, "identifier": entry.identifier}
        if entry.identifier in shipped:
            row.update(
                state="shipped",
                **{k: shipped[entry.identifier][k] for k in ("source_bytes", "object_bytes", "compile_s")},
            )
        elif entry.cached():
            binary, _ = entry.paths(wp.config.kernel_cache_dir)
            source = _source(entry, wp.config.kernel_cache_dir)
            row.update(state="cached", object_bytes=os.path.getsize(binary))
            if os.path.exists(source):
                row["source_bytes"] = os.path.getsize(source)
        else:
            row["state"] = "to compile"
        rows.append(row)
    return rows


def _relative(path: str) -> str:
    import wrt.examples

    root = os.path.dirname(wrt.examples.__file__)
    rel = os.path.relpath(os.path.abspath(path), root)
    return path if rel.startswith("..") else rel
