"""Masks (``type = "mask"``): a render against closed forms, the scene format's checks, the
features a mask asks of the kernels, and the Mitsuba importer's ``mask``."""

import numpy as np
import pytest
from conftest import make_scene
from test_mitsuba_xml import convert, sensor

import wrt
from wrt.errors import SceneError, WrtError
from wrt.renderer import scene_features

ALBEDO, SKY, INTENSITY = 0.5, 0.2, 4.0
WALL = {"type": "polygon", "vertices": [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], "material": "wall"}
PANEL = {"type": "polygon", "vertices": [[-0.5, -0.5, 2], [0.5, -0.5, 2], [0.5, 0.5, 2], [-0.5, 0.5, 2]]}
LIGHTS = [
    {"type": "environment", "radiance": [SKY] * 3},
    {"type": "point", "position": [0.0, 0.0, 4.0], "intensity": [INTENSITY] * 3},
]
MATERIALS = [
    {"name": "wall", "albedo": [ALBEDO] * 3},
    {"name": "green", "albedo": [0.2, 0.6, 0.15]},
    {"name": "clear", "type": "mask", "material": "green", "opacity": 0.0},
]


def wall_render(panel: bool, max_depth: int, device: str):
    shapes = [WALL, {**PANEL, "material": "clear"}] if panel else [WALL]
    render = {"width": 32, "height": 32, "spp": 64, "integrator": "path", "max_depth": max_depth}
    camera = {"origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0}
    return wrt.render(
        make_scene(shapes, render=render, camera=camera, materials=MATERIALS, lights=LIGHTS), device=device
    )


def test_a_clear_mask_shows_the_wall_but_blocks_shadow_rays(device):
    """A mask of opacity 0 between the camera and a diffuse wall (albedo rho) lit by a constant sky
    L and a point light I at (0, 0, 4): the wall, at each pixel's position p (the AOV of the render
    without the panel), is ``rho L`` (its hemisphere sees the sky, through the mask: found by BSDF
    sampling of its null lobe) plus ``rho / pi I cos / r^2`` only where the shadow ray to the point
    light misses the panel (|x|, |y| >= 1 on the wall): shadow rays stop at a mask whatever its
    opacity, as Mitsuba's. Region means within 3% of these closed forms (the sky's MIS noise), with
    and without the panel; the null lobe is a segment of the path (Mitsuba's ``max_depth``), so the
    panel's render takes one more (4 against 3), and with 2 the wall seen through it is black."""
    plain, masked = wall_render(False, 3, device), wall_render(True, 4, device)
    p = plain.aovs["position"]
    r2 = (p**2).sum(axis=2) - 8.0 * p[..., 2] + 16.0
    direct = ALBEDO / np.pi * INTENSITY * 4.0 / r2**1.5  # cos = 4 / r for a light on the wall's axis
    edge = np.maximum(np.abs(p[..., 0]), np.abs(p[..., 1]))
    shadow, lit = edge < 0.85, edge > 1.15  # whole pixels, off the shadow's edge (pixel size ~0.11)
    seen_through = (np.abs(p[..., :2]) < 0.75).all(axis=2)  # behind the panel, from the camera (< 0.83)
    assert shadow.sum() > 50 and lit.sum() > 200 and (seen_through & shadow).sum() > 50
    for image, in_shadow in ((plain.rgb, direct), (masked.rgb, 0.0)):
        expected = ALBEDO * SKY + np.where(shadow, in_shadow, direct)
        for region in (shadow & seen_through, lit):
            np.testing.assert_allclose(image[region].mean(axis=0), expected[region].mean(), rtol=0.03)
    assert (masked.aovs["object_id"][seen_through] == 1).all()  # the AOVs see the mask's surface
    short = wall_render(True, 2, device)
    assert not short.rgb[seen_through].any() and short.rgb[lit].min() > 0.0


def parse(materials, integrator="path"):
    return make_scene(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": materials[-1]["name"]}],
        render={"integrator": integrator},
        materials=materials,
    )


@pytest.mark.parametrize(
    "material, key, message",
    [
        ({"material": "nothing"}, "material", "names no material"),
        ({"material": "glass"}, "material", "names a dielectric"),
        ({"material": "other"}, "material", "names a mask"),
        ({"material": "green", "opacity": 1.5}, "opacity", "[0, 1]"),
        ({"material": "green", "opacity": {"texture": "checkerboard", "color0": [2.0] * 3}}, "opacity", "[0, 1]"),
        ({"material": "green", "two_sided": False}, "two_sided", ""),
        ({"material": "bumpy"}, "material", "names a material with a normal map"),
    ],
)
def test_bad_masks_are_refused(material, key, message):
    """A mask's normal map would be read at the mask (the hit's material), never at its material's:
    refused there, where it would be silently ignored."""
    materials = [
        {"name": "green", "albedo": [0.2, 0.6, 0.15]},
        {"name": "glass", "type": "dielectric"},
        {"name": "other", "type": "mask", "material": "green"},
        {"name": "bumpy", "normal_map": {"texture": "constant", "value": [0.5, 0.5, 1.0]}},
        {"name": "leaf", "type": "mask", **material},
    ]
    with pytest.raises(SceneError, match=key) as error:
        parse(materials)
    assert message in str(error.value) and "material[4]" in str(error.value)


def test_whitted_refuses_masks():
    materials = [{"name": "green"}, {"name": "leaf", "type": "mask", "material": "green"}]
    with pytest.raises(SceneError, match='mask needs integrator = "path"'):
        parse(materials, integrator="whitted")


def test_features_of_a_mask_are_its_own_and_its_inner_materials():
    """A mask sets ``mask`` and what its inner material needs (a plastic's lobe choice); a scene
    without one compiles no mask code."""
    plastic = [{"name": "coat", "type": "plastic"}, {"name": "leaf", "type": "mask", "material": "coat"}]
    features = scene_features(parse(plastic))
    assert features.mask and features.plastic
    assert not scene_features(parse([{"name": "green"}])).mask


MASKED = """
    <shape type="sphere">
        <bsdf type="mask">
            {opacity}
            {inner}
        </bsdf>
    </shape>"""
DIFFUSE = '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.15"/></bsdf>'


def masked(tmp_path, opacity, inner=DIFFUSE, approximate=False) -> dict:
    """The ``[[material]]`` tables, by name, of a sphere whose BSDF is a mask."""
    doc, _ = convert(tmp_path, sensor() + MASKED.format(opacity=opacity, inner=inner), approximate=approximate)
    return {m["name"]: m for m in doc["material"]}


def the_mask(tables: dict) -> dict:
    return next(m for m in tables.values() if m["type"] == "mask")


def test_mitsuba_mask_becomes_a_mask_over_its_nested_bsdf(tmp_path):
    """Exact: a constant opacity (clamped to [0, 1], as Mitsuba does) over the nested BSDF's
    material, one-sided as Mitsuba's diffuse; the mask itself lets rays through on both sides."""
    tables = masked(tmp_path, '<float name="opacity" value="1.5"/>')
    mask = the_mask(tables)
    assert mask["opacity"] == 1.0 and "two_sided" not in mask
    assert tables[mask["material"]] == {
        "name": mask["material"],
        "type": "diffuse",
        "albedo": [0.2, 0.6, 0.15],
        "two_sided": False,
    }
    tables = masked(tmp_path, "", f'<bsdf type="twosided">{DIFFUSE}</bsdf>')
    mask = the_mask(tables)
    assert mask["opacity"] == 0.5 and "two_sided" not in tables[mask["material"]]  # Mitsuba's default opacity


def test_mitsuba_checkerboard_opacity_swaps_its_colours(tmp_path):
    """Mitsuba's checkerboard ``eval_1`` (what a mask reads) swaps its colours against ``eval``."""
    checks = """<texture type="checkerboard" name="opacity">
        <float name="color0" value="0.9"/><float name="color1" value="0.1"/></texture>"""
    opacity = the_mask(masked(tmp_path, checks))["opacity"]
    assert opacity["texture"] == "checkerboard"
    assert opacity["color0"] == [0.1] * 3 and opacity["color1"] == [0.9] * 3


def test_mitsuba_masks_wrt_cannot_convert(tmp_path):
    """``twosided`` over a mask transmits (Mitsuba rejects it); a mask over a dielectric is refused
    (wrt's dielectrics bound media), or left out when approximating."""
    mask = f'<bsdf type="mask">{DIFFUSE}</bsdf>'
    with pytest.raises(WrtError, match="cannot nest a BSDF that transmits"):
        convert(tmp_path, sensor() + f'<shape type="sphere"><bsdf type="twosided">{mask}</bsdf></shape>')
    glass = '<bsdf type="dielectric"/>'
    with pytest.raises(WrtError, match="mask over a dielectric"):
        masked(tmp_path, "", glass)
    tables = masked(tmp_path, "", glass, approximate=True)
    assert [m["type"] for m in tables.values()] == ["dielectric"]
