"""Shared test helpers: build scenes inline from dicts and trace rays through the real kernels."""

from __future__ import annotations

import numpy as np
import pytest
import wrt.kernels  # noqa: F401  (configures Warp)

from wrt.device import init_warp
from wrt.loader import parse_scene
from wrt.trace import Tracer as PrimitiveTracer

init_warp()

CAMERA = {"origin": [0.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0]}


def make_scene(shapes, render=None, camera=None, materials=None, lights=None, scene_dir="."):
    """A validated ``Scene`` from inline tables, with a default camera and render settings."""
    doc = {"camera": camera or CAMERA, "shape": shapes, "light": lights or []}
    if render:
        doc["render"] = render
    if materials:
        doc["material"] = materials
    return parse_scene(doc, file="<test>", scene_dir=scene_dir)


class Tracer(PrimitiveTracer):
    """``wrt.trace.Tracer`` (closest-hit and any-hit ray batches through the real kernels), with
    closest hits reported by shape: ``(t, shape id)``, ``t = t_max`` and -1 on a miss."""

    def closest(self, origins, directions, t_min=0.0, t_max=np.inf, brute_force=False):
        t, prim = super().closest(origins, directions, t_min, t_max, brute_force)
        return t, self.prims.shape_of(prim)


@pytest.fixture
def rng():
    return np.random.default_rng(20261125)
