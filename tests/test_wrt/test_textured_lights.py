"""Textured delta lights: the ``projector`` and a ``spot`` with a ``texture`` (kernels/lights/delta.py)
against closed forms and Mitsuba 3's own emitters, the scene format's checks, and the importer."""

import math

import numpy as np
import pytest
import warp as wp
from conftest import EXAMPLES, make_scene
from test_mitsuba_xml import convert, sensor, write
from wrt.kernels.lights import LightData, light_incident

import wrt
from wrt.device import upload_lights
from wrt.errors import SceneError, WrtError
from wrt.textures import read_bitmap

GRID = str(EXAMPLES / "textures" / "grid.png")  # 64 x 32: aspect 2, a black block at its top left
WALL = {"type": "plane", "point": [0.0, 0.0, -2.0], "normal": [0.0, 0.0, 1.0], "material": "white"}
WHITE = [{"name": "white", "albedo": [0.5, 0.5, 0.5]}]
DIRECT = {"width": 48, "height": 36, "spp": 1, "integrator": "path", "max_depth": 2}  # pixel centres, direct light
CAMERA = {"origin": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, -1.0], "fov": 60.0}


def wall_render(light: dict, render=DIRECT, camera=CAMERA) -> np.ndarray:
    scene = make_scene([WALL], render=render, camera=camera, materials=WHITE, lights=[light])
    return wrt.render(scene, specialize=False).rgb.astype(np.float64)


def test_a_projector_gives_a_facing_plane_pi_scale_irradiance_over_depth_squared_inside_its_frustum():
    """A constant projector at the camera: a wall facing it at depth z receives irradiance
    ``pi scale E / z^2`` everywhere in the frustum (Mitsuba's "irradiance at z = 1 is correct"),
    so a diffuse wall of albedo a at depth 2 shows radiance ``a scale E / 4`` exactly; the lit
    rectangle is the frustum of its vertical ``fov`` (a square one: a constant has aspect 1)."""
    light = {"type": "projector", "position": [0.0, 0.0, 0.0], "direction": [0.0, 0.0, -1.0], "fov": 30.0}
    image = wall_render({**light, "irradiance": [1.0, 2.0, 4.0], "scale": 0.75})
    lit = image[..., 0] > 0.0
    np.testing.assert_allclose(image[lit], np.broadcast_to([0.375, 0.75, 1.5], image[lit].shape) / 4, rtol=1e-5)
    # the camera's vertical fov is 60 degrees over 36 rows: the frustum's half-height tan(15) / tan(30)
    rows, cols = np.nonzero(lit[:, :])
    half = 18 * math.tan(math.radians(15)) / math.tan(math.radians(30))
    assert abs((rows.max() - rows.min() + 1) / 2 - half) <= 1 and abs((cols.max() - cols.min() + 1) / 2 - half) <= 1


def test_a_projected_image_keeps_its_orientation_and_aspect():
    """grid.png (64 x 32) projected from the camera, seen by it: a third of the camera's vertical
    field of view, it fills 32 of 96 rows and, 2 : 1 (the texture's aspect sets the horizontal
    field of view), 64 of 128 columns; upright and unmirrored: each pixel the texel there (one
    texel a pixel, at its centre), the black block at the top left."""
    render = {**DIRECT, "width": 128, "height": 96}
    light = {
        "type": "projector",
        "position": [0.0, 0.0, 0.0],
        "direction": [0.0, 0.0, -1.0],
        "fov": 2 * math.degrees(math.atan(math.tan(math.radians(30)) / 3)),  # 32 of the camera's 96 rows
        "irradiance": {"texture": "bitmap", "file": GRID, "filter": "nearest"},
        "scale": 4.0 / 0.5,  # albedo 0.5, depth 2: the wall's radiance is the texel
    }
    image = wall_render(light, render=render)
    grid = read_bitmap(GRID).astype(np.float64)
    inside = image[32:64, 32:96]
    assert not image[:32].any() and not image[64:].any() and not image[:, :32].any() and not image[:, 96:].any()
    np.testing.assert_allclose(inside, grid, rtol=1e-4, atol=1e-6)
    assert inside[:4, :8].max() < 0.01 < inside[-4:, -8:].max(axis=-1).min()  # the black block, at the top left


def test_a_textured_spot_is_its_profile_times_its_texture():
    """A spot with a constant texture of 0.4 is 0.4 times the same spot without one, pixel for
    pixel; with a checkerboard, each pixel is one of its two colours times the untextured one."""
    spot = {"type": "spot", "position": [0.0, 0.0, 0.0], "direction": [0.0, 0.0, -1.0], "intensity": [3.0, 3.0, 3.0]}
    plain = wall_render(spot)
    assert plain.max() > 0.0
    grey = wall_render({**spot, "texture": {"texture": "constant", "value": 0.4}})
    np.testing.assert_allclose(grey, 0.4 * plain, rtol=1e-5, atol=1e-7)
    checker = {"texture": "checkerboard", "color0": [1.0, 0.0, 0.0], "color1": [0.0, 0.0, 1.0], "scale": 4}
    image = wall_render({**spot, "texture": checker})
    lit = plain[..., 0] > 0.0
    red, blue = image[lit][:, 0] > 0.0, image[lit][:, 2] > 0.0
    assert red.any() and blue.any() and not (red & blue).any()
    np.testing.assert_allclose(image[lit][:, 0] + image[lit][:, 2], plain[lit][:, 0], rtol=1e-5)


@wp.kernel
def incident(lights: LightData, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    k = wp.tid()
    wi, dist, irradiance = light_incident(lights, 0, points[k])
    out[k] = irradiance


@pytest.mark.parametrize("kind", ["projector", "spot"])
def test_light_incident_matches_mitsubas_sample_direction(kind, rng):
    """What the light delivers to random points, against Mitsuba 3's ``sample_direction`` of the
    same emitter (a bitmap through a tilted, rolled frame), to float32 rounding."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    origin, target, up = [0.3, -0.2, 1.0], [0.1, 0.2, -1.0], [0.4, 1.0, 0.2]
    texture = {"type": "bitmap", "filename": GRID}
    if kind == "projector":
        theirs = {"type": "projector", "irradiance": texture, "scale": 1.7, "fov": 50.0}
    else:
        theirs = {"type": "spot", "texture": texture, "intensity": 2.5, "cutoff_angle": 35.0, "beam_width": 20.0}
    emitter = mi.load_dict({**theirs, "to_world": mi.ScalarTransform4f().look_at(origin, target, up)})
    tables = {"irradiance" if kind == "projector" else "texture": {"texture": "bitmap", "file": GRID}}
    direction = np.subtract(target, origin) / np.linalg.norm(np.subtract(target, origin))
    ours = {"type": kind, "position": origin, "direction": list(direction), "up": up, **tables}
    if kind == "projector":
        ours.update(scale=1.7, fov=2 * math.degrees(math.atan(math.tan(math.radians(25.0)) / 2)))  # x-fov 50, aspect 2
    else:
        ours.update(intensity=[2.5] * 3, cutoff_angle=35.0, beam_width=20.0)
    scene = make_scene([WALL], materials=WHITE, lights=[ours])
    points = np.asarray(origin) + 3.0 * direction + rng.uniform(-1.5, 1.5, (400, 3))
    out = wp.zeros(len(points), dtype=wp.vec3)
    wp.launch(incident, len(points), [upload_lights(scene, "cpu"), wp.array(points, dtype=wp.vec3), out])
    expected = []
    for p in points:
        it = mi.Interaction3f()
        it.p = mi.Point3f(*p)
        _, spectrum = emitter.sample_direction(it, mi.Point2f(0.5, 0.5))
        expected.append(np.array(spectrum))
    expected = np.array(expected)
    assert (expected > 0).any(axis=1).mean() > 0.2  # enough points inside the light's frustum
    np.testing.assert_allclose(out.numpy(), expected, rtol=2e-4, atol=1e-6)


@pytest.mark.parametrize(
    "light, key, value",
    [
        ({"type": "projector", "position": [0, 0, 0], "direction": [0, 0, -1]}, "irradiance", None),
        (
            {"type": "projector", "irradiance": 1.0, "position": [0, 0, 0], "direction": [0, 1, 0]},
            "up",
            [0.0, 1.0, 0.0],
        ),
        ({"type": "projector", "irradiance": -1.0, "position": [0, 0, 0], "direction": [0, 0, 1]}, "irradiance", -1.0),
        (
            {"type": "projector", "irradiance": 1.0, "fov": 180, "position": [0, 0, 0], "direction": [0, 0, 1]},
            "fov",
            180,
        ),
        (
            {"type": "spot", "up": [1, 0, 0], "intensity": [1, 1, 1], "position": [0, 0, 0], "direction": [0, 0, 1]},
            "up",
            [1, 0, 0],
        ),
        (
            {
                "type": "spot",
                "texture": {"texture": "bitmap", "file": "missing.png"},
                "intensity": [1, 1, 1],
                "position": [0, 0, 0],
                "direction": [0, 0, 1],
            },
            "file",
            "missing.png",
        ),
    ],
    ids=["no-irradiance", "up-parallel", "negative", "fov-180", "up-untextured", "missing-file"],
)
def test_bad_textured_lights_are_one_line_naming_key_and_value(light, key, value, tmp_path):
    with pytest.raises(SceneError) as caught:
        make_scene([WALL], materials=WHITE, lights=[light], scene_dir=str(tmp_path))
    message = str(caught.value)
    assert "\n" not in message and key in message and "light[0]" in message
    if value is not None:
        assert str(value) in message


PROJECTOR_XML = """
<emitter type="projector">
    <texture name="irradiance" type="bitmap"><string name="filename" value="{grid}"/></texture>
    <float name="fov" value="40"/>
    <float name="scale" value="2"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="1, 1, 0"/></transform>
</emitter>"""


def test_the_importer_converts_projectors_and_textured_spots_exactly(tmp_path):
    """A projector's x-fov on its texture's 2 : 1 film becomes wrt's vertical fov; its lookat's up
    and a spot's its frame's y; nothing approximated (the repository's example too)."""
    scene = wrt.load_scene(str(write(tmp_path, sensor() + PROJECTOR_XML.format(grid=GRID))))
    (light,) = scene.lights
    assert light.type == "projector" and light.scale == 2.0 and light.aspect == 2.0
    assert light.fov == pytest.approx(2 * math.degrees(math.atan(math.tan(math.radians(20.0)) / 2.0)))
    assert np.allclose(light.frame()[1], np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0))
    example = wrt.load_scene(str(EXAMPLES / "mitsuba" / "projector.xml"))
    assert {light.type for light in example.lights} == {"environment", "projector", "spot"}
    assert not example.approximations


def test_the_importer_refuses_a_spot_with_a_constant_texture_and_a_projector_without_irradiance(tmp_path):
    """As Mitsuba 3 refuses them."""
    spot = '<emitter type="spot"><rgb name="texture" value="0.5"/></emitter>'
    with pytest.raises(WrtError, match="spatially varying"):
        convert(tmp_path, sensor() + spot, approximate=False)
    with pytest.raises(WrtError, match="needs an irradiance"):
        convert(tmp_path, sensor() + '<emitter type="projector"/>', approximate=False)
