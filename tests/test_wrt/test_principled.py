"""The principled material (``type = "principled"``) on the host: the scene format's checks, the
features it asks of the kernels, its bake (no medium across it), and the Mitsuba importer's
``principled``."""

import math

import numpy as np
import pytest
from conftest import make_scene
from test_mask import parse
from test_mitsuba_xml import convert, sensor
from wrt.kernels.materials import BSDF_MEDIUM, BSDF_TRANSMISSION

import wrt
from wrt.bake import bake_materials
from wrt.errors import SceneError, WrtError
from wrt.renderer import scene_features

CHECKS = {"texture": "checkerboard", "color0": [0.9] * 3, "color1": [0.1] * 3, "scale": 4}


@pytest.mark.parametrize(
    "table, key, message",
    [
        ({"sheen": 1.5}, "sheen", "[0, 1]"),
        ({"metallic": -0.1}, "metallic", "[0, 1]"),
        ({"roughness": 1.2}, "roughness", "[0, 1]"),
        ({"ior": 0.5}, "ior", "[1, 10]"),
        ({"clearcoat_sampling_rate": -1.0}, "clearcoat_sampling_rate", "[0, 1000]"),
        ({"clearcoat": {**CHECKS, "color0": [2.0] * 3}}, "clearcoat", "[0, 1]"),
        ({"two_sided": False}, "two_sided", "principled's"),
        ({"specular": [0.5, 0.5, 0.5]}, "specular", ""),
    ],
)
def test_bad_principled_materials_are_refused(table, key, message):
    with pytest.raises(SceneError, match=key) as error:
        parse([{"name": "p", "type": "principled", **table}])
    assert message in str(error.value) and "material[0]" in str(error.value)


def test_whitted_refuses_principled_materials():
    with pytest.raises(SceneError, match='principled needs integrator = "path"'):
        parse([{"name": "p", "type": "principled"}], integrator="whitted")


def test_its_keys_and_textures_are_read():
    scene = parse(
        [
            {
                "name": "p",
                "type": "principled",
                "albedo": [0.2, 0.8, 0.1],
                "roughness": 0.0,  # Burley's roughness may be 0 (its alpha stays 0.001)
                "sheen": CHECKS,
                "anisotropy": 0.5,
                "main_specular_sampling_rate": 2.0,
            }
        ]
    )
    material = scene.materials[0]
    assert material.roughness == 0.0 and material.anisotropy == 0.5 and material.main_specular_sampling_rate == 2.0
    assert [key for key, _ in material.textures] == ["sheen"] and material.sheen == pytest.approx(0.5)


def test_features_of_a_principled_material():
    """``principled`` compiles its family in, textures where a parameter is textured, the tangent
    frame where it is anisotropic; a scene without one compiles none of it."""
    plain = scene_features(parse([{"name": "p", "type": "principled"}]))
    assert plain.principled and not plain.anisotropic and not plain.textures and not plain.dielectric
    brushed = scene_features(parse([{"name": "p", "type": "principled", "anisotropy": 0.3, "metallic": CHECKS}]))
    assert brushed.principled and brushed.anisotropic and brushed.textures
    assert not scene_features(parse([{"name": "g"}])).principled


def test_its_transmission_crosses_no_medium_and_an_index_matched_one_is_moved_off_1():
    """A transmitting principled material has glossy transmission but bounds no medium (it keeps
    the media stack as it is, Mitsuba's ``eta`` being its own); at ``ior`` 1 it takes Mitsuba's 1.001."""
    scene = parse(
        [
            {"name": "glass", "type": "dielectric"},
            {"name": "p", "type": "principled", "spec_trans": 0.5, "ior": 1.0},
        ]
    )
    baked = bake_materials(scene)
    by_name = {m.name: k for k, m in enumerate(baked.materials)}
    assert baked.flags[by_name["p"]] & (BSDF_TRANSMISSION | BSDF_MEDIUM) == BSDF_TRANSMISSION
    assert baked.flags[by_name["glass"]] & BSDF_MEDIUM
    assert scene.materials[1].ior == 1.001


def test_a_blend_of_two_equal_principled_materials_renders_as_one():
    """A blend of one principled material with itself is that material: same lobes, same pdf, the
    blend's sample weight ``f cos / pdf`` its own (a render of it equals the plain one's)."""
    principled = {"type": "principled", "albedo": [0.6, 0.3, 0.2], "roughness": 0.4, "clearcoat": 0.5}
    materials = [
        {"name": "a", **principled},
        {"name": "b", **principled},
        {"name": "ab", "type": "blend", "materials": ["a", "b"], "weight": 0.3},
    ]
    images = {}
    for name in ("a", "ab"):
        scene = make_scene(
            [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": name}],
            render={"width": 24, "height": 18, "spp": 16, "integrator": "path", "max_depth": 3},
            camera={"origin": [0.0, 0.5, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0},
            materials=materials,
            lights=[{"type": "environment", "radiance": [0.5, 0.5, 0.5]}],
        )
        images[name] = wrt.render(scene, specialize=False).rgb.astype(np.float64)
    assert images["a"].mean() > 0.05
    np.testing.assert_allclose(images["ab"].mean(axis=(0, 1)), images["a"].mean(axis=(0, 1)), rtol=0.03)


def principled_xml(tmp_path, body: str, approximate: bool = False) -> tuple[dict, list]:
    """The ``[[material]]`` table of a sphere whose BSDF is ``<bsdf type="principled">body</bsdf>``."""
    xml = sensor() + f'<shape type="sphere"><bsdf type="principled" id="p">{body}</bsdf></shape>'
    doc, warnings = convert(tmp_path, xml, approximate=approximate)
    return next(m for m in doc["material"] if m["name"] == "p"), warnings


def test_mitsuba_principled_converts_exactly(tmp_path):
    """Mitsuba's defaults (base colour 0.5, roughness 0.5, specular 0.5: eta 1.5); its names
    (``base_color`` is ``albedo``, ``anisotropic`` is ``anisotropy``); a textured number's
    checkerboard colours swapped (``eval_1``); no ``two_sided`` (its sides are its own)."""
    table, warnings = principled_xml(tmp_path, "")
    assert warnings == []
    assert table["albedo"] == [0.5] * 3 and table["roughness"] == 0.5 and "two_sided" not in table
    assert table["ior"] == pytest.approx(2.0 / (1.0 - math.sqrt(0.04)) - 1.0)  # 1.5
    checks = '<texture type="checkerboard" name="sheen"><float name="color0" value="0.2"/></texture>'
    body = f'<float name="anisotropic" value="0.6"/><float name="eta" value="1.33"/>{checks}'
    table, _ = principled_xml(tmp_path, body)
    assert table["anisotropy"] == 0.6 and table["ior"] == 1.33
    assert table["sheen"]["texture"] == "checkerboard" and table["sheen"]["color1"] == [0.2] * 3


def test_mitsuba_specular_zero_with_transmission_is_mitsubas_0001(tmp_path):
    table, _ = principled_xml(tmp_path, '<float name="specular" value="0"/><float name="spec_trans" value="0.5"/>')
    assert table["ior"] == pytest.approx(2.0 / (1.0 - math.sqrt(0.08e-3)) - 1.0)


def test_mitsuba_principleds_wrt_refuses(tmp_path):
    with pytest.raises(WrtError, match="either eta or specular"):
        principled_xml(tmp_path, '<float name="eta" value="1.4"/><float name="specular" value="0.5"/>')
    twosided = sensor() + '<shape type="sphere"><bsdf type="twosided"><bsdf type="principled"/></bsdf></shape>'
    with pytest.raises(WrtError, match="twosided principled"):
        convert(tmp_path, twosided, approximate=False)


def test_a_thin_principled_material_reads_its_own_keys():
    """``principled_thin`` (Mitsuba's ``principledthin``): ``diff_trans`` in [0, 2], its four
    sampling rates, transmission where ``spec_trans`` or ``diff_trans`` is given; no metallic or
    clearcoat (another type's keys are refused)."""
    scene = parse([{"name": "leaf", "type": "principled_thin", "diff_trans": 1.4, "ior": 1.33}])
    material = scene.materials[0]
    assert material.diff_trans == 1.4 and bake_materials(scene).flags[0] & BSDF_TRANSMISSION
    assert not bake_materials(parse([{"name": "leaf", "type": "principled_thin"}])).flags[0] & BSDF_TRANSMISSION
    with pytest.raises(SceneError, match="diff_trans"):
        parse([{"name": "leaf", "type": "principled_thin", "diff_trans": 2.5}])
    with pytest.raises(SceneError, match="clearcoat"):
        parse([{"name": "leaf", "type": "principled_thin", "clearcoat": 0.5}])
    with pytest.raises(SceneError, match='principled thin needs integrator = "path"'):
        parse([{"name": "leaf", "type": "principled_thin"}], integrator="whitted")


def test_mitsuba_principledthin_converts_exactly(tmp_path):
    checks = '<texture type="checkerboard" name="diff_trans"><float name="color0" value="0.4"/></texture>'
    xml = sensor() + (
        '<shape type="rectangle"><bsdf type="principledthin" id="t"><float name="eta" value="1.33"/>'
        f'<float name="specular_transmittance_sampling_rate" value="2"/>{checks}</bsdf></shape>'
    )
    doc, warnings = convert(tmp_path, xml, approximate=False)
    table = next(m for m in doc["material"] if m["name"] == "t")
    assert warnings == [] and table["type"] == "principled_thin" and table["ior"] == 1.33
    assert table["roughness"] == 0.5 and table["specular_transmittance_sampling_rate"] == 2.0
    assert table["diff_trans"]["texture"] == "checkerboard" and table["diff_trans"]["color1"] == [0.4] * 3
    textured_eta = '<texture type="checkerboard" name="eta"/>'
    with pytest.raises(WrtError, match="textured eta"):
        convert(
            tmp_path, sensor() + f'<shape type="rectangle"><bsdf type="principledthin">{textured_eta}</bsdf></shape>'
        )
