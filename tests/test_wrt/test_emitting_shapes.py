"""Emissive polygons and spheres sampled by next-event estimation (wrt.emitting, kernels/lights/emitting.py):
the pool's power distribution, the sampled density against its evaluation and its integral,
closed forms on a diffuse floor, and the MIS-combined estimator against BSDF sampling alone."""

import numpy as np
import pytest
import warp as wp
from conftest import LAMP_ALBEDO, LAMP_MATERIALS, LAMP_RADIANCE, corner_form_factor, make_scene
from conftest import render_lamp_scene as render
from wrt.kernels.lights import LightData
from wrt.kernels.lights.emitting import make_emitting_pdf, make_sample_emitting
from wrt.kernels.materials import MaterialData
from wrt.kernels.traverse import POLYGON, SPHERE, GeometryData

from wrt.device import upload_geometry, upload_lights, upload_materials
from wrt.emitting import emitting_primitives
from wrt.geometry import build, flatten
from wrt.renderer import scene_features

H, L, ALBEDO = 1.5, LAMP_RADIANCE, LAMP_ALBEDO
FLOOR = {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}
# a non-convex L of [0, 2] x [0, 1] and [0, 1] x [0, 2] (x, z) at height H, wound to emit downward
ELL = {
    "type": "polygon",
    "vertices": [[0, H, 0], [2, H, 0], [2, H, 1], [1, H, 1], [1, H, 2], [0, H, 2]],
    "material": "lamp",
}
CENTER, RADIUS = (0.0, 2.0, 0.0), 0.5
BALL = {"type": "sphere", "center": list(CENTER), "radius": RADIUS, "material": "lamp"}
sample_emitting = make_sample_emitting(False, True, False)
emitting_pdf = make_emitting_pdf(True, False)
DOWN = {"origin": [0, 0.5, 0.0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 1.0}


def corner_solid_angle(a, b, h):
    """Solid angle of a parallel a x b rectangle at height h above a corner of it."""
    return np.arctan(a * b / (h * np.sqrt(h * h + a * a + b * b)))


def ell(f, h):
    """``f`` of the L polygon seen from below its corner: two rectangles less their overlap."""
    return f(2.0, 1.0, h) + f(1.0, 2.0, h) - f(1.0, 1.0, h)


def test_pool_is_by_power_over_polygons_and_spheres():
    scene = make_scene([FLOOR, ELL, BALL], materials=LAMP_MATERIALS)
    pool = emitting_primitives(scene, flatten(scene))
    assert list(pool.kind) == [POLYGON, SPHERE]
    assert list(pool.of_polygon) == [0] and list(pool.of_sphere) == [1]
    assert list(pool.first) == [0, 4, 4]  # the L's four triangles, none for the sphere
    area = np.array([3.0, 4 * np.pi * RADIUS**2])
    np.testing.assert_allclose(pool.area, area, rtol=1e-6)
    np.testing.assert_allclose(pool.cdf, [0.0, area[0] / area.sum(), 1.0], rtol=1e-6)
    np.testing.assert_allclose(pool.area_cdf[-1], 1.0)
    features = scene_features(scene)
    assert features.emissive and features.emissive_shapes
    triangle = {"type": "triangle", "vertices": ELL["vertices"][:3], "material": "lamp"}
    triangles_only = scene_features(make_scene([FLOOR, triangle], materials=LAMP_MATERIALS))
    assert triangles_only.emissive and not triangles_only.emissive_shapes
    # a self-intersecting (bow-tie) polygon stays BSDF-sampled only
    bow = make_scene([{**ELL, "vertices": [[0, H, 0], [2, H, 1], [2, H, 0], [0, H, 2]]}], materials=LAMP_MATERIALS)
    assert len(emitting_primitives(bow, flatten(bow)).kind) == 0


@wp.kernel
def _sample(
    geometry: GeometryData,
    materials: MaterialData,
    lights: LightData,
    p: wp.vec3,
    u: wp.array(dtype=wp.vec3),
    pdf: wp.array(dtype=float),
    pdf_again: wp.array(dtype=float),
):
    k = wp.tid()
    wi, dist, radiance, density = sample_emitting(geometry, materials, lights, p, 0.0, u[k][0], u[k][1], u[k][2])
    e = wp.where(u[k][0] < lights.emit_cdf[1], 0, 1)
    pdf[k] = wp.where(radiance[0] > 0.0, density, 0.0)
    pdf_again[k] = emitting_pdf(geometry, lights, e, p, wi, dist)


@wp.kernel
def _pdf(
    geometry: GeometryData,
    lights: LightData,
    p: wp.vec3,
    e: wp.array(dtype=int),
    wi: wp.array(dtype=wp.vec3),
    dist: wp.array(dtype=float),
    pdf: wp.array(dtype=float),
):
    k = wp.tid()
    pdf[k] = 0.0
    if e[k] >= 0:
        pdf[k] = emitting_pdf(geometry, lights, e[k], p, wi[k], dist[k])


def test_sampled_density_integrates_to_one():
    """From a point under the L's corner: each sample's density equals its evaluation, the mean
    of 1/pdf is the solid angle the emitters subtend, and the density integrated over the
    directions that meet each (uniform directions, a Monte Carlo estimate; the L hides part of
    the sphere, which the sum ignores) is 1."""
    scene = make_scene([ELL, BALL], materials=LAMP_MATERIALS)
    device = wp.get_device("cpu")
    prims = build(scene, device)
    geometry, materials = upload_geometry(prims, device), upload_materials(scene, device)
    lights = upload_lights(scene, device, prims)
    p = np.zeros(3)
    n = 1_000_000
    rng = np.random.default_rng(1)
    u = wp.array(rng.random((n, 3)).astype(np.float32), dtype=wp.vec3, device=device)
    pdf, again = wp.zeros(n, dtype=float, device=device), wp.zeros(n, dtype=float, device=device)
    wp.launch(_sample, n, [geometry, materials, lights, wp.vec3(*p), u, pdf, again], device=device)
    pdf, again = pdf.numpy(), again.numpy()
    valid = pdf > 0
    np.testing.assert_allclose(again[valid], pdf[valid], rtol=1e-4)
    sin2 = RADIUS**2 / CENTER[1] ** 2
    omega = ell(corner_solid_angle, H) + 2 * np.pi * (1 - np.sqrt(1 - sin2))
    assert np.mean(np.where(valid, 1 / np.where(valid, pdf, 1), 0)) == pytest.approx(omega, rel=0.01)

    # uniform directions over the upper hemisphere, traced against the L and the sphere in float64
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 1] = np.abs(d[:, 1])
    t_plane = H / d[:, 1]
    x, z = d[:, 0] * t_plane, d[:, 2] * t_plane
    in_ell = (x >= 0) & (z >= 0) & (((x <= 2) & (z <= 1)) | ((x <= 1) & (z <= 2)))
    c = np.asarray(CENTER)
    b = d @ c
    disc = b * b - (c @ c - RADIUS**2)
    t_ball = np.where(disc > 0, b - np.sqrt(np.maximum(disc, 0)), np.inf)
    total = 0.0
    for e, dist in ((np.where(in_ell, 0, -1), t_plane), (np.where(disc > 0, 1, -1), t_ball)):  # each on its own
        out = wp.zeros(n, dtype=float, device=device)
        inputs = [(e, int), (d, wp.vec3), (np.where(e >= 0, dist, 0.0), float)]
        arrays = [
            wp.array(np.asarray(a, dtype=np.int32 if t is int else np.float32), dtype=t, device=device)
            for a, t in inputs
        ]
        wp.launch(_pdf, n, [geometry, lights, wp.vec3(*p), *arrays, out], device=device)
        total += 2 * np.pi * out.numpy().astype(np.float64).mean()
    assert total == pytest.approx(1.0, rel=0.01)


def test_emissive_polygon_over_a_floor_point_matches_the_form_factor():
    """Floor point under the L's corner: radiance albedo L F, F the L's form factor."""
    r = render([FLOOR, ELL], DOWN, (1, 1), 16000)
    assert r.rgb[0, 0, 0] == pytest.approx(ALBEDO * L * ell(corner_form_factor, H), rel=0.01)


def test_emissive_sphere_over_a_floor_point_matches_the_closed_form():
    """Floor point under a sphere of radiance L: irradiance pi L (r / d)^2, radiance albedo L (r / d)^2."""
    r = render([FLOOR, BALL], DOWN, (1, 1), 1000)
    assert r.rgb[0, 0, 0] == pytest.approx(ALBEDO * L * (RADIUS / CENTER[1]) ** 2, rel=0.01)


def test_mis_matches_bsdf_sampling_alone_with_far_less_noise():
    """Same expectation as BSDF sampling alone (the shapes seen through an instance), per-pixel
    variance far lower."""
    camera = {"origin": [1, 1.2, -2.5], "look_at": [1, 0.3, 0.5], "fov": 50}
    ball = {**BALL, "center": [1.5, 0.8, 1.5], "radius": 0.3}
    shapes = [FLOOR, ELL, ball]
    instanced = [FLOOR, {"type": "instance", "group": "lamps"}]
    groups = [{"name": "lamps", "shape": [ELL, ball]}]
    a = [render(shapes, camera, (16, 12), 16, seed=s).rgb[..., 1].astype(np.float64) for s in range(4)]
    b = [render(instanced, camera, (16, 12), 16, groups, seed=s).rgb[..., 1].astype(np.float64) for s in range(4)]
    a, b = np.stack(a), np.stack(b)
    lit = (a.mean(axis=0) > 0.01) & (a.mean(axis=0) < 1.0)  # the floor, not the lamps seen directly
    ratio = np.median(b.var(axis=0, ddof=1)[lit] / np.maximum(a.var(axis=0, ddof=1)[lit], 1e-12))
    print(f"per-pixel variance ratio, BSDF only / MIS: {ratio:.1f}")
    assert ratio > 10.0
    se = np.sqrt(a.var(axis=0, ddof=1).sum() + b.var(axis=0, ddof=1).sum()) / (a.shape[0] ** 0.5 * a[0].size)
    assert abs(a.mean() - b.mean()) < 4 * se + 1e-4


sample_smooth = make_sample_emitting(True, True, False)
emitting_pdf_smooth = make_emitting_pdf(True, True)


@wp.kernel
def _sample_smooth(
    geometry: GeometryData,
    materials: MaterialData,
    lights: LightData,
    p: wp.vec3,
    u: wp.array(dtype=wp.vec3),
    wi: wp.array(dtype=wp.vec3),
    dist: wp.array(dtype=float),
    pdf: wp.array(dtype=float),
    pdf_again: wp.array(dtype=float),
):
    k = wp.tid()
    w, d, radiance, density = sample_smooth(geometry, materials, lights, p, 0.0, u[k][0], u[k][1], u[k][2])
    wi[k] = w
    dist[k] = d
    pdf[k] = wp.where(radiance[0] > 0.0, density, 0.0)
    pdf_again[k] = emitting_pdf_smooth(geometry, lights, 0, p, w, d)


def test_a_smooth_emitting_mesh_is_sampled_with_its_shading_normals_cosine(tmp_path):
    """Mitsuba 3's convention for a smooth-shaded emitting mesh (its ``sample_position`` and
    ``pdf_direction`` take the interpolated normal): a 1 x 1 triangle at height H whose vertex
    normals all lean 30 degrees from its face normal (down) is sampled with the density
    ``dist^2 / (area |wi . n_shading|)``, not its face normal's, and ``emitting_pdf`` agrees."""
    lean = np.radians(30.0)
    n_s = np.array([np.sin(lean), -np.cos(lean), 0.0])
    obj = tmp_path / "lamp.obj"
    obj.write_text(f"v 0 {H} 0\nv 0 {H} 1\nv 1 {H} 0\n" + f"vn {n_s[0]} {n_s[1]} {n_s[2]}\n" + "f 1//1 2//1 3//1\n")
    lamp = {"type": "mesh", "file": str(obj), "shading": "smooth", "material": "lamp"}
    scene = make_scene([lamp], materials=LAMP_MATERIALS)
    device = wp.get_device("cpu")
    prims = build(scene, device)
    geometry, materials = upload_geometry(prims, device), upload_materials(scene, device)
    lights = upload_lights(scene, device, prims)
    p = np.array([0.2, 0.0, 0.3])
    n = 2000
    u = wp.array(np.random.default_rng(2).random((n, 3)).astype(np.float32), dtype=wp.vec3, device=device)
    out = [wp.zeros(n, dtype=t, device=device) for t in (wp.vec3, float, float, float)]
    wp.launch(_sample_smooth, n, [geometry, materials, lights, wp.vec3(*p), u, *out], device=device)
    wi, dist, pdf, again = (a.numpy().astype(np.float64) for a in out)
    assert np.all(pdf > 0)  # every point faces p by its shading normal
    np.testing.assert_allclose(pdf, dist**2 / (0.5 * np.abs(wi @ n_s)), rtol=1e-4)
    np.testing.assert_allclose(again, pdf, rtol=1e-4)
    assert np.abs(pdf / (dist**2 / (0.5 * np.abs(wi[:, 1]))) - 1).max() > 0.05  # not the face normal's
