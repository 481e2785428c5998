"""Transport that both strategies of the path integrator must agree on: a camera inside water, a
light inside an absorbing medium, and a false (index-matched) interface, each against a closed
form (``docs/stress.md``)."""

from __future__ import annotations

import numpy as np

from .common import make_scene, unit
from .refraction import render
from .report import CaseResult

TOLERANCE = 0.01  # relative error of an image mean against its closed form
WATER_IOR = 1.33


def camera_in_water_case(integrator, transmittance=1.0) -> CaseResult:
    """The camera at the centre of a sphere of water (ior 1.33, radius 1, ``transmittance`` per
    unit), a uniform environment of radiance 1 outside (path; whitted: background 1). Every
    camera ray meets the surface at normal incidence after 1 unit; 1 - F leaves, scaled by ``n^2``
    (radiance ``L / n^2`` is conserved across the interface), and F comes back through the centre
    to the opposite side, 2 units on: every pixel is ``n^2 (1 - F) T (1 - r^K) / (1 - r)``,
    ``T = transmittance``, ``r = F T^2``, with ``K`` infinite for the path integrator (``max_depth``
    64) and 7 for whitted's tree of depth 8. The absorption starts at the camera: it is inside the
    water (``wrt.bake.camera_media``)."""
    water = {"name": "water", "type": "dielectric", "ior": WATER_IOR, "transmittance": [transmittance] * 3}
    scene = make_scene(
        shapes=[{"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "material": "water"}],
        materials=[water],
        lights=[{"type": "environment", "radiance": [1.0, 1.0, 1.0]}] if integrator == "path" else [],
        camera={"origin": [0.0, 0.0, 0.0], "look_at": [0.3, -0.2, 1.0], "fov": 90.0},
        render={"integrator": integrator, "width": 24, "height": 24, "spp": 16, "seed": 3}
        | ({"max_depth": 64} if integrator == "path" else {"max_depth": 8, "background": [1.0, 1.0, 1.0]}),
    )
    f = ((WATER_IOR - 1.0) / (WATER_IOR + 1.0)) ** 2
    r = f * transmittance**2
    terms = 1.0 / (1.0 - r) if integrator == "path" else (1.0 - r**7) / (1.0 - r)
    expected = WATER_IOR**2 * (1.0 - f) * transmittance * terms
    got = render(scene).rgb.astype(np.float64)
    error = abs(got.mean() / expected - 1.0) if np.isfinite(got).all() and got.size else np.inf
    murky = "" if transmittance == 1.0 else f", transmittance {transmittance:g}"
    return CaseResult(
        f"transport: camera inside water{murky} ({integrator})",
        got.shape[0] * got.shape[1] * 16,
        int(not error <= TOLERANCE),
        error,
        TOLERANCE,
        detail={"mean": float(got.mean()), "closed_form": expected},
    )


CAMERA = np.array([0.0, 3.5, 5.0])
LIGHT_CENTRE = np.array([0.0, 1.2, 0.0])
SIZE = 32


def _floor_under_sphere_light(extra_shapes, extra_materials, light_radius, spp, seed):
    """A diffuse floor (albedo 0.5) and a sphere light (radius ``light_radius``, centre 1.2 above
    it, radiance 4) inside a clear or absorbing ior-1.0 sphere ``volume`` of radius 4, seen from
    outside; path integrator, ``max_depth`` 3 (the camera ray, its pass into the volume, the
    light's shadow ray or BSDF sample). Returns the red channel and the floor point of the
    pixels whose centre ray meets the floor 0.1 inside its edges and misses the light (the camera
    ray's first hit is the volume, so the AOVs do not say it: the points are computed, float64,
    from the camera convention)."""
    square = [[-1.5, 0.0, -1.5], [-1.5, 0.0, 1.5], [1.5, 0.0, 1.5], [1.5, 0.0, -1.5]]
    fov = 22.0
    scene = make_scene(
        shapes=[
            {"type": "polygon", "vertices": square, "material": "floor"},
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 4.0, "material": "volume"},
            *extra_shapes,
        ],
        materials=[{"name": "floor", "albedo": [0.5, 0.5, 0.5]}, *extra_materials],
        lights=[{"type": "sphere", "center": LIGHT_CENTRE.tolist(), "radius": light_radius, "radiance": [4.0] * 3}],
        camera={"origin": CAMERA.tolist(), "look_at": [0.0, 0.0, 0.0], "fov": fov},
        render={"integrator": "path", "width": SIZE, "height": SIZE, "spp": spp, "max_depth": 3, "seed": seed},
    )
    rgb = render(scene).rgb[..., 0].astype(np.float64)
    forward, right, up = scene.camera.basis()
    centres = (np.arange(SIZE) + 0.5) / SIZE
    sx, sy = np.meshgrid(2.0 * centres - 1.0, 1.0 - 2.0 * centres)
    tan = np.tan(np.radians(fov) / 2.0)
    view = unit(sx[..., None] * tan * right + sy[..., None] * tan * up + forward)
    p = CAMERA + (-CAMERA[1] / view[..., 1])[..., None] * view
    to_light = LIGHT_CENTRE - CAMERA
    along = np.einsum("...j,j->...", view, to_light)
    miss_light = np.linalg.norm(along[..., None] * view - to_light, axis=-1) > light_radius + 0.05
    keep = (np.abs(p[..., 0]) < 1.4) & (np.abs(p[..., 2]) < 1.4) & miss_light
    return rgb[keep], p[keep]


def _sphere_distance(o, w, c, r):
    """Distance along unit rays ``o + s w`` (float64) to the first crossing of the sphere (c, r),
    for rays that meet it; the entry from outside, or the exit from inside."""
    f = o - c
    b = np.einsum("...j,...j->...", w, f)
    disc = b * b - (np.einsum("...j,...j->...", f, f) - r * r)
    q = np.sqrt(np.maximum(disc, 0.0))
    near = -b - q
    return np.where(near > 0.0, near, -b + q)


def absorbed_irradiance(p, centre, radius, radiance, sigma, n=4096):
    """Irradiance (float64) at floor points ``p`` (normal +y) from a sphere light seen through a
    medium of absorption ``sigma``: ``E = int L exp(-sigma s(w)) cos(theta) dw`` over the cone the
    light subtends, ``s(w)`` the distance to its surface, by a stratified quadrature of ``n``
    directions per point (uniform in the cone's solid angle)."""
    k = int(np.sqrt(n))
    u1, u2 = np.meshgrid((np.arange(k) + 0.5) / k, (np.arange(k) + 0.5) / k)
    u1, u2 = u1.ravel(), u2.ravel()
    out = np.empty(len(p))
    for i, x in enumerate(p):
        axis = centre - x
        d = np.linalg.norm(axis)
        axis = axis / d
        one_minus_cos_max = (radius / d) ** 2 / (1.0 + np.sqrt(1.0 - (radius / d) ** 2))
        w = u1 * one_minus_cos_max  # 1 - cos(theta), uniform in solid angle
        sin = np.sqrt(w * (2.0 - w))
        t1 = unit(np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 0.0, 1.0]))
        t2 = np.cross(axis, t1)
        phi = 2.0 * np.pi * u2
        dirs = (1.0 - w)[:, None] * axis + (sin * np.cos(phi))[:, None] * t1 + (sin * np.sin(phi))[:, None] * t2
        s = _sphere_distance(np.broadcast_to(x, dirs.shape), dirs, centre, radius)
        solid_angle = 2.0 * np.pi * one_minus_cos_max
        out[i] = solid_angle * np.mean(radiance * np.exp(-sigma * s) * np.maximum(dirs[:, 1], 0.0))
    return out


def absorbing_light_case(spp) -> CaseResult:
    """A sphere light and a floor inside an absorbing volume (ior 1.0, transmittance 0.5 per unit,
    sigma = ln 2): each floor pixel must be ``albedo / pi E exp(-sigma l)``, ``E`` the irradiance
    through the medium (``absorbed_irradiance``) and ``l`` the camera ray's length inside the
    volume. Next-event estimation used to ignore the absorption along its shadow ray while
    BSDF-sampled paths applied it, so the MIS sum came out too bright."""
    sigma = np.log(2.0)
    volume = {"name": "volume", "type": "dielectric", "ior": 1.0, "transmittance": [0.5, 0.5, 0.5]}
    got, p = _floor_under_sphere_light([], [volume], 0.2, spp, seed=5)
    view = unit(p - CAMERA)
    entry = _sphere_distance(np.broadcast_to(CAMERA, p.shape), view, np.zeros(3), 4.0)
    inside = np.linalg.norm(p - CAMERA, axis=1) - entry
    expected = 0.5 / np.pi * absorbed_irradiance(p, LIGHT_CENTRE, 0.2, 4.0, sigma) * np.exp(-sigma * inside)
    ratio = got.mean() / expected.mean()
    error = abs(ratio - 1.0) if np.isfinite(got).all() and got.size else np.inf
    return CaseResult(
        "transport: light inside an absorbing medium",
        len(got) * spp,
        int(not error <= TOLERANCE),
        error,
        TOLERANCE,
        detail={"rendered_over_closed_form": ratio, "floor_pixels": len(got)},
    )


def false_interface_case(spp) -> CaseResult:
    """The same floor and light inside a clear volume of priority 1, crossed by the surface of a
    water sphere of priority 0 (a false interface there: invisible). Shadow rays stop at that
    surface, so light beyond it is found only by BSDF sampling, which must then take full weight:
    the floor must match the closed form ``albedo L (r / |c - p|)^2 cos(theta)`` as if the water
    sphere were not there."""
    volume = {"name": "volume", "type": "dielectric", "ior": 1.0, "priority": 1}
    water = {"name": "water", "type": "dielectric", "ior": WATER_IOR}
    sphere = {"type": "sphere", "center": [0.9, 0.5, 0.2], "radius": 0.9, "material": "water"}
    radius = 0.35
    got, p = _floor_under_sphere_light([sphere], [volume, water], radius, spp, seed=9)
    to_c = LIGHT_CENTRE - p
    dist2 = (to_c * to_c).sum(-1)
    expected = 0.5 * 4.0 * radius**2 / dist2 * (to_c[:, 1] / np.sqrt(dist2))
    ratio = got.mean() / expected.mean()
    error = abs(ratio - 1.0) if np.isfinite(got).all() and got.size else np.inf
    return CaseResult(
        "transport: false interface between the floor and the light",
        len(got) * spp,
        int(not error <= 2 * TOLERANCE),
        error,
        2 * TOLERANCE,
        detail={"rendered_over_closed_form": ratio, "floor_pixels": len(got)},
    )


def case_transport(rays, rng):
    spp = int(np.clip(rays // 4000, 128, 512))
    return [
        camera_in_water_case("path"),
        camera_in_water_case("whitted"),
        camera_in_water_case("path", transmittance=0.5),
        camera_in_water_case("whitted", transmittance=0.5),
        absorbing_light_case(spp),
        false_interface_case(spp),
    ]
