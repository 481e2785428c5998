"""Self-intersection: secondary rays spawned with the renderer's offset (``wrt.kernels.spawn``)
must never hit the surface they leave, at scales 1e-3..1e3 and far from the origin; and the
offset sweep that shows how much margin the bound has (``docs/stress.md``)."""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from .. import renderer
from ..kernels import spawn
from ..kernels.stress import trace_spawned
from ..kernels.traverse import KIND_BITS, NO_HIT
from ..trace import Tracer, vec3_array
from .common import (
    f32,
    make_scene,
    random_directions,
    split_cube,
    unit,
    uv_sphere,
)
from .report import CaseResult

SPAWN_ULPS = float(spawn.SPAWN_ULPS)  # the offset is SPAWN_ULPS * EPS32 * (2 max|p| + extent)
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
    n = len(origins)
    names = [
        "hit_t", "hit_prim", "hit_point", "hit_normal", "hit_err",
        "shadow_origin", "shadow_dir", "shadow_hit",
        "reflect_origin", "reflect_dir", "reflect_t", "reflect_prim",
        "refract_origin", "refract_dir", "refract_t", "refract_prim",
    ]  # fmt: skip
    dtype = {
        "_prim": wp.int32,
        "_hit": wp.int32,
        "_point": wp.vec3,
        "_normal": wp.vec3,
        "_origin": wp.vec3,
        "_dir": wp.vec3,
    }
    out = {k: wp.zeros(n, dtype=dtype.get(k[k.rindex("_") :], float), device="cpu") for k in names}
    inputs = [
        tracer.data,
        vec3_array(origins, "cpu"),
        vec3_array(directions, "cpu"),
        vec3_array(shadow_local, "cpu"),
        float(ior),
        float(offset_scale),
    ]
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
    worst hit-point error in units of EPS32 (2 max|p| + extent), the offset's unit).
    """
    hit = out["hit_prim"] != NO_HIT
    p = out["hit_point"][hit].astype(np.float64)
    n_out = out["hit_normal"][hit].astype(np.float64)
    err_unit = out["err_unit"][hit].astype(np.float64)
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
                left = plane_id[out["hit_prim"][hit] >> KIND_BITS]
                arrived = plane_id[np.where(prim >= 0, prim, 0) >> KIND_BITS]
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
            out["err_unit"] = out["hit_err"] / SPAWN_ULPS
            *counts, point_error = self_hit_check(kind, tracer, center, scale, out, plane_id)
            totals[s] = [a + b for a, b in zip(totals[s], counts)]
            worst = max(worst, point_error)
    return totals, worst


# fractions of the renderer's offset tried to find the smallest one that suffices
OFFSET_SWEEP = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.0)


def case_self_intersection(rays, rng):
    """One row per shape: failures are false self-hits and escapes with the renderer's offset;
    ``worst`` is the worst distance of a computed hit point from the float32 surface, in the units
    of the offset (EPS32 (2 max|p| + extent)), against the offset's SPAWN_ULPS."""
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
        results.append(
            CaseResult(f"self-intersection: {kind}", judged, false_hits + escapes, worst, SPAWN_ULPS, "ulps", detail)
        )
    return results


CAMERA_DISTANCES = (1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6)
CONTACT_GAPS = (1e-2, 1e-3, 1e-4)
CONTACT_FLOORS = ("plane", "polygon", "triangles")
CONTACT_MARGIN = 0.05  # floor points this close to the shadow's float64 outline are not judged


def _contact_scene(floor, gap, distance, size):
    """A unit square sheet ``gap`` above a floor, under a directional light grazing at slope
    ``2 gap`` along +x (so the sheet's shadow falls 0.5 beyond it, where the camera sees it), and
    a camera ``distance`` from the scene, framing the same 3 x 3 units whatever the distance."""
    sheet = np.array([[-0.5, gap, -0.5], [-0.5, gap, 0.5], [0.5, gap, 0.5], [0.5, gap, -0.5]])
    ground = np.array([[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]])
    shapes, meshes = [], []
    if floor == "plane":
        shapes.append({"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "floor"})
    elif floor == "polygon":
        shapes.append({"type": "polygon", "vertices": ground.tolist(), "material": "floor"})
    else:
        meshes.append((ground, [[0, 1, 2], [0, 2, 3]], "floor"))
    if floor == "triangles":
        meshes.append((sheet, [[0, 1, 2], [0, 2, 3]], "sheet"))
    else:
        shapes.append({"type": "polygon", "vertices": sheet.tolist(), "material": "sheet"})
    slope = 2.0 * gap
    target = np.array([0.5, 0.0, 0.0])
    eye = target + distance * unit([0.3, 1.0, 0.5])
    return make_scene(
        shapes=shapes,
        meshes=meshes,
        materials=[{"name": "floor", "albedo": [0.8, 0.8, 0.8]}, {"name": "sheet", "albedo": [0.2, 0.2, 0.2]}],
        lights=[{"type": "directional", "direction": [1.0, -slope, 0.0], "irradiance": [1.0 / slope] * 3}],
        camera={
            "origin": eye.tolist(),
            "look_at": target.tolist(),
            "fov": float(np.degrees(2 * np.arctan(1.5 / distance))),
        },
        render={"integrator": "whitted", "width": size, "height": size, "spp": 1, "max_depth": 2},
    )


def contact_shadow_case(floor, rays) -> CaseResult:
    """Contact shadows seen from afar: a sheet 1e-2, 1e-3 and 1e-4 above a ``floor`` (an infinite
    plane, a polygon, two triangles; the sheet a polygon, or two triangles over triangles) under a
    grazing light, rendered (whitted, pixel centres) from 1 to 1e6 units away with the same framing.

    A floor point ``(x, 0, z)`` is in the sheet's shadow when ``|x - 0.5| < 0.5`` and ``|z| < 0.5``
    (float64, from its ``position``); points within ``CONTACT_MARGIN`` of that outline are not
    judged. A lit point that renders black is a false shadow, a shadowed point that does not is a
    lost contact shadow (the spawn offset lifted the shadow ray over the sheet). Both count as
    failures. ``detail`` gives per distance the smallest gap whose shadow survived everywhere."""
    size = max(int(np.sqrt(rays / (len(CAMERA_DISTANCES) * len(CONTACT_GAPS) * len(CONTACT_FLOORS)))), 24)
    lost, false, judged, smallest = 0, 0, 0, {}
    for distance in CAMERA_DISTANCES:
        kept = []
        for gap in CONTACT_GAPS:
            result = renderer.render(_contact_scene(floor, gap, distance, size))
            on_floor = result.aovs["object_id"] == 0  # the floor is the first surface
            p = result.aovs["position"][on_floor].astype(np.float64)
            dark = ~(result.rgb[on_floor][:, 0] > 0.0)
            x, z = np.abs(p[:, 0] - 0.5), np.abs(p[:, 2])
            shadow = (x < 0.5 - CONTACT_MARGIN) & (z < 0.5 - CONTACT_MARGIN)
            lit = (x > 0.5 + CONTACT_MARGIN) | (z > 0.5 + CONTACT_MARGIN)
            lost_here = int(np.count_nonzero(shadow & ~dark))
            lost += lost_here
            false += int(np.count_nonzero(lit & dark))
            judged += int(np.count_nonzero(shadow | lit))
            if lost_here == 0 and np.count_nonzero(shadow) > 0:
                kept.append(gap)
        smallest[f"{distance:g}"] = min(kept) if kept else None
    return CaseResult(
        f"contact shadows, camera 1..1e6 away: {floor} floor",
        judged,
        lost + false,
        unit="lost or false shadow pixels",
        detail={"lost_contact_shadow": lost, "false_shadow": false, "smallest_gap_kept_by_distance": smallest},
    )


def case_contact_shadows(rays, rng):
    return [contact_shadow_case(floor, rays) for floor in CONTACT_FLOORS]
