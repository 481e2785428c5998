"""Emissive triangles sampled by next-event estimation (wrt.emitting, kernels/lights/emitting.py): a
closed form, the MIS-combined estimator against BSDF sampling alone, and their noise."""

import numpy as np
import pytest
from conftest import LAMP_ALBEDO, LAMP_MATERIALS, LAMP_RADIANCE, corner_form_factor, make_scene
from conftest import render_lamp_scene as render

import wrt
from wrt.emitting import emitting_primitives
from wrt.geometry import flatten
from wrt.renderer import scene_features

A, B, H, L, ALBEDO = 2.0, 1.0, 1.5, LAMP_RADIANCE, LAMP_ALBEDO
FLOOR = {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"}
# an a x b rectangle at height h over the origin's corner, two triangles wound to emit downward
QUAD = [
    {"type": "triangle", "vertices": [[0, H, 0], [A, H, 0], [A, H, B]], "material": "lamp"},
    {"type": "triangle", "vertices": [[0, H, 0], [A, H, B], [0, H, B]], "material": "lamp"},
]
CORNER = {"origin": [0, 0.5, 0.0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 1.0}


def test_distribution_is_by_power_and_skips_other_shapes():
    scene = make_scene(
        [FLOOR, *QUAD, {"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 0, 1]], "material": "floor"}],
        materials=LAMP_MATERIALS,
    )
    emitting = emitting_primitives(scene, flatten(scene))
    assert list(emitting.prim) == [0, 1]
    assert list(emitting.of_triangle) == [0, 1, -1]
    np.testing.assert_allclose(emitting.cdf, [0.0, 0.5, 1.0])
    assert scene_features(scene).emissive
    assert not scene_features(make_scene([FLOOR], materials=LAMP_MATERIALS)).emissive


def test_emissive_quad_over_a_corner_matches_the_form_factor(device):
    """Floor point under a corner of a parallel a x b emissive rectangle at height h: albedo L F."""
    r = render([FLOOR, *QUAD], CORNER, (1, 1), 4000, device=device)
    assert r.rgb[0, 0, 0] == pytest.approx(ALBEDO * L * corner_form_factor(A, B, H), rel=0.01)


def test_mis_matches_bsdf_sampling_alone_with_far_less_noise(device):
    """Same expectation as BSDF sampling alone (means within noise), per-pixel variance far lower."""
    camera = {"origin": [1, 1.2, -2.5], "look_at": [1, 0.3, 0.5], "fov": 50}
    shapes = [FLOOR, *QUAD]
    # the same lamp placed by an instance of a group: BSDF-sampled only
    instanced = [FLOOR, {"type": "instance", "group": "lamp"}]
    groups = [{"name": "lamp", "shape": QUAD}]
    a = [render(shapes, camera, (16, 12), 16, seed=s, device=device).rgb[..., 1].astype(np.float64) for s in range(4)]
    b = [
        render(instanced, camera, (16, 12), 16, groups, seed=s, device=device).rgb[..., 1].astype(np.float64)
        for s in range(4)
    ]
    a, b = np.stack(a), np.stack(b)
    lit = (a.mean(axis=0) > 0.01) & (a.mean(axis=0) < 1.0)  # the floor, not the lamp seen directly
    ratio = np.median(b.var(axis=0, ddof=1)[lit] / np.maximum(a.var(axis=0, ddof=1)[lit], 1e-12))
    print(f"per-pixel variance ratio, BSDF only / MIS: {ratio:.1f}")
    assert ratio > 10.0
    ma, mb = a.mean(), b.mean()
    se = np.sqrt(a.var(axis=0, ddof=1).sum() + b.var(axis=0, ddof=1).sum()) / (a.shape[0] ** 0.5 * a[0].size)
    assert abs(ma - mb) < 4 * se + 1e-4


def test_furnace_inside_a_closed_emissive_mesh(device):
    """Inside a closed mesh of albedo a emitting E inward everywhere, every ray sees E / (1 - a)
    (the sum over bounces), whichever triangle each next-event sample picks."""
    emission, albedo = 0.5, 0.6
    sphere = {
        "type": "mesh",
        "file": "examples/meshes/coarse_sphere.obj",
        "flip_normals": True,
        "transform": {"scale": 2.0},
        "material": "inside",
    }
    scene = make_scene(
        [sphere],
        materials=[{"name": "inside", "albedo": [albedo] * 3, "emission": [emission] * 3}],
        camera={"origin": [0.1, 0.2, 0.0], "look_at": [0, 0, -1], "fov": 90},
        render={"width": 8, "height": 8, "integrator": "path", "spp": 64, "max_depth": 200},
        scene_dir=".",
    )
    r = wrt.render(scene, device=device)
    values = r.rgb[..., 0].astype(np.float64)
    assert values.mean() == pytest.approx(emission / (1 - albedo), rel=0.02)
