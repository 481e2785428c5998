"""The camera convention (kernels/camera.py) checked through rendered AOVs."""

import math

import numpy as np
import pytest
from conftest import make_scene

import wrt


def expected_directions(origin, look_at, up, fov, w, h):
    """The scene-format formula in float64, for every pixel centre (row 0 at the top)."""
    forward = np.subtract(look_at, origin, dtype=float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    sx, sy = 2 * x / w - 1, 1 - 2 * y / h
    th = math.tan(math.radians(fov) / 2)
    d = (sx * th * w / h)[..., None] * right + (sy * th)[..., None] * true_up + forward
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_primary_ray_directions_follow_the_formula():
    """(position - origin) / depth recovers each pixel's ray; it must equal the documented formula."""
    cam = {"origin": [1.0, 2.0, 3.0], "look_at": [-2.0, 0.5, -4.0], "up": [0.2, 1.0, 0.1], "fov": 50.0}
    scene = make_scene(
        [{"type": "sphere", "center": cam["origin"], "radius": 100.0}], camera=cam, render={"width": 64, "height": 40}
    )
    r = wrt.render(scene)
    d = (r.aovs["position"] - np.array(cam["origin"])) / r.aovs["depth"][..., None]
    np.testing.assert_allclose(
        d, expected_directions(cam["origin"], cam["look_at"], cam["up"], 50.0, 64, 40), atol=2e-5
    )
    np.testing.assert_allclose(r.aovs["depth"], 100.0, rtol=1e-5)  # from the centre of the sphere


def test_sphere_projects_where_the_formula_says():
    """A small sphere up and to the right of the view axis lands on the pixel the formula predicts."""
    w, h, fov = 200, 100, 40.0
    centre = np.array([0.9, 0.6, -10.0])
    scene = make_scene(
        [{"type": "sphere", "center": centre.tolist(), "radius": 0.15}],
        camera={"origin": [0, 0, 0], "look_at": [0, 0, -1], "up": [0, 1, 0], "fov": fov},
        render={"width": w, "height": h},
    )
    ids = wrt.render(scene).aovs["object_id"]
    th = math.tan(math.radians(fov) / 2)
    sx = (centre[0] / -centre[2]) / (th * w / h)
    sy = (centre[1] / -centre[2]) / th
    px, py = (sx + 1) * w / 2, (1 - sy) * h / 2  # continuous film position of the centre
    assert ids[int(py), int(px)] == 0
    ys, xs = np.nonzero(ids == 0)
    assert xs.mean() + 0.5 == pytest.approx(px, abs=0.5) and ys.mean() + 0.5 == pytest.approx(py, abs=0.5)
    assert py < h / 2 and px > w / 2  # row 0 is the top: above the axis means small y


def test_aspect_and_vertical_fov():
    """The vertical fov spans the image height: a sphere subtending fov/2 half-angle touches top and bottom."""
    fov = 30.0
    dist = 10.0
    radius = dist * math.sin(math.radians(fov / 2))
    scene = make_scene(
        [{"type": "sphere", "center": [0, 0, -dist], "radius": radius * 0.98}],
        camera={"origin": [0, 0, 0], "look_at": [0, 0, -1], "fov": fov},
        render={"width": 120, "height": 60},
    )
    ids = wrt.render(scene).aovs["object_id"]
    column = ids[:, 60]
    # half-angle of the sphere 14.69 deg; pixel-centre rays of rows 0 and 1 leave at 14.76 and 14.27 deg
    assert column[0] == -1 and column[-1] == -1
    assert (column[1:-1] == 0).all()
    cols = np.flatnonzero(ids[30] == 0)
    assert 60 - cols.min() == pytest.approx(30, abs=2)  # circle: horizontal radius in pixels = vertical
