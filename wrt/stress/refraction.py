"""Refraction and whole images: the critical angle, invisible ior-1 objects, high-ior furnaces,
light trapped by total internal reflection, cameras inside objects, and no NaN or Inf pixel
from adversarial scenes (``docs/stress.md``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .. import renderer
from ..loader import override_render
from ..scene import Sphere
from .common import CLOSED_MESHES, EPS32, make_scene, split_cube, unit, uv_sphere
from .report import CaseResult


def render(scene, **overrides):
    """``wrt.render`` of ``scene`` with ``[render]`` keys replaced (validated like the file's)."""
    return renderer.render(override_render(scene, source="<stress>", **overrides))


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
    """What the critical-angle scene's pixel must be, float64: ``ior^2 (1 - F) sum_k F^(2k)``, k < 4.

    The camera ray meets the slab's top face from inside at incidence ``cos_i``; the share 1 - F
    leaves to the background (radiance 1), F is reflected to the bottom face, where 1 - F leaves
    onto a black floor and F comes back up at the same angle (the faces are parallel), and so on:
    the top face is met at segments 1, 3, 5 and 7 of ``SLAB_DEPTH = 8``. Radiance seen from inside
    glass is ``ior^2`` times the radiance outside (``L / n^2`` is conserved across the surface).
    """
    f = fresnel64(cos_i, ior)
    return ior**2 * (1.0 - f) * sum(f ** (2 * k) for k in range(SLAB_DEPTH // 2))


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
            materials=[
                {"name": "glass", "type": "dielectric", "ior": ior},
                {"name": "black", "albedo": [0.0, 0.0, 0.0]},
            ],
            camera={
                "origin": [0.0, 0.0, 0.0],
                "look_at": [math.sin(theta_c), math.cos(theta_c), 0.0],
                "up": [0.0, 1.0, 0.0],
                "fov": fov,
            },
            render={
                "width": size[0],
                "height": size[1],
                "integrator": "whitted",
                "background": [1.0, 1.0, 1.0],
                "max_depth": SLAB_DEPTH,
                "min_throughput": 0.0,
            },
        )
        r = render(scene)
        bad += count_not_finite(r)
        cos_i = unit(r.aovs["position"].astype(np.float64))[..., 1]
        on_top = (r.aovs["object_id"] == 1) & (np.abs(r.aovs["position"][..., 1] - 1.0) < 1e-5)
        one, two = slab_radiance(cos_i + ANGLE_SLACK, ior), slab_radiance(cos_i - ANGLE_SLACK, ior)
        value = r.rgb.astype(np.float64)
        off = np.maximum(np.minimum(one, two)[..., None] - value, value - np.maximum(one, two)[..., None]).max(axis=-1)
        off = off / ior**2  # relative to the ior^2 scale of the values
        off = np.where(on_top, np.maximum(off, 0.0), np.inf)
        worst = max(worst, float(off.max()))
        failures += int(np.count_nonzero(off > VALUE_SLACK))
        pixels += off.size
        near += int(np.count_nonzero(np.abs(np.arccos(np.clip(cos_i, -1, 1)) - theta_c) < 1e-4))
    detail = {
        "pixels_within_1e-4_rad_of_critical": near,
        "not_finite_pixels": bad,
        "critical_angle_deg": math.degrees(theta_c),
    }
    return CaseResult(
        f"refraction at the critical angle: ior {ior:g}", pixels, failures + bad, worst, VALUE_SLACK, "", detail
    )


def case_critical_angle(rays, rng):
    return [critical_angle_case(ior, rng) for ior in CRITICAL_IORS]


IOR_ONE_PLACEMENTS = (("origin", np.zeros(3)), ("1e4 from origin", np.array([1e4, -1e4, 1e4])))


def ior_one_case(name, offset):
    """Dielectrics of ior 1.0 (a sphere and a closed mesh) are invisible: the whitted image equals
    the same scene without them to 1e-6 (filtered shadows, so light passes them too)."""
    v, f = split_cube(4)
    floor = {
        "type": "plane",
        "point": (offset + [0.0, -1.0, 0.0]).tolist(),
        "normal": [0.0, 1.0, 0.0],
        "material": "floor",
    }
    ghost = {"type": "sphere", "center": (offset + [0.3, 0.0, 0.0]).tolist(), "radius": 0.8, "material": "ghost"}
    common = {
        "materials": [
            {"name": "floor", "albedo": [0.5, 0.5, 0.5]},
            {"name": "ghost", "type": "dielectric", "ior": 1.0},
        ],
        "lights": [{"type": "point", "position": (offset + [1.0, 3.0, 2.0]).tolist(), "intensity": [10.0, 10.0, 10.0]}],
        "camera": {"origin": (offset + [0.0, 1.0, 4.0]).tolist(), "look_at": offset.tolist()},
        "render": {
            "width": 64,
            "height": 48,
            "integrator": "whitted",
            "dielectric_shadows": "filtered",
            "background": [0.1, 0.2, 0.3],
        },
    }
    with_ghosts = render(
        make_scene(shapes=[floor, ghost], meshes=[(v * 0.4 + offset + [-0.9, -0.2, 0.5], f, "ghost")], **common)
    )
    without = render(make_scene(shapes=[floor], **common))
    diff = np.abs(with_ghosts.rgb.astype(np.float64) - without.rgb).max(axis=-1)
    diff[np.isnan(diff)] = np.inf
    detail = {"pixels_through_ghosts": int(np.count_nonzero(with_ghosts.aovs["object_id"] >= 1))}
    return CaseResult(
        f"refraction: ior 1.0 is invisible ({name})",
        diff.size,
        int(np.count_nonzero(diff > 1e-6)),
        float(diff.max()),
        1e-6,
        "",
        detail,
    )


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
        materials=[
            {"name": "glass", "type": "dielectric", "ior": 4.0},
            {"name": "air", "type": "dielectric", "ior": 1.0},
        ],
        camera={"origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 40},
        render={
            "width": 64,
            "height": 48,
            "integrator": "whitted",
            "background": [1.0, 1.0, 1.0],
            "max_depth": max_depth,
            "min_throughput": 1e-6,
        },
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
    return CaseResult(
        f"refraction: ior 4.0 furnace, {name}", rgb.size, failures, float(loss[~silhouette].max()), 1e-3, "", detail
    )


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
    return CaseResult(
        f"refraction: ior 4.0 furnace, {name}", loss_shallow.size, failures, float(loss_deep.max()), 1.0, "", detail
    )


def case_high_ior_furnace(rays, rng):
    return [
        furnace_case("two spheres", FURNACE_SCENES["two spheres"]),
        trapped_light_case("air bubble in a sphere", FURNACE_SCENES["air bubble in a sphere"]),
    ]


def _adversarial_scenes():
    """Scenes for the NaN/Inf sweep: (name, scene). Odd image sizes put a pixel centre exactly on
    the view axis, so axis-aligned cameras shoot rays with +-0.0 components."""
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
        {
            "type": "spot",
            "position": [0.0, 0.0, 3.0],
            "direction": [0.0, 0.0, -1.0],
            "intensity": [3.0, 3.0, 3.0],
            "cutoff_angle": 90.0,
            "beam_width": 0.0,
        },
    ]
    axis_camera = {"origin": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0]}
    degenerate = make_scene(
        shapes=[
            {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "material": "shiny"},  # radius 0 below
            {
                "type": "triangle",
                "vertices": [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1e-6, 0.0]],
                "material": "mirror",
            },
            {"type": "triangle", "vertices": [[0.0, -1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "material": "glass"},
            {
                "type": "triangle",
                "vertices": [[-2.0, -2.0, -1.0], [2.0, -2.0, -1.0], [0.0, 2.0, -1.0]],
                "material": "d",
            },
            {
                "type": "triangle",
                "vertices": [[-2.0, -2.0, -1.0], [2.0, -2.0, -1.0], [0.0, 2.0, -1.0]],
                "material": "mirror",
            },
            {"type": "plane", "point": [0.0, 0.0, -1.0], "normal": [0.0, 0.0, 1.0], "material": "lamp"},
            {"type": "plane", "point": [0.0, -1.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "glass"},
        ],
        materials=mats,
        lights=lights,
        camera=axis_camera,
    )
    degenerate = dataclasses.replace(
        degenerate,
        shapes=(
            Sphere(center=(0.0, 0.0, 0.0), radius=0.0, material=degenerate.shapes[0].material),
            *degenerate.shapes[1:],
        ),
    )
    far = np.array([1e5, -1e5, 1e5])
    return [
        ("degenerate primitives, axis camera", degenerate),
        (
            "camera inside a diffuse mesh",
            make_scene(
                meshes=[(ball, ball_faces, "d")],
                materials=mats,
                lights=lights[:1],
                camera={"origin": [0.1, 0.2, 0.3], "look_at": [0.0, 0.0, -1.0]},
            ),
        ),
        (
            "camera inside a glass mesh",
            make_scene(
                shapes=[{"type": "plane", "point": [0.0, -3.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "mirror"}],
                meshes=[(box, box_faces, "glass")],
                materials=mats,
                lights=lights,
                camera={"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0]},
            ),
        ),
        (
            "camera in a plane, looking along it",
            make_scene(
                shapes=[
                    {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "shiny"},
                    {"type": "sphere", "center": [0.0, 0.0, -3.0], "radius": 1.0, "material": "dense"},
                ],
                materials=mats,
                lights=lights,
                camera={"origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0]},
            ),
        ),
        (
            "dense glass and mirrors 1e5 from the origin",
            make_scene(
                shapes=[
                    {"type": "sphere", "center": far.tolist(), "radius": 1.0, "material": "dense"},
                    {
                        "type": "plane",
                        "point": (far + [0.0, -1.0, 0.0]).tolist(),
                        "normal": [0.0, 1.0, 0.0],
                        "material": "mirror",
                    },
                ],
                meshes=[(box * 0.5 + far + [2.0, 0.0, 0.0], box_faces, "glass")],
                materials=mats,
                lights=[
                    {"type": "point", "position": (far + [0.0, 3.0, 2.0]).tolist(), "intensity": [10.0, 10.0, 10.0]}
                ],
                camera={"origin": (far + [0.0, 0.5, 5.0]).tolist(), "look_at": far.tolist()},
            ),
        ),
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
    return [
        CaseResult(
            "no NaN/Inf in integrator outputs",
            pixels,
            bad,
            unit="pixels",
            detail={"not_finite_pixels": bad, **{f"[{k}]": v for k, v in by_scene.items()}},
        )
    ]


def case_camera_inside(rays, rng):
    """A camera inside a closed mesh (the tessellated sphere, the split cube, the fan) sees the mesh
    in every pixel: raycast, 1 spp, 63 x 47 (no pixel may leak to the background)."""
    shot, leaks = 0, 0
    for name, make in CLOSED_MESHES.items():
        v, f = make()
        r = render(
            make_scene(
                meshes=[(v, f, None)], camera={"origin": [0.05, 0.1, -0.02], "look_at": [0.3, -0.2, -1.0], "fov": 120}
            ),
            width=63,
            height=47,
            spp=1,
        )
        leaks += int(np.count_nonzero(r.aovs["object_id"] != 0))
        shot += r.rgb.shape[0] * r.rgb.shape[1]
    return [CaseResult("camera inside a closed mesh", shot, leaks, unit="pixels")]
