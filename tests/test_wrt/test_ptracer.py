"""The light tracer (``integrator = "ptracer"``): it converges to the path integrator's image where
every surface the camera sees has a non-specular lobe, to a closed form, is deterministic
whatever the threads and passes, and refuses what it cannot render."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from conftest import EXAMPLES, make_scene

import wrt
from wrt.errors import SceneError, WrtError
from wrt.loader import override_render
from wrt.rays import trace_rays

BOX = EXAMPLES / "ptracer" / "cornell_box.toml"


def small(scene, size: int):
    return dataclasses.replace(scene, render=dataclasses.replace(scene.render, width=size, height=size))


def test_the_light_tracer_converges_to_the_path_image():
    """Diffuse and glossy walls and balls, an area, a spot and a point light: the two estimators
    of one image agree in the mean (2%) and in each quarter of it (5%)."""
    scene = small(wrt.load_scene(BOX), 32)
    path = wrt.render(override_render(scene, integrator="path"), spp=256).rgb.astype(np.float64)
    light = wrt.render(scene, spp=512).rgb.astype(np.float64)
    assert np.allclose(light.mean(axis=(0, 1)), path.mean(axis=(0, 1)), rtol=0.02)
    for quarter in (np.s_[:16, :16], np.s_[:16, 16:], np.s_[16:, :16], np.s_[16:, 16:]):
        assert np.allclose(light[quarter].mean(axis=(0, 1)), path[quarter].mean(axis=(0, 1)), rtol=0.05)


def test_a_point_light_over_a_plane_gives_the_closed_form():
    """A diffuse square lit by a point light, seen from straight above: radiance
    ``albedo / pi * I cos / d^2`` at every point (within 4% over each 4 x 4 block of pixels, 1% over
    the image)."""
    albedo, intensity, height = 0.6, 2.0, 1.5
    scene = make_scene(
        [{"type": "polygon", "vertices": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], "material": "white"}],
        render={"width": 16, "height": 16, "spp": 2048, "integrator": "ptracer", "max_depth": 2},
        camera={"origin": [0.0, 0.0, 3.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov": 40.0},
        materials=[{"name": "white", "albedo": [albedo] * 3}],
        lights=[{"type": "point", "position": [0.3, 0.0, height], "intensity": [intensity] * 3}],
    )
    result = wrt.render(scene)
    p = result.aovs["position"].astype(np.float64)
    to_light = np.array([0.3, 0.0, height]) - p
    d2 = (to_light**2).sum(axis=-1)
    expected = albedo / np.pi * intensity * (to_light[..., 2] / np.sqrt(d2)) / d2
    blocks = result.rgb[..., 0].reshape(4, 4, 4, 4).mean(axis=(1, 3))
    assert np.allclose(blocks, expected.reshape(4, 4, 4, 4).mean(axis=(1, 3)), rtol=0.04)
    assert result.rgb[..., 0].mean() == pytest.approx(expected.mean(), rel=0.01)


def test_the_image_is_the_same_whatever_the_threads_and_passes():
    scene = small(wrt.load_scene(BOX), 24)
    one = wrt.render(scene, spp=8, threads=1).rgb
    two = wrt.render(scene, spp=8, threads=2).rgb
    passes = wrt.render(scene, spp=8, threads=2, progress=lambda *a: None, progress_every=3).rgb
    assert np.array_equal(one, two) and np.array_equal(one, passes)
    assert wrt.render(scene, spp=8, seed=2).rgb.tolist() != one.tolist()


@pytest.mark.parametrize(
    ("example", "table", "problem"),
    [
        ("path/god_rays.toml", "medium[0]", "no participating media"),
        ("path/conductors.toml", "shape[0]", "an infinite plane with light"),
    ],
)
def test_what_the_light_tracer_cannot_render_is_refused(example, table, problem):
    scene = wrt.load_scene(EXAMPLES / example)
    with pytest.raises(SceneError, match=rf"{re.escape(table)}.*{problem}"):
        override_render(scene, integrator="ptracer")


def test_a_light_inside_glass_is_refused():
    with pytest.raises(SceneError, match=r"light\[0\].type = 'point': lies inside shape\[0\], a dielectric"):
        make_scene(
            [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": "glass"}],
            render={"integrator": "ptracer"},
            materials=[{"name": "glass", "type": "dielectric", "ior": 1.5}],
            lights=[{"type": "point", "position": [0.0, 0.0, 0.0], "intensity": [1.0, 1.0, 1.0]}],
        )


def test_adaptive_sampling_is_refused():
    with pytest.raises(WrtError, match="ptracer: adaptive sampling"):
        wrt.render(small(wrt.load_scene(BOX), 8), spp=32, target_error=0.1)


def test_the_recorded_light_paths_are_the_ones_the_render_splats():
    """``wrt rays`` on a light-traced scene records each slot's light paths as the render traces
    them: every ray leaving a light starts a path, each segment starts where its parent ends,
    one segment deeper, and each connection ends at the camera; recording every slot of an 8 x 8
    image at 4 samples, the connections that reach the lens carry, in all, what the render at 4
    spp splats (the image's sum times its spp, to float32 rounding)."""
    scene = small(wrt.load_scene(BOX), 8)
    pixels = [(x, y) for y in range(8) for x in range(8)]
    tree = trace_rays(scene, pixels, samples=4)
    assert not tree.truncated
    kinds = [tree.kind_name(i) for i in range(len(tree))]
    assert {"emitted", "to camera", "scattered"} <= set(kinds)
    roots = tree.parent < 0
    assert all(kinds[i] in ("emitted", "to camera") for i in np.flatnonzero(roots))
    child = np.flatnonzero(~roots)
    parent = tree.parent[child]
    assert np.all(tree.depth[child] == tree.depth[parent] + 1) and tree.depth.max() <= scene.render.max_depth
    assert np.allclose(tree.origin[child], tree.end[parent], atol=1e-3)  # spawned off the parent's hit
    lit = np.array([k == "to camera" for k in kinds])
    # a pinhole, whose lens is a point: reached but for the shadow rays' margin (1e-4 of the length)
    assert np.allclose(tree.end[lit], scene.camera.origin, atol=1e-3)
    rendered = wrt.render(scene, spp=4).rgb.astype(np.float64).sum(axis=(0, 1)) * 4
    np.testing.assert_allclose(tree.throughput[lit].astype(np.float64).sum(axis=0), rendered, rtol=1e-4)
