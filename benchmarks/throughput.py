"""Ray throughput of the project's BVH against Warp's ``wp.Mesh`` and Embree, on one large mesh.

    python -m wrt_benchmarks.throughput [--triangles N] [--rays N] [--repeats R] [--device cpu] [-o results.json]

One procedural closed triangle mesh (a displaced torus, ``torus_mesh``), two ray sets traced by
every engine (``coherent``: pinhole camera rays over an image grid; ``incoherent``: uniform random
origins in the mesh's bounding box with uniform random unit directions), two queries (``closest``
hit with its distance, ``any`` hit: occlusion yes/no), three engines:

- ``wrt``: the project's BVH, built as the renderer builds it (``wrt.geometry.build``: numpy
  binned SAH) and uploaded by ``wrt.device.upload_geometry``, traced by the kernels
  ``wrt.kernels.traverse.trace_closest`` and ``trace_any``;
- ``wp.Mesh``: Warp's own mesh BVH (SAH, leaf size 4, built in C++) with ``wp.mesh_query_ray``
  and ``wp.mesh_query_ray_anyhit`` (``mesh_closest``, ``mesh_any`` below);
- ``Embree``: Embree 4 through the optional ``embreex`` package (``pip install -e '.[bench]'``),
  skipped when it is not importable. ``EmbreeScene.run`` (embreex 4.4.0.post1) traces its rays
  one ``rtcIntersect1`` (or ``rtcOccluded1``) call after another on the calling thread and has
  no thread option, so one call is single-threaded Embree: that is the "per thread" figure. It
  releases the GIL while it traces, so the thread pool runs it on several cores like the Warp
  engines ("all threads"). Its BVH build runs on Embree's own TBB threads (embreex exposes no
  device configuration to limit them).

The machine may be shared: each timing records ``other_busy_cores``, the cores that other
processes kept busy meanwhile (from /proc/stat; 0 on a quiet machine), so that a contended
number can be told from a real one.

Every engine traces the same rays in the same tiles of ``wrt.renderer.TILE_PIXELS`` rays, launched
from a ``ThreadPoolExecutor`` with 1 worker ("per thread") and with one worker per core ("all
threads"), as the renderer launches its tiles on the CPU (a Warp CPU launch runs on the calling
thread and releases the GIL). On CUDA the Warp engines trace each ray set in one launch (reported
as "all threads"). Times are wall seconds of a whole ray set, median of ``repeats`` runs, after
one untimed warm-up run; kernel loading (compilation with a cold cache) and BVH builds are timed
separately. The engines' answers are compared ray by ray: hit or miss, and the hit distance
``t`` within ``T_RTOL``.

Rays have unit directions, so ``t`` is a distance in scene units; every engine gets
``t_min = 0`` (``wp.mesh_query_ray`` and embreex have no other) and ``t_max = T_MAX``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import warp as wp
import wrt.kernels  # noqa: F401  (configures Warp)
from wrt.kernels import MODULE_OPTIONS
from wrt.kernels.traverse import KIND_BITS, VisitLog

from wrt.bvh import PLOC_RADIUS, build_bvh
from wrt.device import init_warp, resolve_device
from wrt.errors import WrtError
from wrt.files import write_json
from wrt.geometry import build, flatten
from wrt.host import default_threads, machine_info
from wrt.renderer import TILE_PIXELS
from wrt.scene import Camera, Material, Mesh, RenderSettings, Scene
from wrt.tables import text_table
from wrt.trace import Tracer

T_MAX = 1.0e30  # finite in float32 for every engine; a miss reports t = T_MAX
T_RTOL = 1.0e-4  # hit distances closer than this (relative, absolute below 1) agree
SEED = 20261125
ENGINES = ("wrt", "wp.Mesh", "Embree")
RAY_SETS = ("coherent", "incoherent")
QUERIES = ("closest", "any")

wp.set_module_options(MODULE_OPTIONS)  # the wp.Mesh kernels below: compiled as wrt's are


@wp.kernel
def mesh_closest(
    mesh: wp.uint64,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    t_max: float,
    out_t: wp.array(dtype=float),
    out_face: wp.array(dtype=wp.int32),
):
    """Closest hit with ``wp.mesh_query_ray``: ``t`` (``t_max`` on a miss) and face (-1 on a miss)."""
    i = wp.tid()
    q = wp.mesh_query_ray(mesh, origins[i], directions[i], t_max)
    if q.result:
        out_t[i] = q.t
        out_face[i] = q.face
    else:
        out_t[i] = t_max
        out_face[i] = -1


@wp.kernel
def mesh_any(
    mesh: wp.uint64,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    t_max: float,
    out_hit: wp.array(dtype=wp.int32),
):
    """Any hit with ``wp.mesh_query_ray_anyhit``: 1 where a face lies in ``[0, t_max)``."""
    i = wp.tid()
    out_hit[i] = wp.where(wp.mesh_query_ray_anyhit(mesh, origins[i], directions[i], t_max), 1, 0)


def torus_mesh(triangles: int, major: float = 1.0, minor: float = 0.35) -> tuple[np.ndarray, np.ndarray]:
    """A closed, displaced torus of about ``triangles`` triangles (world space, float64).

    The torus lies around the z axis (``major``: radius of the centre circle; ``minor``: the
    tube's mean radius, displaced by up to 20% with two sine patterns so that the surface is not
    a surface of revolution). A grid of ``nu x nv`` vertices (``nu ~ 2 nv``), two triangles per
    quad, wrapping in both directions: every edge is shared by exactly two triangles.

    Returns
    -------
    vertices : (nu * nv, 3) float64
    faces : (2 * nu * nv, 3) int32, consistently wound (normals point out of the tube)
    """
    if triangles < 18:
        raise ValueError(f"triangles must be >= 18 (a 3 x 3 grid), got {triangles}")
    nv = max(3, int(round(np.sqrt(triangles / 4.0))))
    nu = max(3, int(round(triangles / (2.0 * nv))))
    u = np.arange(nu) * (2.0 * np.pi / nu)
    v = np.arange(nv) * (2.0 * np.pi / nv)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    r = minor * (1.0 + 0.15 * np.sin(7.0 * uu) * np.sin(5.0 * vv) + 0.05 * np.sin(31.0 * uu + 17.0 * vv))
    ring = major + r * np.cos(vv)
    vertices = np.stack([ring * np.cos(uu), ring * np.sin(uu), r * np.sin(vv)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    i1, j1 = (i + 1) % nu, (j + 1) % nv
    a, b, c, d = i * nv + j, i1 * nv + j, i1 * nv + j1, i * nv + j1
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return vertices, faces.astype(np.int32)


def coherent_rays(lo: np.ndarray, hi: np.ndarray, rays: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """Primary rays of a pinhole camera looking down at the mesh's box ``[lo, hi]`` from above
    its side: one ray through each pixel centre of a ``width x height`` grid, row by row
    (``width = round(sqrt(rays))``, the last row partial). Unit directions, float32."""
    center = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    camera = Camera(
        origin=tuple(center + radius * np.array([0.3, -2.2, 1.4])), look_at=tuple(center), up=(0.0, 0.0, 1.0), fov=28.0
    )
    forward, right, up = camera.basis()
    width = max(1, int(round(np.sqrt(rays))))
    height = -(-rays // width)
    k = np.arange(rays)
    tan_half = np.tan(np.radians(camera.fov) / 2.0)
    x = (2.0 * ((k % width) + 0.5) / width - 1.0) * tan_half * (width / height)
    y = (1.0 - 2.0 * ((k // width) + 0.5) / height) * tan_half
    d = forward + x[:, None] * right + y[:, None] * up
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(camera.origin), d.shape)
    info = {
        "camera": {
            "origin": list(camera.origin),
            "look_at": list(camera.look_at),
            "up": list(camera.up),
            "fov_deg": camera.fov,
        },
        "width": width,
        "height": height,
    }
    return o.astype(np.float32), d.astype(np.float32), info


def incoherent_rays(lo: np.ndarray, hi: np.ndarray, rays: int, seed: int = SEED) -> tuple[np.ndarray, np.ndarray, dict]:
    """Origins uniform in the box ``[lo, hi]``, directions uniform on the unit sphere (normalised
    Gaussians), from ``numpy.random.default_rng(seed)``; float32."""
    rng = np.random.default_rng(seed)
    o = lo + rng.random((rays, 3)) * (hi - lo)
    d = rng.standard_normal((rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return (
        o.astype(np.float32),
        d.astype(np.float32),
        {"seed": seed, "origins": "uniform in the mesh's bounding box", "directions": "uniform on the sphere"},
    )


def _nbytes(a: wp.array) -> int:
    return int(a.size) * wp.types.type_size_in_bytes(a.dtype)


def _mesh_scene(vertices: np.ndarray, faces: np.ndarray) -> Scene:
    """A scene of the mesh alone (camera and materials do not matter to a BVH)."""
    return Scene(
        render=RenderSettings(),
        camera=Camera(origin=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0)),
        materials=(Material(name="mesh"),),
        shapes=(Mesh(file="<procedural torus>", vertices=vertices, faces=faces, material=0),),
    )


class WrtEngine:
    """The project's BVH, through ``wrt.trace.Tracer``: built and uploaded as the renderer does,
    traced by ``wrt.kernels.traverse`` compiled for the scene's geometry, as a large render's
    specialised kernels are (a triangle mesh: no sphere or polygon tests)."""

    name = "wrt"

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, dev):
        self.dev = dev
        t0 = time.perf_counter()
        self.tracer = Tracer(_mesh_scene(vertices, faces), device=dev, specialize=True)
        wp.synchronize_device(dev)
        seconds = time.perf_counter() - t0
        self.data, self.closest_kernel, self.any_kernel, self.visits_kernel = (
            self.tracer.data,
            self.tracer.closest_kernel,
            self.tracer.any_kernel,
            self.tracer.visits_kernel,
        )
        stats = self.tracer.prims.bvh.stats
        self.face = (
            self.tracer.prims.bvh.order.numpy()
        )  # input face of each triangle in leaf order (the mesh is the only shape)
        self.build = {
            "build_s": seconds,
            "bvh_build_s": stats.build_s,
            "bvh_phases_s": stats.phases_s,
            "build_threads": default_threads() if dev.is_cpu else None,
            "builder": (
                f"wrt.bvh: Morton order, PLOC (radius {PLOC_RADIUS}), SAH leaves, 4-wide collapse; Warp "
                f"kernels on {dev}"
            )
            + ("" if stats.builder == "ploc" else " (balanced fallback)"),
            "wide_nodes": stats.wide_nodes,
            "leaves": stats.leaves,
            "mean_leaf_triangles": stats.mean_leaf_size,
            "sah_cost": stats.sah_cost,
            "stack_need": stats.stack_need,
            "bvh_device_bytes": _nbytes(self.data.nodes) + _nbytes(self.data.prims),
            "triangles_device_bytes": _nbytes(self.data.tri_verts),
            "memory_note": "exact array sizes: device = 112-byte 4-wide node + packed id per triangle; triangles: "
            "3 float32 vertices each (a triangle soup, in leaf order)",
        }

    def kernel_modules(self):
        return [self.closest_kernel.module, self.any_kernel.module]

    def trace(self, query: str, o: wp.array, d: wp.array, out: tuple) -> None:
        if query == "closest":
            wp.launch(
                self.closest_kernel,
                dim=len(o),
                inputs=[self.data, o, d, 0.0, T_MAX, 0, out[0], out[1], out[2]],
                device=self.dev,
            )
        else:
            wp.launch(self.any_kernel, dim=len(o), inputs=[self.data, o, d, 0.0, T_MAX, out[0]], device=self.dev)

    def visits_per_ray(self, o: wp.array, d: wp.array) -> float:
        """Mean wide nodes a closest-hit query visits (``wrt.kernels.traverse.trace_visits``)."""
        log = VisitLog()
        log.nodes = wp.zeros((len(o), 1), dtype=wp.int32, device=self.dev)
        log.count = wp.zeros(len(o), dtype=wp.int32, device=self.dev)
        wp.launch(
            self.visits_kernel,
            dim=len(o),
            inputs=[self.data, o, d, wp.zeros(len(o), dtype=float, device=self.dev), log],
            device=self.dev,
        )
        return float(log.count.numpy().mean())

    def faces_of(self, prim: np.ndarray) -> np.ndarray:
        return np.where(prim >= 0, self.face[np.maximum(prim, 0) >> KIND_BITS], -1)


class WarpMeshEngine:
    """``wp.Mesh`` (Warp's defaults on this device: SAH, leaf size 4) with ``mesh_query_ray``."""

    name = "wp.Mesh"

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, dev):
        self.dev = dev
        self.points = wp.array(vertices.astype(np.float32), dtype=wp.vec3, device=dev)
        self.indices = wp.array(faces.reshape(-1), dtype=wp.int32, device=dev)
        wp.synchronize_device(dev)
        t0 = time.perf_counter()
        self.mesh = wp.Mesh(points=self.points, indices=self.indices)
        wp.synchronize_device(dev)
        n = len(faces)
        max_nodes = 2 * n - 1
        self.build = {
            "build_s": time.perf_counter() - t0,
            "build_threads": 1 if dev.is_cpu else None,
            "builder": "wp.Mesh default: SAH on CPU (C++), LBVH on CUDA; leaf size 4",
            # allocation sizes of Warp 1.19's native bvh.cpp / mesh.cpp: two 16-byte node halves and a
            # parent index per node (2n - 1 allocated), a primitive index and a bounding box per triangle
            "bvh_device_bytes": max_nodes * (2 * 16 + 4) + n * (4 + 2 * 12),
            "triangles_device_bytes": _nbytes(self.points) + _nbytes(self.indices),
            "memory_note": "from the allocation sizes in Warp 1.19's native bvh.cpp and mesh.cpp (2n - 1 nodes "
            "allocated); triangles: shared float32 vertices + 3 int32 indices per triangle",
        }

    def kernel_modules(self):
        return [mesh_closest.module]

    def trace(self, query: str, o: wp.array, d: wp.array, out: tuple) -> None:
        if query == "closest":
            wp.launch(mesh_closest, dim=len(o), inputs=[self.mesh.id, o, d, T_MAX, out[0], out[1]], device=self.dev)
        else:
            wp.launch(mesh_any, dim=len(o), inputs=[self.mesh.id, o, d, T_MAX, out[0]], device=self.dev)

    def faces_of(self, face: np.ndarray) -> np.ndarray:
        return face


def _rss_bytes() -> int | None:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def embree_version() -> str | None:
    """``"4.4.0"`` or such when ``embreex`` imports, else None."""
    try:
        from embreex.rtcore import EmbreeDevice
    except ImportError:
        return None
    return repr(EmbreeDevice()).split(":")[-1].strip()


class EmbreeEngine:
    """Embree through ``embreex`` (a static scene, default build quality, not the robust mode)."""

    name = "Embree"

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        from embreex.mesh_construction import TriangleMesh
        from embreex.rtcore_scene import EmbreeScene

        v = np.ascontiguousarray(vertices, dtype=np.float32)
        f = np.ascontiguousarray(faces, dtype=np.int32)
        rss0 = _rss_bytes()
        t0 = time.perf_counter()
        self.scene = EmbreeScene()
        self.mesh = TriangleMesh(self.scene, v, f)
        # embreex commits (builds) the scene on the first query
        self.scene.run(
            np.zeros((1, 3), np.float32), np.array([[0.0, 0.0, 1.0]], np.float32), dists=T_MAX, query="DISTANCE"
        )
        t1 = time.perf_counter()
        rss1 = _rss_bytes()
        self.build = {
            "build_s": t1 - t0,
            "build_threads": default_threads(),
            "builder": f"Embree {embree_version()} (embreex), TBB threads",
            "rss_growth_bytes": None if rss0 is None else rss1 - rss0,
            "memory_note": "growth of the process's resident memory during scene creation and build (Embree exposes "
            "no memory statistics through embreex): BVH + Embree's copy of the triangles, approximate",
        }

    def trace(self, query: str, o: np.ndarray, d: np.ndarray, out: tuple) -> None:
        if query == "closest":
            out[0][:] = self.scene.run(o, d, dists=T_MAX, query="DISTANCE")
        else:
            out[0][:] = self.scene.run(o, d, dists=T_MAX, query="OCCLUDED") >= 0


def _machine() -> dict:
    return {**machine_info(), "embree": embree_version()}


def _tiles(n: int) -> list[tuple[int, int]]:
    return [(a, min(a + TILE_PIXELS, n)) for a in range(0, n, TILE_PIXELS)]


def _busy_cpu_s() -> float | None:
    """CPU seconds all processes of the machine have run (Linux /proc/stat), or None."""
    try:
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + fields[4]  # idle, iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def _run_tiles(pool: ThreadPoolExecutor, jobs: list) -> float:
    t0 = time.perf_counter()
    for future in [pool.submit(*job) for job in jobs]:
        future.result()
    return time.perf_counter() - t0


def _measure(engine, query: str, o, d, threads: list[int], repeats: int, dev) -> tuple[dict, tuple]:
    """Time ``engine`` on one ray set and query for each thread count: one warm-up, then the
    median of ``repeats``. Returns the timings and the answers (numpy) of the last run."""
    n = len(o)
    is_warp = engine.name != "Embree"
    if is_warp:
        outs = (
            (
                wp.zeros(n, dtype=float, device=dev),
                wp.zeros(n, dtype=wp.int32, device=dev),
                wp.zeros(n, dtype=wp.int32, device=dev),
            )
            if query == "closest"
            else (wp.zeros(n, dtype=wp.int32, device=dev),)
        )
    else:
        outs = (np.empty(n, np.float32),) if query == "closest" else (np.empty(n, np.int32),)
    timings = {}
    if is_warp and dev.is_cuda:
        whole = [(lambda: (engine.trace(query, o, d, outs), wp.synchronize_device(dev)),)]  # noqa: E731
        plans = [("all_threads", 1, whole)]
    else:
        tiles = _tiles(n)
        # views made once: a timed run only launches
        jobs = [(engine.trace, query, o[a:b], d[a:b], tuple(x[a:b] for x in outs)) for a, b in tiles]
        plans = [("per_thread" if t == 1 else "all_threads", t, jobs) for t in threads]
    for label, t, jobs in plans:
        with ThreadPoolExecutor(max_workers=t) as pool:
            warm = _run_tiles(pool, jobs)
            busy0, own0, t0 = _busy_cpu_s(), time.process_time(), time.perf_counter()
            times = [_run_tiles(pool, jobs) for _ in range(repeats)]
            busy1, own1, t1 = _busy_cpu_s(), time.process_time(), time.perf_counter()
        # cores other processes kept busy over the timed runs (/proc/stat counts in 10 ms ticks: coarse for short runs)
        other = None if busy0 is None else max(0.0, (busy1 - busy0) - (own1 - own0)) / (t1 - t0)
        median = statistics.median(times)
        timings[label] = {
            "threads": t,
            "median_s": median,
            "times_s": times,
            "warmup_s": warm,
            "mrays_per_s": n / median / 1e6,
            "other_busy_cores": other,
        }
    if "per_thread" in timings and "all_threads" in timings:
        timings["scaling"] = timings["per_thread"]["median_s"] / timings["all_threads"]["median_s"]
    answers = tuple(x.numpy() if is_warp else x for x in outs)
    return timings, answers


def _agreement(ref: np.ndarray, other: np.ndarray, query: str) -> dict:
    """Ray-by-ray comparison of two engines' answers (``ref`` = wrt)."""
    if query == "any":
        a, b = ref.astype(bool), other.astype(bool)
        return {"hit_miss_mismatches": int(np.count_nonzero(a != b)), "mismatches": int(np.count_nonzero(a != b))}
    hit_a, hit_b = ref < T_MAX, other < T_MAX
    both = hit_a & hit_b
    diff = np.abs(ref[both].astype(np.float64) - other[both]) / np.maximum(1.0, np.abs(ref[both]))
    t_bad = int(np.count_nonzero(diff > T_RTOL))
    hm = int(np.count_nonzero(hit_a != hit_b))
    return {
        "hit_miss_mismatches": hm,
        "t_mismatches": t_bad,
        "mismatches": hm + t_bad,
        "max_rel_t_diff": float(diff.max()) if diff.size else 0.0,
    }


def binned_sah_reference(vertices: np.ndarray, faces: np.ndarray) -> dict:
    """The SAH cost (with wrt's constants) of the top-down binned-SAH tree of the numpy reference
    builder (``harness.binned_sah``, wrt's builder before the device build) on the same mesh."""
    from wrt.kernels.bvh_build import INTERSECTION_COST, TRAVERSAL_COST

    from .binned_sah import build_bvh, sah_cost

    tri = vertices.astype(np.float32)[faces].astype(np.float64)
    t0 = time.perf_counter()
    bvh = build_bvh(tri.min(axis=1), tri.max(axis=1))
    seconds = time.perf_counter() - t0
    leaves = bvh.count[bvh.count > 0]
    return {
        "builder": "harness.binned_sah: numpy, 16 bins, top down, breadth first (binary)",
        "build_s": seconds,
        "sah_cost": sah_cost(bvh, float(TRAVERSAL_COST), float(INTERSECTION_COST)),
        "binary_nodes": len(bvh.count),
        "leaves": len(leaves),
        "mean_leaf_triangles": float(leaves.mean()),
    }


def build_scaling(sizes: list[int], device: str = "cpu", repeats: int = 3) -> list[dict]:
    """Build seconds on tori of ``sizes`` triangles, the fastest of ``repeats`` each, alternating:
    ``wrt_s``, wrt's BVH from the triangle soup (``Primitives.bounds`` and ``wrt.bvh.build_bvh``,
    what ``wp.Mesh`` does from its points and indices); ``wp_mesh_s``, ``wp.Mesh`` from points and
    indices already on the device; ``wrt_scene_s``, all of ``wrt.geometry.build`` (the soup from the
    mesh, the BVH, the triangles reordered to leaf order)."""
    init_warp()
    dev = resolve_device(device)
    rows = []
    for n in sizes:
        vertices, faces = torus_mesh(n)
        scene = _mesh_scene(vertices, faces)
        soup = flatten(scene)
        wrt_s, scene_s, mesh_s = [], [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            bvh = build_bvh(*soup.bounds(), dev)
            wp.synchronize_device(dev)
            wrt_s.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            build(scene, dev)
            scene_s.append(time.perf_counter() - t0)
            mesh_s.append(WarpMeshEngine(vertices, faces, dev).build["build_s"])
        rows.append(
            {
                "triangles": len(faces),
                "wrt_s": min(wrt_s),
                "wp_mesh_s": min(mesh_s),
                "wrt_scene_s": min(scene_s),
                "wrt_phases_s": bvh.stats.phases_s,
                "sah_cost": bvh.stats.sah_cost,
            }
        )
    return rows


def run_throughput(
    triangles: int = 1_000_000,
    rays: int = 1 << 20,
    device: str = "cpu",
    repeats: int = 3,
    threads: int | None = None,
    embree: bool = True,
    reference_sah: bool = False,
) -> dict:
    """Measure closest-hit and any-hit ray throughput of every engine; JSON-serialisable results.

    Parameters
    ----------
    triangles : int
        About this many triangles in the torus (``torus_mesh``).
    rays : int
        Rays in each of the two ray sets.
    device : str
        Warp device of the Warp engines ("cpu" or "cuda"); Embree always runs on the CPU.
    repeats : int
        Timed runs per measurement (the median is reported), after one warm-up run.
    threads : int, optional
        Workers of the "all threads" runs (default: all available cores).
    embree : bool
        Include Embree when ``embreex`` is importable.
    reference_sah : bool
        Also build the binned-SAH reference tree (``binned_sah_reference``: 10-16 s at 1M triangles)
        and report its SAH cost beside wrt's.

    Returns
    -------
    dict
        ``machine``, ``mesh``, ``rays`` (per set: hit fraction...), ``build`` and ``compile_s`` per
        engine, ``throughput[ray_set][query][engine]`` with ``per_thread`` / ``all_threads``
        (``mrays_per_s``, ``median_s``, ``times_s``, ``warmup_s``) and ``scaling``,
        ``agreement[ray_set][query][engine]`` against wrt, and ``ratios`` of wrt to the others.
    """
    if triangles < 18:
        raise ValueError(f"triangles must be >= 18, got {triangles}")
    if rays < 1:
        raise ValueError(f"rays must be >= 1, got {rays}")
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    init_warp()
    dev = resolve_device(device)
    all_threads = max(1, threads or default_threads())
    thread_counts = sorted({1, all_threads})

    vertices, faces = torus_mesh(triangles)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    engines = [WrtEngine(vertices, faces, dev), WarpMeshEngine(vertices, faces, dev)]
    if embree and embree_version() is not None:
        engines.append(EmbreeEngine(vertices, faces))
    compile_s = {}
    for engine in engines:
        if hasattr(engine, "kernel_modules"):
            t0 = time.perf_counter()
            for module in engine.kernel_modules():
                wp.load_module(module, device=dev)
            compile_s[engine.name] = time.perf_counter() - t0

    results = {
        "benchmark": "ray throughput",
        "date": time.strftime("%Y-%m-%d"),
        "machine": _machine(),
        "device": str(dev),
        "repeats": repeats,
        "tile_rays": TILE_PIXELS,
        "threads": thread_counts,
        "t_max": T_MAX,
        "t_rtol": T_RTOL,
        "mesh": {
            "kind": "displaced torus (wrt_benchmarks.throughput.torus_mesh), closed",
            "triangles": len(faces),
            "vertices": len(vertices),
            "lo": lo.tolist(),
            "hi": hi.tolist(),
        },
        "engines": [e.name for e in engines],
        "build": {e.name: e.build for e in engines},
        "compile_s": compile_s,
        "rays": {},
        "throughput": {},
        "agreement": {},
    }
    for ray_set in RAY_SETS:
        make = coherent_rays if ray_set == "coherent" else incoherent_rays
        o_np, d_np, info = make(lo, hi, rays)
        o_np, d_np = np.ascontiguousarray(o_np), np.ascontiguousarray(d_np)
        o_wp = wp.array(o_np, dtype=wp.vec3, device=dev)
        d_wp = wp.array(d_np, dtype=wp.vec3, device=dev)
        per_query, agree = {}, {}
        for query in QUERIES:
            per_engine, answers = {}, {}
            for engine in engines:
                warp_engine = engine.name != "Embree"
                per_engine[engine.name], answers[engine.name] = _measure(
                    engine,
                    query,
                    o_wp if warp_engine else o_np,
                    d_wp if warp_engine else d_np,
                    thread_counts,
                    repeats,
                    dev,
                )
            per_query[query] = per_engine
            ref = answers["wrt"][0]
            agree[query] = {name: _agreement(ref, answers[name][0], query) for name in answers if name != "wrt"}
            if query == "closest":
                info["hit_fraction"] = float(np.mean(ref < T_MAX))
                if len(answers["wp.Mesh"]) > 1:
                    same_t = (ref < T_MAX) & (np.abs(ref - answers["wp.Mesh"][0]) <= T_RTOL * np.maximum(1.0, ref))
                    wrt_face = engines[0].faces_of(answers["wrt"][1])
                    agree[query]["wp.Mesh"]["face_differs_same_t"] = int(
                        np.count_nonzero(same_t & (wrt_face != answers["wp.Mesh"][1]))
                    )
        info["wide_nodes_per_ray"] = engines[0].visits_per_ray(o_wp, d_wp)
        results["rays"][ray_set] = {"count": rays, **info}
        results["throughput"][ray_set] = per_query
        results["agreement"][ray_set] = agree
    results["ratios"] = _ratios(results)
    if reference_sah:
        results["binned_sah_reference"] = binned_sah_reference(vertices, faces)
    return results


def _ratios(results: dict) -> dict:
    """wrt's throughput divided by each other engine's, per ray set, query and thread setting."""
    out = {}
    for ray_set, per_query in results["throughput"].items():
        for query, per_engine in per_query.items():
            for other in per_engine:
                if other == "wrt":
                    continue
                for label in ("per_thread", "all_threads"):
                    if label in per_engine["wrt"] and label in per_engine[other]:
                        key = f"wrt/{other}"
                        out.setdefault(key, {}).setdefault(ray_set, {}).setdefault(query, {})[label] = (
                            per_engine["wrt"][label]["mrays_per_s"] / per_engine[other][label]["mrays_per_s"]
                        )
    return out


def format_table(results: dict) -> str:
    """The results as plain text: throughput per ray set, query and threads, the ratios of wrt to
    ``wp.Mesh`` and Embree, thread scaling, builds and memory, and the agreement counts."""
    m = results["machine"]
    engines = results["engines"]
    lines = [
        f"Ray throughput: {results['mesh']['triangles']:,} triangles ({results['mesh']['kind']}), "
        f"{results['rays']['coherent']['count']:,} rays per set, Warp device {results['device']}, median of "
        f"{results['repeats']}",
        f"machine: {m['cpu']}, {m['cores']} cores, {m['system']}; Python {m['python']}, Warp {m['warp']}, Embree "
        f"{m['embree'] or 'not installed'}",
        "",
    ]
    head = (
        ["rays", "query", "threads"]
        + [f"{e} Mrays/s" for e in engines]
        + [f"wrt/{e}" for e in engines if e != "wrt"]
        + ["other busy cores"]
    )
    rows = [head]
    for ray_set, per_query in results["throughput"].items():
        for query, per_engine in per_query.items():
            for label in ("per_thread", "all_threads"):
                if label not in per_engine["wrt"]:
                    continue
                row = [ray_set, query, str(per_engine["wrt"][label]["threads"])]
                row += [
                    f"{per_engine[e][label]['mrays_per_s']:.3f}" if label in per_engine[e] else "-" for e in engines
                ]
                row += [
                    f"{results['ratios'][f'wrt/{e}'][ray_set][query].get(label, float('nan')):.2f}x"
                    for e in engines
                    if e != "wrt"
                ]
                busy = [per_engine[e][label]["other_busy_cores"] for e in engines if label in per_engine[e]]
                row.append("-" if None in busy else f"{max(busy):.2f}")
                rows.append(row)
    lines += text_table(rows).split("\n")
    lines.append(
        "other busy cores: the most cores other processes kept busy during one of the row's measurements (0 = a "
        "quiet machine)"
    )
    lines += ["", "thread scaling (all threads / 1 thread):"]
    scale = [["rays", "query"] + engines]
    for ray_set, per_query in results["throughput"].items():
        for query, per_engine in per_query.items():
            scale.append(
                [ray_set, query]
                + [f"{per_engine[e]['scaling']:.2f}x" if "scaling" in per_engine[e] else "-" for e in engines]
            )
    lines += text_table(scale).split("\n")
    lines += ["", "build and memory:"]
    mib = 2.0**20
    build = [["engine", "build s", "build threads", "kernel load s", "BVH MiB (device)", "triangles MiB (device)"]]
    for e in engines:
        b = results["build"][e]
        build.append(
            [
                e,
                f"{b['build_s']:.2f}",
                str(b.get("build_threads")),
                f"{results['compile_s'][e]:.2f}" if e in results["compile_s"] else "-",
                f"{b['bvh_device_bytes'] / mib:.1f}"
                if "bvh_device_bytes" in b
                else (
                    f"~{b['rss_growth_bytes'] / mib:.0f} (RSS growth, incl. triangles)"
                    if b.get("rss_growth_bytes")
                    else "-"
                ),
                f"{b['triangles_device_bytes'] / mib:.1f}" if "triangles_device_bytes" in b else "-",
            ]
        )
    lines += text_table(build).split("\n")
    w = results["build"]["wrt"]
    lines += [
        "",
        f"wrt's tree: {w['wide_nodes']:,} 4-wide nodes, {w['leaves']:,} leaves of {w['mean_leaf_triangles']:.2f} "
        "triangles on average, "
        f"SAH cost {w['sah_cost']:.1f}, stack need {w['stack_need']}; "
        + ", ".join(
            f"{ray_set} rays visit {results['rays'][ray_set]['wide_nodes_per_ray']:.1f} nodes"
            for ray_set in results["rays"]
        ),
    ]
    ref = results.get("binned_sah_reference")
    if ref:
        lines.append(
            "binned-SAH reference tree (wrt's builder before the device build) on the same mesh: SAH cost "
            f"{ref['sah_cost']:.1f}, "
            f"{ref['leaves']:,} leaves of {ref['mean_leaf_triangles']:.2f} triangles, built in {ref['build_s']:.1f} s "
            "(numpy, one thread)"
        )
    lines += [
        "",
        f"agreement with wrt (hit/miss differs, or hit distance differs by more than {results['t_rtol']:g} relative):",
    ]
    agree = [["rays", "query", "hit fraction"] + [f"{e} mismatches" for e in engines if e != "wrt"]]
    for ray_set, per_query in results["agreement"].items():
        for query, per_engine in per_query.items():
            agree.append(
                [ray_set, query, f"{results['rays'][ray_set]['hit_fraction']:.3f}"]
                + [
                    f"{per_engine[e]['mismatches']} / {results['rays'][ray_set]['count']:,}"
                    for e in engines
                    if e != "wrt"
                ]
            )
    lines += text_table(agree).split("\n")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m wrt_benchmarks.throughput",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--triangles", type=int, default=1_000_000, help="triangles in the mesh (about; default 1,000,000)"
    )
    parser.add_argument("--rays", type=int, default=1 << 20, help="rays in each ray set (default 1,048,576)")
    parser.add_argument(
        "--repeats", type=int, default=3, help="timed runs per measurement, median reported (default 3)"
    )
    parser.add_argument("--device", default="cpu", help="Warp device of the Warp engines (default cpu)")
    parser.add_argument(
        "--threads", type=int, default=None, help="workers of the all-threads runs (default: all cores)"
    )
    parser.add_argument("--no-embree", action="store_true", help="leave Embree out even when embreex is installed")
    parser.add_argument(
        "--reference-sah", action="store_true", help="also build the binned-SAH reference tree and report its SAH cost"
    )
    parser.add_argument("-o", "--output", help="write the results as JSON here")
    args = parser.parse_args(argv)
    try:
        results = run_throughput(
            args.triangles,
            args.rays,
            device=args.device,
            repeats=args.repeats,
            threads=args.threads,
            embree=not args.no_embree,
            reference_sah=args.reference_sah,
        )
    except (ValueError, WrtError) as e:
        parser.error(str(e))
    results["command"] = " ".join(["python -m wrt_benchmarks.throughput", *(sys.argv[1:] if argv is None else argv)])
    print(format_table(results))
    if args.output:
        write_json(args.output, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
