"""Texture coordinates and textures: surface uv of every shape kind and texture lookups checked
against Mitsuba 3 (``si.uv`` of the same rays, a texture plugin's ``eval`` at the same uv), the
scene format's texture tables and their errors, and the Mitsuba importer's texture conversion."""

import re
import textwrap

import numpy as np
import OpenImageIO as oiio
import pytest
import warp as wp
from conftest import EXAMPLES
from wrt.kernels.materials import MaterialData
from wrt.kernels.textures import ALBEDO, TextureData, material_rgb, texture_float, texture_rgb, uv_context
from wrt.kernels.traverse import NO_HIT, GeometryData, closest_hit, hit_point, prim_shape, ray_hit, texture_context
from wrt_harness.mitsuba_peer import mitsuba_available

import wrt
from wrt.device import upload_geometry, upload_materials, upload_textures
from wrt.errors import SceneError, WrtError
from wrt.geometry import build
from wrt.loader import load_scene, parse_scene

MITSUBA, MITSUBA_REASON = mitsuba_available()
needs_mitsuba = pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)


@wp.kernel
def trace_uv(
    geometry: GeometryData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    out_uv: wp.array(dtype=wp.vec2),
    out_hit: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    o = origins[i]
    d = directions[i]
    t, prim, inst = closest_hit(geometry, o, d, 0.0, 0.0, wp.inf)
    out_hit[i] = wp.where(prim == NO_HIT, 0, 1)
    if prim != NO_HIT:
        p, _n, _err = hit_point(geometry, ray_hit(o, d, 0.0, t, prim, inst))
        out_uv[i] = texture_context(geometry, prim, inst, p, 0.0).uv


@wp.kernel
def lookup(
    textures: TextureData,
    t: wp.int32,
    uvs: wp.array(dtype=wp.vec2),
    out_rgb: wp.array(dtype=wp.vec3),
    out_float: wp.array(dtype=float),
):
    i = wp.tid()
    out_rgb[i] = texture_rgb(textures, t, uv_context(uvs[i]))
    out_float[i] = texture_float(textures, t, uv_context(uvs[i]))


def wrt_uv(scene, origins, directions):
    """(uv (N, 2), hit (N,)) of wrt's closest hits of unit rays."""
    geometry = upload_geometry(build(scene, "cpu"), "cpu")
    n = len(origins)
    uv, hit = wp.zeros(n, dtype=wp.vec2, device="cpu"), wp.zeros(n, dtype=wp.int32, device="cpu")
    inputs = [geometry, wp.array(origins, dtype=wp.vec3), wp.array(directions, dtype=wp.vec3), uv, hit]
    wp.launch(trace_uv, dim=n, inputs=inputs, device="cpu")
    return uv.numpy(), hit.numpy().astype(bool)


def rays_toward(rng, target, spread, n=400):
    """Unit rays from random points around ``target`` (a box of half size 4 * spread) aimed at
    random points within ``spread`` of it."""
    target = np.asarray(target, dtype=np.float64)
    origins = target + rng.uniform(-4.0, 4.0, (n, 3)) * spread
    aims = target + rng.uniform(-1.0, 1.0, (n, 3)) * spread
    directions = aims - origins
    return origins.astype(np.float32), (directions / np.linalg.norm(directions, axis=1, keepdims=True)).astype(
        np.float32
    )


def scene_xml(tmp_path, shape, textured=True):
    """A Mitsuba scene holding one ``shape`` element body (its BSDF a checkerboard diffuse)."""
    bsdf = '<bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf>' if textured else ""
    body = shape.replace("BSDF", bsdf)
    path = tmp_path / "scene.xml"
    path.write_text(
        '<scene version="3.0.0">\n<sensor type="perspective"><film type="hdrfilm">'
        '<integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>\n'
        f"{textwrap.dedent(body)}\n</scene>\n"
    )
    return path


OBJ = """v -1 -1 0.2
v 1 -1 0
v 1 1 0
v -1 1 0.1
vt 0.1 0.2
vt 0.9 0.3
vt 0.8 0.95
vt 0.05 0.7
f 1/1 2/2 3/3 4/4
"""
PLY_HEADER = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
PLY_BODY = "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
PLY_VERTICES = [(-1, -1, 0.2, 0.1, 0.2), (1, -1, 0, 0.9, 0.3), (1, 1, 0, 0.8, 0.95), (-1, 1, 0.1, 0.05, 0.7)]


def write_meshes(tmp_path):
    (tmp_path / "quad.obj").write_text(OBJ)
    uv_props = "property float u\nproperty float v\n"
    with_uv = "".join(" ".join(map(str, v)) + "\n" for v in PLY_VERTICES)
    without_uv = "".join(" ".join(map(str, v[:3])) + "\n" for v in PLY_VERTICES)
    faces = "3 0 1 2\n3 0 2 3\n"
    (tmp_path / "quad_uv.ply").write_text(PLY_HEADER + uv_props + PLY_BODY + with_uv + faces)
    (tmp_path / "quad.ply").write_text(PLY_HEADER + PLY_BODY + without_uv + faces)


TRANSFORM = '<transform name="to_world"><scale x="1.5" y="0.7" z="1.2"/><rotate x="0" y="0.6" z="0.8" angle="35"/>'
SHAPES = {
    "sphere": ('<shape type="sphere"><point name="center" x="0.3" y="-0.2" z="0.1"/>'
               '<float name="radius" value="0.8"/>BSDF</shape>', (0.3, -0.2, 0.1), 0.8),
    "sphere rotated": ('<shape type="sphere"><point name="center" x="0.3" y="-0.2" z="0.1"/>'
                       '<float name="radius" value="0.8"/><transform name="to_world"><rotate x="1" angle="-70"/>'
                       '<rotate z="1" angle="25"/><scale value="1.2"/><translate y="0.3"/></transform>BSDF</shape>',
                       (0.3, 0.06, 0.35), 0.96),
    "rectangle": (f'<shape type="rectangle">{TRANSFORM}<translate x="0.2"/></transform>BSDF</shape>', (0.2, 0, 0), 1.0),
    "cube": (f'<shape type="cube">{TRANSFORM}<translate x="0.2"/></transform>BSDF</shape>', (0.2, 0, 0), 1.2),
    "cube mirrored": ('<shape type="cube"><transform name="to_world"><scale x="-1" y="0.8" z="1.2"/>'
                      "</transform>BSDF</shape>", (0, 0, 0), 1.0),
    "rectangle mirrored": ('<shape type="rectangle"><transform name="to_world"><scale x="-2" y="1" z="1"/>'
                           "</transform>BSDF</shape>", (0, 0, 0), 1.0),
    "disk": (f'<shape type="disk">{TRANSFORM}</transform>BSDF</shape>', (0, 0, 0), 1.0),
    "disk flipped": (f'<shape type="disk">{TRANSFORM}</transform><boolean name="flip_normals" value="true"/>BSDF'
                     "</shape>", (0, 0, 0), 1.0),
    "cylinder": ('<shape type="cylinder"><point name="p0" x="0.1" y="0.2" z="-0.5"/>'
                 '<point name="p1" x="-0.3" y="0.1" z="0.7"/><float name="radius" value="0.4"/>BSDF</shape>',
                 (0, 0.15, 0.1), 0.6),
    "obj with vt": (f'<shape type="obj"><string name="filename" value="quad.obj"/>{TRANSFORM}</transform>BSDF'
                    "</shape>", (0, 0, 0), 1.0),
    "ply with uv": ('<shape type="ply"><string name="filename" value="quad_uv.ply"/>BSDF</shape>', (0, 0, 0), 1.0),
    "ply without uv": ('<shape type="ply"><string name="filename" value="quad.ply"/>'
                       '<boolean name="face_normals" value="true"/>BSDF</shape>', (0, 0, 0), 1.0),
    "instance": ('<shape type="shapegroup" id="g"><shape type="ply"><string name="filename" value="quad_uv.ply"/>'
                 'BSDF</shape><shape type="sphere"><point name="center" x="0" y="0" z="-2"/>'
                 '<float name="radius" value="0.5"/>BSDF</shape></shape>'
                 f'<shape type="instance"><ref id="g"/>{TRANSFORM}<translate z="1"/></transform></shape>',
                 (0, 0, 0), 2.5),
}  # fmt: skip
PERIODIC = {
    "sphere": (0,),
    "sphere rotated": (0,),
    "disk": (1,),
    "disk flipped": (1,),
    "cylinder": (0,),
    "instance": (0,),
}
"""Coordinates that wrap around (an angle in turns): compared modulo 1."""


@needs_mitsuba
@pytest.mark.parametrize("name", SHAPES)
def test_surface_uv_is_mitsubas(tmp_path, name):
    """The uv of wrt's hits equals Mitsuba's ``si.uv`` for the same rays, on every shape kind
    Mitsuba has (meshes with and without texture coordinates, instances: object space)."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    write_meshes(tmp_path)
    body, target, spread = SHAPES[name]
    path = scene_xml(tmp_path, body)
    scene = load_scene(path)
    origins, directions = rays_toward(np.random.default_rng(len(name)), target, spread)
    uv, hit = wrt_uv(scene, origins, directions)
    mi_scene = mi.load_file(str(path))
    mi_uv, mi_hit = np.zeros((len(origins), 2)), np.zeros(len(origins), dtype=bool)
    for k, (o, d) in enumerate(zip(origins, directions)):
        si = mi_scene.ray_intersect(mi.Ray3f(mi.Point3f(*map(float, o)), mi.Vector3f(*map(float, d))))
        mi_hit[k] = bool(si.is_valid())
        mi_uv[k] = si.uv
    assert np.count_nonzero(hit) > len(hit) // 8  # the test looks at hits
    agree = hit == mi_hit
    assert np.count_nonzero(~agree) <= 2, "wrt and Mitsuba hit different rays"
    both = hit & mi_hit
    difference = np.abs(uv[both] - mi_uv[both])
    for axis in PERIODIC.get(name, ()):
        difference[:, axis] = np.minimum(difference[:, axis], 1.0 - difference[:, axis])
    assert difference.max() < 2e-4, (name, difference.max(), uv[both][difference.max(axis=1).argmax()])


def write_png(path, pixels):
    """An 8-bit (or 16-bit for uint16 ``pixels``) image file of ``pixels`` (H, W, C)."""
    out = oiio.ImageOutput.create(str(path))
    h, w, c = pixels.shape
    out.open(str(path), oiio.ImageSpec(w, h, c, "uint16" if pixels.dtype == np.uint16 else "uint8"))
    out.write_image(pixels)
    out.close()


def write_exr(path, pixels):
    out = oiio.ImageOutput.create(str(path))
    h, w, c = pixels.shape
    out.open(str(path), oiio.ImageSpec(w, h, c, "float"))
    out.write_image(pixels.astype(np.float32))
    out.close()


def wrt_lookup(scene, uvs):
    """(rgb (N, 3), luminance (N,)) of wrt's lookup of the scene's first texture at ``uvs``."""
    textures = upload_textures(scene, "cpu")
    rgb, value = wp.zeros(len(uvs), dtype=wp.vec3), wp.zeros(len(uvs), dtype=float)
    wp.launch(lookup, dim=len(uvs), inputs=[textures, 0, wp.array(uvs, dtype=wp.vec2), rgb, value], device="cpu")
    return rgb.numpy(), value.numpy()


IMAGE = np.random.default_rng(7).integers(0, 256, (5, 7, 3)).astype(np.uint8)
TO_UV = (
    '<transform name="to_uv"><scale x="2" y="3"/><rotate z="1" angle="30"/><translate x="0.25" y="-0.5"/></transform>'
)
TEXTURES = {
    "checkerboard": ('<texture type="checkerboard"><rgb name="color0" value="0.9, 0.5, 0.1"/>'
                     '<rgb name="color1" value="0.05, 0.2, 0.3"/></texture>'),
    "checkerboard to_uv": f'<texture type="checkerboard">{TO_UV}</texture>',
    "bitmap bilinear repeat": '<texture type="bitmap"><string name="filename" value="image.png"/></texture>',
    "bitmap nearest mirror": ('<texture type="bitmap"><string name="filename" value="image.png"/>'
                              '<string name="filter_type" value="nearest"/>'
                              '<string name="wrap_mode" value="mirror"/></texture>'),
    "bitmap bilinear mirror": ('<texture type="bitmap"><string name="filename" value="image.png"/>'
                               '<string name="wrap_mode" value="mirror"/></texture>'),
    "bitmap bilinear clamp raw to_uv": ('<texture type="bitmap"><string name="filename" value="image.png"/>'
                                        '<string name="wrap_mode" value="clamp"/><boolean name="raw" value="true"/>'
                                        f"{TO_UV}</texture>"),
    "bitmap grey": '<texture type="bitmap"><string name="filename" value="grey.png"/></texture>',
    "bitmap 16-bit": '<texture type="bitmap"><string name="filename" value="deep.png"/></texture>',
    "bitmap exr": '<texture type="bitmap"><string name="filename" value="image.exr"/></texture>',
    "rawconstant": '<texture type="rawconstant"><vector name="value" x="0.2" y="0.7" z="0.9"/></texture>',
    "rawconstant float": '<texture type="rawconstant"><float name="value" value="0.35"/></texture>',
    "bitmap format variant": ('<texture type="bitmap"><string name="filename" value="image.exr"/>'
                              '<string name="format" value="variant"/></texture>'),
    "bitmap 8-bit format uint8": ('<texture type="bitmap"><string name="filename" value="image.png"/>'
                                  '<string name="format" value="uint8"/></texture>'),
}  # fmt: skip


@needs_mitsuba
@pytest.mark.parametrize("name", TEXTURES)
def test_texture_lookup_is_mitsubas(tmp_path, name):
    """wrt's lookup of a texture converted from Mitsuba XML equals Mitsuba's ``eval`` (RGB) and
    ``eval_1`` (luminance) at 400 uvs in [-1.5, 2.5]^2 (beyond the unit square: the wrap modes)."""
    import mitsuba as mi

    write_png(tmp_path / "image.png", IMAGE)
    write_png(tmp_path / "grey.png", IMAGE[..., :1])
    write_png(tmp_path / "deep.png", (IMAGE.astype(np.uint16) * 257)[::-1])
    write_exr(tmp_path / "image.exr", IMAGE / 257.0)
    nested = TEXTURES[name].replace("<texture ", '<texture name="reflectance" ', 1)
    path = scene_xml(tmp_path, f'<shape type="sphere"><bsdf type="diffuse">{nested}</bsdf></shape>', False)
    uvs = np.random.default_rng(3).uniform(-1.5, 2.5, (400, 2)).astype(np.float32)
    rgb, value = wrt_lookup(load_scene(path), uvs)
    mi.set_variant("scalar_rgb")
    xml = TEXTURES[name].replace("<texture ", '<texture version="3.0.0" ', 1)
    texture = mi.load_string(xml.replace('name="filename" value="', f'name="filename" value="{tmp_path}/'))
    si = mi.SurfaceInteraction3f()
    expected, expected_1 = np.zeros((len(uvs), 3)), np.zeros(len(uvs))
    for k, uv in enumerate(uvs):
        si.uv = mi.Point2f(*map(float, uv))
        expected[k] = texture.eval(si)
        # an RGB rawconstant has no eval_1 in Mitsuba (it raises): wrt's is its channels' mean
        expected_1[k] = expected[k].mean() if name == "rawconstant" else texture.eval_1(si)
    rtol = 5e-4 if "16-bit" in name else 1e-4  # Mitsuba decodes 16-bit sRGB to about 12 bits
    np.testing.assert_allclose(rgb, expected, rtol=rtol, atol=2e-5)
    if name.startswith("checkerboard"):  # Mitsuba's eval_1 swaps color0 and color1 (against eval): not followed
        expected_1 = expected.mean(axis=1)
    np.testing.assert_allclose(value, expected_1, rtol=rtol, atol=2e-5)


@pytest.mark.parametrize(
    "file, storage, problem",
    [
        ("image.exr", "uint8", "format uint8 of a file that is not 8 bits a channel: Mitsuba quantises"),
        ("image.png", "float16", "'format' = 'float16' must be one of variant, uint8"),
    ],
)
def test_a_bitmap_format_wrt_cannot_follow_is_refused(tmp_path, file, storage, problem):
    """``format``: ``variant`` is how wrt stores texels, ``uint8`` of an 8-bit file changes nothing
    (both against Mitsuba above); ``uint8`` of a float file (Mitsuba quantises it) is an
    approximation, refused by default; another name is an error, as in Mitsuba."""
    write_png(tmp_path / "image.png", IMAGE)
    write_exr(tmp_path / "image.exr", IMAGE / 257.0)
    texture = (
        f'<texture type="bitmap" name="reflectance"><string name="filename" value="{file}"/>'
        f'<string name="format" value="{storage}"/></texture>'
    )
    path = scene_xml(tmp_path, f'<shape type="sphere"><bsdf type="diffuse">{texture}</bsdf></shape>', False)
    with pytest.raises(WrtError, match=re.escape(problem)):
        load_scene(path)


@wp.kernel
def albedo_at_hits(
    geometry: GeometryData,
    materials: MaterialData,
    textures: TextureData,
    origins: wp.array(dtype=wp.vec3),
    directions: wp.array(dtype=wp.vec3),
    out_albedo: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    o = origins[i]
    d = directions[i]
    t, prim, inst = closest_hit(geometry, o, d, 0.0, 0.0, wp.inf)
    if prim != NO_HIT:
        p, _n, _err = hit_point(geometry, ray_hit(o, d, 0.0, t, prim, inst))
        m = materials.shape_material[prim_shape(geometry, prim)]
        uv = texture_context(geometry, prim, inst, p, 0.0).uv
        out_albedo[i] = material_rgb(textures, m, ALBEDO, uv_context(uv), materials.albedo[m])


@needs_mitsuba
def test_example_albedo_is_mitsubas():
    """The diffuse albedo at the camera's view of examples/mitsuba/textures.xml (a checkerboard
    floor by reference, a bitmap sphere): the whole path from the XML file to the lookup at a hit
    agrees with Mitsuba's ``eval_diffuse_reflectance`` for the same rays."""
    import mitsuba as mi

    path = EXAMPLES / "mitsuba" / "textures.xml"
    scene = load_scene(path)
    rng = np.random.default_rng(5)
    targets = rng.uniform([-2.5, 0.0, -2.5], [2.5, 1.4, 2.5], (600, 3))
    origins = np.tile(scene.camera.origin, (len(targets), 1))
    directions = targets - origins
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    geometry = upload_geometry(build(scene, "cpu"), "cpu")
    albedo = wp.zeros(len(origins), dtype=wp.vec3)
    inputs = [geometry, upload_materials(scene, "cpu"), upload_textures(scene, "cpu")]
    inputs += [wp.array(origins, dtype=wp.vec3), wp.array(directions, dtype=wp.vec3), albedo]
    wp.launch(albedo_at_hits, dim=len(origins), inputs=inputs, device="cpu")
    mi.set_variant("scalar_rgb")
    mi_scene = mi.load_file(str(path))
    expected = np.zeros((len(origins), 3))
    for k, (o, d) in enumerate(zip(origins.astype(np.float32), directions.astype(np.float32))):
        si = mi_scene.ray_intersect(mi.Ray3f(mi.Point3f(*map(float, o)), mi.Vector3f(*map(float, d))))
        if si.is_valid():
            expected[k] = si.bsdf().eval_diffuse_reflectance(si)
    textured = np.count_nonzero(np.ptp(expected, axis=0))
    assert textured  # the rays see texture variation
    close = np.all(np.abs(albedo.numpy() - expected) < 1e-3, axis=1)
    assert np.count_nonzero(~close) <= 3, np.flatnonzero(~close)  # a ray on a checker edge may differ


def texture_scene(tmp_path, table, key="albedo", kind="diffuse"):
    """A scene whose one material has ``key = table``, parsed from a dict."""
    doc = {
        "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
        "material": [{"name": "m", "type": kind, key: table}],
        "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
    }
    return parse_scene(doc, file="scene.toml", scene_dir=str(tmp_path))


def test_bitmap_lookup_closed_form(tmp_path):
    """A 2 x 2 linear (EXR) bitmap, texel (column, row) = (x, y) holding (x, y, 0.5): nearest
    picks the texel holding (u W, v H); bilinear weighs the texel centres at ((i + 1/2) / W,
    (j + 1/2) / H); outside [0, 1] repeat, mirror and clamp take the indices back."""
    pixels = np.zeros((2, 2, 3))
    pixels[..., 0] = [[0, 1], [0, 1]]
    pixels[..., 1] = [[0, 0], [1, 1]]
    pixels[..., 2] = 0.5
    write_exr(tmp_path / "ramp.exr", pixels)
    uvs = np.array([[0.1, 0.1], [0.9, 0.2], [0.5, 0.5], [0.375, 0.625], [1.1, 0.1], [-0.1, 0.1], [1.6, 0.1]])

    def at(filter, wrap):
        scene = texture_scene(tmp_path, {"texture": "bitmap", "file": "ramp.exr", "filter": filter, "wrap": wrap})
        return wrt_lookup(scene, uvs.astype(np.float32))[0][:, :2]

    nearest = {  # texel (floor(2u), floor(2v)), wrapped
        "repeat": [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0], [1, 0], [1, 0]],
        "mirror": [[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [0, 0], [0, 0]],
        "clamp": [[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [0, 0], [1, 0]],
    }
    # bilinear: x = 2u - 1/2 between texels i = floor(x) and i + 1 (wrapped), weights 1 - frac(x)
    # and frac(x); e.g. u = 0.1: x = -0.3, texels -1 and 0 weighted 0.3 and 0.7 (repeat: -1 is 1)
    bilinear = {
        "repeat": [[0.3, 0.3], [0.7, 0.1], [0.5, 0.5], [0.25, 0.75], [0.3, 0.3], [0.7, 0.3], [0.7, 0.3]],
        "mirror": [[0.0, 0.0], [1.0, 0.0], [0.5, 0.5], [0.25, 0.75], [1.0, 0.0], [0.0, 0.0], [0.3, 0.0]],
        "clamp": [[0.0, 0.0], [1.0, 0.0], [0.5, 0.5], [0.25, 0.75], [1.0, 0.0], [0.0, 0.0], [1.0, 0.0]],
    }
    for wrap in ("repeat", "mirror", "clamp"):
        np.testing.assert_allclose(at("nearest", wrap), nearest[wrap], atol=1e-6, err_msg=wrap)
        np.testing.assert_allclose(at("bilinear", wrap), bilinear[wrap], atol=1e-6, err_msg=wrap)


@pytest.mark.parametrize(
    ("table", "key", "problem"),
    [
        ({"texture": "marble"}, "albedo.texture", "must be one of constant, checkerboard, bitmap"),
        ({"texture": "bitmap"}, "albedo.file", "is required"),
        ({"texture": "bitmap", "file": "nowhere.png"}, "albedo.file", "no such file"),
        ({"texture": "bitmap", "file": "image.png", "filter": "cubic"}, "albedo.filter", "must be one of"),
        ({"texture": "bitmap", "file": "image.png", "wrap": "tile"}, "albedo.wrap", "must be one of"),
        ({"texture": "bitmap", "file": "bright.exr"}, "albedo.file", "albedo must stay in [0, 1]"),
        ({"texture": "checkerboard", "color0": [1.5, 0, 0]}, "albedo.texture", "albedo must stay in [0, 1]"),
        ({"texture": "checkerboard", "scale": 2, "to_uv": [1, 0, 0, 0, 1, 0]}, "albedo.scale", "give one of them"),
        ({"texture": "checkerboard", "scale": [1, 2, 3]}, "albedo.scale", "2 finite numbers"),
        ({"texture": "checkerboard", "to_uv": [1, 0, 0]}, "albedo.to_uv", "6 finite numbers"),
        ({"texture": "checkerboard", "colour0": [1, 0, 0]}, "albedo.colour0", "unknown key (did you mean 'color0'?)"),
    ],
)
def test_bad_texture_tables_are_refused(tmp_path, table, key, problem):
    """A texture table's problem is one SceneError naming the material, the key and the value."""
    write_png(tmp_path / "image.png", IMAGE)
    write_exr(tmp_path / "bright.exr", np.full((2, 2, 3), 1.5))
    with pytest.raises(SceneError) as e:
        texture_scene(tmp_path, table)
    assert f"material[0].{key}" in str(e.value) and problem in str(e.value), str(e.value)


def test_roughness_texture_range(tmp_path):
    """A roughness texture's values (checkerboard: its colours' channel means) must lie in
    [0.001, 1]; its constant stands at their mean."""
    good = {"texture": "checkerboard", "color0": [0.2, 0.2, 0.2], "color1": [0.6, 0.3, 0.0]}
    material = texture_scene(tmp_path, good, key="roughness", kind="glossy").materials[0]
    assert material.roughness == pytest.approx(0.25) and material.textures[0][0] == "roughness"
    with pytest.raises(SceneError, match="roughness must stay in"):
        texture_scene(tmp_path, {**good, "color1": [0, 0, 0]}, key="roughness", kind="glossy")


def test_polygon_uv_key(tmp_path):
    doc = {
        "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
        "shape": [{"type": "polygon", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "uv": [[0, 0], [1, 0]]}],
    }
    with pytest.raises(SceneError, match=r"shape\[0\]\.uv = .*must be a list of 3 pairs"):
        parse_scene(doc)


def test_mesh_file_uvs(tmp_path):
    """OBJ ``vt`` come back as (u, 1 - v) per v/vt vertex (Mitsuba's flip), PLY ``u, v`` or
    ``s, t`` as written, and none from a file without them."""
    from wrt.meshio import load_mesh

    write_meshes(tmp_path)
    vertices, faces, uvs = load_mesh(tmp_path / "quad.obj", return_uvs=True)
    np.testing.assert_allclose(uvs, [[0.1, 0.8], [0.9, 0.7], [0.8, 0.05], [0.05, 0.3]])
    assert faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    _, _, normals, uvs = load_mesh(tmp_path / "quad_uv.ply", return_normals=True, return_uvs=True)
    assert normals is None
    np.testing.assert_allclose(uvs, np.array(PLY_VERTICES)[:, 3:])
    st = (tmp_path / "quad_uv.ply").read_text().replace("property float u\n", "property float s\n")
    (tmp_path / "quad_st.ply").write_text(st.replace("property float v\n", "property float t\n"))
    np.testing.assert_allclose(load_mesh(tmp_path / "quad_st.ply", return_uvs=True)[2], uvs)
    assert load_mesh(tmp_path / "quad.ply", return_uvs=True)[2] is None


@pytest.mark.parametrize("shading", ["flat", "smooth"])
@pytest.mark.parametrize(
    "material",
    [
        {"albedo": {"texture": "checkerboard", "color0": [0.9, 0.9, 0.9], "color1": [0.1, 0.1, 0.1]}},
        {"type": "conductor", "metal": "Au", "roughness": 0.3, "roughness_v": 0.05},  # anisotropic: tangent dp/du
    ],
    ids=["textured", "anisotropic"],
)
def test_a_mesh_keeps_its_files_uvs_where_its_material_needs_them(tmp_path, shading, material):
    """A mesh of a textured or anisotropic material gets its file's texture coordinates, flat-shaded
    (the default) or smooth: an untextured anisotropic material once left a flat mesh without them
    (its dp/du then the triangle's first edge, its highlights turned 90 degrees on a coarse UV
    sphere against Mitsuba's), for its uses of mesh attributes were an empty tuple, taken as none."""
    write_meshes(tmp_path)
    doc = {
        "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
        "material": [{"name": "m", **material}],
        "shape": [{"type": "mesh", "file": "quad.obj", "shading": shading, "material": "m"}],
    }
    (mesh,) = parse_scene(doc, scene_dir=str(tmp_path)).shapes
    np.testing.assert_allclose(mesh.uvs, [[0.1, 0.8], [0.9, 0.7], [0.8, 0.05], [0.05, 0.3]])


def test_planar_uv_closed_form(tmp_path):
    """A polygon's default uv is the affine map taking vertices 0, 1, 2 to (0, 0), (1, 0), (1, 1):
    at ``v0 + a (v1 - v0) + b (v3 - v0)`` of a parallelogram it is (a, b); a plane's is the
    point's coordinates along two orthonormal axes of its plane (distances kept)."""
    v0, e1, e2 = np.array([0.5, -0.2, 0.3]), np.array([2.0, 0.5, 0.0]), np.array([-0.3, 0.6, 1.5])
    corners = [v0, v0 + e1, v0 + e1 + e2, v0 + e2]
    doc = {
        "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
        "material": [{"name": "m", "albedo": {"texture": "checkerboard"}}],
        "shape": [
            {"type": "polygon", "vertices": [c.tolist() for c in corners], "material": "m"},
            {"type": "plane", "point": [0, -5, 0], "normal": [0.2, 1, 0.1], "material": "m"},
        ],
    }
    scene = parse_scene(doc)
    rng = np.random.default_rng(2)
    ab = rng.uniform(0.05, 0.95, (50, 2))
    normal = np.cross(e1, e2) / np.linalg.norm(np.cross(e1, e2))
    points = v0 + ab[:, :1] * e1 + ab[:, 1:] * e2
    uv, hit = wrt_uv(scene, (points + normal).astype(np.float32), np.tile(-normal, (50, 1)).astype(np.float32))
    assert hit.all()
    np.testing.assert_allclose(uv, ab, atol=2e-5)
    n = np.array([0.2, 1, 0.1]) / np.linalg.norm([0.2, 1, 0.1])
    origins = rng.uniform(-3, 3, (50, 3)) + [20, 5, 0]  # away from the polygon
    uv, hit = wrt_uv(scene, origins.astype(np.float32), np.tile(-n, (50, 1)).astype(np.float32))
    assert hit.all()
    on_plane = origins - ((origins - [0, -5, 0]) @ n)[:, None] * n
    distances = np.linalg.norm(on_plane[:, None] - on_plane[None], axis=2)
    np.testing.assert_allclose(np.linalg.norm(uv[:, None] - uv[None], axis=2), distances, atol=1e-4)


def test_textures_feature():
    """Only a scene with a textured material asks for texture coordinates (Features.textures)."""
    from wrt.renderer import scene_features

    plain = parse_scene({"camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]}})
    textured = parse_scene(
        {
            "camera": {"origin": [0, 0, 3], "look_at": [0, 0, 0]},
            "material": [{"name": "m", "albedo": {"texture": "checkerboard"}}],
            "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
        }
    )
    assert not scene_features(plain).textures and scene_features(textured).textures


UNIFORM_SCENE = """
[render]
width = 32
height = 24
spp = 16
integrator = "{integrator}"
max_depth = 4

[camera]
origin = [0.0, 1.0, 4.0]
look_at = [0.0, 0.4, 0.0]
fov = 40.0

[[material]]
name = "m"
{material}

[[shape]]
type = "sphere"
center = [0.0, 0.6, 0.0]
radius = 0.6
material = "m"

[[shape]]
type = "polygon"
vertices = [[-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0], [-3.0, 0.0, -3.0]]
material = "m"

[[light]]
type = "{light}"
{light_keys}
"""
AREA = (
    "area",
    "corner = [-1.0, 3.0, -0.5]\nedge_u = [2.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 1.0]\nradiance = [8.0, 8.0, 8.0]",
)
POINT = ("point", "position = [1.0, 3.0, 2.0]\nintensity = [20.0, 20.0, 20.0]")


def uniform(colour: str) -> str:
    """A checkerboard whose two colours are the same: every lookup gives ``colour``."""
    return f'{{ texture = "checkerboard", color0 = {colour}, color1 = {colour}, scale = 3 }}'


@pytest.mark.parametrize(
    "integrator, light, constant, textured",
    [
        ("path", AREA, "albedo = [0.6, 0.3, 0.2]", f"albedo = {uniform('[0.6, 0.3, 0.2]')}"),
        (
            "path",
            AREA,
            'type = "conductor"\nmetal = "Au"\nroughness = 0.25\nreflectance = [0.9, 0.8, 0.7]',
            f'type = "conductor"\nmetal = "Au"\nroughness = 0.25\nreflectance = {uniform("[0.9, 0.8, 0.7]")}',
        ),
        (
            "path",
            AREA,
            'type = "rough_plastic"\nroughness = 0.2\nalbedo = [0.2, 0.5, 0.3]\nreflectance = [0.8, 0.8, 0.8]',
            f'type = "rough_plastic"\nroughness = 0.2\nalbedo = {uniform("[0.2, 0.5, 0.3]")}\n'
            f"reflectance = {uniform('[0.8, 0.8, 0.8]')}",
        ),
        (
            "whitted",
            POINT,
            'type = "phong"\nalbedo = [0.5, 0.4, 0.3]\nspecular = [0.3, 0.3, 0.3]\nexponent = 20',
            f'type = "phong"\nalbedo = {uniform("[0.5, 0.4, 0.3]")}\n'
            f"specular = {uniform('[0.3, 0.3, 0.3]')}\nexponent = 20",
        ),
        ("raycast", POINT, "albedo = [0.6, 0.3, 0.2]", f"albedo = {uniform('[0.6, 0.3, 0.2]')}"),
        (
            "path",
            AREA,
            'type = "thin_dielectric"\nreflectance = [0.9, 0.8, 0.7]\ntransmittance = [0.6, 0.8, 0.9]',
            f'type = "thin_dielectric"\nreflectance = {uniform("[0.9, 0.8, 0.7]")}\n'
            f"transmittance = {uniform('[0.6, 0.8, 0.9]')}",
        ),
    ],
    ids=["diffuse", "conductor", "rough_plastic", "whitted_phong", "raycast", "thin_dielectric"],
)
def test_uniform_texture_renders_as_its_constant(tmp_path, integrator, light, constant, textured):
    """A texture that gives the same colour everywhere renders the image of that constant, bit for
    bit, through every textured parameter the BSDFs read (a lookup of the wrong slot, a missed
    hook or a wrong uv would change it), in the all-features kernel and the scene's own variant."""
    images = {}
    for name, material in (("constant", constant), ("textured", textured)):
        path = tmp_path / f"{name}.toml"
        path.write_text(
            UNIFORM_SCENE.format(integrator=integrator, material=material, light=light[0], light_keys=light[1])
        )
        scene = load_scene(str(path))
        for specialize in (False, True) if name == "textured" else (False,):
            images[name, specialize] = wrt.render(scene, specialize=specialize).rgb
    assert images["constant", False].max() > 0.05
    for specialize in (False, True):
        np.testing.assert_array_equal(images["textured", specialize], images["constant", False])


def test_uniform_roughness_texture_renders_as_its_constant(tmp_path):
    """A roughness texture of one value renders as that roughness (to float32 rounding of the
    channel mean that ``texture_float`` takes), on a rough dielectric, a glossy material and a
    conductor."""
    materials = ('type = "rough_dielectric"', 'type = "glossy"', 'type = "conductor"\nmetal = "Au"')
    images = {}
    for roughness in ("0.3", uniform("[0.3, 0.3, 0.3]")):
        for material in materials:
            path = tmp_path / "scene.toml"
            keys = f"{material}\nroughness = {roughness}"
            path.write_text(UNIFORM_SCENE.format(integrator="path", material=keys, light=AREA[0], light_keys=AREA[1]))
            images[material, roughness == "0.3"] = wrt.render(load_scene(str(path))).rgb
    for material in materials:
        np.testing.assert_allclose(images[material, False], images[material, True], rtol=1e-4, atol=1e-5)
    images = [images[material, True] for material in materials]
    assert np.abs(images[0] - images[1]).max() > 0.01  # the two materials differ: the comparison has teeth


def test_a_dielectrics_transmittance_cannot_be_a_texture(tmp_path):
    """A dielectric's ``transmittance`` is an absorption per unit length, a property of its volume:
    a texture there is refused, naming the key; a thin dielectric's is a surface's and may be one."""
    checks = {"texture": "checkerboard", "color0": [0.9, 0.9, 0.9], "color1": [0.5, 0.5, 0.5]}
    doc = {"camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]}}
    with pytest.raises(SceneError, match=r"material\[0\]\.transmittance = .*cannot be a texture here"):
        parse_scene({**doc, "material": [{"name": "g", "type": "dielectric", "transmittance": checks}]})
    scene = parse_scene({**doc, "material": [{"name": "g", "type": "thin_dielectric", "transmittance": checks}]})
    assert [name for name, _ in scene.materials[0].textures] == ["transmittance"]


def test_a_sphere_transform_turns_its_texture_and_places_it():
    """A sphere's ``transform`` scales its radius and turns its object axes: under a quarter turn
    about z the texture lags a quarter of u, so with ``to_uv`` shifting u by 1/4 the turned sphere
    renders the unturned one's image (the same samples, the same texels: to rounding), and
    without the shift another."""
    grid = {"texture": "bitmap", "file": str(EXAMPLES / "textures" / "grid.png"), "filter": "nearest"}
    render = {"width": 32, "height": 32, "spp": 1, "integrator": "path", "max_depth": 2}
    camera = {"origin": [0.0, 4.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 30.0}

    def image(shift, transform):
        material = {"name": "m", "albedo": {**grid, "to_uv": [1, 0, shift, 0, 1, 0]}}
        sphere = {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 0.5, "material": "m", "transform": transform}
        light = {"type": "environment", "radiance": [1.0, 1.0, 1.0]}
        doc = {"render": render, "camera": camera, "material": [material], "shape": [sphere], "light": [light]}
        return wrt.render(parse_scene(doc, file="<test>"), specialize=False).rgb

    plain = image(0.0, {"scale": 2.0})
    assert (plain.max(axis=-1) > 0).sum() > 300  # the sphere, radius 1, fills the view
    np.testing.assert_allclose(image(0.25, {"rotate": [0.0, 0.0, 90.0], "scale": 2.0}), plain, rtol=1e-5, atol=1e-6)
    assert not np.allclose(image(0.0, {"rotate": [0.0, 0.0, 90.0], "scale": 2.0}), plain, rtol=1e-2)


@pytest.mark.parametrize(
    "transform", [{"scale": [1.0, 2.0, 1.0]}, {"matrix": [1, 0.5, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}]
)
def test_a_sphere_transform_that_is_not_a_similarity_is_refused(transform):
    doc = {
        "camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]},
        "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "transform": transform}],
    }
    with pytest.raises(SceneError, match=r"shape\[0\].*transform.*a sphere stays a sphere"):
        parse_scene(doc, file="<test>")
