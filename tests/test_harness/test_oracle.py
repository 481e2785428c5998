"""The geometry oracle (harness/oracle.py) sees what the ray tracer sees: pyvista's rasterisation
of the same camera (perspective or orthographic, clip planes included) decodes to the ray
tracer's ``object_id`` AOV."""

import dataclasses

import numpy as np
import pytest
from conftest import EXAMPLES
from wrt_harness.oracle import rasterize_ids

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
