"""The geometry oracle (harness/oracle.py) sees what the ray tracer sees: pyvista's rasterisation
of the same camera (perspective or orthographic, clip planes included) decodes to the ray
tracer's ``object_id`` AOV."""

import dataclasses

import numpy as np
import pytest
from conftest import EXAMPLES
from skimage.io import imread
from wrt_harness.oracle import _decode, _encode, overview, palette, rasterize_ids

import wrt

CAMERAS = {
    "orthographic": {},
    "orthographic, near clip through the red sphere": {"near_clip": 6.7},
    "orthographic, far clip before the blue sphere": {"far_clip": 7.5},
    "perspective, clipped": {"type": "perspective", "width": None, "fov": 50.0, "near_clip": 6.7, "far_clip": 9.0},
}


@pytest.mark.parametrize("name", list(CAMERAS))
def test_rasterised_ids_match_the_ray_tracer(name):
    scene = wrt.load_scene(EXAMPLES / "raycast" / "raycast_orthographic.toml")
    scene = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, **CAMERAS[name]))
    ids = wrt.render(scene).aovs["object_id"]
    assert len(np.unique(ids)) >= 3  # the clip planes cut something away, and something is left
    assert np.mean(rasterize_ids(scene) == ids) > 0.995  # pixels on silhouettes may differ


def test_rasterised_instances_match_the_ray_tracer():
    """Each instance is one surface to the oracle: its group's shapes through its transform."""
    group = [
        {"type": "sphere", "center": [0.6, 0, 0], "radius": 0.5},
        {"type": "polygon", "vertices": [[-1, -0.6, 0], [0, -0.6, 0.3], [-0.5, 0.7, 0]]},
        {"type": "disk", "center": [0, 0.9, 0], "normal": [0, 0, 1], "radius": 0.3},
    ]
    placements = [
        {"translate": [-1.6, 0, 0]},
        {"translate": [1.4, 0.3, 0], "rotate": [0, 30, 20], "scale": [0.8, 1.4, 1]},
        {"translate": [0, -1.6, -1], "matrix": [[1, 0.5, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
    ]
    scene = wrt.parse_scene(
        {
            "render": {"width": 96, "height": 72, "integrator": "raycast"},
            "camera": {"origin": [0, 0, 6], "look_at": [0, 0, 0], "fov": 50},
            "group": [{"name": "g", "shape": group}],
            "shape": [{"type": "instance", "group": "g", "transform": t} for t in placements],
        }
    )
    ids = wrt.render(scene).aovs["object_id"]
    assert set(np.unique(ids)) == {-1, 0, 1, 2}
    assert np.mean(rasterize_ids(scene) == ids) > 0.99


def test_rasterised_light_surfaces_match_the_ray_tracer():
    """Area and sphere lights are surfaces to the oracle too, with the renderer's ids ``-2 - k``
    (k: the index in ``[[light]]``); an area light counts from both sides."""
    area = {"type": "area", "edge_u": [1.2, 0, 0], "radiance": [4, 4, 4]}
    scene = wrt.parse_scene(
        {
            "render": {"width": 96, "height": 72, "integrator": "raycast"},
            "camera": {"origin": [0, 1, 6], "look_at": [0, 0, 0], "fov": 50},
            "shape": [
                {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]},
                {"type": "sphere", "center": [0, 0, 0], "radius": 0.8},
            ],
            "light": [
                {"type": "point", "position": [0, 5, 0], "intensity": [1, 1, 1]},
                {**area, "corner": [-2.6, -0.5, 0], "edge_v": [0, 1.0, 0.3]},  # emits toward the camera
                {"type": "sphere", "center": [1.6, 0.6, -0.5], "radius": 0.45, "radiance": [3, 3, 3]},
                {**area, "corner": [0.8, -0.1, 1], "edge_v": [0.3, -0.8, 0]},  # emits away from it: its back
            ],
        }
    )
    ids = wrt.render(scene).aovs["object_id"]
    assert set(np.unique(ids)) == {-5, -4, -3, -1, 0, 1}
    assert np.mean(ids <= -2) > 0.05
    assert np.mean(rasterize_ids(scene) == ids) > 0.99


def test_palette_colours_light_surfaces_apart():
    """Light ids get pale tints: not black (a miss), not the colour of another light or of a shape."""
    shapes, lights = palette(np.arange(64)), palette(-2 - np.arange(8))
    np.testing.assert_array_equal(palette(np.array([-1])), [[0, 0, 0]])
    assert np.all(lights.min(axis=-1) > 0.5)
    gaps = np.abs(lights[:, None] - np.concatenate([shapes, lights])[None]).max(axis=-1)
    assert np.all(np.sort(gaps, axis=1)[:, 1] > 0.05)  # each differs from all but itself


def test_ids_survive_the_colour_encoding():
    ids = np.array([-1, 0, 1, 254, 255, 256, 70000, 2**23 - 2, -2, -3, -258, -(2**23)])
    colours = np.array([_encode(i) for i in ids])
    assert np.array_equal(_decode(np.rint(255 * colours)), ids)


def test_overview_keeps_the_scene_up(tmp_path):
    """The overview depends on the scene, not on which world axis is its up: a scene with up +y and
    the same scene turned so that its up is +z give the same picture."""
    turn = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # +y to +z

    def scene(m):
        def at(*p):
            return (m @ p).tolist()

        return wrt.parse_scene(
            {
                "camera": {"origin": at(1, 1, 5), "look_at": [0, 0, 0], "up": at(0, 1, 0)},
                "shape": [
                    {"type": "polygon", "vertices": [at(x, -1, z) for x, z in ((-2, 2), (2, 2), (2, -2), (-2, -2))]},
                    {"type": "sphere", "center": at(0.5, 0, 0), "radius": 0.8},
                ],
                "light": [
                    {
                        "type": "area",
                        "corner": at(-1, 2, -1),
                        "edge_u": at(2, 0, 0),
                        "edge_v": at(0, 0, 1),
                        "radiance": [1, 1, 1],
                    }
                ],
            }
        )

    overview(scene(np.eye(3)), str(tmp_path / "y.png"))
    overview(scene(turn), str(tmp_path / "z.png"))
    y, z = imread(tmp_path / "y.png").astype(int), imread(tmp_path / "z.png").astype(int)
    assert len(np.unique(y.reshape(-1, y.shape[-1]), axis=0)) > 10
    assert np.mean(np.abs(y - z).max(axis=-1) > 8) < 0.005  # edges may round differently
