"""Environment maps in scenes (wrt/envmap.py, the loader, the path integrator, the Mitsuba
importer): closed forms, a float64 quadrature, and refusals of what wrt cannot render exactly."""

import textwrap

import numpy as np
import pytest
from envmap_reference import bilinear_irradiance, rotation, sun_sky

import wrt
from wrt.errors import SceneError, WrtError
from wrt.imageio import write_image
from wrt.mitsuba import load_mitsuba
from wrt.renderer import scene_features

SCENE = """\
[render]
width = {size}
height = {size}
integrator = "{integrator}"
max_depth = {max_depth}

[camera]
{camera}

[[material]]
name = "white"
albedo = [0.8, 0.8, 0.8]

[[shape]]
{shape}
material = "white"

[[light]]
type = "environment"
{light}
"""
SPHERE = 'type = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0'
FRONT = "origin = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 40.0"


def scene_file(tmp_path, light, *, shape=SPHERE, camera=FRONT, size=24, integrator="path", max_depth=8):
    path = tmp_path / "scene.toml"
    text = SCENE.format(light=light, shape=shape, camera=camera, size=size, integrator=integrator, max_depth=max_depth)
    path.write_text(text)
    return path


def test_constant_map_is_the_constant_environment(tmp_path):
    """Furnace-like: a white-ish (albedo 0.8) convex sphere under a uniform map of radiance 0.5 is
    0.8 x 0.5 at every pixel it covers at any depth (it never sees itself), the background 0.5;
    the constant environment of the same radiance renders the same."""
    write_image(tmp_path / "grey.exr", np.full((6, 12, 3), 0.25, dtype=np.float32))
    rgb = {}
    for name, light in (("map", 'file = "grey.exr"\nscale = 2.0'), ("constant", "radiance = [0.5, 0.5, 0.5]")):
        scene = wrt.load_scene(scene_file(tmp_path, light))
        assert scene_features(scene).environment_map == (name == "map")
        rgb[name] = wrt.render(scene, spp=64).rgb.astype(np.float64)
    for image in rgb.values():
        on_sphere = image[8:16, 8:16]
        np.testing.assert_allclose(image[0, 0], 0.5, rtol=1e-6)
        assert on_sphere.mean() == pytest.approx(0.4, rel=0.01)
        np.testing.assert_allclose(on_sphere, 0.4, rtol=0.1)
    assert rgb["map"].mean() == pytest.approx(rgb["constant"].mean(), rel=0.01)


def test_floor_under_a_sun_matches_the_float64_irradiance(tmp_path):
    """An orthographic camera looking down at a diffuse floor (albedo 0.8) under a rotated map
    with a sun: every pixel is 0.8 / pi times the map's irradiance on the floor (float64
    quadrature of Mitsuba's bilinear lookup), through next-event estimation, BSDF sampling and
    their MIS weights."""
    image = sun_sky(sun_radiance=300.0)
    write_image(tmp_path / "sky.exr", image.astype(np.float32))
    to_world = rotation((1.0, 0.0, 0.0), 20.0)
    light = 'file = "sky.exr"\ntransform = { rotate = [20.0, 0.0, 0.0] }'
    floor = 'type = "plane"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]'
    camera = (
        'type = "orthographic"\norigin = [0.0, 1.0, 0.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\nwidth = 2.0'
    )
    scene = wrt.load_scene(scene_file(tmp_path, light, shape=floor, camera=camera, size=8, max_depth=2))
    green = wrt.render(scene, spp=512).rgb[..., 1].astype(np.float64)
    expected = 0.8 / np.pi * bilinear_irradiance(image, np.array([0.0, 1.0, 0.0]), to_world)
    assert green.mean() == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize(
    "light, key, problem",
    [
        ('file = "sky.exr"\nradiance = [1.0, 1.0, 1.0]', "radiance", "is for a constant environment"),
        ("radiance = [1.0, 1.0, 1.0]\nscale = 2.0", "scale", "applies to an environment map only"),
        ('file = "nowhere.exr"', "file", "no such file"),
        ('file = "sky.png"', "file", "must be an OpenEXR (.exr) or Radiance HDR (.hdr)"),
        ('file = "sky.exr"\nscale = -1.0', "scale", "must be in [0, inf]"),
        ('file = "sky.exr"\ntransform = { scale = 2.0 }', "transform", "must be a rotation"),
        ('file = "sky.exr"\ntransform = { translate = [0.0, 1.0, 0.0] }', "transform", "must be a rotation"),
        ('file = "bad.exr"', "file", "negative, infinite or NaN"),
        ('file = "row.exr"', "file", "at least 2"),
    ],
)
def test_bad_environment_maps_are_one_scene_error(tmp_path, light, key, problem):
    write_image(tmp_path / "sky.exr", np.ones((4, 8, 3), dtype=np.float32))
    write_image(tmp_path / "bad.exr", np.full((4, 8, 3), -1.0, dtype=np.float32))
    write_image(tmp_path / "row.exr", np.ones((1, 8, 3), dtype=np.float32))
    with pytest.raises(SceneError) as e:
        wrt.load_scene(scene_file(tmp_path, light))
    assert e.value.table == "light[0]" and e.value.key == key and problem in str(e.value), str(e.value)


def test_a_second_map_and_whitted_are_refused(tmp_path):
    write_image(tmp_path / "sky.exr", np.ones((4, 8, 3), dtype=np.float32))
    path = scene_file(tmp_path, 'file = "sky.exr"')
    path.write_text(path.read_text() + '\n[[light]]\ntype = "environment"\nfile = "sky.exr"\n')
    with pytest.raises(SceneError, match=r"light\[1\].*a second environment map"):
        wrt.load_scene(path)
    with pytest.raises(SceneError, match='need integrator = "path"'):
        wrt.load_scene(scene_file(tmp_path, 'file = "sky.exr"', integrator="whitted"))


def mitsuba_scene(tmp_path, emitter):
    (tmp_path / "maps").mkdir(exist_ok=True)
    write_image(tmp_path / "maps" / "sky.exr", np.ones((4, 8, 3), dtype=np.float32))
    path = tmp_path / "scene.xml"
    path.write_text(f'<scene version="3.0.0">\n<path value="maps"/>\n{textwrap.dedent(emitter)}\n</scene>\n')
    return path


def test_mitsuba_envmap_converts_exactly(tmp_path):
    """filename (found on Mitsuba's search path), scale and to_world's rotation; the translation
    is dropped (directions ignore it) and mis_compensation changes only the noise: no warning."""
    path = mitsuba_scene(
        tmp_path,
        """\
        <emitter type="envmap">
            <string name="filename" value="sky.exr"/>
            <float name="scale" value="2.5"/>
            <boolean name="mis_compensation" value="true"/>
            <transform name="to_world"><rotate y="1" angle="90"/><translate x="3"/></transform>
        </emitter>""",
    )
    doc, warnings = load_mitsuba(path)
    (light,) = doc["light"]
    assert warnings == [] and light["file"] == "maps/sky.exr" and light["scale"] == 2.5
    matrix = np.reshape(light["transform"]["matrix"], (4, 4))
    np.testing.assert_allclose(matrix[:3, :3], rotation((0.0, 1.0, 0.0), 90.0), atol=1e-12)
    assert not matrix[:3, 3].any()


def test_mitsuba_envmap_refusals(tmp_path):
    scaled = '<emitter type="envmap"><string name="filename" value="sky.exr"/>'
    scaled += '<transform name="to_world"><scale value="2"/></transform></emitter>'
    with pytest.raises(WrtError, match="to_world is not a rotation"):
        load_mitsuba(mitsuba_scene(tmp_path, scaled))
    _, warnings = load_mitsuba(mitsuba_scene(tmp_path, scaled), approximate=True)
    assert len(warnings) == 1
    missing = '<emitter type="envmap"><string name="filename" value="nowhere.exr"/></emitter>'
    with pytest.raises(WrtError, match="no such environment map 'nowhere.exr'"):
        load_mitsuba(mitsuba_scene(tmp_path, missing))


def test_radiance_hdr_reads_as_its_exr(tmp_path):
    """A Radiance HDR reads as the OpenEXR of the same pixels, up to RGBE's rounding: 8-bit
    mantissas under the exponent of the pixel's largest channel."""
    import OpenImageIO as oiio

    from wrt.envmap import read_environment_map

    image = sun_sky(width=16, height=8, sun=(3, 2)).astype(np.float32)
    out = oiio.ImageOutput.create(str(tmp_path / "sky.hdr"))
    out.open(str(tmp_path / "sky.hdr"), oiio.ImageSpec(16, 8, 3, "float"))
    out.write_image(image)
    out.close()
    error = np.abs(read_environment_map(tmp_path / "sky.hdr") - image)
    assert np.all(error <= image.max(axis=-1, keepdims=True) / 128)
