"""Whole processes, as a user runs them, against Mitsuba 3: a million-triangle mesh and a
path-traced Cornell box. Part of ``wrt bench``.

Each comparison runs both renderers' command lines as child processes, in turn (wrt, Mitsuba,
wrt, ...), after one untimed warm-up run of each (Warp's kernel cache, Python's bytecode cache and
the file cache warm, as on a machine that has rendered before: the children run without
``PYTHONDONTWRITEBYTECODE``, which would make every process compile wrt's sources again; Mitsuba
compiles its LLVM kernels in every process), and reports the median wall time of ``repeats``
runs: process start, imports, scene parsing, mesh reading, BVH build, rendering and writing the
EXR, everything.

- ``mesh``: a binary PLY of ``triangles`` triangles (``wrt_benchmarks.throughput.torus_mesh``, float32
  vertices) seen by a 1024 x 1024 pinhole camera, one primary ray per pixel: ``wrt render`` with
  the raycast integrator, against ``mitsuba -m VARIANT`` with the ``depth`` integrator at one
  sample per pixel (one camera ray per pixel; its distance is the image).
- ``path``: ``examples/mitsuba/cornell_box.xml`` (128 x 128, ``max_depth`` 8) at ``spp`` samples
  with the file's independent sampler: ``wrt render scene.xml --spp N --seed k`` against
  ``mitsuba -Dspp=N -Dseed=k`` (a copy of the file whose sampler takes a ``$seed``), run ``k``
  using seed ``k``. Each image's mean squared error (linear RGB) against the scene's converged
  reference (``wrt_benchmarks.bench.reference_image``) gives the Monte Carlo efficiency
  ``1 / (MSE x wall seconds)``, the MSE averaged over the runs' seeds; the ratio wrt / Mitsuba is
  above 1 when wrt reaches a given error sooner. wrt's other samplers are timed the same way
  (``wrt render --sampler``) and reported beside it.

Mitsuba's variant is ``llvm_ad_rgb`` (vectorised, all cores) where it runs, with Debian's libLLVM
19 (``harness.mitsuba_peer``), else ``scalar_rgb``; the result names the one used.
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import resources

import numpy as np
from wrt_harness import mitsuba_peer

from wrt.imageio import read_image

from .throughput import torus_mesh

CORNELL_XML = str(resources.files("wrt.examples") / "mitsuba" / "cornell_box.xml")
MESH_SIZE = 1024  # pixels, each way
MESH_CAMERA = {"origin": (0.5, -4.0, 2.5), "look_at": (0.0, 0.0, 0.0), "up": (0.0, 0.0, 1.0), "fov": 40.0}


def write_ply(path: str, vertices: np.ndarray, faces: np.ndarray) -> None:
    """A binary little-endian PLY of float32 vertices and triangle faces."""
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float "
        "y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rows["n"], rows["i"] = 3, faces
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(np.ascontiguousarray(vertices, dtype="<f4").tobytes())
        f.write(rows.tobytes())


def mesh_scenes(folder: str, triangles: int) -> tuple[str, str]:
    """The mesh comparison's PLY and its two scene files (wrt TOML, Mitsuba XML) in ``folder``."""
    vertices, faces = torus_mesh(triangles)
    write_ply(os.path.join(folder, "mesh.ply"), vertices, faces)
    c = MESH_CAMERA
    toml = os.path.join(folder, "mesh.toml")
    with open(toml, "w") as f:
        f.write(
            f'[render]\nwidth = {MESH_SIZE}\nheight = {MESH_SIZE}\nspp = 1\nintegrator = "raycast"\n\n'
            f"[camera]\norigin = {list(c['origin'])}\nlook_at = {list(c['look_at'])}\nup = {list(c['up'])}\nfov = "
            f"{c['fov']}\n\n"
            '[[material]]\nname = "grey"\nalbedo = [0.8, 0.8, 0.8]\n\n[[shape]]\ntype = "mesh"\nfile = '
            '"mesh.ply"\nmaterial = "grey"\n'
        )
    xml = os.path.join(folder, "mesh.xml")
    o, t, u = (", ".join(str(x) for x in c[k]) for k in ("origin", "look_at", "up"))
    with open(xml, "w") as f:
        f.write(
            f'<scene version="3.0.0">\n  <integrator type="depth"/>\n'
            f'  <sensor type="perspective">\n    <float name="fov" value="{c["fov"]}"/>\n    <string name="fov_axis" '
            'value="y"/>\n'
            f'    <transform name="to_world"><lookat origin="{o}" target="{t}" up="{u}"/></transform>\n'
            f'    <sampler type="independent"><integer name="sample_count" value="1"/></sampler>\n'
            f'    <film type="hdrfilm"><integer name="width" value="{MESH_SIZE}"/><integer name="height" '
            f'value="{MESH_SIZE}"/>'
            f'<rfilter type="box"/></film>\n  </sensor>\n'
            f'  <shape type="ply"><string name="filename" value="mesh.ply"/></shape>\n</scene>\n'
        )
    return toml, xml


def seeded_copy(xml: str, folder: str) -> str:
    """A copy of ``xml`` in ``folder`` whose sampler reads its seed from a ``$seed`` parameter."""
    with open(xml) as f:
        text = f.read()
    marker = '<sampler type="independent">'
    if marker not in text:
        raise ValueError(f"{xml}: no independent sampler to seed")
    text = text.replace('<default name="spp"', '<default name="seed" value="0"/>\n    <default name="spp"', 1)
    text = text.replace(marker, marker + '\n            <integer name="seed" value="$seed"/>', 1)
    out = os.path.join(folder, os.path.basename(xml))
    with open(out, "w") as f:
        f.write(text)
    return out


def mitsuba_command(variant: str) -> list[str] | None:
    """The ``mitsuba`` command line of ``variant``, or None where the executable is missing."""
    exe = shutil.which("mitsuba") or os.path.join(os.path.dirname(sys.executable), "mitsuba")
    return [exe, "-m", variant] if os.path.exists(exe) else None


def wrt_command() -> list[str]:
    """``wrt`` as installed beside this Python (its console script), else ``python -m wrt``."""
    exe = os.path.join(os.path.dirname(sys.executable), "wrt")
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "wrt"]


CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}  # see the module docstring


def _timed(command: list[str], cwd: str) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=CHILD_ENV)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(
            f"{' '.join(command)} exited with {done.returncode}: {(done.stderr or done.stdout).strip()[-500:]}"
        )
    return seconds


def alternate(commands: dict[str, list[list[str]]], cwd: str, log=None) -> dict[str, list[float]]:
    """Run every command list's warm-up (its first command), then its runs in turn across the
    lists (``a[1] b[1] a[2] b[2] ...``): wall seconds per run, by name."""
    for name, runs in commands.items():
        _timed(runs[0], cwd)
    times = {name: [] for name in commands}
    for k in range(1, max(len(r) for r in commands.values())):
        for name, runs in commands.items():
            if k < len(runs):
                times[name].append(_timed(runs[k], cwd))
                if log:
                    log(f"    {name} run {k}: {times[name][-1]:.2f} s")
    return times


def _summary(times: list[float]) -> dict:
    return {"median_s": statistics.median(times), "min_s": min(times), "max_s": max(times), "times_s": times}


def run_mesh(triangles: int, repeats: int, device: str = "cpu", log=None) -> dict:
    """The mesh comparison (see the module docstring): wall times of both whole processes, wrt's
    on ``device``."""
    variant = mitsuba_peer.variant()
    mitsuba = mitsuba_command(variant)
    with tempfile.TemporaryDirectory(prefix="wrt-bench-mesh-") as folder:
        toml, xml = mesh_scenes(folder, triangles)
        commands = {
            "wrt": [wrt_command() + ["render", toml, "-o", os.path.join(folder, "wrt.exr"), "--device", device]]
            * (repeats + 1)
        }
        if mitsuba is not None:
            commands["Mitsuba"] = [mitsuba + ["-o", os.path.join(folder, "mitsuba.exr"), xml]] * (repeats + 1)
        times = alternate(commands, folder, log)
    result = {
        "triangles": triangles,
        "pixels": MESH_SIZE * MESH_SIZE,
        "repeats": repeats,
        "device": device,
        "mitsuba_variant": variant if mitsuba else None,
    }
    result.update({name: _summary(t) for name, t in times.items()})
    if "Mitsuba" in result:
        result["ratio"] = result["Mitsuba"]["median_s"] / result["wrt"]["median_s"]  # above 1: wrt is faster
    return result


def run_path(
    spp: int,
    repeats: int,
    reference: np.ndarray,
    res: int = 128,
    samplers: tuple[str, ...] = ("independent",),
    device: str = "cpu",
    log=None,
) -> dict:
    """The path-tracing comparison (see the module docstring) at ``res`` x ``res`` pixels: wall
    times, MSEs and Monte Carlo efficiencies of wrt on ``device`` (one entry per sampler, ``wrt``
    for the file's own) and Mitsuba. ``reference``: the converged image at that size."""
    variant = mitsuba_peer.variant()
    mitsuba = mitsuba_command(variant)
    with tempfile.TemporaryDirectory(prefix="wrt-bench-path-") as folder:
        xml = seeded_copy(CORNELL_XML, folder)
        outputs, commands = {}, {}
        for sampler in samplers:
            name = "wrt" if sampler == "independent" else f"wrt {sampler}"
            outputs[name] = [os.path.join(folder, f"{name.replace(' ', '-')}-{k}.exr") for k in range(repeats + 1)]
            extra = [] if sampler == "independent" else ["--sampler", sampler]
            size = ["--width", str(res), "--height", str(res), "--device", device]
            commands[name] = [
                wrt_command() + ["render", xml, "-o", out, "--spp", str(spp), "--seed", str(k)] + size + extra
                for k, out in enumerate(outputs[name])
            ]
        if mitsuba is not None:
            outputs["Mitsuba"] = [os.path.join(folder, f"mitsuba-{k}.exr") for k in range(repeats + 1)]
            commands["Mitsuba"] = [
                mitsuba + ["-o", out, f"-Dspp={spp}", f"-Dseed={k}", f"-Dres={res}", xml]
                for k, out in enumerate(outputs["Mitsuba"])
            ]
        times = alternate(commands, folder, log)
        errors = {
            name: [float(np.mean((read_image(out).rgb.astype(np.float64) - reference) ** 2)) for out in outs[1:]]
            for name, outs in outputs.items()
        }
    result = {
        "scene": "examples/mitsuba/cornell_box.xml",
        "res": res,
        "spp": spp,
        "repeats": repeats,
        "device": device,
        "mitsuba_variant": variant if mitsuba else None,
    }
    for name in times:
        mse = float(np.mean(errors[name]))
        entry = _summary(times[name])
        entry.update({"mse": mse, "mse_runs": errors[name], "efficiency": 1.0 / (mse * entry["median_s"])})
        result[name] = entry
    if "Mitsuba" in result:
        for name in times:
            if name != "Mitsuba":
                result[name]["efficiency_ratio"] = result[name]["efficiency"] / result["Mitsuba"]["efficiency"]
    return result
