"""The path integrator (kernels/path.py): furnaces, closed forms, MIS-weighted emitters, determinism."""

import numpy as np
import pytest
from conftest import CAMERA, corner_form_factor, make_scene

import wrt

ENV = {"type": "environment", "radiance": [0.5, 0.5, 0.5]}


def path(shapes, materials, lights, camera=None, size=(32, 24), spp=64, device="cpu", **render):
    settings = {"width": size[0], "height": size[1], "integrator": "path", "spp": spp, **render}
    return wrt.render(
        make_scene(shapes, materials=materials, lights=lights, camera=camera, render=settings), device=device
    )


def test_white_furnace(device):
    """A diffuse sphere of albedo 1 in a uniform environment renders exactly the environment."""
    r = path(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "white"}],
        [{"name": "white", "albedo": [1, 1, 1]}],
        [ENV],
        max_depth=64,
        device=device,
    )
    values = r.rgb[..., 0].astype(np.float64)
    assert values.mean() == pytest.approx(0.5, abs=4 * values.std() / np.sqrt(values.size) + 1e-4)
    assert values.max() < 0.6 and values.min() > 0.4  # per pixel, 64 spp


def test_diffuse_plane_under_uniform_sky_returns_albedo_times_radiance(device):
    """An infinite floor hides the lower hemisphere: one bounce of albedo a under radiance L gives a L."""
    r = path(
        [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}],
        [{"name": "floor", "albedo": [0.2, 0.5, 0.8]}],
        [ENV],
        camera={"origin": [0, 2, 0.001], "look_at": [0, 0, 0], "fov": 30},
        max_depth=2,
        device=device,
    )
    mean = r.rgb.reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(mean, [0.1, 0.25, 0.4], rtol=0.01)


def test_area_light_over_a_corner_matches_the_form_factor():
    """Floor point under a corner of a parallel a x b light at height h: radiance albedo L F."""
    a, b, h, L, albedo = 2.0, 1.0, 1.5, 4.0, 0.6
    light = {
        "type": "area",
        "corner": [0, h, 0],
        "edge_u": [a, 0, 0],
        "edge_v": [0, 0, b],
        "radiance": [L, L, L],
    }  # emits down: cross = -y
    r = path(
        [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}],
        [{"name": "floor", "albedo": [albedo] * 3}],
        [light],
        camera={"origin": [0, 0.5, 0.0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 1.0},
        size=(1, 1),
        spp=20000,
        max_depth=2,
    )
    assert r.rgb[0, 0, 0] == pytest.approx(albedo * L * corner_form_factor(a, b, h), rel=0.01)


def test_emitters_are_seen_from_the_front_only_and_max_depth_1_shows_only_emitters():
    lights = [
        {"type": "area", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0], "radiance": [3, 2, 1]}
    ]  # faces +z
    floor = [{"type": "plane", "point": [0, 0, -1], "normal": [0, 0, 1], "material": "grey"}]
    grey = [{"name": "grey", "albedo": [0.5, 0.5, 0.5]}]
    front = path(
        floor,
        grey,
        lights,
        camera={"origin": [0, 0, 3], "look_at": [0, 0, 0], "fov": 10},
        size=(8, 8),
        spp=4,
        max_depth=1,
    )
    np.testing.assert_allclose(front.rgb.reshape(-1, 3), np.broadcast_to([3, 2, 1], (64, 3)), rtol=1e-6)
    assert (front.aovs["object_id"] == -2).all()  # the surface of light 0 is not a shape
    back = path(
        floor,
        grey,
        lights,
        camera={"origin": [0, 0, -0.5], "look_at": [0, 0, 1], "up": [0, 1, 0], "fov": 10},
        size=(8, 8),
        spp=4,
        max_depth=8,
    )
    assert (back.rgb == 0).all()  # its back: no emission, and it reflects nothing


@pytest.mark.parametrize(
    "material",
    [
        {"name": "m", "type": "dielectric", "ior": 1.5},
        {"name": "m", "type": "mirror", "reflectance": [1, 1, 1]},
        {"name": "m", "type": "glossy", "roughness": 0.3, "reflectance": [1, 1, 1]},
    ],
)
def test_energy_never_increases_under_a_uniform_environment(material):
    r = path(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "m"}],
        [material],
        [ENV],
        spp=32,
        max_depth=32,
    )
    assert np.isfinite(r.rgb).all()
    if material["type"] == "glossy":  # GGX loses what single scattering cannot reflect, never gains
        assert r.rgb.mean() <= 0.5 + 0.005 and r.rgb.mean() > 0.4
    else:  # lossless: exactly the environment (glass by Fresnel-weighted choice: noisy but unbiased)
        assert r.rgb.mean() == pytest.approx(0.5, abs=0.01)


@pytest.mark.parametrize("sampler, filter", [("independent", "box"), ("stratified", "tent"), ("sobol", "gaussian")])
def test_bit_identical_for_any_thread_count(sampler, filter):
    args = (
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "w", "velocity": [0.3, 0, 0]}],
        [{"name": "w", "albedo": [0.7, 0.7, 0.7]}],
        [ENV, {"type": "point", "position": [2, 2, 2], "intensity": [5, 5, 5]}],
    )
    camera = {**CAMERA, "shutter": [0.0, 1.0], "aperture_radius": 0.05}
    render = {"width": 24, "height": 16, "integrator": "path", "spp": 8, "sampler": sampler, "filter": filter}
    scene = make_scene(*args[:1], materials=args[1], lights=args[2], camera=camera, render=render)
    a, b = wrt.render(scene, threads=1), wrt.render(scene, threads=2)
    assert np.array_equal(a.rgb, b.rgb)


def test_error_falls_as_one_over_sqrt_spp():
    """With independent samples the error of a path-traced image falls as 1/sqrt(spp) (the default
    sobol sampler falls faster on this smooth scene: test_sampling.py measures its rates)."""
    lights = [
        {"type": "area", "corner": [-0.5, 2, -0.5], "edge_u": [1, 0, 0], "edge_v": [0, 0, 1], "radiance": [5, 5, 5]}
    ]
    shapes = [
        {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "g"},
        {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "g"},
    ]
    mats = [{"name": "g", "albedo": [0.6, 0.6, 0.6]}]
    cam = {"origin": [0, 1.5, 3], "look_at": [0, 0.4, 0], "fov": 50}
    reference = path(shapes, mats, lights, camera=cam, spp=2048, seed=99).rgb
    errors = [
        np.sqrt(np.mean((path(shapes, mats, lights, camera=cam, spp=n, sampler="independent").rgb - reference) ** 2))
        for n in (4, 16, 64)
    ]
    slope = np.polyfit(np.log([4, 16, 64]), np.log(errors), 1)[0]
    assert -0.6 < slope < -0.4


def test_thin_lens_blur_matches_the_circle_of_confusion():
    """A small emitting sphere off the plane of focus images as a disk whose radius on the focus
    plane is aperture * |z - f| / z; points on the plane of focus stay sharp."""
    aperture, focus, z = 0.2, 4.0, 8.0
    light = [{"type": "sphere", "center": [0, 0, -z], "radius": 0.02, "radiance": [100, 100, 100]}]
    cam = {"origin": [0, 0, 0], "look_at": [0, 0, -1], "fov": 10, "aperture_radius": aperture, "focus_distance": focus}
    r = path([], [], light, camera=cam, size=(64, 64), spp=256, max_depth=1)
    img = r.rgb[..., 0].astype(np.float64)
    y, x = np.mgrid[0:64, 0:64] + 0.5
    w = img / img.sum()
    r2 = (w * ((x - 32) ** 2 + (y - 32) ** 2)).sum()  # uniform disk of radius R: mean r^2 = R^2 / 2
    radius_px = aperture * abs(z - focus) / z / (focus * np.tan(np.radians(5))) * 32
    assert np.sqrt(2 * r2) == pytest.approx(radius_px, rel=0.1)
    cam["focus_distance"] = z
    sharp = path([], [], light, camera=cam, size=(64, 64), spp=64, max_depth=1).rgb[..., 0]
    assert np.count_nonzero(sharp > 0) < 16
