"""The camera convention (kernels/camera.py) checked through rendered AOVs."""

import math

import numpy as np
import pytest
from conftest import make_scene

import wrt
from wrt.rays import trace_rays


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


def test_primary_ray_directions_follow_the_formula(device):
    """(position - origin) / depth recovers each pixel's ray; it must equal the documented formula."""
    cam = {"origin": [1.0, 2.0, 3.0], "look_at": [-2.0, 0.5, -4.0], "up": [0.2, 1.0, 0.1], "fov": 50.0}
    scene = make_scene(
        [{"type": "sphere", "center": cam["origin"], "radius": 100.0}], camera=cam, render={"width": 64, "height": 40}
    )
    r = wrt.render(scene, device=device)
    d = (r.aovs["position"] - np.array(cam["origin"])) / r.aovs["depth"][..., None]
    np.testing.assert_allclose(
        d, expected_directions(cam["origin"], cam["look_at"], cam["up"], 50.0, 64, 40), atol=2e-5
    )
    np.testing.assert_allclose(r.aovs["depth"], 100.0, rtol=1e-5)  # from the centre of the sphere


def test_sphere_projects_where_the_formula_says(device):
    """A small sphere up and to the right of the view axis lands on the pixel the formula predicts."""
    w, h, fov = 200, 100, 40.0
    centre = np.array([0.9, 0.6, -10.0])
    scene = make_scene(
        [{"type": "sphere", "center": centre.tolist(), "radius": 0.15}],
        camera={"origin": [0, 0, 0], "look_at": [0, 0, -1], "up": [0, 1, 0], "fov": fov},
        render={"width": w, "height": h},
    )
    ids = wrt.render(scene, device=device).aovs["object_id"]
    th = math.tan(math.radians(fov) / 2)
    sx = (centre[0] / -centre[2]) / (th * w / h)
    sy = (centre[1] / -centre[2]) / th
    px, py = (sx + 1) * w / 2, (1 - sy) * h / 2  # continuous film position of the centre
    assert ids[int(py), int(px)] == 0
    ys, xs = np.nonzero(ids == 0)
    assert xs.mean() + 0.5 == pytest.approx(px, abs=0.5) and ys.mean() + 0.5 == pytest.approx(py, abs=0.5)
    assert py < h / 2 and px > w / 2  # row 0 is the top: above the axis means small y


def test_aspect_and_vertical_fov(device):
    """The vertical fov spans the image height: a sphere subtending fov/2 half-angle touches top and bottom."""
    fov = 30.0
    dist = 10.0
    radius = dist * math.sin(math.radians(fov / 2))
    scene = make_scene(
        [{"type": "sphere", "center": [0, 0, -dist], "radius": radius * 0.98}],
        camera={"origin": [0, 0, 0], "look_at": [0, 0, -1], "fov": fov},
        render={"width": 120, "height": 60},
    )
    ids = wrt.render(scene, device=device).aovs["object_id"]
    column = ids[:, 60]
    # half-angle of the sphere 14.69 deg; pixel-centre rays of rows 0 and 1 leave at 14.76 and 14.27 deg
    assert column[0] == -1 and column[-1] == -1
    assert (column[1:-1] == 0).all()
    cols = np.flatnonzero(ids[30] == 0)
    assert 60 - cols.min() == pytest.approx(30, abs=2)  # circle: horizontal radius in pixels = vertical


# --- orthographic camera and clip planes -------------------------------------------------------
TILTED = {"origin": [1.0, 2.0, 3.0], "look_at": [-2.0, 0.5, -4.0], "up": [0.2, 1.0, 0.1]}


def frame(cam):
    """``(forward, right, up')`` of the scene-format convention, float64."""
    forward = np.subtract(cam["look_at"], cam["origin"], dtype=float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, cam.get("up", [0.0, 1.0, 0.0]))
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def expected_rays(cam, w, h):
    """Unclipped camera rays ``(o, d)`` (H, W, 3) of every pixel centre, float64, from the documented
    formulas: the pinhole rays, or parallel rays along ``forward`` from the camera plane."""
    forward, right, up = frame(cam)
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    sx, sy = (2 * x / w - 1)[..., None], (1 - 2 * y / h)[..., None]
    if cam.get("type") == "orthographic":
        half = cam["width"] / 2
        o = np.asarray(cam["origin"]) + sx * half * right + sy * (half * h / w) * up
        return o, np.broadcast_to(forward, o.shape)
    return np.broadcast_to(cam["origin"], (h, w, 3)), expected_directions(
        cam["origin"], cam["look_at"], cam.get("up", [0, 1, 0]), cam.get("fov", 45.0), w, h
    )


def sphere_roots(o, d, centre, radius):
    """Both distances (float64, NaN on a miss) along unit rays ``o + t d`` to the sphere."""
    f = o - np.asarray(centre)
    b = np.einsum("...j,...j->...", f, d)
    disc = b * b - (np.einsum("...j,...j->...", f, f) - radius * radius)
    q = np.sqrt(np.where(disc >= 0, disc, np.nan))
    return -b - q, -b + q


def test_orthographic_rays_follow_the_formula(device):
    """Every pixel's hit, minus depth times forward, lies where the formula starts its ray, and
    the depth is the closed-form distance along ``forward`` to a sphere ahead."""
    cam = {**TILTED, "type": "orthographic", "width": 3.0}
    w, h = 48, 30
    forward, _, _ = frame(cam)
    centre, radius = np.asarray(cam["origin"]) + 20 * forward + [0.3, -0.2, 0.1], 10.0
    scene = make_scene(
        [{"type": "sphere", "center": centre.tolist(), "radius": radius}], camera=cam, render={"width": w, "height": h}
    )
    r = wrt.render(scene, device=device)
    o, d = expected_rays(cam, w, h)
    near, _ = sphere_roots(o, d, centre, radius)
    np.testing.assert_allclose(r.aovs["depth"], near, rtol=2e-6)
    np.testing.assert_allclose(r.aovs["position"] - r.aovs["depth"][..., None] * forward, o, atol=2e-5)
    # samples spread over the pixel (box filter) start on the camera plane, within their pixel
    tree = trace_rays(scene, [(0, 0), (47, 29), (20, 11)], samples=8, max_depth=1)
    _, right, up = frame(cam)
    offset = tree.origin - np.asarray(cam["origin"])
    sx, sy = offset @ right / 1.5, offset @ up / (1.5 * h / w)
    x, y = tree.pixel[:, 0], tree.pixel[:, 1]
    assert len(tree.origin) == 24 and np.allclose(offset @ forward, 0.0, atol=1e-5)
    assert np.all((sx > 2 * x / w - 1 - 1e-5) & (sx < 2 * (x + 1) / w - 1 + 1e-5))
    assert np.all((sy < 1 - 2 * y / h + 1e-5) & (sy > 1 - 2 * (y + 1) / h - 1e-5))
    np.testing.assert_allclose(tree.direction, np.broadcast_to(forward, tree.direction.shape), atol=1e-6)


def test_orthographic_sphere_silhouette_is_a_circle_of_known_radius(device):
    """An orthographic view of a sphere off the view axis: its silhouette is the circle of the
    sphere's radius (19.5 pixels here: 15 pixels per unit) around the projection of its centre,
    whatever its distance."""
    cam = {**TILTED, "type": "orthographic", "width": 6.0}
    w, h = 90, 60
    forward, right, up = frame(cam)
    offset, radius = np.array([0.8, -0.5]), 1.3
    centre = np.asarray(cam["origin"]) + 7.0 * forward + offset[0] * right + offset[1] * up
    scene = make_scene(
        [{"type": "sphere", "center": centre.tolist(), "radius": radius}], camera=cam, render={"width": w, "height": h}
    )
    ids = wrt.render(scene, device=device).aovs["object_id"]
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    plane = np.stack([(2 * x / w - 1) * 3.0, (1 - 2 * y / h) * 2.0], axis=-1)  # camera-plane coordinates
    distance = np.linalg.norm(plane - offset, axis=-1)
    clear = np.abs(distance - radius) > 1e-4
    assert np.array_equal((ids == 0)[clear], (distance < radius)[clear])
    assert np.count_nonzero(ids == 0) == pytest.approx(math.pi * (radius * w / 6.0) ** 2, rel=0.02)


CLIPPED = {
    "perspective": {**TILTED, "fov": 30.0},
    "orthographic": {**TILTED, "type": "orthographic", "width": 4.0},
}


@pytest.mark.parametrize("spp", [1, 4], ids=["centre ray is the sample", "separate AOV ray"])
@pytest.mark.parametrize("kind", list(CLIPPED))
def test_clip_planes_cut_the_camera_rays(device, kind, spp):
    """Near and far clip planes cutting a sphere: a ray starts where its distance along forward
    from the camera plane is near_clip (inside the sphere for the central pixels, which see its
    back) and misses what lies beyond far_clip; depth is measured from where the ray starts."""
    cam = CLIPPED[kind]
    w, h = 40, 30
    forward, _, _ = frame(cam)
    centre, radius = np.asarray(cam["origin"]) + 8.0 * forward, 1.6
    cam = {**cam, "near_clip": 7.0, "far_clip": 9.2}
    scene = make_scene(
        [{"type": "sphere", "center": centre.tolist(), "radius": radius}],
        camera=cam,
        render={"width": w, "height": h, "spp": spp},
    )
    r = wrt.render(scene, device=device)
    o, d = expected_rays(cam, w, h)
    cos = d @ forward
    t_near, t_far = 7.0 / cos, 9.2 / cos
    roots = np.stack(sphere_roots(o, d, centre, radius))
    visible = (roots > t_near) & (roots < t_far)
    t = np.where(visible[0], roots[0], np.where(visible[1], roots[1], np.nan))
    clear = np.all(np.isnan(roots) | (np.minimum(np.abs(roots - t_near), np.abs(roots - t_far)) > 1e-3), axis=0)
    clear &= np.abs(np.nan_to_num(np.diff(roots, axis=0)[0], nan=1.0)) > 1e-3  # not grazing
    hit = ~np.isnan(t)
    assert np.array_equal((r.aovs["object_id"] == 0)[clear], hit[clear])
    assert 0 < np.count_nonzero(hit & ~visible[0]) and 0 < np.count_nonzero(visible[0])  # back and front seen
    assert np.count_nonzero(~hit & ~np.isnan(roots[0])) > 0  # and rays the clip planes cut away
    # float32 rays 8 units long, near-grazing hits amplifying their rounding: 1e-4 absolute
    np.testing.assert_allclose(r.aovs["depth"][hit & clear], (t - t_near)[hit & clear], atol=1e-4)
    np.testing.assert_allclose(r.aovs["position"][hit & clear], (o + t[..., None] * d)[hit & clear], atol=1e-4)


def test_camera_media_are_found_where_the_central_ray_starts():
    """``wrt.bake.camera_media`` tests ``origin + near_clip forward``: a near clip plane inside
    a glass sphere starts the rays in the glass; one beyond it, outside."""
    from wrt.device import camera_media

    glass = [{"name": "glass", "type": "dielectric", "ior": 1.5}]
    sphere = [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"}]
    for cam, expected in (
        ({"origin": [0, 0, 5], "look_at": [0, 0, 0]}, []),
        ({"origin": [0, 0, 5], "look_at": [0, 0, 0], "near_clip": 4.5}, [0]),
        ({"origin": [0, 0, 0.5], "look_at": [0, 0, 0], "near_clip": 2.0}, []),
        ({"origin": [0, 0.5, 0.5], "look_at": [0, 0.5, 0], "type": "orthographic", "width": 4.0}, [0]),
    ):
        assert camera_media(make_scene(sphere, camera=cam, materials=glass)) == expected, cam
