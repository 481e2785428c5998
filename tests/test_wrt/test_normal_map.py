"""Normal maps: the hit's tangent frame (``wrt.kernels.traverse.surface_derivatives``) against
Mitsuba 3's ``si.dp_du``, ``si.dp_dv`` and ``sh_frame``, the perturbed normal
(``wrt.kernels.hit.perturbed_normal``) against a float64 reference, a flat normal map rendering as
none, the scene key's checks and the Mitsuba importer's ``normalmap``."""

import numpy as np
import pytest
import warp as wp
from conftest import EXAMPLES
from test_textures import SHAPES, needs_mitsuba, rays_toward, scene_xml, write_exr, write_meshes, write_png
from wrt.kernels.hit import perturbed_normal, surface_hit
from wrt.kernels.materials import MaterialData
from wrt.kernels.traverse import (
    NO_HIT,
    GeometryData,
    closest_hit,
    hit_point,
    ray_hit,
    shading_normal,
    surface_derivatives,
)

import wrt
from wrt.device import upload_geometry, upload_materials
from wrt.errors import SceneError, WrtError
from wrt.geometry import build
from wrt.loader import load_scene, parse_scene
from wrt.renderer import scene_features

S_RGB = wp.constant(wp.vec3(1.0, 0.5, 0.5))  # tangent-space normals along s and t: perturbed_normal returns them
T_RGB = wp.constant(wp.vec3(0.5, 1.0, 0.5))


@wp.kernel
def trace_frames(
    geometry: GeometryData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    out_dpdu: wp.array(dtype=wp.vec3),
    out_dpdv: wp.array(dtype=wp.vec3),
    out_frame: wp.array(dtype=wp.mat33),
    out_hit: wp.array(dtype=wp.int32),
):
    """dp/du, dp/dv and the shading frame (rows s, t, n) at each ray's closest hit."""
    i = wp.tid()
    o = origins[i]
    d = directions[i]
    t, prim, inst = closest_hit(geometry, o, d, 0.0, 0.0, wp.inf)
    out_hit[i] = wp.where(prim == NO_HIT, 0, 1)
    if prim != NO_HIT:
        p, n, _err = hit_point(geometry, ray_hit(o, d, 0.0, t, prim, inst))
        ns = shading_normal(geometry, prim, inst, p, n, 0.0)
        dpdu, dpdv = surface_derivatives(geometry, prim, inst, p, 0.0)
        out_dpdu[i] = dpdu
        out_dpdv[i] = dpdv
        out_frame[i] = wp.matrix_from_rows(perturbed_normal(ns, dpdu, S_RGB), perturbed_normal(ns, dpdu, T_RGB), ns)


@needs_mitsuba
@pytest.mark.parametrize("name", SHAPES)
def test_tangent_frame_is_mitsubas(tmp_path, name):
    """dp/du, dp/dv and the shading frame (s, t, n) of wrt's hits equal Mitsuba's ``si.dp_du``,
    ``si.dp_dv`` and ``si.sh_frame`` for the same rays, on every shape kind (meshes with and without
    texture coordinates, instances)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    write_meshes(tmp_path)
    body, target, spread = SHAPES[name]
    path = scene_xml(tmp_path, body)
    origins, directions = rays_toward(np.random.default_rng(len(name)), target, spread, n=200)
    geometry = upload_geometry(build(load_scene(path), "cpu"), "cpu")
    n = len(origins)
    dpdu, dpdv, frames, hit = wp.zeros(n, wp.vec3), wp.zeros(n, wp.vec3), wp.zeros(n, wp.mat33), wp.zeros(n, wp.int32)
    rays = [wp.array(origins, dtype=wp.vec3), wp.array(directions, dtype=wp.vec3)]
    wp.launch(trace_frames, dim=n, inputs=[geometry, *rays, dpdu, dpdv, frames, hit], device="cpu")
    dpdu, dpdv, frames, hit = dpdu.numpy(), dpdv.numpy(), frames.numpy(), hit.numpy().astype(bool)
    mi_scene = mi.load_file(str(path))
    compared = 0
    for k in np.flatnonzero(hit):
        si = mi_scene.ray_intersect(
            mi.Ray3f(mi.Point3f(*map(float, origins[k])), mi.Vector3f(*map(float, directions[k])))
        )
        mi_dpdu = np.array(si.dp_du, dtype=np.float64)
        if not si.is_valid() or np.linalg.norm(mi_dpdu) < 1e-3:  # a miss at an edge, or near a pole or centre
            continue
        np.testing.assert_allclose(dpdu[k], mi_dpdu, atol=2e-3 * np.linalg.norm(mi_dpdu), err_msg=name)
        mi_dpdv = np.array(si.dp_dv, dtype=np.float64)
        np.testing.assert_allclose(dpdv[k], mi_dpdv, atol=2e-3 * np.linalg.norm(mi_dpdv), err_msg=name)
        mi_frame = np.array([si.sh_frame.s, si.sh_frame.t, si.sh_frame.n], dtype=np.float64)
        np.testing.assert_allclose(frames[k], mi_frame, atol=2e-3, err_msg=name)
        compared += 1
    assert compared > n // 8


@wp.kernel
def perturb(
    n: wp.array(dtype=wp.vec3),
    dpdu: wp.array(dtype=wp.vec3),
    rgb: wp.array(dtype=wp.vec3),
    out: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    out[i] = perturbed_normal(n[i], dpdu[i], rgb[i])


def perturbed_reference(n, dpdu, rgb):
    """float64: normalize(2 rgb - 1) in the frame (s, t, n), s = dpdu made orthogonal to n."""
    s = dpdu - np.sum(n * dpdu, axis=1, keepdims=True) * n
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    t = np.cross(n, s)
    m = 2.0 * rgb - 1.0
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    return m[:, :1] * s + m[:, 1:2] * t + m[:, 2:] * n


def run_perturb(n, dpdu, rgb):
    out = wp.zeros(len(n), wp.vec3)
    arrays = [wp.array(np.asarray(a, np.float32), dtype=wp.vec3) for a in (n, dpdu, rgb)]
    wp.launch(perturb, dim=len(n), inputs=[*arrays, out], device="cpu")
    return out.numpy().astype(np.float64)


def test_perturbed_normal_float64():
    """The perturbed normal equals the float64 reference for random normals, tangents (of any
    length, not orthogonal to the normal) and texels; a texel of (1/2, 1/2, 1) gives the normal
    itself bit for bit; a tangent along the normal falls back to ``frame(n)``'s."""
    rng = np.random.default_rng(3)
    n = rng.normal(size=(500, 3))
    n = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    dpdu = (rng.normal(size=(500, 3)) * rng.uniform(0.1, 10.0, (500, 1))).astype(np.float32)
    rgb = rng.uniform(0.0, 1.0, (500, 3)).astype(np.float32)
    got = run_perturb(n, dpdu, rgb)
    expected = perturbed_reference(n.astype(np.float64), dpdu.astype(np.float64), rgb.astype(np.float64))
    np.testing.assert_allclose(got, expected, atol=2e-5)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-6)
    flat = run_perturb(n, dpdu, np.tile(np.float32([0.5, 0.5, 1.0]), (500, 1)))
    assert np.array_equal(flat.astype(np.float32), n)
    along = run_perturb([[0.0, 0.0, 1.0]], [[0.0, 0.0, 2.0]], [[1.0, 0.5, 0.5]])
    np.testing.assert_array_equal(along, [[1.0, 0.0, 0.0]])  # Duff et al.'s s of +z, Mitsuba's coordinate_system


@wp.kernel
def hit_normals(
    geometry: GeometryData,
    materials: MaterialData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    out_n: wp.array(dtype=wp.vec3),
    out_front: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    t, prim, inst = closest_hit(geometry, origins[i], directions[i], 0.0, 0.0, wp.inf)
    if prim != NO_HIT:
        hit = surface_hit(geometry, materials, ray_hit(origins[i], directions[i], 0.0, t, prim, inst))
        out_n[i] = hit.n_facing
        out_front[i] = wp.where(hit.front, 1, 0)


def test_hit_normal_of_a_normal_mapped_sphere(tmp_path):
    """``surface_hit``'s shading normal on a sphere under a uniform, strongly tilted normal map is
    the float64 perturbation of the sphere's normal in its frame (s along 2 pi (-y, x, 0)), mirrored
    about the sphere's normal where the ray sees the perturbed surface from below but the sphere
    from outside (as Mitsuba 3's ``normalmap``), turned to the ray's side; ``front`` is the side of
    the sphere."""
    write_png(tmp_path / "tilt.png", np.full((2, 2, 3), (230, 60, 170), np.uint8))
    scene = parse_scene(
        {
            "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
            "material": [{"name": "m", "normal_map": {"texture": "bitmap", "file": "tilt.png"}}],
            "shape": [{"type": "sphere", "center": [0.2, -0.1, 0.3], "radius": 0.9, "material": "m"}],
        },
        scene_dir=str(tmp_path),
    )
    origins, directions = rays_toward(np.random.default_rng(5), (0.2, -0.1, 0.3), 0.9, n=300)
    geometry = upload_geometry(build(scene, "cpu"), "cpu")
    materials = upload_materials(scene, "cpu")
    n_out, front = wp.zeros(len(origins), wp.vec3), wp.full(len(origins), -1, dtype=wp.int32)
    inputs = [geometry, materials, wp.array(origins, dtype=wp.vec3), wp.array(directions, dtype=wp.vec3)]
    wp.launch(hit_normals, dim=len(origins), inputs=[*inputs, n_out, front], device="cpu")
    n_out, front = n_out.numpy().astype(np.float64), front.numpy()
    hit = front >= 0
    assert np.count_nonzero(hit) > 100
    o, d = origins[hit].astype(np.float64), directions[hit].astype(np.float64)
    c = np.array([0.2, -0.1, 0.3])
    b = np.sum(d * (o - c), axis=1)
    root = np.sqrt(b * b - np.sum((o - c) ** 2, axis=1) + 0.81)
    t = np.where(-b - root > 0.0, -b - root, -b + root)  # the far side from inside
    normal = (o + t[:, None] * d - c) / 0.9
    dpdu = np.stack([-normal[:, 1], normal[:, 0], np.zeros(len(normal))], axis=1)
    expected = perturbed_reference(normal, dpdu, np.tile(np.array([230, 60, 170]) / 255.0, (len(normal), 1)))
    below = np.sum(expected * d, axis=1) * np.sum(normal * d, axis=1) < 0.0  # one surface's side only
    expected = np.where(below[:, None], 2.0 * np.sum(expected * normal, axis=1)[:, None] * normal - expected, expected)
    facing = np.sum(normal * d, axis=1) < 0.0
    np.testing.assert_array_equal(front[hit].astype(bool), facing)
    np.testing.assert_allclose(n_out[hit], np.where(facing[:, None], expected, -expected), atol=1e-4)
    assert below.any() and not facing.all()  # some rays see the perturbed surface from below, some leave the sphere


FLAT_SCENE = {
    "render": {"width": 24, "height": 18, "spp": 4, "max_depth": 4},
    "camera": {"origin": [0.0, 1.4, 3.0], "look_at": [0.0, 0.4, 0.0], "fov": 40.0},
    "shape": [
        {"type": "sphere", "center": [0.0, 0.6, 0.0], "radius": 0.6, "material": "ball"},
        {
            "type": "polygon",
            "vertices": [[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]],
            "uv": [[0, 0], [2, 0], [2, 3], [0, 3]],
            "material": "floor",
        },
    ],
}
LIGHTS = {
    "path": [
        {"type": "area", "corner": [-1, 3, -0.5], "edge_u": [2, 0, 0], "edge_v": [0, 0, 1], "radiance": [8, 8, 8]},
        {"type": "environment", "radiance": [0.1, 0.1, 0.1]},
    ],
    "whitted": [{"type": "point", "position": [1.0, 3.0, 2.0], "intensity": [20.0, 20.0, 20.0]}],
}


@pytest.mark.parametrize("integrator", ["path", "whitted"])
def test_flat_normal_map_renders_as_none(tmp_path, integrator):
    """A normal map of tangent-space normal (0, 0, 1) everywhere (texels exactly (1/2, 1/2, 1): a
    float file, as 8 bits cannot hold 1/2) renders bit for bit the image without one, in the
    all-features kernel and (path) the scene's own variant. (An 8-bit "flat" map, (128, 128, 255),
    tilts normals by 0.3 degrees, as in Mitsuba.)"""
    write_exr(tmp_path / "flat.exr", np.tile(np.float32([0.5, 0.5, 1.0]), (3, 4, 1)))
    flat = {"texture": "bitmap", "file": "flat.exr", "filter": "nearest"}
    images = {}
    for mapped in (False, True):
        extra = {"normal_map": flat} if mapped else {}
        materials = [
            {"name": "ball", "type": "phong" if integrator == "whitted" else "rough_plastic", **extra},
            {"name": "floor", "albedo": [0.6, 0.5, 0.4], **extra},
        ]
        scene = parse_scene(
            {**FLAT_SCENE, "render": {**FLAT_SCENE["render"], "integrator": integrator}, "material": materials,
             "light": LIGHTS[integrator]},
            scene_dir=str(tmp_path),
        )  # fmt: skip
        assert scene_features(scene).normal_map == mapped
        for specialize in (False, True) if mapped and integrator == "path" else (False,):
            images[mapped, specialize] = wrt.render(scene, specialize=specialize).rgb
    assert images[False, False].max() > 0.05
    for key, image in images.items():
        np.testing.assert_array_equal(image, images[False, False], err_msg=str(key))


@pytest.mark.parametrize(
    "table, key, problem",
    [
        ('"normal.png"', "normal_map", 'texture = "bitmap"'),
        ('{ texture = "checkerboard" }', "normal_map", 'texture = "bitmap"'),
        ('{ texture = "bitmap", file = "normal.png", raw = false }', "normal_map.raw", "always read raw"),
        ('{ texture = "bitmap", file = "bright.exr" }', "normal_map.file", "must stay in [0, 1]"),
        ('{ texture = "bitmap", file = "normal.png", wrap = "tile" }', "normal_map.wrap", "one of"),
    ],
)
def test_bad_normal_maps_are_refused(tmp_path, table, key, problem):
    write_png(tmp_path / "normal.png", np.full((2, 2, 3), (128, 128, 255), np.uint8))
    write_exr(tmp_path / "bright.exr", np.full((2, 2, 3), 2.0))
    path = tmp_path / "scene.toml"
    path.write_text(
        f'[camera]\norigin = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[material]]\nname = "m"\nnormal_map = {table}\n'
    )
    with pytest.raises(SceneError) as error:
        load_scene(path)
    assert key in str(error.value) and problem in str(error.value), str(error.value)


def test_normal_map_is_read_raw(tmp_path):
    """An 8-bit normal map's texels are its bytes / 255, never sRGB-decoded."""
    write_png(tmp_path / "normal.png", np.full((1, 1, 3), (200, 90, 230), np.uint8))
    scene = parse_scene(
        {
            "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
            "material": [{"name": "m", "normal_map": {"texture": "bitmap", "file": "normal.png"}}],
        },
        scene_dir=str(tmp_path),
    )
    ((name, texture),) = scene.materials[0].textures
    assert name == "normal_map" and texture.raw
    np.testing.assert_allclose(texture.texels[0, 0], np.array([200, 90, 230]) / 255.0, rtol=1e-6)


NORMALMAP_XML = """<scene version="3.0.0">
<bsdf type="normalmap" id="bumpy">
  <texture name="normalmap" type="bitmap"><string name="filename" value="normal.png"/>{raw}</texture>{shadowing}
  <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf></bsdf>
</bsdf>
<shape type="rectangle"><ref id="bumpy"/></shape>
</scene>
"""


@pytest.mark.parametrize(
    "raw, shadowing, refused",
    [
        ('<boolean name="raw" value="true"/>', "", 0),
        ("", "", 1),
        ('<boolean name="raw" value="true"/>', '<boolean name="use_shadowing_function" value="false"/>', 1),
    ],
    ids=["exact", "srgb", "no_shadowing"],
)
def test_mitsuba_normalmap_is_converted_or_refused(tmp_path, raw, shadowing, refused):
    """Mitsuba 3's ``normalmap`` with a raw map becomes the nested BSDF with the map as its
    ``normal_map``, exactly (its shadowing function included); a map Mitsuba would sRGB-decode,
    or the shadowing function turned off, is refused by default and converted with ``approximate``."""
    write_png(tmp_path / "normal.png", np.full((2, 2, 3), (150, 120, 240), np.uint8))
    path = tmp_path / "scene.xml"
    path.write_text(NORMALMAP_XML.format(raw=raw, shadowing=shadowing))
    if refused:
        with pytest.raises(WrtError, match="not converted exactly"):
            load_scene(path)
    scene = load_scene(path, approximate=bool(refused))
    material = scene.materials[scene.shapes[0].material]
    assert material.two_sided and material.albedo == (0.2, 0.4, 0.6)
    ((name, texture),) = material.textures
    assert name == "normal_map" and texture.raw
    assert len(scene.approximations) == refused


def bump_shadowing(cos_i, cos_d):
    """Mitsuba 3.9.1's factor on a normal-mapped BSDF (the shadow terminator term of Chiang et al.
    2019): GGX's G1 of the light direction against the unperturbed normal (``cos_i``), with
    alpha^2 = tan^2(theta_d) / 8 of the angle between the unperturbed and perturbed normals."""
    alpha2 = np.clip(0.125 * (1.0 - cos_d**2) / cos_d**2, 0.0, 1.0)
    tan2_i = (1.0 - cos_i**2) / np.maximum(cos_i**2, 1e-12)
    return np.where(cos_i > 0.0, 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * tan2_i)), 0.0)


MITSUBA_NORMALMAP = """<scene version="3.0.0">
<bsdf type="normalmap" id="bumpy">
  <texture name="normalmap" type="bitmap"><string name="filename" value="tilt.png"/>
    <boolean name="raw" value="true"/><string name="filter_type" value="nearest"/></texture>
  <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
</bsdf>
<shape type="rectangle"><transform name="to_world"><rotate x="0.8" y="0.6" angle="-50"/><translate z="-1"/></transform>
  <ref id="bumpy"/></shape>
<shape type="sphere"><point name="center" x="0.3" y="0.2" z="0.2"/><float name="radius" value="0.5"/>
  <ref id="bumpy"/></shape>
</scene>
"""


@needs_mitsuba
def test_perturbed_normal_is_mitsubas_normalmap(tmp_path):
    """Mitsuba's own ``normalmap`` around a diffuse BSDF, evaluated at the hits of the same rays on a
    rectangle and a sphere: ``eval * pi / albedo`` is the cosine of the light direction against
    wrt's perturbed normal, times Mitsuba 3's shadowing function (``bump_shadowing``, which the
    kernels apply as ``normal_map_shadowing``). Fitting this pins the perturbed frame (its
    tangent, handedness and the raw texel decoding) to Mitsuba's."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    write_png(tmp_path / "tilt.png", np.full((2, 2, 3), (200, 90, 230), np.uint8))
    path = tmp_path / "scene.xml"
    path.write_text(MITSUBA_NORMALMAP)
    scene = load_scene(path, approximate=True)
    rng = np.random.default_rng(11)
    origins = (rng.uniform(-0.6, 0.6, (200, 3)) + [0.0, 0.0, 3.0]).astype(np.float32)
    aims = rng.uniform(-0.7, 0.7, (200, 3)) * [1.0, 1.0, 0.0]
    directions = aims - origins
    directions = (directions / np.linalg.norm(directions, axis=1, keepdims=True)).astype(np.float32)
    geometry, materials = upload_geometry(build(scene, "cpu"), "cpu"), upload_materials(scene, "cpu")
    n_out, front = wp.zeros(len(origins), wp.vec3), wp.full(len(origins), -1, dtype=wp.int32)
    inputs = [geometry, materials, wp.array(origins, dtype=wp.vec3), wp.array(directions, dtype=wp.vec3)]
    wp.launch(hit_normals, dim=len(origins), inputs=[*inputs, n_out, front], device="cpu")
    n_out, front = n_out.numpy().astype(np.float64), front.numpy()
    mi_scene = mi.load_file(str(path))
    lights = rng.normal(size=(8, 3))
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    compared = 0
    for k in np.flatnonzero(front == 1):
        si = mi_scene.ray_intersect(
            mi.Ray3f(mi.Point3f(*map(float, origins[k])), mi.Vector3f(*map(float, directions[k])))
        )
        if not si.is_valid():
            continue
        n = np.array(si.sh_frame.n, dtype=np.float64)
        bsdf = si.bsdf()
        for wo in lights:
            value = np.array(bsdf.eval(mi.BSDFContext(), si, si.to_local(mi.Vector3f(*wo))))[0] * np.pi / 0.5
            cos_o = np.dot(wo, n_out[k])
            expected = max(cos_o, 0.0) * bump_shadowing(np.dot(wo, n), np.dot(n, n_out[k]))
            assert abs(value - expected) < 2e-3, (k, wo, value, expected)
            compared += cos_o > 0.05 and np.dot(wo, n) > 0.05
    assert compared > 300


@needs_mitsuba
def test_normal_map_at_grazing_views_is_mitsubas():
    """At the hits of grazing camera rays on examples/mitsuba/normal_map.xml's floor, wrt's shading
    normal and shadowing reproduce Mitsuba 3's ``normalmap`` ``eval`` for 12 light directions,
    including the hits that see the mapped surface from below (the view above the unmapped
    surface): Mitsuba mirrors the mapped normal about the unmapped one there. Shading those hits
    with the mapped normal turned around instead made the whole image 1.5-2.4% darker."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    path = EXAMPLES / "mitsuba" / "normal_map.xml"
    scene = load_scene(path)
    rng = np.random.default_rng(5)
    n = 600
    camera = np.array([0.0, 1.6, 3.6])
    targets = np.c_[rng.uniform(-3, 3, n), np.zeros(n), rng.uniform(-3, 0, n)]
    directions = targets - camera
    directions = (directions / np.linalg.norm(directions, axis=1, keepdims=True)).astype(np.float32)
    origins = np.repeat(camera[None], n, 0).astype(np.float32)
    geometry, materials = upload_geometry(build(scene, "cpu"), "cpu"), upload_materials(scene, "cpu")
    n_out, front = wp.zeros(n, wp.vec3), wp.full(n, -1, dtype=wp.int32)
    inputs = [geometry, materials, wp.array(origins, dtype=wp.vec3), wp.array(directions, dtype=wp.vec3)]
    wp.launch(hit_normals, dim=n, inputs=[*inputs, n_out, front], device="cpu")
    n_out, front = n_out.numpy().astype(np.float64), front.numpy()
    mi_scene = mi.load_file(str(path))
    lights = rng.normal(size=(12, 3))
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    mirrored = 0
    for k in np.flatnonzero(front >= 0):
        si = mi_scene.ray_intersect(
            mi.Ray3f(mi.Point3f(*map(float, origins[k])), mi.Vector3f(*map(float, directions[k])))
        )
        if si.shape.is_emitter():  # the lamp: no normal map
            continue
        unmapped = np.array(si.sh_frame.n, dtype=np.float64) * (1.0 if front[k] else -1.0)
        mapped = 2.0 * np.dot(n_out[k], unmapped) * unmapped - n_out[k]  # the normal before any mirroring
        mirrored += np.dot(-directions[k], mapped) < 0.0
        bsdf = si.bsdf()
        albedo = np.array(bsdf.eval_diffuse_reflectance(si))[0]
        for wo in lights:
            value = np.array(bsdf.eval(mi.BSDFContext(), si, si.to_local(mi.Vector3f(*wo))))[0] * np.pi / albedo
            cos_o = np.dot(wo, n_out[k])
            cos_i = np.dot(wo, unmapped)
            expected = max(cos_o, 0.0) * float(bump_shadowing(cos_i, np.dot(unmapped, n_out[k])))
            assert abs(value - expected) < 1e-3, (k, wo, value, expected)
    assert mirrored > 50


def test_a_constant_normal_map_of_no_tilt_renders_bit_for_bit_as_none():
    """``normal_map = { texture = "constant", value = [0.5, 0.5, 1] }`` (Mitsuba's ``rawconstant``, or
    an ``<rgb>`` normalmap): ``perturbed_normal`` returns the normal itself and the shadowing
    function 1, so the image is the unmapped one bit for bit (the all-features kernel renders both);
    a tilted constant changes it."""
    images = []
    for normal_map in (None, [0.5, 0.5, 1.0], [0.7, 0.5, 0.8]):
        material = {"name": "m", "type": "conductor", "metal": "Au", "roughness": 0.2, "roughness_v": 0.05}
        if normal_map is not None:
            material["normal_map"] = {"texture": "constant", "value": normal_map}
        scene = parse_scene(
            {
                "render": {"width": 16, "height": 12, "spp": 4, "integrator": "path"},
                "camera": {"origin": [0, 0, 4], "look_at": [0, 0, 0]},
                "material": [material],
                "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "m"}],
                "light": [{"type": "point", "position": [2, 2, 4], "intensity": [20, 20, 20]}],
            }
        )
        images.append(wrt.render(scene, specialize=False).rgb)
    assert np.array_equal(images[0], images[1]) and not np.array_equal(images[0], images[2])
    with pytest.raises(SceneError, match=r"normal_map\.value = \[1\.5, 0\.5, 1\]: its value ranges over"):
        parse_scene(
            {
                "camera": {"origin": [0, 0, 4], "look_at": [0, 0, 0]},
                "material": [{"name": "m", "normal_map": {"texture": "constant", "value": [1.5, 0.5, 1]}}],
                "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "m"}],
            }
        )
