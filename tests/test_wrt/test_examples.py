"""Every bundled example scene (examples/**/*.toml) loads and renders a sane tiny image."""

import numpy as np
import pytest
from conftest import EXAMPLES

import wrt
from wrt.loader import override_render

SCENES = sorted(
    p for p in EXAMPLES.rglob("*.toml") if p.name != "features.toml"
)  # not examples/own_matrix's feature list


def test_examples_are_found():
    assert SCENES, f"no *.toml under {EXAMPLES}"


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_example_renders(path):
    scene = override_render(wrt.load_scene(path), width=48, height=36, spp=1)
    result = wrt.render(scene)
    assert result.rgb.shape == (36, 48, 3)
    assert np.isfinite(result.rgb).all(), "NaN or Inf in the image"
    assert result.rgb.max() > 0.0, "all-black image"
    assert result.aovs["object_id"].max() >= 0, "the camera sees no shape"


WALLS = [
    [[s, -1, -1], [s, 1, -1], [s, 1, 1], [s, -1, 1]] if axis == 0 else
    [[-1, s, -1], [1, s, -1], [1, s, 1], [-1, s, 1]] if axis == 1 else
    [[-1, -1, s], [1, -1, s], [1, 1, s], [-1, 1, s]]
    for axis in range(3) for s in (-1, 1)
]  # fmt: skip


@pytest.mark.parametrize("look_at", [[1, 1, 1], [1, 1, 0], [0, 0, 1]], ids=["corner", "edge", "face"])
def test_closed_polygon_box_seen_from_its_centre_lets_no_ray_out(tmp_path, look_at):
    """Issue 13: a box of six polygon walls, the camera at its centre looking at a corner or an
    edge, odd image size (pixel centres on the images of edges): every camera ray hits a wall
    (the old polygon test let hundreds escape), and the Cornell box camera is on its axis."""
    shapes = "".join(f'[[shape]]\ntype = "polygon"\nvertices = {w}\nmaterial = "m"\n\n' for w in WALLS)
    path = tmp_path / "box.toml"
    path.write_text(
        '[render]\nwidth = 101\nheight = 101\nspp = 1\nintegrator = "raycast"\n\n'
        f"[camera]\norigin = [0.0, 0.0, 0.0]\nlook_at = {look_at}\nfov = 150.0\n\n"
        '[[material]]\nname = "m"\nalbedo = [0.5, 0.5, 0.5]\n\n' + shapes
    )
    ids = wrt.render(wrt.load_scene(path)).aovs["object_id"]
    assert np.count_nonzero(ids < 0) == 0
    assert wrt.load_scene(EXAMPLES / "path" / "cornell_box.toml").camera.origin[:2] == (0.0, 0.0)
