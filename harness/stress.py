"""The stress suite behind ``wrt stress``: adversarial rays through the real Warp kernels.

Every case builds its scene in memory, shoots rays through the kernels the renderer uses
(``wrt.kernels.traverse.trace_closest`` / ``trace_any``, ``wrt.kernels.stress.trace_spawned``, or
``wrt.render`` with the raycast and whitted integrators) and counts the rays that break the
case's rule. A case passes when that count is zero. The bounds and what each case measures are
documented in ``docs/stress.md``.

Ray budget: ``rays`` (N, ``wrt stress --rays``) is the number of rays each ray-batch case
shoots; the image cases render fixed small images whatever N (their ray count is reported).
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

import wrt.kernels  # noqa: F401  (configures Warp)
from wrt.kernels import spawn
from wrt.kernels.traverse import NO_HIT, SPHERE, trace_any, trace_closest
from wrt.device import upload_geometry
from wrt.files import write_atomic
from wrt.bvh import lane_bounds
from wrt.geometry import build
from wrt.loader import parse_scene
from wrt.scene import Mesh

EPS32 = 2.0**-24  # float32 unit roundoff: |fl(x) - x| <= EPS32 |x|
DEFAULT_RAYS = 10**6


# --- results -----------------------------------------------------------------------------------


@dataclass
class CaseResult:
    """One row of the table.

    ``failures`` counts the rays (or pixels) that break the case's rule; ``worst`` is the worst
    measured error in ``unit`` (None where the rule is a count, e.g. leaks), ``bound`` the limit
    it is held to (a ray beyond it is a failure). ``detail`` holds further measured numbers.
    """

    case: str
    rays: int
    failures: int
    worst: float | None = None
    bound: float | str | None = None
    unit: str = ""
    detail: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        return self.failures == 0

    def as_dict(self) -> dict:
        return {**dataclasses.asdict(self), "passed": self.passed}


def _fmt(value, unit=""):
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    text = f"{value:.3g}" if isinstance(value, float) else str(value)
    return f"{text} {unit}".strip()


def table_rows(results: list[CaseResult]) -> list[list[str]]:
    rows = [["case", "rays", "failures", "worst error", "bound", "result"]]
    for r in results:
        rows.append([r.case, str(r.rays), str(r.failures), _fmt(r.worst, r.unit), _fmt(r.bound, r.unit), "pass" if r.passed else "FAIL"])
    return rows


def format_table(results: list[CaseResult]) -> str:
    """The plain-text table ``wrt stress`` prints."""
    rows = table_rows(results)
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    lines = ["  ".join(cell.ljust(w) if k == 0 else cell.rjust(w) for k, (cell, w) in enumerate(zip(row, widths))) for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def format_markdown(results: list[CaseResult], rays: int, seed: int) -> str:
    rows = table_rows(results)
    lines = [f"# wrt stress: N = {rays} rays, seed {seed}", "", "| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    lines += ["| " + " | ".join(row) + " |" for row in rows[1:]]
    lines += ["", "## Details", ""]
    for r in results:
        if r.detail:
            lines.append(f"- **{r.case}** ({r.seconds:.1f} s): " + ", ".join(f"{k} = {_fmt(v)}" for k, v in r.detail.items()))
        else:
            lines.append(f"- **{r.case}** ({r.seconds:.1f} s)")
    return "\n".join(lines) + "\n"


def write_report(results: list[CaseResult], folder: str, rays: int, seed: int) -> tuple[str, str]:
    """Write ``stress.json`` and ``stress.md`` into ``folder`` (created if needed); returns their paths."""
    os.makedirs(folder, exist_ok=True)
    json_path, md_path = os.path.join(folder, "stress.json"), os.path.join(folder, "stress.md")
    doc = {"rays": rays, "seed": seed, "passed": all(r.passed for r in results), "cases": [r.as_dict() for r in results]}
    write_atomic(json_path, json.dumps(doc, indent=2, default=float) + "\n")
    write_atomic(md_path, format_markdown(results, rays, seed))
    return json_path, md_path


# --- scenes and ray batches --------------------------------------------------------------------


def make_scene(shapes=(), meshes=(), materials=(), camera=None, render=None, lights=()):
    """A validated ``Scene`` from inline tables, plus meshes given as arrays.

    ``meshes``: ``(vertices (V, 3), faces (F, 3), material name or None)``; they follow the
    ``shapes`` in ``[[shape]]`` order (so their object ids come after).
    """
    doc = {"camera": camera or {"origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0]}, "shape": list(shapes), "material": list(materials), "light": list(lights)}
    if render:
        doc["render"] = render
    scene = parse_scene(doc, file="<stress>")
    index = {m.name: i for i, m in enumerate(scene.materials)}
    extra = tuple(
        Mesh(file="<stress>", vertices=np.asarray(v, np.float64), faces=np.asarray(f, np.int32), material=index[m or "default"]) for v, f, m in meshes
    )
    return dataclasses.replace(scene, shapes=scene.shapes + extra)


def _vec3_array(a) -> wp.array:
    return wp.array(np.ascontiguousarray(np.asarray(a, np.float32).reshape(-1, 3)), dtype=wp.vec3, device="cpu")


class Tracer:
    """Closest-hit and any-hit queries of ray batches against a scene, on the CPU."""

    def __init__(self, scene):
        self.prims = build(scene, "cpu")
        self.data = upload_geometry(self.prims, "cpu")

    def closest(self, origins, directions, t_min=0.0, t_max=np.inf, brute_force=False):
        """``(t, packed primitive id)`` per ray; ``t = t_max`` and id -1 on a miss."""
        o, d = _vec3_array(origins), _vec3_array(directions)
        t = wp.zeros(len(o), dtype=float, device="cpu")
        prim = wp.zeros(len(o), dtype=wp.int32, device="cpu")
        wp.launch(trace_closest, dim=len(o), inputs=[self.data, o, d, float(t_min), float(t_max), int(brute_force), t, prim], device="cpu")
        return t.numpy(), prim.numpy()

    def occluded(self, origins, directions, t_min=0.0, t_max=np.inf):
        o, d = _vec3_array(origins), _vec3_array(directions)
        hit = wp.zeros(len(o), dtype=wp.int32, device="cpu")
        wp.launch(trace_any, dim=len(o), inputs=[self.data, o, d, float(t_min), float(t_max), hit], device="cpu")
        return hit.numpy().astype(bool)

    def triangles(self, packed):
        """Vertices (n, 3, 3) of the triangles with these packed ids, as stored on the device (float32 values)."""
        verts = self.prims.tri_verts.astype(np.float32).astype(np.float64)
        return verts[np.asarray(packed) >> 2]


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_directions(rng, n):
    return unit(rng.normal(size=(n, 3)))


def f32(a):
    """The float32 value of ``a``, as float64 (what the device holds)."""
    return np.asarray(a, np.float64).astype(np.float32).astype(np.float64)


# --- closed meshes -------------------------------------------------------------------------------


def uv_sphere(n_lon=64, n_lat=32):
    """Unit sphere as latitude/longitude quads split in two, with a triangle fan at each pole."""
    theta = np.linspace(0.0, np.pi, n_lat + 1)[1:-1]
    phi = np.linspace(0.0, 2.0 * np.pi, n_lon, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.column_stack([(np.sin(th) * np.cos(ph)).ravel(), np.cos(th).ravel(), (np.sin(th) * np.sin(ph)).ravel()])
    vertices = np.vstack([[0.0, 1.0, 0.0], ring, [0.0, -1.0, 0.0]])
    south = len(vertices) - 1
    j = np.arange(n_lon)
    jn = (j + 1) % n_lon

    def idx(i, k):
        return 1 + i * n_lon + k

    faces = [np.column_stack([np.zeros(n_lon, int), idx(0, jn), idx(0, j)]), np.column_stack([np.full(n_lon, south), idx(n_lat - 2, j), idx(n_lat - 2, jn)])]
    for i in range(n_lat - 2):
        a, b, c, d = idx(i, j), idx(i, jn), idx(i + 1, j), idx(i + 1, jn)
        faces += [np.column_stack([a, b, d]), np.column_stack([a, d, c])]
    return vertices, np.vstack(faces)


def split_cube(k=8):
    """Cube [-1, 1]^3, each face a k x k grid of squares split into two triangles (coplanar neighbours)."""
    grid = np.arange(k + 1)
    faces, keys = [], {}

    def vid(p):
        return keys.setdefault(tuple(int(c) for c in p), len(keys))

    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, k):
            ids = np.empty((k + 1, k + 1), int)
            for a in grid:
                for b in grid:
                    p = np.zeros(3, int)
                    p[axis], p[u], p[v] = side, a, b
                    ids[a, b] = vid(p)
            q0, q1, q2, q3 = ids[:-1, :-1].ravel(), ids[1:, :-1].ravel(), ids[1:, 1:].ravel(), ids[:-1, 1:].ravel()
            tris = np.vstack([np.column_stack([q0, q1, q2]), np.column_stack([q0, q2, q3])])
            faces.append(tris if side == k else tris[:, ::-1])  # outward: (u, v, axis) is right-handed
    vertices = np.array(list(keys), dtype=np.float64) * (2.0 / k) - 1.0
    return vertices, np.vstack(faces)


def bicone_fan(n=256):
    """Two cones on a shared rim of ``n`` vertices: a fan of ``n`` needle-thin triangles around each apex."""
    phi = 2.0 * np.pi * np.arange(n) / n
    vertices = np.vstack([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], np.column_stack([np.cos(phi), np.zeros(n), np.sin(phi)])])
    j = 2 + np.arange(n)
    jn = 2 + (np.arange(n) + 1) % n
    faces = np.vstack([np.column_stack([np.zeros(n, int), jn, j]), np.column_stack([np.ones(n, int), j, jn])])
    return vertices, faces


CLOSED_MESHES = {"uv sphere 64x32": uv_sphere, "split cube 8x8": split_cube, "bicone fan 256": bicone_fan}
# (scale, offset): the unit mesh, and the mesh 100x larger 1e4 units from the origin
PLACEMENTS = ((1.0, np.zeros(3)), (100.0, np.array([1.0e4, -7.0e3, 3.0e3])))


def _edge_targets(vertices, faces, n, rng, vertex_share=0.2):
    """Points exactly on shared edges (float64 lerps) and at vertices of a mesh: ``n`` of them."""
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    pick = edges[rng.integers(0, len(edges), n)]
    s = rng.random(n)[:, None]
    s[: int(n * vertex_share)] = 0.0
    return vertices[pick[:, 0]] + s * (vertices[pick[:, 1]] - vertices[pick[:, 0]])


def watertight_case(name, vertices, faces, rays, rng) -> CaseResult:
    """Rays aimed exactly at shared edges and vertices of a closed convex mesh must hit it.

    Half the rays start inside (random points of the ball of radius 0.5 around the centre): any
    miss is a leak. Half start outside and enter through the target: their first hit must be
    the target (t = distance to it, +1e-3 of the mesh size); a miss or a later hit is a leak.
    Half the rays of each kind use the unit mesh, half a copy 100x larger 1e4 units away.
    """
    leaks = {"inside": 0, "outside": 0}
    shot = 0
    for scale, offset in PLACEMENTS:
        v = vertices * scale + offset
        tracer = Tracer(make_scene(meshes=[(v, faces, None)]))
        n = max(rays // (2 * len(PLACEMENTS)), 1)
        for kind in leaks:
            target = _edge_targets(v, faces, n, rng)
            if kind == "inside":
                inner = offset + 0.5 * scale * random_directions(rng, n) * rng.random((n, 1)) ** (1 / 3)
                d = unit(target - inner)
                _, prim = tracer.closest(inner, d)
                leaks[kind] += int(np.count_nonzero(prim == NO_HIT))
            else:
                inner = offset + 0.5 * scale * random_directions(rng, n) * rng.random((n, 1)) ** (1 / 3)
                d = unit(inner - target)
                distance = 3.0 * scale
                t, prim = tracer.closest(target - distance * d, d)
                leaks[kind] += int(np.count_nonzero((prim == NO_HIT) | (t > distance + 1e-3 * scale)))
            shot += n
    return CaseResult(f"watertight: {name}", shot, leaks["inside"] + leaks["outside"], unit="leaks", detail={"leaks_from_inside": leaks["inside"], "leaks_from_outside": leaks["outside"]})


def case_watertight(rays, rng):
    return [watertight_case(name, *make(), rays, rng) for name, make in CLOSED_MESHES.items()]


# --- self-intersection ----------------------------------------------------------------------------

SPAWN_ULPS = float(spawn.SPAWN_ULPS)  # the offset is SPAWN_ULPS * EPS32 * (max|o| + max|p| + t)
SELF_HIT_SHAPES = ("sphere", "uv sphere mesh", "split cube mesh", "quad 2000 sizes wide")
# (object scale, distance of its centre from the world origin): every scale at the origin and as far
# as float32 still resolves the object to 1e-5 of its size with ulps of the distance (D <= 1e5 scale)
SELF_HIT_PLACEMENTS = ((1e-3, 0.0), (1e-3, 1e2), (1.0, 0.0), (1.0, 1e3), (1.0, 1e5), (1e3, 0.0), (1e3, 1e5))
FAR_AWAY = unit([1.0, -0.7, 0.4])


def _self_hit_scene(kind, scale, center):
    if kind == "sphere":
        return make_scene(shapes=[{"type": "sphere", "center": center.tolist(), "radius": scale}])
    if kind == "quad 2000 sizes wide":  # two triangles far larger than the distances rays travel
        v = np.array([[-1e3, 0.0, -1e3], [1e3, 0.0, -1e3], [1e3, 0.0, 1e3], [-1e3, 0.0, 1e3]])
        return make_scene(meshes=[(v * scale + center, [[0, 2, 1], [0, 3, 2]], None)])
    v, f = uv_sphere() if kind == "uv sphere mesh" else split_cube()
    return make_scene(meshes=[(v * scale + center, f, None)])


def _plane_ids(tracer):
    """An id per device triangle, equal for triangles in the same plane (the halves of a quad)."""
    v = tracer.prims.tri_verts
    n = unit(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))
    offset = np.einsum("ij,ij->i", n, v[:, 0]) / max(np.abs(v).max(), 1e-30)
    keys = np.round(np.column_stack([n, offset]) * 1e6)
    return np.unique(keys, axis=0, return_inverse=True)[1].ravel()


def trace_spawned_batch(tracer, origins, directions, shadow_local, ior, offset_scale=1.0):
    """Run ``wrt.kernels.stress.trace_spawned``; returns its outputs as numpy arrays by name."""
    from wrt.kernels.stress import trace_spawned

    n = len(origins)
    names = [
        "hit_t", "hit_prim", "hit_point", "hit_normal", "hit_err",
        "shadow_origin", "shadow_dir", "shadow_hit",
        "reflect_origin", "reflect_dir", "reflect_t", "reflect_prim",
        "refract_origin", "refract_dir", "refract_t", "refract_prim",
    ]  # fmt: skip
    dtype = {"_prim": wp.int32, "_hit": wp.int32, "_point": wp.vec3, "_normal": wp.vec3, "_origin": wp.vec3, "_dir": wp.vec3}
    out = {k: wp.zeros(n, dtype=dtype.get(k[k.rindex("_"):], float), device="cpu") for k in names}
    inputs = [tracer.data, _vec3_array(origins), _vec3_array(directions), _vec3_array(shadow_local), float(ior), float(offset_scale)]
    wp.launch(trace_spawned, dim=n, inputs=inputs + [out[k] for k in names], device="cpu")
    return {k: v.numpy() for k, v in out.items()}


def _self_hit_rays(rng, n, scale, center):
    """Primary rays at an object of size ``scale``: half from 2..10 sizes away aimed at points of a
    ball slightly larger than it (so some graze its silhouette), half from inside it."""
    half = n // 2
    target = center + scale * 1.05 * random_directions(rng, half) * rng.random((half, 1)) ** (1 / 3)
    outside = target - scale * rng.uniform(2.0, 10.0, (half, 1)) * random_directions(rng, half)
    inside = center + scale * 0.9 * random_directions(rng, n - half) * rng.random((n - half, 1)) ** (1 / 3)
    origins = np.vstack([outside, inside])
    directions = np.vstack([unit(target - outside), random_directions(rng, n - half)])
    # shadow directions in the hit's frame: cos(theta) log-uniform in [1e-5, 1] (many graze the surface)
    cos = 10.0 ** rng.uniform(-5.0, 0.0, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    sin = np.sqrt(1.0 - cos**2)
    shadow_local = np.column_stack([sin * np.cos(phi), sin * np.sin(phi), cos])
    return origins, directions, shadow_local


def _sphere_far_root(o, w, c, r):
    """Exit distance (float64) of unit rays ``o + t w`` starting inside the sphere (c, r)."""
    f = o - c
    b = np.einsum("ij,ij->i", w, f)
    cc = np.einsum("ij,ij->i", f, f) - r * r
    q = np.sqrt(np.maximum(b * b - cc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(b <= 0.0, q - b, -cc / (q + b))


def _inside_convex_mesh(tracer, points):
    """Whether each point is strictly inside every face plane of the convex mesh (float64)."""
    v = tracer.prims.tri_verts.astype(np.float32).astype(np.float64)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    offset = np.einsum("ij,ij->i", n, v[:, 0])
    return np.array([bool(np.all(n @ x < offset)) for x in points], dtype=bool)


def self_hit_check(kind, tracer, center, scale, out, plane_id=None):
    """Count the secondary rays that fall back onto the surface they leave, and those that escape.

    The objects are convex with outward normals, or a flat quad, so the rule is exact. A ray
    leaving a flat quad hits nothing (it cannot cross its plane twice). A ray leaving outward
    (direction . outward normal > 0) hits nothing. A ray leaving inward must start inside the
    object and reach the far side: on a sphere, a spawned origin outside it (float64, against the
    float32 sphere) or a hit before half the float64 exit distance is a failure; on a mesh, a hit
    in the plane it leaves is a false self-hit, and a miss is an escape unless the spawned origin
    lies outside another face's plane (a hit within rounding of an edge: the ray may rightly leave
    through the neighbouring face; counted as ``edge_exits``, not judged).
    A first hit farther from the surface than the offset's bound (``SPAWN_ULPS``) counts as a
    false self-hit too. Returns (secondary rays judged, false self-hits, escapes, edge exits,
    worst hit-point error in units of EPS32 (max|o| + max|p| + t)).
    """
    hit = out["hit_prim"] != NO_HIT
    p = out["hit_point"][hit].astype(np.float64)
    n_out = out["hit_normal"][hit].astype(np.float64)
    t = out["hit_t"][hit].astype(np.float64)
    o = out["origins"][hit]
    err_unit = EPS32 * (np.abs(o).max(axis=1) + np.abs(p).max(axis=1) + t)
    if kind == "sphere":
        c, r = f32(center), float(np.float32(scale))
        distance = np.linalg.norm(p - c, axis=1) - r
    else:
        tri = tracer.triangles(out["hit_prim"][hit])
        normal = unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
        distance = np.einsum("ij,ij->i", normal, p - tri[:, 0])
    point_error = np.abs(distance) / err_unit
    worst_point_error = float(point_error.max()) if hit.any() else 0.0
    judged, false_hits, escapes, edge_exits = 0, int(np.count_nonzero(point_error > SPAWN_ULPS)), 0, 0
    for ray in ("shadow", "reflect", "refract"):
        prim = out["shadow_hit" if ray == "shadow" else f"{ray}_prim"][hit]
        traced = prim != -2
        judged += int(np.count_nonzero(traced))
        o2 = out[f"{ray}_origin"][hit].astype(np.float64)
        w = out[f"{ray}_dir"][hit].astype(np.float64)
        outward = traced & (np.einsum("ij,ij->i", w, n_out) > 0.0)
        inward = traced & ~outward
        landed = (prim == 1) if ray == "shadow" else (prim >= 0)
        if kind.startswith("quad"):
            false_hits += int(np.count_nonzero(traced & landed))
            continue
        false_hits += int(np.count_nonzero(outward & landed))
        if kind == "sphere":
            outside = np.linalg.norm(o2 - c, axis=1) >= r
            false_hits += int(np.count_nonzero(inward & outside))
            escapes += int(np.count_nonzero(inward & ~outside & ~landed))
            if ray != "shadow":
                t_exit = _sphere_far_root(o2, w, c, r)
                t2 = out[f"{ray}_t"][hit].astype(np.float64)
                false_hits += int(np.count_nonzero(inward & ~outside & landed & (t2 < 0.5 * t_exit)))
        else:
            if ray != "shadow":
                left = plane_id[out["hit_prim"][hit] >> 2]
                arrived = plane_id[np.where(prim >= 0, prim, 0) >> 2]
                false_hits += int(np.count_nonzero(inward & landed & (arrived == left)))
            missed = np.flatnonzero(inward & ~landed)
            inside = _inside_convex_mesh(tracer, o2[missed])
            escapes += int(np.count_nonzero(inside))
            edge_exits += int(np.count_nonzero(~inside))
    return judged, false_hits, escapes, edge_exits, worst_point_error


def self_intersection(kind, rays, rng, offset_scales=(1.0,)):
    """Secondary rays from spheres or meshes at every scale and distance of ``SELF_HIT_PLACEMENTS``.

    Returns ``{offset_scale: (judged, false hits, escapes, edge exits)}`` and the worst hit-point
    error. Offsets other than the renderer's (scale 1) are probed with the first 1/8 of the rays.
    """
    n = max(rays // len(SELF_HIT_PLACEMENTS), 2)
    totals = {s: [0, 0, 0, 0] for s in offset_scales}
    worst = 0.0
    for scale, distance in SELF_HIT_PLACEMENTS:
        center = distance * FAR_AWAY
        tracer = Tracer(_self_hit_scene(kind, scale, center))
        plane_id = None if kind == "sphere" else _plane_ids(tracer)
        origins, directions, shadow_local = _self_hit_rays(rng, n, scale, center)
        for s in offset_scales:
            m = n if s == 1.0 else max(n // 8, 2)  # the smaller offsets are probed with 1/8 of the rays
            out = trace_spawned_batch(tracer, origins[:m], directions[:m], shadow_local[:m], ior=1.5, offset_scale=s)
            out["origins"] = f32(origins[:m])
            *counts, point_error = self_hit_check(kind, tracer, center, scale, out, plane_id)
            totals[s] = [a + b for a, b in zip(totals[s], counts)]
            worst = max(worst, point_error)
    return totals, worst


# fractions of the renderer's offset tried to find the smallest one that suffices
OFFSET_SWEEP = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.0)


def case_self_intersection(rays, rng):
    """One row per shape: failures are false self-hits and escapes with the renderer's offset;
    ``worst`` is the worst distance of a computed hit point from the float32 surface, in the units
    of the offset (EPS32 (max|o| + max|p| + t)), against the offset's SPAWN_ULPS."""
    results = []
    for kind in SELF_HIT_SHAPES:
        totals, worst = self_intersection(kind, rays, rng, OFFSET_SWEEP)
        judged, false_hits, escapes, edge_exits = totals[1.0]
        enough = [s for s in OFFSET_SWEEP if all(sum(totals[x][1:3]) == 0 for x in OFFSET_SWEEP if x >= s)]
        needed = min(enough) * SPAWN_ULPS if enough else math.inf
        detail = {
            "false_self_hits": false_hits,
            "escapes": escapes,
            "edge_exits_not_judged": edge_exits,
            "offset_used_ulps": SPAWN_ULPS,
            "smallest_offset_tried_without_failures_ulps": needed,
            "failures_by_offset_ulps": {f"{s * SPAWN_ULPS:g}": sum(totals[s][1:3]) for s in OFFSET_SWEEP},
            "worst_hit_point_error_ulps": worst,
        }
        results.append(CaseResult(f"self-intersection: {kind}", judged, false_hits + escapes, worst, SPAWN_ULPS, "ulps", detail))
    return results


# --- precision against float64 ---------------------------------------------------------------------


def sphere_t64(o, d, c, r):
    """Nearest positive root (float64) of rays ``o + t d`` against the sphere (c, r), inf on a miss,
    and the ray's distance from the centre. Inputs are float64 copies of the float32 values."""
    f = o - c
    a = np.einsum("ij,ij->i", d, d)
    b = np.einsum("ij,ij->i", f, d)
    g = f - (b / a)[:, None] * d
    gg = np.einsum("ij,ij->i", g, g)
    disc = a * (r * r - gg)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -b - np.copysign(np.sqrt(np.maximum(disc, 0.0)), b)
        t0, t1 = (np.einsum("ij,ij->i", f, f) - r * r) / q, q / a
    near, far = np.minimum(t0, t1), np.maximum(t0, t1)
    t = np.where(near > 0, near, np.where(far > 0, far, np.inf))
    return np.where(disc >= 0, t, np.inf), np.sqrt(gg / a) * np.sqrt(a)


SPHERE_C = 4.0  # |t32 - t64| <= SPHERE_C * EPS32 * (|o - c| + kappa t), see sphere_error_scale
SPHERE_BAND = 2.0  # hit/miss may differ from float64 only within SPHERE_BAND * EPS32 |o - c| of the silhouette


def sphere_error_scale(t, h, r, f):
    """``|o - c| + kappa t``: what the sphere root's error is proportional to (in EPS32 units).

    ``|o - c|`` carries the rounding of the ray origin relative to the centre (it dominates for
    origins near the surface, where ``t`` is small); ``kappa t`` with
    ``kappa = r / sqrt(r^2 - h^2)`` (``h`` the ray's distance from the centre) the square root's
    sensitivity toward the silhouette, capped at ``sqrt(r |o - c| / EPS32)``: the error of a
    square root of a discriminant that is itself rounding noise.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        graze = t * r / np.sqrt(np.maximum(r * r - h * h, 0.0))
    return f + np.minimum(graze, np.sqrt(r * f / EPS32))


def judge_spheres(t32, prim, o, d, c, r):
    """Compare kernel ``t`` with the float64 root. Returns (relative error in ulps of hits both
    found, its ratio to the bound, hit/miss disagreements outside the band, worst disagreement
    in units of EPS32 |o - c|)."""
    t64, h = sphere_t64(o, d, c, r)
    f = np.linalg.norm(o - c, axis=1)
    both = (prim != NO_HIT) & np.isfinite(t64)
    error = np.abs(t32[both] - t64[both])
    rel = error / t64[both] / EPS32
    ratio = error / (SPHERE_C * EPS32 * sphere_error_scale(t64[both], h[both], r, f[both]))
    differ = (prim != NO_HIT) != np.isfinite(t64)
    gap = np.abs(h[differ] - r) / (EPS32 * f[differ])
    return rel, ratio, int(np.count_nonzero(gap > SPHERE_BAND)), float(gap.max()) if gap.size else 0.0


SPHERE_RADII = (1e-3, 2.1e-2, 0.37, 1.0, 3.3, 1e2)


def case_sphere_precision(rays, rng):
    """Rays from 1e4 to 1e6 radii away at small and large spheres: half spread over the disc the
    sphere covers, a quarter grazing it from inside the silhouette, a quarter from just outside."""
    rel, ratio, disagree, gap = [], [], 0, 0.0
    n = max(rays // len(SPHERE_RADII), 4)
    for radius in SPHERE_RADII:
        c = rng.normal(size=3) * 3.0 * radius
        w = random_directions(rng, n)
        side = unit(np.cross(w, random_directions(rng, n)))
        u = rng.random(n)
        grazing = 10.0 ** rng.uniform(-9.0, -1.0, n)
        h = radius * np.where(u < 0.5, np.sqrt(rng.random(n)), np.where(u < 0.75, 1.0 - grazing, 1.0 + grazing))
        o = c + h[:, None] * side - (radius * 10.0 ** rng.uniform(4.0, 6.0, n))[:, None] * w
        tracer = Tracer(make_scene(shapes=[{"type": "sphere", "center": c.tolist(), "radius": radius}]))
        t32, prim = tracer.closest(o, w)
        a, b, k, g = judge_spheres(t32, prim, f32(o), f32(w), f32(c), float(np.float32(radius)))
        rel.append(a)
        ratio.append(b)
        disagree += k
        gap = max(gap, g)
    rel, ratio = np.concatenate(rel), np.concatenate(ratio)
    detail = {
        "max_ratio_to_bound": float(ratio.max()),
        "median_ulps": float(np.median(rel)),
        "p99_ulps": float(np.percentile(rel, 99)),
        "hit_miss_disagreements_beyond_band": disagree,
        "worst_disagreement_eps_dist": gap,
        "band_eps_dist": SPHERE_BAND,
    }
    bound = f"{SPHERE_C:g}(|o-c|/t+k) ulps"
    return [CaseResult("sphere precision: 1e4-1e6 radii", n * len(SPHERE_RADII), int(np.count_nonzero(ratio > 1.0)) + disagree, float(rel.max()), bound, "ulps", detail)]


TRIANGLE_C = 1.0  # |t32 - t64| <= TRIANGLE_C ulp(t): t is computed in float64 and rounded once
TRIANGLE_BAND = 8.0  # hit/miss may differ from float64 within TRIANGLE_BAND EPS32 max|v - o| / |cos| of an edge


def judge_triangle(t32, prim, o, d, v):
    """Compare kernel ``t`` on triangle ``v`` (3, 3) with float64 (inputs: float64 copies of the
    float32 values). Returns (error in ulps of hits both found, its ratio to the bound, |cos| of
    those rays, hit/miss disagreements farther than the band from an edge)."""
    normal = np.cross(v[1] - v[0], v[2] - v[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        t64 = (v[0] - o) @ normal / (d @ normal)
    p = o + t64[:, None] * d
    # signed distance of the float64 hit point to the nearest edge, in the plane (> 0 inside)
    edges = ((v[1], v[2]), (v[2], v[0]), (v[0], v[1]))
    inside = np.min([(p - a) @ unit(np.cross(normal, b - a)) for a, b in edges], axis=0)
    cos = np.abs(d @ normal) / np.linalg.norm(normal) / np.linalg.norm(d, axis=1)
    span = np.abs(v[None] - o[:, None]).max(axis=(1, 2))
    band = TRIANGLE_BAND * EPS32 * span / np.maximum(cos, 1e-30)
    hit = prim != NO_HIT
    expected = (inside >= 0) & (t64 > 0)
    disagree = int(np.count_nonzero((hit != expected) & (np.abs(inside) > band)))
    both = hit & expected
    ulps = np.abs(t32[both] - t64[both]) / np.spacing(t64[both].astype(np.float32)).astype(np.float64)
    return ulps, ulps / TRIANGLE_C, cos[both], disagree


def case_ulps(rays, rng):
    """float32 kernel t against float64 on random rays: random triangles and spheres of sizes
    1e-2..1e2 placed up to 3 sizes from the origin, rays from 0.1 to 100 sizes away aimed at them."""
    n = max(rays // 32, 4)
    results = []
    tri_err, tri_norm, tri_cos, tri_disagree = [], [], [], 0
    for _ in range(16):
        size = 10.0 ** rng.uniform(-2.0, 2.0)
        v = rng.normal(size=(3, 3)) * size + rng.normal(size=3) * 3.0 * size
        tracer = Tracer(make_scene(shapes=[{"type": "triangle", "vertices": v.tolist()}]))
        bary = rng.random((n, 3))
        bary /= bary.sum(axis=1, keepdims=True)
        target = bary @ v
        o = target - random_directions(rng, n) * (size * 10.0 ** rng.uniform(-1.0, 2.0, n))[:, None]
        d = unit(target - o)
        t32, prim = tracer.closest(o, d)
        ulps, ratio, cos, disagree = judge_triangle(t32, prim, f32(o), f32(d), f32(v))
        tri_err.append(ulps)
        tri_norm.append(ratio)
        tri_cos.append(cos)
        tri_disagree += disagree
    err, ratio, cos = np.concatenate(tri_err), np.concatenate(tri_norm), np.concatenate(tri_cos)
    results.append(_ulps_result("t vs float64: triangles", 16 * n, err, ratio, tri_disagree, TRIANGLE_C, {"max_ulps_cos_above_0.1": float(err[cos > 0.1].max())}))
    sph_err, sph_ratio, sph_disagree = [], [], 0
    for _ in range(16):
        radius = 10.0 ** rng.uniform(-2.0, 2.0)
        c = rng.normal(size=3) * 3.0 * radius
        tracer = Tracer(make_scene(shapes=[{"type": "sphere", "center": c.tolist(), "radius": radius}]))
        target = c + 1.1 * radius * random_directions(rng, n) * rng.random((n, 1)) ** (1 / 3)
        o = target - random_directions(rng, n) * (radius * 10.0 ** rng.uniform(0.3, 2.0, n))[:, None]
        d = unit(target - o)
        t32, prim = tracer.closest(o, d)
        rel, ratio, k, _ = judge_spheres(t32, prim, f32(o), f32(d), f32(c), float(np.float32(radius)))
        sph_err.append(rel)
        sph_ratio.append(ratio)
        sph_disagree += k
    err, ratio = np.concatenate(sph_err), np.concatenate(sph_ratio)
    results.append(_ulps_result("t vs float64: spheres", 16 * n, err, ratio, sph_disagree, f"{SPHERE_C:g}(|o-c|/t+k) ulps", {}))
    return results


def _ulps_result(name, rays, err, ratio, disagree, bound, extra):
    pct = np.percentile(err, [50, 90, 99, 99.9]) if err.size else [0.0] * 4
    detail = {"median_ulps": float(pct[0]), "p90_ulps": float(pct[1]), "p99_ulps": float(pct[2]), "p99.9_ulps": float(pct[3]), "max_ratio_to_bound": float(ratio.max()), "hit_miss_disagreements_beyond_band": disagree, **extra}
    return CaseResult(name, rays, int(np.count_nonzero(ratio > 1.0)) + disagree, float(err.max()), bound, "ulps", detail)


# --- grazing and degenerate geometry ----------------------------------------------------------------


def _not_finite_t(t):
    """t values a kernel must never return: NaN, -inf, or <= 0 (t is in (t_min, t_max] = (0, inf])."""
    return np.isnan(t) | (t <= 0.0)


def _signed_zero_directions(rng, n, axes_zero):
    """Unit directions with the components in ``axes_zero`` exactly +0.0 or -0.0 (random sign)."""
    d = random_directions(rng, n)
    for k in axes_zero:
        d[:, k] = np.where(rng.random(n) < 0.5, 0.0, -0.0)
    return unit(d) if len(axes_zero) < 3 else d


def case_plane_grazing(rays, rng):
    """Rays parallel to a plane (in it, just above, just below), with +0.0 and -0.0 normal
    components, must miss it; rays at 1e-30..1e-45 (denormal) to it must hit far away or miss,
    never return NaN. The plane is an infinite ``plane`` and, edge-on, a triangle and a polygon."""
    n = max(rays // 8, 8)
    shapes = [
        {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0]},
        {"type": "triangle", "vertices": [[-5.0, 0.0, -5.0], [5.0, 0.0, -5.0], [0.0, 0.0, 5.0]]},
        {"type": "polygon", "vertices": [[-3.0, 0.0, -3.0], [3.0, 0.0, -3.0], [3.0, 0.0, 3.0], [-3.0, 0.0, 3.0]]},
    ]
    failures, shot, nan = 0, 0, 0
    for shape in shapes:
        tracer = Tracer(make_scene(shapes=[shape]))
        height = rng.choice([0.0, -0.0, 1e-30, -1e-30, 1e-7, -1e-7, 1.0], n)
        o = np.column_stack([rng.uniform(-2, 2, n), height, rng.uniform(-2, 2, n)])
        d = _signed_zero_directions(rng, n, [1])
        t, prim = tracer.closest(o, d)
        hit_any = tracer.occluded(o, d)
        nan += int(np.count_nonzero(np.isnan(t)))
        failures += int(np.count_nonzero((prim != NO_HIT) | hit_any | _not_finite_t(t)))
        # nearly parallel: tiny (down to denormal) normal components, from 1 above the plane
        dy = -rng.choice([1e-30, 1e-38, 1e-40, 1e-45, 1e-20, 1e-7], n)
        d2 = np.column_stack([rng.normal(size=n), np.zeros(n), rng.normal(size=n)])
        d2 = unit(d2)
        d2[:, 1] = dy
        o2 = o.copy()
        o2[:, 1] = 1.0
        t2, prim2 = tracer.closest(o2, d2)
        nan += int(np.count_nonzero(np.isnan(t2)))
        failures += int(np.count_nonzero(_not_finite_t(t2) | ((prim2 != NO_HIT) & (t2 < 0.5 / np.abs(f32(dy))))))
        shot += 2 * n
    return [CaseResult("grazing: rays along planes", shot, failures, unit="rays", detail={"nan_t": nan})]


def _distance_to_segment(p, a, b):
    ab = b - a
    length2 = float(ab @ ab)
    s = np.clip(((p - a) @ ab) / length2, 0.0, 1.0) if length2 > 0 else np.zeros(len(p))
    return np.linalg.norm(p - (a + s[:, None] * ab), axis=1)


def case_degenerate_triangles(rays, rng):
    """Zero-area triangles (a point, collinear vertices, a repeated vertex): hit, if ever, only
    on their point or segment (within 16 EPS32 max|v - o|, from rays aimed at it or 1e-4 beside
    it); a needle triangle 1e-6 wide is hit and missed where float64 says (rays aimed inside it and
    1e-5 beside it; the triangle bounds of ``case_ulps``); no NaN."""
    n = max(rays // 8, 8)
    failures, shot, degenerate_hits = 0, 0, 0
    degenerate = [
        [[0.3, 0.2, 0.0]] * 3,
        [[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [2.0, 1.0, 0.0]],
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
    ]
    for vertices in degenerate:
        tracer = Tracer(make_scene(shapes=[{"type": "triangle", "vertices": vertices}]))
        v = f32(vertices)
        target = v[0] + rng.random((n, 1)) * (v[2] - v[0])  # on the segment (or the point)
        target[n // 2 :] += random_directions(rng, n - n // 2) * 1e-4  # and beside it
        o = target + random_directions(rng, n) * rng.uniform(0.5, 5.0, (n, 1))
        d = unit(target - o)
        t, prim = tracer.closest(o, d)
        hit = prim != NO_HIT
        p = f32(o[hit]) + t[hit, None].astype(np.float64) * f32(d[hit])
        tolerance = 16.0 * EPS32 * np.abs(v[None] - f32(o[hit])[:, None]).max(axis=(1, 2))
        off = _distance_to_segment(p, v[0], v[2]) > tolerance
        degenerate_hits += int(np.count_nonzero(hit))
        failures += int(np.count_nonzero(off)) + int(np.count_nonzero(np.isnan(t)))
        shot += n
    needle = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1e-6, 0.0]])
    tracer = Tracer(make_scene(shapes=[{"type": "triangle", "vertices": needle.tolist()}]))
    x = rng.uniform(0.05, 0.95, n)
    width = 1e-6 * (1.0 - np.abs(2.0 * x - 1.0))  # height of the needle at x
    y = np.where(rng.random(n) < 0.5, width * rng.uniform(0.2, 0.8, n), np.where(rng.random(n) < 0.5, -1e-5, width + 1e-5))
    target = np.column_stack([x, y, np.zeros(n)])
    o = target + np.column_stack([rng.normal(size=(n, 2)) * 0.3, rng.uniform(0.5, 3.0, n)])
    d = unit(target - o)
    t, prim = tracer.closest(o, d)
    ulps, ratio, _, disagree = judge_triangle(t, prim, f32(o), f32(d), f32(needle))
    failures += disagree + int(np.count_nonzero(ratio > 1.0)) + int(np.count_nonzero(np.isnan(t)))
    shot += n
    worst = float(ulps.max()) if ulps.size else 0.0
    detail = {"zero_area_hits_on_their_segment": degenerate_hits}
    return [CaseResult("degenerate: zero-area and needle triangles", shot, failures, worst, TRIANGLE_C, "ulps", detail)]


def case_zero_radius_sphere(rays, rng):
    """Spheres of radius 0 and 1e-30 (not loadable: built directly): no NaN, no t <= 0, and a hit
    only at the centre's distance; the BVH over a zero-size box agrees with brute force."""
    from wrt.scene import Sphere

    n = max(rays // 4, 8)
    failures, shot = 0, 0
    for radius in (0.0, 1e-30):
        scene = make_scene(shapes=[{"type": "sphere", "center": [0.5, -0.25, 1.0], "radius": 1.0}, {"type": "sphere", "center": [3.0, 0.0, 0.0], "radius": 0.5}])
        scene = dataclasses.replace(scene, shapes=(Sphere(center=(0.5, -0.25, 1.0), radius=radius, material=0), scene.shapes[1]))
        tracer = Tracer(scene)
        c = np.array([0.5, -0.25, 1.0])
        o = c + random_directions(rng, n) * rng.uniform(0.1, 10.0, (n, 1))
        aim = np.where(rng.random((n, 1)) < 0.5, c, c + rng.normal(size=(n, 3)) * 1e-6)
        d = unit(aim - o)
        d[: n // 8] = 0.0  # zero directions too
        t, prim = tracer.closest(o, d)
        tb, primb = tracer.closest(o, d, brute_force=True)
        dist = np.linalg.norm(f32(o) - c, axis=1)
        small = (prim >> 2 == 0) & ((prim & 3) == 0) & (prim != NO_HIT)
        failures += int(np.count_nonzero(_not_finite_t(t) | (small & (np.abs(t - dist) > 1e-5 * dist)) | (t != tb) | (prim != primb)))
        shot += n
    return [CaseResult("degenerate: zero-radius spheres", shot, failures, unit="rays")]


def case_coincident(rays, rng):
    """Coincident surfaces (z-fighting): a triangle twice, a sphere twice, a triangle in a plane,
    a closed mesh twice. Every ray that hits the single surface hits one of the copies, at the
    single surface's t (same function: bit-identical; plane vs triangle: within 4 ulps)."""
    n = max(rays // 8, 8)
    tri = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]]
    v, f = split_cube(4)
    setups = [
        ("triangle x2", [{"type": "triangle", "vertices": tri}] * 2, [], 0.0),
        ("sphere x2", [{"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0}] * 2, [], 0.0),
        ("triangle in plane", [{"type": "triangle", "vertices": tri}, {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}], [], 4.0),
        ("mesh x2", [], [(v, f, None), (v, f, None)], 0.0),
    ]
    failures, shot, worst = 0, 0, 0.0
    for _, shapes, meshes, tolerance in setups:
        single = Tracer(make_scene(shapes=shapes[:1], meshes=meshes[:1]))
        double = Tracer(make_scene(shapes=shapes, meshes=meshes))
        target = rng.uniform(-1.0, 1.0, (n, 3)) * [1.0, 1.0, 0.0]
        o = target + random_directions(rng, n) * rng.uniform(1.5, 5.0, (n, 1))
        d = unit(target - o)
        t1, p1 = single.closest(o, d)
        t2, p2 = double.closest(o, d)
        hit = p1 != NO_HIT
        ulps = np.abs(t2[hit] - t1[hit]) / np.spacing(t1[hit])
        worst = max(worst, float(ulps.max()) if ulps.size else 0.0)
        failures += int(np.count_nonzero(hit & (p2 == NO_HIT))) + int(np.count_nonzero(ulps > tolerance)) + int(np.count_nonzero(np.isnan(t2)))
        shot += n
    return [CaseResult("coincident surfaces (z-fighting)", shot, failures, worst, 4.0, "ulps")]


def case_zero_components(rays, rng):
    """Unit directions with +0.0, -0.0, denormal (1e-40) and tiny components, from origins exactly on
    BVH box planes: the BVH's slab test must never cull what brute force hits (same t; the
    primitive may differ only on a tie), any-hit agrees, no NaN. A ray tangent to a sphere within
    the sphere test's rounding (|h - r| <= SPHERE_BAND EPS32 |o - c|) may go either way. Scene: a split cube, spheres and triangles in a BVH."""
    n = max(rays // 4, 16)
    v, f = split_cube(4)
    scene = make_scene(
        shapes=[
            {"type": "sphere", "center": [3.0, 0.0, 0.0], "radius": 1.0},
            {"type": "sphere", "center": [-3.0, 1.0, 0.0], "radius": 0.5},
            {"type": "triangle", "vertices": [[0.0, 3.0, -1.0], [1.0, 3.0, 1.0], [-1.0, 3.0, 1.0]]},
        ],
        meshes=[(v, f, None)],
    )
    tracer = Tracer(scene)
    lo, hi = lane_bounds(tracer.prims.bvh.nodes.numpy())
    used = np.isfinite(lo[..., 0])
    planes = np.concatenate([lo[used], hi[used]]).astype(np.float64)  # origins on the planes of every box in the BVH
    o = rng.uniform(-4.0, 4.0, (n, 3))
    pick = planes[rng.integers(0, len(planes), n)]
    for k in range(3):
        on = rng.random(n) < 0.5
        o[on, k] = pick[on, k]
    tiny = np.array([0.0, -0.0, 1e-40, -1e-40, 1e-30, -1e-30, 1e-10])
    d = random_directions(rng, n)
    keep = rng.integers(0, 3, n)  # one component stays: the directions are unit vectors
    for k in range(3):
        zero = (rng.random(n) < 0.5) & (keep != k)
        d[zero, k] = rng.choice(tiny, int(zero.sum()))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    axial = rng.random(n) < 0.25  # along an axis, the other two components +-0.0
    d[axial] = np.eye(3)[rng.integers(0, 3, int(axial.sum()))] * rng.choice([-1.0, 1.0], (int(axial.sum()), 1))
    d[axial] = np.where(d[axial] == 0.0, rng.choice([0.0, -0.0], (int(axial.sum()), 3)), d[axial])
    t, prim = tracer.closest(o, d)
    tb, primb = tracer.closest(o, d, brute_force=True)
    hit_any = tracer.occluded(o, d)
    mismatch = (t != tb) | (hit_any != (primb != NO_HIT))  # the primitive may differ on a tie (same t)
    # a ray tangent to a sphere within its test's rounding (SPHERE_BAND) may go either way
    tangent = np.zeros(n, dtype=bool)
    for ref in (prim, primb):
        sphere = mismatch & (ref != NO_HIT) & ((ref & 3) == SPHERE)
        k = ref[sphere] >> 2
        c, r = f32(tracer.prims.sphere_center[k]), f32(tracer.prims.sphere_radius[k])
        f = f32(o[sphere]) - c
        dd = f32(d[sphere])
        h = np.linalg.norm(f - np.einsum("ij,ij->i", f, dd)[:, None] * dd / np.einsum("ij,ij->i", dd, dd)[:, None], axis=1)
        tangent[np.flatnonzero(sphere)[np.abs(h - r) <= SPHERE_BAND * EPS32 * np.linalg.norm(f, axis=1)]] = True
    failures = int(np.count_nonzero((mismatch & ~tangent) | _not_finite_t(t)))
    detail = {"bvh_vs_brute_force_mismatches": int(np.count_nonzero(mismatch & ~tangent)), "sphere_tangent_within_rounding": int(np.count_nonzero(mismatch & tangent))}
    return [CaseResult("zero and -0.0 direction components (BVH)", n, failures, unit="rays", detail=detail)]


# --- refraction and images ---------------------------------------------------------------------------


def render(scene, **overrides):
    """``wrt.render`` of ``scene`` with ``[render]`` keys replaced (validated like the file's)."""
    import wrt
    from wrt.loader import override_render

    return wrt.render(override_render(scene, source="<stress>", **overrides))


def fresnel64(cos_i, eta):
    """Unpolarised Fresnel reflectance (float64, Hecht sec. 4.6) for incidence cosine ``cos_i`` and
    ``eta = n1 / n2``; 1 under total internal reflection."""
    cos_i = np.clip(cos_i, 0.0, 1.0)
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    return np.where(sin2_t >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp))


def count_not_finite(result) -> int:
    """Pixels with NaN or Inf in RGB, normal or position, or NaN depth (depth is +inf on a miss)."""
    bad = ~np.isfinite(result.rgb).all(axis=-1)
    bad |= ~np.isfinite(result.aovs["normal"]).all(axis=-1) | ~np.isfinite(result.aovs["position"]).all(axis=-1)
    bad |= np.isnan(result.aovs["depth"])
    return int(np.count_nonzero(bad))


CRITICAL_IORS = (1.5, 4.0)
ANGLE_SLACK = 4.0 * EPS32  # uncertainty of a pixel's incidence cosine (float32 camera ray, hit point)
VALUE_SLACK = 1e-5  # float32 Fresnel and Snell arithmetic
SLAB_DEPTH = 8  # max_depth of the critical-angle renders


def slab_radiance(cos_i, ior):
    """What the critical-angle scene's pixel must be, float64: ``(1 - F) sum_k F^(2k)``, k < 4.

    The camera ray meets the slab's top face from inside at incidence ``cos_i``; the share 1 - F
    leaves to the background (radiance 1), F is reflected to the bottom face, where 1 - F leaves
    onto a black floor and F comes back up at the same angle (the faces are parallel), and so on:
    the top face is met at segments 1, 3, 5 and 7 of ``SLAB_DEPTH = 8``.
    """
    f = fresnel64(cos_i, ior)
    return (1.0 - f) * sum(f ** (2 * k) for k in range(SLAB_DEPTH // 2))


def critical_angle_case(ior, rng):
    """Camera inside a clear glass slab of ior ``ior`` (1.5 units thick, 2000 wide) over a black
    floor, looking up at the top face across the critical angle, under a background of 1, no
    lights, no throughput cut. Every pixel must equal ``slab_radiance`` of its incidence angle
    (exact float64 Fresnel), within the Fresnel values of angles ``ANGLE_SLACK`` either side, plus
    ``VALUE_SLACK``; past the critical angle that is 0 (total internal reflection all the way).
    Two views: 20 degrees across the critical angle, and 0.02 degrees centred on it (pixels 5e-6
    rad apart)."""
    v, f = split_cube(1)
    slab = (v * [1e3, 0.75, 1e3] + [0.0, 0.25, 0.0], f, "glass")  # x, z in [-1e3, 1e3], y in [-0.5, 1]
    floor = {"type": "plane", "point": [0.0, -0.6, 0.0], "normal": [0.0, 1.0, 0.0], "material": "black"}
    theta_c = math.asin(1.0 / ior)
    worst, failures, pixels, near, bad = 0.0, 0, 0, 0, 0
    for fov, size in ((20.0, (64, 48)), (0.02, (33, 33))):
        scene = make_scene(
            shapes=[floor],
            meshes=[slab],
            materials=[{"name": "glass", "type": "dielectric", "ior": ior}, {"name": "black", "albedo": [0.0, 0.0, 0.0]}],
            camera={"origin": [0.0, 0.0, 0.0], "look_at": [math.sin(theta_c), math.cos(theta_c), 0.0], "up": [0.0, 1.0, 0.0], "fov": fov},
            render={"width": size[0], "height": size[1], "integrator": "whitted", "background": [1.0, 1.0, 1.0], "max_depth": SLAB_DEPTH, "min_throughput": 0.0},
        )
        r = render(scene)
        bad += count_not_finite(r)
        cos_i = unit(r.aovs["position"].astype(np.float64))[..., 1]
        on_top = (r.aovs["object_id"] == 1) & (np.abs(r.aovs["position"][..., 1] - 1.0) < 1e-5)
        one, two = slab_radiance(cos_i + ANGLE_SLACK, ior), slab_radiance(cos_i - ANGLE_SLACK, ior)
        value = r.rgb.astype(np.float64)
        off = np.maximum(np.minimum(one, two)[..., None] - value, value - np.maximum(one, two)[..., None]).max(axis=-1)
        off = np.where(on_top, np.maximum(off, 0.0), np.inf)
        worst = max(worst, float(off.max()))
        failures += int(np.count_nonzero(off > VALUE_SLACK))
        pixels += off.size
        near += int(np.count_nonzero(np.abs(np.arccos(np.clip(cos_i, -1, 1)) - theta_c) < 1e-4))
    detail = {"pixels_within_1e-4_rad_of_critical": near, "not_finite_pixels": bad, "critical_angle_deg": math.degrees(theta_c)}
    return CaseResult(f"refraction at the critical angle: ior {ior:g}", pixels, failures + bad, worst, VALUE_SLACK, "", detail)


def case_critical_angle(rays, rng):
    return [critical_angle_case(ior, rng) for ior in CRITICAL_IORS]


IOR_ONE_PLACEMENTS = (("origin", np.zeros(3)), ("1e4 from origin", np.array([1e4, -1e4, 1e4])))


def ior_one_case(name, offset):
    """Dielectrics of ior 1.0 (a sphere and a closed mesh) are invisible: the whitted image equals
    the same scene without them to 1e-6 (filtered shadows, so light passes them too)."""
    v, f = split_cube(4)
    floor = {"type": "plane", "point": (offset + [0.0, -1.0, 0.0]).tolist(), "normal": [0.0, 1.0, 0.0], "material": "floor"}
    ghost = {"type": "sphere", "center": (offset + [0.3, 0.0, 0.0]).tolist(), "radius": 0.8, "material": "ghost"}
    common = {
        "materials": [{"name": "floor", "albedo": [0.5, 0.5, 0.5]}, {"name": "ghost", "type": "dielectric", "ior": 1.0}],
        "lights": [{"type": "point", "position": (offset + [1.0, 3.0, 2.0]).tolist(), "intensity": [10.0, 10.0, 10.0]}],
        "camera": {"origin": (offset + [0.0, 1.0, 4.0]).tolist(), "look_at": offset.tolist()},
        "render": {"width": 64, "height": 48, "integrator": "whitted", "dielectric_shadows": "filtered", "background": [0.1, 0.2, 0.3]},
    }
    with_ghosts = render(make_scene(shapes=[floor, ghost], meshes=[(v * 0.4 + offset + [-0.9, -0.2, 0.5], f, "ghost")], **common))
    without = render(make_scene(shapes=[floor], **common))
    diff = np.abs(with_ghosts.rgb.astype(np.float64) - without.rgb).max(axis=-1)
    diff[np.isnan(diff)] = np.inf
    detail = {"pixels_through_ghosts": int(np.count_nonzero(with_ghosts.aovs["object_id"] >= 1))}
    return CaseResult(f"refraction: ior 1.0 is invisible ({name})", diff.size, int(np.count_nonzero(diff > 1e-6)), float(diff.max()), 1e-6, "", detail)


def case_ior_one(rays, rng):
    return [ior_one_case(name, offset) for name, offset in IOR_ONE_PLACEMENTS]


FURNACE_SCENES = {
    "two spheres": [
        {"type": "sphere", "center": [-0.6, 0.0, 0.0], "radius": 0.5, "material": "glass"},
        {"type": "sphere", "center": [0.6, 0.0, 0.0], "radius": 0.5, "material": "glass"},
    ],
    "air bubble in a sphere": [
        {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 0.5, "material": "glass"},
        {"type": "sphere", "center": [0.0, 0.1, 0.0], "radius": 0.2, "material": "air"},
    ],
}


def _furnace(shapes, max_depth):
    scene = make_scene(
        shapes=shapes,
        materials=[{"name": "glass", "type": "dielectric", "ior": 4.0}, {"name": "air", "type": "dielectric", "ior": 1.0}],
        camera={"origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 40},
        render={"width": 64, "height": 48, "integrator": "whitted", "background": [1.0, 1.0, 1.0], "max_depth": max_depth, "min_throughput": 1e-6},
    )
    return render(scene)


def furnace_case(name, shapes):
    """Clear glass of ior 4.0 under a uniform background of 1, no lights: energy is only
    redistributed, so no pixel exceeds 1 + 1e-5, and none falls below 1 - 1e-3 (what the tree's
    cuts may drop: 48 segments, branches under 1e-6) except at the silhouette (first hit at
    |cos| < 0.05), where entering light meets the far side just under the critical angle and leaks
    out over more bounces than the tree keeps (bound 2e-2 there)."""
    r = _furnace(shapes, 48)
    rgb = r.rgb.astype(np.float64).min(axis=-1)
    view = unit(r.aovs["position"].astype(np.float64) - [0.0, 0.0, 3.0])
    cos = np.abs(np.einsum("...k,...k->...", view, r.aovs["normal"]))
    silhouette = (r.aovs["object_id"] >= 0) & (cos < 0.05)
    low = np.where(silhouette, rgb < 1.0 - 2e-2, rgb < 1.0 - 1e-3)
    failures = count_not_finite(r) + int(np.count_nonzero(low | (r.rgb.max(axis=-1) > 1.0 + 1e-5)))
    loss = 1.0 - rgb
    detail = {
        "worst_loss_at_silhouette": float(loss[silhouette].max()) if silhouette.any() else 0.0,
        "pixels_losing_over_1e-3": int(np.count_nonzero(loss > 1e-3)),
        "max_pixel": float(r.rgb.max()),
        "glass_pixels": int(np.count_nonzero(r.aovs["object_id"] >= 0)),
    }
    return CaseResult(f"refraction: ior 4.0 furnace, {name}", rgb.size, failures, float(loss[~silhouette].max()), 1e-3, "", detail)


def trapped_light_case(name, shapes):
    """Light trapped by total internal reflection (an air bubble in ior-4 glass: critical angle
    14.5 degrees at both walls) escapes over hundreds of bounces, so a whitted tree cut at a
    finite max_depth loses part of it: that is the depth cut, not a leak. Checked: no pixel above
    1 + 1e-5, no NaN, and the loss shrinks as max_depth grows (48 -> 400)."""
    shallow, deep = _furnace(shapes, 48), _furnace(shapes, 400)
    loss_shallow = 1.0 - shallow.rgb.astype(np.float64).min(axis=-1)
    loss_deep = 1.0 - deep.rgb.astype(np.float64).min(axis=-1)
    failures = count_not_finite(shallow) + count_not_finite(deep)
    failures += int(np.count_nonzero(np.maximum(shallow.rgb, deep.rgb).max(axis=-1) > 1.0 + 1e-5))
    failures += int(not loss_deep.sum() < loss_shallow.sum())
    detail = {
        "total_loss_depth_48": float(loss_shallow.sum()),
        "total_loss_depth_400": float(loss_deep.sum()),
        "pixels_losing_over_1e-3_depth_48": int(np.count_nonzero(loss_shallow > 1e-3)),
        "pixels_losing_over_1e-3_depth_400": int(np.count_nonzero(loss_deep > 1e-3)),
        "max_pixel": float(max(shallow.rgb.max(), deep.rgb.max())),
    }
    return CaseResult(f"refraction: ior 4.0 furnace, {name}", loss_shallow.size, failures, float(loss_deep.max()), 1.0, "", detail)


def case_high_ior_furnace(rays, rng):
    return [furnace_case("two spheres", FURNACE_SCENES["two spheres"]), trapped_light_case("air bubble in a sphere", FURNACE_SCENES["air bubble in a sphere"])]


def _adversarial_scenes():
    """Scenes for the NaN/Inf sweep: (name, scene). Odd image sizes put a pixel centre exactly on
    the view axis, so axis-aligned cameras shoot rays with +-0.0 components."""
    from wrt.scene import Sphere

    ball, ball_faces = uv_sphere(32, 16)
    box, box_faces = split_cube(4)
    mats = [
        {"name": "d", "albedo": [0.5, 0.5, 0.5]},
        {"name": "glass", "type": "dielectric", "ior": 1.5, "transmittance": [0.8, 0.9, 1.0]},
        {"name": "dense", "type": "dielectric", "ior": 4.0},
        {"name": "mirror", "type": "mirror"},
        {"name": "shiny", "type": "phong", "albedo": [0.3, 0.3, 0.3], "specular": [0.6, 0.6, 0.6], "exponent": 1e6},
        {"name": "lamp", "albedo": [0.0, 0.0, 0.0], "emission": [2.0, 2.0, 2.0]},
    ]
    lights = [
        {"type": "point", "position": [0.0, 0.5, 0.0], "intensity": [5.0, 5.0, 5.0]},
        {"type": "directional", "direction": [0.0, -1.0, 0.0], "irradiance": [1.0, 1.0, 1.0]},
        {"type": "spot", "position": [0.0, 0.0, 3.0], "direction": [0.0, 0.0, -1.0], "intensity": [3.0, 3.0, 3.0], "cutoff_angle": 90.0, "beam_width": 0.0},
    ]
    axis_camera = {"origin": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]}
    degenerate = make_scene(
        shapes=[
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "material": "shiny"},  # radius 0 below
            {"type": "triangle", "vertices": [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1e-6, 0.0]], "material": "mirror"},
            {"type": "triangle", "vertices": [[0.0, -1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "material": "glass"},
            {"type": "triangle", "vertices": [[-2.0, -2.0, -1.0], [2.0, -2.0, -1.0], [0.0, 2.0, -1.0]], "material": "d"},
            {"type": "triangle", "vertices": [[-2.0, -2.0, -1.0], [2.0, -2.0, -1.0], [0.0, 2.0, -1.0]], "material": "mirror"},
            {"type": "plane", "point": [0.0, 0.0, -1.0], "normal": [0.0, 0.0, 1.0], "material": "lamp"},
            {"type": "plane", "point": [0.0, -1.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "glass"},
        ],
        materials=mats,
        lights=lights,
        camera=axis_camera,
    )
    degenerate = dataclasses.replace(degenerate, shapes=(Sphere(center=(0.0, 0.0, 0.0), radius=0.0, material=degenerate.shapes[0].material), *degenerate.shapes[1:]))
    far = np.array([1e5, -1e5, 1e5])
    return [
        ("degenerate primitives, axis camera", degenerate),
        ("camera inside a diffuse mesh", make_scene(meshes=[(ball, ball_faces, "d")], materials=mats, lights=lights[:1], camera={"origin": [0.1, 0.2, 0.3], "look_at": [0.0, 0.0, -1.0]})),
        ("camera inside a glass mesh", make_scene(shapes=[{"type": "plane", "point": [0.0, -3.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "mirror"}], meshes=[(box, box_faces, "glass")], materials=mats, lights=lights, camera={"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0]})),
        ("camera in a plane, looking along it", make_scene(shapes=[{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "shiny"}, {"type": "sphere", "center": [0.0, 0.0, -3.0], "radius": 1.0, "material": "dense"}], materials=mats, lights=lights, camera={"origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0]})),
        ("dense glass and mirrors 1e5 from the origin", make_scene(
            shapes=[
                {"type": "sphere", "center": far.tolist(), "radius": 1.0, "material": "dense"},
                {"type": "plane", "point": (far + [0.0, -1.0, 0.0]).tolist(), "normal": [0.0, 1.0, 0.0], "material": "mirror"},
            ],
            meshes=[(box * 0.5 + far + [2.0, 0.0, 0.0], box_faces, "glass")],
            materials=mats,
            lights=[{"type": "point", "position": (far + [0.0, 3.0, 2.0]).tolist(), "intensity": [10.0, 10.0, 10.0]}],
            camera={"origin": (far + [0.0, 0.5, 5.0]).tolist(), "look_at": far.tolist()},
        )),
    ]


def case_not_finite(rays, rng):
    """No NaN or Inf in any output (RGB, normal, position; depth NaN) of either integrator, at 1
    and 4 spp, across adversarial scenes: degenerate primitives (zero-radius sphere, needle,
    edge-on and coincident triangles) seen along an axis, cameras inside closed meshes (diffuse and
    glass), a camera in a plane, ior 4 glass and mirrors 1e5 from the origin."""
    bad, pixels, by_scene = 0, 0, {}
    for name, scene in _adversarial_scenes():
        for integrator in ("raycast", "whitted"):
            for spp in (1, 4):
                r = render(scene, width=41, height=31, spp=spp, integrator=integrator, max_depth=12)
                count = count_not_finite(r)
                bad += count
                pixels += r.rgb.shape[0] * r.rgb.shape[1] * spp
                by_scene[name] = by_scene.get(name, 0) + count
    return [CaseResult("no NaN/Inf in integrator outputs", pixels, bad, unit="pixels", detail={"not_finite_pixels": bad, **{f"[{k}]": v for k, v in by_scene.items()}})]


def case_camera_inside(rays, rng):
    """A camera inside a closed mesh (the tessellated sphere, the split cube, the fan) sees the mesh
    in every pixel: raycast, 1 spp, 63 x 47 (no pixel may leak to the background)."""
    shot, leaks = 0, 0
    for name, make in CLOSED_MESHES.items():
        v, f = make()
        r = render(make_scene(meshes=[(v, f, None)], camera={"origin": [0.05, 0.1, -0.02], "look_at": [0.3, -0.2, -1.0], "fov": 120}), width=63, height=47, spp=1)
        leaks += int(np.count_nonzero(r.aovs["object_id"] != 0))
        shot += r.rgb.shape[0] * r.rgb.shape[1]
    return [CaseResult("camera inside a closed mesh", shot, leaks, unit="pixels")]


# --- the suite ------------------------------------------------------------------------------------

CASES = [
    ("watertight", case_watertight),
    ("self-intersection", case_self_intersection),
    ("sphere-precision", case_sphere_precision),
    ("ulps", case_ulps),
    ("grazing", case_plane_grazing),
    ("degenerate", case_degenerate_triangles),
    ("zero-radius", case_zero_radius_sphere),
    ("coincident", case_coincident),
    ("zero-components", case_zero_components),
    ("critical-angle", case_critical_angle),
    ("ior-one", case_ior_one),
    ("high-ior", case_high_ior_furnace),
    ("camera-inside", case_camera_inside),
    ("not-finite", case_not_finite),
]


def run_suite(rays: int = DEFAULT_RAYS, seed: int = 0, only=None, progress=None) -> list[CaseResult]:
    """Run every case group (or those named in ``only``) with ``rays`` rays per ray-batch case.

    ``progress(result)`` is called after each row. Each group draws from its own random stream
    (seed, group index), so results do not depend on which other groups run.
    """
    from wrt.device import init_warp

    if rays < 1:
        raise ValueError(f"rays must be >= 1, got {rays}")
    init_warp()
    results = []
    for index, (group, fn) in enumerate(CASES):
        if only is not None and group not in only:
            continue
        start = time.perf_counter()
        rows = fn(rays, np.random.default_rng([seed, index]))
        elapsed = (time.perf_counter() - start) / len(rows)
        for row in rows:
            row.seconds = elapsed
            results.append(row)
            if progress:
                progress(row)
    return results


def command(rays: int, seed: int, report: str | None) -> int:
    """``wrt stress``: run the suite, print the table (and write the report); 0 if all pass, else 1."""
    import sys

    from wrt.errors import WrtError

    start = time.perf_counter()
    results = run_suite(rays, seed, progress=lambda r: print(f"  {'pass' if r.passed else 'FAIL'}  {r.case} ({r.seconds:.1f} s)", file=sys.stderr, flush=True))
    print(format_table(results))
    failed = [r for r in results if not r.passed]
    print(f"\n{len(results) - len(failed)} of {len(results)} cases pass; N = {rays} rays, seed {seed}, {time.perf_counter() - start:.0f} s")
    if report:
        try:
            paths = write_report(results, report, rays, seed)
        except OSError as e:
            raise WrtError(f"{report}: cannot write the report ({e.strerror})") from None
        print("wrote " + ", ".join(paths))
    return 1 if failed else 0
