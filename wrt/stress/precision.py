"""Precision against float64: sphere and triangle hit distances within their error bounds, and
the distribution of the triangle test's error in ulps (``docs/stress.md``)."""

from __future__ import annotations

import numpy as np

from ..kernels.traverse import NO_HIT
from ..trace import Tracer
from .common import EPS32, f32, make_scene, random_directions, unit
from .report import CaseResult


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
    return [
        CaseResult(
            "sphere precision: 1e4-1e6 radii",
            n * len(SPHERE_RADII),
            int(np.count_nonzero(ratio > 1.0)) + disagree,
            float(rel.max()),
            bound,
            "ulps",
            detail,
        )
    ]


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
    results.append(
        _ulps_result(
            "t vs float64: triangles",
            16 * n,
            err,
            ratio,
            tri_disagree,
            TRIANGLE_C,
            {"max_ulps_cos_above_0.1": float(err[cos > 0.1].max())},
        )
    )
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
    results.append(
        _ulps_result("t vs float64: spheres", 16 * n, err, ratio, sph_disagree, f"{SPHERE_C:g}(|o-c|/t+k) ulps", {})
    )
    return results


def _ulps_result(name, rays, err, ratio, disagree, bound, extra):
    pct = np.percentile(err, [50, 90, 99, 99.9]) if err.size else [0.0] * 4
    detail = {
        "median_ulps": float(pct[0]),
        "p90_ulps": float(pct[1]),
        "p99_ulps": float(pct[2]),
        "p99.9_ulps": float(pct[3]),
        "max_ratio_to_bound": float(ratio.max()),
        "hit_miss_disagreements_beyond_band": disagree,
        **extra,
    }
    return CaseResult(
        name, rays, int(np.count_nonzero(ratio > 1.0)) + disagree, float(err.max()), bound, "ulps", detail
    )
