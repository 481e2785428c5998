"""Shared test helpers: build scenes inline from dicts and trace rays through the real kernels."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import kernels  # noqa: F401  (configures Warp)
from kernels.traverse import trace_any, trace_closest
from wrt.device import init_warp, upload_geometry
from wrt.geometry import build
from wrt.loader import parse_scene

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


class Tracer:
    """Closest-hit and any-hit queries of ray batches against a scene, on the CPU."""

    def __init__(self, scene):
        self.prims = build(scene)
        self.data = upload_geometry(self.prims, "cpu")

    def closest(self, origins, directions, t_min=0.0, t_max=np.inf, brute_force=False):
        """Returns (t, shape id) per ray; t = t_max and shape -1 on a miss."""
        o = wp.array(np.asarray(origins, np.float32).reshape(-1, 3), dtype=wp.vec3, device="cpu")
        d = wp.array(np.asarray(directions, np.float32).reshape(-1, 3), dtype=wp.vec3, device="cpu")
        t = wp.zeros(len(o), dtype=float, device="cpu")
        prim = wp.zeros(len(o), dtype=wp.int32, device="cpu")
        wp.launch(trace_closest, dim=len(o), inputs=[self.data, o, d, float(t_min), float(t_max), int(brute_force), t, prim], device="cpu")
        return t.numpy(), self.prims.shape_of(prim.numpy())

    def occluded(self, origins, directions, t_min=0.0, t_max=np.inf):
        o = wp.array(np.asarray(origins, np.float32).reshape(-1, 3), dtype=wp.vec3, device="cpu")
        d = wp.array(np.asarray(directions, np.float32).reshape(-1, 3), dtype=wp.vec3, device="cpu")
        hit = wp.zeros(len(o), dtype=wp.int32, device="cpu")
        wp.launch(trace_any, dim=len(o), inputs=[self.data, o, d, float(t_min), float(t_max), hit], device="cpu")
        return hit.numpy().astype(bool)


@pytest.fixture
def rng():
    return np.random.default_rng(20261125)
