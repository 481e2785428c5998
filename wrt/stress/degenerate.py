"""Grazing and degenerate geometry: rays in a plane, zero-area triangles, zero-radius spheres,
coincident surfaces, and directions with zero or -0.0 components (``docs/stress.md``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..bvh import lane_bounds
from ..kernels.traverse import KIND_BITS, KIND_MASK, NO_HIT, SPHERE
from ..scene import Sphere
from ..trace import Tracer
from .common import EPS32, f32, make_scene, random_directions, split_cube, unit
from .precision import SPHERE_BAND, TRIANGLE_C, judge_triangle
from .report import CaseResult


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
    y = np.where(
        rng.random(n) < 0.5, width * rng.uniform(0.2, 0.8, n), np.where(rng.random(n) < 0.5, -1e-5, width + 1e-5)
    )
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
    n = max(rays // 4, 8)
    failures, shot = 0, 0
    for radius in (0.0, 1e-30):
        scene = make_scene(
            shapes=[
                {"type": "sphere", "center": [0.5, -0.25, 1.0], "radius": 1.0},
                {"type": "sphere", "center": [3.0, 0.0, 0.0], "radius": 0.5},
            ]
        )
        scene = dataclasses.replace(
            scene, shapes=(Sphere(center=(0.5, -0.25, 1.0), radius=radius, material=0), scene.shapes[1])
        )
        tracer = Tracer(scene)
        c = np.array([0.5, -0.25, 1.0])
        o = c + random_directions(rng, n) * rng.uniform(0.1, 10.0, (n, 1))
        aim = np.where(rng.random((n, 1)) < 0.5, c, c + rng.normal(size=(n, 3)) * 1e-6)
        d = unit(aim - o)
        d[: n // 8] = 0.0  # zero directions too
        t, prim = tracer.closest(o, d)
        tb, primb = tracer.closest(o, d, brute_force=True)
        dist = np.linalg.norm(f32(o) - c, axis=1)
        small = (prim >> KIND_BITS == 0) & ((prim & KIND_MASK) == 0) & (prim != NO_HIT)
        failures += int(
            np.count_nonzero(
                _not_finite_t(t) | (small & (np.abs(t - dist) > 1e-5 * dist)) | (t != tb) | (prim != primb)
            )
        )
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
        (
            "triangle in plane",
            [
                {"type": "triangle", "vertices": tri},
                {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]},
            ],
            [],
            4.0,
        ),
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
        failures += (
            int(np.count_nonzero(hit & (p2 == NO_HIT)))
            + int(np.count_nonzero(ulps > tolerance))
            + int(np.count_nonzero(np.isnan(t2)))
        )
        shot += n
    return [CaseResult("coincident surfaces (z-fighting)", shot, failures, worst, 4.0, "ulps")]


def case_zero_components(rays, rng):
    """Unit directions with +0.0, -0.0, denormal (1e-40) and tiny components, from origins exactly on
    BVH box planes: the BVH's slab test must never cull what brute force hits (same t; the
    primitive may differ only on a tie), any-hit agrees, no NaN. A ray tangent to a sphere within
    the sphere test's rounding (|h - r| <= SPHERE_BAND EPS32 |o - c|) may go either way. Scene: a
    split cube, spheres and triangles in a BVH."""
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
        sphere = mismatch & (ref != NO_HIT) & ((ref & KIND_MASK) == SPHERE)
        k = ref[sphere] >> KIND_BITS
        c, r = f32(tracer.prims.sphere_center[k]), f32(tracer.prims.sphere_radius[k])
        f = f32(o[sphere]) - c
        dd = f32(d[sphere])
        h = np.linalg.norm(
            f - np.einsum("ij,ij->i", f, dd)[:, None] * dd / np.einsum("ij,ij->i", dd, dd)[:, None], axis=1
        )
        tangent[np.flatnonzero(sphere)[np.abs(h - r) <= SPHERE_BAND * EPS32 * np.linalg.norm(f, axis=1)]] = True
    failures = int(np.count_nonzero((mismatch & ~tangent) | _not_finite_t(t)))
    detail = {
        "bvh_vs_brute_force_mismatches": int(np.count_nonzero(mismatch & ~tangent)),
        "sphere_tangent_within_rounding": int(np.count_nonzero(mismatch & tangent)),
    }
    return [CaseResult("zero and -0.0 direction components (BVH)", n, failures, unit="rays", detail=detail)]
