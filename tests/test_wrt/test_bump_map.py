"""Bump maps (``bump_map``, Mitsuba 3's ``bumpmap``): the height field's gradient
(``wrt.kernels.textures.texture_float_grad``) against Mitsuba's ``eval_1_grad``, the bumped normal
(``wrt.kernels.hit.bumped_normal``) against a float64 reference of Mitsuba's frame, renders, the
scene format's checks and the importer."""

import numpy as np
import pytest
import warp as wp
from conftest import EXAMPLES, make_scene
from test_mitsuba_xml import convert, sensor
from wrt.kernels.hit import bumped_normal
from wrt.kernels.textures import TextureData, texture_float_grad, uv_context

import wrt
from wrt.device import _texture_data
from wrt.errors import SceneError, WrtError
from wrt.renderer import scene_features
from wrt.textures import Bitmap, light_texture_table, read_bitmap

HEIGHTS = str(EXAMPLES / "textures" / "bump_map.png")
GRID = str(EXAMPLES / "textures" / "grid.png")


@wp.kernel
def gradients(textures: TextureData, uvs: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec2)):
    k = wp.tid()
    out[k] = texture_float_grad(textures, 0, uv_context(uvs[k]))


@pytest.mark.parametrize(
    "file, to_uv",
    [(HEIGHTS, None), (GRID, [[3.0, 0.0, 0.2], [0.0, 2.0, -0.1]]), (HEIGHTS, [[1, 0.5, 0], [-0.3, 2, 0]])],
)
def test_the_gradient_is_mitsubas_eval_1_grad(file, to_uv, rng):
    """At random uvs (beyond [0, 1]: wrapped), for a grey and a colour bitmap, through a scaling
    and a shearing to_uv, to float32 rounding."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    matrix = np.eye(3) if to_uv is None else np.vstack([to_uv, [0.0, 0.0, 1.0]])
    theirs = {"type": "bitmap", "filename": file, "raw": True}
    if to_uv is not None:
        theirs["to_uv"] = mi.ScalarTransform4f(
            [
                [matrix[0, 0], matrix[0, 1], 0, matrix[0, 2]],
                [matrix[1, 0], matrix[1, 1], 0, matrix[1, 2]],
                [0, 0, 1, 0],
                [0, 0, 0, 1],
            ]
        )
    texture = mi.load_dict(theirs)
    ours = Bitmap(file=file, texels=read_bitmap(file, raw=True), to_uv=matrix)
    uvs = rng.uniform(-0.5, 1.5, (300, 2))
    out = wp.zeros(len(uvs), dtype=wp.vec2)
    table = _texture_data(light_texture_table([ours]), "cpu")
    wp.launch(gradients, len(uvs), [table, wp.array(uvs, dtype=wp.vec2), out])
    expected = []
    for uv in uvs:
        si = mi.SurfaceInteraction3f()
        si.uv = mi.Point2f(*uv)
        expected.append(np.array(texture.eval_1_grad(si)))
    expected = np.array(expected)
    assert np.abs(expected).max() > 1.0  # steep enough to matter
    np.testing.assert_allclose(out.numpy(), expected, rtol=1e-4, atol=1e-3 * np.abs(expected).max())


@wp.kernel
def bump(
    ns: wp.array(dtype=wp.vec3),
    n: wp.array(dtype=wp.vec3),
    dpdu: wp.array(dtype=wp.vec3),
    dpdv: wp.array(dtype=wp.vec3),
    grad: wp.array(dtype=wp.vec2),
    out: wp.array(dtype=wp.vec3),
):
    k = wp.tid()
    out[k] = bumped_normal(ns[k], n[k], dpdu[k], dpdv[k], grad[k])


def test_the_bumped_normal_is_mitsubas_frame_float64(rng):
    """Mitsuba's ``bumpmap`` frame in float64: each derivative's component along the shading normal
    replaced by the height's gradient, the normal their normalised cross product turned to the
    geometric normal's side; random frames, derivatives of any length, gradients up to 20."""
    count = 400
    n = rng.normal(size=(count, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    ns = n + 0.3 * rng.normal(size=(count, 3))
    ns /= np.linalg.norm(ns, axis=1, keepdims=True)
    dpdu, dpdv = (rng.normal(size=(count, 3)) * rng.uniform(0.2, 5.0, (count, 1)) for _ in range(2))
    grad = rng.uniform(-20.0, 20.0, (count, 2))
    du = dpdu + (grad[:, :1] - np.sum(ns * dpdu, axis=1, keepdims=True)) * ns
    dv = dpdv + (grad[:, 1:] - np.sum(ns * dpdv, axis=1, keepdims=True)) * ns
    expected = np.cross(du, dv)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    expected *= np.where(np.sum(n * expected, axis=1, keepdims=True) < 0.0, -1.0, 1.0)
    arrays = [wp.array(a.astype(np.float32), dtype=wp.vec3) for a in (ns, n, dpdu, dpdv)]
    out = wp.zeros(count, dtype=wp.vec3)
    wp.launch(bump, count, [*arrays, wp.array(grad.astype(np.float32), dtype=wp.vec2), out])
    np.testing.assert_allclose(out.numpy(), expected, atol=2e-5)


MATERIALS = [{"name": "floor", "albedo": [0.6, 0.6, 0.6]}]
FLOOR = {"type": "polygon", "vertices": [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]], "material": "floor"}
RENDER = {"width": 40, "height": 30, "spp": 4, "integrator": "path", "max_depth": 2}
CAMERA = {"origin": [0.0, 2.0, 3.0], "look_at": [0.0, 0.0, 0.0], "fov": 45.0}
LIGHTS = [{"type": "point", "position": [-1.0, 1.5, 1.0], "intensity": [4.0, 4.0, 4.0]}]


def floor_render(bump_map=None, **keys):
    material = {**MATERIALS[0], **keys}
    if bump_map is not None:
        material["bump_map"] = bump_map
    scene = make_scene([FLOOR], render=RENDER, camera=CAMERA, materials=[material], lights=LIGHTS)
    return wrt.render(scene, specialize=False).rgb.astype(np.float64)


def test_a_bump_map_tilts_the_shading_and_its_scale_sets_how_much():
    """The height field changes the floor's shading; scale 0 renders the unbumped floor (to
    rounding: the frame is rebuilt from the derivatives), and a larger scale changes it more."""
    plain = floor_render()
    table = {"texture": "bitmap", "file": HEIGHTS, "raw": True, "scale": 4}
    flat = floor_render(table, bump_scale=0.0)
    np.testing.assert_allclose(flat, plain, rtol=1e-4, atol=1e-6)
    small = np.abs(floor_render(table, bump_scale=0.005) - plain).mean()
    large = np.abs(floor_render(table, bump_scale=0.05) - plain).mean()
    assert 0.0 < small < large


def test_a_bump_map_asks_for_the_mapped_kernels():
    table = {"texture": "bitmap", "file": HEIGHTS}
    scene = make_scene([FLOOR], materials=[{**MATERIALS[0], "bump_map": table}], lights=LIGHTS)
    assert scene_features(scene).normal_map and scene_features(scene).textures


@pytest.mark.parametrize(
    "material, key, value",
    [
        ({"bump_map": {"texture": "checkerboard"}}, "bump_map", "checkerboard"),
        (
            {"bump_map": {"texture": "bitmap", "file": HEIGHTS}, "normal_map": {"texture": "bitmap", "file": GRID}},
            "bump_map",
            None,
        ),
        ({"bump_scale": 0.1}, "bump_scale", "0.1"),
        ({"bump_map": {"texture": "bitmap", "file": HEIGHTS}, "bump_scale": "x"}, "bump_scale", "x"),
    ],
    ids=["checkerboard", "with-normal-map", "scale-alone", "scale-not-a-number"],
)
def test_bad_bump_maps_are_one_line_naming_key_and_value(material, key, value):
    with pytest.raises(SceneError) as caught:
        make_scene([FLOOR], materials=[{**MATERIALS[0], **material}], lights=LIGHTS)
    message = str(caught.value)
    assert "\n" not in message and key in message and "material[0]" in message
    if value is not None:
        assert value in message


def test_a_mask_or_blend_of_a_bump_mapped_material_is_refused():
    bumped = {"name": "bumped", "albedo": [0.5, 0.5, 0.5], "bump_map": {"texture": "bitmap", "file": HEIGHTS}}
    for wrapper in ({"type": "mask", "material": "bumped"}, {"type": "blend", "materials": ["bumped", "floor"]}):
        with pytest.raises(SceneError, match="bump map"):
            make_scene([FLOOR], materials=[*MATERIALS, bumped, {"name": "w", **wrapper}], lights=LIGHTS)


BUMPED_XML = """
<bsdf type="bumpmap" id="b">
    <texture name="anything" type="{kind}">{file}</texture>
    <float name="scale" value="0.3"/>
    {extra}
    <bsdf type="diffuse"/>
</bsdf>
<shape type="sphere"><ref id="b"/></shape>"""


def test_the_importer_converts_a_bumpmap_exactly(tmp_path):
    file = f'<string name="filename" value="{HEIGHTS}"/><boolean name="raw" value="true"/>'
    doc, approximations = convert(tmp_path, sensor() + BUMPED_XML.format(kind="bitmap", file=file, extra=""), False)
    (material,) = doc["material"]
    assert material["bump_scale"] == 0.3 and material["bump_map"]["texture"] == "bitmap" and not approximations
    example = wrt.load_scene(str(EXAMPLES / "mitsuba" / "bumpmap.xml"))
    assert sum(any(k == "bump_map" for k, _ in m.textures) for m in example.materials) == 2


def test_the_importer_refuses_what_it_cannot_bump(tmp_path):
    with pytest.raises(WrtError, match="must be a bitmap"):
        convert(tmp_path, sensor() + BUMPED_XML.format(kind="checkerboard", file="", extra=""), False)
    file = f'<string name="filename" value="{HEIGHTS}"/>'
    off = '<boolean name="use_shadowing_function" value="false"/>'
    with pytest.raises(WrtError, match="shadowing function"):
        convert(tmp_path, sensor() + BUMPED_XML.format(kind="bitmap", file=file, extra=off), False)
