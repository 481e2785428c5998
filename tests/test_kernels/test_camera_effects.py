"""Motion blur and pixel filters, end to end through the render kernels, against closed forms."""

import math

import numpy as np
import pytest
from conftest import make_scene

import wrt

GLOW = [{"name": "glow", "albedo": [0.0, 0.0, 0.0], "emission": [1.0, 1.0, 1.0]}]
CAMERA = {"origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0], "fov": 40.0}


def half_plane(edge_x: float, velocity=(0.0, 0.0, 0.0)) -> dict:
    """An emitting square patch covering x < edge_x of the plane z = 0 (in view), facing +z."""
    return {
        "type": "polygon",
        "vertices": [[-100.0, -100.0, 0.0], [edge_x, -100.0, 0.0], [edge_x, 100.0, 0.0], [-100.0, 100.0, 0.0]],
        "material": "glow",
        "velocity": list(velocity),
    }


def emitted(device, shapes, size, spp, camera=CAMERA, **render):
    settings = {"width": size[0], "height": size[1], "integrator": "path", "spp": spp, "max_depth": 1, **render}
    return wrt.render(make_scene(shapes, materials=GLOW, camera=camera, render=settings), device=device)


def column_x(width: int, height: int, fov: float = 40.0, distance: float = 5.0) -> np.ndarray:
    """World x on the plane z = 0 of each pixel column's centre, and the pixel width there."""
    half = distance * math.tan(math.radians(fov) / 2) * width / height
    return (2 * (np.arange(width) + 0.5) / width - 1) * half, 2 * half / width


def test_motion_blur_of_a_moving_edge_is_the_fraction_of_the_shutter_it_covers(device):
    """An edge moving from x = -6 to x = 6 over the shutter [0, 1] covers a point x for a fraction
    1 - (x + 6) / 12 of the time: the time-averaged image is a linear ramp. The patch's static
    bounds end at x = -6, so the ramp is only there if the BVH bounds the whole sweep."""
    w, h = 48, 4
    r = emitted(
        device,
        [half_plane(-6.0, velocity=(12.0, 0.0, 0.0))],
        (w, h),
        512,
        camera={**CAMERA, "shutter": [0.0, 1.0]},
        sampler="sobol",
    )
    x, pixel = column_x(w, h)
    expected = np.clip(1 - (x + 6) / 12, 0, 1)
    inside = (np.abs(x + 6) > pixel) & (
        np.abs(x - 6) > pixel
    )  # pixels clear of the ramp's two kinks (box filter: exact there)
    measured = r.rgb[..., 0].mean(axis=0)
    assert inside.sum() > 20
    np.testing.assert_allclose(measured[inside], expected[inside], atol=0.01)
    assert np.any((expected > 0.2) & (expected < 0.8) & inside)


def test_a_closed_shutter_shows_the_shape_where_its_velocity_has_carried_it(device):
    moving = [
        {"type": "sphere", "center": [-1.0, 0.2, 0.0], "radius": 0.8, "material": "grey", "velocity": [0.5, -0.1, 0.0]}
    ]
    still = [{"type": "sphere", "center": [-0.25, 0.05, 0.0], "radius": 0.8, "material": "grey"}]
    grey = [{"name": "grey", "albedo": [0.6, 0.6, 0.6]}]
    render = {"width": 40, "height": 30, "integrator": "raycast", "spp": 4}
    a = wrt.render(
        make_scene(moving, materials=grey, camera={**CAMERA, "shutter": [1.5, 1.5]}, render=render), device=device
    )
    b = wrt.render(make_scene(still, materials=grey, camera=CAMERA, render=render), device=device)
    np.testing.assert_allclose(a.rgb, b.rgb, atol=2e-5)
    assert np.array_equal(a.aovs["object_id"], b.aovs["object_id"])
    np.testing.assert_allclose(a.aovs["normal"], b.aovs["normal"], atol=2e-5)


def test_nothing_moves_outside_an_open_shutter_without_velocity(device):
    scene = [half_plane(0.0)]
    a = emitted(device, scene, (16, 4), 16, camera={**CAMERA, "shutter": [0.0, 3.0]})
    b = emitted(device, scene, (16, 4), 16)
    assert np.array_equal(a.rgb, b.rgb)  # time is drawn (dimension 4) but no dimension it shares


def truncated_normal_cdf(x: float, sigma: float = 0.5, radius: float = 2.0) -> float:
    phi = lambda v: 0.5 * (1 + math.erf(v / (sigma * math.sqrt(2))))  # noqa: E731
    return (phi(x) - phi(-radius)) / (phi(radius) - phi(-radius))


@pytest.mark.parametrize(
    "filter, cdf",
    [
        ("box", lambda x: min(max(x + 0.5, 0.0), 1.0)),
        ("tent", lambda x: 0.5 * (1 + min(max(x, -1.0), 0.0)) ** 2 if x < 0 else 1 - 0.5 * (1 - min(x, 1.0)) ** 2),
        ("gaussian", truncated_normal_cdf),
    ],
)
def test_pixel_filters_weigh_an_edge_by_their_profile(device, filter, cdf):
    """A vertical edge on the boundary between columns W/2 - 1 and W/2: a pixel whose centre is
    s pixels left of it gets the filter's mass left of the edge, CDF(s), from the emitter."""
    w, h = 8, 8
    r = emitted(device, [half_plane(0.0)], (w, h), 1024, filter=filter, sampler="sobol")
    measured = r.rgb[..., 0].astype(np.float64).mean(axis=0)
    for column in range(w):
        s = (w / 2 - column) - 0.5  # distance of the centre left of the edge, pixels
        assert measured[column] == pytest.approx(cdf(s), abs=3e-3), (filter, column)


def test_one_sample_per_pixel_stays_at_the_centre_whatever_the_filter(device):
    a = emitted(device, [half_plane(0.03)], (8, 4), 1, filter="gaussian")
    b = emitted(device, [half_plane(0.03)], (8, 4), 1, filter="box")
    assert np.array_equal(a.rgb, b.rgb)
    assert set(np.unique(a.rgb)) <= {0.0, 1.0}
