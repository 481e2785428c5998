"""Textured emission: a material's ``emission`` given by a texture over the surface's uv
(Mitsuba 3's area emitter with a textured ``radiance``), seen directly, found by BSDF sampling,
sampled by next-event estimation among the emissive primitives and emitted by the light tracer;
the scene format's checks and the Mitsuba importer."""

import numpy as np
import pytest
from conftest import make_scene
from test_mitsuba_xml import convert, sensor

import wrt
from wrt.errors import SceneError

LEFT, RIGHT = [3.0, 0.5, 0.1], [0.1, 0.6, 2.5]
HALVES = {"texture": "checkerboard", "color0": LEFT, "color1": RIGHT, "to_uv": [0.5, 0.0, 0.25, 0.0, 0.0, 0.25]}
"""A checkerboard looked up at (u / 2 + 1/4, 1/4): ``LEFT`` where u < 1/2, ``RIGHT`` elsewhere."""
LAMP = [[-1.0, 1.5, -0.5], [1.0, 1.5, -0.5], [1.0, 1.5, 0.5], [-1.0, 1.5, 0.5]]  # u along +x, emitting down
FLOOR = {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}
CAMERA = {"origin": [0.0, 0.4, 3.5], "look_at": [0.0, 0.6, 0.0], "fov": 60.0}


def lamp_scene(textured: bool, integrator: str, spp: int, size=(32, 24), max_depth=3):
    """The floor under a 2 x 1 lamp whose left half emits ``LEFT`` and right half ``RIGHT``: one
    polygon of emission ``HALVES`` (``textured``) or its two halves, each of a constant emission."""
    dark = {"albedo": [0.0, 0.0, 0.0]}
    if textured:
        materials = [{"name": "lamp", **dark, "emission": HALVES}]
        shapes = [{"type": "polygon", "vertices": LAMP, "material": "lamp"}]
    else:
        materials = [{"name": "left", **dark, "emission": LEFT}, {"name": "right", **dark, "emission": RIGHT}]
        a, b, c, d = LAMP
        mid = [[0.0, 1.5, -0.5], [0.0, 1.5, 0.5]]
        shapes = [
            {"type": "polygon", "vertices": [a, mid[0], mid[1], d], "material": "left"},
            {"type": "polygon", "vertices": [mid[0], b, c, mid[1]], "material": "right"},
        ]
    render = {"width": size[0], "height": size[1], "spp": spp, "integrator": integrator, "max_depth": max_depth}
    return make_scene(
        [*shapes, FLOOR],
        render=render,
        camera=CAMERA,
        materials=[*materials, {"name": "floor", "albedo": [0.7, 0.7, 0.7]}],
    )


@pytest.mark.parametrize("integrator, spp", [("path", 256), ("ptracer", 512)])
def test_a_textured_lamp_lights_the_floor_as_its_two_halves_do(integrator, spp):
    """The path tracer (next-event estimation of a uniform point on the lamp, MIS with BSDF
    sampling) and the light tracer (rays leaving a uniform point) find a textured emitter's light
    as they find the same light from two emitters of constant emission: the image means within 1.5%
    per channel, each quarter's within 4%. The halves differ in colour (red left, blue right), so a
    texture looked up at the wrong uv, or its mean taken, shifts the quarters' colours."""
    textured = wrt.render(lamp_scene(True, integrator, spp)).rgb.astype(np.float64)
    halves = wrt.render(lamp_scene(False, integrator, spp)).rgb.astype(np.float64)
    assert np.allclose(textured.mean(axis=(0, 1)), halves.mean(axis=(0, 1)), rtol=0.015)
    for quarter in (np.s_[:12, :16], np.s_[:12, 16:], np.s_[12:, :16], np.s_[12:, 16:]):
        assert np.allclose(textured[quarter].mean(axis=(0, 1)), halves[quarter].mean(axis=(0, 1)), rtol=0.04)
    left, right = textured[12:, :16].mean(axis=(0, 1)), textured[12:, 16:].mean(axis=(0, 1))
    assert left[0] > 1.2 * right[0] and right[2] > 1.2 * left[2]  # the floor's colours follow the halves


@pytest.mark.parametrize("integrator", ["path", "whitted"])
def test_the_camera_sees_the_texture_on_the_emitter(integrator):
    """Looking up at the lamp from below (one sample at each pixel centre, direct view): every pixel
    on its left half shows ``LEFT`` and on its right half ``RIGHT``, exactly (the emitter reflects
    nothing)."""
    scene = make_scene(
        [{"type": "polygon", "vertices": LAMP, "material": "lamp"}],
        render={"width": 40, "height": 20, "spp": 1, "integrator": integrator, "max_depth": 1},
        camera={"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 1.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": 90.0},
        materials=[{"name": "lamp", "albedo": [0.0, 0.0, 0.0], "emission": HALVES}],
    )
    image = wrt.render(scene, specialize=False).rgb.astype(np.float64)
    # at height 1.5 the image spans x in [-3, 3] over 40 columns and z in [-1.5, 1.5] over 20 rows:
    # the lamp's halves fill columns 14-19 and 20-25 of rows 7-12, the rest is black
    np.testing.assert_allclose(image[7:13, 14:20], np.broadcast_to(LEFT, (6, 6, 3)), rtol=1e-5)
    np.testing.assert_allclose(image[7:13, 20:26], np.broadcast_to(RIGHT, (6, 6, 3)), rtol=1e-5)
    assert image[:, :13].max() == 0.0 and image[:, 27:].max() == 0.0 and image[:6].max() == 0.0


def test_an_emission_texture_outside_its_range_is_refused():
    bad = {"texture": "checkerboard", "color0": [1.0, -0.5, 0.0], "color1": [1.0, 1.0, 1.0]}
    with pytest.raises(SceneError, match=r"material\[0\]\.emission.*emission must stay in \[0, 1e\+18\]"):
        make_scene(
            [{"type": "polygon", "vertices": LAMP, "material": "lamp"}],
            materials=[{"name": "lamp", "emission": bad}],
        )


def test_a_textured_area_emitter_imports_as_an_emissive_rectangle_with_its_texture(tmp_path):
    """Mitsuba's area emitter with a bitmap ``radiance`` on a rectangle: a polygon of Mitsuba's uv
    whose material emits the texture (no light row: it is sampled among the emissive primitives)."""
    scene, warnings = convert(
        tmp_path,
        sensor()
        + """
    <shape type="rectangle">
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        <emitter type="area">
            <texture name="radiance" type="checkerboard">
                <rgb name="color0" value="2, 1, 0.5"/>
                <rgb name="color1" value="0.5, 1, 2"/>
            </texture>
        </emitter>
    </shape>""",
        approximate=False,
    )
    assert warnings == [] and scene["light"] == []
    (shape,) = scene["shape"]
    assert shape["type"] == "polygon" and shape["uv"] == [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    (material,) = [m for m in scene["material"] if m["name"] == shape["material"]]
    assert material["emission"] == {"texture": "checkerboard", "color0": [2.0, 1.0, 0.5], "color1": [0.5, 1.0, 2.0]}


def test_an_area_emitter_that_reflects_imports_as_an_emissive_shape_exactly(tmp_path):
    """A rectangle emitter whose BSDF reflects is an emissive polygon of that BSDF, not a light
    row that would reflect nothing: imported without a warning."""
    scene, warnings = convert(
        tmp_path,
        sensor()
        + """
    <shape type="rectangle">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="4"/></emitter>
    </shape>""",
        approximate=False,
    )
    assert warnings == [] and scene["light"] == []
    (shape,) = scene["shape"]
    (material,) = [m for m in scene["material"] if m["name"] == shape["material"]]
    assert material["emission"] == [4.0, 4.0, 4.0] and material["albedo"] == [0.6, 0.6, 0.6]


def test_an_emitters_default_bsdf_is_black_as_mitsubas(tmp_path):
    """Mitsuba gives a shape with an emitter but no BSDF a black diffuse one (reflectance 0, not
    the 0.5 of other shapes): such a rectangle is a light row (reflecting nothing), and a cube an
    emissive mesh of albedo 0. Seen in front of a constant sky, Mitsuba's rectangle shows its
    radiance alone."""
    light = '<emitter type="area"><rgb name="radiance" value="2"/></emitter>'
    scene, warnings = convert(
        tmp_path, sensor() + f'<shape type="rectangle">{light}</shape><shape type="cube">{light}</shape>'
    )
    assert warnings == [] and [row["type"] for row in scene["light"]] == ["area"]
    (cube,) = [m for m in scene["material"] if "emission" in m]
    assert cube["albedo"] == [0.0, 0.0, 0.0] and cube["emission"] == [2.0, 2.0, 2.0]
