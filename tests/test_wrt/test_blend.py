"""Blends (``type = "blend"``): renders against their materials' mixed, the scene format's checks,
the features a blend asks of the kernels, and the Mitsuba importer's ``blendbsdf``."""

import numpy as np
import pytest
from conftest import make_scene
from test_mask import parse
from test_mitsuba_xml import convert, sensor

import wrt
from wrt.errors import SceneError, WrtError
from wrt.renderer import scene_features

SPHERE = {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0}
FLOOR = {"type": "plane", "point": [0.0, -1.0, 0.0], "normal": [0.0, 1.0, 0.0], "material": "floor"}
LIGHTS = [
    {"type": "environment", "radiance": [0.3, 0.35, 0.4]},
    {"type": "sphere", "center": [2.0, 3.0, 2.0], "radius": 0.5, "radiance": [30.0, 28.0, 25.0]},
]
MATERIALS = [
    {"name": "floor", "albedo": [0.5, 0.5, 0.5]},
    {"name": "red", "albedo": [0.7, 0.1, 0.1]},
    {"name": "blue", "albedo": [0.1, 0.2, 0.6]},
    {"name": "metal", "type": "glossy", "reflectance": [0.9, 0.8, 0.6], "roughness": 0.25},
    {"name": "mixed", "albedo": [0.46, 0.14, 0.3]},  # 0.6 red + 0.4 blue
    {"name": "purple", "type": "blend", "materials": ["red", "blue"], "weight": 0.4},
    {"name": "tarnish", "type": "blend", "materials": ["red", "metal"], "weight": 0.7},
]


def sphere_render(material: str, spp: int, seed: int = 1):
    render = {"width": 40, "height": 30, "spp": spp, "seed": seed, "integrator": "path", "max_depth": 4}
    camera = {"origin": [0.0, 0.5, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0}
    shapes = [{**SPHERE, "material": material}, FLOOR]
    scene = make_scene(shapes, render=render, camera=camera, materials=MATERIALS, lights=LIGHTS)
    return wrt.render(scene, specialize=False).rgb.astype(np.float64)


def test_a_blend_of_two_diffuse_materials_is_their_mixed_albedo():
    """Two Lambertian materials blended with weight w are one Lambertian of albedo ``(1 - w) a +
    w b``: the blend draws the same cosine-weighted directions with the same weights (its own f
    over its own pdf), so the renders agree to rounding."""
    blend, mixed = sphere_render("purple", 16), sphere_render("mixed", 16)
    np.testing.assert_allclose(blend, mixed, rtol=1e-4, atol=1e-6)


def test_a_blend_is_the_weighted_sum_of_its_materials_renders():
    """Light transport is linear in the BSDF at one bounce: with ``max_depth`` counting the camera
    ray and one bounce (direct light only), a blend's image is ``(1 - w)`` times the image with its
    first material plus ``w`` times the image with its second (the same scene otherwise)."""
    images = {}
    for material in ("tarnish", "red", "metal"):
        render = {"width": 40, "height": 30, "spp": 256, "integrator": "path", "max_depth": 2}
        camera = {"origin": [0.0, 0.5, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0}
        scene = make_scene(
            [{**SPHERE, "material": material}], render=render, camera=camera, materials=MATERIALS, lights=LIGHTS[1:]
        )
        images[material] = wrt.render(scene, specialize=False).rgb.astype(np.float64)
    expected = 0.3 * images["red"] + 0.7 * images["metal"]
    np.testing.assert_allclose(images["tarnish"].mean(axis=(0, 1)), expected.mean(axis=(0, 1)), rtol=0.02)


@pytest.mark.parametrize(
    "blend, key, message",
    [
        ({"materials": ["green", "nothing"]}, "materials", "names no material"),
        ({"materials": ["green", "glass"]}, "materials", "names a dielectric"),
        ({"materials": ["other", "green"]}, "materials", "names a blend"),
        ({"materials": ["veil", "green"]}, "materials", "names a mask"),
        ({"materials": ["green", "bumpy"]}, "materials", "names a material with a normal map"),
        ({"materials": ["green"]}, "materials", "a list of 2 names"),
        ({"materials": "green"}, "materials", "a list of 2 names"),
        ({"materials": ["green", "green"], "weight": 1.5}, "weight", "[0, 1]"),
        ({"materials": ["green", "green"], "weight": {"texture": "checkerboard", "color0": [2.0] * 3}}, "weight", ""),
        ({"materials": ["green", "green"], "two_sided": False}, "two_sided", ""),
        ({}, "materials", "is required"),
    ],
)
def test_bad_blends_are_refused(blend, key, message):
    materials = [
        {"name": "green", "albedo": [0.2, 0.6, 0.15]},
        {"name": "glass", "type": "dielectric"},
        {"name": "other", "type": "blend", "materials": ["green", "green"]},
        {"name": "veil", "type": "mask", "material": "green"},
        {"name": "bumpy", "normal_map": {"texture": "constant", "value": [0.5, 0.5, 1.0]}},
        {"name": "leaf", "type": "blend", **blend},
    ]
    with pytest.raises(SceneError, match=key) as error:
        parse(materials)
    assert message in str(error.value) and "material[5]" in str(error.value)


def test_whitted_refuses_blends():
    materials = [{"name": "green"}, {"name": "leaf", "type": "blend", "materials": ["green", "green"]}]
    with pytest.raises(SceneError, match='blend needs integrator = "path"'):
        parse(materials, integrator="whitted")


def test_features_of_a_blend_are_its_own_and_its_materials():
    """A blend sets ``blend`` and what its materials need (a plastic's lobe choice, an anisotropic
    conductor's tangent frame), through a mask over it too; a scene without one compiles no blend code."""
    materials = [
        {"name": "coat", "type": "plastic"},
        {"name": "brushed", "type": "glossy", "roughness": 0.1, "roughness_v": 0.4},
        {"name": "mix", "type": "blend", "materials": ["coat", "brushed"]},
        {"name": "leaf", "type": "mask", "material": "mix"},
    ]
    features = scene_features(parse(materials))
    assert features.blend and features.plastic and features.anisotropic and features.mask
    assert not scene_features(parse([{"name": "green"}])).blend


BLENDED = """
    <shape type="sphere">
        <bsdf type="blendbsdf">
            {weight}
            {nested}
        </bsdf>
    </shape>"""
DIFFUSE = '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.15"/></bsdf>'
METAL = '<bsdf type="roughconductor"><float name="alpha" value="0.2"/><string name="material" value="none"/></bsdf>'


def blended(tmp_path, weight, nested=DIFFUSE + METAL) -> dict:
    """The ``[[material]]`` tables, by name, of a sphere whose BSDF is a blendbsdf."""
    doc, _ = convert(tmp_path, sensor() + BLENDED.format(weight=weight, nested=nested), approximate=False)
    return {m["name"]: m for m in doc["material"]}


def test_mitsuba_blendbsdf_becomes_a_blend_of_its_nested_bsdfs(tmp_path):
    """Exact: a constant weight (clamped to [0, 1], as Mitsuba does) between the two nested BSDFs'
    materials, in their order, one-sided as Mitsuba's diffuse and conductors; ``twosided`` around
    the blend makes both two-sided; a textured weight is a texture of the blend's."""
    tables = blended(tmp_path, '<float name="weight" value="1.5"/>')
    blend = next(m for m in tables.values() if m["type"] == "blend")
    assert blend["weight"] == 1.0 and "two_sided" not in blend
    first, second = (tables[name] for name in blend["materials"])
    assert first == {"name": blend["materials"][0], "type": "diffuse", "albedo": [0.2, 0.6, 0.15], "two_sided": False}
    assert second["type"] == "glossy" and second["roughness"] == 0.2 and second["two_sided"] is False
    two_sided = (
        f'<shape type="sphere"><bsdf type="twosided"><bsdf type="blendbsdf">{DIFFUSE}{METAL}</bsdf></bsdf></shape>'
    )
    doc, _ = convert(tmp_path, sensor() + two_sided, approximate=False)
    assert all("two_sided" not in m for m in doc["material"])
    checks = '<texture type="checkerboard" name="weight"><float name="color0" value="0.9"/></texture>'
    weight = next(m for m in blended(tmp_path, checks).values() if m["type"] == "blend")["weight"]
    assert weight["texture"] == "checkerboard" and weight["color1"] == [0.9] * 3  # eval_1 swaps the colours


@pytest.mark.parametrize(
    "nested, message",
    [
        (DIFFUSE, "exactly two nested"),
        (DIFFUSE + METAL + DIFFUSE, "exactly two nested"),
        (DIFFUSE + '<bsdf type="dielectric"/>', "blendbsdf of a dielectric is not supported"),
        (DIFFUSE + f'<bsdf type="mask">{DIFFUSE}</bsdf>', "blendbsdf of a mask is not supported"),
    ],
)
def test_mitsuba_blends_wrt_cannot_convert(tmp_path, nested, message):
    with pytest.raises(WrtError, match=message):
        blended(tmp_path, "", nested)
