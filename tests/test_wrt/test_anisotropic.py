"""Anisotropic roughness (``roughness_v``): the scene key and its checks, the Mitsuba importer's
``alpha_u`` and ``alpha_v``, an isotropic material rendering bit for bit the same through the
anisotropic code, and the alphas lying along the shading frame's axes. The microfacet functions
themselves (against float64 and Mitsuba's ``MicrofacetDistribution``, chi-square of the sampling)
are tests/test_kernels/test_microfacet.py's; the image against Mitsuba's is the ``anisotropic``
cross-check (test_mitsuba_crosscheck.py)."""

import numpy as np
import pytest
from conftest import make_scene
from test_mitsuba_xml import convert

import wrt
from wrt.errors import SceneError, WrtError
from wrt.renderer import scene_features

SPHERE = [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "metal"}]
LIGHTS = [{"type": "point", "position": [2, 3, 4], "intensity": [30, 30, 30]}]


def metal(**keys):
    return [{"name": "metal", "type": "conductor", "metal": "Au", "roughness": 0.3, **keys}]


def test_roughness_v_makes_a_material_anisotropic():
    scene = make_scene(SPHERE, materials=metal(roughness_v=0.05), lights=LIGHTS)
    material = scene.materials[0]
    assert (material.roughness, material.roughness_v, material.anisotropic) == (0.3, 0.05, True)
    assert scene_features(scene).anisotropic
    isotropic = make_scene(SPHERE, materials=metal(), lights=LIGHTS)
    assert isotropic.materials[0].roughness_v is None and not scene_features(isotropic).anisotropic


@pytest.mark.parametrize(
    "materials, message",
    [
        (metal(roughness_v=0.0), r"material\[0\]\.roughness_v = 0(\.0)?: must be in \[0\.001, 1\]"),
        (metal(roughness_v="0.1"), r"material\[0\]\.roughness_v = '0\.1': must be a number"),
        (
            [{"name": "metal", "type": "conductor", "metal": "Au", "roughness_v": 0.1}],
            r"material\[0\]\.roughness_v = 0\.1: needs a rough conductor: roughness 0 is a smooth one",
        ),
        ([{"name": "metal", "type": "rough_plastic", "roughness_v": 0.1}], r"material\[0\]\.roughness_v"),
        ([{"name": "metal", "type": "diffuse", "roughness_v": 0.1}], r"material\[0\]\.roughness_v"),
    ],
)
def test_bad_roughness_v_is_one_message_naming_it(materials, message):
    with pytest.raises(SceneError, match=message):
        make_scene(SPHERE, materials=materials, lights=LIGHTS)


def test_an_isotropic_material_renders_bit_for_bit_through_the_anisotropic_code():
    """``roughness_v`` equal to ``roughness``: the scene compiles the anisotropic code (its
    Features say so), yet every function is its isotropic form bit for bit and no tangent is
    taken: the image is the isotropic scene's exactly. The all-features kernel renders both."""
    render = {"width": 12, "height": 8, "spp": 4, "integrator": "path"}
    images = []
    for keys in ({}, {"roughness_v": 0.3}):
        scene = make_scene(SPHERE, render=render, materials=metal(**keys), lights=LIGHTS)
        images.append(wrt.render(scene, specialize=False).rgb)
    assert np.array_equal(*images) and images[0].max() > 0.0


def test_the_alphas_lie_along_the_tangent_and_across_it():
    """A sphere's tangent runs around its z axis: seen along z, a highlight stretched along the
    tangent (``roughness`` the larger alpha) spreads around the pole, one stretched across it
    (``roughness_v`` the larger) along the meridians. Swapping the alphas turns the image by a
    quarter turn about the view axis (the sphere's symmetry), which no isotropic material does."""
    render = {"width": 48, "height": 48, "spp": 16, "integrator": "path", "max_depth": 2}  # direct light
    camera = {"origin": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "fov": 35}
    light = [{"type": "point", "position": [3.0, 0.0, 3.0], "intensity": [40, 40, 40]}]
    images = []
    for u, v in ((0.4, 0.05), (0.05, 0.4)):
        scene = make_scene(
            SPHERE,
            render=render,
            camera=camera,
            materials=[{"name": "metal", "type": "glossy", "roughness": u, "roughness_v": v}],
            lights=light,
        )
        images.append(wrt.render(scene).rgb.astype(np.float64).mean(axis=-1))
    along, across = images
    # the highlight sits right of centre (the light is at +x): along the tangent (vertical there)
    # it is tall and narrow, across it (horizontal) wide and short
    rows, cols = np.nonzero(along > 0.5 * along.max())
    rows_x, cols_x = np.nonzero(across > 0.5 * across.max())
    assert np.ptp(rows) > 2 * np.ptp(cols), (np.ptp(rows), np.ptp(cols))
    assert np.ptp(cols_x) > 2 * np.ptp(rows_x), (np.ptp(rows_x), np.ptp(cols_x))


def test_mitsubas_alpha_u_and_alpha_v_convert_exactly(tmp_path):
    body = """
    <shape type="sphere"><bsdf type="roughconductor">
        <string name="distribution" value="ggx"/><string name="material" value="Al"/>
        <float name="alpha_u" value="0.25"/><float name="alpha_v" value="0.05"/></bsdf></shape>
    <shape type="sphere"><bsdf type="roughdielectric">
        <float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/></bsdf></shape>"""
    doc, warnings = convert(tmp_path, body, approximate=False)
    assert warnings == []
    first, second = doc["material"]
    assert (first["type"], first["roughness"], first["roughness_v"], first["distribution"]) == (
        "conductor",
        0.25,
        0.05,
        "ggx",
    )
    assert (second["type"], second["roughness"], second["roughness_v"]) == ("rough_dielectric", 0.1, 0.3)
    assert all(m.anisotropic for m in wrt.parse_scene(doc, scene_dir=str(tmp_path)).materials[:2])


@pytest.mark.parametrize(
    "params, message",
    [
        ('<float name="alpha_u" value="0.2"/>', "give both alpha_u and alpha_v"),
        (
            '<float name="alpha" value="0.2"/><float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.1"/>',
            "give either alpha or alpha_u and alpha_v",
        ),
    ],
)
def test_mitsubas_incomplete_alphas_are_refused(tmp_path, params, message):
    with pytest.raises(WrtError, match=rf"scene.xml:2: .*{message}"):
        convert(tmp_path, f'<shape type="sphere"><bsdf type="roughconductor">{params}</bsdf></shape>')


def test_an_anisotropic_rotated_sphere_converts_exactly_with_its_frame(tmp_path):
    """A sphere that Mitsuba's to_world turns keeps its frame (a ``transform`` turning its object
    axes, which its tangent field follows: test_normal_map compares it with Mitsuba's); before,
    wrt's spheres had none and this was only an approximation."""
    body = """<shape type="sphere"><transform name="to_world"><rotate x="1" angle="40"/></transform>
        <bsdf type="roughconductor"><float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.05"/></bsdf>
        </shape>"""
    doc, warnings = convert(tmp_path, body, approximate=False)
    (sphere,) = doc["shape"]
    assert not warnings and np.allclose(
        np.reshape(sphere["transform"]["matrix"], (4, 4))[1:3, 1:3], [[0.766, -0.643], [0.643, 0.766]], atol=1e-3
    )


def test_mitsubas_identity_normal_map_over_an_anisotropic_conductor_converts_exactly(tmp_path):
    """The shape of Mitsuba's test_normalmap_identity_roughconductor_path: a normalmap given as a
    ``<spectrum type="srgb">`` colour around an anisotropic rough conductor."""
    body = """<shape type="sphere"><bsdf type="normalmap">
        <spectrum name="normalmap" type="srgb"><rgb name="color" value="0.5, 0.5, 1.0"/></spectrum>
        <bsdf type="roughconductor"><string name="material" value="Al"/><string name="distribution" value="ggx"/>
        <float name="alpha_u" value="0.25"/><float name="alpha_v" value="0.05"/></bsdf></bsdf></shape>"""
    doc, warnings = convert(tmp_path, body, approximate=False)
    material = doc["material"][0]
    assert warnings == [] and (material["roughness"], material["roughness_v"]) == (0.25, 0.05)
    assert material["normal_map"] == {"texture": "constant", "value": [0.5, 0.5, 1.0]}
    assert wrt.parse_scene(doc, scene_dir=str(tmp_path)).materials[0].anisotropic
