"""Every bundled example scene (examples/**/*.toml) loads and renders a sane tiny image."""

import numpy as np
import pytest
from conftest import EXAMPLES

import wrt
from wrt.loader import override_render

SCENES = sorted(EXAMPLES.rglob("*.toml"))


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
